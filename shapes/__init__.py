"""Facet shape models, materials, primitives, mesh IO and the shape library.

The package depends on no other project package. Geometry is SI (metres, m², kg m²) in the
model (body) frame. Main entry points:

- :class:`FacetModel` (vertices, facets, groups, materials, mass properties) and its
  render-ready :class:`CompiledFacets` (coplanar facets merged by material);
- :func:`load` / :func:`load_damit` for mesh files, :mod:`shapes.primitives` for builders;
- :class:`VisibilityTable`, :func:`build_visibility_table`, :func:`visible_fraction`,
  :func:`joint_visible_fraction` for self-shadowing of non-convex models;
- :func:`validate` and :class:`ShapeError`;
- :class:`ShapeLibrary` / :func:`get_library` for the folder of named shapes;
- :func:`perturbed_model` (and its record :class:`Perturbation`): a "real object" drawn
  around a model, for validating inversions on truths that are not their model.

The names are loaded on first use (PEP 562 module ``__getattr__``): ``import shapes`` or a
light submodule such as :mod:`shapes.files` does not import trimesh, scipy.spatial or
networkx, which cost seconds at the start of a process.

Modules
-------
- :mod:`~shapes.appendage` — Appendages for facet models: an antenna or a thruster placed clear
  on a flat face.
- :mod:`~shapes.articulation` — Articulated shapes: named rigid parts on one-axis joints.
- :mod:`~shapes.compiled` — The compiled (render-ready) form of a facet model: coplanar facets
  merged by material.
- :mod:`~shapes.errors` — The exception raised for bad shape input (meshes, materials, library
  entries).
- :mod:`~shapes.files` — File helpers of every package: atomic writes, output folders, temporary
  names, checksums.
- :mod:`~shapes.io` — Reading and writing facet models: trimesh formats, the DAMIT shape format,
  grouped OBJ.
- :mod:`~shapes.mass` — Mass properties of triangle soups: uniform solids, thin shells,
  assemblies, principal axes.
- :mod:`~shapes.material` — Surface materials of facet groups, stored as plain BRDF
  specifications.
- :mod:`~shapes.model` — The facet model: a triangle mesh with named groups, materials and mass
  properties.
- :mod:`~shapes.perturbation` — Perturbed copies of a facet model: stretch, materials, mass
  distribution and an appendage drawn around it, with the true values recorded.
- :mod:`~shapes.preview` — PNG previews of facet models, coloured by material, seen from a
  chosen direction.
- :mod:`~shapes.primitives` — Primitive facet models with named groups and default materials
  (SI, metres).
- :mod:`~shapes.protocols` — The interfaces that facet models, their compiled form and
  visibility tables see of each other.
- :mod:`~shapes.validation` — Checks of facet models, each raising
  :class:`~shapes.errors.ShapeError` with a clear message.
- :mod:`~shapes.library` — The shape library: a folder of named mesh files with a JSON manifest,
  and the built-in one (package).
- :mod:`~shapes.visibility` — Self-shadowing of non-convex models: ray-cast fractions and
  precomputed bit-mask tables (package).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

#: Public name → the submodule defining it (``primitives`` is the submodule itself).
_SOURCES = {
    "DEFAULT_ANGLE_TOLERANCE": "shapes.compiled",
    "CompiledFacets": "shapes.compiled",
    "FacetModel": "shapes.model",
    "Material": "shapes.material",
    "Perturbation": "shapes.perturbation",
    "ShapeError": "shapes.errors",
    "ShapeLibrary": "shapes.library.core",
    "VisibilityTable": "shapes.visibility.table",
    "build_visibility_table": "shapes.visibility.build",
    "builtin_library_path": "shapes.library.core",
    "get_library": "shapes.library.core",
    "inertia_from_components": "shapes.model",
    "joint_visible_fraction": "shapes.visibility.sampling",
    "load": "shapes.io",
    "load_damit": "shapes.io",
    "perturbed_model": "shapes.perturbation",
    "primitives": "shapes.primitives",
    "validate": "shapes.validation",
    "visible_fraction": "shapes.visibility.sampling",
    "write_obj": "shapes.io",
}

__all__ = [
    "DEFAULT_ANGLE_TOLERANCE",
    "CompiledFacets",
    "FacetModel",
    "Material",
    "Perturbation",
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
    "perturbed_model",
    "primitives",
    "validate",
    "visible_fraction",
    "write_obj",
]


def __getattr__(name: str) -> Any:
    """Import the submodule that defines ``name`` on first access (PEP 562)."""
    source = _SOURCES.get(name)
    if source is None:
        raise AttributeError(f"module 'shapes' has no attribute {name!r}")
    module = importlib.import_module(source)
    value = module if name == "primitives" else getattr(module, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


if TYPE_CHECKING:  # static analysers and IDEs see the eager imports
    from shapes import primitives
    from shapes.compiled import DEFAULT_ANGLE_TOLERANCE, CompiledFacets
    from shapes.errors import ShapeError
    from shapes.io import load, load_damit, write_obj
    from shapes.library.core import ShapeLibrary, builtin_library_path, get_library
    from shapes.material import Material
    from shapes.model import FacetModel, inertia_from_components
    from shapes.perturbation import Perturbation, perturbed_model
    from shapes.validation import validate
    from shapes.visibility.build import build_visibility_table
    from shapes.visibility.sampling import joint_visible_fraction, visible_fraction
    from shapes.visibility.table import VisibilityTable
