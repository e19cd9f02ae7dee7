"""The exception raised for bad shape input (meshes, materials, library entries)."""

from __future__ import annotations

__all__ = ["ShapeError"]


class ShapeError(ValueError):
    """A mesh, material, shape-library entry or option is invalid.

    Subclass of :class:`ValueError`, so the ``lightcurve`` CLI prints it as a one-line error.
    Messages name the file, facet, group or field at fault.
    """
