"""The multi-start search of a torque-free state scored by the best EGI (variable
projection), its parts, and the joint mode's ambiguity rule."""

import math
from dataclasses import replace

import numpy as np
import pytest

from benchmarks import shape_recovery
from filters.attitude import attitude_matrix, quaternion_from_matrix, random_quaternion
from lightcurve.analysis.egi import FitEpochs, joint, search
from lightcurve.analysis.egi.fit import EGIFit, fit_egi
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
    """Five minutes (150 epochs at 2 s) of a 3 × 2 × 1 m box tumbling at 0.8 °/s, with
    negligible noise (0.001 mag drawn, 0.03 mag stated), and its true state."""
    shape = shape_recovery.objects()["box_3x2x1"]
    arc = shape_recovery.observe(shape, "geo_tumbling", np.random.default_rng(21), 0.001)
    table = arc.table.iloc[:150].reset_index(drop=True)
    table["mag_err"] = 0.03
    arc = Observations(table, arc.meta, arc.source)
    q, w = table[["q1", "q2", "q3", "q4"]].to_numpy()[0], table[["wx", "wy", "wz"]].to_numpy()[0]
    return arc, search.TorqueFreeState(*joint.principal_start(shape, q, w))


def test_the_search_fits_a_short_arc_as_well_as_the_true_state(short_arc, monkeypatch):
    # From random states, the search reaches the true state's χ² (same grid). On five
    # minutes it finds other attitudes that fit as well (60–80° from the truth and its
    # twins on these seeds): one short arc does not give the attitude, so only the fit is
    # asserted.
    arc, truth = short_arc
    material = shape_recovery._true_material()
    monkeypatch.setattr(search, "FINE_STARTS", 1)
    monkeypatch.setattr(search, "POLISH_STEPS", 3)
    minima = search.search_states(arc, material, seed=1, starts=2, screened=64, normals=300)
    reference = search.scored_minimum(arc, truth, material, 300)
    assert minima[0].chi2 <= 1.5 * reference.chi2
    epochs = FitEpochs.from_observations([arc], [minima[0].attitudes])
    assert minima[0].fit.residual_rms_mag(epochs) < 0.005
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
    # 90 over 100 epochs less 10 areas: reduced χ² 1, no misfit; 500: a misfit
    assert result(best).reduced_chi2 == 1.0 and not result(best).misfit
    poor = joint.JointFit(replace(fit, chi2=500.0), epochs, [], np.ones(2), [], 0, [best])
    assert poor.misfit


def test_a_second_file_joins_in_the_frame_that_fits_best():
    # Two arcs of one box; the second's true state is given in its principal frame turned
    # by an axis permutation. The join turns it into a frame of the first file's in which
    # the two arcs' EGI fits at least as well as in the true one (short arcs may allow
    # another turn: only the fit is asserted).
    shape = shape_recovery.objects()["box_3x2x1"]
    material = shape_recovery._true_material()
    arcs, truths = [], []
    for seed in (31, 32):
        arc = shape_recovery.observe(shape, "geo_tumbling", np.random.default_rng(seed), 0.01)
        arc = Observations(arc.table.iloc[:200].reset_index(drop=True), arc.meta, arc.source)
        q, w = arc.table[["q1", "q2", "q3", "q4"]].to_numpy(), arc.table[["wx", "wy", "wz"]]
        truths.append(search.TorqueFreeState(*joint.principal_start(shape, q[0], w.to_numpy()[0])))
        arcs.append(arc)
    seconds = [(arc.mjd - arc.mjd[0]) * 86400.0 for arc in arcs]
    turn = search.proper_axis_turns()[7]
    moments = np.diag(turn @ np.diag([1.0, *truths[1].ratios]) @ turn.T)
    moved = search.TorqueFreeState(
        quaternion_from_matrix(turn @ attitude_matrix(truths[1].first)),
        turn @ truths[1].omega,
        moments[1:] / moments[0],
    )
    assert (
        np.max(
            search.frame_free_angles(truths[1].attitudes(seconds[1]), moved.attitudes(seconds[1]))
        )
        < 0.01
    )
    first = truths[0].attitudes(seconds[0])
    state, joined = search._joined(arcs, [first], [moved], material, normals=300)
    assert state is moved

    def chi2(second):
        epochs = FitEpochs.from_observations(arcs, [first, second])
        return fit_egi(epochs, material, normals=300).chi2

    assert chi2(joined) <= 1.05 * chi2(truths[1].attitudes(seconds[1]))
    assert chi2(joined) < 0.5 * chi2(moved.attitudes(seconds[1]))
