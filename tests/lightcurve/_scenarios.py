"""The shipped scenario files, and edited copies of them for fast command tests."""

from __future__ import annotations

import re
from pathlib import Path

SCENARIOS = Path(__file__).resolve().parents[2] / "data" / "scenarios"


def edited_copy(
    folder: Path,
    source: Path,
    substitutions: dict[str, str],
    *,
    text: str | None = None,
    name: str | None = None,
) -> Path:
    """A copy of the scenario file ``source`` in ``folder`` with regular-expression edits.

    Parameters
    ----------
    folder : pathlib.Path
        Where the copy is written.
    source : pathlib.Path
        The scenario file.
    substitutions : dict
        ``pattern → replacement`` (:func:`re.sub`, every match), applied in order.
    text : str, optional
        Content to edit instead of the file's (e.g. the file's with a field broken).
    name : str, optional
        File name of the copy (default: the source's).

    Returns
    -------
    pathlib.Path
        The copy.
    """
    text = source.read_text() if text is None else text
    for pattern, replacement in substitutions.items():
        text = re.sub(pattern, replacement, text)
    path = folder / (source.name if name is None else name)
    path.write_text(text)
    return path
