"""Material presets: named reflectance models with parameters and their sources.

The presets live in ``brdf/data/materials.toml``, package data read through
:mod:`importlib.resources` (so an installed wheel has them). Each table is one material::

    [white-paint]
    model = "lambert"
    params = { rd = 0.80 }
    source = "…literature reference or 'fitted to …'"

``load_presets()`` returns ``name → Preset(model, params, source)``; every entry is validated
with `brdf.get`, so a bad preset is reported with the file and the material name.
"""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path
from typing import Any, NamedTuple

from brdf.registry import BRDF, get

__all__ = ["PRESETS_PATH", "Preset", "load_presets"]

PRESETS_PATH = Path(str(resources.files("brdf").joinpath("data", "materials.toml")))


class Preset(NamedTuple):
    """A material preset: registry model name, parameters and the source of the values."""

    model: str
    params: dict[str, float]
    source: str

    def brdf(self) -> BRDF:
        """The preset as a validated `BRDF`."""
        return get(self.model, **self.params)


def load_presets(path: str | Path | None = None) -> dict[str, Preset]:
    """Read and validate the material presets.

    Parameters
    ----------
    path : str or Path, optional
        TOML file (default `PRESETS_PATH`).

    Returns
    -------
    dict
        Material name → `Preset`.

    Raises
    ------
    ValueError
        Invalid TOML, a missing ``model``/``params``/``source`` key, or parameters rejected by
        `brdf.get`; the message names the file and the material.
    OSError
        The file cannot be read.
    """
    path = Path(path) if path is not None else PRESETS_PATH
    try:
        document: dict[str, Any] = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as error:
        raise ValueError(f"{path}: {error}") from None
    presets = {}
    for name, entry in document.items():
        missing = [key for key in ("model", "params", "source") if key not in entry]
        if not isinstance(entry, dict) or missing:
            raise ValueError(f"{path}: material {name!r} needs keys model, params, source")
        try:
            model = get(entry["model"], **entry["params"])
        except ValueError as error:
            raise ValueError(f"{path}: material {name!r}: {error}") from None
        presets[name] = Preset(model.name, dict(model.params), str(entry["source"]))
    return presets
