"""The multi-start search of a torque-free state scored by the best EGI (variable
projection), its parts, and the joint mode's ambiguity rule."""

import math

import numpy as np
import pytest

from benchmarks import shape_recovery
from filters.attitude import attitude_matrix, quaternion_from_matrix, random_quaternion
from lightcurve.analysis.egi import FitEpochs, joint, search
from lightcurve.analysis.egi.fit import EGIFit
from lightcurve.io.observations import Observations


def test_random_states_cover_the_rates_and_physical_inertia():
    states = search.random_states(500, np.random.default_rng(1))
    rates = np.array([np.linalg.norm(s.omega) for s in states])
    low, high = search.RATE_RANGE
    assert rates.min() >= low and rates.max() <= high
    assert rates.max() - rates.min() > 0.8 * (high - low)
    ratios = np.array([s.ratios for s in states])
    # J₁ ≤ J₂ ≤ J₃ ≤ J₁ + J₂ (J₁ = 1): a physical body
    assert np.all(ratios[:, 0] >= 1.0) and np.all(ratios[:, 1] >= ratios[:, 0])
    assert np.all(ratios[:, 1] <= 1.0 + ratios[:, 0] + 1e-12)
    assert np.allclose([np.linalg.norm(s.first) for s in states], 1.0)


def test_proper_axis_turns_are_the_24_rotations_of_the_axes():
    turns = search.proper_axis_turns()
    assert turns.shape == (24, 3, 3)
    assert np.allclose(np.linalg.det(turns), 1.0)
    assert np.allclose(np.einsum("kji,kjl->kil", turns, turns), np.eye(3))
    assert len({tuple(t.round().ravel()) for t in turns}) == 24


def test_frame_free_angles_ignore_a_constant_body_turn_only():
    rng = np.random.default_rng(4)
    history = random_quaternion(40, rng)
    turn = attitude_matrix(random_quaternion((), rng))
    body_turned = quaternion_from_matrix(np.einsum("ij,ejk->eik", turn, attitude_matrix(history)))
    assert np.max(search.frame_free_angles(history, body_turned)) < 1e-4
    # a constant inertial turn is not a change of body frame: it is another attitude
    inertial_turned = quaternion_from_matrix(attitude_matrix(history) @ turn)
    assert np.median(search.frame_free_angles(history, inertial_turned)) > 10.0
    kept = search.distinct([history, body_turned, inertial_turned])
    assert kept == [0, 2]


@pytest.fixture(scope="module")
def short_arc():
    """Ten minutes (300 epochs at 2 s) of a 3 × 2 × 1 m box tumbling at 1.2 °/s, with
    negligible noise (0.001 mag drawn, 0.03 mag stated)."""
    shape = shape_recovery.objects()["box_3x2x1"]
    rng = np.random.default_rng(21)
    arc = shape_recovery.observe(shape, "geo_tumbling", rng, 0.001)
    table = arc.table.iloc[:300].reset_index(drop=True)
    table["mag_err"] = 0.03
    arc = Observations(table, arc.meta, arc.source)
    moments = np.linalg.eigvalsh(shape.inertia)
    first, omega, ratios = joint.principal_start(
        shape,
        table[["q1", "q2", "q3", "q4"]].to_numpy()[0],
        table[["wx", "wy", "wz"]].to_numpy()[0],
    )
    assert np.allclose(ratios, moments[1:] / moments[0])
    return arc, search.TorqueFreeState(first, omega, ratios)


def test_the_search_finds_a_known_tumblers_state_from_random_starts(short_arc, monkeypatch):
    arc, truth = short_arc
    material = shape_recovery._true_material()
    monkeypatch.setattr(search, "FINE_STARTS", 2)
    minima = search.search_states(arc, material, seed=3, starts=6, screened=512, normals=300)
    seconds = (arc.mjd - arc.mjd[0]) * 86400.0
    true_q = truth.attitudes(seconds)
    best = minima[0]
    # the lowest minimum is the truth, modulo the body frame …
    assert np.max(search.frame_free_angles(true_q, best.attitudes)) < 5.0
    # … and fits the light curve at the noise
    epochs = FitEpochs.from_observations([arc], [best.attitudes])
    assert best.fit.residual_rms_mag(epochs) < 0.01
    assert [m.chi2 for m in minima] == sorted(m.chi2 for m in minima)


def _hypothesis(label, chi2, angle):
    return joint.Hypothesis(label, chi2, 0.03, 0, angle)


def test_ambiguous_only_when_a_tied_hypothesis_has_another_attitude():
    epochs = FitEpochs(
        *(np.zeros((100, 3)),) * 2, *(np.ones(100),) * 3, np.zeros(100, int), np.zeros(100)
    )
    areas = np.r_[np.ones(10), np.zeros(90)]
    fit = EGIFit(np.zeros((100, 3)), areas, areas, None, np.ones(100), 90.0, 0.0)

    def result(*hypotheses):
        return joint.JointFit(fit, epochs, [], np.ones(2), [], 0, list(hypotheses))

    best = _hypothesis("minimum 1", 90.0, 0.0)
    # reduced χ² 1: Δχ² = 5 ties; 5 > 9 does not
    assert result(best, _hypothesis("minimum 2", 95.0, 40.0)).ambiguous
    assert not result(best, _hypothesis("minimum 2", 100.0, 40.0)).ambiguous
    # a tie on the same attitude (a near-copy) is no ambiguity
    assert not result(best, _hypothesis("minimum 2", 91.0, 2.0)).ambiguous
    assert result(
        best, _hypothesis("minimum 2", 91.0, 2.0), _hypothesis("mirror", 92.0, math.inf)
    ).ambiguous
    assert not result(best).ambiguous
