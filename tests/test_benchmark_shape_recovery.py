"""The shape-recovery benchmark's core on one small case: its objects, scores and summary."""

import argparse

import numpy as np
import pytest

from benchmarks import shape_recovery
from lightcurve.analysis.egi import EGIFit, FitEpochs, fit_egi
from lightcurve.analysis.egi.epochs import truth_attitudes


def test_objects_are_closed_convex_and_not_in_the_library():
    from shapes import get_library

    names = set(get_library().names())
    for name, model in shape_recovery.objects().items():
        assert name not in names
        assert model.mesh.is_watertight and model.mesh.is_convex


@pytest.fixture(scope="module")
def arcs():
    shape = shape_recovery.objects()["box_3x2x1"]
    rng = np.random.default_rng(5)
    fitted_on = shape_recovery.observe(shape, "geo_tumbling", rng, 0.03)
    held_out = shape_recovery.observe(shape, "geo_tumbling", rng, 0.03)
    return shape, fitted_on, held_out


def test_the_true_egi_scores_at_the_noise(arcs):
    shape, _, held_out = arcs
    compiled = shape.compiled()
    truth = EGIFit(
        compiled.normals,
        compiled.areas,
        np.zeros(len(compiled.areas)),
        shape_recovery._true_material(),
        np.zeros(1),
        0.0,
        0.0,
    )
    scored = shape_recovery.score(shape, truth, held_out, 0.03)
    assert scored["heldout_ratio"] == pytest.approx(1.0, abs=0.1)
    assert scored["axis_ratio_error"] < 1e-6
    assert max(scored["normal_error_deg"]) < 1e-6
    assert scored["n_facets"] == 6


def test_a_known_material_fit_is_scored_and_summarised(arcs):
    shape, fitted_on, held_out = arcs
    epochs = FitEpochs.from_observations([fitted_on], [truth_attitudes(fitted_on)])
    fit = fit_egi(epochs, shape_recovery._true_material(), normals=500)
    fewest, faces = shape_recovery._faces(
        shape, fit, epochs, held_out, 0.03, argparse.Namespace(faces="fewest")
    )
    assert faces["kept_facets"] < faces["fitted_facets"]
    scored = shape_recovery.score(shape, fewest, held_out, 0.03)
    assert max(scored["normal_error_deg"]) < 5.0
    record = {
        "scenario": "geo_tumbling",
        "known": {"fit_s": 1.0, **faces, **scored},
        "fitted": {"error": "x"},
    }
    summary = shape_recovery.summarise([record])
    assert summary["geo_tumbling/known"]["runs"] == 1
    assert summary["geo_tumbling/known"]["simplified_runs"] == 1
    # the baseline beside it: the plain fit's own scores
    plain = shape_recovery.score(shape, fit, held_out, 0.03)["heldout_ratio"]
    assert summary["geo_tumbling/known"]["all_faces_heldout_ratio_median"] == plain
    assert summary["geo_tumbling/fitted"]["failed"] == 1
    assert scored["heldout_ratio_egi"] == pytest.approx(scored["heldout_ratio"], rel=0.5)
    record |= shape_recovery.identifiability(shape, [fitted_on], held_out)
    split = shape_recovery.summarise([record])["geo_tumbling/known"]
    assert split["phase_inside_runs"] + split["phase_outside_runs"] == 1


def test_frame_alignment_recovers_a_constant_turn():
    from filters.attitude import attitude_matrix, quaternion_from_matrix, random_quaternion

    rng = np.random.default_rng(2)
    truth = random_quaternion((50,), rng)
    turn = attitude_matrix(random_quaternion((), rng))
    fitted = quaternion_from_matrix(np.einsum("ji,ejk->eik", turn, attitude_matrix(truth)))
    found = shape_recovery.frame_alignment(truth, fitted)
    assert np.allclose(found, turn, atol=1e-9)
    assert np.max(shape_recovery.aligned_errors(truth, fitted, found)) < 1e-5


def test_the_mirror_alignment_undoes_the_mirror_hypothesis(arcs):
    from filters.attitude import attitude_matrix, quaternion_from_matrix, random_quaternion
    from lightcurve.analysis.egi.joint import mirror_turns

    _, fitted_on, _ = arcs
    truth = truth_attitudes(fitted_on)
    (half,) = mirror_turns([fitted_on])
    turn = attitude_matrix(random_quaternion((), np.random.default_rng(8)))
    # fitted attitudes of the mirror hypothesis in a turned body frame: A = Rᵀ A_true R_m
    fitted = quaternion_from_matrix(turn.T @ attitude_matrix(truth) @ half)
    errors, mapping, label = shape_recovery.mirror_aligned(truth, [fitted], [fitted_on])
    assert label == "mirror" and np.max(errors) < 1e-5
    assert np.allclose(mapping, -turn, atol=1e-9)
    direct = quaternion_from_matrix(turn.T @ attitude_matrix(truth))
    errors, mapping, label = shape_recovery.mirror_aligned(truth, [direct], [fitted_on])
    assert label == "direct" and np.allclose(mapping, turn, atol=1e-9)


def test_identifiability_of_a_held_out_arc(arcs):
    shape, fitted_on, held_out = arcs
    found = shape_recovery.identifiability(shape, [fitted_on], held_out)
    assert 0.0 <= found["heldout_unseen_flux_share"] <= 1.0
    assert found["heldout_phase_outside_deg"] >= 0.0
    # the held-out arc itself: every facet it shows was seen, at phase angles inside
    itself = shape_recovery.identifiability(shape, [held_out], held_out)
    assert itself["heldout_unseen_flux_share"] == 0.0
    assert itself["heldout_phase_outside_deg"] == 0.0


def test_a_leo_pass_sweeps_a_wider_phase_range_than_a_geo_arc():
    shape = shape_recovery.objects()["box_1.5x1.5x1"]

    def phase_span(scenario):
        arc = shape_recovery.observe(shape, scenario, np.random.default_rng(4), 0.03)
        sun, obs = arc.sun_vectors, arc.observer_vectors
        cosine = np.sum(sun * obs, 1) / np.linalg.norm(sun, axis=1) / np.linalg.norm(obs, axis=1)
        return np.ptp(np.degrees(np.arccos(cosine)))

    assert phase_span("leo_pass") > 2 * phase_span("geo_tumbling")
