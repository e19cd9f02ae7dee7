"""Precomputed visibility tables: per-point visibility bits of effective facets on a grid of
body-frame directions, their files and their lookups.

:class:`VisibilityTable` stores, for a :class:`~shapes.visibility.directions.CubeSphereGrid` of
body-frame directions, one bit per sample point of :func:`shapes.visibility.sampling.facet_sampling`
(does the ray toward that direction escape?), and gives the visible and the joint
lit-and-seen fractions for any directions by interpolating every point's bits over the grid
nodes around ``L`` and around ``V`` (compiled kernels of :mod:`shapes.visibility.kernels`).
Tables are built by :func:`shapes.visibility.build_visibility_table`.

Horizon continuation: for a direction behind facet ``k`` (``n_k·d ≤ 0``) the table stores
the bits of the mirror direction ``d − 2 (n_k·d) n_k``, which are continuous across the
facet's horizon; interpolating just above the horizon then blends values of the same shadow
geometry instead of zeros. The table must therefore always be used together with the
front-facing factors ``max(0, n·L) max(0, n·V)`` the flux carries anyway
(:meth:`VisibilityTable.joint` applies them unless told not to).
"""

from __future__ import annotations

import os
import threading
from typing import Any

import numpy as np
from array_api_compat import array_namespace

from shapes.compiled import CompiledFacets
from shapes.errors import ShapeError
from shapes.files import write_npz
from shapes.visibility.cells import cell_entries
from shapes.visibility.directions import CubeSphereGrid

__all__ = ["DEFAULT_RESOLUTION", "FORMAT_VERSION", "TableFormatError", "VisibilityTable"]

#: Cube-sphere resolution of tables: 6·26² + 2 = 4058 directions, ~3.5° apart.
DEFAULT_RESOLUTION = 26
#: Version of the table files written by :meth:`VisibilityTable.save`. Version 1 stored one
#: visible fraction per facet and direction (no joint fractions); it is refused.
FORMAT_VERSION = 2
_FLOATS = (np.dtype(np.float32), np.dtype(np.float64))
_BUILD_LOCK = threading.Lock()
_SEGMENT_FIELDS = ("segment_facet", "segment_word", "segment_shift", "segment_length")


class TableFormatError(ShapeError):
    """A visibility-table file of another format version (rebuild the table)."""


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
        (:func:`shapes.visibility.kernels.segment_layout`). Facets without segments are never
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
        *,
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
        self._frozen: dict[int, tuple[np.ndarray, dict[str, np.ndarray]]] = {}
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
        """Memory of the table's arrays for lookups (bits, per-cell entries, segments), bytes."""
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
            resolution=self.resolution,
            structure=self.structure,
            areas=self.areas,
            normals=self.normals,
            samples=self.samples,
            spacing=self.spacing,
            rotation=np.asarray(rotation, float) @ self.rotation,
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
        value is left unspecified), cached. A read-only ``order`` array (a renderer's) is
        recognised by identity, without hashing its contents on every call."""
        frozen = isinstance(order, np.ndarray) and not order.flags.writeable
        if frozen and id(order) in self._frozen and self._frozen[id(order)][0] is order:
            return self._frozen[id(order)][1]
        key = b"" if order is None else np.asarray(order, np.int64).tobytes()
        if key not in self._lookups:
            with _BUILD_LOCK:  # the threads of one render call share one build
                if key not in self._lookups:
                    self._lookups[key] = self._build_lookup(order)
        if frozen:
            self._frozen[id(order)] = (order, self._lookups[key])
        return self._lookups[key]

    def _build_lookup(self, order: np.ndarray | None) -> dict[str, np.ndarray]:
        """The arrays of :meth:`_lookup` for ``order``."""
        order = np.arange(self.n_facets) if order is None else np.asarray(order, np.int64)
        if order.ndim != 1 or np.any((order < -1) | (order >= self.n_facets)):
            raise ValueError(f"order must list facet indices below {self.n_facets} or -1")
        unused = order < 0
        segments = self._segments()
        count = np.where(unused, 0, np.diff(segments["segment_start"])[order])
        first = np.repeat(segments["segment_start"][order], count)
        step = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
        lookup = {
            "segment_start": np.concatenate([[0], np.cumsum(count)]).astype(np.int64),
            "segment_word": segments["segment_word"][first + step],
            "segment_mask": segments["segment_mask"][first + step],
            "segment_weight": segments["segment_weight"][first + step],
            # an unused column faces nowhere: never looked up
            "normals": np.ascontiguousarray(np.where(unused, 0.0, self.normals[order].T)),
            "flat_index": self.grid.node_index.reshape(-1).astype(np.int64),
            "rotation": np.ascontiguousarray(self.rotation),
        }
        full = np.empty((len(self.grid), -(-len(order) // 64)), dtype=np.uint64)
        _kernels().full_flags(
            self.bits,
            lookup["segment_start"],
            lookup["segment_word"],
            lookup["segment_mask"],
            full,
        )
        lookup["full"] = full
        lookup.update(self._cell_entries(order))
        return lookup

    def _segments(self) -> dict[str, np.ndarray]:
        """The segments sorted by facet (``segment_start`` per facet), with their bit masks."""
        if "segments" not in self._cache:
            lay = self.layout
            by_facet = np.argsort(lay["segment_facet"], kind="stable")
            count = np.bincount(lay["segment_facet"], minlength=self.n_facets)
            self._cache["segments"] = {
                "segment_start": np.concatenate([[0], np.cumsum(count)]).astype(np.int64),
                "segment_word": np.ascontiguousarray(lay["segment_word"][by_facet]),
                "segment_mask": np.ascontiguousarray(self._segment_masks()[by_facet]),
                "segment_weight": np.ascontiguousarray(lay["segment_weight"][by_facet]),
            }
        return self._cache["segments"]

    def _cells(self) -> dict[str, np.ndarray]:
        """Per grid cell, the facets partly shadowed around it and their points' bits at
        its corners (:func:`~shapes.visibility.cells.cell_entries`, cached)."""
        if "cells" not in self._cache:
            self._cache["cells"] = cell_entries(
                self.bits,
                self._segments(),
                node_index=self.grid.node_index,
                directions=self.grid.directions,
                normals=self.normals,
            )
        return self._cache["cells"]

    def _cell_entries(self, order: np.ndarray) -> dict[str, np.ndarray]:
        """:meth:`_cells` with one entry per output column of ``order`` (and each corner's
        visible fraction of the facet precomputed: the one-sided case is three products)."""
        cells, seg = self._cells(), self._segments()
        used = np.flatnonzero(order >= 0)
        columns = used[np.argsort(order[used], kind="stable")]
        per_facet = np.bincount(order[used], minlength=self.n_facets)
        first_column = np.cumsum(per_facet) - per_facet
        facet = cells["entry_facet"]
        start = cells["cell_start"]
        if np.all(per_facet == 1):  # every facet in one column (a renderer's order): no copies
            entry_facet, entry_word, cell_start = facet, cells["entry_word"], start
            column = columns[first_column][facet]
        else:
            count = per_facet[facet]
            source = np.repeat(np.arange(len(facet)), count)
            step = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
            entry_facet = np.ascontiguousarray(facet[source])
            entry_word = np.ascontiguousarray(cells["entry_word"][source])
            entry_cell = np.repeat(np.arange(len(start) - 1), np.diff(start))
            cell_start = np.searchsorted(entry_cell[source], np.arange(len(start)))
            column = columns[first_column[entry_facet] + step]
        # 16-byte records; a float32 holds every column index below 2²⁴ exactly
        value = np.empty((len(entry_facet), 4), np.float32 if len(order) <= 2**24 else float)
        _kernels().cell_fractions(
            cells["cell_words"],
            entry_word,
            entry_facet,
            seg["segment_start"],
            seg["segment_weight"],
            value[:, :3],
        )
        value[:, 3] = column
        del column
        first_word = np.full(len(start), len(cells["cell_words"]), np.int64)
        inner = start < len(facet)
        first_word[inner] = cells["entry_word"][start[inner]]
        return {
            "cell_start": cell_start.astype(np.int64),
            "cell_word_start": first_word,
            "entry_value": value,
            "entry_facet": entry_facet,
            "entry_word": entry_word,
            "cell_words": cells["cell_words"],
            "facet_segment_start": seg["segment_start"],
            "facet_segment_weight": seg["segment_weight"],
        }

    def _segment_masks(self) -> np.ndarray:
        """(S,) uint64 bits of each segment within its word."""
        length = self.layout["segment_length"].astype(np.uint64)
        ones = np.where(
            length == 64, np.uint64(2**64 - 1), (np.uint64(1) << (length % np.uint64(64))) - 1
        )
        return ones.astype(np.uint64) << self.layout["segment_shift"].astype(np.uint64)

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
        shares (:mod:`shapes.visibility.kernels`). At grid nodes this is the exact joint
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
        if not (isinstance(light, np.ndarray) and isinstance(view, np.ndarray)):
            if _is_tensor(light) or _is_tensor(view):
                return self._joint_torch(light, view, lookup, facing)
            light, view = _as_float_array(light), _as_float_array(view)
        if light.dtype not in _FLOATS or view.dtype not in _FLOATS:
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
            lookup["cell_start"],
            lookup["cell_word_start"],
            lookup["entry_value"],
            lookup["entry_facet"],
            lookup["entry_word"],
            lookup["cell_words"],
            lookup["facet_segment_start"],
            lookup["facet_segment_weight"],
            lookup["normals"],
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
        """Write the table atomically as a compressed ``.npz`` (format :data:`FORMAT_VERSION`;
        zlib level 1, :func:`shapes.files.write_npz`).

        The bits are stored direction-major per word (``bits.T``), which keeps neighbouring
        directions' words together and compresses best.
        """
        lay = self.layout
        write_npz(
            path,
            dict(
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
            ),
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
                    resolution=int(data["resolution"]),
                    structure=str(data["structure"]),
                    areas=data["areas"],
                    normals=data["normals"],
                    samples=int(data["samples"]),
                    spacing=float(data["spacing"]),
                    rotation=data["rotation"],
                )
        except TableFormatError:
            raise
        except ShapeError as exc:
            raise ShapeError(f"{path}: {exc}") from None
        except (OSError, KeyError, ValueError, IndexError, TypeError) as exc:
            raise ShapeError(f"{path}: not a readable visibility table ({exc})") from None


def _kernels() -> Any:
    """:mod:`shapes.visibility.kernels`, imported on first use (numba is not needed to load
    shapes or read their tables)."""
    from shapes.visibility import kernels as joint_visibility

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
