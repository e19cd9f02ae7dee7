"""docs/cli.md equals what the CLI prints (python -m lightcurve.cli_reference)."""

from pathlib import Path

from lightcurve.cli_reference import render

DOC = Path(__file__).resolve().parents[2] / "docs" / "cli.md"


def test_cli_reference_is_up_to_date():
    assert DOC.read_text() == render(), (
        "docs/cli.md is stale: run `python -m lightcurve.cli_reference > docs/cli.md`"
    )
