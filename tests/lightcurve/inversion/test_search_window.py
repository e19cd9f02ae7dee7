"""The initial search's window of a turn: a slow rotator is searched on windows long enough
to tell its states apart."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benchmarks.mismatch_study import draw_case, simulate_case
from filters.global_search import SearchResult
from lightcurve.inversion import invert, shape_symmetry
from lightcurve.inversion.search import turn_window
from shapes import get_library


def _found(rates_deg_s: list[float], chi2: list[float]) -> SearchResult:
    n = len(rates_deg_s)
    omega = np.zeros((n, 3))
    omega[:, 2] = np.radians(rates_deg_s)
    return SearchResult(
        q=np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)),
        omega=omega,
        k=None,
        shape=np.zeros(n, dtype=int),
        chi2=np.asarray(chi2, dtype=float),
        covariance=np.tile(np.eye(6), (n, 1, 1)),
        epochs=np.arange(90),
        screened=1000,
    )


def test_turn_window_follows_the_slowest_plausible_fit() -> None:
    found = _found([1.0, 0.5, 0.1], [90.0, 150.0, 400.0])
    # the fit at 0.1 °/s is not plausible (χ² above twice the best): 360° at 0.5 °/s
    assert turn_window(found, math.radians(360.0)) == pytest.approx(720.0)
    assert turn_window(found, math.radians(360.0), ratio=5.0) == pytest.approx(3600.0)
    assert turn_window(found, 0.0) == 0.0
    assert turn_window(_found([0.0], [90.0]), math.radians(360.0)) == math.inf


def test_a_slow_tumbler_is_searched_over_a_turn() -> None:
    """A box-wing tumbling at 0.31 °/s over a 40-minute GEO arc (exact model): the default
    300 s window left many states fitting alike and the UKF ended 106° off; the window of
    a turn finds it."""
    case = draw_case(0, 4, "geo", "box_wing")
    assert math.degrees(np.linalg.norm(case.omega0)) < 0.35
    observations = simulate_case(case, "exact")
    shape = get_library().load("box_wing")
    result = invert(observations, {"box_wing": shape}, "ukf", seed=case.inversion_seed)
    assert any("searched again on windows up to" in note for note in result.notes)
    error = math.degrees(
        shape_symmetry(shape).attitude_error(result.quaternion, observations.truth[-1, :4])
    )
    assert error < 5.0
    assert not result.none_fits
