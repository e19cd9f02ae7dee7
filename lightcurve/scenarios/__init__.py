"""Scenario files and studies of the close-range navigation problems.

``lightcurve.scenarios`` reads the TOML scenario files of ``data/scenarios/`` with errors
that name the file and the field (:mod:`~lightcurve.scenarios.toml`), and runs the studies
behind the ``monocular`` (seed 000), ``plan`` (seed 001), ``stereo`` (seed 004) and
``relnav`` (seed 003) commands; the estimators themselves live in :mod:`filters`.
"""

from lightcurve.scenarios.toml import ScenarioError, TomlTable, load_toml

__all__ = ["ScenarioError", "TomlTable", "load_toml"]
