"""The pipeline: the stages of the design engine (``ribbond.design``), the prediction
(``ribbond.deploy``) and the print programs (``ribbond.gcode``) run in order, above all three.

- ``compile``: ``design_mesh`` (mesh -> design, prediction, programs) and ``write_design``;
- ``repredict``: a design folder's prediction made again;
- ``worker``: ``python -m ribbond.pipeline.worker``, one compile in its own process (the daemon's);
- ``predict_worker``: ``python -m ribbond.pipeline.predict_worker``, one prediction in its own process.
"""
