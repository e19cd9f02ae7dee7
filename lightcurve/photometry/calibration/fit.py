"""The robust fit of a shape's photometric parameters to observations with known attitudes.

Given observations of one object (or of a family of identical ones) whose attitude at each
epoch follows a known profile, :func:`calibrate` fits a magnitude offset (the albedo–area
scale of the model) and any chosen BRDF parameters of the model's materials by robust
least squares (``scipy.optimize.least_squares``, soft-L1 loss; Triggs et al. 2000 on robust
cost functions in bundle adjustment):

``Σ_e ρ(((m_e − m̂_e(θ) − Δm)/σ_e)²) + Σ_j ρ(((θ_j − θ_j⁰)/s_j)²)``

The second sum is a Gaussian prior about the library's values (the laboratory fit), 1σ
``s_j`` = ``prior_dex`` in log10 for the parameters the BRDF registry searches on a log scale
(lobe widths, exponents) and ``prior_fraction`` of the parameter's search range otherwise.
A parameter the data do not constrain therefore stays near its library value instead of
being fitted to noise, and is reported as unconstrained: its posterior 1σ is more than
half its prior 1σ. The covariance is the Gauss–Newton ``(JᵀJ)⁻¹`` at the solution, scaled by
the squared robust spread (1.4826 × median absolute deviation) of the normalised data
residuals when above one.

:func:`cross_validate` holds out whole nights (k folds of the nights, seeded): what a
prediction for a night the calibration has not seen is worth.

References
----------
Triggs, B., McLauchlan, P. F., Hartley, R. I., & Fitzgibbon, A. W. (2000). Bundle
adjustment — a modern synthesis. *Vision Algorithms: Theory and Practice*, LNCS 1883,
298–372.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.optimize import least_squares

import brdf
from filters.attitude import quaternion_multiply
from lightcurve.io.observations import Observations
from lightcurve.photometry.calibration.prediction import (
    PredictionGeometry,
    Shape,
    model_magnitude,
    shape_flux,
)
from lightcurve.photometry.earthshine import earthshine_applies, known_positions
from lightcurve.photometry.profiles import offset_quaternion
from lightcurve.photometry.render import flux_to_magnitude
from shapes import Material
from shapes.articulation import ArticulatedModel

__all__ = [
    "ATTITUDE_OFFSETS",
    "Calibration",
    "calibrate",
    "cross_validate",
    "night_index",
]


@dataclass(frozen=True)
class Calibration:
    """Fitted photometric parameters of a shape.

    Attributes
    ----------
    magnitude_offset : float
        Added to the model's magnitudes (mag; negative: the object is brighter than the
        model, a larger albedo–area product).
    parameters : dict
        ``"group.name"`` → ``{"value", "sigma", "prior", "constrained"}`` for every fitted
        BRDF parameter, and ``"magnitude_offset"`` → ``{"value", "sigma"}``.
    correlation : (p, p) numpy.ndarray
        Correlation matrix of the fitted parameters, in the order of ``parameters``.
    train_rms_mag : float
        rms of ``m − m̂`` over the observations fitted (mag).
    n_observations : int
    materials : dict
        The calibrated materials (group → :class:`shapes.Material`).
    shadows : str
        The renderer's shadow mode of the fit.
    offset_deg : (3,) numpy.ndarray
        Fitted attitude offsets ``[roll, pitch, yaw]`` (deg; zeros when not fitted).
    joint_offsets_deg : dict
        Part name → fitted joint offset (deg) of an articulated shape's parts (empty when
        not fitted).
    earthshine : bool
        Whether the fit's model includes the Earth's light
        (:mod:`lightcurve.photometry.earthshine`); predictions then need the ``obj_*``
        positions.
    """

    magnitude_offset: float
    parameters: dict[str, dict[str, Any]]
    correlation: np.ndarray
    train_rms_mag: float
    n_observations: int
    materials: dict[str, Material] = field(repr=False)
    shadows: str = "auto"
    offset_deg: np.ndarray = field(default_factory=lambda: np.zeros(3))
    joint_offsets_deg: dict[str, float] = field(default_factory=dict)
    earthshine: bool = False

    def apply(self, model: Shape) -> Shape:
        """``model`` with the calibrated materials and joint offsets (the magnitude offset
        is applied to magnitudes by :meth:`magnitude`)."""
        model = model.replace(materials={**model.materials, **self.materials})
        if self.joint_offsets_deg:
            model = _as_articulated(model).with_joint_offsets(self.joint_offsets_deg)
        return model

    def magnitude(self, model: Shape, q: Any, observations: Observations) -> np.ndarray:
        """Calibrated magnitudes of ``model`` at attitudes ``q`` (inertial → body, one per
        row of ``observations``, whose Sun and observer vectors, and with earthshine the
        ``obj_*`` positions, give the geometry)."""
        turned = _turned(np.asarray(q, dtype=float), self.offset_deg)
        earthshine = "on" if self.earthshine else "off"
        magnitude = model_magnitude(
            self.apply(model), turned, observations, shadows=self.shadows, earthshine=earthshine
        )
        return magnitude + self.magnitude_offset

    def to_json(self) -> dict[str, Any]:
        """What ``simulate --calibration`` applies: the magnitude offset, the attitude
        and joint offsets, each calibrated material (``brdf``, ``params``) and whether the
        Earth's light was modelled."""
        return {
            "magnitude_offset": self.magnitude_offset,
            "offset_deg": [float(v) for v in self.offset_deg],
            "joint_offsets_deg": {k: float(v) for k, v in self.joint_offsets_deg.items()},
            "earthshine": self.earthshine,
            "materials": {
                group: {"brdf": m.brdf, "params": dict(m.params), "name": m.name}
                for group, m in self.materials.items()
            },
        }


def _as_articulated(model: Shape) -> ArticulatedModel:
    if not isinstance(model, ArticulatedModel):
        raise ValueError(f"calibration: {model.name} has no articulated parts")
    return model


@dataclass(frozen=True)
class _Free:
    """One fitted BRDF parameter: its material group, name, prior and search scale."""

    group: str
    name: str
    prior: float
    sigma: float
    log: bool
    lower: float
    upper: float

    def to_search(self, value: float) -> float:
        return math.log10(value) if self.log else value

    def from_search(self, x: float) -> float:
        return 10.0**x if self.log else x


def calibrate(
    model: Shape,
    q: np.ndarray,
    observations: Observations,
    *,
    parameters: Sequence[str] = (),
    offset: bool = True,
    attitude_offsets: bool = False,
    joint_offsets: Sequence[str] = (),
    prior_dex: float = 0.3,
    prior_fraction: float = 0.25,
    offset_sigma_deg: float = 5.0,
    joint_sigma_deg: float = 20.0,
    loss_scale: float = 3.0,
    shadows: str = "auto",
    earthshine: str = "auto",
    starts: int = 6,
    seed: int = 0,
) -> Calibration:
    """Fit a magnitude offset, attitude and joint offsets and BRDF parameters of ``model``.

    Parameters
    ----------
    model : FacetModel or ArticulatedModel
        The shape with its library materials and joints (the prior).
    q : (E, 4) array
        The object's attitude at each observation (inertial → body), from its profile.
    observations : Observations
        Measured magnitudes with their 1σ and the object → Sun / observer vectors.
    parameters : sequence of str
        ``"group.name"`` of each BRDF parameter fitted (e.g. ``"chassis.rd"``); ``"group.*"``
        fits every parameter of that group's BRDF.
    offset : bool
        Fit the magnitude offset (albedo–area scale).
    attitude_offsets : bool
        Fit a fixed rotation of the body from the profile, 3-2-1 Euler angles ``[roll,
        pitch, yaw]`` (deg, ``q = q_off ⊗ q``, as :func:`~lightcurve.photometry.profiles.
        offset_quaternion`), under a prior of ``offset_sigma_deg`` about zero.
    joint_offsets : sequence of str
        Parts of an articulated ``model`` whose joint offset (deg, added to the tracking or
        scheduled angle) is fitted, under a prior of ``joint_sigma_deg`` about the stored
        offset: how far the real pointing of, e.g., a Sun-tracking array is from its law.
    prior_dex, prior_fraction : float
        1σ of the prior about the library values: in log10 for log-scale parameters,
        as a fraction of the registry's search range otherwise.
    offset_sigma_deg : float
        1σ of the attitude offsets' prior (deg).
    joint_sigma_deg : float
        1σ of the joint offsets' prior (deg).
    loss_scale : float
        Residual (in units of the observations' 1σ) where the soft-L1 loss turns from
        quadratic to linear: observations further out (glints of the model or the sky,
        mis-identifications) weigh less.
    shadows : str
        Self-shadowing mode of the renderer (:class:`~lightcurve.photometry.render.Renderer`
        or :class:`~lightcurve.photometry.articulated.ArticulatedRenderer`).
    earthshine : {"auto", "on", "off"}
        Include the Earth's light in the model
        (:func:`~lightcurve.photometry.earthshine.earthshine_applies`: ``"auto"`` when the
        observations carry the ``obj_*`` positions and the object is in low orbit).
    starts : int
        Starts of the local fit: the priors' centre, and ``starts − 1`` points drawn from
        the priors (``numpy.random.default_rng(seed)``). Each is screened by a short fit
        (10 iterations); the best is fitted to convergence.
    seed : int
        Seed of those draws.

    Returns
    -------
    Calibration
    """
    free = _free_parameters(model, parameters, prior_dex, prior_fraction)
    joints = _joint_parts(model, joint_offsets)
    layout = _Layout(offset, attitude_offsets, len(joints), len(free))
    with_earth = earthshine_applies(earthshine, known_positions(observations), "earthshine")
    measured = np.asarray(observations.magnitudes, dtype=float)
    sigma = np.asarray(observations.magnitude_errors, dtype=float)
    finite = np.isfinite(measured) & np.isfinite(sigma) & (sigma > 0)
    if finite.sum() < layout.size + 1:
        raise ValueError(
            f"calibration: {int(finite.sum())} usable observations for {layout.size} parameters"
        )
    rows = np.flatnonzero(finite)
    q = np.asarray(q, dtype=float)[rows]
    geometry = PredictionGeometry.of(model, _subset(observations, finite), with_earth)
    measured, sigma = measured[rows], sigma[rows]
    faint = float(np.max(measured)) + 10.0  # a dark model epoch: far fainter than any data

    def shape_at(x: np.ndarray) -> Shape:
        shape = model.replace(materials=_materials(model, free, x[layout.materials]))
        if joints:
            shape = shape.with_joint_offsets(dict(zip(joints, x[layout.joints], strict=True)))
        return shape

    def predicted(x: np.ndarray) -> np.ndarray:
        turned = _turned(q, x[layout.angles])
        flux = shape_flux(shape_at(x), turned, geometry, shadows)
        magnitude = np.minimum(flux_to_magnitude(flux), faint)
        return magnitude + (x[0] if offset else 0.0)

    stored = [_stored_offset(model, part) for part in joints]
    prior_centre = np.concatenate(
        [np.zeros(layout.n_angles), stored, [f.to_search(f.prior) for f in free]]
    )
    prior_sigma = np.concatenate(
        [
            np.full(layout.n_angles, offset_sigma_deg),
            np.full(len(joints), joint_sigma_deg),
            [f.sigma for f in free],
        ]
    )

    def residuals(x: np.ndarray) -> np.ndarray:
        data = (measured - predicted(x)) / sigma
        return np.concatenate([data, (x[int(offset) :] - prior_centre) / prior_sigma])

    def started(x: np.ndarray) -> np.ndarray:
        """``x`` with the magnitude offset at the median of the data's residuals."""
        x = x.copy()
        if offset:
            x[0] = 0.0
            x[0] = float(np.median(measured - predicted(x)))
        return x

    def robust_cost(x: np.ndarray) -> float:
        """The fit's soft-L1 objective (``least_squares``' ``ρ``)."""
        z = (residuals(x) / loss_scale) ** 2
        return float(np.sum(2.0 * (np.sqrt(1.0 + z) - 1.0)))

    x0 = started(np.concatenate([np.zeros(int(offset)), prior_centre]))
    # joint offsets move glints across the data: the objective has a minimum per glint,
    # so each starts at the best of a grid over ±3σ of its prior before the local fit
    for k in np.arange(layout.size)[layout.joints]:
        grid = x0[k] + joint_sigma_deg * np.linspace(-3.0, 3.0, 25)
        trials = [started(np.where(np.arange(layout.size) == k, value, x0)) for value in grid]
        x0 = min(trials, key=robust_cost)

    unbounded = int(offset) + layout.n_angles + len(joints)
    lower = np.concatenate([np.full(unbounded, -np.inf), [f.to_search(f.lower) for f in free]])
    upper = np.concatenate([np.full(unbounded, np.inf), [f.to_search(f.upper) for f in free]])
    inside = (np.nextafter(lower, np.inf), np.nextafter(upper, -np.inf))
    # further starts: the priors' centre moved by a draw of the priors (seeded); lobe widths
    # and weights have several local minima once glints and the Earth's light are modelled
    rng = np.random.default_rng(seed)
    x_starts = [np.clip(x0, *inside)]
    for _ in range(starts - 1):
        moved = x0 + np.concatenate([np.zeros(int(offset)), rng.normal(0.0, prior_sigma)])
        x_starts.append(np.clip(started(np.clip(moved, *inside)), *inside))
    # each unknown scaled by its prior's 1σ (the magnitude offset by 1 mag): the Jacobian's
    # own scaling ("jac") crawls along the offset–albedo valley for hundreds of iterations
    scale = np.concatenate([np.ones(int(offset)), prior_sigma])

    def local_fit(x: np.ndarray, max_nfev: int | None = None) -> Any:
        return least_squares(
            residuals,
            x,
            bounds=(lower, upper),
            loss="soft_l1",
            f_scale=loss_scale,
            x_scale=scale,
            max_nfev=max_nfev,
        )

    # with several starts, each is screened by a short fit; the best is fitted to convergence
    if len(x_starts) > 1:
        screened = sorted((local_fit(x, _SCREEN_NFEV) for x in x_starts), key=lambda r: r.cost)
        x_starts = [screened[0].x]
    fit = local_fit(x_starts[0])
    data = fit.fun[: len(measured)]
    spread = 1.4826 * float(np.median(np.abs(data - np.median(data))))
    covariance = np.linalg.pinv(fit.jac.T @ fit.jac, hermitian=True) * max(1.0, spread**2)
    sigmas = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        correlation = covariance / np.outer(sigmas, sigmas)
    out: dict[str, dict[str, Any]] = {}
    if offset:
        out["magnitude_offset"] = {"value": float(fit.x[0]), "sigma": float(sigmas[0])}
    for name, k in zip(
        ATTITUDE_OFFSETS[: layout.n_angles], np.arange(layout.size)[layout.angles], strict=True
    ):
        out[name] = {
            "value": float(fit.x[k]),
            "sigma": float(sigmas[k]),
            "prior": 0.0,
            "constrained": bool(sigmas[k] < 0.5 * offset_sigma_deg),
        }
    for part, prior, k in zip(joints, stored, np.arange(layout.size)[layout.joints], strict=True):
        out[f"{part}.joint_offset_deg"] = {
            "value": float(fit.x[k]),
            "sigma": float(sigmas[k]),
            "prior": prior,
            "constrained": bool(sigmas[k] < 0.5 * joint_sigma_deg),
        }
    for f, k in zip(free, np.arange(layout.size)[layout.materials], strict=True):
        value = f.from_search(float(fit.x[k]))
        # a log-scale parameter's 1σ is carried to linear units at the value
        scale = value * math.log(10.0) if f.log else 1.0
        out[f"{f.group}.{f.name}"] = {
            "value": value,
            "sigma": float(sigmas[k]) * scale,
            "prior": f.prior,
            "constrained": bool(sigmas[k] < 0.5 * f.sigma),
        }
    residual = measured - predicted(fit.x)
    residual = residual[np.abs(residual) < 10.0]  # the model's dark epochs left out
    return Calibration(
        magnitude_offset=float(fit.x[0]) if offset else 0.0,
        parameters=out,
        correlation=np.nan_to_num(correlation),
        train_rms_mag=float(np.sqrt(np.mean(residual**2))),
        n_observations=len(measured),
        materials=_materials(model, free, fit.x[layout.materials]),
        shadows=shadows,
        offset_deg=fit.x[layout.angles].copy() if attitude_offsets else np.zeros(3),
        joint_offsets_deg={p: float(v) for p, v in zip(joints, fit.x[layout.joints], strict=True)},
        earthshine=with_earth,
    )


#: Iterations of the short fit that screens each start of :func:`calibrate`.
_SCREEN_NFEV = 10

#: Names of the fitted attitude offsets (3-2-1 Euler angles of the body from its profile).
ATTITUDE_OFFSETS = ("offset_roll_deg", "offset_pitch_deg", "offset_yaw_deg")


@dataclass(frozen=True)
class _Layout:
    """Where each kind of unknown sits in the fit's vector: the magnitude offset, the
    attitude offsets (deg), the joint offsets (deg), the BRDF parameters (search
    coordinates)."""

    offset: bool
    attitude_offsets: bool
    n_joints: int
    n_materials: int

    @property
    def n_angles(self) -> int:
        return 3 if self.attitude_offsets else 0

    @property
    def size(self) -> int:
        return int(self.offset) + self.n_angles + self.n_joints + self.n_materials

    @property
    def angles(self) -> slice:
        first = int(self.offset)
        return slice(first, first + self.n_angles)

    @property
    def joints(self) -> slice:
        first = int(self.offset) + self.n_angles
        return slice(first, first + self.n_joints)

    @property
    def materials(self) -> slice:
        return slice(self.size - self.n_materials, self.size)


def _joint_parts(model: Shape, names: Sequence[str]) -> list[str]:
    """The parts whose joint offsets are fitted, checked: moving parts of ``model``."""
    names = list(dict.fromkeys(names))
    if not names:
        return []
    moving = [p.name for p in _as_articulated(model).articulation.moving]
    unknown = [n for n in names if n not in moving]
    if unknown:
        raise ValueError(
            f"calibration: {model.name} has no moving part(s) {', '.join(unknown)} "
            f"(moving parts: {', '.join(moving) or 'none'})"
        )
    return names


def _stored_offset(model: Shape, part: str) -> float:
    """The joint offset (deg) the library stores for ``part``."""
    parts = _as_articulated(model).articulation.parts
    return float(next(p.joint.offset_deg for p in parts if p.name == part))


def _turned(q: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Attitudes ``q_off ⊗ q`` of the offsets ``[roll, pitch, yaw]`` (deg); ``q`` itself
    without offsets."""
    if len(angles) == 0:
        return q
    return quaternion_multiply(offset_quaternion(angles), q)


def _free_parameters(
    model: Shape, names: Sequence[str], prior_dex: float, prior_fraction: float
) -> list[_Free]:
    """The fitted parameters named ``"group.name"`` (or ``"group.*"``), with their priors."""
    free: list[_Free] = []
    for entry in names:
        group, _, name = entry.partition(".")
        if group not in model.materials:
            known = ", ".join(model.materials)
            raise ValueError(f"calibration: no material group {group!r} (the shape has {known})")
        material = model.materials[group]
        info = brdf.describe(material.brdf)
        chosen = info.parameter_names if name == "*" else (name,)
        for each in chosen:
            if each not in info.parameter_names:
                raise ValueError(
                    f"calibration: {material.brdf} has no parameter {each!r} "
                    f"(it has {', '.join(info.parameter_names)})"
                )
            spec = info.parameter(each)
            prior = float(material.params.get(each, spec.default))
            lo, hi = spec.fit_range
            log = spec.log_scale
            sigma = prior_dex if log else prior_fraction * (hi - lo)
            lower = max(lo, spec.lower) if not log else max(lo, 1e-12)
            free.append(_Free(group, each, prior, sigma, log, lower, hi))
    return free


def _materials(model: Shape, free: Sequence[_Free], x: np.ndarray) -> dict[str, Material]:
    """The model's materials with the fitted values ``x`` (search coordinates). Lobe weights
    whose sum would exceed one are scaled down to sum to one (energy conservation)."""
    params = {g: dict(m.params) for g, m in model.materials.items()}
    for f, value in zip(free, x, strict=True):
        params[f.group][f.name] = f.from_search(float(value))
    out = {}
    for group, values in params.items():
        material = model.materials[group]
        weights = [k for k in brdf.describe(material.brdf).weights if k in values]
        total = sum(values[k] for k in weights)
        if total > 1.0:
            for k in weights:
                values[k] *= (1.0 - 1e-9) / total
        out[group] = Material(material.brdf, values, name=material.name)
    return out


def _subset(observations: Observations, rows: np.ndarray) -> Observations:
    """The observations of the rows selected by a mask."""
    return replace(observations, table=observations.table[rows].reset_index(drop=True))


def night_index(mjd: np.ndarray, longitude_deg: float) -> np.ndarray:
    """The night of each observation: the local mean solar date of the evening it began,
    ``⌊MJD + λ/360° − ½⌋`` (``λ`` east longitude), so that one night keeps one index
    across midnight."""
    return np.floor(np.asarray(mjd, dtype=float) + longitude_deg / 360.0 - 0.5).astype(int)


def cross_validate(
    model: Shape,
    q: np.ndarray,
    observations: Observations,
    nights: np.ndarray,
    *,
    folds: int = 5,
    seed: int = 0,
    **options: Any,
) -> dict[str, Any]:
    """k-fold cross-validation of :func:`calibrate` by night.

    The nights are shuffled (``numpy.random.default_rng(seed)``) and dealt into ``folds``
    groups; each group is predicted by the calibration on the others. ``seed`` is also the
    seed of every calibration's starts; ``options`` go to :func:`calibrate`.

    Returns
    -------
    dict
        ``train_rms_mag`` (the calibration on every night), ``cv_rms_mag`` and
        ``cv_bias_mag`` (rms and mean of measured − predicted over every held-out
        observation), ``folds`` (per fold: nights, observations, rms, bias) and
        ``calibration`` (on every night).
    """
    nights = np.asarray(nights)
    unique = np.unique(nights)
    if folds < 2 or folds > len(unique):
        raise ValueError(f"folds must be between 2 and the {len(unique)} nights, got {folds}")
    order = np.random.default_rng(seed).permutation(unique)
    held_out = np.full(len(nights), np.nan)
    per_fold = []
    for k in range(folds):
        test = np.isin(nights, order[k::folds])
        train = _subset(observations, ~test)
        calibration = calibrate(model, np.asarray(q)[~test], train, seed=seed, **options)
        test_obs = _subset(observations, test)
        predicted = calibration.magnitude(model, np.asarray(q)[test], test_obs)
        residual = test_obs.magnitudes - predicted  # +inf where the model is dark: left out
        residual = np.where(np.isfinite(residual), residual, np.nan)
        held_out[test] = residual
        per_fold.append(
            {
                "nights": len(order[k::folds]),
                "observations": int(test.sum()),
                "rms_mag": float(np.sqrt(np.nanmean(residual**2))),
                "bias_mag": float(np.nanmean(residual)),
            }
        )
    everything = calibrate(model, q, observations, seed=seed, **options)
    return {
        "train_rms_mag": everything.train_rms_mag,
        "cv_rms_mag": float(np.sqrt(np.nanmean(held_out**2))),
        "cv_bias_mag": float(np.nanmean(held_out)),
        "folds": per_fold,
        "calibration": everything,
    }
