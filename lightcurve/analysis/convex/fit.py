"""Convex shape + spin inversion: fits from pole starts, their settings, results and
uncertainties.

:func:`fit` runs Levenberg–Marquardt (:mod:`lightcurve.analysis.convex.optimize`) on the model of
:mod:`lightcurve.analysis.convex.compiled` (or the torch model of
:mod:`lightcurve.analysis.convex.model`) from one or several starting spin states at once; the shape
starts from a sphere (Kaasalainen & Torppa 2001, *Optimization methods for asteroid lightcurve
inversion I*). Period scans, which run the same fits over a grid of trial periods, are in
:mod:`lightcurve.analysis.convex.scan`.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from lightcurve.analysis.convex.data import Photometry
from lightcurve.analysis.convex.layout import CONVEXITY_WEIGHT
from lightcurve.analysis.convex.optimize import levenberg_marquardt, scaled_inverse
from lightcurve.analysis.convex.sphere import GaussianSphere
from lightcurve.analysis.spin import SpinState

__all__ = [
    "ConvexSettings",
    "ConvexSolution",
    "fibonacci_poles",
    "fit",
]

logger = logging.getLogger(__name__)

_FREE_DEFAULT = ("lambda", "beta", "rate")


@dataclass(frozen=True, kw_only=True)
class ConvexSettings:
    """Model and optimiser settings (defaults: those of DAMIT's convexinv test run).

    Parameters
    ----------
    degree, order : int
        Spherical-harmonics degree and order of the Gaussian image (6, 6).
    nrows : int
        Rings per hemisphere of the Gaussian sphere (8 → 512 facets).
    convexity_weight : float
        Regularisation weight ``w`` (0.1).
    phase : (a, d, k)
        Phase-function parameters (0.5, 0.1 rad, −0.5 rad⁻¹).
    lambert : float
        Lambert weight ``c`` (0.1).
    free : tuple of str
        Non-shape parameters to fit, among ``lambda``, ``beta``, ``rate``, ``a``, ``d``,
        ``k``, ``c`` (the shape coefficients except ``c_00`` are always free; the scale of
        calibrated curves is free when there are any; φ0 stays fixed since a rotation of the
        Gaussian image about the spin axis is the same model).
    max_iter : int
        Levenberg–Marquardt iterations at most (100; DAMIT's test run stops at 50, where
        this optimiser is not yet converged on Ariadne: it stops at 77 by ``rtol``).
    rtol : float
        Convergence threshold on the relative χ² decrease.
    dtype : str or dtype
        Precision of the facet × epoch sums: ``"float64"`` or ``"float32"`` (numpy or torch
        dtypes are accepted too).
    engine : {"numba", "torch"}
        ``"numba"``: :class:`~lightcurve.analysis.convex.compiled.CompiledModel` (CPU; its kernels
        are compiled once per machine and cached). ``"torch"``:
        :class:`~lightcurve.analysis.convex.model.ConvexModel` (CUDA when available).
    compile : bool
        ``torch.compile`` the torch model's facet × epoch kernel (``engine="torch"`` only;
        about 30 s of compilation per process).
    """

    degree: int = 6
    order: int = 6
    nrows: int = 8
    convexity_weight: float = CONVEXITY_WEIGHT
    phase: tuple[float, float, float] = (0.5, 0.1, -0.5)
    lambert: float = 0.1
    free: tuple[str, ...] = _FREE_DEFAULT
    max_iter: int = 100
    rtol: float = 1e-7
    dtype: Any = "float64"
    engine: str = "numba"
    compile: bool = False

    def __post_init__(self) -> None:
        if self.engine not in ("numba", "torch"):
            raise ValueError(f"engine must be 'numba' or 'torch', got {self.engine!r}")
        if self.compile and self.engine != "torch":
            raise ValueError("compile=True needs engine='torch' (torch.compile)")
        if self.numpy_dtype not in (np.float32, np.float64):
            raise ValueError(f"dtype must be float32 or float64, got {self.dtype}")

    @property
    def numpy_dtype(self) -> np.dtype:
        """:attr:`dtype` as a numpy dtype."""
        return np.dtype(str(self.dtype).removeprefix("torch."))

    @property
    def sphere(self) -> GaussianSphere:
        return _sphere(self.nrows, self.degree, self.order)

    def model(self, data: Photometry, epoch_mjd: float):
        """The model of these settings for ``data`` with its rotation angle referred to
        ``epoch_mjd``."""
        if self.engine == "numba":
            from lightcurve.analysis.convex.compiled import CompiledModel

            return CompiledModel(
                data, self.sphere, epoch_mjd, self.convexity_weight, self.numpy_dtype
            )
        import torch

        from lightcurve.analysis.convex.model import ConvexModel

        return _TorchModel(
            ConvexModel(
                data,
                self.sphere,
                epoch_mjd,
                self.convexity_weight,
                getattr(torch, self.numpy_dtype.name),
                compile=self.compile,
            )
        )


_SPHERES: dict[tuple[int, int, int], GaussianSphere] = {}


def _sphere(nrows: int, degree: int, order: int) -> GaussianSphere:
    """One Gaussian sphere (its triangulation and harmonics) per process and shape."""
    key = (nrows, degree, order)
    if key not in _SPHERES:
        _SPHERES[key] = GaussianSphere(nrows, degree, order)
    return _SPHERES[key]


class _TorchModel:
    """:class:`~lightcurve.analysis.convex.model.ConvexModel` seen through numpy arrays."""

    def __init__(self, model) -> None:
        import torch

        self._torch, self.model = torch, model
        self.layout, self.sphere, self.epoch_mjd = model.layout, model.sphere, model.epoch_mjd
        self.has_calibrated = model.has_calibrated
        self.brightness = self._array(model.brightness)
        self.sigma = self._array(model.sigma)
        self.relative_rows = self._array(model.relative_rows).astype(bool)

    @staticmethod
    def _array(tensor):
        return None if tensor is None else tensor.detach().cpu().numpy().astype(float)

    def _tensor(self, array):
        return self._torch.as_tensor(
            np.asarray(array), dtype=self._torch.float64, device=self.model.device
        )

    def evaluate(self, params, jacobian=True, lambert_free=False):
        with self._torch.no_grad():
            out = self.model.evaluate(self._tensor(params), jacobian, lambert_free)
        return tuple(self._array(t) for t in out)

    def residuals(self, params, jacobian=True, lambert_free=False):
        with self._torch.no_grad():
            out = self.model.residuals(self._tensor(params), jacobian, lambert_free)
        return tuple(self._array(t) for t in out)

    def areas(self, coefficients):
        return self._array(self.model.areas(self._tensor(coefficients)))

    def convexity(self, areas):
        return self._array(self.model.convexity(self._tensor(areas).to(self.model.dtype)))


@dataclass(kw_only=True)
class ConvexSolution:
    """One converged (or stopped) fit.

    Attributes
    ----------
    spin : SpinState
        Pole, sidereal period, φ0 at t0.
    chi2 : float
        ``Σ ((y − model)/σ)²`` over the data (regularisation excluded).
    rms : float
        ``√(Σ (y − model)²/N)`` in relative-intensity units (DAMIT's "rms").
    coefficients : (K,) float
        Harmonics coefficients of the Gaussian image.
    areas : (F,) float
        Facet areas of the Gaussian image (arbitrary scale).
    normals : (F, 3) float
        Facet normals.
    dark_facet : float
        ``|Σ A_i n_i| / Σ A_i``: the relative area of the dark facet closing the image.
    sigma : dict
        1σ uncertainties (``lambda_deg``, ``beta_deg``, ``period_h``, ``pole_deg``) from the
        curvature ``(JᵀJ)⁻¹`` scaled by χ²/(N − p).
    model : (N,) float
        Model brightness at the data epochs.
    parameters : (P,) float
        Full parameter vector.
    iterations : int
    converged : bool
    """

    spin: SpinState
    chi2: float
    rms: float
    coefficients: np.ndarray
    areas: np.ndarray
    normals: np.ndarray
    dark_facet: float
    sigma: dict[str, float]
    model: np.ndarray
    parameters: np.ndarray
    iterations: int
    converged: bool
    extra: dict[str, float] = field(default_factory=dict)

    def summary(self) -> dict[str, float]:
        """JSON-ready dict: ``lambda_deg``, ``beta_deg``, ``period_h``, ``rms``, ``chi2`` …"""
        return {
            "lambda_deg": math.degrees(self.spin.lambda_rad),
            "beta_deg": math.degrees(self.spin.beta_rad),
            "period_h": self.spin.period_h,
            "rms": self.rms,
            "chi2": self.chi2,
            "phi0_deg": math.degrees(self.spin.phi0_rad),
            "epoch_mjd": self.spin.epoch_mjd,
            "sigma": dict(self.sigma),
            "dark_facet_percent": 100 * self.dark_facet,
            "iterations": self.iterations,
            "converged": self.converged,
            **self.extra,
        }


#: Largest |β| of a fitted pole (rad): 0.006° short of the ecliptic poles, where λ would
#: lose its derivative and the optimiser could not turn the pole towards another meridian.
_MAX_LATITUDE = math.pi / 2 - 1e-4


def _canonical_pole(layout):
    lam_i, beta_i, phi_i = layout.index("lambda"), layout.index("beta"), layout.index("phi0")

    def project(x):
        if not isinstance(x, np.ndarray):  # a torch tensor
            import torch

            return torch.as_tensor(
                project(x.detach().cpu().numpy()), dtype=x.dtype, device=x.device
            )
        lam, beta = x[:, lam_i], x[:, beta_i]
        # Latitude beyond ±90°: the same axis with the longitude turned by 180°. That pole
        # frame is the old one turned by 180° about the axis, so φ0 − π keeps the attitude
        # (and the model) continuous across the pole.
        beta = np.arctan2(np.sin(beta), np.cos(beta))
        over = np.abs(beta) > math.pi / 2
        beta = np.where(over, np.sign(beta) * math.pi - beta, beta)
        x = x.copy()
        x[:, lam_i] = np.remainder(np.where(over, lam + math.pi, lam), 2 * math.pi)
        x[:, beta_i] = np.clip(beta, -_MAX_LATITUDE, _MAX_LATITUDE)
        x[:, phi_i] = np.where(over, x[:, phi_i] - math.pi, x[:, phi_i])
        return x

    return project


def _start_vectors(model, settings: ConvexSettings, starts: Sequence[SpinState]) -> np.ndarray:
    lay = model.layout
    x0 = np.zeros((len(starts), lay.size))
    for row, s in enumerate(starts):
        x0[row, lay.spin] = [
            s.lambda_rad,
            s.beta_rad,
            s.rate,
            s.phi0_rad + s.rate * (model.epoch_mjd - s.epoch_mjd) * 86400.0,
        ]
    x0[:, lay.phase] = settings.phase
    x0[:, lay.lambert] = settings.lambert
    if model.has_calibrated:
        # Start the calibrated curves' scale at its least-squares value for the sphere.
        fitted, _ = model.evaluate(x0, jacobian=False)
        w = ~model.relative_rows / model.sigma**2
        scale = (w * fitted * model.brightness).sum(1) / (w * fitted**2).sum(1)
        x0[:, lay.log_scale] = np.log(scale)
    return x0


def _free_mask(model, settings: ConvexSettings) -> np.ndarray:
    lay = model.layout
    free = np.zeros(lay.size, dtype=bool)
    # c_00 (the overall size) is fixed: relative curves do not see it and the scale of the
    # calibrated curves is the separate parameter log_scale.
    free[1 : lay.n_coefficients] = True
    for name in settings.free:
        if name == "phi0":
            raise ValueError(
                "phi0 cannot be fitted together with the shape: a rotation of the Gaussian "
                "image about the spin axis is the same model"
            )
        free[lay.index(name)] = True
    if model.has_calibrated:
        free[lay.log_scale] = True
    return free


def _solve(
    model,
    x0: np.ndarray,
    free: np.ndarray,
    settings: ConvexSettings,
    stop: Callable[[int, np.ndarray, np.ndarray], np.ndarray] | None = None,
):
    lambert_free = "c" in settings.free
    if isinstance(model, _TorchModel):
        residuals = lambda x, jacobian: model.residuals(x, jacobian, lambert_free)  # noqa: E731
    else:
        index = np.flatnonzero(free)

        def residuals(x, jacobian):
            return model.residuals(x, jacobian, lambert_free, index)

    # The compiled kernels run in parallel; the small matrix products around them are
    # faster on one BLAS thread than contending with them (several times so on a busy
    # machine).
    with threadpool_limits(limits=1, user_api="blas"):
        return levenberg_marquardt(
            residuals,
            x0,
            free,
            max_iter=settings.max_iter,
            rtol=settings.rtol,
            project=_canonical_pole(model.layout),
            stop=stop,
        )


def _solutions(
    model, free: np.ndarray, result, epoch_mjd: float, rows: Sequence[int] | None = None
) -> list[ConvexSolution]:
    """Solutions of the rows ``rows`` (default all) of an LM result."""
    lay = model.layout
    rows = np.arange(len(result.x)) if rows is None else np.asarray(rows, dtype=int)
    x_rows = result.x[rows]
    fitted, _ = model.evaluate(x_rows, jacobian=False)
    areas = model.areas(x_rows[:, : lay.n_coefficients])
    dark = np.linalg.norm(model.convexity(areas), axis=1)
    y = model.brightness
    data_chi2 = (((y - fitted) / model.sigma) ** 2).sum(1)
    rms = np.sqrt(((y - fitted) ** 2).mean(1))
    n, p = len(y), int(free.sum())
    index = np.flatnonzero(free).tolist()
    out = []
    for i, row in enumerate(rows):
        x = result.x[row].copy()
        lam, beta, rate, phi0 = (float(v) for v in x[lay.spin])
        sigma = _uncertainties(
            result.hessian[row], float(result.chi2[row]), x, lay=lay, index=index, n=n, p=p
        )
        spin = SpinState(lam, beta, 2 * math.pi / rate, phi0 % (2 * math.pi), model.epoch_mjd)
        spin = spin.at_epoch(epoch_mjd)
        out.append(
            ConvexSolution(
                spin=spin,
                chi2=float(data_chi2[i]),
                rms=float(rms[i]),
                coefficients=x[: lay.n_coefficients].copy(),
                areas=areas[i].astype(float),
                normals=model.sphere.normals,
                dark_facet=float(dark[i]),
                sigma=sigma,
                model=fitted[i].astype(float),
                parameters=x,
                iterations=int(result.iterations[row]),
                converged=bool(result.converged[row]),
            )
        )
    return out


def _uncertainties(hessian, chi2, x, *, lay, index, n, p) -> dict[str, float]:
    """1σ of λ, β (deg), P (h) and the pole direction (deg) from ``χ²_ν (JᵀJ)⁻¹``."""
    try:
        cov = scaled_inverse(hessian) * chi2 / max(n - p, 1)
    except np.linalg.LinAlgError:
        return {}
    var = dict(zip(index, np.diag(cov), strict=True))
    out = {}
    lam_i, beta_i, rate_i = lay.index("lambda"), lay.index("beta"), lay.index("rate")
    beta = x[beta_i]
    if lam_i in var and beta_i in var:
        out["lambda_deg"] = math.degrees(math.sqrt(max(var[lam_i], 0.0)))
        out["beta_deg"] = math.degrees(math.sqrt(max(var[beta_i], 0.0)))
        out["pole_deg"] = math.degrees(
            math.sqrt(max(var[lam_i], 0.0) * math.cos(beta) ** 2 + max(var[beta_i], 0.0))
        )
    if rate_i in var:
        rate = x[rate_i]
        out["period_h"] = 2 * math.pi / rate**2 * math.sqrt(max(var[rate_i], 0.0)) / 3600.0
    return out


def fit(
    data: Photometry,
    starts: SpinState | Sequence[SpinState],
    settings: ConvexSettings | None = None,
    epoch_mjd: float | None = None,
) -> list[ConvexSolution]:
    """Fit shape and spin from one or several starting spin states (batched).

    The model's rotation angle is referred to the data's weighted mean epoch
    (:attr:`Photometry.mean_epoch`), where the period is least correlated with the
    rotation phase of the shape: with t0 at one end of decades of data a period change turns
    the body at the other end by many degrees, which the shape must undo, and the
    optimiser crawls along that narrow valley (``docs/analysis.md``).

    Parameters
    ----------
    data : Photometry
    starts : SpinState or sequence of SpinState
        Starting pole(s) and period(s).
    settings : ConvexSettings, optional
    epoch_mjd : float, optional
        Epoch t0 at which the solutions report φ0 (default: that of the first start).

    Returns
    -------
    list of ConvexSolution
        Sorted by χ², best first.
    """
    settings = settings or ConvexSettings()
    starts = [starts] if isinstance(starts, SpinState) else list(starts)
    if not starts:
        raise ValueError("no starting spin state")
    model = settings.model(data, data.mean_epoch)
    free = _free_mask(model, settings)
    result = _solve(model, _start_vectors(model, settings, starts), free, settings)
    report = starts[0].epoch_mjd if epoch_mjd is None else float(epoch_mjd)
    return sorted(_solutions(model, free, result, report), key=lambda s: s.chi2)


def fibonacci_poles(count: int) -> list[tuple[float, float]]:
    """``count`` pole directions (λ, β) in rad, spread evenly over the sphere."""
    if count < 1:
        raise ValueError(f"need at least one pole start, got {count}")
    k = np.arange(count) + 0.5
    beta = np.arcsin(1 - 2 * k / count)
    lam = (np.pi * (1 + 5**0.5) * k) % (2 * np.pi)
    return list(zip(lam.tolist(), beta.tolist(), strict=True))
