"""The inversion on objects that are not exactly their library model. Prints JSON.

    python -m benchmarks.mismatch [--runs 50] [--pf-runs 20] [--methods ukf,mmae,pf]
        [--scenarios geo,leo] [--shapes box,box_wing,rocket_body]
        [--bank box,box_wing,rocket_body,cube,cylinder,plate] [--option [METHOD:]KEY=VALUE ...]
        [--seed 0] [--workers 2] [--out FILE]

Truths, scenarios and noise are those of :mod:`benchmarks.mismatch_study`: per run a
perturbation of a library shape (the parent: ``--shapes`` in turn), tumbling from a
random attitude at 0.3–1.5 °/s, seen over a 40-minute geostationary arc or a low-orbit pass
at 2 s, 0.03 mag, rendered with ray-cast shadows; every run is also inverted on the parent
itself (``truth: exact``, the same states, geometry and noise) unless ``--no-exact``.
Run ``i`` of a scenario is the same object for every method. The methods, called in-process
with ``lightcurve.inversion.invert(observations, shapes, method, seed=…, **options)``
(no attitude prior: the initial state is searched):

``ukf``
    the parent as the only candidate;
``mmae``
    the bank (at least five shapes, the parent among them); and ``mmae_foreign``: the
    bank without the parent, where the right answer is ``none_fits``;
``pf``
    the parent and ``--pf-shapes − 1`` other shapes of the bank (uniform prior over
    them), the others taken in turn.

``--option KEY=VALUE`` (repeatable) passes an option to ``invert`` (every method, or one
with ``METHOD:KEY=VALUE``); values are Python literals (``True``, ``0.5``,
``("inertia", "scale")``), anything else a string, so the script measures options as they
are added.

Per run: the final attitude error modulo the parent's symmetry group and the rate error
turned by the same group element (when the reported shape is the parent), the error from
the nearest of the truth and its photometric twins at the last epoch (reciprocity, and for
a mirror-symmetric shape mirror, twins: an ambiguity the arc left), the reported
attitude 1σ and whether the error is within 3 × it, the NEES of ``[δθ, ω]`` (6 degrees of
freedom) where the covariance is finite, the parent's probability, ``none_fits``, the
residual rms, the fraction of measurements rejected by the innovation gate, the estimated
parameters against the truth's (``k1, k2`` tanh inertia about the parent's axes,
``magnitude_offset``, ``stretch_1..3``; every estimated key the truth has) and the
runtime. An inversion that raises is recorded with its error.

Aggregated per method, scenario and truth: the fraction of runs within 5° of the truth (a
run with the wrong shape or an error counts as outside) and within 5° of the truth or a
twin, of rates within 0.05 °/s, of runs with the truth inside the reported 3σ (among runs
with the parent reported), of the parent at ``p ≥ 0.9`` (MMAE, PF), of ``none_fits`` (for
``mmae_foreign`` the detection rate), the PF's right shape at ``p ≥ 0.9`` and within 5°,
medians of the errors, 1σ, NEES, residual, rejected fraction and runtime.
"""

from __future__ import annotations

import argparse
import ast
import functools
import math
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from benchmarks._machine import machine_info
from benchmarks._report import emit_report
from benchmarks.mismatch_study import (
    SCENARIOS,
    Case,
    candidates,
    draw_case,
    score,
    simulate_case,
    truth_parameters,
)
from lightcurve.inversion import METHODS, invert, validate_request
from lightcurve.io.atomic import json_ready
from lightcurve.io.observations import Observations
from shapes import FacetModel, get_library

#: Shapes the objects are drawn from, in turn (the parents).
DEFAULT_SHAPES = ("box", "box_wing", "rocket_body")
#: MMAE candidates (the parents and three more), also the PF's other candidates.
DEFAULT_BANK = ("box", "box_wing", "rocket_body", "cube", "cylinder", "plate")
WITHIN_DEG = 5.0
RATE_WITHIN_DEG_S = 0.05
PROBABILITY = 0.9


@dataclass(frozen=True)
class Settings:
    """What one benchmark run measures (the command line, parsed)."""

    seed: int = 0
    methods: tuple[str, ...] = ("ukf", "mmae", "pf")
    scenarios: tuple[str, ...] = SCENARIOS
    runs: dict[str, int] = field(default_factory=lambda: {"ukf": 50, "mmae": 50, "pf": 20})
    shapes: tuple[str, ...] = DEFAULT_SHAPES
    bank: tuple[str, ...] = DEFAULT_BANK
    pf_shapes: int = 3
    exact: bool = True
    options: dict[str, dict[str, Any]] = field(default_factory=dict)
    geo_duration_s: float = 2400.0
    leo_min_pass_s: float = 300.0

    def options_for(self, method: str) -> dict[str, Any]:
        """Options passed to ``invert`` for ``method`` (the common ones, then its own)."""
        return {**self.options.get("*", {}), **self.options.get(method, {})}

    def cases(self) -> int:
        """Cases per scenario: the most runs any chosen method makes."""
        return max(self.runs[m] for m in self.methods)


@functools.lru_cache(maxsize=16)
def _shape(name: str) -> FacetModel:
    return get_library().load(name)


def run_case(settings: Settings, scenario: str, index: int) -> dict[str, Any]:
    """Simulate case ``index`` of ``scenario`` and invert it with every method whose run
    count reaches it; the case record, the truth's parameters and one record per inversion."""
    parent = settings.shapes[index % len(settings.shapes)]
    case = draw_case(
        settings.seed,
        index,
        scenario,
        parent,
        geo_duration_s=settings.geo_duration_s,
        leo_min_pass_s=settings.leo_min_pass_s,
    )
    kinds = ("perturbed", "exact") if settings.exact else ("perturbed",)
    lightcurves: dict[str, Observations | str] = {}
    for kind in kinds:
        try:
            lightcurves[kind] = simulate_case(case, kind)
        except ValueError as exc:  # dark at every epoch: every run of this truth fails
            lightcurves[kind] = f"simulate: {exc}"
    truths = {
        kind: truth_parameters(case, kind, obs)
        for kind, obs in lightcurves.items()
        if not isinstance(obs, str)
    }
    records = []
    for method in settings.methods:
        if index >= settings.runs[method]:
            continue
        for foreign in (False, True) if method == "mmae" else (False,):
            names = candidates(
                method, parent, index, list(settings.bank), settings.pf_shapes, foreign
            )
            for kind in kinds:
                if foreign and kind == "exact":
                    continue
                label = f"{method}_foreign" if foreign else method
                observations = lightcurves[kind]
                if isinstance(observations, str):
                    record = {
                        "scenario": scenario,
                        "run": index,
                        "parent": parent,
                        "error": observations,
                    }
                else:
                    record = _one_run(settings, case, method, names, observations, truths[kind])
                records.append(record | {"method": label, "truth": kind, "candidates": names})
    return {"case": case.record(), "truth_parameters": truths, "runs": records}


def _one_run(
    settings: Settings,
    case: Case,
    method: str,
    names: list[str],
    observations: Observations,
    truths: dict[str, float],
) -> dict[str, Any]:
    """One inversion and its score; an inversion that raises gives its error."""
    start = time.perf_counter()
    try:
        result = invert(
            observations,
            {name: _shape(name) for name in names},
            method,
            seed=case.inversion_seed,
            **settings.options_for(method),
        )
    except Exception as exc:  # a failed inversion is a result of the benchmark
        return {
            "scenario": case.scenario,
            "run": case.index,
            "parent": case.parent,
            "error": f"{type(exc).__name__}: {exc}"[:500],
            "wall_s": time.perf_counter() - start,
        }
    record = score(result, observations, case, truths)
    return {
        "scenario": case.scenario,
        "run": case.index,
        "parent": case.parent,
        **record,
        "wall_s": time.perf_counter() - start,
    }


# ------------------------------------------------------------------------------ aggregation
def _fraction(flags: Sequence[bool]) -> float | None:
    return float(np.mean(flags)) if len(flags) else None


def _median(values: Sequence[float | None]) -> float | None:
    finite = [v for v in values if v is not None and math.isfinite(v)]
    return float(np.median(finite)) if finite else None


def summarise(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Aggregate figures per ``method/scenario/truth`` (module docstring)."""
    groups: dict[str, list[dict[str, Any]]] = {}
    for r in records:
        groups.setdefault(f"{r['method']}/{r['scenario']}/{r['truth']}", []).append(r)
    return {key: _summary(group) for key, group in sorted(groups.items())}


def _summary(runs: list[dict[str, Any]]) -> dict[str, Any]:
    done = [r for r in runs if "error" not in r]
    right = [r for r in done if "attitude_error_deg" in r]
    within = [r.get("attitude_error_deg", math.inf) <= WITHIN_DEG for r in runs]
    rates = [r.get("rate_error_deg_s", math.inf) <= RATE_WITHIN_DEG_S for r in runs]
    nees = [r["nees"] for r in right if r.get("nees") is not None and math.isfinite(r["nees"])]
    out: dict[str, Any] = {
        "runs": len(runs),
        "errors": len(runs) - len(done),
        "parent_reported": len(right),
        "within_5_deg": _fraction(within),
        "rates_within_0_05_deg_s": _fraction(rates),
        "within_5_deg_and_0_05_deg_s": _fraction(
            [a and b for a, b in zip(within, rates, strict=True)]
        ),
        "within_5_deg_of_truth_or_twin": _fraction(
            [r.get("attitude_error_or_twin_deg", math.inf) <= WITHIN_DEG for r in runs]
        ),
        "inside_3_sigma": _fraction([r["inside_3_sigma"] for r in right]),
        "none_fits": _fraction([r["none_fits"] for r in done]),
        "median_attitude_error_deg": _median([r["attitude_error_deg"] for r in right]),
        "median_rate_error_deg_s": _median([r["rate_error_deg_s"] for r in right]),
        "median_attitude_sigma_deg": _median([r["attitude_sigma_deg"] for r in done]),
        "median_nees": _median(nees),
        "mean_nees": float(np.mean(nees)) if nees else None,
        "nees_available": len(nees),
        "median_residual_rms_mag": _median([r["residual_rms_mag"] for r in done]),
        "median_rejected_fraction": _median([r["rejected_fraction"] for r in done]),
        "median_runtime_s": _median([r["runtime_s"] for r in done]),
    }
    if all(r["parent"] in r["candidates"] and len(r["candidates"]) > 1 for r in runs):
        parent_p = [(r.get("p_parent") or 0.0) >= PROBABILITY for r in runs]
        out["parent_p_0_9"] = _fraction(parent_p)
        out["parent_p_0_9_and_within_5_deg"] = _fraction(
            [p and w for p, w in zip(parent_p, within, strict=True)]
        )
    ratio = [r["inertia_ratio_error"] for r in done if "inertia_ratio_error" in r]
    if ratio:
        out["median_inertia_ratio_error"] = _median(ratio)
    keys = sorted({k for r in done for k in r.get("parameter_errors", {})})
    if keys:
        out["median_abs_parameter_errors"] = {
            k: _median([abs(r["parameter_errors"][k]) for r in done if k in r["parameter_errors"]])
            for k in keys
        }
    return out


# ------------------------------------------------------------------------------- command line
def parse_option(text: str) -> tuple[str, str, Any]:
    """``[METHOD:]KEY=VALUE`` → ``(method or "*", key, value)``; the value is a Python
    literal when it parses as one, else the string itself."""
    target, colon, rest = text.partition(":")
    if not colon or "=" in target:
        target, rest = "*", text
    key, equals, value = rest.partition("=")
    key = key.strip()
    if not equals or not key.isidentifier():
        raise argparse.ArgumentTypeError(f"expected [METHOD:]KEY=VALUE, got {text!r}")
    if target != "*" and target not in METHODS:
        raise argparse.ArgumentTypeError(f"unknown method {target!r} in {text!r}")
    try:
        parsed = ast.literal_eval(value.strip())
    except (ValueError, SyntaxError):
        parsed = value.strip()
    return target, key, parsed


def _names(text: str) -> tuple[str, ...]:
    return tuple(name.strip() for name in text.split(",") if name.strip())


def parse_args(argv: list[str] | None = None) -> tuple[Settings, argparse.Namespace]:
    """The settings of the command line (checked: names, counts, options)."""
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.mismatch", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--runs", type=int, default=50, help="runs per scenario (UKF, MMAE)")
    parser.add_argument("--pf-runs", type=int, help="PF runs per scenario (default min(runs, 20))")
    parser.add_argument("--methods", type=_names, default=("ukf", "mmae", "pf"))
    parser.add_argument("--scenarios", type=_names, default=SCENARIOS)
    parser.add_argument("--shapes", type=_names, default=DEFAULT_SHAPES, help="parents")
    parser.add_argument("--bank", type=_names, default=DEFAULT_BANK, help="MMAE candidates")
    parser.add_argument("--pf-shapes", type=int, default=3, help="PF candidates per run")
    parser.add_argument(
        "--option",
        action="append",
        type=parse_option,
        default=[],
        metavar="[METHOD:]KEY=VALUE",
        help="option passed to invert (repeatable)",
    )
    parser.add_argument("--no-exact", action="store_true", help="skip the exact-model truths")
    parser.add_argument("--geo-duration", type=float, default=2400.0, help="GEO arc, s")
    parser.add_argument("--leo-min-pass", type=float, default=300.0, help="shortest pass, s")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2, help="processes (1: in-process)")
    parser.add_argument("--out", help="also write the JSON report here")
    args = parser.parse_args(argv)
    options: dict[str, dict[str, Any]] = {}
    for target, key, value in args.option:
        options.setdefault(target, {})[key] = value
    settings = Settings(
        seed=args.seed,
        methods=args.methods,
        scenarios=args.scenarios,
        runs={
            "ukf": args.runs,
            "mmae": args.runs,
            "pf": args.pf_runs if args.pf_runs is not None else min(args.runs, 20),
        },
        shapes=args.shapes,
        bank=args.bank,
        pf_shapes=args.pf_shapes,
        exact=not args.no_exact,
        options=options,
        geo_duration_s=args.geo_duration,
        leo_min_pass_s=args.leo_min_pass,
    )
    try:
        check(settings)
    except ValueError as exc:
        parser.error(str(exc))
    return settings, args


def check(settings: Settings) -> None:
    """Refuse unknown methods, scenarios or shapes, a bank without the parents or with
    fewer than five shapes, and options ``invert`` would refuse (before any run)."""
    unknown = set(settings.methods) - set(METHODS)
    if unknown or not settings.methods:
        raise ValueError(f"methods must be among {', '.join(METHODS)}, got {settings.methods}")
    if set(settings.scenarios) - set(SCENARIOS) or not settings.scenarios:
        raise ValueError(f"scenarios must be among {', '.join(SCENARIOS)}")
    names = set(get_library().names())
    missing = (set(settings.shapes) | set(settings.bank)) - names
    if missing:
        raise ValueError(f"no shape(s) {', '.join(sorted(missing))} in the library")
    if set(settings.shapes) - set(settings.bank):
        raise ValueError("every parent (--shapes) must be in the bank (--bank)")
    if "mmae" in settings.methods and len(settings.bank) < 5:
        raise ValueError("the MMAE bank needs at least five shapes")
    if not 1 <= settings.pf_shapes <= len(settings.bank):
        raise ValueError("--pf-shapes must be between 1 and the bank's size")
    if min(settings.runs[m] for m in settings.methods) < 1:
        raise ValueError("run counts must be positive")
    for method in settings.methods:
        n_shapes = {"ukf": 1, "mmae": len(settings.bank), "pf": settings.pf_shapes}[method]
        validate_request(method, n_shapes=n_shapes, **settings.options_for(method))


def _single_threaded() -> None:
    """Pool initializer: one BLAS and one torch thread per process (two processes share
    the two cores)."""
    from threadpoolctl import threadpool_limits

    global _LIMITS
    _LIMITS = threadpool_limits(1)
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)


_LIMITS: Any = None


def run(settings: Settings, workers: int = 2) -> list[dict[str, Any]]:
    """Every case of every scenario (in order of scenario and run)."""
    jobs = [(s, i) for s in settings.scenarios for i in range(settings.cases())]
    done: dict[tuple[str, int], dict[str, Any]] = {}

    def report(job: tuple[str, int], case: dict[str, Any]) -> None:
        done[job] = case
        errors = [f"{r['method']}/{r['truth']}: {r['error']}" for r in case["runs"] if "error" in r]
        times = ", ".join(
            f"{r['method']}/{r['truth']} {r['wall_s']:.0f} s" for r in case["runs"] if "wall_s" in r
        )
        print(
            f"mismatch: {len(done)}/{len(jobs)} {job[0]} run {job[1]} ({case['case']['parent']})"
            f": {times}" + (f"; errors: {errors}" if errors else ""),
            file=sys.stderr,
            flush=True,
        )

    if workers <= 1:
        for job in jobs:
            report(job, run_case(settings, *job))
    else:
        with ProcessPoolExecutor(max_workers=workers, initializer=_single_threaded) as pool:
            futures = {pool.submit(run_case, settings, *job): job for job in jobs}
            for future in as_completed(futures):
                report(futures[future], future.result())
    return [done[job] for job in jobs]


def main(argv: list[str] | None = None) -> None:
    settings, args = parse_args(argv)
    start = time.perf_counter()
    cases = run(settings, args.workers)
    records = [r for case in cases for r in case["runs"]]
    report = {
        "benchmark": "mismatch",
        "command": "python -m benchmarks.mismatch "
        + " ".join(sys.argv[1:] if argv is None else argv),
        "seed": settings.seed,
        "runs": {m: settings.runs[m] for m in settings.methods},
        "settings": asdict(settings),
        "machine": machine_info(),
        "workers": args.workers,
        "wall_s": time.perf_counter() - start,
        "summary": summarise(records),
        "cases": cases,
    }
    emit_report(json_ready(report), args.out)


if __name__ == "__main__":
    main()
