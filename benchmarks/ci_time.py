"""Where the test suite's time goes: per-test CPU time, recorded by a pytest plugin.

Wall-clock durations (``pytest --durations``) on a shared machine measure the load as much as
the tests; the CPU time a test costs does not depend on how many other processes share the
cores. Loaded as a plugin, this module appends one JSON line per test to the file named by
``CI_TIME_LOG``: its node id, the xdist worker, the wall time and the CPU time of the test
process and of the child processes it waited for (subprocesses, notebook kernels; the
set-up of fixtures counts with the first test that uses them, numba's compilation with the
first test that calls a kernel). Each record also lists the numba kernels the test process
compiled (``numba_compiles``: the compiled function, its signature and the CPU seconds of the
compilation; kernels loaded from numba's on-disk cache are not compiled and not listed)::

    CI_TIME_LOG=/tmp/tests.jsonl python -m pytest -n 2 --dist worksteal -p benchmarks.ci_time

Run as a script, it summarises one or two such logs (a baseline and a new run) as JSON: the
test count, summed CPU and wall time, per-worker totals, the slowest tests, numba's
compilations (per kernel, and those compiled by more than one worker) and, for two logs, the
per-test ratios on the tests both ran::

    python -m benchmarks.ci_time /tmp/after.jsonl --baseline /tmp/before.jsonl --top 20
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import time
from collections import defaultdict
from collections.abc import Iterator
from pathlib import Path

import pytest

from benchmarks._machine import machine_info

LOG_VARIABLE = "CI_TIME_LOG"


class _NumbaCompiles:
    """Numba's ``numba:compile`` events of this process (cache misses only), outermost ones.

    A kernel that calls other jitted functions compiles them inside its own compilation; the
    time is counted once, for the outermost kernel, and the inner ones are named with it.
    """

    def __init__(self) -> None:
        self.done: list[dict] = []
        self._open: list[tuple[str, float, list[str]]] = []

    def on_start(self, event) -> None:
        function = event.data["dispatcher"].py_func
        name = f"{function.__module__}.{function.__qualname__}"
        if self._open:
            self._open[-1][2].append(name)
        self._open.append((name, time.process_time(), []))

    def on_end(self, event) -> None:
        name, start, inner = self._open.pop()
        if not self._open:
            signature = ", ".join(map(str, event.data["args"]))
            self.done.append(
                {
                    "kernel": name,
                    "signature": signature,
                    "cpu_s": round(time.process_time() - start, 3),
                    "inner": inner,
                }
            )

    def drain(self) -> list[dict]:
        done, self.done = self.done, []
        return done


_numba_compiles = _NumbaCompiles()


def pytest_configure(config: pytest.Config) -> None:
    """With a log to write, listen to numba's compilations (when numba is installed)."""
    if not os.environ.get(LOG_VARIABLE):
        return
    try:
        from numba.core import event
    except ImportError:
        return

    class Listener(event.Listener):
        on_start = staticmethod(_numba_compiles.on_start)
        on_end = staticmethod(_numba_compiles.on_end)

    event.register("numba:compile", Listener())


def _cpu_seconds() -> tuple[float, float]:
    """User + system CPU time (s) of this process and of its waited-for children."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime, children.ru_utime + children.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    """Time one test (set-up, call and tear-down) and append its record to the log."""
    log = os.environ.get(LOG_VARIABLE)
    own, children = _cpu_seconds()
    start = time.perf_counter()
    yield
    if not log:
        return
    own_after, children_after = _cpu_seconds()
    record = {
        "nodeid": item.nodeid,
        "worker": os.environ.get("PYTEST_XDIST_WORKER", "main"),
        "wall_s": time.perf_counter() - start,
        "cpu_s": own_after - own,
        "children_cpu_s": children_after - children,
        "numba_compiles": _numba_compiles.drain(),
    }
    with open(log, "a") as stream:  # one short line per write: whole lines from every worker
        stream.write(json.dumps(record) + "\n")


def read_log(path: Path) -> dict[str, dict]:
    """Records of a log by node id (a test recorded twice keeps its last record)."""
    records = {}
    for number, line in enumerate(path.read_text().splitlines(), start=1):
        try:
            record = json.loads(line)
        except json.JSONDecodeError as exc:
            raise ValueError(f"{path}, line {number}: not a JSON record ({exc})") from exc
        records[record["nodeid"]] = record
    return records


def total_cpu(record: dict) -> float:
    """CPU seconds of a test: its own process plus the children it waited for."""
    return record["cpu_s"] + record["children_cpu_s"]


def summary(records: dict[str, dict], top: int) -> dict[str, object]:
    """Counts, summed CPU and wall time, per-worker totals and the ``top`` slowest tests."""
    workers: dict[str, dict[str, float]] = defaultdict(lambda: {"tests": 0, "cpu_s": 0.0})
    for record in records.values():
        workers[record["worker"]]["tests"] += 1
        workers[record["worker"]]["cpu_s"] += total_cpu(record)
    slowest = sorted(records.values(), key=total_cpu, reverse=True)[:top]
    kernels: dict[str, dict] = {}
    for record in records.values():
        for compiled in record.get("numba_compiles", []):
            entry = kernels.setdefault(compiled["kernel"], {"cpu_s": 0.0, "compiles": []})
            entry["cpu_s"] += compiled["cpu_s"]
            entry["compiles"].append((record["worker"], compiled["signature"]))
    twice = {
        name: round(entry["cpu_s"], 2)
        for name, entry in kernels.items()
        if any(
            len({w for w, s in entry["compiles"] if s == signature}) > 1
            for _, signature in entry["compiles"]
        )
    }
    return {
        "tests": len(records),
        "cpu_s": sum(map(total_cpu, records.values())),
        "wall_s": sum(r["wall_s"] for r in records.values()),
        "workers": dict(workers),
        "slowest": [
            {"test": r["nodeid"], "cpu_s": round(total_cpu(r), 2), "wall_s": round(r["wall_s"], 2)}
            for r in slowest
        ],
        "numba": {
            "compiles": sum(len(e["compiles"]) for e in kernels.values()),
            "cpu_s": round(sum(e["cpu_s"] for e in kernels.values()), 2),
            "kernels": {
                name: {"compiles": len(e["compiles"]), "cpu_s": round(e["cpu_s"], 2)}
                for name, e in sorted(kernels.items(), key=lambda kv: -kv[1]["cpu_s"])
            },
            "compiled_by_several_workers": twice,
        },
    }


def compare(records: dict[str, dict], baseline: dict[str, dict], top: int) -> dict[str, object]:
    """CPU time of the tests both runs ran, new over baseline, and the largest changes."""
    common = sorted(records.keys() & baseline.keys())
    new = sum(total_cpu(records[k]) for k in common)
    old = sum(total_cpu(baseline[k]) for k in common)
    changes = sorted(
        common, key=lambda k: abs(total_cpu(records[k]) - total_cpu(baseline[k])), reverse=True
    )
    return {
        "common_tests": len(common),
        "cpu_s": new,
        "baseline_cpu_s": old,
        "ratio": new / old if old else None,
        "only_in_baseline": sorted(baseline.keys() - records.keys()),
        "only_in_new": sorted(records.keys() - baseline.keys()),
        "largest_changes": [
            {
                "test": k,
                "cpu_s": round(total_cpu(records[k]), 2),
                "baseline_cpu_s": round(total_cpu(baseline[k]), 2),
            }
            for k in changes[:top]
        ],
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("log", type=Path, help="JSON-lines log written with the plugin")
    parser.add_argument("--baseline", type=Path, help="log of the baseline run to compare with")
    parser.add_argument("--top", type=int, default=20, help="slowest tests listed (default 20)")
    args = parser.parse_args(argv)
    records = read_log(args.log)
    report: dict[str, object] = {"run": summary(records, args.top)}
    if args.baseline:
        baseline = read_log(args.baseline)
        report["baseline"] = summary(baseline, args.top)
        report["comparison"] = compare(records, baseline, args.top)
    report["machine"] = machine_info()
    report["load_average"] = os.getloadavg()
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
