"""Facet shape models, materials, primitives, mesh IO and the shape library.

The package depends on no other project package. Geometry is SI (metres, m², kg m²) in the
model (body) frame. Main entry points:

- :class:`FacetModel` (vertices, facets, groups, materials, mass properties) and its
  render-ready :class:`CompiledFacets` (coplanar facets merged by material);
- :func:`load` / :func:`load_damit` for mesh files, :mod:`shapes.primitives` for builders;
- :class:`VisibilityTable`, :func:`build_visibility_table`, :func:`visible_fraction`,
  :func:`joint_visible_fraction` for self-shadowing of non-convex models;
- :func:`validate` and :class:`ShapeError`;
- :class:`ShapeLibrary` / :func:`get_library` for the folder of named shapes.
"""

from shapes import primitives
from shapes.compiled import DEFAULT_ANGLE_TOLERANCE, CompiledFacets
from shapes.errors import ShapeError
from shapes.io import load, load_damit, write_obj
from shapes.library import ShapeLibrary, builtin_library_path, get_library
from shapes.material import Material
from shapes.model import FacetModel, inertia_from_components
from shapes.validation import validate
from shapes.visibility import (
    VisibilityTable,
    build_visibility_table,
    joint_visible_fraction,
    visible_fraction,
)

__all__ = [
    "DEFAULT_ANGLE_TOLERANCE",
    "CompiledFacets",
    "FacetModel",
    "Material",
    "ShapeError",
    "ShapeLibrary",
    "VisibilityTable",
    "build_visibility_table",
    "builtin_library_path",
    "get_library",
    "inertia_from_components",
    "joint_visible_fraction",
    "load",
    "load_damit",
    "primitives",
    "validate",
    "visible_fraction",
    "write_obj",
]
