"""Stereo relative-state and inertia EKF (Feng et al.): model, Jacobians, seeded Monte Carlo."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from scipy.linalg import expm

from filters.attitude import (
    euler321_to_quaternion,
    euler_rate_principal,
    quaternion_conjugate,
    quaternion_multiply,
    quaternion_to_rotation_vector,
    ratios_from_tanh,
    rk4_step,
    rotate,
    rotation_vector_to_quaternion,
)
from filters.gaussian import discrete_process_noise
from filters.navigation.camera import PinholeCamera
from filters.navigation.hill import mean_motion
from filters.navigation.stereo import (
    StereoCamera,
    StereoEKF,
    _transition_and_noise,
    feature_points,
    relative_attitude_derivative,
    rotational_error_matrix,
)
from lightcurve.studies.stereo import StereoScenario, run_monte_carlo

N = mean_motion(6878.137e3)
M_CAM = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
PAIR = StereoCamera(PinholeCamera.from_fov(60.0, 2048), 1.0)
COORDS = np.array(
    [
        [0.5, 0.5, 0.5],
        [-0.5, 0.5, -0.5],
        [0.5, -0.5, -0.5],
        [-0.5, -0.5, 0.5],
        [-0.5, -0.5, -0.5],
        [0.5, 0.5, -0.5],
        [0.5, -0.5, 0.5],
        [-0.5, 0.5, 0.5],
        [0.5, 0.0, 0.0],
        [0.0, 0.5, 0.0],
        [0.0, 0.0, 0.5],
        [-0.5, 0.0, 0.0],
    ]
)


def scenario(**changes) -> StereoScenario:
    """The nominal scenario of data/scenarios/stereo_nominal.toml, shortened for tests."""
    base = StereoScenario(
        mean_motion=N,
        camera_from_hill=M_CAM,
        stereo=PAIR,
        feature_coordinates=COORDS,
        feature_count=4,
        target_size=1.0,
        inertia=np.array([100.0, 160.0, 130.0]),
        attitude=euler321_to_quaternion(np.radians([30.0, 20.0, 10.0])),
        omega=np.radians([1.0, 2.0, 1.5]),
        position=np.array([0.0, 10.0, 0.0]),
        velocity=np.array([-2.767e-3, 0.0, 1.107e-3]),
        angle_noise=1e-5,
        angular_acceleration_psd=1e-12,
        acceleration_psd=9e-14,
        duration=240.0,
        step=1.0,
        window=120.0,
        truth_substeps=2,
        initial_attitude_error=np.radians([1.0, -1.0, 1.0]),
        initial_k=np.zeros(2),
        sigma={
            "attitude": math.radians(1.0),
            "omega": math.radians(0.05),
            "k": 0.5,
            "position": 0.1,
            "velocity": 1e-3,
        },
    )
    return base.with_(**changes)


# --------------------------------------------------------------------------- stereo camera
def test_stereo_disparity_gives_depth():
    points = np.array([[0.3, -0.2, 12.0], [-1.0, 0.5, 25.0]])
    pix = PAIR.project(points)
    f = PAIR.focal_length
    np.testing.assert_allclose(pix[:, 0] - pix[:, 2], f * PAIR.baseline / points[:, 2])
    np.testing.assert_allclose(pix[:, 1], pix[:, 3])


def test_stereo_jacobian_matches_finite_differences():
    p = np.array([0.4, -0.3, 11.0])
    eps = 1e-6
    numeric = np.stack(
        [(PAIR.project(p + eps * e) - PAIR.project(p - eps * e)) / (2 * eps) for e in np.eye(3)],
        axis=-1,
    )
    np.testing.assert_allclose(PAIR.jacobian(p), numeric, rtol=1e-7)


def test_bad_baseline_rejected():
    with pytest.raises(ValueError, match="baseline"):
        StereoCamera(PAIR.camera, 0.0)


# --------------------------------------------------------------------------- error dynamics
def _error_after(dx, q_hat, w_hat, k_hat, omega_c, h):
    """Propagate estimate and perturbed truth by ``h`` and return their error (torch)."""
    q_true = quaternion_multiply(rotation_vector_to_quaternion(dx[:3]), q_hat)
    x_true = torch.cat([q_true, w_hat + dx[3:6]])
    x_hat = torch.cat([q_hat, w_hat])
    x_true = rk4_step(relative_attitude_derivative_torch(k_hat + dx[6:8], omega_c), x_true, h)
    x_hat = rk4_step(relative_attitude_derivative_torch(k_hat, omega_c), x_hat, h)
    dq = quaternion_multiply(x_true[:4], quaternion_conjugate(x_hat[:4]))
    return torch.cat([quaternion_to_rotation_vector(dq), x_true[4:] - x_hat[4:], dx[6:8]])


def relative_attitude_derivative_torch(k, omega_c):
    """The relative kinematics of :func:`relative_attitude_derivative`, written for torch."""
    from filters.attitude import quaternion_rate

    def f(x):
        q, w = x[:4], x[4:]
        w_rel = w - rotate(q, omega_c)
        return torch.cat([quaternion_rate(q, w_rel), euler_rate_principal(w, ratios_from_tanh(k))])

    return f


def test_error_dynamics_match_autograd_of_the_nonlinear_model():
    q_hat = torch.tensor(euler321_to_quaternion(np.radians([40.0, -25.0, 70.0])))
    w_hat = torch.tensor([0.03, -0.05, 0.04], dtype=torch.float64)
    k_hat = torch.tensor([0.4, -0.7], dtype=torch.float64)
    omega_c = torch.tensor(M_CAM @ [0, 0, N])
    h = 1e-3
    jac = torch.autograd.functional.jacobian(
        lambda dx: _error_after(dx, q_hat, w_hat, k_hat, omega_c, h),
        torch.zeros(8, dtype=torch.float64),
    ).numpy()
    f = rotational_error_matrix(w_hat.numpy(), k_hat.numpy())
    np.testing.assert_allclose((jac - np.eye(8)) / h, f, atol=2e-4)
    # The chaser-rate terms cancel in δθ̇ = −[ω×]δθ + δω: check it is ω, not ω − A ω_C.
    assert abs(f[0, 1] - w_hat[2].item()) < 1e-12


def test_numpy_derivative_matches_torch_version():
    x = np.concatenate(
        [euler321_to_quaternion(np.radians([10.0, 20.0, 30.0])), [0.01, 0.02, -0.03]]
    )
    k = np.array([0.2, -0.3])
    omega_c = M_CAM @ [0, 0, N]
    a = relative_attitude_derivative(ratios_from_tanh(k), omega_c)(x)
    b = relative_attitude_derivative_torch(torch.tensor(k), torch.tensor(omega_c))(torch.tensor(x))
    np.testing.assert_allclose(a, b.numpy(), atol=1e-15)


def test_series_discretisation_matches_van_loan():
    f = rotational_error_matrix(np.array([0.03, -0.05, 0.04]), np.array([0.4, -0.7]))
    gqg = np.zeros((8, 8))
    gqg[3:6, 3:6] = np.eye(3)  # Q_d is linear in Q: unit density keeps Van Loan well scaled
    phi, q = _transition_and_noise(f[None], gqg, 1.0)
    phi_ref, q_ref = discrete_process_noise(f, gqg, 1.0)
    np.testing.assert_allclose(phi[0], expm(f), atol=1e-12)
    np.testing.assert_allclose(phi[0], phi_ref, atol=1e-12)
    np.testing.assert_allclose(q[0], q_ref, rtol=1e-9, atol=1e-13)
    assert q[0, 0, 0] == pytest.approx(1 / 3, rel=1e-3)  # δθ variance of integrated noise


# --------------------------------------------------------------------------- measurement model
def _ekf(batch=(), **kw):
    q = euler321_to_quaternion(np.radians([30.0, 20.0, 10.0]))
    return StereoEKF(
        np.broadcast_to(q, (*batch, 4)),
        np.broadcast_to([0.02, 0.03, 0.025], (*batch, 3)),
        np.broadcast_to([0.1, -0.2], (*batch, 2)),
        np.broadcast_to([0.5, 12.0, -0.3], (*batch, 3)),
        np.broadcast_to([1e-3, 0, 2e-4], (*batch, 3)),
        np.broadcast_to(np.eye(14) * 1e-4, (*batch, 14, 14)),
        stereo=PAIR,
        features=COORDS[:4],
        mean_motion=N,
        camera_from_hill=M_CAM,
        angle_noise=1e-5,
        angular_acceleration_psd=1e-12,
        acceleration_psd=1e-13,
        **kw,
    )


def test_measurement_jacobian_matches_finite_differences():
    ekf = _ekf()
    _, h = ekf.predicted_measurement()

    def measure(dx):
        q = quaternion_multiply(rotation_vector_to_quaternion(dx[:3]), ekf.q)
        pts = feature_points(q, M_CAM @ (ekf.position + dx[8:11]), COORDS[:4])
        return PAIR.project(pts).reshape(-1)

    eps = 1e-7
    numeric = np.stack(
        [(measure(eps * e) - measure(-eps * e)) / (2 * eps) for e in np.eye(14)], axis=-1
    )
    np.testing.assert_allclose(h, numeric, rtol=1e-5, atol=1e-4)


def test_batch_of_filters_equals_single_filters():
    single, batch = _ekf(), _ekf((3,))
    rng = np.random.default_rng(5)
    pixels = single.predicted_measurement()[0] + 0.05 * rng.standard_normal((4, 4))
    single.predict(1.0)
    single.update(pixels)
    batch.predict(1.0)
    batch.update(np.broadcast_to(pixels, (3, 4, 4)))
    for i in range(3):
        np.testing.assert_allclose(batch.q[i], single.q, atol=1e-14)
        np.testing.assert_allclose(batch.P[i], single.P, rtol=1e-10, atol=1e-22)


def test_feature_and_covariance_shapes_are_checked():
    with pytest.raises(ValueError, match="N >= 3"):
        _ekf().__class__(
            [0, 0, 0, 1], [0, 0, 0], [0, 0], [0, 10, 0], [0, 0, 0], np.eye(14),
            stereo=PAIR, features=COORDS[:2], mean_motion=N, camera_from_hill=M_CAM,
            angle_noise=1e-5, angular_acceleration_psd=0, acceleration_psd=0,
        )  # fmt: skip
    with pytest.raises(ValueError, match="feature_count"):
        scenario(feature_count=13)
    with pytest.raises(ValueError, match="window"):
        scenario(window=500.0)


# --------------------------------------------------------------------------- Monte Carlo
@pytest.fixture(scope="module")
def nominal():
    return run_monte_carlo(scenario(), runs=16, seed=11)


def test_nominal_accuracy_meets_the_papers_figures(nominal):
    rt = nominal.rtmse
    assert rt["attitude_deg"] < 0.1
    assert rt["omega_rad_s"] < 6e-5
    assert rt["position_m"] <= 0.010
    assert rt["velocity_m_s"] <= 10e-6
    assert rt["inertia_k"] <= 0.02
    assert nominal.features_in_view == 1.0


def test_nominal_nees_is_consistent(nominal):
    low, high = nominal.nees_band
    assert low <= nominal.nees_mean <= high
    assert nominal.nees_fraction_in_band > 0.8
    # The filter's own sigma tracks the actual error over the window (within 30 %).
    h = nominal.history
    window = h["time_s"] > 120
    for name in ("attitude_deg", "omega_rad_s", "position_m"):
        ratio = np.sqrt(np.mean(h[name][window] ** 2) / np.mean(h[f"sigma_{name}"][window] ** 2))
        assert 0.7 < ratio < 1.3, name


def test_monte_carlo_is_reproducible():
    a = run_monte_carlo(scenario(duration=10.0, window=5.0), runs=3, seed=4)
    b = run_monte_carlo(scenario(duration=10.0, window=5.0), runs=3, seed=4)
    c = run_monte_carlo(scenario(duration=10.0, window=5.0), runs=3, seed=5)
    assert a.rtmse == b.rtmse
    assert a.rtmse != c.rtmse


@pytest.mark.parametrize(
    ("changes_low", "changes_high", "direction"),
    [
        ({"feature_count": 3}, {"feature_count": 12}, "decreases"),
        ({"target_size": 0.2}, {"target_size": 3.0}, "decreases"),
        ({"angle_noise": 1e-5, "target_size": 0.6}, {"angle_noise": 8e-5, "target_size": 0.6},
         "increases"),
    ],
)  # fmt: skip
def test_sweep_trends_follow_the_paper(changes_low, changes_high, direction):
    short = {"duration": 120.0, "window": 60.0}
    low = run_monte_carlo(scenario(**changes_low, **short), runs=6, seed=2).rtmse
    high = run_monte_carlo(scenario(**changes_high, **short), runs=6, seed=2).rtmse
    sign = 1 if direction == "decreases" else -1
    assert sign * (low["attitude_deg"] - high["attitude_deg"]) > 0
    assert sign * (low["omega_rad_s"] - high["omega_rad_s"]) > 0
