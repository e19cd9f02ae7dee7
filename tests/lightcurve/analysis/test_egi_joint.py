"""The joint mode's parts: the torque-free attitudes, the variable-projection refinement of
the states, the round logic and the command's wiring."""

import json
import math

import numpy as np
import pytest

import brdf
from benchmarks import shape_recovery
from filters.attitude import (
    attitude_angle,
    attitude_matrix,
    quaternion_from_matrix,
    rotation_vector_to_quaternion,
)
from lightcurve.analysis.egi import FitEpochs, joint, normal_grid, search
from lightcurve.analysis.egi.epochs import truth_attitudes
from lightcurve.analysis.egi.fit import egi_residuals, fit_egi
from lightcurve.cli import main
from lightcurve.io.observations import Observations


@pytest.fixture(scope="module")
def tumbling():
    """A 3 × 2 × 1 m box tumbling over a short geostationary arc (400 epochs at 2 s)."""
    shape = shape_recovery.objects()["box_3x2x1"]
    rng = np.random.default_rng(11)
    arc = shape_recovery.observe(shape, "geo_tumbling", rng, 0.03)
    arc = Observations(arc.table.iloc[:400].reset_index(drop=True), arc.meta, arc.source)
    moments, axes = np.linalg.eigh(shape.inertia)
    axes = axes * np.sign(np.linalg.det(axes))
    truth = truth_attitudes(arc)
    principal = quaternion_from_matrix(np.einsum("ji,ejk->eik", axes, attitude_matrix(truth)))
    omega = axes.T @ arc.table[["wx", "wy", "wz"]].to_numpy()[0]
    return arc, principal, omega, moments[1:] / moments[0]


def test_torque_free_attitudes_follow_the_simulated_truth(tumbling):
    arc, principal, omega, ratios = tumbling
    seconds = (arc.mjd - arc.mjd[0]) * 86400.0
    q = search.torque_free_attitudes(principal[0], omega, ratios, seconds)
    assert np.degrees(np.max(attitude_angle(q, principal))) < 0.05


def test_refinement_lowers_the_profile_chi2_to_the_truths(tumbling):
    arc, principal, omega, ratios = tumbling
    turn = np.random.default_rng(3).standard_normal(3)
    turn *= math.radians(10.0) / np.linalg.norm(turn)
    start = quaternion_from_matrix(
        attitude_matrix(rotation_vector_to_quaternion(turn)) @ attitude_matrix(principal[0])
    )
    material = shape_recovery._true_material()
    seconds = (arc.mjd - arc.mjd[0]) * 86400.0
    grid = normal_grid(joint.REFINE_NORMALS)

    def chi2(q):
        epochs = FitEpochs.from_observations([arc], [q])
        return float(np.sum(egi_residuals(epochs, material, grid) ** 2))

    before = search.torque_free_attitudes(start, omega * 1.01, ratios * 1.02, seconds)
    (after,), _ = joint.refine_states([arc], [(start, omega * 1.01)], ratios * 1.02, material)
    assert chi2(after) < chi2(before)
    assert chi2(after) < 1.2 * chi2(principal)


def test_the_mirror_hypothesis_gives_the_mirror_image_the_same_light_curve():
    # A chiral shape has no symmetry to hide behind: only its mirror image under the
    # mirrored attitudes reproduces the light curve, to the few degrees the Sun–observer
    # plane turns over the arc.
    from lightcurve.photometry.render import Renderer
    from shapes import FacetModel

    shape = shape_recovery.objects()["chiral"]
    arc = shape_recovery.observe(shape, "geo_tumbling", np.random.default_rng(12), 0.03)
    arc = Observations(arc.table.iloc[:400].reset_index(drop=True), arc.meta, arc.source)
    (half,) = joint.mirror_turns([arc])
    assert np.allclose(half @ half, np.eye(3)) and np.linalg.det(half) == pytest.approx(1.0)
    q = truth_attitudes(arc)
    mirrored = quaternion_from_matrix(attitude_matrix(q) @ half)
    image = FacetModel(-shape.vertices, shape.faces[:, ::-1], materials=shape_recovery.MATERIAL)

    def magnitudes(model, attitudes):
        render = Renderer(model, shadows="none")
        return render.magnitude(attitudes, arc.sun_vectors, arc.observer_vectors)

    truth = magnitudes(shape, q)

    def rms(mag):
        return float(np.sqrt(np.mean((mag - truth) ** 2)))

    assert rms(magnitudes(image, mirrored)) < 0.05
    assert rms(magnitudes(image, q)) > 0.5 and rms(magnitudes(shape, mirrored)) > 0.5


def test_the_rounds_stop_when_chi2_stops_falling(tumbling, monkeypatch):
    arc, principal, omega, ratios = tumbling
    calls = []

    def truth_states(observations, shape, seed):
        calls.append(shape.name)
        return [(principal[0], omega)], ratios, 0.03, [principal]

    monkeypatch.setattr(joint, "REFINE_STEPS", 3)
    material = shape_recovery._true_material()
    fit = joint.fit_joint(
        [arc], material, estimate_states=truth_states, normals=300, rounds=4, start="ellipsoid"
    )
    assert calls[0] == "start_ellipsoid" and 2 <= len(fit.rounds) < 4
    assert fit.best_round < len(fit.rounds)
    assert fit.fit.residual_rms_mag(fit.epochs) < 1.3 * 0.03
    # both hypotheses were fitted; the returned fit is the best of them
    assert {h.label for h in fit.hypotheses} == set(joint.HYPOTHESES)
    assert fit.hypotheses[0].chi2 == fit.fit.chi2 <= fit.hypotheses[1].chi2
    assert fit.rounds[fit.best_round].hypothesis == fit.hypotheses[0].label
    reduced = max(fit.fit.chi2 / (len(fit.epochs) - np.count_nonzero(fit.fit.areas)), 1.0)
    tied = (fit.hypotheses[1].chi2 - fit.fit.chi2) / reduced < joint.TIE_DELTA_CHI2
    # the mirror's attitude is another one
    assert fit.hypotheses[0].angle_to_best_deg == 0.0
    assert fit.hypotheses[1].angle_to_best_deg > joint.DISAGREE_DEG
    assert fit.ambiguous == tied
    with pytest.raises(ValueError, match="at least one round"):
        joint.fit_joint([arc], material, estimate_states=truth_states, rounds=0)
    with pytest.raises(ValueError, match="need estimate_states"):
        joint.fit_joint([arc], material, rounds=2)
    with pytest.raises(ValueError, match="cannot support"):
        joint.fit_joint([arc], material, estimate_states=truth_states, normals=20000)


def test_start_shape_carries_the_material():
    material = brdf.get("lambert", rd=0.3)
    shape = joint.start_shape(material)
    assert shape.name == "start_ellipsoid"
    assert joint.start_shape(material, "box").name == "box"


def test_joint_command_writes_method_joint(tumbling, tmp_path, monkeypatch, capsys):
    arc, principal, omega, ratios = tumbling
    monkeypatch.delenv("LIGHTCURVE_LIBRARY", raising=False)
    path = tmp_path / "arc.csv"
    from lightcurve import io

    io.write(arc, path)
    from lightcurve import joint_shape

    monkeypatch.setattr(
        joint_shape,
        "inverted_states",
        lambda o, s, seed: ([(principal[0], omega)], ratios, 0.03, [principal]),
    )
    monkeypatch.setattr(joint, "refine_states", lambda o, s, r, m: ([principal], r))
    truth = search.TorqueFreeState(principal[0], omega, ratios)
    (turn,) = joint.mirror_turns([arc])
    mirrored = quaternion_from_matrix(attitude_matrix(principal) @ turn)

    def found(observations, material, mirrors, *, seed, starts):
        # the search's answer stood in by the truth and its mirror
        out = []
        for label, q in (("minimum 1", principal), ("mirror", mirrored)):
            epochs = FitEpochs.from_observations([arc], [q])
            fit = fit_egi(epochs, material, normals=200)
            out.append(search.StateHypothesis(label, [truth], [q], fit, epochs))
        return sorted(out, key=lambda h: h.fit.chi2)

    monkeypatch.setattr(joint, "search_hypotheses", found)
    material = shape_recovery.MATERIAL
    params = [f"--param={k}={v}" for k, v in material.params.items()]
    argv = ["shape", path, "--out", tmp_path / "out", "--brdf", material.brdf, *params]
    assert main([str(a) for a in [*argv, "--normals", "200", "--rounds", "2", "-q"]]) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["method"] == "joint" and summary["attitude_source"] == "joint"
    assert len(summary["joint"]["rounds"]) >= 1
    # the search's hypotheses, then an inversion round's
    assert summary["joint"]["rounds"][0]["hypothesis"] in ("minimum 1", "mirror")
    assert summary["joint"]["rounds"][0]["inversion_rms_mag"] is None
    labels = [h["label"] for h in summary["joint"]["hypotheses"]]
    assert sorted(labels) in (["direct", "mirror"], ["minimum 1", "mirror"])
    assert all("angle_to_best_deg" in h for h in summary["joint"]["hypotheses"])
    assert isinstance(summary["joint"]["ambiguous"], bool)
    assert summary["joint"]["misfit"] == (summary["joint"]["reduced_chi2"] > 4.0)
    assert summary["joint"]["start"] == "search"
    assert (tmp_path / "out" / "attitudes.csv").is_file()
    assert main([str(a) for a in ["shape", path, "--out", tmp_path / "o2", "-q"]]) == 2
    assert "give the material" in capsys.readouterr().err
