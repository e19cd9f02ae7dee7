"""docs/validation.md stays scannable: its first table is the summary (figure, requirement,
ours, command) and no table cell holds more than a few dozen words; longer accounts belong
in the sections below the summary or in the topic pages."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "validation.md"
MAX_WORDS = 40
SUMMARY_COLUMNS = ["figure", "requirement", "ours", "command"]
FENCE = re.compile(r"^```.*?^```", re.S | re.M)
SEPARATOR = re.compile(r"^\|?\s*:?-+:?\s*(\|\s*:?-+:?\s*)*\|?$")


def split_row(line: str) -> list[str]:
    """The cells of a table row: split on pipes that are not escaped (`\\|`)."""
    line = line.strip()
    line = line[1:] if line.startswith("|") else line
    line = line[:-1] if line.endswith("|") and not line.endswith("\\|") else line
    return [cell.strip() for cell in re.split(r"(?<!\\)\|", line)]


def tables(text: str) -> list[tuple[int, list[list[str]]]]:
    """``(line of the header, rows)`` of each GitHub-flavoured table, header row first."""
    lines = FENCE.sub(lambda m: "\n" * m.group(0).count("\n"), text).split("\n")
    found = []
    number = 0
    while number < len(lines) - 1:
        if lines[number].lstrip().startswith("|") and SEPARATOR.match(lines[number + 1].strip()):
            start, rows = number, [split_row(lines[number])]
            number += 2
            while number < len(lines) and lines[number].lstrip().startswith("|"):
                rows.append(split_row(lines[number]))
                number += 1
            found.append((start + 1, rows))
        else:
            number += 1
    return found


def long_cells(text: str, limit: int = MAX_WORDS) -> list[str]:
    """``line: words: start of cell`` of each table cell over ``limit`` words."""
    problems = []
    for line, rows in tables(text):
        for offset, row in enumerate(rows):
            for cell in row:
                words = len(cell.split())
                if words > limit:
                    where = line + offset + (offset > 0)  # the separator line after the header
                    problems.append(f"line {where}: {words} words: {cell[:60]}…")
    return problems


def test_the_parser_finds_tables_and_long_cells():
    text = (
        "| a | b |\n| --- | --- |\n| one | `x \\| y` |\n\n```\n| not | a table |\n|---|---|\n```\n"
        f"| c |\n|---|\n| {'word ' * (MAX_WORDS + 1)}|\n"
    )
    found = tables(text)
    assert [rows[0] for _, rows in found] == [["a", "b"], ["c"]]
    assert found[0][1][1] == ["one", "`x \\| y`"]
    (problem,) = long_cells(text)
    assert problem.startswith(f"line 11: {MAX_WORDS + 1} words")


def test_no_table_cell_is_over_the_word_limit():
    assert long_cells(PAGE.read_text()) == []


def test_the_first_table_is_the_summary():
    found = tables(PAGE.read_text())
    assert found, "docs/validation.md has no table"
    _, rows = found[0]
    assert [cell.lower() for cell in rows[0]] == SUMMARY_COLUMNS
    assert len(rows) > 20
    assert all(len(row) == len(SUMMARY_COLUMNS) for row in rows)
