"""Does a torque-free light-curve model, fitted per reading, tell a tumbler's reading apart?
Prints JSON.

The two-period analysis (:mod:`lightcurve.analysis.tumbling`) finds a lattice of
combination frequencies; which basis of it is the precession ``f_φ`` and the rotation
``f_ψ``, and in which mode, is its weak step. This study measures whether the torque-free
motion itself, fitted to the light curve under each reading, picks the true one.

**Model.** Under fixed Sun and observer directions the brightness is a function of the
attitude. Truncated at degree 2 of the rotation group, it is linear in the entries of the
attitude matrix and in the 25 degree-2 functions ``tr(S_a M S_b Mᵀ)`` (S_a: a basis of the
symmetric traceless matrices; Edmonds 1957, *Angular Momentum in Quantum Mechanics*,
ch. 4); at degree 3 (``--degree 3``) also in the 49 functions ``⟨T_a, (M ⊗ M ⊗ M) T_b⟩``
of the symmetric traceless rank-3 tensors T_a. A constant rotation on either side of ``M``
(the direction of ``L``, the initial precession angle, the shape's axes) is a linear map of
these columns, so only the torque-free motion in the frame of ``L``
(:mod:`filters.attitude.torque_free_motion`) is nonlinear: the moments ``A/C``, ``B/C`` on a
``grid × grid`` lattice (triangle inequality), ``d = L²/(2E)`` solved for the reading's
ratio ``P_φ/P_ψ``, and the time origin of the rotation over half a rotation period
(``phases`` steps; a half-period shift is a constant rotation by π). Fitted in flux
(``10^{−0.4 m}``, weights from the magnitude errors), each curve with a cubic trend, every
coefficient varying within the curve as a Legendre polynomial of degree ``MODULATION`` (the
geometry's slow change).

**Readings.** Every basis ``T (f_φ, f_ψ)`` of the *true* pair (entries of T in {−1, 0, 1},
``|det T| = 1``, both positive) in SAM and in LAM, and the twin of each (the same spin about
``L`` and the same other frequency x read in the other mode: a SAM ``(f_s + x, x)`` and a
LAM ``(x, f_s − x)``), kept when the torque-free period ratio allows it: ``f_ψ/f_φ < 1/2``
in a SAM, ``< C/A − 1`` in a LAM with ``C/A`` bounded
(:func:`~lightcurve.analysis.tumbling_reading.reading_hypotheses`; the figures in
``docs/analysis.md`` were measured with the bound 5, since raised). The true pair isolates
the reading step from the search's errors.

**Figures per run.** Each reading's least χ²; the true reading's rank; the margin of the
best rival; two references on the same points: the model at the true motion (true moments,
energy and period, time origin scanned: the truncation's floor) and the two-period Fourier
series at the true pair (order 6, the same trend and modulation: the model-free floor).

    python -m benchmarks.tumbling_model_reading [--seed 1] [--runs 0,1,4] [--points 1500]
        [--grid 7] [--phases 16] [--degree 2]
"""

from __future__ import annotations

import argparse
import itertools
import math
import time
from typing import Any

import numpy as np

from benchmarks._machine import machine_info
from benchmarks._report import emit_report
from benchmarks.tumbling_periods import MIN_CYCLES, simulate_run
from filters.attitude.torque_free_motion import (
    ScaledMotion,
    attitude_about_momentum,
    scaled_motion,
)
from filters.attitude.torque_free_periods import euler_periods, principal_state
from lightcurve.analysis.fourier_design import FourierDesign
from lightcurve.analysis.period import StackedLightCurves
from lightcurve.analysis.tumbling import TREND_DEGREE, two_period_combinations
from lightcurve.analysis.tumbling_reading import motions_with_ratio, reading_hypotheses

#: Degree of each coefficient's Legendre polynomial in the curve's time.
MODULATION = 2
#: Order of the reference two-period Fourier series.
FOURIER_ORDER = 6


def _traceless_basis(rank: int) -> np.ndarray:
    """(2 rank + 1, 3, …, 3) orthonormal basis of the symmetric traceless tensors of
    ``rank`` (2 or 3): the null space of the symmetrisation's complement and the trace."""
    size = 3**rank
    symmetrise = np.zeros((size, size))
    for index in itertools.product(range(3), repeat=rank):
        row = np.ravel_multi_index(index, (3,) * rank)
        perms = list(itertools.permutations(index))
        for perm in perms:
            symmetrise[row, np.ravel_multi_index(perm, (3,) * rank)] += 1.0 / len(perms)
    trace = np.einsum("nii...->n...", np.eye(size).reshape((size,) + (3,) * rank))
    constraints = np.concatenate([np.eye(size) - symmetrise, trace.reshape(size, -1).T])
    _, values, vectors = np.linalg.svd(constraints)
    null = vectors[np.sum(values > 1e-9) :]
    return null.reshape((len(null),) + (3,) * rank)


_TRACELESS = _traceless_basis(2)
_TRACELESS_3 = _traceless_basis(3)


def model_columns(attitude: np.ndarray, degree: int = 2) -> np.ndarray:
    """(N, 34) degree-1 and degree-2 functions of attitude matrices (N, 3, 3) (module
    docstring), with ``degree = 3`` also the 49 degree-3 ones (N, 83); the constant is the
    trend's."""
    n = len(attitude)
    rotated = np.einsum("nij,ajk,nlk->nail", attitude, _TRACELESS, attitude)
    columns = [
        attitude.reshape(n, 9),
        np.einsum("nail,bil->nab", rotated, _TRACELESS).reshape(n, 25),
    ]
    if degree == 3:
        once = np.einsum("nip,bpqr->nbiqr", attitude, _TRACELESS_3)
        twice = np.einsum("njq,nbiqr->nbijr", attitude, once)
        thrice = np.einsum("nkr,nbijr->nbijk", attitude, twice)
        columns.append(np.einsum("nbijk,aijk->nab", thrice, _TRACELESS_3).reshape(n, 49))
    return np.concatenate(columns, axis=1)


class FluxFit:
    """Weighted least squares in flux with per-curve trend and modulated coefficients."""

    def __init__(self, data: StackedLightCurves, keep: np.ndarray, degree: int = 2) -> None:
        self.degree = degree
        magnitude = data.magnitudes[keep]
        flux = 10.0 ** (-0.4 * (magnitude - np.median(magnitude)))
        sigma = flux * 0.4 * math.log(10.0) * data.sigma[keep]
        self.design = FourierDesign(
            data.times[keep], flux, sigma, data.curve[keep], trend_degree=TREND_DEGREE
        )
        self.t = self.design.t
        self.legendre = np.polynomial.legendre.legvander(self.design.tau, MODULATION).T

    def chi2(self, attitude: np.ndarray) -> float:
        """χ² of the model columns of ``attitude`` (N, 3, 3) at the fit's points."""
        x = model_columns(attitude, self.degree).T
        x = np.concatenate([x * row for row in self.legendre], axis=0)
        design = self.design
        xw = x * design.w
        sums = xw @ design.nuisance
        gram = xw @ x.T - sums @ sums.T
        gram += 1e-10 * np.trace(gram) * np.eye(len(gram))
        rhs = xw @ design.y
        return float(design.base - np.linalg.solve(gram, rhs) @ rhs)

    def best_origin(self, motion: ScaledMotion, f_psi: float, phases: int) -> float:
        """Least χ² over the rotation's time origin (half a period in ``phases`` steps)."""
        return min(
            self.chi2(attitude_about_momentum(motion, f_psi * self.t - origin))
            for origin in np.arange(phases) / (2.0 * phases)
        )


def study_run(
    seed: int, index: int, *, points: int, grid: int, phases: int, degree: int = 2
) -> dict[str, Any]:
    """The figures of one run of the tumbler benchmark (module docstring).

    Parameters
    ----------
    seed, index : int
        The run (:func:`benchmarks.tumbling_periods.simulate_run`).
    points : int
        Points fitted (a subset drawn with the seed ``N``, the run's point count).
    grid : int
        Moment lattice per axis.
    phases : int
        Time origins per half rotation period.
    degree : int
        Model degree, 2 or 3.

    Returns
    -------
    dict
        JSON-ready figures; ``true_rank`` is 0 when the true reading has the least χ²
        (None when no body of the lattice has its period ratio).
    """
    observations, inertia, omega, scenario, _ = simulate_run(seed, index)
    truth = euler_periods(inertia, omega)
    data = StackedLightCurves.of(observations)
    n = len(data.times)
    keep = np.sort(np.random.default_rng(n).choice(n, min(n, points), replace=False))
    fit = FluxFit(data, keep, degree)
    pair = np.array([1.0 / truth.precession_period_s, 1.0 / truth.rotation_period_s])
    started = time.process_time()
    readings, unreachable = [], 0
    for f_phi, f_psi, mode, _ in reading_hypotheses(pair):
        motions = motions_with_ratio(f_psi / f_phi, mode, grid)
        if not motions:  # no body of the lattice has this period ratio in this mode
            unreachable += 1
            continue
        chi2 = min(fit.best_origin(m, f_psi, phases) for m in motions)
        readings.append(
            {
                "precession_s": 1.0 / f_phi,
                "rotation_s": 1.0 / f_psi,
                "mode": mode,
                "true": bool(np.allclose([f_phi, f_psi], pair, rtol=1e-9) and mode == truth.mode),
                "chi2": chi2,
            }
        )
    cpu = time.process_time() - started
    readings.sort(key=lambda r: r["chi2"])
    rank = next((i for i, r in enumerate(readings) if r["true"]), None)
    true_chi2 = None if rank is None else readings[rank]["chi2"]
    rival = min(r["chi2"] for r in readings if not r["true"])
    moments, rates = principal_state(inertia, omega)
    two_e = float(np.sum(moments * rates**2))
    d = float(np.sum((moments * rates) ** 2)) / two_e / moments[2]
    floor_model = fit.best_origin(
        scaled_motion(moments / moments[2], d, truth.mode), pair[1], 4 * phases
    )
    fourier = fit.design.solve_combinations(
        pair[None], two_period_combinations(FOURIER_ORDER), modulation=MODULATION
    )[1][0]
    return {
        "run": index,
        "scenario": scenario,
        "mode": truth.mode,
        "true_precession_s": truth.precession_period_s,
        "true_rotation_s": truth.rotation_period_s,
        "covered": bool(np.ptp(data.times) >= MIN_CYCLES * max(1.0 / pair)),
        "points": len(keep),
        "true_rank": rank,
        "true_chi2": true_chi2,
        "best_rival_chi2": rival,
        "model_at_true_motion_chi2": floor_model,
        "fourier_at_true_pair_chi2": float(fourier),
        "true_motion_to_fourier_ratio": floor_model / float(fourier),
        "readings": readings,
        "readings_without_motion": unreachable,
        "reading_cpu_s": cpu,
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--runs", default="0,1,4,10,12,13", help="comma-separated run indices")
    parser.add_argument("--points", type=int, default=1500, help="points fitted per run")
    parser.add_argument("--grid", type=int, default=7, help="moment lattice per axis")
    parser.add_argument("--phases", type=int, default=16, help="time origins per half period")
    parser.add_argument("--degree", type=int, choices=(2, 3), default=2, help="model degree")
    parser.add_argument("--out", help="also write the JSON report here")
    args = parser.parse_args(argv)
    records = [
        study_run(
            args.seed,
            int(i),
            points=args.points,
            grid=args.grid,
            phases=args.phases,
            degree=args.degree,
        )
        for i in args.runs.split(",")
    ]
    report = {
        "seed": args.seed,
        "points": args.points,
        "grid": args.grid,
        "phases": args.phases,
        "degree": args.degree,
        "machine": machine_info(),
        "true_reading_first": int(sum(r["true_rank"] == 0 for r in records)),
        "true_reading_without_motion": int(sum(r["true_rank"] is None for r in records)),
        "runs": len(records),
        "records": records,
    }
    emit_report(report, args.out)


if __name__ == "__main__":
    main()
