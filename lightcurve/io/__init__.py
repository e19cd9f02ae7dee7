"""Observation files and tables: their format, validation, reading and atomic writing.

The lowest floor of :mod:`lightcurve`: every other room reads and writes observations through
it, and it imports no other room. ``from lightcurve import io; io.read(path)`` reads any
supported file; the names of :mod:`~lightcurve.io.observation_files` are handed on from here on
first use (PEP 562), so that importing a light module of this package (the rules, the DAMIT
parser) does not import pandas.

Modules
-------
- :mod:`~lightcurve.io.observation_files` — one registry of file formats: :func:`read`,
  :func:`write`, :func:`read_csv`, :func:`read_parquet`, :func:`read_damit`, :func:`sniff_format`.
- :mod:`~lightcurve.io.observations` — :class:`~lightcurve.io.observations.Observations`, the
  in-memory form of an observation file, and its validation.
- :mod:`~lightcurve.io.observation_rules` — what every observation table must satisfy
  (ranges, shadow states, errors), importable without pandas.
- :mod:`~lightcurve.io.tables` — photometry tables as observers keep them, cell by cell.
- :mod:`~lightcurve.io.damit` — DAMIT light-curve text files.
- :mod:`~lightcurve.io.atomic` — atomic result files: text, JSON and tables.
- :mod:`~lightcurve.io.scenario_files` — typed TOML scenario files with errors naming the
  file, table and field.
"""

from __future__ import annotations

import importlib
from typing import Any

#: Names handed on from :mod:`lightcurve.io.observation_files`.
_FORMAT_NAMES = (
    "AU_KM",
    "formats",
    "read",
    "read_csv",
    "read_damit",
    "read_parquet",
    "sniff_format",
    "write",
)

__all__ = list(_FORMAT_NAMES)


def __getattr__(name: str) -> Any:
    """Import :mod:`lightcurve.io.observation_files` on first access of its names (PEP 562)."""
    if name not in _FORMAT_NAMES:
        raise AttributeError(f"module 'lightcurve.io' has no attribute {name!r}")
    value = getattr(importlib.import_module("lightcurve.io.observation_files"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
