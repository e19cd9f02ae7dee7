"""Self-shadowing of non-convex models: ray-cast fractions and precomputed bit-mask tables.

The light that reaches the observer from a facet comes from the part of it that is both
lit (the ray toward the Sun ``L`` escapes the body) and seen (the ray toward the observer
``V`` escapes). :func:`joint_visible_fraction` computes that *joint* fraction by ray casting
both rays from every sample point of a facet; :func:`visible_fraction` the fraction for one
direction. :class:`VisibilityTable` stores, for a
:class:`~shapes.visibility.directions.CubeSphereGrid` of body-frame directions, one bit per sample
point (does the ray toward that direction escape?), and gives both fractions for any directions by
interpolating every point's bits over the grid nodes around ``L`` and around ``V``
(:mod:`shapes.visibility.kernels`); :func:`build_visibility_table` ray-casts it.

Why joint and not ``lit · seen``: at low phase angles the lit and the seen parts are nearly
the same area, so the product of the two fractions counts the shadow twice (a facet half in
shadow reflects half of its light, not a quarter). Per sample point the joint test is exact,
and it keeps merged facets exact too: compiled facets merge every facet with the same normal
and material, even on different planes, and since the flux of the merged facet is
``ρ (n·L)(n·V) Σ_i A_i J_i``, the area-weighted mean of the members' joint fractions (which
is what the weighted sample points give) is exactly right, however differently the members
are shadowed.

Modules
-------
- :mod:`~shapes.visibility.directions` — the quasi-uniform cube-sphere grid of directions with
  fast barycentric lookup.
- :mod:`~shapes.visibility.raycast` — occlusion ray casting against a mesh (Embree through
  trimesh when available), stratified sample points on facets.
- :mod:`~shapes.visibility.sampling` — sample points of the shadowable facets and the exact
  ray-cast fractions :func:`visible_fraction`, :func:`joint_visible_fraction`.
- :mod:`~shapes.visibility.table` — :class:`VisibilityTable`: the bits, the ``.npz`` format,
  the interpolated lookups.
- :mod:`~shapes.visibility.kernels` — the tables' compiled (numba) bit-mask kernels.
- :mod:`~shapes.visibility.cells` — packed per-facet flags of the grid (facing, partly
  shadowed around a cell).
- :mod:`~shapes.visibility.build` — :func:`build_visibility_table`, the coarse-to-fine ray
  casting of a table on a pool of threads; :mod:`~shapes.visibility.build_kernels`, its
  compiled kernels.
- :mod:`~shapes.visibility.posed` — shadows of articulated shapes, ray-cast against the parts
  in their per-epoch pose.

This ``__init__`` only hands the public names on.
"""

from shapes.visibility.build import build_visibility_table
from shapes.visibility.sampling import (
    DEFAULT_SAMPLES,
    DEFAULT_SPACING,
    FacetSampling,
    facet_sampling,
    joint_visible_fraction,
    visible_fraction,
)
from shapes.visibility.table import (
    DEFAULT_RESOLUTION,
    FORMAT_VERSION,
    TableFormatError,
    VisibilityTable,
)

__all__ = [
    "DEFAULT_RESOLUTION",
    "DEFAULT_SAMPLES",
    "DEFAULT_SPACING",
    "FORMAT_VERSION",
    "FacetSampling",
    "TableFormatError",
    "VisibilityTable",
    "build_visibility_table",
    "facet_sampling",
    "joint_visible_fraction",
    "visible_fraction",
]
