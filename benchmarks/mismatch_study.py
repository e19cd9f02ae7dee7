"""Cases of the model-mismatch study: geometry, truths, candidates and the score of one run.

:mod:`benchmarks.mismatch` runs these over many seeded cases and aggregates them; the test
of the benchmark calls them with short arcs. A **case** is one object seen in one scenario:

- the object: a library shape (the *parent*) and a perturbation of it
  (:func:`shapes.perturbed_model`: stretch ±15 % along the principal axes, reflectances
  ±30 %, lobe exponents ×/÷ 2, principal moments 5–10 % off with axes tilted ≤ 5°, an
  antenna or thruster where a face can hold it), tumbling torque-free from a uniform random
  attitude with rates of uniform direction and magnitude uniform in ``RATE_DEG_S``. Case
  ``i`` draws the object from ``numpy.random.default_rng([seed, i, 0])``, so the same object
  is seen in every scenario;
- the scenario (geometry from ``default_rng([seed, i, 1 + k])`` for the k-th scenario of
  :data:`SCENARIOS`), seen from Mount Lemmon on a night drawn in 2024 January–February:

  ``geo``
      a geostationary slot at a longitude uniform in [−130°, −70°], an arc of
      ``GEO_DURATION_S`` (40 min) from a start uniform in the dark hours, one measurement
      per ``CADENCE_S`` (2 s);
  ``leo``
      a circular low orbit (altitude uniform in [500, 1200] km, inclination in [45°, 100°],
      node and argument of latitude uniform), redrawn until the night holds a pass of at
      least ``LEO_MIN_PASS_S`` with the object above 10° elevation, sunlit and the site's
      Sun below −12°; the longest such pass at 2 s;

- the light curves: the perturbed object and (``exact``) the parent itself, both rendered
  with ray-cast shadows (``shadows="exact"``), with the same Gaussian noise of
  ``NOISE_MAG`` (0.03 mag) drawn from ``default_rng([seed, i, 10 + k])``.

Attitude errors are measured at the last epoch modulo the parent's symmetry group (the
perturbed object's body frame is the parent's), rate errors with the same group element.
"""

from __future__ import annotations

import contextlib
import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from benchmarks._orbits import random_low_orbit
from filters.attitude import (
    quaternion_conjugate,
    quaternion_multiply,
    quaternion_to_rotation_vector,
    random_quaternion,
)
from filters.attitude.inertia import ratios_from_tanh, tanh_from_inertia
from filters.gaussian import mahalanobis_squared
from filters.symmetry import SymmetryGroup
from lightcurve.inversion import InversionResult, shape_symmetry
from lightcurve.io.observations import Observations
from lightcurve.photometry.render import Renderer
from lightcurve.photometry.simulate import GaussianNoise, simulate
from lightcurve.sky.ephemeris import (
    EARTH_RADIUS_KM,
    CircularOrbit,
    orbit_geometry,
    site_position,
    sun_position,
)
from lightcurve.sky.geometry import reciprocity_twin
from lightcurve.sky.shadow_earth import earth_shadow
from lightcurve.sky.sites import get_site
from shapes import FacetModel, Perturbation, get_library, perturbed_model

__all__ = [
    "SCENARIOS",
    "Case",
    "candidates",
    "draw_case",
    "geo_geometry",
    "leo_geometry",
    "score",
    "simulate_case",
    "truth_parameters",
]

SCENARIOS = ("geo", "leo")
SITE = "Mount Lemmon"
NOISE_MAG = 0.03
CADENCE_S = 2.0
GEO_DURATION_S = 2400.0
RATE_DEG_S = (0.3, 1.5)
LEO_MIN_PASS_S = 300.0
#: Step (s) of the scan of a night for low-orbit passes.
LEO_SCAN_STEP_S = 20.0
MAX_GEOMETRY_DRAWS = 500
#: First night (UTC MJD 60324 = 2024-01-15) and the number of nights drawn from.
FIRST_NIGHT_MJD = 60324.0
NIGHTS = 40
_GATE_NOTE = re.compile(r"(\d+) measurement\(s\) rejected by the innovation gate")


@dataclass(frozen=True)
class Case:
    """One object in one scenario (module docstring).

    Attributes
    ----------
    scenario : str
    index : int
    parent : str
        Library name of the shape the object was drawn from.
    perturbation : Perturbation
    q0 : (4,) numpy.ndarray
        Attitude at the first epoch, inertial → body, scalar last.
    omega0 : (3,) numpy.ndarray
        Body rates at the first epoch, rad/s.
    geometry : Observations
        Epochs and Sun/observer vectors (no magnitudes).
    geometry_record : dict
        How the geometry was drawn (night, slot or orbit, redraws).
    noise_seed : int
        Seed of the noise of both light curves.
    inversion_seed : int
        ``seed`` passed to :func:`lightcurve.inversion.invert`.
    """

    scenario: str
    index: int
    parent: str
    perturbation: Perturbation
    q0: np.ndarray
    omega0: np.ndarray
    geometry: Observations
    geometry_record: dict[str, Any]
    noise_seed: int
    inversion_seed: int

    def record(self) -> dict[str, Any]:
        """JSON-ready description of the case (the perturbation in full)."""
        return {
            "scenario": self.scenario,
            "run": self.index,
            "parent": self.parent,
            "q0": [float(v) for v in self.q0],
            "omega0_deg_s": [math.degrees(float(v)) for v in self.omega0],
            "rate_deg_s": math.degrees(float(np.linalg.norm(self.omega0))),
            "epochs": len(self.geometry),
            "geometry": self.geometry_record,
            "noise_seed": self.noise_seed,
            "inversion_seed": self.inversion_seed,
            "perturbation": self.perturbation.to_dict(),
        }


def _unit(rows: np.ndarray) -> np.ndarray:
    return rows / np.linalg.norm(rows, axis=-1, keepdims=True)


def geo_geometry(
    rng: np.random.Generator,
    duration_s: float = GEO_DURATION_S,
    cadence_s: float = CADENCE_S,
) -> tuple[Observations, dict[str, Any]]:
    """A geostationary arc (module docstring), redrawn until 90 % of its epochs are kept."""
    site = get_site(SITE)
    for draws in range(MAX_GEOMETRY_DRAWS):
        night = FIRST_NIGHT_MJD + int(rng.integers(0, NIGHTS))
        start = night + rng.uniform(2.0, 12.5 - duration_s / 3600.0) / 24.0
        longitude = float(rng.uniform(-130.0, -70.0))
        mjd = start + np.arange(0.0, duration_s, cadence_s) / 86400.0
        try:
            geometry = orbit_geometry(CircularOrbit.geostationary(longitude, start), site, mjd)
        except ValueError:  # no epoch dark, high and sunlit
            continue
        if len(geometry) >= 0.9 * len(mjd):
            record = {"start_mjd": start, "longitude_deg": longitude, "redraws": draws}
            return geometry, record
    raise RuntimeError(f"no geostationary arc kept 90 % of its epochs in {MAX_GEOMETRY_DRAWS}")


def leo_geometry(
    rng: np.random.Generator,
    min_pass_s: float = LEO_MIN_PASS_S,
    cadence_s: float = CADENCE_S,
) -> tuple[Observations, dict[str, Any]]:
    """The longest observable pass of a low circular orbit over one night (module
    docstring), the orbit redrawn until it lasts ``min_pass_s``."""
    site = get_site(SITE)
    night = FIRST_NIGHT_MJD + int(rng.integers(0, NIGHTS))
    scan = night + np.arange(0.0, 15 * 3600.0, LEO_SCAN_STEP_S) / 86400.0
    r_site, r_sun = site_position(site, scan), sun_position(scan)
    up = _unit(r_site)
    dark = np.sum(up * _unit(r_sun), axis=1) <= math.sin(math.radians(-12.0))
    for draws in range(MAX_GEOMETRY_DRAWS):
        orbit = random_low_orbit(rng, night)
        r_obj = orbit.position(scan)
        high = np.sum(up * _unit(r_obj - r_site), axis=1) >= math.sin(math.radians(10.0))
        lit = ~earth_shadow(r_obj, r_sun, "cylindrical").in_umbra
        first, last = _longest_run(dark & high & lit)
        if (last - first) * LEO_SCAN_STEP_S < min_pass_s:
            continue
        step = LEO_SCAN_STEP_S / 86400.0
        mjd = np.arange(scan[first] - step, scan[last] + step, cadence_s / 86400.0)
        try:
            geometry = orbit_geometry(orbit, site, mjd)
        except ValueError:
            continue
        if (len(geometry) - 1) * cadence_s >= min_pass_s:
            record = {
                "night_mjd": night,
                "altitude_km": orbit.radius_km - EARTH_RADIUS_KM,
                "inclination_deg": orbit.inclination_deg,
                "raan_deg": orbit.raan_deg,
                "argument_of_latitude_deg": orbit.argument_of_latitude_deg,
                "pass_s": float((geometry.mjd[-1] - geometry.mjd[0]) * 86400.0),
                "max_elevation_deg": float(np.max(geometry.table["elevation_deg"])),
                "redraws": draws,
            }
            return geometry, record
    raise RuntimeError(f"no low orbit gave a {min_pass_s:g} s pass in {MAX_GEOMETRY_DRAWS} draws")


def _longest_run(mask: np.ndarray) -> tuple[int, int]:
    """First and last index of the longest run of True (0, 0 when none)."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    if not len(edges):
        return 0, 0
    starts, stops = edges[::2], edges[1::2]
    k = int(np.argmax(stops - starts))
    return int(starts[k]), int(stops[k] - 1)


def draw_case(
    seed: int,
    index: int,
    scenario: str,
    parent: str,
    *,
    geo_duration_s: float = GEO_DURATION_S,
    leo_min_pass_s: float = LEO_MIN_PASS_S,
) -> Case:
    """Case ``index`` of ``scenario`` with the object drawn around library shape ``parent``."""
    k = SCENARIOS.index(scenario)
    body = np.random.default_rng([seed, index, 0])
    model = get_library().load(parent)
    perturbation = perturbed_model(model, body)
    q0 = random_quaternion((), body)
    omega0 = _unit(body.standard_normal(3)) * math.radians(body.uniform(*RATE_DEG_S))
    where = np.random.default_rng([seed, index, 1 + k])
    if scenario == "geo":
        geometry, record = geo_geometry(where, geo_duration_s)
    else:
        geometry, record = leo_geometry(where, leo_min_pass_s)
    noise = np.random.default_rng([seed, index, 10 + k])
    return Case(
        scenario=scenario,
        index=index,
        parent=parent,
        perturbation=perturbation,
        q0=q0,
        omega0=omega0,
        geometry=geometry,
        geometry_record=record,
        noise_seed=int(noise.integers(2**31)),
        inversion_seed=int(noise.integers(2**31)),
    )


def simulate_case(case: Case, truth: str) -> Observations:
    """The light curve of the perturbed object (``truth="perturbed"``) or of its parent
    (``"exact"``), ray-cast shadows, Gaussian noise from the case's noise seed."""
    model = case.perturbation.model if truth == "perturbed" else get_library().load(case.parent)
    return simulate(
        case.geometry,
        model,
        q0=case.q0,
        omega0=case.omega0,
        noise=GaussianNoise(NOISE_MAG),
        shadows="exact",
        seed=case.noise_seed,
    )


def candidates(
    method: str, parent: str, index: int, bank: list[str], pf_shapes: int, foreign: bool = False
) -> list[str]:
    """Candidate shapes of a run: the parent alone (``ukf``); the bank (``mmae``), without
    the parent when ``foreign``; the parent and ``pf_shapes − 1`` others of the bank taken in
    turn from run ``index`` on (``pf``)."""
    others = [name for name in bank if name != parent]
    if method == "ukf":
        return [parent]
    if method == "mmae":
        return others if foreign else [parent, *others]
    return [parent] + [others[(index + k) % len(others)] for k in range(pf_shapes - 1)]


def truth_parameters(case: Case, truth: str, observations: Observations) -> dict[str, float]:
    """True values of the parameters an inversion may estimate, named as in
    ``InversionResult.parameters``: ``k1, k2`` (tanh inertia about the parent's principal
    axes, from the diagonal of the true tensor there), ``magnitude_offset`` (median of the
    noiseless magnitude minus the parent's at the true states, mag) and, for a perturbed
    truth, ``stretch_1..3``; plus ``mismatch_rms_mag``, the rms of that difference about
    its median (how far the object's light curve is from any offset copy of the parent's)."""
    parent = get_library().load(case.parent)
    axes = parent.principal_axes
    if truth == "exact":
        moments = parent.principal_moments
    else:
        moments = np.diag(axes.T @ case.perturbation.inertia @ axes)
    out: dict[str, float] = {}
    with contextlib.suppress(ValueError):  # a plate: the tanh form needs J3 < J1 + J2
        out["k1"], out["k2"] = (float(v) for v in tanh_from_inertia(moments))
    states = observations.truth
    sun, observer = observations.sun_vectors, observations.observer_vectors
    model = case.perturbation.model if truth == "perturbed" else parent
    difference = _magnitudes(model, states, sun, observer) - _magnitudes(
        parent, states, sun, observer
    )
    difference = difference[np.isfinite(difference)]
    offset = float(np.median(difference)) if difference.size else math.nan
    out["magnitude_offset"] = offset
    out["mismatch_rms_mag"] = (
        float(np.sqrt(np.mean((difference - offset) ** 2))) if difference.size else math.nan
    )
    if truth == "perturbed":
        for axis, factor in enumerate(case.perturbation.stretch, start=1):
            out[f"stretch_{axis}"] = float(factor)
    return out


def _magnitudes(model: FacetModel, states: np.ndarray, sun: np.ndarray, observer: np.ndarray):
    return np.asarray(Renderer(model, shadows="exact").magnitude(states[:, :4], sun, observer))


def score(
    result: InversionResult,
    observations: Observations,
    case: Case,
    truths: dict[str, float],
) -> dict[str, Any]:
    """Figures of one inversion against the truth (see :mod:`benchmarks.mismatch`)."""
    parent = case.parent
    record: dict[str, Any] = {
        "shape": result.shape,
        "p_parent": (
            float(result.shape_probabilities[parent])
            if parent in result.shape_probabilities
            else None
        ),
        "probabilities": {k: float(v) for k, v in result.shape_probabilities.items()},
        "none_fits": bool(result.none_fits),
        "quaternion": [float(v) for v in result.quaternion],
        "omega_deg_s": [math.degrees(float(v)) for v in result.omega_rad_s],
        "attitude_sigma_deg": float(result.attitude_sigma_deg),
        "residual_rms_mag": float(result.residual_rms_mag),
        "n_measurements": int(result.n_measurements),
        "rejected_fraction": _rejected_fraction(result),
        "runtime_s": float(result.runtime_s),
        "notes": list(result.notes),
    }
    if result.shape == parent:
        record.update(_state_errors(result, observations, get_library().load(parent)))
    values = {k: _value(v) for k, v in result.parameters.items()}
    record["parameters"] = values
    record["parameter_sigmas"] = {
        k: float(v["sigma"]) for k, v in result.parameters.items() if isinstance(v, dict)
    }
    record["model_error_mag"] = float(getattr(result, "model_error_mag", math.nan))
    record["parameter_errors"] = {k: v - truths[k] for k, v in values.items() if k in truths}
    if "k1" in values and "k1" in truths:
        estimated = ratios_from_tanh(np.array([values["k1"], values["k2"]]))
        true = ratios_from_tanh(np.array([truths["k1"], truths["k2"]]))
        record["inertia_ratio_error"] = float(np.max(np.abs(estimated - true)))
    return record


def _value(entry: Any) -> float:
    """An estimated parameter's value: ``{"value", "sigma"}`` or a bare number."""
    return float(entry["value"] if isinstance(entry, dict) else entry)


def _state_errors(
    result: InversionResult, observations: Observations, parent: FacetModel
) -> dict[str, Any]:
    """Final attitude error (deg) and rate error (deg/s) modulo the parent's symmetry (the
    rates turned by the group element that brings the truth closest), the truth inside the
    reported 3σ (attitude error ≤ 3 × the total 1σ), and the NEES of ``[δθ, ω]``."""
    group = shape_symmetry(parent)
    truth = observations.truth[-1]
    q, omega = result.quaternion, result.omega_rad_s
    q_true, element = group.closest(q, truth[:4])
    omega_true = group.equivalent_rates(truth[4:])[int(element)]
    dtheta = quaternion_to_rotation_vector(quaternion_multiply(q_true, quaternion_conjugate(q)))
    attitude = math.degrees(float(group.attitude_error(q, truth[:4])))
    error = np.concatenate([dtheta, omega_true - omega])
    covariance = np.asarray(result.covariance, float)[:6, :6]
    nees: float | None = None
    if np.all(np.isfinite(covariance)):
        try:
            nees = float(mahalanobis_squared(error, covariance))
        except np.linalg.LinAlgError:
            nees = math.inf
    twins = _twin_errors(group, q, truth, observations)
    nearest = min(twins, key=twins.get) if twins else None
    return {
        "attitude_error_deg": attitude,
        "rate_error_deg_s": math.degrees(float(np.linalg.norm(omega_true - omega))),
        "inside_3_sigma": bool(attitude <= 3.0 * result.attitude_sigma_deg),
        "nees": nees,
        "attitude_error_or_twin_deg": min(attitude, twins[nearest]) if twins else attitude,
        "nearest_twin": nearest if twins and twins[nearest] < attitude else None,
    }


def _twin_errors(
    group: SymmetryGroup, q: np.ndarray, truth: np.ndarray, observations: Observations
) -> dict[str, float]:
    """Attitude error (deg, modulo the group) of ``q`` from the photometric twins of the
    true final state under the final geometry: the reciprocity twin
    (:func:`lightcurve.sky.geometry.reciprocity_twin`), and for a mirror-symmetric shape the
    mirror twin (:meth:`filters.symmetry.SymmetryGroup.mirror_twin`) and its reciprocity
    twin. Each renders as the truth does while the geometry stands still; a long arc tells
    them apart, so an estimate at a twin is an ambiguity the arc did not resolve."""
    sun, observer = observations.sun_vectors[-1], observations.observer_vectors[-1]
    twins = {"reciprocity": reciprocity_twin(truth[:4], sun, observer)}
    mirror = group.mirror_twin(truth[:4], truth[4:], sun, observer)
    if mirror is not None:
        twins["mirror"] = mirror[0]
        twins["mirror_reciprocity"] = reciprocity_twin(mirror[0], sun, observer)
    return {
        name: math.degrees(float(group.attitude_error(q, np.asarray(twin, float))))
        for name, twin in twins.items()
    }


def _rejected_fraction(result: InversionResult) -> float | None:
    """Fraction of the measurements rejected by the innovation gate: the result's
    ``rejected_fraction`` when it has one, else read from its notes (None for a method
    without a gate)."""
    value = getattr(result, "rejected_fraction", None)
    if value is not None:
        return float(value)
    for note in result.notes:
        match = _GATE_NOTE.search(note)
        if match:
            return int(match.group(1)) / max(int(result.n_measurements), 1)
    return None if result.method == "pf" else 0.0
