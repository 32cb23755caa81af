"""The design engine: target mesh → principal curvature line field → bounded directional flattening
→ ribbon spacing → stripe patterns → staggered ribbons with thickness → the design folder.

Pure functions over numpy arrays (``V``, ``F``); it reads and writes only the files it is given.
Built by issues 3 and 4; nothing is here yet.
"""
