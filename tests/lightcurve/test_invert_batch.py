"""Batch inversion end to end through ``lightcurve invert``.

Forty simulated inputs, one truncated, one with a NaN magnitude and one whose header names a
shape the library does not have: 37 "ok" summaries and 3 "error" records with clear
messages; a run killed with SIGKILL midway and rerun finishes with no partial files and no
repeated work; the same batch on a real ``dask.distributed.LocalCluster`` gives the same
summaries as that resumed local batch (floating-point fields to rounding). The filters start
at the simulation's initial state (``--init none``) so the 40 inversions take seconds; the
searches are tested in ``test_inversion.py``.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from lightcurve import io
from lightcurve.cli import main
from lightcurve.photometry.simulate import GaussianNoise, simulate
from lightcurve.sky.ephemeris import CircularOrbit, Site, orbit_geometry
from shapes import get_library

N_INPUTS = 40
N_EPOCHS = 30  # half a minute at 1 s: the residual check still sees the 0.05 mag noise
START_MJD = 60379.2  # 2024-03-10 04:48 UTC, night at Mount Lemmon
Q0 = np.array([0.2, -0.1, 0.3, 0.927]) / np.linalg.norm([0.2, -0.1, 0.3, 0.927])
OMEGA0_DEG_S = np.array([0.8, -0.5, 1.2])
BAD = {"obj05": "truncated", "obj17": "NaN", "obj29": "unknown shape"}
VOLATILE = ("runtime_s",)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("batch") / "in"
    folder.mkdir()
    mjd = START_MJD + np.arange(N_EPOCHS) / 86400.0
    site = Site(32.4434, -110.7881, 2790.0, "Mount Lemmon")
    geometry = orbit_geometry(CircularOrbit.geostationary(-100.0, START_MJD), site, mjd)
    shape = get_library().load("box")
    for i in range(N_INPUTS):
        result = simulate(
            geometry,
            shape,
            q0=Q0,
            omega0=np.deg2rad(OMEGA0_DEG_S),
            noise=GaussianNoise(0.05),
            seed=i,
        )
        io.write(result, folder / f"obj{i:02d}.csv")
    truncated = folder / "obj05.csv"
    text = truncated.read_text()
    truncated.write_text(text[: int(0.6 * len(text))])  # cut in the middle of a row
    lines = (folder / "obj17.csv").read_text().splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("epoch"))
    columns = lines[header].split(",")
    row = lines[header + 12].split(",")
    row[columns.index("mag")] = "nan"
    lines[header + 12] = ",".join(row)
    (folder / "obj17.csv").write_text("\n".join(lines) + "\n")
    unknown = folder / "obj29.csv"
    unknown.write_text(unknown.read_text().replace("# shape: box\n", "# shape: starship_v9\n"))
    return folder


def command(inputs: Path, out: Path, *extra: str) -> list[str]:
    return [
        "invert",
        str(inputs),
        "--method",
        "ukf",
        "--q0",
        ",".join(f"{v:.12f}" for v in Q0),
        "--omega0",
        ",".join(f"{v}" for v in OMEGA0_DEG_S),
        "--attitude-sigma-deg",
        "2",
        "--omega-sigma",
        "0.05",
        "--init",
        "none",
        "--no-progress",
        "--out",
        str(out),
        *extra,
    ]


def test_given_candidates_invert_a_file_whose_header_names_an_unknown_shape(inputs, tmp_path):
    """The header's shape only stands in for missing candidates: with ``--shape`` given, a
    file simulated from a shape the library lacks is inverted with that candidate."""
    out = tmp_path / "out"
    argv = command(inputs / "obj29.csv", out, "--shape", "box", "-q")
    assert main(argv) == 0
    record = json.loads((out / "obj29" / "summary.json").read_text())
    assert record["status"] == "ok" and record["shape"] == "box", record


def summaries(out: Path) -> dict[str, dict]:
    records = {}
    for path in sorted(out.glob("*/summary.json")):
        record = json.loads(path.read_text())
        records[path.parent.name] = {k: v for k, v in record.items() if k not in VOLATILE}
    return records


def same_record(a: object, b: object) -> bool:
    """Equal JSON records, floats to 1e-9 relative (1e-12 absolute) and the rest exactly.

    The local run computes in the test process with its own thread count, the Dask workers
    with one thread each; BLAS kernels and torch reductions do not promise the same last
    digits for different thread counts.
    """
    if isinstance(a, float) and isinstance(b, float):
        return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same_record(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same_record(x, y) for x, y in zip(a, b, strict=True))
    return type(a) is type(b) and a == b


def check_complete(out: Path) -> None:
    """37 ok, the 3 bad inputs as errors with clear messages, no temporary files left."""
    records = summaries(out)
    assert len(records) == N_INPUTS
    errors = {stem: r["error"] for stem, r in records.items() if r["status"] == "error"}
    assert set(errors) == set(BAD)
    assert "truncated" in errors["obj05"] and "obj05.csv" in errors["obj05"]
    assert "NaN" in errors["obj17"] and "row" in errors["obj17"]
    assert "starship_v9" in errors["obj29"] and "no shape" in errors["obj29"]
    for stem, record in records.items():
        if stem in BAD:
            continue
        assert record["status"] == "ok" and record["shape"] == "box"
        assert record["residual_rms_mag"] < 0.1  # the noise is 0.05 mag
        assert len(pd.read_parquet(out / stem / "estimates.parquet")) == record["n_measurements"]
    table = pd.read_csv(out / "summary.csv")
    assert len(table) == N_INPUTS and (table["status"] == "ok").sum() == N_INPUTS - len(BAD)
    assert not list(out.rglob("*.tmp"))


@pytest.fixture(scope="module")
def resumed(inputs, tmp_path_factory) -> tuple[Path, dict[str, int], dict[str, int]]:
    """A batch killed with SIGKILL after eight summaries, then rerun to the end.

    Returns the output folder and the summaries' modification times (ns) after the kill and
    after the rerun.
    """
    out = tmp_path_factory.mktemp("resumed") / "out"
    cli = [sys.executable, "-m", "lightcurve.cli", *command(inputs, out)]
    process = subprocess.Popen(cli, start_new_session=True, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 300
    while len(list(out.glob("*/summary.json"))) < 8:
        assert process.poll() is None, "the batch finished before it could be killed"
        assert time.monotonic() < deadline
        time.sleep(0.02)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    before = {p.parent.name: p.stat().st_mtime_ns for p in out.glob("*/summary.json")}
    assert 8 <= len(before) < N_INPUTS
    for path in out.glob("*/summary.json"):
        json.loads(path.read_text())  # every summary on disk is whole
    assert main(command(inputs, out)) == 1  # three inputs are bad
    after = {p.parent.name: p.stat().st_mtime_ns for p in out.glob("*/summary.json")}
    return out, before, after


def test_killed_batch_resumes_without_repeating_work(resumed):
    out, before, after = resumed
    check_complete(out)
    redone = {stem for stem in before if after[stem] != before[stem]}
    assert redone <= set(BAD)  # only error records are retried; finished work is not redone


def test_dask_cluster_gives_the_same_summaries(inputs, resumed, tmp_path):
    """The Dask batch equals the local one (the resumed batch: killed, then rerun here)."""
    from dask.distributed import LocalCluster

    local = resumed[0]
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        code = main(command(inputs, tmp_path / "dask", "--scheduler", cluster.scheduler_address))
    assert code == 1
    check_complete(tmp_path / "dask")
    local, dask = summaries(local), summaries(tmp_path / "dask")
    assert local.keys() == dask.keys()
    for stem in local:
        assert same_record(dask[stem], local[stem]), (stem, dask[stem], local[stem])
