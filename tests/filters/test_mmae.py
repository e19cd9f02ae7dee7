"""MMAE bank: model probabilities, floor, fused attitude and the none-fits test."""

import math

import numpy as np
import pytest

from filters.attitude import (
    attitude_angle,
    axis_angle_to_quaternion,
    propagate,
    quaternion_multiply,
    random_quaternion,
    rotate,
)
from filters.mmae import MultipleModelBank
from filters.ukf import AttitudeUKF, ProcessNoise, torque_free_dynamics

INERTIA = np.diag([1.0, 1.6, 2.1])
SIGMA = 0.01
# Each "model" is a sensor seeing the body-frame components of its own two inertial vectors.
MODELS = [
    np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
    np.array([[0.0, 1.0, 0.0], [0.6, 0.0, 0.8]]),
    np.array([[0.6, 0.8, 0.0], [0.0, -0.6, 0.8]]),
    np.array([[-0.48, 0.6, 0.64], [0.8, 0.0, -0.6]]),  # outside the bank
]


def _hx(model: int, k: int):
    def hx(q, theta):
        return rotate(q, MODELS[model][k % 2])[..., k % 3]

    return hx


def _run(truth_model: int, steps: int, floor: float = 1e-3, burst: tuple = (0, 0), seed=0):
    rng = np.random.default_rng(seed)
    q0 = random_quaternion((), rng)
    w0 = np.radians([1.5, -1.0, 2.0])
    truth = propagate(np.concatenate([q0, w0]), np.arange(steps, dtype=float), INERTIA)
    start = quaternion_multiply(axis_angle_to_quaternion([1.0, 2.0, 0.5], math.radians(5)), q0)
    p0 = np.diag([math.radians(5) ** 2] * 3 + [math.radians(0.2) ** 2] * 3)
    filters = [
        AttitudeUKF(start, w0, p0, torque_free_dynamics(INERTIA), process_noise=ProcessNoise())
        for _ in range(3)
    ]
    bank = MultipleModelBank(filters, ["a", "b", "c"], floor=floor, window=40)
    history = []
    for k in range(steps):
        if k:
            bank.predict(1.0)
        z = rotate(truth[k, :4], MODELS[truth_model][k % 2])[k % 3] + rng.normal(0, SIGMA)
        if burst[0] <= k < burst[1]:
            z += 30 * SIGMA  # a burst of outliers the true model's filter cannot explain
        bank.update(z, SIGMA**2, [_hx(m, k) for m in range(3)])
        history.append(bank.probabilities.copy())
    return bank, truth, np.array(history)


def test_true_model_wins_and_the_fused_attitude_is_its_estimate():
    bank, truth, _ = _run(truth_model=2, steps=120)
    assert bank.best == 2 and bank.probabilities[2] > 0.99
    q, omega, covariance = bank.fused()
    assert math.degrees(float(attitude_angle(q, truth[-1, :4]))) < 1.0
    assert np.allclose(omega, truth[-1, 4:], atol=math.radians(0.05))
    assert not bank.none_fits and bank.consistent[2]
    # The mixture covariance includes the spread of the (floored) losing models' means.
    assert np.trace(covariance) >= np.trace(bank.estimate(2)[2][:6, :6]) * (1 - 1e-9)


def test_none_fits_when_the_truth_is_outside_the_bank():
    bank, _, _ = _run(truth_model=3, steps=120)
    assert bank.none_fits
    assert np.all(bank.windowed_nis > bank.bound)


def test_floor_lets_the_true_model_recover_from_a_burst_of_outliers():
    # Early outliers, while every model is still alive, hit the true model hardest: its
    # filter is the most confident. Without a floor its probability falls by ~10⁻¹⁹⁴ and
    # needs about 20 good measurements to climb back; with the floor, three.
    burst = (4, 10)
    bank, _, with_floor = _run(truth_model=1, steps=60, floor=1e-3, burst=burst)
    _, _, without = _run(truth_model=1, steps=60, floor=0.0, burst=burst)
    assert with_floor[burst[1] - 1, 1] == pytest.approx(1e-3, rel=0.05)  # held at the floor
    assert without[burst[1] - 1, 1] < 1e-100
    assert with_floor[burst[1] + 4, 1] > 0.9 and without[burst[1] + 4, 1] < 1e-50
    assert bank.best == 1 and with_floor[-1, 1] > 0.99


def test_fused_attitude_is_an_eigenvector_average_not_a_linear_blend():
    q = random_quaternion((), 7)
    filters = [
        AttitudeUKF(sign * q, [0, 0, 0], np.eye(6) * 1e-4, torque_free_dynamics(INERTIA))
        for sign in (1.0, -1.0)
    ]
    bank = MultipleModelBank(filters, ["plus", "minus"])
    fused, _, _ = bank.fused()
    assert float(attitude_angle(fused, q)) < 1e-9  # a component blend would give ~0


def test_bank_validation():
    ukf = AttitudeUKF([0, 0, 0, 1.0], [0, 0, 0], np.eye(6), torque_free_dynamics(INERTIA))
    with pytest.raises(ValueError, match="one filter per model"):
        MultipleModelBank([ukf], ["a", "b"])
    with pytest.raises(ValueError, match="floor"):
        MultipleModelBank([ukf, ukf], ["a", "b"], floor=0.6)


def test_hypotheses_within_a_model_are_weighted_by_their_likelihoods():
    """One model, two hypotheses: the truth and a start 60° away. The data pick the truth
    and the model's estimate is that hypothesis."""
    rng = np.random.default_rng(3)
    q0 = random_quaternion((), rng)
    w0 = np.radians([1.0, 2.0, -1.0])
    truth = propagate(np.concatenate([q0, w0]), np.arange(60.0), INERTIA)
    wrong = quaternion_multiply(axis_angle_to_quaternion([0.0, 1.0, 1.0], math.radians(60)), q0)
    p0 = np.diag([math.radians(3) ** 2] * 3 + [math.radians(0.1) ** 2] * 3)
    ukf = AttitudeUKF(np.stack([wrong, q0]), w0, p0, torque_free_dynamics(INERTIA))
    bank = MultipleModelBank([ukf], ["only"], log_prior=[np.array([0.0, 0.0])])
    for k in range(len(truth)):
        if k:
            bank.predict(1.0)
        z = rotate(truth[k, :4], MODELS[0][k % 2])[k % 3] + rng.normal(0, SIGMA)
        bank.update(z, SIGMA**2, [_hx(0, k)])
    assert bank.leader(0) == 1 and np.exp(bank.log_weights[0][1]) > 0.999
    q, _, _ = bank.estimate(0)
    assert math.degrees(float(attitude_angle(q, truth[-1, :4]))) < 1.0
    assert bank.probabilities[0] == 1.0


def _bank_with_a_lost_model(models: tuple[str, ...] = ("a", "b")) -> MultipleModelBank:
    """Model "a" is well started; model "b"'s rates are known only to ±100 rad/s, so its
    prediction over 300 s overflows."""
    p0 = np.diag([math.radians(5) ** 2] * 3 + [math.radians(0.2) ** 2] * 3)
    lost = p0.copy()
    lost[3:6, 3:6] = np.eye(3) * 1e4
    covariance = {"a": p0, "b": lost}
    filters = [
        AttitudeUKF([0, 0, 0, 1.0], W_LOST, covariance[m], torque_free_dynamics(INERTIA))
        for m in models
    ]
    return MultipleModelBank(filters, models, floor=1e-3 if len(models) > 1 else 0.0, window=5)


W_LOST = np.radians([1.5, -1.0, 2.0])


def test_a_diverged_model_is_dropped_with_probability_zero():
    bank = _bank_with_a_lost_model()
    times = np.arange(0.0, 3000.0, 300.0)
    truth = propagate(np.concatenate([[0, 0, 0, 1.0], W_LOST]), times, INERTIA)
    for k in range(len(truth)):
        if k:
            bank.predict(300.0)  # raised "quaternion has zero or non-finite norm" before
        z = rotate(truth[k, :4], MODELS[0][k % 2])[k % 3]
        bank.update(z, SIGMA**2, [_hx(0, k), _hx(0, k)])
        if k:  # the floor does not bring it back
            assert bank.probabilities.tolist() == [1.0, 0.0]
    assert list(bank.dropped) == ["b"] and "non-finite prediction" in bank.dropped["b"]
    assert not bank.consistent[1] and not bank.all_diverged and bank.best == 0
    q, _, covariance = bank.fused()
    assert float(attitude_angle(q, bank.estimate(0)[0])) < 1e-9
    assert np.all(np.isfinite(covariance))


def test_when_every_model_diverges_the_bank_says_no_model_fits():
    bank = _bank_with_a_lost_model(("b",))
    bank.predict(300.0)
    bank.update(0.5, SIGMA**2, [_hx(0, 1)])
    assert bank.all_diverged and bank.none_fits and list(bank.dropped) == ["b"]
    # The last finite state is still the estimate; the probabilities are left as they were.
    assert bank.probabilities.tolist() == [1.0]
    q, _, covariance = bank.fused()
    assert np.all(np.isfinite(q)) and np.all(np.isfinite(covariance))
