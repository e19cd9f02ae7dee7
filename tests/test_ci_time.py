"""The suite's CPU-time log: numba's compilations per test and their summary."""

import json
from types import SimpleNamespace

from benchmarks.ci_time import _NumbaCompiles, read_log, summary


def _event(function, args=("float64",)):
    return SimpleNamespace(data={"dispatcher": SimpleNamespace(py_func=function), "args": args})


def outer():
    """Stands for a kernel."""


def inner():
    """Stands for a jitted function the kernel calls."""


def test_nested_compilations_count_once_for_the_outermost_kernel():
    compiles = _NumbaCompiles()
    compiles.on_start(_event(outer))
    compiles.on_start(_event(inner))
    compiles.on_end(_event(inner))
    compiles.on_end(_event(outer, ("float32", "int64")))
    (record,) = compiles.drain()
    assert record["kernel"].endswith(".outer")
    assert record["inner"] == [f"{inner.__module__}.inner"]
    assert record["signature"] == "float32, int64" and record["cpu_s"] >= 0.0
    assert compiles.drain() == []


def test_summary_flags_a_signature_compiled_by_two_workers(tmp_path):
    def record(nodeid, worker, *compiles):
        return {
            "nodeid": nodeid,
            "worker": worker,
            "wall_s": 1.0,
            "cpu_s": 1.0,
            "children_cpu_s": 0.0,
            "numba_compiles": [
                {"kernel": k, "signature": s, "cpu_s": t, "inner": []} for k, s, t in compiles
            ],
        }

    log = tmp_path / "log.jsonl"
    lines = [
        record("a", "gw0", ("m.twice", "f8", 2.0), ("m.two_signatures", "f4", 1.0)),
        record("b", "gw1", ("m.twice", "f8", 3.0), ("m.two_signatures", "f8", 1.5)),
        record("c", "gw0", ("m.two_signatures", "f8", 0.5)),
        record("d", "gw1", ("m.per_dtype", "f4", 1.0)),
        record("e", "gw0", ("m.per_dtype", "f8", 1.0)),
    ]
    log.write_text("".join(json.dumps(line) + "\n" for line in lines))
    numba = summary(read_log(log), top=2)["numba"]
    assert numba["compiles"] == 7 and numba["cpu_s"] == 10.0
    assert numba["kernels"]["m.twice"] == {"compiles": 2, "cpu_s": 5.0}
    # m.two_signatures: f8 by gw0 and gw1; m.per_dtype: each signature by one worker only
    assert numba["compiled_by_several_workers"] == {"m.twice": 5.0, "m.two_signatures": 3.0}
