"""Former home of the TOML scenario helpers, now :mod:`lightcurve.scenarios`.

Kept only as a re-export for ``lightcurve/commands/plan.py`` until it imports
:mod:`lightcurve.scenarios` directly; then this module should be deleted.
"""

from lightcurve.scenarios import ScenarioError, TomlTable, load_toml

__all__ = ["ScenarioError", "TomlTable", "load_toml"]
