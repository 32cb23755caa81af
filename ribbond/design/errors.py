"""Errors of the design engine: ``MeshError`` (the mesh readers', from ``ribbond.mesh.errors``) and
``DesignError``; both are ``ValueError`` so callers can catch bad input uniformly."""

from __future__ import annotations

from ..mesh.errors import MeshError

__all__ = ["DesignError", "MeshError"]


class DesignError(ValueError):
    """The mesh is valid but the design cannot be made as asked (for example it does not fit the frame)."""
