"""Start-up cost of the command line: ``lightcurve --help`` and ``lightcurve <command> --help``.

Each case runs ``python -m lightcurve.cli … --help`` as a new process (output discarded);
wall and CPU seconds (user + system of the child) are the best of ``--repeat`` rounds, each
round running every case once, alternated with the same cases of a baseline source tree when
``--baseline DIR`` is given (a checkout or ``git archive`` of an earlier commit: it is put
first on ``PYTHONPATH``, so the same interpreter and packages run the older code). Prints
JSON with the figures, the ratios to the baseline and the machine.

    python -m benchmarks.startup [--baseline DIR] [--repeat 5] [--commands ,simulate,convex]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

from benchmarks._machine import machine_info

COMMANDS = ("", "convex", "simulate", "invert", "geometry", "import", "shapes")


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _run(argv: list[str], env: dict[str, str], cwd: Path) -> tuple[float, float]:
    """Wall and CPU seconds of one process."""
    cpu = _children_cpu()
    began = time.perf_counter()
    subprocess.run(argv, env=env, cwd=cwd, stdout=subprocess.DEVNULL, check=True)
    return time.perf_counter() - began, _children_cpu() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--baseline", type=Path, help="source tree of the baseline")
    parser.add_argument("--repeat", type=int, default=5, help="rounds (best of)")
    parser.add_argument(
        "--commands",
        default=",".join(COMMANDS),
        help="comma-separated commands whose --help is timed (an empty item: lightcurve --help)",
    )
    args = parser.parse_args()
    commands = [c.strip() for c in args.commands.split(",")]
    trees = {"current": Path(__file__).resolve().parents[1]}
    if args.baseline is not None:
        trees["baseline"] = args.baseline.resolve()
    rows: dict[str, dict[str, list[tuple[float, float]]]] = {}
    for _ in range(args.repeat):
        for command in commands:
            label = f"lightcurve {command} --help".replace("  ", " ")
            for tree, path in trees.items():
                env = dict(os.environ)
                if tree == "baseline":
                    env["PYTHONPATH"] = os.pathsep.join(
                        filter(None, [str(path), env.get("PYTHONPATH")])
                    )
                argv = [sys.executable, "-m", "lightcurve.cli", *([command] if command else [])]
                run = _run([*argv, "--help"], env, cwd=path)  # python -m: cwd first on sys.path
                rows.setdefault(label, {}).setdefault(tree, []).append(run)
    out: dict = {"machine": machine_info(), "load_average": os.getloadavg(), "cases": {}}
    for label, by_tree in rows.items():
        case = {}
        for tree, runs in by_tree.items():
            case[f"{tree}_seconds"] = min(r[0] for r in runs)
            case[f"{tree}_cpu_seconds"] = min(r[1] for r in runs)
        if "baseline" in by_tree:
            case["ratio_seconds"] = case["current_seconds"] / case["baseline_seconds"]
            case["ratio_cpu_seconds"] = case["current_cpu_seconds"] / case["baseline_cpu_seconds"]
        out["cases"][label] = case
    out["load_average_end"] = os.getloadavg()
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
