"""Sample points of the shadowable facets and exact (ray-cast) visible and joint fractions.

:func:`facet_sampling` places the ray origins on every effective facet that can be shadowed;
:func:`visible_fraction` and :func:`joint_visible_fraction` cast rays from them for given
directions (the "exact" shadowing of the renderer), and the precomputed tables of
:mod:`shapes.visibility.table` store the same rays' outcomes on a grid of directions.

Sampling: each original triangle ``i`` of effective facet ``k`` is cut into ``m_i²`` equal
sub-triangles with ``m_i = max(1, round(√(samples · A_i / A_k)), ⌈√A_i / h⌉)`` and a ray
leaves from each sub-triangle centroid, lifted ``1e-4`` of the model size off the surface;
each point carries the area share ``(A_i / m_i²) / Σ`` of its effective facet. ``samples``
(default 16) sets the points per effective facet; the spacing ``h`` (default 1 % of the
model's bounding-box diagonal) keeps large flat facets of CAD models, which merge into few
effective facets, resolved: a shadow edge is then placed to about ``h`` on every facet,
whatever the tessellation. Every member triangle gets at least its centroid.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.sparse import csr_matrix

from shapes.compiled import CompiledFacets
from shapes.visibility.directions import CubeSphereGrid
from shapes.visibility.raycast import Occluder, facet_sample_points

if TYPE_CHECKING:
    from shapes.model import FacetModel

__all__ = [
    "DEFAULT_SAMPLES",
    "DEFAULT_SPACING",
    "FacetSampling",
    "facet_sampling",
    "joint_visible_fraction",
    "visible_fraction",
]

#: Target number of ray origins per effective facet.
DEFAULT_SAMPLES = 16
#: Largest sample spacing, fraction of the model's bounding-box diagonal (√ of the area one
#: point stands for).
DEFAULT_SPACING = 0.01
_RAY_LIFT = 1e-4  # origin offset along the normal, fraction of the model's bounding diagonal
_CHUNK_RAYS = 1 << 21
_WEIGHT_BITS = 30  # point weights are rounded to 30-bit mantissas, so equal areas group
_ORDER_RESOLUTION = 8  # grid of the storage order of facets (by normal)


@dataclass(frozen=True, eq=False, kw_only=True)
class FacetSampling:
    """Ray origins on the effective facets that can be shadowed.

    Attributes
    ----------
    facet : (P,) int
        Effective facet of each point. Points are grouped by facet, facets ordered by the
        direction of their normal (so that facets facing alike are stored together), and
        within a facet points of equal weight are adjacent.
    weight : (P,) float
        Share of its effective facet's area each point stands for (sums to 1 per facet).
    origins : (P, 3) float
        Points lifted off their triangle along its normal, m.
    normals : (P, 3) float
        Normal of each point's effective facet.
    n_facets : int
        Number of effective facets ``K``.
    samples : int
        Target number of points per effective facet.
    spacing : float
        Largest point spacing, fraction of the model's bounding-box diagonal (0: none).
    """

    facet: np.ndarray
    weight: np.ndarray
    origins: np.ndarray
    normals: np.ndarray
    n_facets: int
    samples: int
    spacing: float

    def __len__(self) -> int:
        return len(self.facet)

    @cached_property
    def _pooling(self) -> csr_matrix:
        """(K, P) sparse matrix of the point weights."""
        return csr_matrix(
            (self.weight, (self.facet, np.arange(len(self)))), shape=(self.n_facets, len(self))
        )

    def pool(self, values: np.ndarray) -> np.ndarray:
        """Area-weighted sums per facet of per-point ``values (D, P)`` → ``(D, K)``."""
        return np.asarray((self._pooling @ np.asarray(values, float).T).T)


def facet_sampling(
    compiled: CompiledFacets, samples: int, spacing: float = DEFAULT_SPACING
) -> FacetSampling:
    """Sample points of the shadowable effective facets (see the module docstring)."""
    if int(samples) != samples or int(samples) < 1:
        raise ValueError(f"samples must be a positive integer, got {samples!r}")
    if not spacing >= 0.0:
        raise ValueError(f"spacing must be ≥ 0, got {spacing!r}")
    samples, spacing = int(samples), float(spacing)
    cols = np.flatnonzero(compiled.can_be_shadowed)
    members = [compiled.members[k] for k in cols]
    member_facets = np.concatenate(members) if members else np.zeros(0, np.int64)
    member_col = cols[np.repeat(np.arange(len(cols)), [len(m) for m in members])]
    if len(member_facets) == 0:
        empty = np.zeros((0, 3))
        return FacetSampling(
            facet=np.zeros(0, np.int64),
            weight=np.zeros(0),
            origins=empty,
            normals=empty,
            n_facets=len(compiled),
            samples=samples,
            spacing=spacing,
        )
    tri = compiled.vertices[compiled.faces[member_facets]]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    share = area / compiled.areas[member_col]
    scale = float(np.linalg.norm(np.ptp(compiled.vertices, axis=0)))
    subdiv = np.rint(np.sqrt(samples * share))
    if spacing > 0.0:
        subdiv = np.maximum(subdiv, np.ceil(np.sqrt(area) / (spacing * scale)))
    subdiv = np.clip(subdiv, 1, 64).astype(np.int64)
    points, which, weight = facet_sample_points(tri, subdiv)
    unit_cross = cross / np.maximum(2.0 * area, 1e-300)[:, None]
    origins = points + _RAY_LIFT * scale * unit_cross[which]
    facet = member_col[which]
    mantissa, exponent = np.frexp(weight)
    weight = np.ldexp(np.round(mantissa * 2.0**_WEIGHT_BITS) / 2.0**_WEIGHT_BITS, exponent)
    # storage order: facets by the grid cell of their normal (facets facing alike together)
    index, weights = CubeSphereGrid(_ORDER_RESOLUTION).locate(compiled.normals)
    nearest = index[np.arange(len(index)), weights.argmax(axis=1)]
    rank = np.empty(len(nearest), np.int64)
    rank[np.argsort(nearest, kind="stable")] = np.arange(len(nearest))
    order = np.lexsort((np.arange(len(facet)), -weight, facet, rank[facet]))
    facet, weight, origins = facet[order], weight[order], origins[order]
    weight = weight / np.bincount(facet, weights=weight, minlength=len(compiled))[facet]
    return FacetSampling(
        facet=facet,
        weight=weight,
        origins=origins,
        normals=compiled.normals[facet],
        n_facets=len(compiled),
        samples=samples,
        spacing=spacing,
    )


class _Caster:
    """A model's sample points and ray caster, kept for repeated calls (renderer, tables)."""

    def __init__(
        self, compiled: CompiledFacets, samples: int, spacing: float, backend: str
    ) -> None:
        self.sampling = facet_sampling(compiled, samples, spacing)
        self.occluder = Occluder(compiled.vertices, compiled.faces, backend=backend)
        self.scene_origins = self.occluder.to_scene(self.sampling.origins)
        self.normals32 = self.sampling.normals.astype(np.float32)

    def chunk_rows(self) -> int:
        return max(1, _CHUNK_RAYS // max(1, len(self.sampling)))

    def visible(self, directions: np.ndarray, mirror: bool) -> np.ndarray:
        """``(D, P)`` bool: the ray from each point toward each direction escapes.

        ``mirror``: behind a point's facet the mirror direction is cast (table build);
        otherwise such points are not cast and give False.
        """
        d = directions.astype(np.float32)
        cos = d @ self.normals32.T
        if mirror:
            ray = d[:, None, :] - (2.0 * np.minimum(cos, 0.0))[..., None] * self.normals32
            origins = np.broadcast_to(self.scene_origins, ray.shape).reshape(-1, 3)
            return ~self.occluder.query(origins, ray.reshape(-1, 3)).reshape(cos.shape)
        return self.passing(d, cos > 0.0)

    def pooled(self, out: np.ndarray, escaping: Callable[[slice], np.ndarray]) -> np.ndarray:
        """Fill the shadowable columns of ``out (N, K)`` chunk by chunk with the area-weighted
        share of points whose rays escape, ``escaping(rows) → (len(rows), P) bool``; the
        other columns keep their front-facing 0/1."""
        sampling = self.sampling
        if len(sampling) == 0 or len(out) == 0:
            return out
        cols = np.unique(sampling.facet)
        step = self.chunk_rows()
        for start in range(0, len(out), step):
            rows = slice(start, start + step)
            out[rows, cols] = sampling.pool(escaping(rows))[:, cols]
        return np.round(out, 12)  # sums of weights: 1 - 1e-16 is 1

    def passing(self, d: np.ndarray, cast: np.ndarray) -> np.ndarray:
        """``(D, P)`` bool: ``cast`` and the ray from the point toward ``d`` escapes."""
        rows, points = np.nonzero(cast)
        out = np.zeros(cast.shape, dtype=bool)
        out[rows, points] = ~self.occluder.query(self.scene_origins[points], d[rows])
        return out


_CASTERS: weakref.WeakKeyDictionary[CompiledFacets, dict[tuple, _Caster]] = (
    weakref.WeakKeyDictionary()
)


def _caster(
    compiled: CompiledFacets, samples: int | None, spacing: float | None, backend: str
) -> _Caster:
    """The cached caster of ``compiled``; ``None`` sampling parameters default to those of
    the model's table when it has one (so that exact and table modes differ only by
    interpolation), else to :data:`DEFAULT_SAMPLES` and :data:`DEFAULT_SPACING`."""
    table = compiled.visibility
    if samples is None:
        samples = table.samples if table is not None else DEFAULT_SAMPLES
    if spacing is None:
        spacing = table.spacing if table is not None else DEFAULT_SPACING
    cache = _CASTERS.setdefault(compiled, {})
    key = (samples, spacing, backend)
    if key not in cache:
        cache[key] = _Caster(compiled, samples, spacing, backend)
    return cache[key]


def _compiled(model: FacetModel | CompiledFacets) -> CompiledFacets:
    return model if isinstance(model, CompiledFacets) else model.compiled()


def _unit_rows(directions: Any, name: str) -> np.ndarray:
    d = np.asarray(directions, float)
    if d.ndim != 2 or d.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {d.shape}")
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def visible_fraction(
    model: FacetModel | CompiledFacets,
    directions: np.ndarray,
    *,
    samples: int | None = None,
    spacing: float | None = None,
    backend: str = "auto",
) -> np.ndarray:
    """Ray-cast visible (or lit) fraction of each effective facet from each direction.

    Parameters
    ----------
    model : FacetModel or CompiledFacets
        Its compiled facets are used.
    directions : (D, 3) float
        Body-frame directions toward the observer (or the Sun).
    samples : int, optional
        Target ray origins per effective facet (same scheme as the tables). Default: the
        sampling of the model's visibility table when it has one (so that table and exact
        modes differ only by interpolation), else :data:`DEFAULT_SAMPLES`.
    spacing : float, optional
        Largest sample spacing, fraction of the bounding-box diagonal (0: none). Default:
        the table's, else :data:`DEFAULT_SPACING`.
    backend : {"auto", "embree", "trimesh"}
        Ray caster (see :class:`~shapes.visibility.raycast.Occluder`).

    Returns
    -------
    (D, K) float
        In [0, 1]; 0 for facets facing away from the direction.
    """
    compiled = _compiled(model)
    d = _unit_rows(directions, "directions")
    out = (d @ compiled.normals.T > 0.0).astype(float)
    caster = _caster(compiled, samples, spacing, backend)
    return caster.pooled(out, lambda rows: caster.visible(d[rows], mirror=False))


def joint_visible_fraction(
    model: FacetModel | CompiledFacets,
    light: np.ndarray,
    view: np.ndarray,
    *,
    samples: int | None = None,
    spacing: float | None = None,
    backend: str = "auto",
) -> np.ndarray:
    """Ray-cast fraction of each effective facet that is both lit and seen.

    For every sample point of a facet facing both directions, the ray toward the Sun and
    (where that one escapes) the ray toward the observer are cast; the fraction is the
    area-weighted share of points whose two rays both escape.

    Parameters
    ----------
    model : FacetModel or CompiledFacets
        Its compiled facets are used.
    light, view : (N, 3) float
        Body-frame directions to the Sun and to the observer (row by row).
    samples, spacing, backend :
        As :func:`visible_fraction`.

    Returns
    -------
    (N, K) float
        In [0, 1]; 0 for facets facing away from ``L`` or ``V``. Symmetric in ``L`` and
        ``V``.
    """
    compiled = _compiled(model)
    lights, views = _unit_rows(light, "light"), _unit_rows(view, "view")
    if len(lights) != len(views):
        raise ValueError(f"light and view differ in length: {len(lights)} and {len(views)}")
    out = ((lights @ compiled.normals.T > 0.0) & (views @ compiled.normals.T > 0.0)).astype(float)
    caster = _caster(compiled, samples, spacing, backend)

    def both(rows: slice) -> np.ndarray:
        el = lights[rows].astype(np.float32)
        ev = views[rows].astype(np.float32)
        facing = (el @ caster.normals32.T > 0.0) & (ev @ caster.normals32.T > 0.0)
        return caster.passing(ev, caster.passing(el, facing))

    return caster.pooled(out, both)
