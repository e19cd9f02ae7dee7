"""Global search: residual Jacobians, batched LM, priors, screening, trajectories."""

import math

import numpy as np
import pytest
import torch

from filters.attitude import (
    attitude_angle,
    attitude_matrix,
    axis_angle_to_quaternion,
    propagate,
    quaternion_conjugate,
    quaternion_multiply,
    quaternion_to_rotation_vector,
    random_quaternion,
    rotate,
    rotation_vector_to_quaternion,
)
from filters.global_search import (
    BatchProblem,
    Candidates,
    Prior,
    distinct_states,
    global_search,
    refine,
    residual_jacobian,
    uniform_rates,
)
from filters.global_search.refinement import _with_twins
from filters.global_search.selection import _best_distinct, _replenish
from filters.symmetry import SymmetryGroup
from tests.filters._directions import VECTORS

INERTIA = np.diag([1.0, 1.7, 2.2])


def _measure(q, epochs, shape):
    """A smooth, non-linear scalar attitude sensor (two inertial directions seen in the
    body frame, so that no rotation leaves it unchanged); the shape index changes it."""
    a = rotate(q, VECTORS[0])
    b = rotate(q, VECTORS[1])
    value = a[..., 0] + 0.5 * b[..., 1] * a[..., 2] + 0.3 * a[..., 1] + 0.4 * b[..., 2]
    return value + 0.3 * shape[:, None] * b[..., 0]


def _problem(q0, w0, seconds=120, sigma=0.01, seed=0, shape=0):
    times = np.arange(0.0, seconds, 2.0)
    truth = propagate(np.concatenate([q0, w0]), times, INERTIA)
    clean = _measure(torch.as_tensor(truth[None, :, :4]), None, torch.tensor([shape]))[0]
    noisy = clean.numpy() + np.random.default_rng(seed).normal(0, sigma, len(times))
    return BatchProblem(times, noisy, np.full(len(times), sigma), _measure, [INERTIA, INERTIA])


def test_jacobian_matches_finite_differences_of_the_residuals():
    q0 = random_quaternion((), 0)
    w0 = np.radians([2.0, -1.0, 3.0])
    problem = _problem(q0, w0)
    epochs = np.arange(0, 60, 3)
    q = torch.as_tensor(random_quaternion(3, 1))
    v = torch.as_tensor(np.random.default_rng(2).normal(0, 0.03, (3, 3)))
    shape = torch.zeros(3, dtype=torch.long)
    for t_start in (0.0, float(problem.times[epochs[-1]])):  # forwards and backwards
        _r, jac = residual_jacobian(problem, q, v, shape, epochs, t_start=t_start)
        for j, step in enumerate([1e-6] * 3 + [1e-8] * 3):
            dq = torch.zeros(3, 3, dtype=torch.float64)
            dv = torch.zeros(3, 3, dtype=torch.float64)
            (dq if j < 3 else dv)[:, j % 3] = step
            plus, minus = (
                problem.residuals_of(
                    problem.trajectory(
                        quaternion_multiply(rotation_vector_to_quaternion(s * dq), q),
                        v[:, :3] + s * dv,
                        None,
                        shape,
                        epochs,
                        t_start,
                    ),
                    shape,
                    epochs,
                )
                for s in (1.0, -1.0)
            )
            numeric = (plus - minus) / (2 * step)
            # Rate columns are forward differences: relative truncation error ~ ½ h t.
            assert torch.allclose(jac[..., j], numeric, rtol=1e-3, atol=1e-4 * numeric.abs().max())


@pytest.mark.parametrize("at_end", [False, True], ids=["initial-state", "final-state"])
def test_levenberg_marquardt_recovers_the_truth_and_its_covariance(at_end):
    """Initial states (t_start = 0), and final states fitted backwards over the arc."""
    q0 = random_quaternion((), 3)
    w0 = np.radians([1.5, 2.5, -1.0])
    problem = _problem(q0, w0, seconds=200, sigma=0.002)
    t_start = float(problem.times[-1]) if at_end else 0.0
    truth = propagate(np.concatenate([q0, w0]), problem.times, INERTIA)[-1 if at_end else 0]
    q_true, w_true = truth[:4], truth[4:]
    rng = np.random.default_rng(4)
    n = 4
    starts = quaternion_multiply(
        axis_angle_to_quaternion(rng.standard_normal((n, 3)), np.full(n, math.radians(8))),
        q_true,
    )
    w_start = w_true + rng.normal(0, math.radians(0.1), (n, 3))
    epochs = np.arange(len(problem.times))
    fit = refine(
        problem,
        Candidates(
            q=torch.as_tensor(starts),
            omega=torch.as_tensor(w_start),
            shape=torch.zeros(n, dtype=torch.long),
        ),
        epochs,
        iterations=25,
        t_start=t_start,
    )
    q, w, k, chi2, cov = fit.q, fit.omega, fit.k, fit.chi2, fit.covariance
    errors = np.degrees(attitude_angle(q.numpy(), q_true))
    assert np.all(errors < 0.3), errors
    assert np.allclose(w.numpy(), w_true, atol=math.radians(0.01))
    # χ² of a correct fit: E − 6 degrees of freedom (5σ tolerance).
    dof = len(epochs) - 6
    assert np.all(np.abs(chi2.numpy() - dof) < 5 * math.sqrt(2 * dof))
    sigma = np.degrees(np.sqrt(np.trace(cov.numpy()[:, :3, :3], axis1=1, axis2=2)))
    assert np.all(errors < 5 * sigma) and np.all(sigma < 0.3)
    assert k is None


def test_refine_linearises_only_accepted_steps_and_returns_the_fit_s_own_jacobian():
    """Each iteration predicts every trial state once and probes (six predictions) only
    the accepted ones; the covariance is that of the Jacobian at the returned states."""
    q0 = random_quaternion((), 11)
    w0 = np.radians([1.0, -2.0, 1.5])
    problem = _problem(q0, w0, seconds=60, sigma=0.005)
    rows = []
    measure = problem.measure

    def counting(q, epochs, shape):
        rows.append(q.shape[0])
        return measure(q, epochs, shape)

    problem.measure = counting
    n = 13  # no multiple of 6: trial calls (n rows) and probe calls (6 × accepted) differ
    rng = np.random.default_rng(12)
    start = Candidates(
        q=torch.as_tensor(
            quaternion_multiply(rotation_vector_to_quaternion(rng.normal(0, 0.1, (n, 3))), q0)
        ),
        omega=torch.as_tensor(w0 + rng.normal(0, 0.01, (n, 3))),
        shape=torch.zeros(n, dtype=torch.long),
    )
    epochs = np.arange(0, 30, 2)
    prior = Prior.rates_only(math.radians(5.0))
    fit = refine(problem, start, epochs, iterations=6, prior=prior)
    # First linearisation: n states and 6 n probes; then per iteration n trials and
    # 6 × (accepted) probes, never all 7 n.
    assert rows[:2] == [n, 6 * n]
    trials = [r for r in rows[2:] if r == n]
    probes = [r for r in rows[2:] if r != n]
    assert 1 <= len(trials) <= 6 and 0 < len(probes) <= len(trials)
    assert all(p % 6 == 0 for p in probes) and sum(probes) < 6 * n * len(trials)
    problem.measure = measure
    r, jac = residual_jacobian(problem, fit.q, fit.omega, fit.shape, epochs, prior=prior)
    assert torch.allclose(fit.chi2, (r * r).sum(dim=1), rtol=1e-12, atol=0.0)
    expected = torch.linalg.pinv(jac.transpose(1, 2) @ jac, hermitian=True)
    assert torch.allclose(fit.covariance, expected, rtol=1e-6, atol=1e-12)


def test_every_kind_of_twin_is_refined_and_counted():
    """``twins`` may return several kinds; a kind no candidate has adds nothing."""
    q0 = random_quaternion((), 9)
    w0 = np.radians([1.0, 2.0, -1.5])
    problem = _problem(q0, w0, seconds=60)
    q = torch.as_tensor(random_quaternion(4, 10))
    w = torch.as_tensor(np.tile(w0, (4, 1)))
    shape = torch.tensor([0, 0, 1, 1])
    half_turn = np.array([0.0, 0.0, 1.0, 0.0])
    calls = []

    def twins(q_, w_, s_):
        calls.append(len(q_))
        turned = quaternion_multiply(q_, half_turn)
        return [(turned, w_, s_ == 1), (turned, -w_, np.zeros(len(q_), bool)), (q_, w_, s_ >= 0)]

    chi2, cov = torch.zeros(4, dtype=torch.float64), torch.zeros(4, 6, 6, dtype=torch.float64)
    start = Candidates(q=q, omega=w, shape=shape, chi2=chi2, covariance=cov)
    out, factor = _with_twins(problem, twins, start, np.arange(10), iterations=2, prior=None)
    assert calls == [4] and factor == 3 and out.k is None
    assert len(out) == len(out.omega) == len(out.chi2) == len(out.covariance) == 4 + 2 + 4
    assert out.shape.tolist() == [0, 0, 1, 1, 1, 1, 0, 0, 1, 1]
    assert torch.all(out.chi2[4:] > 0)  # the twins carry their own refined fit


def test_prior_pulls_an_uninformative_fit_to_the_prior_mean():
    q0 = random_quaternion((), 5)
    w0 = np.radians([1.0, 0.0, 0.5])
    problem = _problem(q0, w0, seconds=20, sigma=10.0)  # measurements carry almost nothing
    prior = Prior(q0, w0, math.radians(2.0), math.radians(0.05))
    start = quaternion_multiply(rotation_vector_to_quaternion([0.1, 0.0, 0.0]), q0)
    fit = refine(
        problem,
        Candidates(
            q=torch.as_tensor(start[None]),
            omega=torch.as_tensor(w0[None] + 0.01),
            shape=torch.zeros(1, dtype=torch.long),
        ),
        np.arange(len(problem.times)),
        iterations=20,
        prior=prior,
    )
    q, cov = fit.q, fit.covariance
    assert math.degrees(float(attitude_angle(q[0].numpy(), q0))) < 0.05
    assert np.allclose(np.sqrt(np.diag(cov[0].numpy()))[:3], math.radians(2.0), rtol=0.05)


def _search(problem, **settings):
    """``global_search`` at up to 4°/s with 16-s screening (64 candidates, seed 1, two
    iterations unless ``settings`` say otherwise)."""
    defaults = dict(
        n_candidates=64,
        omega_max=math.radians(4.0),
        seed=1,
        screen_duration=16.0,
        iterations=2,
    )
    return global_search(problem, **(defaults | settings))


def test_global_search_finds_the_attitude_and_the_shape_from_a_uniform_prior():
    q0 = random_quaternion((), 6)
    w0 = np.radians([2.0, -1.5, 1.0])
    problem = _problem(q0, w0, seconds=120, sigma=0.01, shape=1)
    result = _search(
        problem,
        n_candidates=4000,
        n_shapes=2,
        seed=7,
        windows=(16.0, 48.0, 120.0),  # continuation: rates settle before the arc grows
        keep=(64, 16, 6),
        iterations=12,
    )
    best = 0
    assert result.shape[best] == 1
    assert math.degrees(float(attitude_angle(result.q[best], q0))) < 3.0
    assert np.allclose(result.omega[best], w0, atol=math.radians(0.05))
    assert result.chi2[best] < len(problem.times)
    assert np.all(np.diff(result.chi2) >= 0) and result.screened == 4000


@pytest.mark.parametrize("max_rotation_deg, expected", [(20.0, 24), (math.inf, 10)])
def test_long_windows_are_sampled_densely_enough_for_the_fastest_rotation(
    max_rotation_deg, expected
):
    # 120 s at up to 4°/s with at most 20° between samples: ⌈120 · 4 / 20⌉ = 24 epochs,
    # more than min_epochs = 10 (which alone would put 48° of rotation between samples).
    problem = _problem(random_quaternion((), 3), np.radians([1.0, 0.5, -1.0]), seconds=120)
    result = _search(
        problem,
        windows=(16.0, 120.0),
        keep=(4, 2),
        min_epochs=10,
        max_rotation=math.radians(max_rotation_deg),
    )
    assert len(result.epochs) == expected
    assert result.epochs[0] == 0 and problem.times[result.epochs[-1]] == 118.0


def test_backward_and_forward_trajectories_agree():
    q0 = random_quaternion((), 8)
    w0 = np.radians([3.0, 1.0, -2.0])
    problem = _problem(q0, w0)
    epochs = np.arange(len(problem.times))
    shape = torch.zeros(1, dtype=torch.long)
    forward = problem.trajectory(
        torch.as_tensor(q0[None]), torch.as_tensor(w0[None]), None, shape, epochs
    )
    # Start from the last state and go back to the first epoch.
    truth = propagate(np.concatenate([q0, w0]), problem.times, INERTIA)
    backward = problem.trajectory(
        torch.as_tensor(truth[-1:, :4]),
        torch.as_tensor(truth[-1:, 4:]),
        None,
        shape,
        epochs,
        t_start=float(problem.times[-1]),
    )
    assert np.degrees(attitude_angle(forward[0].numpy(), truth[:, :4])).max() < 1e-4
    assert np.degrees(attitude_angle(backward[0].numpy(), truth[:, :4])).max() < 1e-4


def test_a_rate_scale_searches_a_smaller_ball_on_longer_windows():
    problem = _problem(random_quaternion((), 3), np.radians([0.2, 0.1, -0.1]), seconds=120)
    messages = []
    result = _search(
        problem,
        windows=(16.0, 48.0, 120.0),
        keep=(8, 4, 2),
        min_epochs=10,
        rate_scales=(1.0, 0.25),
        progress=messages.append,
    )
    # Windows stretched fourfold (48 s → 192 s is beyond the last window and dropped).
    windows = [m.split(" on ")[1].split(",")[0] for m in messages if m.startswith("refined")]
    assert windows == ["16 s", "48 s", "120 s", "64 s", "120 s"]
    assert result.screened == 128
    # Both scales end on the same window, so their χ² compare.
    assert problem.times[result.epochs[-1]] == 118.0
    with pytest.raises(ValueError, match="rate_scales must be in"):
        global_search(problem, rate_scales=(1.0, 1.5))


def test_the_quarter_rate_scale_finds_a_slow_rotator():
    # 0.6°/s over 8 min: 14° per 24 s screening window. The full ball alone ends 172° off
    # on this light curve (χ² 853 on its last window); the quarter scale screens on 64 s.
    direction = np.random.default_rng(2).standard_normal(3)
    q0 = random_quaternion((), 102)
    w0 = math.radians(0.6) * direction / np.linalg.norm(direction)
    problem = _problem(q0, w0, seconds=480, sigma=0.01)
    result = _search(
        problem,
        n_candidates=2000,
        seed=7,
        windows=(16.0, 32.0, 64.0, 128.0, 256.0, 480.0),
        keep=(32, 32, 32, 16, 8, 4),
        min_epochs=20,
        iterations=12,
        rate_scales=(1.0, 0.25),
    )
    assert math.degrees(float(attitude_angle(result.q[0], q0))) < 3.0
    assert np.allclose(result.omega[0], w0, atol=math.radians(0.05))
    assert result.chi2[0] < 1.5 * len(result.epochs)


def test_uniform_rates_fill_the_ball_uniformly():
    w = uniform_rates(20000, 2.0, np.random.default_rng(9))
    radius = np.linalg.norm(w, axis=1)
    assert radius.max() <= 2.0
    # P(|ω| ≤ r) = (r/R)³.
    assert abs(np.mean(radius <= 1.0) - 0.125) < 0.01
    prior = Prior(random_quaternion((), 1), np.zeros(3), 0.1, 0.01)
    q, omega = prior.sample(5, np.random.default_rng(1))
    assert np.allclose(q[0], prior.q) and np.allclose(omega[0], 0.0)


def _box_group() -> SymmetryGroup:
    """The four proper rotations of a box with three different sides (identity and the
    half-turns about its axes)."""
    return SymmetryGroup(
        np.stack([np.diag(d) for d in ([1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1])]).astype(
            float
        )
    )


def test_distinct_merges_symmetry_equivalent_states_and_near_duplicates():
    rng = np.random.default_rng(4)
    group = _box_group()
    q = random_quaternion(3, rng)
    w = np.radians(rng.normal(0.0, 2.0, (3, 3)))
    # candidate 3: a symmetry-equivalent of candidate 0 (same physical state);
    # candidate 4: candidate 1 turned by 1° (a near duplicate); candidate 5: the same
    # attitude as 2 but spinning differently (distinct).
    q_eq, w_eq = group.equivalent_attitudes(q[0])[2], group.equivalent_rates(w[0])[2]
    q_near = quaternion_multiply(axis_angle_to_quaternion([0, 0, 1], math.radians(1.0)), q[1])
    qs = np.vstack([q, q_eq, q_near, q[2]])
    w_near = attitude_matrix(q_near) @ attitude_matrix(q[1]).T @ w[1]  # same inertial rates
    ws = np.vstack([w, w_eq, w_near, w[2] + np.radians([0.5, 0, 0])])
    shape = np.zeros(6, dtype=int)
    angle, rate = math.radians(3.0), math.radians(0.05)
    assert list(distinct_states(qs, ws, shape, angle, rate, [group])) == [0, 1, 2, 5]
    # without the group the equivalent attitude (a half-turn away) counts as distinct
    assert list(distinct_states(qs, ws, shape, angle, rate)) == [0, 1, 2, 3, 5]
    # another shape index never duplicates
    other = np.array([0, 0, 0, 1, 0, 0])
    assert list(distinct_states(qs, ws, other, angle, rate, [group] * 2)) == [0, 1, 2, 3, 5]
    cost = torch.tensor([5.0, 1.0, 3.0, 0.5, 0.9, 4.0], dtype=torch.float64)
    candidates = Candidates(
        q=torch.as_tensor(qs), omega=torch.as_tensor(ws), shape=torch.zeros(6, dtype=torch.long)
    )
    candidates.chi2 = cost
    best = _best_distinct(candidates, 3, per_shape=False, angle=angle, rate=rate, groups=[group])
    assert best.tolist() == [3, 4, 2]  # 0 and 1 are worse copies of 3 and 4


def test_replenish_fills_up_with_capped_draws_around_the_survivors():
    rng = np.random.default_rng(5)
    q = torch.as_tensor(random_quaternion(2, rng))
    v = torch.as_tensor(np.radians([[1.0, 0.0, 0.5], [-2.0, 1.0, 0.0]]))
    shape = torch.tensor([0, 1])
    wide = np.diag([1.0] * 3 + [1e-2] * 3)  # 57° and 5.7°/s: far above the caps
    tight = np.diag([1e-6] * 3 + [1e-10] * 3)
    covariance = torch.as_tensor(np.stack([wide, tight]))
    cap = np.array([math.radians(10.0)] * 3 + [math.radians(0.1)] * 3)
    parents = Candidates(q=q, omega=v, shape=shape, covariance=covariance)
    out = _replenish(parents, 400, per_shape=True, cap=cap, rng=rng, scale=1.0)
    q2, v2, s2 = out.q, out.omega, out.shape
    assert len(q2) == 800 and s2.bincount().tolist() == [400, 400]
    assert torch.equal(q2[:2], q) and torch.equal(v2[:2], v)
    for s, sigma_att, sigma_rate in ((0, cap[0], cap[3]), (1, 1e-3, 1e-5)):
        rows = torch.nonzero(s2 == s).flatten()[1:]
        dtheta = quaternion_to_rotation_vector(
            quaternion_multiply(q2[rows].numpy(), quaternion_conjugate(q[s].numpy()))
        )
        dw = (v2[rows] - v[s]).numpy()
        assert np.std(dtheta, axis=0) == pytest.approx(np.full(3, sigma_att), rel=0.15)
        assert np.std(dw, axis=0) == pytest.approx(np.full(3, sigma_rate), rel=0.15)
    # nothing to add when the set is full
    assert len(_replenish(parents, 1, per_shape=True, cap=cap, rng=rng)) == 2
