"""Photometric observation scheduling: the magnitude Jacobian, the error-state transition and
planned vs uniform epochs for a tumbling box-wing (a reduced ``benchmarks/planner.py`` study)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import torch

import shapes
from filters.attitude import (
    inertia_from_normalized,
    quaternion_conjugate,
    quaternion_multiply,
    random_quaternion,
    rk4_step,
    torque_free_derivative,
)
from lightcurve import io
from lightcurve.analysis.photometric_planning import PhotometricPlanningModel, compare_schedules
from lightcurve.io.observations import Observations

ROOT = Path(__file__).resolve().parents[3]
GEOMETRY = ROOT / "data" / "geometry" / "geo_mount_lemmon.csv"
SIGMA_MAG = 0.03


@pytest.fixture(scope="module")
def box_wing():
    return shapes.get_library().load("box_wing")


@pytest.fixture(scope="module")
def geometry():
    """The 20-minute GEO geometry, one candidate epoch every 5 s (241 epochs)."""
    full = io.read(GEOMETRY, require_magnitudes=False)
    return Observations(full.table.iloc[::5].reset_index(drop=True), full.meta, full.source)


def tumbling_states(model, inertia, runs: int, seed: int) -> np.ndarray:
    """Uniform attitudes, rates of 0.5–2 °/s in uniform directions (body frame)."""
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=(runs, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    omega = axis * np.radians(rng.uniform(0.5, 2.0, (runs, 1)))
    return model.state(random_quaternion(runs, rng), omega, inertia)


def test_magnitude_jacobian_matches_finite_differences(box_wing, geometry):
    model = PhotometricPlanningModel.from_observations(geometry, box_wing, SIGMA_MAG)
    rng = np.random.default_rng(3)
    x = model.state(random_quaternion(24, rng), np.zeros(3), box_wing.inertia)
    steps = rng.integers(0, model.n_epochs, 24)
    magnitude, jac = model.magnitude_jacobian(x, steps)
    assert np.all(np.isfinite(magnitude)) and np.all(jac[:, 3:] == 0.0)
    eps = 1e-6
    numeric = np.stack(
        [
            (model.magnitude_at(x, steps, eps * e) - model.magnitude_at(x, steps, -eps * e))
            / (2 * eps)
            for e in np.eye(3)
        ],
        axis=-1,
    )
    scale = np.abs(jac).max(axis=1, keepdims=True)
    np.testing.assert_allclose(jac[:, :3] / scale, numeric / scale, atol=1e-6)


def test_information_is_rank_one_and_zero_at_dark_epochs(box_wing):
    # Observer opposite the Sun (phase angle 180°): no facet is both lit and seen.
    sun = np.array([[1.5e11, 0.0, 0.0]] * 2)
    observer = np.array([[3.6e7, 1.0e6, 2.0e6], [-3.6e7, 0.0, 0.0]])
    table = Observations(
        io.read(GEOMETRY, require_magnitudes=False).table.iloc[:2].reset_index(drop=True)
    )
    model = dataclasses.replace(
        PhotometricPlanningModel.from_observations(table, box_wing, SIGMA_MAG),
        sun=sun,
        observer=observer,
    )
    x = model.state(random_quaternion(2, 5), np.zeros(3), box_wing.inertia)
    info = model.information(np.repeat(x, 2, axis=0), np.array([0, 0, 1, 1]))
    magnitude, jac = model.magnitude_jacobian(np.repeat(x, 2, axis=0), np.array([0, 0, 1, 1]))
    lit = np.isfinite(magnitude)
    np.testing.assert_array_equal(lit, [True, True, False, False])
    assert np.all(info[~lit] == 0.0)
    np.testing.assert_allclose(info[lit], jac[lit, :, None] * jac[lit, None, :] / SIGMA_MAG**2)
    assert np.all(np.linalg.matrix_rank(info[lit], tol=1e-8 * info[lit].max()) == 1)


@pytest.mark.parametrize("estimate_inertia", [False, True])
def test_transition_matches_the_rk4_jacobian(box_wing, geometry, estimate_inertia):
    base = PhotometricPlanningModel.from_observations(
        geometry, box_wing, SIGMA_MAG, estimate_inertia=estimate_inertia
    )
    n = base.n_states
    x = base.state(random_quaternion(1, 1), np.radians([[3.0, -2.0, 4.0]]), np.diag([1, 2, 2.5]))
    dt = float(base.times[1] - base.times[0])
    reference = torch.as_tensor(base.predict(x, 0)[0])

    def step(delta: torch.Tensor) -> torch.Tensor:
        """RK4 map of the perturbed state, in the error coordinates around the prediction."""
        x0 = torch.as_tensor(x[0])
        dq = torch.cat([delta[:3], torch.sqrt(1 - delta[:3] @ delta[:3])[None]])
        l = x0[7:] + (delta[6:] if n == 11 else 0.0)
        state = torch.cat([quaternion_multiply(dq, x0[:4]), x0[4:7] + delta[3:6]])
        f = torque_free_derivative(inertia_from_normalized(l))
        for _ in range(32):
            state = rk4_step(f, state, dt / 32)
        error = quaternion_multiply(state[:4], quaternion_conjugate(reference[:4]))[:3]
        parts = [error, state[4:7] - reference[4:7]] + ([l - reference[7:]] if n == 11 else [])
        return torch.cat(parts)

    zero = torch.zeros(n, dtype=torch.float64)
    jac = torch.autograd.functional.jacobian(step, zero, vectorize=True).numpy()
    errors = []
    for substeps in (4, 8):
        phi, _ = dataclasses.replace(base, max_substep=dt / substeps).linearize(x, 0)
        errors.append(np.abs(phi[0] - jac).max() / np.abs(jac).max())
    # Second order in the substep (13° of rotation per substep at 4 substeps: 2.3e-3).
    assert errors[1] < 1e-3
    assert 3.0 < errors[0] / errors[1] < 5.0


def test_process_noise_at_rest_is_the_closed_form(box_wing, geometry):
    rate_noise = 2e-6
    model = PhotometricPlanningModel.from_observations(
        geometry, box_wing, SIGMA_MAG, rate_noise=rate_noise, max_substep=2.0
    )
    x = model.state(random_quaternion(1, 2), np.zeros(3), box_wing.inertia)
    phi, q = model.linearize(x, 0)
    dt = model.times[1] - model.times[0]
    # At rest δq̇_v = δω/2, δω̇ = w: the integrated random walk.
    s = rate_noise**2
    expected = np.block(
        [
            [s * dt**3 / 12 * np.eye(3), s * dt**2 / 4 * np.eye(3)],
            [s * dt**2 / 4 * np.eye(3), s * dt * np.eye(3)],
        ]
    )
    np.testing.assert_allclose(q[0], expected, rtol=1e-9, atol=1e-30)
    np.testing.assert_allclose(
        phi[0], np.block([[np.eye(3), dt / 2 * np.eye(3)], [0 * np.eye(3), np.eye(3)]]), atol=1e-14
    )


def test_planned_epochs_beat_uniform_spacing(box_wing, geometry):
    """Reduced study: 3 tumbling runs, 24 of 240 epochs, 6 and 11 error states."""
    p0 = np.diag([np.radians(5.0) ** 2 / 4] * 3 + [np.radians(0.05) ** 2] * 3)
    for estimate_inertia in (False, True):
        model = PhotometricPlanningModel.from_observations(
            geometry, box_wing, SIGMA_MAG, rate_noise=1e-7, estimate_inertia=estimate_inertia
        )
        x0 = tumbling_states(model, box_wing.inertia, 3, seed=9)
        prior = p0 if not estimate_inertia else np.diag([*np.diag(p0), *[0.01] * 5])
        study = compare_schedules(model, x0, prior, budget=24)
        assert np.all(study.taken["planned"].sum(axis=1) == 24)
        ratio = study.ratio()
        assert np.all(ratio < 0.5), ratio
        # Accounting for the dynamics and the prior beats taking the brightest-gradient epochs.
        assert np.all(ratio < study.ratio("largest_information"))


def test_geometry_only_tables_need_a_magnitude_noise(box_wing):
    geometry = io.read(GEOMETRY, require_magnitudes=False)
    with pytest.raises(ValueError, match=r"geo_mount_lemmon\.csv.*sigma_mag"):
        PhotometricPlanningModel.from_observations(geometry, box_wing)
    with pytest.raises(ValueError, match="sigma_mag"):
        PhotometricPlanningModel.from_observations(geometry, box_wing, sigma_mag=-1.0)
