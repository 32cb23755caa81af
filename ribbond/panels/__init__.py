"""Panels (issue 26): a target one sheet cannot make, cut into panels, each an ordinary design.

- ``cut``: the spectral partition of the face graph and the seams' straightening;
- ``seams``: the seams between panels, their lengths and matched points;
- ``stitch``: the stitch marks printed along a seam;
- ``sewing``: the panels' predictions sewn together along their seams (the sewn prediction);
- ``picture``: ``panels.png``;
- ``project``: ``design_project`` (each panel designed by ``ribbond.pipeline.compile``) and the project
  folder (``write_project``).
"""
