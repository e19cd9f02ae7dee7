"""Is a tumbling object's attitude determined by one light curve of unknown shape?

On the ``geo_joint`` arcs of :mod:`benchmarks.shape_recovery` (the benchmark's own draws: a
40-minute geostationary arc at 2 s of a convex object tumbling torque-free, noise 0.02–0.05
mag, the material given), the profile χ² — the χ² of the best non-negative EGI for a given
torque-free trajectory (:func:`lightcurve.analysis.egi.fit.fit_egi`, ``--normals`` normals,
every epoch) — of

* ``truth``: the true trajectory, and ``truth_refined``: it refined by the search's fine
  descent (the grid's own bias removed);
* ``found``: the distinct minima of the multi-start search
  (:func:`lightcurve.analysis.egi.search.search_states`; random states, no use of the truth).

For each: ``chi2_per_epoch``, ``delta_chi2`` from the lowest of all (in units of the lowest's
reduced χ², at least 1), the attitude error at the last epoch after the benchmark's
alignment modulo the frame and the mirror (:func:`benchmarks.shape_recovery.mirror_aligned`)
and the held-out ratio (:func:`benchmarks.shape_recovery.score`: the held-out arc's rms
over the noise, predicted by the recovered mesh mapped into the true body frame).
``within_9``: how many distinct states lie within Δχ² = 9 of the lowest, and how many of
them are more than 5° off.

The baseline measured in the same run is the truth's own χ² (what the search must reach).

    python -m benchmarks.joint_identifiability [--runs 4] [--seed 34]
        [--objects box_3x2x1,prism] [--starts 32] [--normals 1000] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

import numpy as np

from benchmarks._machine import machine_info
from benchmarks._report import emit_report
from benchmarks.shape_recovery import (
    NOISE_MAG,
    SCENARIOS,
    _true_material,
    mirror_aligned,
    objects,
    observe,
    score,
)
from lightcurve.analysis.egi import FitEpochs, fit_egi
from lightcurve.analysis.egi.epochs import truth_attitudes
from lightcurve.analysis.egi.joint import principal_start
from lightcurve.analysis.egi.search import (
    TorqueFreeState,
    distinct,
    refine_state,
    search_states,
)
from lightcurve.io.atomic import json_ready

#: Δχ² (in reduced χ² of the lowest) within which states are not told apart.
TIE = 9.0
#: Attitude error (deg) beyond which a state is a different answer.
OFF_DEG = 5.0


def geo_joint_case(name: str, run: int, seed: int) -> dict[str, Any]:
    """The ``geo_joint`` draw of :mod:`benchmarks.shape_recovery` for ``name`` and ``run``:
    the arc, the held-out arc, the noise and the true shape."""
    shapes = objects()
    k = SCENARIOS.index("geo_joint")
    rng = np.random.default_rng([seed, run, k, sorted(shapes).index(name)])
    noise_mag = float(rng.uniform(*NOISE_MAG))
    arc = observe(shapes[name], "geo_joint", rng, noise_mag)
    held_out = observe(shapes[name], "geo_joint", rng, noise_mag)
    return {"shape": shapes[name], "arc": arc, "held_out": held_out, "noise_mag": noise_mag}


def true_state(case: dict[str, Any]) -> TorqueFreeState:
    """The true first-epoch state in the principal frame of the true shape's inertia."""
    arc = case["arc"]
    q = truth_attitudes(arc)[0]
    w = arc.table[["wx", "wy", "wz"]].to_numpy(dtype=float)[0]
    return TorqueFreeState(*principal_start(case["shape"], q, w))


def describe(case: dict[str, Any], attitudes: np.ndarray, fit) -> dict[str, Any]:
    """Attitude error at the last epoch (modulo frame and mirror) and held-out figures."""
    arc = case["arc"]
    errors, turn, alignment = mirror_aligned(truth_attitudes(arc), [attitudes], [arc])
    scored = score(case["shape"], fit, case["held_out"], case["noise_mag"], turn)
    return {
        "chi2": fit.chi2,
        "chi2_per_epoch": fit.chi2 / len(arc),
        "attitude_error_deg": float(errors[-1]),
        "alignment": alignment,
        "heldout_ratio": scored["heldout_ratio"],
        "heldout_ratio_egi": scored["heldout_ratio_egi"],
    }


def study(name: str, run: int, args) -> dict[str, Any]:
    """Truth and search minima of one arc (module docstring)."""
    case = geo_joint_case(name, run, args.seed)
    arc, material = case["arc"], _true_material()
    seconds = (arc.mjd - arc.mjd[0]) * 86400.0
    truth = true_state(case)
    rows: list[tuple[str, np.ndarray, Any]] = []
    for label, state in (
        ("truth", truth),
        ("truth_refined", refine_state(arc, truth, material)[0]),
    ):
        q = state.attitudes(seconds)
        fit = fit_egi(FitEpochs.from_observations([arc], [q]), material, normals=args.normals)
        rows.append((label, q, fit))
    began, cpu = time.perf_counter(), time.process_time()
    minima = search_states(
        arc, material, seed=args.seed + run, starts=args.starts, normals=args.normals
    )
    search_s, search_cpu_s = time.perf_counter() - began, time.process_time() - cpu
    rows += [(f"found_{k}", m.attitudes, m.fit) for k, m in enumerate(minima)]
    lowest = min(fit.chi2 for _, _, fit in rows)
    free = int(np.count_nonzero(rows[0][2].areas))
    reduced = max(lowest / max(len(arc) - free, 1), 1.0)
    described = {label: describe(case, q, fit) for label, q, fit in rows}
    for row in described.values():
        row["delta_chi2"] = (row["chi2"] - lowest) / reduced
    order = sorted(described, key=lambda label: described[label]["chi2"])
    histories = {label: q for label, q, _ in rows}
    kept = [order[k] for k in distinct([histories[label] for label in order])]
    tied = [label for label in kept if described[label]["delta_chi2"] < TIE]
    return {
        "object": name,
        "run": run,
        "noise_mag": case["noise_mag"],
        "epochs": len(arc),
        "states": described,
        "search_s": search_s,
        "search_cpu_s": search_cpu_s,
        "within_9": len(tied),
        "within_9_off": sum(described[label]["attitude_error_deg"] > OFF_DEG for label in tied),
        "best_found_minus_truth": (
            min(described[k]["chi2"] for k in described if k.startswith("found"))
            - min(described["truth"]["chi2"], described["truth_refined"]["chi2"])
        )
        / reduced,
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=4, help="runs per object")
    parser.add_argument("--first-run", type=int, default=0)
    parser.add_argument("--seed", type=int, default=34)
    parser.add_argument("--objects", default="box_3x2x1,prism")
    parser.add_argument("--starts", type=int, default=32, help="screened states refined")
    parser.add_argument("--normals", type=int, default=1000)
    parser.add_argument("--out", default=None, help="also write the JSON here")
    args = parser.parse_args(argv)
    records = []
    for run in range(args.first_run, args.first_run + args.runs):
        for name in args.objects.split(","):
            records.append(study(name, run, args))
            print(json.dumps(json_ready(records[-1])), file=sys.stderr, flush=True)
    report = {
        "benchmark": "joint_identifiability",
        "machine": machine_info(),
        "seed": args.seed,
        "runs_per_object": args.runs,
        "starts": args.starts,
        "normals": args.normals,
        "records": records,
    }
    emit_report(json_ready(report), args.out)


if __name__ == "__main__":
    main()
