"""Observation files written and read back in both formats."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from lightcurve import io
from lightcurve.io.observations import Observations


def assert_csv_parquet_round_trip(observations: Observations, folder: Path) -> Observations:
    """Write ``observations`` to CSV, read it, write that to Parquet and read it again.

    Asserts that both files read back the table of ``observations`` exactly and the last one
    its metadata.

    Returns
    -------
    Observations
        What the Parquet file read back.
    """
    io.write(observations, folder / "round_trip.csv")
    back = io.read(folder / "round_trip.csv")
    io.write(back, folder / "round_trip.parquet")
    again = io.read(folder / "round_trip.parquet")
    pd.testing.assert_frame_equal(back.table, observations.table)
    pd.testing.assert_frame_equal(again.table, observations.table)
    assert again.meta == observations.meta
    return again
