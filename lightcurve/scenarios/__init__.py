"""Scenario files and studies of the close-range navigation problems.

``lightcurve.scenarios`` reads the TOML scenario files of ``data/scenarios/`` with errors
that name the file and the field (:mod:`~lightcurve.scenarios.toml`), and runs the studies
behind the ``monocular`` (Deng et al. 2024), ``plan`` (Li et al. 2024), ``stereo`` (Feng et al.) and
``relnav`` (Shi et al.) commands; the estimators themselves live in :mod:`filters`.
"""

from lightcurve.scenarios.toml import ScenarioError, TomlTable, load_toml

__all__ = ["ScenarioError", "TomlTable", "load_toml"]
