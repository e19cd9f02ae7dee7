"""Photometric rendering of facet models: flux ratio and apparent magnitude.

For effective facets ``i`` (unit normal ``n_i`` in the body frame, area ``A_i``, BRDF
``ρ_i``) and unit body-frame vectors to the Sun ``L = A(q) ŝ`` and to the observer
``V = A(q) ô`` at observer range ``d`` (docs/rendering.md, "The measurement model"):

``F_obs / F_sun = (1 AU / r_sun)² Σ_i ρ_i(n_i, L, V) A_i (n_i·L)(n_i·V) lit_i seen_i / d²``,
``m = −26.74 − 2.5 log10(F_obs / F_sun)``.

``lit_i``/``seen_i`` are the unshadowed/unoccluded fractions of facet ``i`` seen along ``L``
and ``V`` (their product approximates the fraction that is both): 1 for a convex body
(``shadows="none"``), interpolated from the shape's precomputed visibility table
(``"table"``), or ray cast for every epoch (``"exact"``, the reference). A fully dark epoch
has zero flux and infinite magnitude.

Two code paths evaluate the same formula over any leading batch shape (particles ×
epochs); numpy inputs give numpy outputs, torch inputs torch outputs:

* the fused kernels of :mod:`lightcurve.photometry.kernels` (numba, compiled once per machine and
  cached): CPU computations whose result needs no gradient, i.e. every simulation, filter
  and particle update. One pass over the facets per row, no (rows × facets) arrays, rows
  spread over ``torch.get_num_threads()`` threads;
* torch (the *eager* path): when an input requires grad (the global search and the
  photometric planner differentiate the flux with respect to the attitude), on CUDA, for
  :meth:`Renderer.facet_flux`, and for a shape with a BRDF that has no fused kernel. Every
  BRDF is evaluated through its cosine form (``n·L``, ``n·V``, ``L·V`` and, for anisotropic
  Ashikhmin–Shirley, ``H·u``, ``H·v``), one call per material on a contiguous block of
  facets, in cache-sized chunks of rows.
"""

from __future__ import annotations

import ast
import importlib.util
import logging
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache, cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

import brdf
from filters.attitude import rotate
from lightcurve.sky.geometry import AU_M
from shapes import CompiledFacets, FacetModel, joint_visible_fraction

if TYPE_CHECKING:
    import torch

logger = logging.getLogger(__name__)

__all__ = [
    "BACKENDS",
    "SHADOW_MODES",
    "SUN_MAGNITUDE",
    "Renderer",
    "flux_to_magnitude",
    "magnitude_to_flux",
]

#: Apparent magnitude of the Sun at 1 AU (V band).
SUN_MAGNITUDE = -26.74
SHADOW_MODES = ("auto", "none", "table", "exact")
BACKENDS = ("auto", "torch")
# Facet-rows per chunk by default: 65536 elements = 256 KiB in float32, cache-sized.
_CHUNK_ELEMENTS = 65536
# Every Renderer compiles the same kernel code with its own constants; allow that many
# specialisations before dynamo falls back to eager (its default limit is 8).
_RECOMPILE_LIMIT = 64
# Rows × facets of one shadow-factor array on the fused path (16 MiB in float64).
_SHADOW_ELEMENTS = 1 << 21
# Rows × facets of one table shadow-factor block (512 KiB in float64): written by the table
# lookup and read by the facet sums while it is still in the core's L2 cache.
_TABLE_BLOCK_ELEMENTS = 1 << 16


def flux_to_magnitude(flux: Any) -> Any:
    """``m = −26.74 − 2.5 log10(F/F_sun)``; zero flux gives ``+inf``.

    Parameters
    ----------
    flux : array
        Flux ratio ``F_obs / F_sun`` (≥ 0).

    Returns
    -------
    array
        Apparent magnitude.
    """
    if _is_tensor(flux):
        return SUN_MAGNITUDE - 2.5 * flux.log10()
    with np.errstate(divide="ignore"):
        return SUN_MAGNITUDE - 2.5 * np.log10(flux)


def magnitude_to_flux(magnitude: Any) -> Any:
    """Inverse of :func:`flux_to_magnitude`."""
    return 10.0 ** (-0.4 * (magnitude - SUN_MAGNITUDE))


@dataclass(frozen=True)
class _Block:
    """A contiguous run of effective facets sharing one material."""

    start: int
    stop: int
    model: brdf.BRDF


class Renderer:
    """Renders a facet model's brightness for batches of attitudes and geometries.

    Parameters
    ----------
    shape : FacetModel or CompiledFacets
        The shape (its compiled, coplanar-merged facets are used).
    shadows : {"auto", "none", "table", "exact"}
        Self-shadowing mode. ``"auto"``: ``"none"`` when no facet can ever be shadowed
        (convex bodies), else ``"table"`` when the shape carries a visibility table, else
        ``"exact"``.
    dtype : torch.dtype, optional
        Computation precision (``torch.float64`` by default; ``torch.float32`` is up to 2×
        faster).
    device : str or torch.device, optional
        Where the torch path computes (default: CUDA when torch sees a GPU, else the CPU, where
        the fused kernels serve the calls without gradient). torch itself is imported only
        when a call needs it, so numpy-only work (a simulation) never pays for it.
    chunk_size : int, optional
        Rows (epochs × particles) per chunk. By default ``65536 // facets`` (at least 16):
        the (chunk × facets) work arrays then stay in the L2 cache, which measured 1.3–1.6×
        faster than 256-row chunks for 1280 facets.
    scale_sun_distance : bool
        Scale the Sun's flux by ``(1 AU / r_sun)²`` (True: physically right for any object).
    compile : bool
        Compile the torch path's per-chunk kernel with ``torch.compile`` (inductor). It only
        serves the calls that take the torch path (gradients, CUDA, :meth:`facet_flux`); the
        fused kernels are faster on the CPU without it. The first call pays 10–30 s of
        compilation; falls back to eager execution (with a logged warning) where compilation
        is unavailable. Raises dynamo's recompile limit to 64, since each renderer
        specialises the kernel to its own facets and materials.
    backend : {"auto", "torch"}
        ``"auto"``: the fused numba kernels for CPU calls that need no gradient, torch
        otherwise (see the module docstring); ``"torch"``: always torch (the reference path
        of the tests and the baseline of ``benchmarks/render.py``).

    Examples
    --------
    >>> from shapes import primitives
    >>> r = Renderer(primitives.box(1.0, 2.0, 3.0))
    >>> m = r.magnitude([0, 0, 0, 1], [1.5e11, 0, 0], [4e7, 1e7, 0])
    """

    def __init__(
        self,
        shape: FacetModel | CompiledFacets,
        *,
        shadows: str = "auto",
        dtype: torch.dtype | None = None,
        device: str | torch.device | None = None,
        chunk_size: int | None = None,
        scale_sun_distance: bool = True,
        compile: bool = False,
        backend: str = "auto",
    ) -> None:
        compiled = shape.compiled() if isinstance(shape, FacetModel) else shape
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
        if shadows not in SHADOW_MODES:
            raise ValueError(f"shadows must be one of {', '.join(SHADOW_MODES)}, got {shadows!r}")
        if shadows == "auto":
            if not np.any(compiled.can_be_shadowed):
                shadows = "none"
            else:
                shadows = "table" if compiled.visibility is not None else "exact"
        if shadows == "table" and compiled.visibility is None:
            raise ValueError("shadows='table' needs a shape with a visibility table")
        self.compiled = compiled
        self.shadows = shadows
        self.backend = backend
        self._dtype = dtype
        self._device = device
        self.chunk_size = (
            max(16, _CHUNK_ELEMENTS // len(compiled.areas))
            if chunk_size is None
            else int(chunk_size)
        )
        self.scale_sun_distance = scale_sun_distance

        # Sort facets by material so that each BRDF sees one contiguous block (a view).
        order = np.argsort(compiled.material_index, kind="stable")
        self._order = order
        normals = compiled.normals[order]
        tangents = compiled.tangents[order]
        bitangents = np.cross(normals, tangents)
        materials = compiled.material_index[order]
        self._blocks: list[_Block] = []
        self._anisotropic = False
        for index in np.unique(materials):
            rows = np.flatnonzero(materials == index)
            material = compiled.materials[index]
            model = brdf.get(material.brdf, **material.params)
            self._anisotropic |= model.anisotropic
            self._blocks.append(_Block(int(rows[0]), int(rows[-1]) + 1, model))
        self.n_facets = len(order)
        # The frame matrix stacks normals, tangents and bitangents: one GEMM per direction.
        self._frame_rows = (
            np.concatenate([normals, tangents, bitangents], axis=0)
            if self._anisotropic
            else normals
        )
        self._static_shapes = compile
        self._kernel = _compiled_or_eager(self._facet_terms) if compile else self._facet_terms
        self._fused: Any = None  # lightcurve.photometry.kernels.FusedFlux, built on first use

    @cached_property
    def dtype(self) -> torch.dtype:
        """Computation precision (a torch dtype)."""
        import torch

        return torch.float64 if self._dtype is None else self._dtype

    @cached_property
    def device(self) -> torch.device:
        """Device of the torch path (imports torch)."""
        import torch

        if self._device is not None:
            return torch.device(self._device)
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")

    @cached_property
    def _on_cpu(self) -> bool:
        """Whether the renderer computes on the CPU, decided without importing torch when
        torch is not loaded and its build has no GPU support."""
        if self._device is not None:
            return str(self._device).split(":")[0] == "cpu"
        if "torch" not in sys.modules and not _torch_build_has_gpu():
            return True
        return self.device.type == "cpu"

    @cached_property
    def _numpy_dtype(self) -> np.dtype:
        """The compute dtype as numpy's (float32 or float64)."""
        name = "float64" if self._dtype is None else str(self._dtype).rsplit(".", 1)[-1]
        return np.dtype(np.float32 if name == "float32" else np.float64)

    @cached_property
    def _frame(self) -> torch.Tensor:
        import torch

        return torch.as_tensor(self._frame_rows, dtype=self.dtype, device=self.device)

    @cached_property
    def _areas(self) -> torch.Tensor:
        import torch

        areas = self.compiled.areas[self._order]
        return torch.as_tensor(areas, dtype=self.dtype, device=self.device)

    # ------------------------------------------------------------------ public API
    def flux(self, q: Any, sun: Any, observer: Any) -> Any:
        """Flux ratio ``F_obs / F_sun`` (dimensionless).

        Parameters
        ----------
        q : (..., 4) array
            Attitudes (inertial → body).
        sun, observer : (..., 3) array
            Object → Sun and object → observer vectors in the inertial frame, metres
            (broadcast against ``q``: e.g. ``q`` of shape (P, E, 4) with geometry (E, 3)).

        Returns
        -------
        (...) array
            Same kind as ``q`` (numpy or torch); torch results keep the input's device.
        """
        return self._evaluate(q, sun, observer, per_facet=False)

    def magnitude(self, q: Any, sun: Any, observer: Any) -> Any:
        """Apparent magnitude ``−26.74 − 2.5 log10(F_obs/F_sun)`` (``inf`` when dark).

        Parameters are those of :meth:`flux`.
        """
        return flux_to_magnitude(self.flux(q, sun, observer))

    def facet_flux(self, q: Any, sun: Any, observer: Any) -> Any:
        """Contribution of each effective facet to the flux ratio.

        Returns
        -------
        (..., K) array
            In the order of ``self.compiled`` facets; sums to :meth:`flux` over the last axis.
        """
        out = self._evaluate(q, sun, observer, per_facet=True)
        inverse = np.argsort(self._order)
        return out[..., inverse]

    # ------------------------------------------------------------------ internals
    def _evaluate(self, q: Any, sun: Any, observer: Any, per_facet: bool) -> Any:
        if not per_facet and self._fusable(q, sun, observer):
            return self._evaluate_fused(q, sun, observer)
        import torch

        as_numpy = not isinstance(q, torch.Tensor)
        out_device = None if as_numpy else q.device
        q, sun, observer = (
            torch.as_tensor(np.asarray(v) if not isinstance(v, torch.Tensor) else v).to(
                self.device, self.dtype
            )
            for v in (q, sun, observer)
        )
        # numpy's rule (torch.broadcast_shapes imports sympy, seconds on first use)
        shape = np.broadcast_shapes(
            tuple(q.shape[:-1]), tuple(sun.shape[:-1]), tuple(observer.shape[:-1])
        )
        q = q.expand(*shape, 4).reshape(-1, 4)
        sun = sun.expand(*shape, 3).reshape(-1, 3)
        observer = observer.expand(*shape, 3).reshape(-1, 3)
        sun_range = torch.linalg.vector_norm(sun, dim=-1)
        obs_range = torch.linalg.vector_norm(observer, dim=-1)
        light = rotate(q, sun / sun_range[:, None])
        view = rotate(q, observer / obs_range[:, None])
        scale = 1.0 / obs_range**2
        if self.scale_sun_distance:
            scale = scale * (AU_M / sun_range) ** 2
        pieces = []
        for start in range(0, light.shape[0], self.chunk_size):
            stop = min(start + self.chunk_size, light.shape[0])
            chunk_l, chunk_v = light[start:stop], view[start:stop]
            shadow = self._shadow_factor(chunk_l, chunk_v)
            if self._static_shapes and stop - start < self.chunk_size:
                # Pad the last chunk so the compiled kernel sees one static shape.
                pad = self.chunk_size - (stop - start)
                chunk_l = torch.cat([chunk_l, chunk_l[:1].expand(pad, 3)])
                chunk_v = torch.cat([chunk_v, chunk_v[:1].expand(pad, 3)])
                if shadow is not None:
                    shadow = torch.cat([shadow, shadow[:1].expand(pad, -1)])
            contrib = self._kernel(chunk_l, chunk_v, shadow)[: stop - start]
            contrib = contrib * scale[start:stop, None]
            pieces.append(contrib if per_facet else contrib.sum(dim=-1))
        result = torch.cat(pieces, dim=0) if pieces else torch.zeros(0, dtype=self.dtype)
        result = result.reshape((*shape, *((self.n_facets,) if per_facet else ())))
        if as_numpy:
            return result.detach().cpu().numpy()
        return result.to(out_device)

    def _fusable(self, *inputs: Any) -> bool:
        """Whether the fused CPU kernels may evaluate these inputs (no gradient, no GPU)."""
        if self.backend != "auto" or not self._on_cpu or not self._fused_kernels_exist:
            return False
        torch = sys.modules.get("torch")
        if torch is None:
            return True  # no tensor can be among the inputs
        grad = torch.is_grad_enabled()
        for v in inputs:
            if isinstance(v, torch.Tensor) and (
                v.device.type != "cpu" or (grad and v.requires_grad)
            ):
                return False
        return True

    @cached_property
    def _fused_kernels_exist(self) -> bool:
        """Whether every material's BRDF has a fused kernel (if not, torch renders)."""
        from lightcurve.photometry.kernels import KINDS

        return all(block.model.name in KINDS for block in self._blocks)

    def _fused_flux(self) -> Any:
        if self._fused is None:
            from lightcurve.photometry.kernels import FusedFlux, block_parameters, facet_table

            compiled, order = self.compiled, self._order
            dtype = self._numpy_dtype
            table = facet_table(
                compiled.normals[order], compiled.areas[order], compiled.tangents[order], dtype
            )
            blocks = []
            for block in self._blocks:
                model = block.model
                kind, row = block_parameters(model.name, model.params, model.anisotropic)
                blocks.append((kind, block.start, block.stop, row))
            self._fused = FusedFlux(table, blocks, dtype)
        return self._fused

    @cached_property
    def _table_slots(self) -> np.ndarray:
        """Compiled facet of each slot of the fused kernels (-1: padding), for the visibility
        table to write the joint fractions straight into the kernels' layout and dtype."""
        fused = self._fused_flux()
        slots = np.where(fused.padding, -1, self._order[fused.source])
        slots.flags.writeable = False  # the table recognises it without hashing it
        return slots

    def _evaluate_fused(self, q: Any, sun: Any, observer: Any) -> np.ndarray | torch.Tensor:
        """:meth:`flux` by the fused numba kernels (CPU, no gradient)."""
        as_numpy = not _is_tensor(q)
        q, sun, observer = (_float64_array(v) for v in (q, sun, observer))
        for name, value, size in (("q", q, 4), ("sun", sun, 3), ("observer", observer, 3)):
            if value.ndim == 0 or value.shape[-1] != size:
                raise ValueError(f"{name} must have shape (..., {size}), got {value.shape}")
        shape = np.broadcast_shapes(q.shape[:-1], sun.shape[:-1], observer.shape[:-1])
        q, sun, observer = (_rows(v, shape) for v in (q, sun, observer))
        fused = self._fused_flux()
        light, view, scale = fused.geometry(
            q, sun, observer, AU_M if self.scale_sun_distance else 0.0
        )
        if self.shadows == "none":
            sums = fused.sums(light, view)
        elif self.shadows == "table":  # cache-sized blocks: the factor stays in L2
            from lightcurve.photometry.kernels.threads import run_rows

            sums = np.empty(len(light), dtype=fused.dtype)
            step = max(1, _TABLE_BLOCK_ELEMENTS // fused.n_slots)
            slots, table = self._table_slots, self.compiled.visibility

            def blocks(first: int, last: int) -> None:
                buffer = np.empty((min(step, last - first), fused.n_slots), fused.dtype)
                for start in range(first, last, step):
                    rows = slice(start, min(start + step, last))
                    factor = buffer[: rows.stop - start]
                    table.joint(light[rows], view[rows], order=slots, facing=False, out=factor)
                    sums[rows] = fused.sums(light[rows], view[rows], factor, per_slot=True)

            run_rows(blocks, len(light), 2 * self.n_facets)
        else:  # ray-cast shadow factors for blocks of rows, to bound the (rows × facets) array
            sums = np.zeros(len(light), dtype=fused.dtype)
            step = max(1, _SHADOW_ELEMENTS // self.n_facets)
            for start in range(0, len(light), step):
                rows = slice(start, start + step)
                factor = self._shadow_factor(light[rows], view[rows])
                sums[rows] = fused.sums(light[rows], view[rows], factor)
        flux = (sums * scale).astype(fused.dtype, copy=False).reshape(shape)
        if as_numpy:
            return flux
        import torch

        return torch.from_numpy(flux)

    def _facet_terms(self, light: torch.Tensor, view: torch.Tensor, shadow: Any) -> torch.Tensor:
        """``ρ A (n·L)(n·V) · shadow`` for every facet of a chunk, shape (chunk, K)."""
        k = self.n_facets
        proj_l = light @ self._frame.T
        proj_v = view @ self._frame.T
        nl, nv = proj_l[:, :k], proj_v[:, :k]
        lv = (light * view).sum(dim=-1, keepdim=True)
        hu = hv = None
        if self._anisotropic:
            half_norm = (2.0 + 2.0 * lv).clamp(min=1e-30).sqrt()
            hu = (proj_l[:, k : 2 * k] + proj_v[:, k : 2 * k]) / half_norm
            hv = (proj_l[:, 2 * k :] + proj_v[:, 2 * k :]) / half_norm
        import torch

        rho = torch.cat(
            [
                block.model.from_cosines(
                    nl[:, block.start : block.stop],
                    nv[:, block.start : block.stop],
                    lv,
                    hu=None if hu is None else hu[:, block.start : block.stop],
                    hv=None if hv is None else hv[:, block.start : block.stop],
                )
                for block in self._blocks
            ],
            dim=-1,
        )
        terms = rho * self._areas * nl.clamp(min=0.0) * nv.clamp(min=0.0)
        return terms if shadow is None else terms * shadow

    def _shadow_factor(self, light: Any, view: Any) -> Any:
        """Joint (lit and seen) fraction for a chunk, shape (chunk, K), or None when no
        shadowing applies.

        ``light``/``view`` are torch tensors (eager path) or numpy arrays (fused path); the
        factor is of the same kind and dtype, in the renderer's (material-sorted) facet order.
        Facets turned away from ``L`` or ``V`` may get any value: the flux multiplies them by
        ``max(0, n·L) max(0, n·V) = 0``.
        """
        if self.shadows == "none":
            return None
        if self.shadows == "table":
            return self.compiled.visibility.joint(light, view, order=self._order, facing=False)
        rays = [v.detach().cpu().numpy() if _is_tensor(v) else v for v in (light, view)]
        factor = joint_visible_fraction(self.compiled, *(v.astype(float) for v in rays))
        factor = factor[:, self._order]
        if _is_tensor(light):
            import torch

            return torch.as_tensor(factor, dtype=self.dtype, device=self.device)
        return np.ascontiguousarray(factor, dtype=light.dtype)


def _compiled_or_eager(kernel: Callable[..., torch.Tensor]) -> Callable[..., torch.Tensor]:
    """``torch.compile(kernel)``, replaced by ``kernel`` itself if compilation fails."""
    import torch

    config = torch._dynamo.config
    if hasattr(config, "recompile_limit"):
        config.recompile_limit = max(config.recompile_limit, _RECOMPILE_LIMIT)
    compiled = torch.compile(kernel, dynamic=False)
    state = {"kernel": compiled}

    def run(*args: Any) -> torch.Tensor:
        try:
            return state["kernel"](*args)
        except Exception as exc:  # inductor needs a C++ toolchain; any failure → eager
            if state["kernel"] is kernel:
                raise
            logger.warning("torch.compile failed (%s); rendering eagerly", exc)
            state["kernel"] = kernel
            return kernel(*args)

    return run


def _is_tensor(value: Any) -> bool:
    """Whether ``value`` is a torch tensor (False without importing torch when it is not
    loaded: no tensor can exist then)."""
    torch = sys.modules.get("torch")
    return torch is not None and isinstance(value, torch.Tensor)


@cache
def _torch_build_has_gpu() -> bool:
    """Whether the installed torch is a CUDA/ROCm build, read from ``torch/version.py``
    without importing torch (True when that cannot be told: then torch is asked)."""
    try:
        spec = importlib.util.find_spec("torch")
        source = Path(next(iter(spec.submodule_search_locations)), "version.py")
        values = {}
        for node in ast.parse(source.read_text(encoding="utf-8")).body:
            target = getattr(node, "target", None) or (getattr(node, "targets", None) or [None])[0]
            if isinstance(target, ast.Name) and target.id in ("cuda", "hip"):
                values[target.id] = ast.literal_eval(node.value)
        return set(values) != {"cuda", "hip"} or any(v is not None for v in values.values())
    except (AttributeError, OSError, StopIteration, TypeError, ValueError, SyntaxError):
        return True


def _float64_array(value: Any) -> np.ndarray:
    """A float64 numpy array of ``value`` (numpy, sequence or CPU tensor)."""
    if _is_tensor(value):
        value = value.detach().numpy()
    return np.asarray(value, dtype=np.float64)


def _rows(value: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` broadcast to ``(*shape, n)`` as a writable C-ordered ``(rows, n)`` array."""
    if value.shape[:-1] != shape:
        value = np.broadcast_to(value, (*shape, value.shape[-1]))
    value = value.reshape(-1, value.shape[-1])
    if not (value.flags.c_contiguous and value.flags.writeable):
        value = value.copy()  # one kernel specialisation: C order, writable
    return value


def lambert_sphere_flux(albedo: float, radius: float, distance: float, alpha: Any) -> Any:
    """Closed-form flux ratio of a Lambertian sphere at phase angle ``alpha`` (rad).

    ``(2/3) ρ R²/d² · [sin α + (π − α) cos α]/π`` (Russell 1916), Sun at 1 AU.

    Parameters
    ----------
    albedo : float
        Lambert albedo ``rd`` (the BRDF is ``rd/π``).
    radius, distance : float
        Sphere radius and observer range (m).
    alpha : array
        Phase angle (rad).
    """
    alpha = np.asarray(alpha, dtype=float)
    return (
        (2.0 / 3.0)
        * albedo
        * radius**2
        / distance**2
        * (np.sin(alpha) + (math.pi - alpha) * np.cos(alpha))
        / math.pi
    )
