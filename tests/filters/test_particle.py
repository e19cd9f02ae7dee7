"""Particle filter: resampling, likelihoods, tempering, roughening, modes, convergence."""

import math

import numpy as np
import pytest
import torch

from filters.attitude import (
    attitude_angle,
    attitude_matrix,
    axis_angle_to_quaternion,
    propagate,
    quaternion_multiply,
    random_quaternion,
    rotate,
    rotation_vector_to_quaternion,
)
from filters.particle import AttitudeParticleFilter, systematic_resample
from filters.symmetry import SymmetryGroup
from tests.filters._directions import VECTORS

INERTIA = np.diag([1.0, 1.5, 2.0])


def _sensor(k: int):
    """Body-frame component ``k % 3`` of inertial vector ``k % 2``."""

    def measure(q, shape):
        return rotate(q, VECTORS[k % 2])[..., k % 3]

    return measure


def test_systematic_resampling_counts_are_within_one_of_n_times_the_weight():
    weights = torch.tensor([0.5, 0.25, 0.125, 0.0625, 0.0625], dtype=torch.float64)
    for seed in range(20):
        index = systematic_resample(weights, torch.Generator().manual_seed(seed))
        counts = torch.bincount(index, minlength=5).to(torch.float64)
        assert torch.all(torch.abs(counts - 5 * weights) < 1.0 + 1e-12)
    # Two blocks resampled within themselves: every draw stays in its block.
    blocks = torch.tensor([0.7, 0.1, 0.2, 0.25, 0.25, 0.25, 0.25], dtype=torch.float64)
    sizes = torch.tensor([3, 4])
    for seed in range(20):
        index = systematic_resample(blocks, torch.Generator().manual_seed(seed), sizes)
        assert torch.all(index[:3] < 3) and torch.all(index[3:] >= 3)
        counts = torch.bincount(index, minlength=7).to(torch.float64)
        assert torch.all(torch.abs(counts - blocks * sizes.repeat_interleave(sizes)) < 1 + 1e-12)


def test_gaussian_update_without_tempering_matches_bayes_rule():
    q = random_quaternion(50, 0)
    pf = AttitudeParticleFilter(q, np.zeros((50, 3)), [INERTIA], ess_threshold=0.0)
    predicted = _sensor(0)(pf.q, pf.shape)
    z, r = float(predicted[7]), 0.3**2
    info = pf.update(z, r, _sensor(0))
    expected = torch.exp(-0.5 * (predicted - z) ** 2 / r)
    assert torch.allclose(pf.weights, expected / expected.sum())
    evidence = math.log(float(torch.mean(expected)) / math.sqrt(2 * math.pi * r))
    assert info.stages == 1 and info.resampled == 0
    assert info.log_evidence == pytest.approx(evidence, rel=1e-9)


def test_student_likelihood_tolerates_an_outlier():
    q = random_quaternion(400, 1)
    ess = {}
    for likelihood in ("gaussian", "student"):
        pf = AttitudeParticleFilter(
            q, np.zeros((400, 3)), [INERTIA], likelihood=likelihood, ess_threshold=0.0
        )
        predicted = _sensor(1)(pf.q, pf.shape)
        pf.update(float(predicted.mean()) + 3.0, 0.05**2, _sensor(1))  # a 60σ outlier
        ess[likelihood] = pf.ess
    assert ess["student"] > 20 * ess["gaussian"]


def test_tempering_keeps_the_ess_above_the_threshold_between_resamplings():
    q = random_quaternion(2000, 2)
    pf = AttitudeParticleFilter(q, np.zeros((2000, 3)), [INERTIA], ess_threshold=0.5, seed=3)
    truth = _sensor(0)(torch.as_tensor(q[:1]), None)
    info = pf.update(float(truth[0]), 0.001**2, _sensor(0))
    assert info.stages > 1 and info.resampled >= 1
    assert torch.allclose(
        torch.linalg.vector_norm(pf.q, dim=1), torch.ones(2000, dtype=torch.float64)
    )


def test_converges_from_a_uniform_attitude_prior_on_a_vector_sensor():
    rng = np.random.default_rng(4)
    q0 = random_quaternion((), rng)
    w0 = np.radians([2.0, -1.0, 1.5])
    truth = propagate(np.concatenate([q0, w0]), np.arange(0.0, 120.0, 2.0), INERTIA)
    n = 4000
    pf = AttitudeParticleFilter(
        random_quaternion(n, rng),
        w0 + rng.normal(0, math.radians(0.2), (n, 3)),
        [INERTIA],
        seed=5,
    )
    sigma = 0.02
    for k in range(len(truth)):
        if k:
            pf.predict(2.0)
        z = float(_sensor(k)(torch.as_tensor(truth[k, :4]), None)) + rng.normal(0, sigma)
        pf.update(z, sigma**2, _sensor(k))
    q, omega, covariance = pf.estimate()
    assert math.degrees(float(attitude_angle(q, truth[-1, :4]))) < 3.0
    assert np.linalg.norm(omega - truth[-1, 4:]) < math.radians(0.1)
    assert covariance.shape == (6, 6) and np.all(np.diag(covariance) > 0)


def test_modes_report_separated_clusters_with_their_weights():
    rng = np.random.default_rng(6)
    center = random_quaternion((), rng)
    turn = axis_angle_to_quaternion([0, 0, 1.0], math.radians(90))
    other = quaternion_multiply(turn, center)
    jitter = rotation_vector_to_quaternion(rng.normal(0, math.radians(1), (300, 3)))
    q = np.concatenate(
        [quaternion_multiply(jitter[:200], center), quaternion_multiply(jitter[200:], other)]
    )
    log_w = np.log(np.r_[np.full(200, 0.7 / 200), np.full(100, 0.3 / 100)])
    pf = AttitudeParticleFilter(q, np.zeros((300, 3)), [INERTIA], log_weights=log_w)
    modes = pf.modes()
    assert [round(m.weight, 6) for m in modes] == [0.7, 0.3]
    assert math.degrees(float(attitude_angle(modes[0].quaternion, center))) < 0.5
    assert math.degrees(float(attitude_angle(modes[1].quaternion, other))) < 0.5
    assert 0.5 < math.degrees(modes[0].attitude_sigma) < 2.5
    # Folding modulo a 4-fold body symmetry about z (which maps one cluster onto the
    # other: other = turn ⊗ center) merges them into one mode.
    quarter = attitude_matrix(axis_angle_to_quaternion([0, 0, 1.0], math.radians(90)))
    group = SymmetryGroup(np.stack([np.linalg.matrix_power(quarter, i) for i in range(4)]))

    def fold(q_ref, qs, omega, shape):
        return group.closest(q_ref, qs)[0], omega

    merged = pf.modes(fold=fold)
    assert len(merged) == 1 and merged[0].weight == pytest.approx(1.0)


def test_roughening_spreads_duplicates_after_resampling():
    q = np.repeat(random_quaternion(10, 7), 100, axis=0)
    q = quaternion_multiply(
        rotation_vector_to_quaternion(np.random.default_rng(8).normal(0, 0.01, (1000, 3))), q
    )
    pf = AttitudeParticleFilter(q, np.zeros((1000, 3)), [INERTIA], seed=9, bandwidth=1.0)
    pf.log_weights = torch.log_softmax(torch.linspace(0, 20, 1000, dtype=torch.float64), 0)
    pf._resample_move(torch.tensor([True]), None, 0)
    assert len(torch.unique(pf.q, dim=0)) > 900  # resampled copies were jittered apart


def test_shape_index_probabilities_follow_the_likelihood():
    """Joint attitude–shape inversion: shape 1 sees a different inertial direction than
    the truth (shape 0), so over a rotating arc its particles cannot follow the data."""
    rng = np.random.default_rng(10)
    q0 = random_quaternion((), rng)
    w0 = np.radians([3.0, 1.0, -2.0])
    truth = propagate(np.concatenate([q0, w0]), np.arange(0.0, 60.0, 2.0), INERTIA)
    n = 3000
    jitter = rotation_vector_to_quaternion(rng.normal(0, math.radians(5), (n, 3)))
    pf = AttitudeParticleFilter(
        quaternion_multiply(jitter, q0),
        np.tile(w0, (n, 1)),
        [INERTIA, INERTIA],
        shape=np.repeat([0, 1], n // 2),
        seed=1,
    )

    def measure_at(k):
        def measure(qs, s):
            own = rotate(qs, VECTORS[0])[..., k % 3]
            other = rotate(qs, VECTORS[1])[..., k % 3]
            return torch.where(s == 0, own, other)

        return measure

    for k in range(len(truth)):
        if k:
            pf.predict(2.0)
        z = float(rotate(torch.as_tensor(truth[k, :4]), VECTORS[0])[k % 3]) + rng.normal(0, 0.02)
        pf.update(z, 0.02**2, measure_at(k))
    p = pf.shape_probabilities(2)
    assert p[0] > 0.99 and p.sum() == pytest.approx(1.0)


def _two_hypotheses(components):
    """200 particles about each of two attitudes 40° apart, at rest."""
    rng = np.random.default_rng(11)
    centers = random_quaternion(2, rng)
    centers[1] = quaternion_multiply(
        axis_angle_to_quaternion([1.0, 0, 0], math.radians(40)), centers[0]
    )
    spread = rotation_vector_to_quaternion(rng.normal(0, math.radians(0.5), (400, 3)))
    q = quaternion_multiply(spread, np.repeat(centers, 200, axis=0))
    labels = np.repeat([0, 1], 200)
    pf = AttitudeParticleFilter(
        q, np.zeros((400, 3)), [INERTIA], components=labels if components else None, seed=12
    )
    return pf, torch.as_tensor(centers)


@pytest.mark.parametrize("components", [False, True])
def test_mixture_tracking_keeps_a_mode_that_the_early_data_disfavour(components):
    """Ten measurements of hypothesis B, then thirty of A: Bayes' rule over the whole
    sequence favours A by a likelihood ratio of about e^±100s. Plain SIR resamples A's
    particles away while B leads and cannot recover; mixture tracking (Vermaak et al.
    2003) keeps A's particles and weight bookkeeping, so A ends with the posterior mass."""
    pf, centers = _two_hypotheses(components)
    sigma = 0.05
    for k in range(40):
        truth = centers[1] if k < 10 else centers[0]
        z = float(rotate(truth, VECTORS[k % 2])[k % 3])
        pf.update(z, sigma**2, _sensor(k))
    near_a = attitude_angle(pf.q, centers[0][None]) < math.radians(5)
    mass_a = float(pf.weights[near_a].sum())
    if components:
        assert pf.n_components == 2
        assert int(near_a.sum()) == 200  # A's component kept every particle
        assert mass_a > 0.999
        assert pf.component_weights() == pytest.approx([mass_a, 1 - mass_a])
    else:
        assert int(near_a.sum()) == 0 and mass_a == 0.0


def test_component_weights_follow_bayes_rule_through_resampling():
    """Without roughening, a component's new weight is ``Σ_i∈c w_i p(z | x_i)``
    normalised — checked to 1e-9 at every update, resampling included, with every
    component keeping its particle count."""
    pf, centers = _two_hypotheses(True)
    pf.bandwidth = 0.0
    rng = np.random.default_rng(13)
    sigma = 0.01
    resamplings = 0
    for k in range(15):
        z = float(rotate(centers[0], VECTORS[k % 2])[k % 3]) + rng.normal(0, sigma)
        q, log_w, component = pf.q.clone(), pf.log_weights.clone(), pf.component.clone()
        info = pf.update(z, sigma**2, _sensor(k), max_stages=1)
        resamplings += info.resampled
        posterior = torch.exp(log_w + pf.log_likelihood(_sensor(k)(q, None), z, sigma**2))
        mass = torch.zeros(2, dtype=torch.float64).index_add_(0, component, posterior)
        assert pf.component_weights() == pytest.approx((mass / mass.sum()).numpy(), rel=1e-9)
        assert torch.bincount(pf.component).tolist() == [200, 200]
    assert resamplings > 0
