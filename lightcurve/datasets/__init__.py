"""Adapters for real data sets shipped in ``data/`` (each module documents its source)."""
