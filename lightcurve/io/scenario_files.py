"""Scenario files: typed TOML reading with errors that name the file, table and field.

Every command that runs a study from a TOML scenario (``monocular``, ``plan``, ``stereo``,
``relnav``) reads it through :func:`load_toml` and :class:`TomlTable`: each field is read
with its type and range, unknown fields are rejected (a misspelt key is an error, not a
silently ignored setting), and every problem is a :class:`ScenarioError` (a ``ValueError``)
whose message starts with ``FILE: [table] field:``, which the CLI prints as one line.

Example
-------
>>> root = load_toml("data/scenarios/nutation.toml")  # doctest: +SKIP
>>> truth = root.table("truth")  # doctest: +SKIP
>>> omega = truth.array("omega0_deg_s", (3,))  # doctest: +SKIP
>>> truth.check_unknown()  # doctest: +SKIP
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Collection
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["ScenarioError", "TomlTable", "load_toml"]

_REQUIRED = object()


class ScenarioError(ValueError):
    """A scenario file that cannot be used; the message names the file and field."""


class TomlTable:
    """One table of a parsed TOML file whose fields are read with a type and checked.

    Parameters
    ----------
    data : dict
        The parsed table.
    path : pathlib.Path
        The file (for messages).
    name : str
        Dotted table name, ``""`` for the top level.
    """

    def __init__(self, data: dict[str, Any], path: Path, name: str = "") -> None:
        self.data = data
        self.path = Path(path)
        self.name = name
        self._read: set[str] = set()

    def error(self, field: str, message: str) -> ScenarioError:
        """A :class:`ScenarioError` about ``field`` of this table."""
        table = f"[{self.name}] " if self.name else ""
        return ScenarioError(f"{self.path}: {table}{field}: {message}")

    def has(self, field: str) -> bool:
        """Whether the field is present (does not mark it as read)."""
        return field in self.data

    def _get(self, field: str, default: Any) -> Any:
        self._read.add(field)
        if field in self.data:
            return self.data[field]
        if default is _REQUIRED:
            raise self.error(field, "missing field")
        return default

    def table(self, field: str) -> TomlTable:
        """A required sub-table."""
        value = self._get(field, _REQUIRED)
        if not isinstance(value, dict):
            raise self.error(field, "must be a table")
        return TomlTable(value, self.path, f"{self.name}.{field}" if self.name else field)

    def tables(self, *fields: str) -> tuple[TomlTable, ...]:
        """Required sub-tables, in the order of ``fields``."""
        return tuple(self.table(field) for field in fields)

    def optional_table(self, field: str) -> TomlTable | None:
        """A sub-table, or ``None`` when absent."""
        return self.table(field) if self.has(field) else self._get(field, None)

    def number(
        self,
        field: str,
        default: Any = _REQUIRED,
        *,
        positive: bool = False,
        minimum: float | None = None,
        maximum: float | None = None,
    ) -> float:
        """A finite float; ``positive`` requires > 0, ``minimum``/``maximum`` bound it."""
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
        if maximum is not None and value > maximum:
            raise self.error(field, f"must be <= {maximum}, got {value}")
        return value

    def integer(self, field: str, default: Any = _REQUIRED, *, minimum: int | None = None) -> int:
        """An integer, optionally ``>= minimum``."""
        value = self._get(field, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(field, f"must be an integer, got {value!r}")
        if minimum is not None and value < minimum:
            raise self.error(field, f"must be >= {minimum}, got {value}")
        return value

    def boolean(self, field: str, default: Any = _REQUIRED) -> bool:
        """``true`` or ``false``."""
        value = self._get(field, default)
        if not isinstance(value, bool):
            raise self.error(field, f"must be true or false, got {value!r}")
        return value

    def string(
        self, field: str, default: Any = _REQUIRED, *, choices: Collection[str] | None = None
    ) -> str:
        """A string, optionally one of ``choices``."""
        value = self._get(field, default)
        if not isinstance(value, str):
            raise self.error(field, f"must be a string, got {value!r}")
        if choices is not None and value not in choices:
            raise self.error(field, f"must be one of {sorted(choices)}, got {value!r}")
        return value

    def array(
        self, field: str, shape: tuple[int | None, ...], default: Any = _REQUIRED
    ) -> np.ndarray:
        """A finite float array of the given shape (``None`` = any length on that axis)."""
        value = self._get(field, default)
        try:
            array = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise self.error(field, f"must be an array of numbers, got {value!r}") from None
        fits = array.ndim == len(shape) and all(
            want is None or want == got for want, got in zip(shape, array.shape, strict=False)
        )
        if not fits:
            wanted = " x ".join("N" if s is None else str(s) for s in shape)
            raise self.error(field, f"must be a {wanted} array, got shape {array.shape}")
        if not np.all(np.isfinite(array)):
            raise self.error(field, "must contain finite numbers only")
        return array

    def check_unknown(self) -> None:
        """Reject fields that were never read (typos are errors, not ignored settings)."""
        unknown = sorted(set(self.data) - self._read)
        if unknown:
            raise self.error(unknown[0], "unknown field (check its spelling in the docs)")


def load_toml(path: str | Path) -> TomlTable:
    """Parse a TOML file into its top-level :class:`TomlTable`.

    Raises
    ------
    OSError
        The file cannot be read (a missing file or a folder is named in one line).
    ScenarioError
        Not valid TOML (the parser's message carries the line and column).
    """
    path = Path(path)
    try:
        with path.open("rb") as handle:
            data = tomllib.load(handle)
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such scenario file") from None
    except IsADirectoryError:
        raise IsADirectoryError(f"{path}: a folder, not a scenario file") from None
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: not valid TOML: {exc}") from None
    return TomlTable(data, path)
