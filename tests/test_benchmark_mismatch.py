"""The model-mismatch benchmark: its command line, candidates, aggregates and one tiny run."""

import argparse
import json
import math

import numpy as np
import pytest

from benchmarks.mismatch import Settings, check, parse_args, parse_option, run_case, summarise
from benchmarks.mismatch_study import candidates, draw_case

BANK = ["box", "box_wing", "rocket_body", "cube", "cylinder", "plate"]


def test_options_are_python_literals_for_every_method_or_one():
    assert parse_option("estimate_inertia=True") == ("*", "estimate_inertia", True)
    assert parse_option("ukf:gate_probability=0.001") == ("ukf", "gate_probability", 0.001)
    assert parse_option("estimate=('inertia', 'scale')") == ("*", "estimate", ("inertia", "scale"))
    assert parse_option("likelihood=student") == ("*", "likelihood", "student")
    for bad in ("estimate_inertia", "=1", "kalman:alpha=1"):
        with pytest.raises(argparse.ArgumentTypeError):
            parse_option(bad)


def test_the_command_line_sets_the_run_counts_and_refuses_what_invert_would():
    settings, _ = parse_args(["--runs", "2", "--methods", "ukf,pf", "--option", "ukf:alpha=0.5"])
    assert settings.runs == {"ukf": 2, "mmae": 2, "pf": 2}
    assert settings.options_for("ukf") == {"alpha": 0.5} and settings.options_for("pf") == {}
    assert parse_args([])[0].runs["pf"] == 20
    with pytest.raises(ValueError, match="option"):
        check(Settings(methods=("pf",), options={"*": {"estimate_offset": True}}))
    with pytest.raises(ValueError, match="bank"):
        check(Settings(shapes=("itokawa",), bank=tuple(BANK)))
    with pytest.raises(ValueError, match="five"):
        check(Settings(methods=("mmae",), shapes=("box",), bank=("box", "cube")))


def test_candidates_hold_the_parent_except_for_the_foreign_bank():
    assert candidates("ukf", "box", 0, BANK, 3) == ["box"]
    inside = candidates("mmae", "box_wing", 0, BANK, 3)
    assert inside[0] == "box_wing" and sorted(inside) == sorted(BANK)
    foreign = candidates("mmae", "box_wing", 0, BANK, 3, foreign=True)
    assert "box_wing" not in foreign and len(foreign) == 5
    pf = [candidates("pf", "box", i, BANK, 3) for i in range(3)]
    assert all(c[0] == "box" and len(set(c)) == 3 for c in pf)
    assert len({tuple(c) for c in pf}) == 3  # the others change from run to run


def test_the_same_object_is_drawn_in_every_scenario():
    geo = draw_case(0, 1, "geo", "box", geo_duration_s=300.0)
    again = draw_case(0, 1, "geo", "box", geo_duration_s=300.0)
    assert geo.perturbation.model.fingerprint == again.perturbation.model.fingerprint
    np.testing.assert_array_equal(geo.q0, again.q0)
    assert geo.geometry_record == again.geometry_record
    assert 0.3 <= math.degrees(np.linalg.norm(geo.omega0)) <= 1.5
    assert len(geo.geometry) >= 135  # 90 % of 150 epochs


def test_the_aggregates_count_wrong_shapes_and_errors_as_misses():
    def run(**fields):
        base = {"method": "mmae", "scenario": "geo", "truth": "perturbed", "parent": "box"}
        base["candidates"] = ["box", "cube"]
        base.update(fields)
        return base

    common = {
        "none_fits": False,
        "attitude_sigma_deg": 1.0,
        "residual_rms_mag": 0.03,
        "rejected_fraction": 0.0,
        "runtime_s": 1.0,
    }
    records = [
        run(
            p_parent=0.95,
            attitude_error_deg=1.0,
            rate_error_deg_s=0.01,
            inside_3_sigma=True,
            nees=6.0,
            **common,
        ),
        run(
            p_parent=0.95,
            attitude_error_deg=9.0,
            rate_error_deg_s=0.01,
            inside_3_sigma=False,
            nees=None,
            **common,
        ),
        run(p_parent=0.2, **{**common, "none_fits": True}),  # the other shape reported
        run(error="RuntimeError: diverged"),
    ]
    (summary,) = summarise(records).values()
    assert summary["runs"] == 4 and summary["errors"] == 1 and summary["parent_reported"] == 2
    assert summary["within_5_deg"] == 0.25
    assert summary["rates_within_0_05_deg_s"] == 0.5
    assert summary["inside_3_sigma"] == 0.5
    assert summary["parent_p_0_9"] == 0.5 and summary["parent_p_0_9_and_within_5_deg"] == 0.25
    assert summary["none_fits"] == pytest.approx(1 / 3)
    assert summary["nees_available"] == 1


def test_one_short_run_of_the_ukf_on_both_truths_gives_finite_figures():
    settings = Settings(
        methods=("ukf",),
        scenarios=("geo",),
        runs={"ukf": 1, "mmae": 1, "pf": 1},
        geo_duration_s=300.0,
        # a quick search: few candidates, one round
        options={"*": {"global_candidates": 2000, "search_rounds": 1, "refine_keep": (32, 8)}},
    )
    case = run_case(settings, "geo", 0)
    json.dumps(case)
    assert case["case"]["parent"] == "box" and case["case"]["perturbation"]["parent"] == "box"
    assert {r["truth"] for r in case["runs"]} == {"perturbed", "exact"}
    for record in case["runs"]:
        assert "error" not in record, record.get("error")
        assert record["shape"] == "box" and record["candidates"] == ["box"]
        assert math.isfinite(record["attitude_error_deg"]) and record["attitude_error_deg"] <= 180
        assert math.isfinite(record["rate_error_deg_s"]) and math.isfinite(record["runtime_s"])
        assert 0.0 <= record["rejected_fraction"] <= 1.0
    exact = case["truth_parameters"]["exact"]
    assert exact["magnitude_offset"] == 0.0 and exact["mismatch_rms_mag"] == 0.0
    assert case["truth_parameters"]["perturbed"]["mismatch_rms_mag"] > 0.0


def test_putting_back_the_stretch_and_materials_leaves_only_the_appendage():
    from benchmarks.mismatch_parts import PARTS, part_errors

    parts = part_errors(0, 0, geo_duration_s=60.0)
    assert parts["parent"] == "box" and parts["appendage"] in ("antenna", "thruster")
    rms = {name: parts[name]["rms_mag"] for name in PARTS}
    assert all(0.0 <= v < 2.0 for v in rms.values())
    # The library box is off by the perturbation; with its stretch and paint put back,
    # only the small appendage is left to tell the two apart.
    assert rms["stretch+materials"] < 0.5 * rms["library"]
    assert parts["stretch+materials"]["p90_mag"] <= parts["library"]["p90_mag"]
