"""The interfaces that facet models, their compiled form and visibility tables see of each other.

:class:`~shapes.model.FacetModel` holds a :class:`~shapes.visibility.VisibilityTable` and is
checked by :mod:`shapes.validation`; the table is built from a model's
:class:`~shapes.compiled.CompiledFacets`. Naming the concrete classes in each other's type
hints made an import cycle among these modules (even under ``TYPE_CHECKING``). The modules
that only *hold* or *read* the other object annotate with these protocols instead, so the
imports run one way: ``validation``, ``compiled`` → ``protocols``; ``visibility`` →
``compiled``; ``model`` → all of them but ``visibility``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

if TYPE_CHECKING:
    import trimesh

__all__ = ["FacetMesh", "FacetVisibility"]


class FacetMesh(Protocol):
    """What the checks of :mod:`shapes.validation` read from a facet model.

    :class:`shapes.model.FacetModel` implements it.
    """

    name: str
    unit: str
    vertices: np.ndarray
    faces: np.ndarray
    group_names: list[str]
    group_index: np.ndarray

    @property
    def triangles(self) -> np.ndarray:
        """Vertex coordinates of each facet ``(F, 3, 3)``."""
        ...

    @property
    def areas(self) -> np.ndarray:
        """Facet areas ``(F,)`` in the model's unit squared."""
        ...

    @property
    def scale(self) -> float:
        """Characteristic size of the model in its unit."""
        ...

    @property
    def mesh(self) -> trimesh.Trimesh:
        """The model as a trimesh mesh."""
        ...

    @property
    def is_watertight(self) -> bool:
        """Whether every edge is shared by exactly two facets."""
        ...


class FacetVisibility(Protocol):
    """What a facet model and its compiled form need from a precomputed visibility table.

    :class:`shapes.visibility.VisibilityTable` implements it.
    """

    structure: str

    def check_fits(self, compiled: Any) -> None:
        """Raise unless the table was built for these compiled facets."""
        ...

    def rotated(self, rotation: np.ndarray) -> FacetVisibility:
        """The table of the model turned by ``rotation`` (3 × 3, body frame)."""
        ...
