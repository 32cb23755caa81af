"""Triangle mesh files: the readers and the writer (``files``: OBJ, OFF, STL and PLY in, OBJ out) and
their one error (``errors.MeshError``). Below the design engine: it imports nothing else of ribbond."""
