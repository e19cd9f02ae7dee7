"""Batch runner: bad inputs recorded, resumability, parallel workers, Dask."""

import json
import sys
from pathlib import Path

import pandas as pd
import pytest

from lightcurve.batch import collect_inputs, run_batch

sys.path.insert(0, str(Path(__file__).parent))
from batch_jobs import count_rows, count_rows_reporting

ROW = "2024-01-01T00:00:{s:02d}Z,{mag},0.05,1.4e8,2.0e7,1.0e6,3.0e4,1.0e4,5.0e3"
HEADER = "epoch,mag,mag_err,sun_x,sun_y,sun_z,obs_x,obs_y,obs_z\n"


def make_inputs(folder: Path, n: int = 6) -> list[Path]:
    folder.mkdir()
    paths = []
    for i in range(n):
        path = folder / f"obj{i:02d}.csv"
        path.write_text(HEADER + "\n".join(ROW.format(s=s, mag=10 + i) for s in range(5)) + "\n")
        paths.append(path)
    paths[1].write_text(HEADER + ROW.format(s=0, mag=10) + "\n2024-01-01T00:00:01Z,10\n")
    paths[2].write_text(HEADER + ROW.format(s=0, mag="nan") + "\n")
    return paths


def test_bad_inputs_are_recorded_and_batch_continues(tmp_path):
    make_inputs(tmp_path / "in")
    table = run_batch(count_rows, [tmp_path / "in"], tmp_path / "out", progress=False)
    assert list(table["status"]) == ["ok", "error", "error", "ok", "ok", "ok"]
    assert "truncated" in table["error"][1] and "row 2" in table["error"][1]
    assert "value is NaN" in table["error"][2]
    summary = json.loads((tmp_path / "out" / "obj00" / "summary.json").read_text())
    assert summary["n_measurements"] == 5 and summary["values"] == [1.0, None]
    assert pd.read_csv(tmp_path / "out" / "summary.csv").shape[0] == 6


def test_resume_skips_finished_and_overwrite_redoes(tmp_path):
    make_inputs(tmp_path / "in")
    run_batch(count_rows, [tmp_path / "in"], tmp_path / "out", progress=False)
    first = (tmp_path / "out" / "obj03" / "summary.json").stat().st_mtime_ns
    stale = tmp_path / "out" / "obj04" / ".estimates.parquet.abc.parquet.tmp"
    stale.write_text("partial")
    (tmp_path / "out" / "obj05" / "summary.json").unlink()  # as if killed before the summary
    table = run_batch(count_rows, [tmp_path / "in"], tmp_path / "out", progress=False)
    assert (tmp_path / "out" / "obj03" / "summary.json").stat().st_mtime_ns == first
    assert not stale.exists()
    assert (tmp_path / "out" / "obj05" / "summary.json").exists()
    assert list(table["status"]).count("ok") == 4
    run_batch(count_rows, [tmp_path / "in"], tmp_path / "out", progress=False, overwrite=True)
    assert (tmp_path / "out" / "obj03" / "summary.json").stat().st_mtime_ns > first


def test_parallel_workers_give_the_same_summaries(tmp_path):
    make_inputs(tmp_path / "in")
    serial = run_batch(count_rows, [tmp_path / "in"], tmp_path / "a", progress=False)
    parallel = run_batch(count_rows, [tmp_path / "in"], tmp_path / "b", progress=False, workers=2)
    columns = ["input", "status", "error", "n_measurements"]
    pd.testing.assert_frame_equal(serial[columns], parallel[columns])


@pytest.mark.parametrize("workers", [1, 2])
def test_every_running_file_gets_a_progress_bar(tmp_path, capsys, workers):
    paths = make_inputs(tmp_path / "in", n=3)
    table = run_batch(
        count_rows_reporting,
        [tmp_path / "in"],
        tmp_path / "out",
        workers=workers,
        progress=True,
        job_progress=True,
    )
    err = capsys.readouterr().err
    assert list(table["status"]) == ["ok", "error", "error"]
    for path in paths:  # failed inputs report before failing, so every file has its bar
        assert f"{path.stem}:  50%" in err
    assert "rows read" in err


def test_input_collection_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such file or folder"):
        collect_inputs([tmp_path / "missing"])
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    (tmp_path / "a" / "x.csv").write_text("")
    (tmp_path / "b" / "x.csv").write_text("")
    with pytest.raises(ValueError, match="share the stem 'x'"):
        collect_inputs([tmp_path / "a", tmp_path / "b"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="no input files"):
        collect_inputs([tmp_path / "empty"])
