"""Typed reading of TOML scenario files with errors that name the file, table and field.

A small stop-gap shared by the ``stereo`` and ``relnav`` commands until the generic
``lightcurve.scenarios`` helpers exist; every error is a :class:`ScenarioError`
(a ``ValueError``), printed by the CLI as one line.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["ScenarioError", "TomlTable", "load_toml"]

_MISSING = object()


class ScenarioError(ValueError):
    """A scenario file that cannot be used, with the file and field in the message."""


class TomlTable:
    """One table of a parsed TOML file; fields are read with a type and checked.

    Parameters
    ----------
    data : dict
        The parsed table.
    path : pathlib.Path
        The file, for messages.
    name : str
        Dotted table name (``""`` for the top level).
    """

    def __init__(self, data: dict[str, Any], path: Path, name: str = "") -> None:
        self.data = data
        self.path = path
        self.name = name
        self._read: set[str] = set()

    def _where(self, field: str) -> str:
        table = f"[{self.name}] " if self.name else ""
        return f"{self.path}: {table}{field}"

    def error(self, field: str, message: str) -> ScenarioError:
        """A :class:`ScenarioError` about ``field`` of this table."""
        return ScenarioError(f"{self._where(field)}: {message}")

    def _get(self, field: str, default: Any) -> Any:
        self._read.add(field)
        if field in self.data:
            return self.data[field]
        if default is _MISSING:
            raise self.error(field, "missing field")
        return default

    def table(self, field: str) -> TomlTable:
        """A sub-table (required)."""
        value = self._get(field, _MISSING)
        if not isinstance(value, dict):
            raise self.error(field, "must be a table")
        return TomlTable(value, self.path, f"{self.name}.{field}" if self.name else field)

    def has(self, field: str) -> bool:
        """Whether the field is present."""
        return field in self.data

    def number(
        self,
        field: str,
        default: Any = _MISSING,
        *,
        positive: bool = False,
        minimum: float | None = None,
    ) -> float:
        """A finite float; ``positive`` requires > 0, ``minimum`` requires ≥ minimum."""
        value = self._get(field, default)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.error(field, f"must be a number, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise self.error(field, "must be finite")
        if positive and value <= 0:
            raise self.error(field, f"must be positive, got {value}")
        if minimum is not None and value < minimum:
            raise self.error(field, f"must be >= {minimum}, got {value}")
        return value

    def integer(self, field: str, default: Any = _MISSING, *, minimum: int | None = None) -> int:
        """An integer, optionally ≥ ``minimum``."""
        value = self._get(field, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(field, f"must be an integer, got {value!r}")
        if minimum is not None and value < minimum:
            raise self.error(field, f"must be >= {minimum}, got {value}")
        return value

    def boolean(self, field: str, default: Any = _MISSING) -> bool:
        """A true/false value."""
        value = self._get(field, default)
        if not isinstance(value, bool):
            raise self.error(field, f"must be true or false, got {value!r}")
        return value

    def string(self, field: str, default: Any = _MISSING, *, choices: Any = None) -> str:
        """A string, optionally one of ``choices``."""
        value = self._get(field, default)
        if not isinstance(value, str):
            raise self.error(field, f"must be a string, got {value!r}")
        if choices is not None and value not in choices:
            raise self.error(field, f"must be one of {sorted(choices)}, got {value!r}")
        return value

    def array(
        self, field: str, shape: tuple[int | None, ...], default: Any = _MISSING
    ) -> np.ndarray:
        """A numeric array of the given shape (``None`` for any length)."""
        value = self._get(field, default)
        try:
            array = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise self.error(field, f"must be an array of numbers, got {value!r}") from None
        ok = array.ndim == len(shape) and all(
            want is None or want == got for want, got in zip(shape, array.shape, strict=False)
        )
        if not ok:
            wanted = " x ".join("N" if s is None else str(s) for s in shape)
            raise self.error(field, f"must be a {wanted} array, got shape {array.shape}")
        if not np.all(np.isfinite(array)):
            raise self.error(field, "must contain finite numbers only")
        return array

    def check_unknown(self) -> None:
        """Reject fields that were never read (typos are errors, not silently ignored)."""
        unknown = sorted(set(self.data) - self._read)
        if unknown:
            raise self.error(unknown[0], "unknown field (check its spelling in the docs)")


def load_toml(path: str | Path) -> TomlTable:
    """Parse a TOML file into its top-level :class:`TomlTable`.

    Raises
    ------
    OSError
        When the file cannot be read.
    ScenarioError
        When it is not valid TOML (with the parser's line and column).
    """
    path = Path(path)
    try:
        with path.open("rb") as handle:
            data = tomllib.load(handle)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: not valid TOML: {exc}") from None
    return TomlTable(data, path)
