"""The tumbling benchmark's core on tiny cases (so it cannot rot)."""

import numpy as np

from benchmarks.tumbling_periods import (
    drift_nights,
    egg,
    lattice_relation,
    rates_in_mode,
    run_case,
)
from filters.attitude.torque_free_periods import euler_periods


def test_run_case_records_truth_and_estimate():
    record = run_case(0, 2)  # a short low-orbit pass
    assert record["scenario"] == "leo" and record["mode"] == "SAM"
    assert record["true_rotation_s"] > record["true_precession_s"] > 0
    assert {"both_right", "pair_right", "tumbling", "delta_bic", "covered"} <= set(record)
    assert record["lattice"] in ("same", "finer", "coarser", "other")
    assert record["lattice_right"] == (record["lattice"] == "same")
    assert {"rule_both_right", "reading_method", "reading_delta_chi2"} <= set(record)
    assert record["reading_method"] in ("convex", "rule")


def test_rates_in_the_asked_mode_and_an_asymmetric_egg():
    rng = np.random.default_rng(1)
    inertia = np.diag([1.0, 2.0, 2.5])
    for mode in ("SAM", "LAM"):
        assert euler_periods(inertia, rates_in_mode(rng, inertia, mode)).mode == mode
    assert euler_periods(inertia, rates_in_mode(rng, inertia, "PA-max")).mode == "PA"
    body = egg(np.array([1.0, 1.5, 2.0]), np.array([1.5, 1.5]))
    assert body.vertices[:, 0].max() > 1.4 and body.vertices[:, 0].min() > -1.01


def test_drift_nights_grow_the_period():
    nights = drift_nights(0, 0, 0.005)
    assert len(nights) == 30
    first, last = (np.linalg.norm(n.truth[0, 4:]) for n in (nights[0], nights[-1]))
    assert abs(first / last - 1.005) < 1e-9


def test_short_pass_whose_period_sits_at_the_range_edge_is_searched():
    """A 9-min low-orbit pass: the one-period search's period lies at the edge of the default
    range, and the one-period rival must still be fitted there."""
    record = run_case(0, 11)
    assert "error" not in record and "delta_bic" in record


def test_lattice_relation_of_generators_sublattices_and_aliases():
    truth = np.array([1 / 365.7, 1 / 1885.9])  # (f_φ, f_ψ), Hz
    f_phi, f_psi = truth
    assert lattice_relation(truth[::-1], truth) == "same"
    assert lattice_relation(np.array([f_phi - f_psi, f_psi]), truth) == "same"
    assert lattice_relation(np.array([f_phi + f_psi, f_phi]), truth) == "same"
    assert lattice_relation(np.array([f_phi / 2, f_psi]), truth) == "finer"
    assert lattice_relation(np.array([2 * f_phi + f_psi, f_psi]), truth) == "coarser"
    assert lattice_relation(np.array([1 / 413.1, 1 / 543.7]), truth) == "other"
