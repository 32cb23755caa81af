"""The design engine: target mesh → principal curvature line field → bounded directional flattening
→ ribbon spacing → stripe patterns → staggered ribbons with thickness → the design folder.

Pure functions over numpy arrays (``V``, ``F``), one concept per module; it reads and writes only
the files it is given. ``ribbond.pipeline.compile.design_mesh`` wires the stages together; ``ribbonctl design``
runs it. Issue 3 built intake, the k1 line field and the flattening; ribbons come with issue 4.
"""
