"""The light-curve error of a level-of-detail proxy against its full mesh.

A proxy (:mod:`shapes.library.proxy`) stands for its full shape in the estimators only when
its light curves match the full mesh's to within the data's noise. The error is measured
over random geometries: uniform attitudes on SO(3), a Sun direction uniform on the sphere and
an observer direction uniform on the sphere within :data:`MAX_PHASE_DEG` of the Sun (beyond
it the lit crescent is thin, the object faint and rarely observed). Both models render with
their own material and the shadowing the inversion uses (``shadows="auto"``: the visibility
table of a non-convex shape, none for a convex one), at the same distances, so the magnitude
difference is the shape's alone. Geometries where either model is dark are left out.
"""

from __future__ import annotations

import sys

import numpy as np

from filters.attitude import random_quaternion
from lightcurve.photometry.render import Renderer
from shapes.model import FacetModel

__all__ = ["MAX_PHASE_DEG", "PROXY_GEOMETRIES", "PROXY_SEED", "ProxyErrorMeter"]

#: Random geometries of the measurement.
PROXY_GEOMETRIES = 10_000
#: Seed of the geometries.
PROXY_SEED = 20261206
#: Largest phase angle (Sun–object–observer) drawn, degrees.
MAX_PHASE_DEG = 120.0
_SUN_DISTANCE_M = 1.495978707e11
_OBSERVER_DISTANCE_M = 1.0e9
_CHUNK = 1000  # geometries rendered a call (one progress-bar step)


def random_geometries(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` random attitudes and Sun and observer vectors (inertial frame, metres).

    Returns
    -------
    q : (n, 4) array
        Attitudes, inertial → body, scalar last.
    sun, observer : (n, 3) arrays
        Object → Sun and object → observer vectors; phase angle ≤ :data:`MAX_PHASE_DEG`.
    """
    rng = np.random.default_rng(seed)
    q = random_quaternion(n, rng)
    sun = rng.standard_normal((n, 3))
    sun /= np.linalg.norm(sun, axis=1, keepdims=True)
    observer = np.empty((n, 3))
    cos_max = np.cos(np.radians(MAX_PHASE_DEG))
    missing = np.arange(n)
    while len(missing):  # rejection: observer directions within the phase limit
        draw = rng.standard_normal((len(missing), 3))
        draw /= np.linalg.norm(draw, axis=1, keepdims=True)
        keep = np.einsum("ij,ij->i", draw, sun[missing]) >= cos_max
        observer[missing[keep]] = draw[keep]
        missing = missing[~keep]
    return q, sun * _SUN_DISTANCE_M, observer * _OBSERVER_DISTANCE_M


class ProxyErrorMeter:
    """``meter(model, proxy)`` → the proxy's error record (the ``measure`` of
    :func:`shapes.library.proxy.choose_proxy`).

    The full model's magnitudes are computed once per model and kept, so trying several
    proxies of one shape renders the full mesh once.

    Parameters
    ----------
    geometries : int
        Random geometries (≥ 10).
    seed : int
        Seed of the geometries.
    progress : bool
        Draw a tqdm bar on stderr for each model rendered.
    """

    def __init__(
        self, geometries: int = PROXY_GEOMETRIES, seed: int = PROXY_SEED, *, progress: bool = False
    ) -> None:
        if geometries < 10:
            raise ValueError(f"proxy error: at least 10 geometries are needed, got {geometries}")
        self.geometries = int(geometries)
        self.seed = int(seed)
        self.progress = bool(progress)
        self._geometry = random_geometries(self.geometries, self.seed)
        self._reference: tuple[FacetModel, np.ndarray, str] | None = None

    def _magnitudes(self, renderer: Renderer, label: str) -> np.ndarray:
        from tqdm import tqdm

        q, sun, observer = self._geometry
        out = np.empty(len(q))
        bar = tqdm(
            total=len(q), desc=label, unit="geometry", disable=not self.progress, file=sys.stderr
        )
        with bar:
            for first in range(0, len(q), _CHUNK):
                rows = slice(first, first + _CHUNK)
                out[rows] = renderer.magnitude(q[rows], sun[rows], observer[rows])
                bar.update(len(out[rows]))
        return out

    def __call__(self, model: FacetModel, proxy: FacetModel) -> dict:
        """The error record of ``proxy`` against ``model``.

        Returns
        -------
        dict
            ``rms_mag`` and ``max_mag`` (rms and largest absolute magnitude difference),
            ``geometries`` (used: both models lit and seen), ``seed``, ``max_phase_deg``,
            ``shadows`` (the full model's shadowing mode).

        Raises
        ------
        ValueError
            The proxy renders with other shadowing than the full model, or no geometry
            shows both models.
        """
        approx_renderer = Renderer(proxy)
        if self._reference is None or self._reference[0] is not model:
            full_renderer = Renderer(model)
            if approx_renderer.shadows == full_renderer.shadows:
                magnitudes = self._magnitudes(full_renderer, f"{len(model.faces)} facets")
                self._reference = (model, magnitudes, full_renderer.shadows)
            shadows = full_renderer.shadows
        else:
            shadows = self._reference[2]
        if approx_renderer.shadows != shadows:
            raise ValueError(
                f"{model.name}: the proxy renders with shadows {approx_renderer.shadows!r}, "
                f"the full shape with {shadows!r}"
            )
        full = self._reference[1]
        approx = self._magnitudes(approx_renderer, f"proxy, {len(proxy.faces)} facets")
        seen = np.isfinite(full) & np.isfinite(approx)
        if not np.any(seen):
            raise ValueError(f"{model.name}: no random geometry shows both the shape and proxy")
        difference = approx[seen] - full[seen]
        return {
            "rms_mag": float(np.sqrt(np.mean(difference**2))),
            "max_mag": float(np.max(np.abs(difference))),
            "geometries": int(np.count_nonzero(seen)),
            "seed": self.seed,
            "max_phase_deg": MAX_PHASE_DEG,
            "shadows": shadows,
        }
