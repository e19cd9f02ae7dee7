"""Propagation: conservation laws, the closed-form axisymmetric motion, numpy vs torch RK4."""

import numpy as np
import pytest
import torch

from filters.attitude import (
    PrincipalInertia,
    attitude_angle,
    attitude_matrix,
    axisymmetric_solution,
    inertia_from_tanh,
    principal_axes,
    propagate,
    propagate_rk4,
    quaternion_rate,
    random_quaternion,
    rk4_step,
    state_derivative,
    torque_free_derivative,
    torque_free_trajectory,
)

# The nutating body of Deng et al. 2024, scenario A (J and ω0 of the paper).
J_NUTATION = np.array([[0.85, 0.13, 0.17], [0.13, 1.37, -0.11], [0.17, -0.11, 1.0]])
OMEGA_NUTATION = np.deg2rad([5.0, 2.3, 3.5])


def test_conservation_nutating_body():
    """DOP853 at rtol 1e-12 over 10⁴ s conserves T and |H| (and H in inertial space)."""
    x0 = np.r_[0.0, 0.0, 0.0, 1.0, OMEGA_NUTATION]
    times = np.linspace(0.0, 1e4, 201)
    raw = propagate(x0, times, J_NUTATION, normalize=False)
    w = raw[:, 4:]
    energy = 0.5 * np.einsum("ni,ij,nj->n", w, J_NUTATION, w)
    h_body = w @ J_NUTATION.T
    assert np.max(np.abs(energy / energy[0] - 1)) < 1e-9
    h_norm = np.linalg.norm(h_body, axis=1)
    assert np.max(np.abs(h_norm / h_norm[0] - 1)) < 1e-9
    q = raw[:, :4]
    # Raw integrator drift of |q| (measured 2e-11): the output is renormalised on request
    # (checked on the first 10³ s: the same steps, the last one cut at 10³ s, so the states
    # agree to the tolerance, the quaternions divided by |q|).
    assert np.max(np.abs(np.linalg.norm(q, axis=1) - 1)) < 1e-10
    head = propagate(x0, times[:21], J_NUTATION)
    assert np.max(np.abs(np.linalg.norm(head[:, :4], axis=1) - 1)) < 1e-12
    unit = q / np.linalg.norm(q, axis=1, keepdims=True)
    np.testing.assert_allclose(head[:, :4], unit[:21], rtol=0, atol=1e-10)
    np.testing.assert_allclose(head[:, 4:], w[:21], rtol=0, atol=1e-10)
    h_inertial = np.einsum("nji,nj->ni", attitude_matrix(unit), h_body)
    assert np.max(np.linalg.norm(h_inertial - h_inertial[0], axis=1)) < 1e-9 * h_norm[0]


def test_axisymmetric_closed_form():
    """Numerical propagation matches the exact torque-free axisymmetric motion to 1e-8 rad."""
    inertia = np.diag([1.0, 1.0, 2.0])
    q0 = random_quaternion(rng=12)
    w0 = np.array([0.02, -0.01, 0.05])
    times = np.linspace(0.0, 1000.0, 101)
    q_exact, w_exact = axisymmetric_solution(q0, w0, 1.0, 2.0, times)
    states = propagate(np.r_[q0, w0], times, inertia)
    assert np.max(attitude_angle(states[:, :4], q_exact)) < 1e-8
    assert np.max(np.abs(states[:, 4:] - w_exact)) < 1e-10


def test_closed_form_satisfies_kinematics():
    """The closed form itself obeys q̇ = ½ Ω(ω) q (central differences)."""
    q0 = random_quaternion(rng=13)
    w0 = np.array([0.1, 0.05, -0.2])
    t = np.array([10.0 - 1e-4, 10.0, 10.0 + 1e-4])
    q, w = axisymmetric_solution(q0, w0, 3.0, 1.5, t)
    numeric = (q[2] - q[0]) / 2e-4
    np.testing.assert_allclose(numeric, quaternion_rate(q[1], w[1]), atol=1e-8)


def test_rk4_torch_equals_numpy_batched():
    """Batched RK4 on 10⁴ particles: torch float64 equals numpy to 1e-12."""
    rng = np.random.default_rng(14)
    n = 10_000
    x0 = np.concatenate([random_quaternion(n, rng), rng.normal(scale=0.05, size=(n, 3))], axis=1)
    out_np = propagate_rk4(x0, J_NUTATION, dt=1.0, n_steps=20)
    out_t = propagate_rk4(torch.tensor(x0), torch.tensor(J_NUTATION), dt=1.0, n_steps=20)
    assert isinstance(out_t, torch.Tensor)
    assert out_np.shape == (21, n, 7)
    np.testing.assert_allclose(out_t.numpy(), out_np, atol=1e-12, rtol=0)


def test_rk4_converges_to_dop853_at_fourth_order():
    x0 = np.r_[random_quaternion(rng=15), OMEGA_NUTATION * 10]
    truth = propagate(x0, [0.0, 20.0], J_NUTATION)[-1]
    errors = []
    for dt in (0.5, 0.25):
        out = propagate_rk4(x0, J_NUTATION, dt=dt, n_steps=int(20 / dt))[-1]
        errors.append(np.max(np.abs(out - truth)))
    assert 12 < errors[0] / errors[1] < 20  # 2⁴ = 16


def test_batched_dop853_matches_single_runs():
    rng = np.random.default_rng(16)
    x0 = np.concatenate([random_quaternion(4, rng), rng.normal(scale=0.05, size=(4, 3))], axis=1)
    times = np.linspace(0.0, 50.0, 6)
    batch = propagate(x0, times, J_NUTATION)
    for i in range(4):
        np.testing.assert_allclose(batch[:, i], propagate(x0[i], times, J_NUTATION), atol=1e-10)


def test_torque_changes_momentum_as_expected():
    """A constant body torque about a principal axis of a body at rest spins it up linearly."""
    inertia = np.diag([2.0, 3.0, 4.0])
    x0 = np.r_[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]
    states = propagate(x0, [0.0, 5.0], inertia, torque=lambda t, x: np.array([0.0, 0.0, 0.8]))
    assert states[-1, 6] == pytest.approx(0.8 / 4.0 * 5.0, rel=1e-10)


def test_state_derivative_matches_generic_closure():
    rng = np.random.default_rng(17)
    x = np.concatenate([random_quaternion(5, rng), rng.normal(size=(5, 3))], axis=1)
    np.testing.assert_allclose(
        torque_free_derivative(J_NUTATION)(x), state_derivative(x, J_NUTATION), atol=1e-14
    )
    step = rk4_step(torque_free_derivative(J_NUTATION), x, 0.1)
    np.testing.assert_allclose(np.linalg.norm(step[:, :4], axis=1), 1.0, atol=1e-15)


def test_propagate_rejects_bad_input():
    with pytest.raises(ValueError, match="strictly increasing"):
        propagate(np.r_[0, 0, 0, 1, 0, 0, 0.1], [0.0, 2.0, 1.0], J_NUTATION)
    with pytest.raises(ValueError, match="finite"):
        propagate(np.r_[0, 0, 0, 1, np.nan, 0, 0.1], [0.0, 1.0], J_NUTATION)
    with pytest.raises(ValueError, match="triangle inequality"):
        propagate(np.r_[0, 0, 0, 1, 0, 0, 0.1], [0.0, 1.0], np.diag([1.0, 1.0, 3.0]))


def test_generic_rk4_integrates_time_dependent_systems():
    """ẋ = t: one step from 0 to 1 is exact for a quadratic (RK4 is exact up to cubics)."""
    from filters.attitude import rk4

    out = rk4(lambda t, x: np.full_like(x, t), 0.0, np.zeros(3), 1.0)
    np.testing.assert_allclose(out, 0.5, atol=1e-15)
    # Translational states are not renormalised.
    big = rk4(lambda t, x: x, 0.0, np.full(4, 2.0), 0.1)
    assert np.all(big > 2.0)


def test_trajectory_chains_equal_the_core_rk4_and_the_tanh_form_its_inertia():
    """``torque_free_trajectory`` (principal axes) visits unsorted offsets of both signs
    like a chain of the core's RK4 steps; ``PrincipalInertia.from_tanh(k, P)`` is the
    inertia ``P diag J(k) Pᵀ``; per-state inertias, numpy and autograd tensors agree."""
    rng = np.random.default_rng(12)
    q0 = random_quaternion(5, rng)
    w0 = rng.normal(0.0, 0.05, (5, 3))
    k = rng.normal(0.0, 0.7, (5, 2))
    axes = principal_axes(J_NUTATION)[1]
    inertias = axes @ inertia_from_tanh(k) @ axes.T
    offsets = np.array([7.0, -3.5, 2.5, 0.0, -9.0])
    expected = np.empty((5, len(offsets), 7))
    for i, t in enumerate(offsets):
        x = np.concatenate([q0, w0], axis=1)
        steps = max(1, int(np.ceil(abs(t) / 2.0)))
        for _ in range(steps if t else 0):
            x = rk4_step(torque_free_derivative(inertias), x, t / steps)
        expected[:, i] = x
    # Intervals between sorted offsets are cut alike, so chains equal restarts only where
    # each interval fits max_step: 2.5 → 7 (4.5 s, 3 steps of 1.5) vs 0 → 7 (4 steps).
    for inertia in (inertias, PrincipalInertia.from_tanh(k, axes)):
        q, w = torque_free_trajectory(q0, w0, [0.0, -3.5, -9.0], inertia, 2.0)
        assert np.allclose(q, expected[:, [3, 1, 4], :4], atol=1e-12)
        assert np.allclose(w, expected[:, [3, 1, 4], 4:], atol=1e-14)
        q_t, _ = torque_free_trajectory(
            torch.tensor(q0, requires_grad=True), torch.tensor(w0), [7.0], inertia, 2.0
        )
        assert q_t.requires_grad and np.allclose(q_t.detach(), expected[:, [0], :4], atol=1e-12)
    q, _ = torque_free_trajectory(q0, w0, offsets, inertias, 2.0)
    chained = expected[:, [0, 1, 3, 4], :4]
    assert np.allclose(q[:, [1, 3, 4]], chained[:, 1:], atol=1e-12)
    assert attitude_angle(q[:, 0], chained[:, 0]).max() < 1e-6  # 2.5 → 7 in other steps


@pytest.mark.parametrize("per_body", [False, True], ids=["shared-inertia", "per-state-inertia"])
def test_compiled_trajectory_equals_the_element_wise_torch_kernel(per_body):
    """The compiled numpy branch and the torch branch do the same arithmetic."""
    rng = np.random.default_rng(21)
    q0 = random_quaternion(64, rng)
    w0 = rng.normal(0.0, 0.08, (64, 3))
    inertia = (
        PrincipalInertia.from_tanh(rng.normal(0.0, 0.7, (64, 2)))
        if per_body
        else PrincipalInertia.from_inertia(J_NUTATION)
    )
    offsets = np.array([0.0, 13.0, -4.0, 3.5, -30.0, 61.0])
    q, w = torque_free_trajectory(q0, w0, offsets, inertia, 2.0)
    q_t, w_t = torque_free_trajectory(
        torch.tensor(q0, requires_grad=True), torch.tensor(w0), offsets, inertia, 2.0
    )
    assert np.allclose(q, q_t.detach().numpy(), rtol=0, atol=1e-14)
    assert np.allclose(w, w_t.detach().numpy(), rtol=0, atol=1e-15)


@pytest.mark.parametrize("bodies", [1, 2, 3, 4])
def test_a_stack_of_inertias_propagates_each_body_as_alone(bodies):
    """``PrincipalInertia.from_inertia`` of a stack of tensors (three of them, a ``(3, 3)``
    array of moments, included) gives every body its own axes and ratios: a trajectory of
    the stack equals each body's trajectory alone."""
    rng = np.random.default_rng(bodies)
    stack = np.stack(
        [J_NUTATION, np.diag([260.4, 208.3, 135.4]), np.diag([0.83, 3.33, 4.17]), np.eye(3)]
    )[:bodies]
    together = PrincipalInertia.from_inertia(stack)
    q0 = random_quaternion(bodies, rng)
    w0 = rng.normal(0.0, 0.05, (bodies, 3))
    q, w = torque_free_trajectory(q0, w0, [0.0, 40.0, 90.0], together, 2.0)
    for i in range(bodies):
        alone = PrincipalInertia.from_inertia(stack[i])
        np.testing.assert_allclose(together.ratios[i], alone.ratios, atol=1e-14)
        q_i, w_i = torque_free_trajectory(
            q0[i : i + 1], w0[i : i + 1], [0.0, 40.0, 90.0], alone, 2.0
        )
        assert attitude_angle(q[i], q_i[0]).max() < 1e-9
        np.testing.assert_allclose(w[i], w_i[0], atol=1e-12)
