"""Adapters for real data sets shipped in ``data/`` (each module documents its source).

Modules
-------
- :mod:`~lightcurve.datasets.starlink` — Starlink v1.5 brightness observations (Pomenis, Mount
  Lemmon) and the two-surface model.
"""
