"""Atomic writers leave either the old or the complete new file."""

import numpy as np
import pandas as pd
import pytest

from lightcurve.io.atomic import (
    atomic_path,
    atomic_write_csv,
    atomic_write_json,
    atomic_write_table,
)


def test_failed_write_keeps_old_content(tmp_path):
    target = tmp_path / "summary.json"
    atomic_write_json(target, {"status": "ok"})
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("partial")
        raise RuntimeError("killed")
    assert target.read_text().strip().startswith("{")
    assert [p.name for p in tmp_path.iterdir()] == ["summary.json"]


def test_table_formats(tmp_path):
    table = pd.DataFrame({"a": [1.0, 2.0]})
    atomic_write_table(table, tmp_path / "t.parquet")
    atomic_write_table(table, tmp_path / "t.csv")
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "t.parquet"), table)
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "t.csv"), table)
    with pytest.raises(ValueError, match="unknown table format"):
        atomic_write_table(table, tmp_path / "t.xlsx")
    with pytest.raises(ValueError, match="not JSON compliant"):
        atomic_write_json(tmp_path / "bad.json", {"x": float("nan")})


def test_csv_columns_written_as_pandas_writes_them(tmp_path):
    rng = np.random.default_rng(5)
    values = rng.normal(size=200) * 10.0 ** rng.integers(-30, 30, 200)
    values[:3] = [np.nan, np.inf, -0.0]
    columns = {"x": values, "n": np.arange(200), "flag": values > 0}
    atomic_write_csv(columns, tmp_path / "ours.csv")
    pd.DataFrame(columns).to_csv(tmp_path / "pandas.csv", index=False)
    assert (tmp_path / "ours.csv").read_text() == (tmp_path / "pandas.csv").read_text()
    with pytest.raises(ValueError, match="different lengths"):
        atomic_write_csv({"x": values, "n": np.arange(3)}, tmp_path / "bad.csv")
