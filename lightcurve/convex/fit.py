"""Convex shape + spin inversion: fits from pole starts, period scans, and their results.

:func:`fit` runs Levenberg–Marquardt (:mod:`lightcurve.convex.optimize`) on the model of
:mod:`lightcurve.convex.model` from one or several starting spin states at once; the shape
starts from a sphere. :func:`period_scan` fits a grid of trial periods, each from several
pole starts spread over the sphere, all batched, and returns χ²(P) with its minima
(Kaasalainen, Torppa & Muinonen 2001, sec. 4; Ďurech et al. 2010 for DAMIT's settings).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import torch

from lightcurve.convex.data import Photometry
from lightcurve.convex.model import ConvexModel
from lightcurve.convex.optimize import levenberg_marquardt, scaled_inverse
from lightcurve.convex.sphere import GaussianSphere
from lightcurve.spin import SpinState

__all__ = [
    "ConvexSettings",
    "ConvexSolution",
    "PeriodScan",
    "fibonacci_poles",
    "fit",
    "period_profile",
    "period_scan",
]

_FREE_DEFAULT = ("lambda", "beta", "rate")


@dataclass(frozen=True)
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
    dtype : torch.dtype
        Precision of the facet × epoch arrays.
    compile : bool
        Compile the facet × epoch kernel (:class:`~lightcurve.convex.model.ConvexModel`).
    """

    degree: int = 6
    order: int = 6
    nrows: int = 8
    convexity_weight: float = 0.1
    phase: tuple[float, float, float] = (0.5, 0.1, -0.5)
    lambert: float = 0.1
    free: tuple[str, ...] = _FREE_DEFAULT
    max_iter: int = 100
    rtol: float = 1e-7
    dtype: torch.dtype = torch.float64
    compile: bool = False

    @property
    def sphere(self) -> GaussianSphere:
        return GaussianSphere(self.nrows, self.degree, self.order)


@dataclass
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

    def project(x: torch.Tensor) -> torch.Tensor:
        lam, beta = x[:, lam_i], x[:, beta_i]
        # Latitude beyond ±90°: the same axis with the longitude turned by 180°. That pole
        # frame is the old one turned by 180° about the axis, so φ0 − π keeps the attitude
        # (and the model) continuous across the pole.
        beta = torch.atan2(torch.sin(beta), torch.cos(beta))
        over = beta.abs() > math.pi / 2
        beta = torch.where(over, torch.sign(beta) * math.pi - beta, beta)
        x = x.clone()
        x[:, lam_i] = torch.remainder(torch.where(over, lam + math.pi, lam), 2 * math.pi)
        x[:, beta_i] = beta.clamp(-_MAX_LATITUDE, _MAX_LATITUDE)
        x[:, phi_i] = torch.where(over, x[:, phi_i] - math.pi, x[:, phi_i])
        return x

    return project


def _start_vectors(model: ConvexModel, settings: ConvexSettings, starts: Sequence[SpinState]):
    lay = model.layout
    x0 = torch.zeros((len(starts), lay.size), dtype=torch.float64, device=model.device)
    for row, s in enumerate(starts):
        x0[row, lay.spin] = torch.tensor(
            [
                s.lambda_rad,
                s.beta_rad,
                s.rate,
                s.phi0_rad + s.rate * (model.epoch_mjd - s.epoch_mjd) * 86400.0,
            ],
            dtype=torch.float64,
        )
    x0[:, lay.phase] = torch.tensor(settings.phase, dtype=torch.float64)
    x0[:, lay.lambert] = settings.lambert
    return x0


def _free_mask(model: ConvexModel, settings: ConvexSettings) -> torch.Tensor:
    lay = model.layout
    free = torch.zeros(lay.size, dtype=torch.bool, device=model.device)
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
    data: Photometry,
    starts: Sequence[SpinState],
    settings: ConvexSettings,
    epoch_mjd: float,
):
    model = ConvexModel(
        data,
        settings.sphere,
        epoch_mjd,
        settings.convexity_weight,
        settings.dtype,
        compile=settings.compile,
    )
    x0 = _start_vectors(model, settings, starts)
    free = _free_mask(model, settings)
    lambert_free = "c" in settings.free
    if model.has_calibrated:
        # Start the calibrated curves' scale at its least-squares value for the sphere.
        with torch.no_grad():
            fitted, _ = model.evaluate(x0, jacobian=False)
            w = (1 - model.relative_rows) / model.sigma**2
            scale = (w * fitted * model.brightness).sum(1) / (w * fitted**2).sum(1)
            x0[:, model.layout.log_scale] = torch.log(scale.to(torch.float64))

    def residuals(x: torch.Tensor, jacobian: bool):
        return model.residuals(x, jacobian, lambert_free)

    result = levenberg_marquardt(
        residuals,
        x0,
        free,
        max_iter=settings.max_iter,
        rtol=settings.rtol,
        project=_canonical_pole(model.layout),
    )
    return model, free, result


def _solutions(
    model: ConvexModel, free: torch.Tensor, result, epoch_mjd: float
) -> list[ConvexSolution]:
    lay = model.layout
    with torch.no_grad():
        fitted, _ = model.evaluate(result.x, jacobian=False)
        areas = model.areas(result.x[:, : lay.n_coefficients])
        dark = torch.linalg.vector_norm(model.convexity(areas), dim=1)
    y = model.brightness
    data_chi2 = (((y - fitted) / model.sigma) ** 2).sum(1)
    rms = torch.sqrt(((y - fitted) ** 2).mean(1))
    n, p = len(y), int(free.sum())
    index = torch.nonzero(free).flatten().tolist()
    out = []
    for row in range(len(result.x)):
        x = result.x[row].cpu().numpy()
        lam, beta, rate, phi0 = (float(v) for v in x[lay.spin])
        sigma = _uncertainties(result.hessian[row], float(result.chi2[row]), n, p, index, lay, x)
        spin = SpinState(lam, beta, 2 * math.pi / rate, phi0 % (2 * math.pi), model.epoch_mjd)
        spin = spin.at_epoch(epoch_mjd)
        out.append(
            ConvexSolution(
                spin=spin,
                chi2=float(data_chi2[row]),
                rms=float(rms[row]),
                coefficients=x[: lay.n_coefficients].copy(),
                areas=areas[row].cpu().numpy().astype(float),
                normals=model.sphere.normals,
                dark_facet=float(dark[row]),
                sigma=sigma,
                model=fitted[row].cpu().numpy().astype(float),
                parameters=x,
                iterations=int(result.iterations[row]),
                converged=bool(result.converged[row]),
            )
        )
    return out


def _uncertainties(hessian, chi2, n, p, index, lay, x) -> dict[str, float]:
    """1σ of λ, β (deg), P (h) and the pole direction (deg) from ``χ²_ν (JᵀJ)⁻¹``."""
    try:
        cov = scaled_inverse(hessian).cpu().numpy() * chi2 / max(n - p, 1)
    except RuntimeError:
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
    model, free, result = _solve(data, starts, settings, data.mean_epoch)
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


@dataclass
class PeriodScan:
    """χ² against trial period.

    Attributes
    ----------
    periods_h : (n,) float
        Trial periods (h).
    chi2 : (n,) float
        Best χ² over the pole starts at each trial period.
    best : list of ConvexSolution
        The best fit of each trial period.
    seconds : float
        Wall-clock time of the scan.
    """

    periods_h: np.ndarray
    chi2: np.ndarray
    best: list[ConvexSolution]
    seconds: float

    def minimum(self) -> ConvexSolution:
        """The global minimum."""
        return self.best[int(np.argmin(self.chi2))]

    def local_minima(self, count: int = 5) -> list[ConvexSolution]:
        """The ``count`` deepest local minima of χ²(P), best first."""
        c = self.chi2
        is_min = np.r_[True, c[1:] <= c[:-1]] & np.r_[c[:-1] <= c[1:], True]
        rows = np.flatnonzero(is_min)
        rows = rows[np.argsort(c[rows])][:count]
        return [self.best[r] for r in rows]


def period_step(data: Photometry, period_h: float, coefficient: float = 0.5) -> float:
    """Trial-period step ``coefficient · P²/(2T)`` (h) for a data span T.

    Adjacent χ² minima of a double-peaked light curve are ``P²/(2T)`` apart (half a
    rotation accumulated over the span), so a step of half that misses none.
    """
    return coefficient * period_h**2 / (2.0 * data.span_days * 24.0)


def period_scan(
    data: Photometry,
    period_range_h: tuple[float, float],
    poles: int | Sequence[tuple[float, float]] = 6,
    settings: ConvexSettings | None = None,
    step_coefficient: float = 0.5,
    thin: int | None = 20,
    batch_size: int = 48,
    epoch_mjd: float | None = None,
    progress: bool = False,
) -> PeriodScan:
    """χ² against trial period, each period fitted from several pole starts.

    Every trial period is fitted from every pole start (the shape from a sphere), all of
    them batched; the scan's χ² at a period is the best over the pole starts, so that a
    wrong local minimum in pole does not show as a false minimum in period (DAMIT's
    ``period_scan``). The trial periods are ``period_step`` apart.

    Parameters
    ----------
    data : Photometry
    period_range_h : (float, float)
        Scan interval (h).
    poles : int or sequence of (λ, β)
        Number of pole starts (spread by :func:`fibonacci_poles`) or the starts (rad).
    settings : ConvexSettings, optional
        Model of the scan; default a light one (degree 3, 72 facets, 10 iterations,
        float32): the scan only has to rank the periods, the minima are refined afterwards.
    step_coefficient : float
        See :func:`period_step`.
    thin : int or None
        Fit at most this many evenly spaced points per light curve (None: all). χ² is
        scaled back to the full number of points.
    batch_size : int
        Fits (periods × poles) run together.
    epoch_mjd : float, optional
        Epoch t0 at which the solutions report φ0 (default: the first epoch); the fits
        themselves refer the rotation to the data's mean epoch, as :func:`fit`.
    progress : bool
        Show a tqdm progress bar.

    Returns
    -------
    PeriodScan
    """
    low, high = sorted(float(v) for v in period_range_h)
    if not (low > 0 and high > low):
        raise ValueError(f"period range must be 0 < A < B hours, got {period_range_h}")
    settings = settings or SCAN_SETTINGS
    pole_starts = fibonacci_poles(poles) if isinstance(poles, int) else list(poles)
    periods = [low]
    while periods[-1] < high:
        periods.append(periods[-1] + period_step(data, periods[-1], step_coefficient))
    periods = np.array(periods)
    fitted = data.thinned(thin) if thin else data
    epoch = float(data.mjd.min()) if epoch_mjd is None else float(epoch_mjd)
    starts = [
        SpinState(lam, beta, p * 3600.0, 0.0, epoch) for p in periods for lam, beta in pole_starts
    ]
    solutions: list[ConvexSolution] = []
    began = time.perf_counter()
    chunks = range(0, len(starts), batch_size)
    if progress:
        from tqdm import tqdm

        chunks = tqdm(chunks, desc="period scan", unit="batch")
    for start in chunks:
        model, free, result = _solve(
            fitted, starts[start : start + batch_size], settings, data.mean_epoch
        )
        solutions += _solutions(model, free, result, epoch)
    scale = len(data) / len(fitted)
    per_period = [
        solutions[i * len(pole_starts) : (i + 1) * len(pole_starts)] for i in range(len(periods))
    ]
    best = [min(group, key=lambda s: s.chi2) for group in per_period]
    return PeriodScan(
        periods, scale * np.array([b.chi2 for b in best]), best, time.perf_counter() - began
    )


#: The light model of :func:`period_scan`.
SCAN_SETTINGS = ConvexSettings(degree=3, order=3, nrows=3, max_iter=10, dtype=torch.float32)


def refine(
    solutions: Sequence[ConvexSolution], data: Photometry, settings: ConvexSettings
) -> list[ConvexSolution]:
    """Refit solutions (e.g. scan minima) with other settings from their spin states, batched.

    Returns
    -------
    list of ConvexSolution
        Sorted by χ², best first.
    """
    return fit(data, [s.spin for s in solutions], settings)


def period_profile(
    data: Photometry,
    solution: ConvexSolution,
    periods_h: Sequence[float],
    settings: ConvexSettings | None = None,
) -> list[ConvexSolution]:
    """χ² profile in period: the fit redone at each fixed period from ``solution``.

    The pole, the shape and any other free parameter of ``settings`` are refitted with the
    rotation rate held at each trial period, starting from ``solution``'s parameters (its
    shape, not a sphere), all periods batched. The profile's curvature gives the period's
    uncertainty with the correlated parameters re-optimised; its minimum shows where the
    χ² of the data and model lies, independently of the optimiser's path in period.

    Parameters
    ----------
    data : Photometry
        The data ``solution`` was fitted to.
    solution : ConvexSolution
        A fit of :func:`fit` with the same settings.
    periods_h : sequence of float
        Fixed trial periods (h).
    settings : ConvexSettings, optional

    Returns
    -------
    list of ConvexSolution
        One per period, in the order of ``periods_h``.
    """
    settings = settings or ConvexSettings()
    model = ConvexModel(
        data,
        settings.sphere,
        data.mean_epoch,
        settings.convexity_weight,
        settings.dtype,
        compile=settings.compile,
    )
    lay = model.layout
    if len(solution.parameters) != lay.size:
        raise ValueError("solution and settings have different spherical-harmonics degrees")
    periods = np.asarray(periods_h, dtype=float)
    x0 = torch.as_tensor(solution.parameters, dtype=torch.float64, device=model.device)
    x0 = x0.repeat(len(periods), 1)
    x0[:, lay.index("phi0")] = solution.spin.at_epoch(data.mean_epoch).phi0_rad
    x0[:, lay.index("rate")] = torch.as_tensor(2 * math.pi / (periods * 3600.0))
    free = _free_mask(model, settings)
    free[lay.index("rate")] = False
    lambert_free = "c" in settings.free
    result = levenberg_marquardt(
        lambda x, jacobian: model.residuals(x, jacobian, lambert_free),
        x0,
        free,
        max_iter=settings.max_iter,
        rtol=settings.rtol,
        project=_canonical_pole(lay),
    )
    return _solutions(model, free, result, solution.spin.epoch_mjd)
