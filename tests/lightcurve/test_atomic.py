"""Atomic writers leave either the old or the complete new file."""

import pandas as pd
import pytest

from lightcurve.atomic import atomic_path, atomic_write_json, atomic_write_table


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
