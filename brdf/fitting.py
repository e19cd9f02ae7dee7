"""Least-squares fits of reflectance-model parameters to tabulated BRDF measurements.

`fit` minimises, by default, the log-space residuals ``r = log10(ρ_model) − log10(ρ_measured)``
(dex) with `scipy.optimize.least_squares` (trust-region reflective, box bounds). Specular
materials span many decades (the Starlink solar array: 10⁻³ to 5·10⁴ sr⁻¹) so the logarithm
gives every measurement a comparable weight. Exponent-like parameters (``log_scale`` in
`brdf.describe`) are searched in their logarithm; the fit restarts from several points spread
over their ranges (``starts``) and keeps the best. Weights whose sum may not exceed 1
(``ModelInfo.weights``: ``rd + rs`` of Phong and Cook–Torrance, ``rd + rb + rn`` of the two-lobe
model) are searched by stick breaking: the last free weight directly, each earlier one as its
fraction in [0, 1] of what the later ones leave (e.g. ``rd/(1 − rs)``), so the sum holds.

Two options describe the measurement rather than the material. ``weights`` multiply each
squared residual (the cost is ``Σ wᵢ rᵢ²``); `mirror_band_weights` gives every band of angular
distance from the mirror direction the same total weight, so the few points on a narrow
specular peak are not drowned by the many diffuse ones. ``fit_tilt`` fits the alignment offset
of the lab set-up: the sample normal rotated by ``tilt`` (deg) from ``z`` towards ``x``, the
plane of incidence of scans at azimuths 0°/180° (a sample mounted or a scan zero set a fraction
of a degree off shifts the measured mirror peak by twice that angle).

The 1σ uncertainties come from the Jacobian at the optimum,
``C = s² (JᵀJ)⁻¹`` with ``s² = Σ wᵢ rᵢ²/(N − p)`` (weights normalised to mean 1), mapped to the
model parameters through the derivative of the search-variable transform.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from brdf._geometry import cosines, tangent_cosines
from brdf.registry import BRDF, BRDFParameterError, ModelInfo, describe, get
from brdf.tables import BRDFTable

__all__ = ["FitResult", "fit", "mirror_band_weights", "mirror_distance_deg"]

MIRROR_BANDS_DEG = (1.0, 3.0, 10.0, 30.0, 90.0)


@dataclass(frozen=True, eq=False)
class FitResult:
    """Outcome of `fit`.

    Attributes
    ----------
    model : str
        Registry name.
    params : dict
        All parameters at the optimum (free, fixed and tied).
    uncertainties : dict
        1σ of each free and tied parameter (same units; ``inf`` when the data do not
        constrain it).
    rms : float
        RMS residual, weighted (``√(Σ w r² / Σ w)``) when the fit was: log10 units (dex) for a
        log fit, sr⁻¹ otherwise.
    residuals : (N_used,) ndarray
        ``log10(model/data)`` (log fit) or ``model − data`` per used row (unweighted).
    used : (N,) bool ndarray
        Rows of the table that entered the fit (positive value, ``n·L > 0`` and ``n·V > 0``).
    free : tuple of str
        Fitted parameter names.
    success : bool
        Optimiser converged and the parameters pass `brdf.get` validation.
    message : str
    log : bool
        Whether the residuals are in log space.
    nfev : int
        Residual evaluations of the best start.
    weights : (N_used,) ndarray or None
        Weights of the used rows, normalised to mean 1 (None: unweighted fit).
    tilt, tilt_sigma : float
        Tilt (deg) of the sample normal from ``z`` towards ``x`` used in the fit and its 1σ
        (0 when held fixed).
    """

    model: str
    params: dict[str, float]
    uncertainties: dict[str, float]
    rms: float
    residuals: np.ndarray
    used: np.ndarray
    free: tuple[str, ...]
    success: bool
    message: str
    log: bool = True
    nfev: int = field(default=0)
    weights: np.ndarray | None = None
    tilt: float = 0.0
    tilt_sigma: float = 0.0

    @property
    def rms_unweighted(self) -> float:
        """Plain RMS of `residuals` (same units as `rms`)."""
        return float(np.sqrt(np.mean(self.residuals**2)))

    def brdf(self) -> BRDF:
        """The fitted model as a validated `BRDF`."""
        return get(self.model, **self.params)


@dataclass(frozen=True)
class _Search:
    """Map between the search vector ``x`` and the model parameters.

    ``shared`` lists the free weights searched by stick breaking (the first directly, each
    later one as its fraction of ``budget`` minus the earlier ones); ``budget`` is 1 minus the
    fixed weights.
    """

    info: ModelInfo
    free: tuple[str, ...]
    fixed: dict[str, float]
    tied: dict[str, str]
    bounds: dict[str, tuple[float, float]]
    shared: tuple[str, ...] = ()
    budget: float = 1.0

    def is_log(self, name: str) -> bool:
        return self.info.parameter(name).log_scale

    def is_fraction(self, name: str) -> bool:
        return name in self.shared[1:]

    def to_x(self, params: Mapping[str, float]) -> np.ndarray:
        fractions = {}
        remaining = self.budget
        for name in self.shared:
            if self.is_fraction(name):
                fractions[name] = params[name] / remaining if remaining > 0.0 else 0.0
            remaining -= params[name]
        x = []
        for name in self.free:
            value = fractions.get(name, params[name])
            x.append(math.log(value) if self.is_log(name) else value)
        return np.array(x)

    def x_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        low, high = [], []
        for name in self.free:
            lo, hi = (0.0, 1.0) if self.is_fraction(name) else self.bounds[name]
            if self.is_log(name):
                lo, hi = math.log(lo), math.log(hi)
            low.append(lo)
            high.append(hi)
        return np.array(low), np.array(high)

    def to_params(self, x: np.ndarray) -> dict[str, float]:
        values = {
            name: float(math.exp(v) if self.is_log(name) else v)
            for name, v in zip(self.free, x, strict=True)
        }
        values.update(self.fixed)
        remaining = self.budget
        for name in self.shared:
            if self.is_fraction(name):
                values[name] = values[name] * max(remaining, 0.0)
            remaining -= values[name]
        for name, source in self.tied.items():
            values[name] = values[source]
        return values


def _starting_points(search: _Search, initial: np.ndarray, starts: int) -> list[np.ndarray]:
    """The initial point, then points spread over the ranges of the log-scaled parameters."""
    low, high = search.x_bounds()
    points = [np.clip(initial, low, high)]
    for k in range(1, starts):
        point = points[0].copy()
        fraction = (k - 0.5) / (starts - 1)
        for index, name in enumerate(search.free):
            if search.is_log(name):
                point[index] = low[index] + fraction * (high[index] - low[index])
        points.append(point)
    return points


def fit(
    model_name: str,
    table: BRDFTable,
    *,
    params: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    fixed: Mapping[str, float] | None = None,
    tied: Mapping[str, str] | None = None,
    log: bool = True,
    starts: int = 5,
    floor: float = 1e-12,
    weights: np.ndarray | None = None,
    tilt: float = 0.0,
    fit_tilt: bool = False,
    tilt_bounds: tuple[float, float] = (-1.0, 1.0),
) -> FitResult:
    """Fit the parameters of ``model_name`` to tabulated BRDF measurements.

    Parameters
    ----------
    model_name : str
        Registry name (`brdf.available`).
    table : BRDFTable
        Measurements; the sample normal is ``z`` and its tangent (``u`` of anisotropic models)
        is azimuth 0.
    params : mapping, optional
        Initial values of the free parameters (defaults: `brdf.describe` defaults).
    bounds : mapping, optional
        ``name → (low, high)`` search bounds (defaults: each parameter's ``fit_range``).
    fixed : mapping, optional
        Parameters held at the given values.
    tied : mapping, optional
        ``name → other``: parameter ``name`` equals ``other`` (e.g. ``{"nv": "nu"}`` for an
        isotropic Ashikhmin–Shirley fit to in-plane data).
    log : bool
        Fit log10 residuals (default) or linear residuals.
    starts : int
        Number of starting points (≥ 1).
    floor : float
        Lower clamp of the model value (sr⁻¹) before the logarithm.
    weights : (N,) array, optional
        Non-negative weight of each table row in the cost ``Σ w r²`` (e.g.
        `mirror_band_weights`); normalised to mean 1 over the used rows.
    tilt : float
        Tilt (deg) of the sample normal from ``z`` towards ``x`` (rotation about ``y``): the
        value used, or the starting value when ``fit_tilt``. The tangent turns with it.
    fit_tilt : bool
        Fit ``tilt`` as a nuisance parameter of the measurement, within ``tilt_bounds`` (deg).
    tilt_bounds : (float, float)
        Search range of the tilt (deg).

    Returns
    -------
    FitResult

    Raises
    ------
    brdf.BRDFParameterError
        Unknown model or parameter names, or bounds outside a parameter's valid range.
    ValueError
        Fewer usable rows than free parameters, weights of the wrong shape, negative, not
        finite or all zero on the used rows, or a tilt outside ``tilt_bounds``.
    """
    from scipy.optimize import least_squares

    info = describe(model_name)
    fixed = {name: float(v) for name, v in (fixed or {}).items()}
    tied = dict(tied or {})
    for name in (*fixed, *tied, *tied.values(), *(params or {}), *(bounds or {})):
        info.parameter(name)
    free = tuple(n for n in info.parameter_names if n not in fixed and n not in tied)
    search_bounds = {}
    for name in free:
        spec = info.parameter(name)
        lo, hi = (bounds or {}).get(name, spec.fit_range)
        if not (lo < hi and spec.contains(np.array([lo, hi])).all()):
            raise BRDFParameterError(
                f"{info.name}: bounds ({lo:g}, {hi:g}) of {name!r} must be increasing and "
                f"inside its valid range {spec.range_text}"
            )
        search_bounds[name] = (float(lo), float(hi))
    # Weights whose sum is bounded by 1: stick breaking over the free ones, last first.
    shared = tuple(name for name in reversed(info.weights) if name in free)
    budget = 1.0 - sum(fixed.get(name, 0.0) for name in info.weights)
    if shared:
        lo, hi = search_bounds[shared[0]]
        if not min(hi, budget) > lo:
            raise BRDFParameterError(
                f"{info.name}: the fixed weights leave {budget:g} for {shared[0]!r}, below its "
                f"lower bound {lo:g} ({' + '.join(info.weights)} ≤ 1)"
            )
        search_bounds[shared[0]] = (lo, min(hi, budget))
    search = _Search(info, free, fixed, tied, search_bounds, shared, budget)

    light, view = table.directions()
    nl, nv, _ = cosines(np, np.array([0.0, 0.0, 1.0]), light, view)
    used = (nl > 0) & (nv > 0) & ((table.value > 0) if log else True)
    count = len(free) + int(fit_tilt)
    if used.sum() <= count:
        raise ValueError(
            f"{table.source or 'table'}: {int(used.sum())} usable rows for {count} parameters"
        )
    light, view = light[used], view[used]
    target = np.log10(table.value[used]) if log else table.value[used]
    scale = _row_weights(table, weights, used)
    if not tilt_bounds[0] <= tilt <= tilt_bounds[1] or not tilt_bounds[0] < tilt_bounds[1]:
        raise ValueError(
            f"tilt {tilt:g}° must lie in the increasing range tilt_bounds {tilt_bounds}"
        )
    anisotropic = info.name == "ashikhmin-shirley"

    def model_values(params: Mapping[str, float], tilt_deg: float) -> np.ndarray:
        angle = math.radians(tilt_deg)
        normal = np.array([math.sin(angle), 0.0, math.cos(angle)])
        tangent = np.array([math.cos(angle), 0.0, -math.sin(angle)])
        nl, nv, lv = cosines(np, normal, light, view)
        extra = {}
        if anisotropic:
            hu, hv = tangent_cosines(np, normal, tangent, light, view)
            extra = {"hu": hu, "hv": hv}
        return info.cosine(nl, nv, lv, **params, **extra)

    def unweighted(x: np.ndarray) -> np.ndarray:
        if fit_tilt:
            x, tilt_deg = x[:-1], x[-1]
        else:
            tilt_deg = tilt
        model = model_values(search.to_params(x), tilt_deg)
        return (np.log10(np.maximum(model, floor)) if log else model) - target

    def residuals(x: np.ndarray) -> np.ndarray:
        raw = unweighted(x)
        return raw if scale is None else raw * scale

    initial = {spec.name: spec.default for spec in info.parameters}
    initial.update(params or {})
    initial.update(fixed)
    low, high = search.x_bounds()
    if fit_tilt:
        low, high = np.append(low, tilt_bounds[0]), np.append(high, tilt_bounds[1])
    best = None
    for x0 in _starting_points(search, search.to_x(initial), max(1, starts)):
        if fit_tilt:
            x0 = np.append(x0, tilt)
        result = least_squares(residuals, np.clip(x0, low, high), bounds=(low, high), method="trf")
        if best is None or result.cost < best.cost:
            best = result
    model_x = best.x[:-1] if fit_tilt else best.x
    fitted = search.to_params(model_x)
    values = {name: fitted[name] for name in info.parameter_names}
    sigma = _uncertainties(search, best, len(target), extra=int(fit_tilt))
    tilt_sigma = sigma.pop("", 0.0)
    uncertainties = sigma
    uncertainties.update({n: uncertainties.get(s, 0.0) for n, s in tied.items()})
    message = best.message
    success = bool(best.success)
    try:
        get(info.name, **values)
    except ValueError as error:
        success, message = False, f"{message}; {error}"
    raw = unweighted(best.x)
    return FitResult(
        model=info.name,
        params=values,
        uncertainties=uncertainties,
        rms=float(np.sqrt(2.0 * best.cost / len(target))),
        residuals=raw,
        used=used,
        free=free,
        success=success,
        message=message,
        log=log,
        nfev=int(best.nfev),
        weights=None if scale is None else scale**2,
        tilt=float(best.x[-1]) if fit_tilt else float(tilt),
        tilt_sigma=tilt_sigma,
    )


def _row_weights(
    table: BRDFTable, weights: np.ndarray | None, used: np.ndarray
) -> np.ndarray | None:
    """Square roots of the used rows' weights normalised to mean 1 (None when unweighted)."""
    if weights is None:
        return None
    name = table.source or "table"
    weights = np.asarray(weights, dtype=float)
    if weights.shape != used.shape:
        raise ValueError(f"{name}: {weights.shape} weights for {used.size} rows")
    bad = ~np.isfinite(weights) | (weights < 0)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{name}: weight of row {row} is {weights[row]!r}, must be finite ≥ 0")
    chosen = weights[used]
    if not chosen.sum() > 0:
        raise ValueError(f"{name}: the weights of the usable rows are all zero")
    return np.sqrt(chosen / chosen.mean())


def mirror_distance_deg(table: BRDFTable) -> np.ndarray:
    """Angle (deg) between each row's scatter direction and the mirror direction of its source.

    The mirror direction reflects the direction to the source about the sample normal ``z``.
    """
    light, view = table.directions()
    mirror = light * np.array([-1.0, -1.0, 1.0])
    return np.degrees(np.arccos(np.clip(np.sum(mirror * view, axis=-1), -1.0, 1.0)))


def mirror_band_weights(
    table: BRDFTable, edges_deg: tuple[float, ...] = MIRROR_BANDS_DEG
) -> np.ndarray:
    """Row weights giving every band of distance from the mirror direction equal total weight.

    The rows are grouped per incidence (``zenith_in``, ``azimuth_in``) and, within each, by
    the angle between the scatter direction and the mirror direction of the source into bands
    with the given upper edges (deg; a last band takes the rest). Each non-empty band of each
    incidence gets the same total weight, shared equally by its rows. Glossy lobes vary on
    angular scales proportional to the distance from the mirror direction, so bands spaced
    roughly logarithmically (default 1°, 3°, 10°, 30°, 90°) each carry comparable information
    about the lobe shapes, whereas uniform angular sampling puts almost every point in the
    diffuse wings.

    Parameters
    ----------
    table : BRDFTable
        Measurements (sample normal ``z``).
    edges_deg : tuple of float
        Increasing upper band edges (deg).

    Returns
    -------
    (N,) ndarray
        Weights, mean 1 over the rows.
    """
    edges = np.asarray(edges_deg, dtype=float)
    if edges.ndim != 1 or edges.size == 0 or np.any(np.diff(edges) <= 0) or edges[0] <= 0:
        raise ValueError(f"band edges {edges_deg!r} must be positive and increasing")
    band = np.searchsorted(edges + 1e-9, mirror_distance_deg(table))
    _, incidence = np.unique(
        np.stack([table.zenith_in, table.azimuth_in], axis=-1), axis=0, return_inverse=True
    )
    _, cell, counts = np.unique(
        np.stack([incidence.ravel(), band], axis=-1),
        axis=0,
        return_inverse=True,
        return_counts=True,
    )
    weights = 1.0 / counts[cell.ravel()]
    return weights / weights.mean()


def _uncertainties(search: _Search, result: Any, count: int, extra: int = 0) -> dict[str, float]:
    """1σ of the free parameters from the Jacobian at the optimum.

    ``extra`` trailing search variables (the tilt) are parameters themselves; their 1σ is
    returned under the key ``""``.
    """
    jacobian = result.jac
    dof = max(count - jacobian.shape[1], 1)
    variance = 2.0 * result.cost / dof
    information = jacobian.T @ jacobian
    eigenvalues, eigenvectors = np.linalg.eigh(information)
    null = eigenvalues <= 1e-12 * max(eigenvalues.max(), np.finfo(float).tiny)
    covariance_x = variance * np.linalg.pinv(information, hermitian=True)
    # Directions the data do not constrain have unbounded uncertainty.
    unconstrained = np.any(np.abs(eigenvectors[:, null]) > 1e-6, axis=1)
    # Derivative of the free parameters with respect to the search variables.
    step = 1e-7
    size = len(search.free)
    model_x = result.x[:size]
    base = search.to_params(model_x)
    transform = np.eye(size + extra)
    for j in range(size):
        shifted = model_x.copy()
        shifted[j] += step
        moved = search.to_params(shifted)
        transform[:size, j] = [(moved[n] - base[n]) / step for n in search.free]
    covariance = transform @ covariance_x @ transform.T
    sigma = np.sqrt(np.abs(np.diag(covariance)))
    sigma[unconstrained | ~np.isfinite(sigma)] = np.inf
    names = (*search.free, *[""] * extra)
    return {name: float(s) for name, s in zip(names, sigma, strict=True)}
