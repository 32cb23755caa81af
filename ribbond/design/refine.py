"""Midpoint subdivision of the flat mesh, so that stripe periods span enough edges.

A stripe pattern resolves a period only if it spans several edges (KCPS15 §5 treat coarse meshes
specially; we refine instead). The flat map is piecewise linear, so subdividing it at edge
midpoints changes no position: per-vertex fields are interpolated linearly at the new vertices and
per-face fields are inherited by the four children.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .stripes import edge_topology


@dataclass(frozen=True)
class Subdivision:
    """One or more rounds of midpoint subdivision.

    Attributes
    ----------
    F : (m', 3) the refined faces (same winding as the original ones).
    parent : (m',) the original face each refined face lies in.
    weights : sparse-free prolongation of vertex values: the value at refined vertex v is
        ``0.5 * (x[pair[v, 0]] + x[pair[v, 1]])`` (pairs of one vertex repeated for kept vertices),
        applied round after round by ``prolong``.
    """

    F: np.ndarray
    parent: np.ndarray
    pairs: tuple[np.ndarray, ...]

    def prolong(self, values: np.ndarray) -> np.ndarray:
        """Vertex values (n, …) of the original mesh interpolated onto the refined one (n', …)."""
        x = np.asarray(values, dtype=float)
        for pair in self.pairs:
            x = 0.5 * (x[pair[:, 0]] + x[pair[:, 1]])
        return x

    @property
    def rounds(self) -> int:
        return len(self.pairs)


def subdivide(F: np.ndarray, n_vertices: int, rounds: int) -> Subdivision:
    """Split every face into four at its edge midpoints, ``rounds`` times.

    Parameters
    ----------
    F : (m, 3) faces; n_vertices : vertex count; rounds : ≥ 0.

    Returns
    -------
    The refined faces (4^rounds · m), each face's original face, and the vertex prolongation.
    """
    if rounds < 0:
        raise ValueError(f"rounds must be ≥ 0, got {rounds}")
    F = np.asarray(F, dtype=np.int64)
    parent = np.arange(len(F))
    pairs = []
    n = n_vertices
    for _ in range(rounds):
        top = edge_topology(F)
        mid = n + top.face_edges                       # (m, 3): midpoint of half-edge k
        a, b, c = F.T
        mab, mbc, mca = mid.T
        F = np.concatenate([np.column_stack([a, mab, mca]), np.column_stack([b, mbc, mab]),
                            np.column_stack([c, mca, mbc]), np.column_stack([mab, mbc, mca])])
        parent = np.tile(parent, 4)
        keep = np.repeat(np.arange(n)[:, None], 2, axis=1)
        pairs.append(np.concatenate([keep, top.edges]))
        n += len(top.edges)
    return Subdivision(F=F, parent=parent, pairs=tuple(pairs))
