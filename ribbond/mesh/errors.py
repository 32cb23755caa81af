"""The one error of the mesh readers: a ``ValueError`` so callers can catch bad input uniformly."""

from __future__ import annotations


class MeshError(ValueError):
    """The input mesh cannot be used; the message names the problem and, where possible, where it is.

    Attributes
    ----------
    problem : str
        a short, stable key for the kind of problem (``"unreadable"``, ``"empty"``, ``"too_small"``,
        ``"non_finite"``, ``"zero_area"``, ``"non_manifold_edge"``, ``"non_manifold_vertex"``,
        ``"orientation"``, ``"components"``, ``"closed"``, ``"not_disk"``, ``"too_many_faces"``,
        ``"bad_index"``), for programs (the daemon's API) that react to it.
    """

    def __init__(self, problem: str, message: str) -> None:
        super().__init__(message)
        self.problem = problem
