"""Commands under load: CPU and wall time of user commands quiet and beside CPU-bound processes.

A command that spreads its work over threads is fair on a shared machine only if its threads
sleep while they wait: busy-waiting threads (OpenMP's default spin) burn CPU whenever another
process holds a core, so the same job costs several times its quiet CPU time. This benchmark
runs each command twice in one run, first alone and then beside ``--load`` busy-loop processes
that it starts itself, and reports the CPU time (user + system of the command's process tree,
from ``wait4``) and the wall time of both with their ratios.

    python -m benchmarks.load [--load 2] [--repeats 1] [--commands tour-ukf,...] [--out FILE]

The machine's own load (``os.getloadavg``) is printed before each phase: on a shared machine
the "quiet" phase is only as quiet as the other tenants allow.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks._machine import machine_info
from benchmarks._report import emit_report

ROOT = Path(__file__).resolve().parents[1]


#: Each command: the argument lists that prepare its inputs (``setup``, untimed) and the timed
#: one. ``{tmp}`` is the command's scratch folder, ``{out}`` a fresh folder per timed run (a
#: batch inversion resumes from outputs already written, so each run must start empty).
def _argv(command: str) -> list[str]:
    """A command line (after ``lightcurve``) as its argument list."""
    return shlex.split(command)


#: The README tour's geometry and simulation (``{where}``: ``{tmp}`` or ``{out}``).
_GEOMETRY = "geometry --start 2024-03-10T04:48:00 --duration 1200 --geo -100 --out {tmp}/geo.csv"
_SIMULATE = (
    "simulate {tmp}/geo.csv --shape box_wing --q0 0,0,0,1 --omega0 0.5,1,-0.3 "
    "--noise-mag 0.05 --seed 1 --out {where}/sim.csv"
)
_MAIN_JOB_SHAPES = "box_wing,rocket_body,box,cylinder,plate,cube"

COMMANDS: dict[str, dict[str, list[list[str]]]] = {
    "simulate": {
        "setup": [_argv(_GEOMETRY)],
        "timed": _argv(_SIMULATE.replace("{where}", "{out}")),
    },
    "tour-ukf": {
        "setup": [_argv(_GEOMETRY), _argv(_SIMULATE.replace("{where}", "{tmp}"))],
        "timed": _argv("invert {tmp}/sim.csv --shape box_wing --method ukf --out {out}/inv"),
    },
    "main-job-file": {
        "setup": [],
        "timed": _argv(
            "invert data/observations/box_tumbling_ccd.csv --shapes "
            f"{_MAIN_JOB_SHAPES} --method mmae --out {{out}}/mmae"
        ),
    },
    "convex": {
        "setup": [],
        "timed": _argv(
            "convex data/observations/real/ariadne.csv --pole 220,0 --period 5.76198 "
            "--out {out}/ariadne"
        ),
    },
}


def _spin() -> None:
    """A CPU-bound process: the load beside the measured command."""
    while True:
        pass


def _run(argv: list[str], extra: list[str], tmp: str) -> dict[str, float]:
    """Run ``lightcurve`` with ``argv`` and return its wall and CPU seconds (process tree)."""
    out = tempfile.mkdtemp(dir=tmp)
    args = [sys.executable, "-m", "lightcurve", *extra, *(a.format(tmp=tmp, out=out) for a in argv)]
    start = time.perf_counter()
    process = subprocess.Popen(args, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(process.pid, 0)
    wall = time.perf_counter() - start
    stderr = process.stderr.read().decode()
    process.stderr.close()
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{shlex.join(args)} failed:\n{stderr}")
    return {"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime}


def _measure(name: str, extra: list[str], repeats: int, warmup: bool) -> dict[str, float]:
    """Best-of-``repeats`` wall and CPU time of command ``name`` (inputs prepared untimed;
    with ``warmup`` one untimed run first, so on-disk compile caches are filled)."""
    spec = COMMANDS[name]
    with tempfile.TemporaryDirectory() as tmp:
        for argv in spec["setup"]:
            _run(argv, extra, tmp)
        if warmup:
            _run(spec["timed"], extra, tmp)
        runs = [_run(spec["timed"], extra, tmp) for _ in range(repeats)]
    return {key: min(run[key] for run in runs) for key in ("wall_s", "cpu_s")}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--load", type=int, default=2, help="busy-loop processes beside it")
    parser.add_argument("--repeats", type=int, default=1, help="runs per phase (best taken)")
    parser.add_argument(
        "--commands", default=",".join(COMMANDS), help="comma-separated: " + ", ".join(COMMANDS)
    )
    parser.add_argument(
        "--threads", type=int, help="pass --threads N to every command (default: its own)"
    )
    parser.add_argument("--out", type=Path, help="also write the JSON here")
    args = parser.parse_args(argv)
    names = [name.strip() for name in args.commands.split(",") if name.strip()]
    unknown = sorted(set(names) - set(COMMANDS))
    if unknown:
        parser.error(f"unknown commands {unknown}; choose from {sorted(COMMANDS)}")
    extra = [] if args.threads is None else ["--threads", str(args.threads)]

    results = {}
    for name in names:
        quiet_load = os.getloadavg()[0]
        quiet = _measure(name, extra, args.repeats, warmup=True)
        spinners = [multiprocessing.Process(target=_spin, daemon=True) for _ in range(args.load)]
        for process in spinners:
            process.start()
        try:
            time.sleep(1.0)
            loaded_load = os.getloadavg()[0]
            loaded = _measure(name, extra, args.repeats, warmup=False)
        finally:
            for process in spinners:
                process.terminate()
                process.join()
        results[name] = {
            "quiet": quiet,
            "loaded": loaded,
            "cpu_ratio": loaded["cpu_s"] / quiet["cpu_s"],
            "wall_ratio": loaded["wall_s"] / quiet["wall_s"],
            "load_average_quiet": quiet_load,
            "load_average_loaded": loaded_load,
        }
    report = {
        "benchmark": "commands under load",
        "load_processes": args.load,
        "threads_option": args.threads,
        "machine": machine_info(),
        "results": results,
    }
    emit_report(report, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
