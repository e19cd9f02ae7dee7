"""USQUE attitude UKF: sigma points vs filterpy, covariance propagation, consistency, gating."""

import math

import numpy as np
import pytest
from filterpy.kalman import MerweScaledSigmaPoints, unscented_transform

from filters.attitude import (
    axis_angle_to_quaternion,
    inertia_from_tanh,
    propagate,
    propagate_torque_free,
    quaternion_conjugate,
    quaternion_multiply,
    quaternion_to_grp,
    quaternion_to_rotation_vector,
    random_quaternion,
    rk4_step,
    rotate,
    rotation_vector_to_quaternion,
    torque_free_derivative,
)
from filters.gaussian import chi2_band, mahalanobis_squared
from filters.ukf import (
    AttitudeUKF,
    ProcessNoise,
    sigma_points,
    torque_free_dynamics,
    unscented_moments,
)

# The nutating body of Deng et al. 2024.
INERTIA = np.array([[0.85, 0.13, 0.17], [0.13, 1.37, -0.11], [0.17, -0.11, 1.0]])
VECTORS = np.array([[1.0, 2.0, 3.0], [-2.0, 0.5, 1.0]]) / np.sqrt([[14.0], [5.25]])


def _vector_measurement(k: int):
    """Body-frame component ``k % 3`` of inertial vector ``k % 2``: a cheap attitude sensor."""

    def hx(q, theta):
        return rotate(q, VECTORS[k % 2])[..., k % 3]

    return hx


def test_batched_sigma_points_and_moments_match_filterpy():
    rng = np.random.default_rng(0)
    points = MerweScaledSigmaPoints(7, alpha=0.7, beta=2.0, kappa=0.5)
    x = rng.standard_normal((3, 7))
    a = rng.standard_normal((3, 7, 7))
    p = a @ np.swapaxes(a, 1, 2) + 0.1 * np.eye(7)
    sigmas = sigma_points(points, x, p)
    noise = np.diag(rng.random(7))
    mean, cov = unscented_moments(points, sigmas**2, noise)
    for b in range(3):
        assert np.allclose(sigmas[b], points.sigma_points(x[b], p[b]))
        ref_mean, ref_cov = unscented_transform(sigmas[b] ** 2, points.Wm, points.Wc, noise)
        assert np.allclose(mean[b], ref_mean) and np.allclose(cov[b], ref_cov)


def test_prediction_matches_the_linearised_transition():
    """With a tiny covariance the unscented prediction is Φ P Φᵀ, Φ the Jacobian of the
    propagation in [δθ, ω] coordinates computed here by central differences."""
    q0 = random_quaternion((), 1)
    w0 = np.radians([3.0, -2.0, 4.0])
    p0 = np.diag([1e-8, 2e-8, 3e-8, 1e-10, 2e-10, 3e-10])
    ukf = AttitudeUKF(
        q0, w0, p0, torque_free_dynamics(INERTIA, max_step=0.5), process_noise=ProcessNoise(0, 0)
    )
    ukf.predict(5.0)
    q1, w1 = propagate_torque_free(q0, w0, INERTIA, 5.0, 0.5)
    phi = np.zeros((6, 6))
    for j in range(6):
        step = np.zeros(6)
        step[j] = 1e-6
        out = []
        for sign in (1.0, -1.0):
            qs = quaternion_multiply(rotation_vector_to_quaternion(sign * step[:3]), q0)
            qe, we = propagate_torque_free(qs, w0 + sign * step[3:], INERTIA, 5.0, 0.5)
            dtheta = quaternion_to_rotation_vector(
                quaternion_multiply(qe, quaternion_conjugate(q1))
            )
            out.append(np.concatenate([dtheta, we]))
        phi[:, j] = (out[0] - out[1]) / 2e-6
    assert np.allclose(ukf.q[0], q1, atol=1e-9) and np.allclose(ukf.omega[0], w1, atol=1e-12)
    expected = phi @ p0 @ phi.T
    assert np.allclose(ukf.P[0], expected, rtol=1e-3, atol=1e-16)


def test_usque_converges_and_is_consistent_on_vector_measurements():
    """A Monte Carlo bank of 40 members in one filter: 30° and 0.5°/s initial errors, one
    noisy body-frame vector component per second; final NEES inside its 99 % band."""
    runs, steps, sigma = 40, 240, 0.01
    rng = np.random.default_rng(1)
    q_true = random_quaternion(runs, rng)
    w_true = rng.standard_normal((runs, 3)) * math.radians(2.0)
    axes = rng.standard_normal((runs, 3))
    q_start = quaternion_multiply(
        axis_angle_to_quaternion(axes, np.full(runs, math.radians(30))), q_true
    )
    w_start = w_true + rng.standard_normal((runs, 3)) * math.radians(0.5)
    p0 = np.diag([math.radians(30) ** 2] * 3 + [math.radians(0.5) ** 2] * 3)
    ukf = AttitudeUKF(
        q_start, w_start, p0, torque_free_dynamics(INERTIA), process_noise=ProcessNoise(0, 0)
    )
    truth = propagate(np.concatenate([q_true, w_true], 1), np.arange(steps), INERTIA)
    for k in range(steps):
        if k:
            ukf.predict(1.0)
        z = rotate(truth[k, :, :4], VECTORS[k % 2])[:, k % 3] + rng.normal(0, sigma, runs)
        ukf.update(z, sigma**2, _vector_measurement(k))
    dtheta = quaternion_to_grp(quaternion_multiply(truth[-1, :, :4], quaternion_conjugate(ukf.q)))
    error = np.concatenate([dtheta, truth[-1, :, 4:] - ukf.omega], 1)
    assert np.degrees(np.linalg.norm(dtheta, axis=1)).max() < 1.0
    nees = mahalanobis_squared(error, ukf.P[:, :6, :6])
    low, high = chi2_band(6, runs, 0.99)
    assert low < nees.mean() < high


def test_tanh_inertia_is_estimated_on_a_nutating_body():
    k_true = np.array([0.6, -0.3])
    inertia = inertia_from_tanh(k_true)
    q0 = random_quaternion((), 2)
    w0 = np.radians([4.0, 3.0, 2.0])
    truth = propagate(np.concatenate([q0, w0]), np.arange(400.0), inertia)
    rng = np.random.default_rng(2)
    p0 = np.diag([math.radians(2) ** 2] * 3 + [math.radians(0.1) ** 2] * 3 + [0.3**2] * 2)
    ukf = AttitudeUKF(
        q0,
        w0,
        p0,
        torque_free_dynamics(np.eye(3), tanh_index=(0, 1)),
        params=[0.2, 0.0],
        process_noise=ProcessNoise(0, 0, params=(0.0, 0.0)),
    )
    for k in range(len(truth)):
        if k:
            ukf.predict(1.0)
        z = rotate(truth[k, :4], VECTORS[k % 2])[k % 3] + rng.normal(0, 0.005)
        ukf.update(z, 0.005**2, _vector_measurement(k))
    sigma_k = np.sqrt(np.diag(ukf.P[0])[6:])
    assert np.all(np.abs(ukf.params[0] - k_true) < 0.05)
    assert np.all(np.abs(ukf.params[0] - k_true) < 4 * sigma_k)


def test_gate_and_missing_measurements_leave_the_state_unchanged():
    ukf = AttitudeUKF(
        [[0, 0, 0, 1.0], [0, 0, 0, 1.0]],
        [0.01, 0, 0],
        np.eye(6) * 1e-4,
        torque_free_dynamics(INERTIA),
    )
    before = (ukf.q.copy(), ukf.x.copy(), ukf.P.copy())
    result = ukf.update(np.array([1e3, np.nan]), 1e-4, _vector_measurement(0))
    assert result.gated.all()
    assert np.array_equal(ukf.q, before[0]) and np.array_equal(ukf.x, before[1])
    assert np.array_equal(ukf.P, before[2])
    evaluated = ukf.evaluate(0.2, 1e-4, _vector_measurement(0))
    assert not evaluated.gated[0] and np.array_equal(ukf.x, before[1])
    accepted = ukf.update(evaluated.predicted, 1e-4, _vector_measurement(0))
    assert not accepted.gated.any() and np.all(
        np.trace(ukf.P, axis1=1, axis2=2) < np.trace(before[2], axis1=1, axis2=2)
    )


def test_underweighting_shrinks_the_covariance_less():
    traces = []
    for gamma in (0.0, 1.0):
        ukf = AttitudeUKF(
            [0, 0, 0, 1.0],
            [0, 0, 0],
            np.eye(6) * 0.1,
            torque_free_dynamics(INERTIA),
            underweighting=gamma,
        )
        ukf.update(0.3, 1e-4, _vector_measurement(1))
        traces.append(np.trace(ukf.P[0]))
    assert traces[1] > traces[0]


def test_bank_members_evolve_independently():
    rng = np.random.default_rng(4)
    q = random_quaternion(2, rng)
    w = rng.standard_normal((2, 3)) * 0.02
    bank = AttitudeUKF(q, w, np.eye(6) * 1e-3, torque_free_dynamics(INERTIA))
    singles = [
        AttitudeUKF(q[i], w[i], np.eye(6) * 1e-3, torque_free_dynamics(INERTIA)) for i in (0, 1)
    ]
    z = np.array([0.1, -0.2])
    for k in range(3):
        bank.predict(2.0)
        bank.update(z + 0.01 * k, 1e-4, _vector_measurement(k))
        for i, single in enumerate(singles):
            single.predict(2.0)
            single.update(z[i] + 0.01 * k, 1e-4, _vector_measurement(k))
    for i, single in enumerate(singles):
        assert np.allclose(bank.q[i], single.q[0]) and np.allclose(bank.P[i], single.P[0])


def test_bad_covariance_shape_is_rejected():
    with pytest.raises(ValueError, match="covariance must be 6×6"):
        AttitudeUKF([0, 0, 0, 1.0], [0, 0, 0], np.eye(5), torque_free_dynamics(INERTIA))


def test_torque_free_propagation_matches_the_attitude_core():
    """``propagate_torque_free`` (fused torch RK4) agrees with the core's ``rk4_step`` of
    ``torque_free_derivative`` to rounding, for numpy and torch inputs, with one shared
    inertia and with one inertia per state, forwards and backwards."""
    torch = pytest.importorskip("torch")
    rng = np.random.default_rng(4)
    q = random_quaternion(64, 5)
    omega = rng.normal(size=(64, 3)) * 0.05
    per_state = np.stack([INERTIA, np.diag([3.0, 1.0, 2.0])])[rng.integers(0, 2, 64)]
    for inertia in (INERTIA, per_state):
        for dt in (7.3, -7.3):
            x = np.concatenate([q, omega], axis=1)
            f = torque_free_derivative(inertia)
            for _ in range(8):  # ceil(7.3 / 1.0) steps
                x = rk4_step(f, x, dt / 8)
            q_np, w_np = propagate_torque_free(q, omega, inertia, dt, 1.0)
            q_t, w_t = propagate_torque_free(
                torch.as_tensor(q), torch.as_tensor(omega), inertia, dt, 1.0
            )
            for qq, ww in ((q_np, w_np), (q_t.numpy(), w_t.numpy())):
                assert np.allclose(qq, x[:, :4], atol=1e-13)
                assert np.allclose(ww, x[:, 4:], atol=1e-15)
            assert not np.allclose(q_np, q, atol=1e-3)  # it did move


def _overflowing_pair() -> AttitudeUKF:
    """Two members; the second's rates are known only to ±100 rad/s, so some of its sigma
    points spin far beyond what 1-s RK4 steps can integrate over 300 s (they overflow)."""
    p = np.diag([0.01] * 3 + [1e-6] * 3)
    lost = p.copy()
    lost[3:6, 3:6] = np.eye(3) * 1e4
    omega = [0.01, 0.0, 0.02]
    return AttitudeUKF([0, 0, 0, 1.0], [omega, omega], np.stack([p, lost]), _dynamics())


def _dynamics():
    return torque_free_dynamics(np.diag([1.0, 1.6, 2.1]))


def test_a_member_whose_prediction_overflows_diverges_and_is_frozen():
    ukf = _overflowing_pair()
    before = ukf.q.copy(), ukf.x.copy(), ukf.P.copy()
    single = AttitudeUKF(ukf.q[0], ukf.omega[0], ukf.P[0], _dynamics())
    ukf.predict(300.0)  # raised "quaternion has zero or non-finite norm" before
    single.predict(300.0)
    assert ukf.divergence[0] is None and "non-finite prediction" in ukf.divergence[1]
    assert ukf.diverged.tolist() == [False, True]
    # The live member is unaffected by its neighbour; the diverged one keeps its last state.
    assert np.allclose(ukf.q[0], single.q[0]) and np.allclose(ukf.P[0], single.P[0])
    for now, then in zip((ukf.q, ukf.x, ukf.P), before, strict=True):
        assert np.array_equal(now[1], then[1])
    # From then on every measurement is gated for it and it explains none of them.
    result = ukf.update(0.1, 0.01, lambda q, p: q[..., 0])
    assert result.gated.tolist() == [False, True]
    assert result.log_likelihood[1] == -np.inf and np.isfinite(result.log_likelihood[0])
    assert np.array_equal(ukf.P[1], before[2][1]) and not np.array_equal(ukf.P[0], single.P[0])
    evaluated = ukf.evaluate(0.1, 0.01, lambda q, p: q[..., 0])
    assert evaluated.log_likelihood[1] == -np.inf
    ukf.select([1])
    assert ukf.diverged.tolist() == [True]
