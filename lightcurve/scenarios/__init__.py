"""Scenario files of the close-range navigation studies.

``lightcurve.scenarios`` reads the TOML scenario files of ``data/scenarios/`` with errors
that name the file and the field (:mod:`~lightcurve.io.scenario_files`) into the scenario
definitions of :mod:`lightcurve.studies`: ``monocular`` (Deng et al. 2024), ``landing``
(``plan``, Li et al. 2024), ``stereo`` (Feng et al.) and ``relnav`` (Shi et al.). The studies
themselves live in :mod:`lightcurve.studies`, the estimators in :mod:`filters`.
"""

from lightcurve.io.scenario_files import ScenarioError, TomlTable, load_toml

__all__ = ["ScenarioError", "TomlTable", "load_toml"]
