"""Analytic Jacobians against torch autograd (Deng et al. 2024, eqs. 27–31; the tanh form)."""

import numpy as np
import torch
from torch.autograd.functional import jacobian

from filters.attitude import (
    error_state_matrix,
    euler_rate,
    euler_rate_jacobian,
    euler_rate_jacobian_normalized,
    euler_rate_jacobian_tanh,
    euler_rate_principal,
    inertia_from_normalized,
    normalized_from_inertia,
    random_quaternion,
    ratios_from_tanh,
    state_derivative,
    state_jacobian,
    transition_matrix,
)

J_NUTATION = np.array([[0.85, 0.13, 0.17], [0.13, 1.37, -0.11], [0.17, -0.11, 1.0]])
OMEGA = np.deg2rad([5.0, 2.3, 3.5])


def t(x):
    return torch.tensor(x, dtype=torch.float64)


def test_normalized_inertia_jacobians_match_autograd():
    """M = ∂ω̇/∂ω and N = ∂ω̇/∂l of the 11-state model equal autograd to 1e-9."""
    l = normalized_from_inertia(J_NUTATION)
    for w in (OMEGA, np.array([0.3, -0.7, 0.2])):
        m_auto = jacobian(lambda ww: euler_rate(ww, inertia_from_normalized(t(l))), t(w))
        n_auto = jacobian(lambda ll, w=w: euler_rate(t(w), inertia_from_normalized(ll)), t(l))
        np.testing.assert_allclose(
            euler_rate_jacobian(w, inertia_from_normalized(l)), m_auto.numpy(), atol=1e-12
        )
        np.testing.assert_allclose(euler_rate_jacobian_normalized(w, l), n_auto.numpy(), atol=1e-12)
        c = error_state_matrix(w, l)
        assert c.shape == (11, 11)
        np.testing.assert_allclose(c[3:6, 3:6], m_auto.numpy(), atol=1e-9)
        np.testing.assert_allclose(c[3:6, 6:], n_auto.numpy(), atol=1e-9)
        np.testing.assert_allclose(c[:3, 3:6], 0.5 * np.eye(3))
        assert np.all(c[6:] == 0) and np.all(c[3:6, :3] == 0)


def test_error_state_attitude_block_is_true_linearisation():
    """−[ω×] and ½ I: propagate a perturbed attitude and compare δq_v growth."""
    from filters.attitude import quaternion_conjugate, quaternion_multiply, rk4_step
    from filters.attitude.propagation import torque_free_derivative

    f = torque_free_derivative(J_NUTATION)
    q = random_quaternion(rng=30)
    dq0 = np.array([1e-6, -2e-6, 0.5e-6])
    dw0 = np.array([2e-7, 1e-7, -1e-7])
    q_pert = quaternion_multiply(np.r_[dq0, np.sqrt(1 - dq0 @ dq0)], q)
    x_ref = np.r_[q, OMEGA]
    x_pert = np.r_[q_pert, OMEGA + dw0]
    dt = 0.01
    x_ref1 = rk4_step(f, x_ref, dt)
    x_pert1 = rk4_step(f, x_pert, dt)
    dq1 = quaternion_multiply(x_pert1[:4], quaternion_conjugate(x_ref1[:4]))[:3]
    c = error_state_matrix(OMEGA, normalized_from_inertia(J_NUTATION))[:6, :6]
    predicted = transition_matrix(c, dt) @ np.r_[dq0, dw0]
    np.testing.assert_allclose(dq1, predicted[:3], atol=1e-12)
    np.testing.assert_allclose(x_pert1[4:] - x_ref1[4:], predicted[3:], atol=1e-12)


def test_tanh_jacobian_matches_autograd():
    rng = np.random.default_rng(31)
    for _ in range(5):
        w, k = rng.normal(size=3), rng.normal(size=2)
        auto = jacobian(lambda kk, w=w: euler_rate_principal(t(w), ratios_from_tanh(kk)), t(k))
        np.testing.assert_allclose(euler_rate_jacobian_tanh(w, k), auto.numpy(), atol=1e-12)


def test_full_state_jacobian_matches_autograd():
    x = np.r_[random_quaternion(rng=32), OMEGA]
    auto = jacobian(lambda xx: state_derivative(xx, t(J_NUTATION)), t(x))
    np.testing.assert_allclose(state_jacobian(x, J_NUTATION), auto.numpy(), atol=1e-12)


def test_batched_and_torch_jacobians():
    rng = np.random.default_rng(33)
    w = rng.normal(size=(4, 3))
    l = normalized_from_inertia(J_NUTATION)
    c = error_state_matrix(w, l)
    assert c.shape == (4, 11, 11)
    np.testing.assert_allclose(c[2], error_state_matrix(w[2], l), atol=1e-15)
    c_t = error_state_matrix(t(w), t(l))
    np.testing.assert_allclose(c_t.numpy(), c, atol=1e-14)
    np.testing.assert_allclose(
        transition_matrix(c_t, 0.5).numpy(), transition_matrix(c, 0.5), atol=1e-12
    )


def test_transition_matrix_series_equals_scipy_expm():
    from scipy.linalg import expm

    rng = np.random.default_rng(34)
    for scale in (1e-3, 0.3, 5.0, 40.0):
        c = rng.normal(scale=scale, size=(6, 11, 11))
        ours = transition_matrix(c, 0.7)
        ref = np.stack([expm(ci * 0.7) for ci in c])
        # Both methods square their scaled result back, which amplifies rounding (and with it
        # the last digits of the processor's BLAS kernels) in proportion to ‖C Δt‖: at scale
        # 40 (‖C Δt‖₁ ≈ 300–440) they differ by up to 2e-13 of the largest element.
        for ours_i, ref_i, c_i in zip(ours, ref, c, strict=True):
            norm = np.abs(c_i * 0.7).sum(axis=0).max()
            scale_i = max(1.0, norm) * max(1.0, np.abs(ref_i).max())
            assert np.max(np.abs(ours_i - ref_i)) < 1e-13 * scale_i
