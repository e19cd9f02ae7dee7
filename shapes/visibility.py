"""Self-shadowing of non-convex models: ray-cast fractions and precomputed bit-mask tables.

The light that reaches the observer from a facet comes from the part of it that is both
lit (the ray toward the Sun ``L`` escapes the body) and seen (the ray toward the observer
``V`` escapes). :func:`joint_visible_fraction` computes that *joint* fraction by ray casting
both rays from every sample point of a facet; :func:`visible_fraction` the fraction for one
direction. :class:`VisibilityTable` stores, for a :class:`~shapes.directions.CubeSphereGrid`
of body-frame directions, one bit per sample point (does the ray toward that direction
escape?), and gives both fractions for any directions by interpolating every point's bits
over the grid nodes around ``L`` and around ``V`` (:mod:`shapes.joint_visibility`).

Why joint and not ``lit · seen``: at low phase angles the lit and the seen parts are nearly
the same area, so the product of the two fractions counts the shadow twice (a facet half in
shadow reflects half of its light, not a quarter). Per sample point the joint test is exact,
and it keeps merged facets exact too: compiled facets merge every facet with the same normal
and material, even on different planes, and since the flux of the merged facet is
``ρ (n·L)(n·V) Σ_i A_i J_i``, the area-weighted mean of the members' joint fractions (which
is what the weighted sample points give) is exactly right, however differently the members
are shadowed.

Sampling: each original triangle ``i`` of effective facet ``k`` is cut into ``m_i²`` equal
sub-triangles with ``m_i = max(1, round(√(samples · A_i / A_k)), ⌈√A_i / h⌉)`` and a ray
leaves from each sub-triangle centroid, lifted ``1e-4`` of the model size off the surface;
each point carries the area share ``(A_i / m_i²) / Σ`` of its effective facet. ``samples``
(default 16) sets the points per effective facet; the spacing ``h`` (default 1 % of the
model's bounding-box diagonal) keeps large flat facets of CAD models, which merge into few
effective facets, resolved: a shadow edge is then placed to about ``h`` on every facet,
whatever the tessellation. Every member triangle gets at least its centroid.

Horizon continuation: for a direction behind facet ``k`` (``n_k·d ≤ 0``) the table stores
the bits of the mirror direction ``d − 2 (n_k·d) n_k``, which are continuous across the
facet's horizon; interpolating just above the horizon then blends values of the same shadow
geometry instead of zeros. The table must therefore always be used together with the
front-facing factors ``max(0, n·L) max(0, n·V)`` the flux carries anyway
(:meth:`VisibilityTable.joint` applies them unless told not to).
"""

from __future__ import annotations

import os
import weakref
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
from array_api_compat import array_namespace
from scipy.sparse import csr_matrix

from shapes.compiled import CompiledFacets
from shapes.directions import CubeSphereGrid
from shapes.errors import ShapeError
from shapes.files import atomic_write
from shapes.raycast import Occluder, facet_sample_points

if TYPE_CHECKING:
    from shapes.model import FacetModel

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

#: Cube-sphere resolution of tables: 6·26² + 2 = 4058 directions, ~3.5° apart.
DEFAULT_RESOLUTION = 26
#: Target number of ray origins per effective facet.
DEFAULT_SAMPLES = 16
#: Largest sample spacing, fraction of the model's bounding-box diagonal (√ of the area one
#: point stands for).
DEFAULT_SPACING = 0.01
#: Version of the table files written by :meth:`VisibilityTable.save`. Version 1 stored one
#: visible fraction per facet and direction (no joint fractions); it is refused.
FORMAT_VERSION = 2
_RAY_LIFT = 1e-4  # origin offset along the normal, fraction of the model's bounding diagonal
_CHUNK_RAYS = 1 << 21
_WEIGHT_BITS = 30  # point weights are rounded to 30-bit mantissas, so equal areas group
_ORDER_RESOLUTION = 8  # grid of the storage order of facets (by normal)
_SEGMENT_FIELDS = ("segment_facet", "segment_word", "segment_shift", "segment_length")


class TableFormatError(ShapeError):
    """A visibility-table file of another format version (rebuild the table)."""


# ----------------------------------------------------------------------------- sampling
@dataclass(frozen=True, eq=False)
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
            np.zeros(0, np.int64), np.zeros(0), empty, empty, len(compiled), samples, spacing
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
        facet, weight, origins, compiled.normals[facet], len(compiled), samples, spacing
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
        Ray caster (see :class:`~shapes.raycast.Occluder`).

    Returns
    -------
    (D, K) float
        In [0, 1]; 0 for facets facing away from the direction.
    """
    compiled = _compiled(model)
    d = _unit_rows(directions, "directions")
    out = (d @ compiled.normals.T > 0.0).astype(float)
    caster = _caster(compiled, samples, spacing, backend)
    sampling = caster.sampling
    if len(sampling) == 0 or len(d) == 0:
        return out
    cols = np.unique(sampling.facet)
    step = caster.chunk_rows()
    for start in range(0, len(d), step):
        rows = slice(start, start + step)
        out[rows, cols] = sampling.pool(caster.visible(d[rows], mirror=False))[:, cols]
    return np.round(out, 12)  # sums of weights: 1 - 1e-16 is 1


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
    sampling = caster.sampling
    if len(sampling) == 0 or len(lights) == 0:
        return out
    cols = np.unique(sampling.facet)
    step = caster.chunk_rows()
    for start in range(0, len(lights), step):
        rows = slice(start, start + step)
        el = lights[rows].astype(np.float32)
        ev = views[rows].astype(np.float32)
        facing = (el @ caster.normals32.T > 0.0) & (ev @ caster.normals32.T > 0.0)
        both = caster.passing(ev, caster.passing(el, facing))
        out[rows, cols] = sampling.pool(both)[:, cols]
    return np.round(out, 12)


# ------------------------------------------------------------------------------- tables
class VisibilityTable:
    """Per-point visibility bits of effective facets on a grid of body-frame directions.

    Parameters
    ----------
    bits : (D, W) uint64
        Row ``d``: the bits of every sample point (1: the ray toward grid direction ``d``
        escapes the body; mirror-continued behind the facet, see the module docstring),
        packed by ``layout``.
    layout : mapping
        ``segment_facet``, ``segment_word``, ``segment_shift``, ``segment_length`` (int) and
        ``segment_weight`` (float: area share of one point) of the segments
        (:func:`shapes.joint_visibility.segment_layout`). Facets without segments are never
        shadowed.
    resolution : int
        Cube-sphere resolution ``n`` (``D = 6 n² + 2``).
    structure : str
        :attr:`CompiledFacets.structure` of the facets the table was built for.
    areas : (K,) float
        Their areas, m² (checked when attaching).
    normals : (K, 3) float
        Their normals in the grid frame.
    samples : int
        Target ray origins per effective facet used to build it.
    spacing : float
        Largest sample spacing used to build it, fraction of the bounding-box diagonal.
    rotation : (3, 3) float, optional
        Grid frame → body frame (identity unless the model was rotated after the build).

    Attributes
    ----------
    directions : (D, 3) float
        Grid directions in the body frame.
    fraction : (D, K) float32
        Visible fraction of each facet from each grid direction (computed on first use).
    """

    def __init__(
        self,
        bits: np.ndarray,
        layout: dict[str, np.ndarray],
        resolution: int,
        structure: str,
        areas: np.ndarray,
        normals: np.ndarray,
        samples: int,
        spacing: float,
        rotation: np.ndarray | None = None,
    ) -> None:
        self.grid = CubeSphereGrid(resolution)
        self.resolution = int(resolution)
        self.structure = str(structure)
        self.areas = np.asarray(areas, float)
        self.normals = np.asarray(normals, float).reshape(-1, 3)
        self.samples = int(samples)
        self.spacing = float(spacing)
        self.rotation = np.eye(3) if rotation is None else np.asarray(rotation, float)
        self.bits = np.ascontiguousarray(bits, dtype=np.uint64)
        self.layout = {key: np.asarray(layout[key], np.int64) for key in _SEGMENT_FIELDS}
        self.layout["segment_weight"] = np.asarray(layout["segment_weight"], np.float64)
        self._check()
        self._lookups: dict[bytes, dict[str, np.ndarray]] = {}
        self._cache: dict[Any, Any] = {}

    def _check(self) -> None:
        """Raise :class:`ShapeError` unless the arrays describe a consistent table."""
        k, lay = len(self.areas), self.layout
        facet, word = lay["segment_facet"], lay["segment_word"]
        shift, length = lay["segment_shift"], lay["segment_length"]
        weight = lay["segment_weight"]
        problems = []
        if self.bits.ndim != 2 or self.bits.shape[0] != len(self.grid):
            problems.append(f"bits must be ({len(self.grid)}, W), got {self.bits.shape}")
        if self.normals.shape != (k, 3):
            problems.append(f"normals must be ({k}, 3), got {self.normals.shape}")
        if len({len(a) for a in (facet, word, shift, length, weight)}) != 1:
            problems.append("segment arrays differ in length")
        elif len(facet):
            if facet.min() < 0 or facet.max() >= k:
                problems.append("segment facets out of range")
            if word.min() < 0 or word.max() >= self.bits.shape[1]:
                problems.append("segment words out of range")
            if length.min() < 1 or shift.min() < 0 or np.max(shift + length) > 64:
                problems.append("segments must lie inside one 64-bit word")
            total = np.bincount(facet, weights=weight * length, minlength=k)
            if not np.allclose(total[np.unique(facet)], 1.0, rtol=0.0, atol=1e-6):
                problems.append("point weights do not sum to 1 per facet")
        if problems:
            raise ShapeError(f"inconsistent visibility table: {'; '.join(problems)}")

    # ------------------------------------------------------------------ properties
    @property
    def directions(self) -> np.ndarray:
        return self.grid.directions @ self.rotation.T

    @property
    def n_facets(self) -> int:
        return len(self.areas)

    @property
    def n_points(self) -> int:
        """Sample points stored per direction."""
        return int(self.layout["segment_length"].sum())

    @property
    def nbytes(self) -> int:
        """Memory of the table's arrays in the renderer's use (bits, flags, segments), bytes."""
        lookup = self._lookup(None)
        return int(self.bits.nbytes + sum(a.nbytes for a in lookup.values()))

    @property
    def fraction(self) -> np.ndarray:
        """(D, K) float32 visible fraction of every facet from every grid direction."""
        if "fraction" not in self._cache:
            lookup = self._lookup(None)
            out = np.empty((len(self.grid), self.n_facets))
            _kernels().direction_fractions(
                self.bits,
                lookup["segment_start"],
                lookup["segment_word"],
                lookup["segment_mask"],
                lookup["segment_weight"],
                out,
            )
            self._cache["fraction"] = np.round(out, 12).astype(np.float32)
        return self._cache["fraction"]

    def rotated(self, rotation: np.ndarray) -> VisibilityTable:
        """The same table for a body frame rotated by ``rotation`` (``v_new = R v_old``)."""
        return VisibilityTable(
            self.bits,
            self.layout,
            self.resolution,
            self.structure,
            self.areas,
            self.normals,
            self.samples,
            self.spacing,
            np.asarray(rotation, float) @ self.rotation,
        )

    def check_fits(self, compiled: CompiledFacets) -> None:
        """Raise :class:`ShapeError` unless the table was built for these effective facets."""
        if (
            self.n_facets != len(compiled)
            or self.structure != compiled.structure
            or not np.allclose(self.areas, compiled.areas, rtol=1e-6, atol=0.0)
            or not np.allclose(self.normals @ self.rotation.T, compiled.normals, atol=1e-6)
        ):
            raise ShapeError(
                f"visibility table ({self.n_facets} facets) was built for another mesh than "
                f"this one ({len(compiled)} effective facets); rebuild it"
            )

    # ------------------------------------------------------------------ lookups
    def _lookup(self, order: np.ndarray | None) -> dict[str, np.ndarray]:
        """The kernels' arrays with output column ``j`` = facet ``order[j]`` (None: the
        table's own order; a facet may fill several columns or none; -1: a column whose
        value is left unspecified), cached."""
        key = b"" if order is None else np.asarray(order, np.int64).tobytes()
        if key not in self._lookups:
            order = np.arange(self.n_facets) if order is None else np.asarray(order, np.int64)
            if order.ndim != 1 or np.any((order < -1) | (order >= self.n_facets)):
                raise ValueError(f"order must list facet indices below {self.n_facets} or -1")
            k = len(order)
            unused = order < 0
            lay = self.layout
            by_facet = np.argsort(lay["segment_facet"], kind="stable")
            count = np.bincount(lay["segment_facet"], minlength=self.n_facets)
            start = np.concatenate([[0], np.cumsum(count)])
            count = np.where(unused, 0, count[order])
            first = np.repeat(start[order], count)
            step = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
            segments = by_facet[first + step]
            mask = self._segment_masks()
            lookup = {
                "segment_start": np.concatenate([[0], np.cumsum(count)]).astype(np.int64),
                "segment_word": np.ascontiguousarray(lay["segment_word"][segments]),
                "segment_mask": np.ascontiguousarray(mask[segments], dtype=np.uint64),
                "segment_weight": np.ascontiguousarray(lay["segment_weight"][segments]),
                # an unused column faces nowhere: never looked up
                "normals": np.ascontiguousarray(np.where(unused, 0.0, self.normals[order].T)),
                "flat_index": self.grid.node_index.reshape(-1).astype(np.int64),
                "rotation": np.ascontiguousarray(self.rotation),
            }
            full = np.empty((len(self.grid), -(-k // 64)), dtype=np.uint64)
            hidden = np.empty_like(full)
            _kernels().full_flags(
                self.bits,
                lookup["segment_start"],
                lookup["segment_word"],
                lookup["segment_mask"],
                full,
                hidden,
            )
            lookup["full"] = full
            front = np.zeros((len(self.grid), 64 * full.shape[1]), dtype=bool)
            front[:, :k] = self.grid.directions @ lookup["normals"] > 0.0
            front = _bit_rows(front)
            corners = self._cell_corners()
            lookup["cell_partial"] = ~np.bitwise_and.reduce(full[corners], axis=1)
            lookup["cell_front"] = np.bitwise_or.reduce(front[corners], axis=1)
            lookup["cell_hidden"] = np.bitwise_and.reduce(hidden[corners], axis=1)
            lookup.update(self._sparse_rows())
            self._lookups[key] = lookup
        return self._lookups[key]

    def _segment_masks(self) -> np.ndarray:
        """(S,) uint64 bits of each segment within its word."""
        length = self.layout["segment_length"].astype(np.uint64)
        ones = np.where(
            length == 64, np.uint64(2**64 - 1), (np.uint64(1) << (length % np.uint64(64))) - 1
        )
        return ones.astype(np.uint64) << self.layout["segment_shift"].astype(np.uint64)

    def _cell_corners(self) -> np.ndarray:
        """(cells, 3) corner nodes of the grid's triangles, in the kernels' cell order."""
        ni = self.grid.node_index
        lower = np.stack([ni[:, :-1, :-1], ni[:, 1:, :-1], ni[:, :-1, 1:]], axis=-1)
        upper = np.stack([ni[:, 1:, 1:], ni[:, 1:, :-1], ni[:, :-1, 1:]], axis=-1)
        return np.stack([lower, upper], axis=3).reshape(-1, 3)

    def _sparse_rows(self) -> dict[str, np.ndarray]:
        """The bit rows without their all-ones words (cached): ``row_words`` flags the
        stored words of each row, ``row_rank`` indexes ``compact`` per 64-word chunk.

        The lookups of a row then touch a few cache lines instead of a whole row."""
        if "sparse" not in self._cache:
            d, w = self.bits.shape
            used = np.zeros(w, np.uint64)
            np.bitwise_or.at(used, self.layout["segment_word"], self._segment_masks())
            stored = np.zeros((d, 64 * -(-w // 64)), dtype=bool)
            stored[:, :w] = (self.bits & used) != used
            per_chunk = stored.reshape(d, -1, 64).sum(axis=2).reshape(-1)
            rank = (np.cumsum(per_chunk) - per_chunk).reshape(d, -1)
            self._cache["sparse"] = {
                "row_words": _bit_rows(stored),
                "row_rank": rank.astype(np.int64),
                "compact": np.append(self.bits[stored[:, :w]], np.uint64(2**64 - 1)),
            }
        return self._cache["sparse"]

    def interpolate(self, directions: Any) -> Any:
        """Visible fractions of all effective facets for arbitrary body-frame directions.

        Parameters
        ----------
        directions : (..., 3) float array or torch.Tensor
            Body-frame directions (non-zero; need not be unit).

        Returns
        -------
        (..., K) array of the input's kind, dtype (float32/float64) and device.
            Barycentric blend of the three grid nodes around each direction. Multiply by the
            front-facing factor ``max(0, n·d)`` (behind a facet the table holds the mirror
            continuation, not 0). For the lit-and-seen fraction use :meth:`joint`, not the
            product of two of these.
        """
        d = _as_float_array(directions)
        if not np.array_equal(self.rotation, np.eye(3)):
            d = d @ self._as_kind(self.rotation, d)
        xp = array_namespace(d)
        index, weights = self.grid.locate(xp.reshape(d, (-1, 3)))
        table = self._as_kind(self.fraction, d)
        out = xp.take(table, index[:, 0], axis=0) * weights[:, 0:1]
        for k in (1, 2):  # take = torch.index_select: 4× faster than fancy indexing
            out += xp.take(table, index[:, k], axis=0) * weights[:, k : k + 1]
        return xp.reshape(out, (*d.shape[:-1], self.n_facets))

    def joint(
        self,
        light: Any,
        view: Any,
        *,
        order: np.ndarray | None = None,
        facing: bool = True,
        out: np.ndarray | None = None,
    ) -> Any:
        """Fraction of every effective facet that is both lit and seen.

        Every sample point's bits are interpolated over the three grid nodes around ``L``
        and the three around ``V``, and the products are summed with the points' area
        shares (:mod:`shapes.joint_visibility`). At grid nodes this is the exact joint
        fraction of the sample points; it is symmetric in ``L`` and ``V``.

        Parameters
        ----------
        light, view : (..., 3) float arrays or torch.Tensors
            Body-frame directions to the Sun and the observer (non-zero, need not be unit;
            same shape).
        order : (C,) int, optional
            Facet of each output column (default: the compiled facets' order, ``C = K``);
            a facet may fill several columns, and a column of -1 gets an unspecified value
            without any work (a renderer's zero-area padding slots).
        facing : bool
            True: facets turned away from ``L`` or ``V`` give 0. False: their value is
            unspecified (for callers that multiply by ``max(0, n·L) max(0, n·V)``), which
            saves work.
        out : (N, C) numpy array, optional
            Output for numpy inputs of shape (N, 3) (float32 or float64; by default the
            dtype of the inputs).

        Returns
        -------
        (..., C) array of the input's kind, dtype (float32/float64) and device.
            numpy inputs run a compiled kernel; torch inputs are differentiable through the
            barycentric weights (the bits are constants).
        """
        lookup = self._lookup(order)
        if _is_tensor(light) or _is_tensor(view):
            return self._joint_torch(light, view, lookup, facing)
        light, view = _as_float_array(light), _as_float_array(view)
        if light.shape != view.shape or light.shape[-1:] != (3,):
            raise ValueError(
                f"light and view must have the same shape (..., 3), got {light.shape} and "
                f"{view.shape}"
            )
        dtype = np.result_type(light, view)
        columns = lookup["normals"].shape[1]
        rows_l = np.ascontiguousarray(light.reshape(-1, 3))
        rows_v = np.ascontiguousarray(view.reshape(-1, 3))
        result = np.empty((len(rows_l), columns), dtype) if out is None else out
        if result.shape != (len(rows_l), columns):
            raise ValueError(f"out must have shape {(len(rows_l), columns)}")
        _kernels().joint_rows(
            rows_l,
            rows_v,
            lookup["rotation"],
            self.resolution,
            lookup["flat_index"],
            lookup["row_words"],
            lookup["row_rank"],
            lookup["compact"],
            lookup["cell_partial"],
            lookup["cell_front"],
            lookup["cell_hidden"],
            lookup["normals"],
            lookup["segment_start"],
            lookup["segment_word"],
            lookup["segment_mask"],
            lookup["segment_weight"],
            facing,
            result,
        )
        return result.reshape((*light.shape[:-1], columns))

    def _joint_torch(self, light: Any, view: Any, lookup: dict[str, np.ndarray], facing: bool):
        import torch

        like = light if _is_tensor(light) else view
        light, view = (
            torch.as_tensor(v, dtype=like.dtype, device=like.device) for v in (light, view)
        )
        shape = light.shape[:-1]
        rotation = self._as_kind(self.rotation, light)
        rows_l = light.reshape(-1, 3) @ rotation
        rows_v = view.reshape(-1, 3) @ rotation
        index_l, weight_l = self.grid.locate(rows_l)
        index_v, weight_v = self.grid.locate(rows_v)
        columns = lookup["normals"].shape[1]
        pairs = np.empty((len(rows_l), 3, 3, columns))
        _kernels().pair_values(
            index_l.cpu().numpy().astype(np.int64),
            index_v.cpu().numpy().astype(np.int64),
            self.bits,
            lookup["full"],
            lookup["segment_start"],
            lookup["segment_word"],
            lookup["segment_mask"],
            lookup["segment_weight"],
            pairs,
        )
        pairs_t = torch.as_tensor(pairs, dtype=like.dtype, device=like.device)
        result = torch.einsum("ra,rb,rabk->rk", weight_l, weight_v, pairs_t)
        if facing:
            normals = self._as_kind(lookup["normals"], light)
            result = result * ((rows_l @ normals > 0) & (rows_v @ normals > 0)).to(result.dtype)
        return result.reshape(*shape, columns)

    def _as_kind(self, array: np.ndarray, like: Any) -> Any:
        """``array`` converted to the kind, dtype and device of ``like`` (cached)."""
        key = (id(array), str(like.dtype), str(getattr(like, "device", "numpy")))
        if key not in self._cache:
            if isinstance(like, np.ndarray):
                self._cache[key] = array.astype(like.dtype)
            else:
                import torch

                self._cache[key] = torch.as_tensor(array, dtype=like.dtype, device=like.device)
        return self._cache[key]

    # ------------------------------------------------------------------ files
    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the table atomically as a compressed ``.npz`` (format :data:`FORMAT_VERSION`).

        The bits are stored direction-major per word (``bits.T``), which keeps neighbouring
        directions' words together and compresses best.
        """
        lay = self.layout
        with atomic_write(path, "wb") as handle:
            np.savez_compressed(
                handle,
                format_version=np.int64(FORMAT_VERSION),
                resolution=np.int64(self.resolution),
                structure=np.str_(self.structure),
                areas=self.areas,
                normals=self.normals,
                samples=np.int64(self.samples),
                spacing=np.float64(self.spacing),
                rotation=self.rotation,
                bits_by_word=np.ascontiguousarray(self.bits.T).astype("<u8"),
                segment_facet=lay["segment_facet"].astype(np.int32),
                segment_word=lay["segment_word"].astype(np.int32),
                segment_shift=lay["segment_shift"].astype(np.uint8),
                segment_length=lay["segment_length"].astype(np.uint8),
                segment_weight=lay["segment_weight"],
            )

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> VisibilityTable:
        """Read a table written by :meth:`save`.

        Raises
        ------
        TableFormatError
            The file has another format version (e.g. version 1, written before the tables
            held per-point bits): it must be rebuilt.
        ShapeError
            The file is not a readable table.
        """
        try:
            with np.load(path, allow_pickle=False) as data:
                version = int(data["format_version"])
                if version != FORMAT_VERSION:
                    raise TableFormatError(
                        f"{path}: visibility-table format version {version}, this version of "
                        f"the toolkit reads version {FORMAT_VERSION} (per-point bits for the "
                        "joint lit-and-seen fraction); rebuild the table"
                    )
                layout = {key: data[key] for key in (*_SEGMENT_FIELDS, "segment_weight")}
                return cls(
                    np.asarray(data["bits_by_word"], dtype=np.uint64).T,
                    layout,
                    int(data["resolution"]),
                    str(data["structure"]),
                    data["areas"],
                    data["normals"],
                    int(data["samples"]),
                    float(data["spacing"]),
                    data["rotation"],
                )
        except TableFormatError:
            raise
        except ShapeError as exc:
            raise ShapeError(f"{path}: {exc}") from None
        except (OSError, KeyError, ValueError, IndexError, TypeError) as exc:
            raise ShapeError(f"{path}: not a readable visibility table ({exc})") from None


def build_visibility_table(
    model: FacetModel | CompiledFacets,
    *,
    resolution: int = DEFAULT_RESOLUTION,
    samples: int = DEFAULT_SAMPLES,
    spacing: float = DEFAULT_SPACING,
    backend: str = "auto",
    progress: bool = False,
) -> VisibilityTable:
    """Ray-cast the visibility table of a model's effective facets.

    Parameters
    ----------
    model : FacetModel or CompiledFacets
    resolution : int
        Cube-sphere resolution (``6 n² + 2`` directions).
    samples : int
        Target ray origins per effective facet.
    spacing : float
        Largest sample spacing, fraction of the bounding-box diagonal (0: none).
    backend : {"auto", "embree", "trimesh"}
    progress : bool
        Show a tqdm progress bar.

    Returns
    -------
    VisibilityTable
        Cost: ``(6 n² + 2) × points`` rays (points ≈ ``samples × K_shadowable``); 4058
        directions × 16 samples × 672 facets (Itokawa) take about 30 s with Embree on one
        loaded core. Memory: one bit per direction and point.
    """
    compiled = _compiled(model)
    grid = CubeSphereGrid(resolution)
    caster = _caster(compiled, int(samples), float(spacing), backend)
    sampling = caster.sampling
    layout, position = _kernels().segment_layout(sampling.facet, sampling.weight, len(compiled))
    n_words = int(layout.pop("n_words"))
    bits = np.empty((len(grid), n_words), dtype=np.uint64)
    step = caster.chunk_rows()
    starts = range(0, len(grid), step)
    if progress:
        from tqdm import tqdm

        starts = tqdm(starts, desc="visibility", unit="chunk", leave=False)
    for start in starts:
        visible = caster.visible(grid.directions[start : start + step], mirror=True)
        stream = np.zeros((len(visible), 64 * n_words), dtype=bool)
        stream[:, position] = visible
        packed = np.packbits(stream, axis=1, bitorder="little")
        bits[start : start + step] = packed.view("<u8").astype(np.uint64, copy=False)
    return VisibilityTable(
        bits,
        layout,
        resolution,
        compiled.structure,
        compiled.areas,
        compiled.normals,
        sampling.samples,
        sampling.spacing,
    )


def _bit_rows(flags: np.ndarray) -> np.ndarray:
    """(N, 64 C) bool → (N, C) uint64, flag ``j`` as bit ``j % 64`` of word ``j // 64``."""
    return np.packbits(flags, axis=1, bitorder="little").view("<u8").astype(np.uint64)


def _kernels() -> Any:
    """:mod:`shapes.joint_visibility`, imported on first use (numba is not needed to load
    shapes or read their tables)."""
    from shapes import joint_visibility

    return joint_visibility


def _as_float_array(value: Any) -> Any:
    """``value`` as a float32/float64 numpy array, or the torch tensor itself."""
    if _is_tensor(value):
        return value
    d = np.asarray(value)
    return d if d.dtype in (np.float32, np.float64) else d.astype(np.float64)


def _is_tensor(value: Any) -> bool:
    import sys

    torch = sys.modules.get("torch")
    return torch is not None and isinstance(value, torch.Tensor)
