"""The benchmarks' shared command-line pieces."""

import argparse

import pytest

from benchmarks._report import add_sections_argument


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="bench")
    add_sections_argument(parser, ("build", "render", "breakdown"))
    return parser


def test_sections_default_to_all_and_take_a_subset():
    assert _parser().parse_args([]).sections == {"build", "render", "breakdown"}
    assert _parser().parse_args(["--sections", "render, build"]).sections == {"build", "render"}


@pytest.mark.parametrize("text", ["rendre", "render,foo", ","])
def test_unknown_or_empty_sections_are_refused_with_the_known_names(text, capsys):
    with pytest.raises(SystemExit) as stop:
        _parser().parse_args(["--sections", text])
    assert stop.value.code == 2
    message = capsys.readouterr().err.strip().splitlines()[-1]
    assert message.startswith("bench: error: argument --sections:")
    assert message.endswith("choose from build, render, breakdown")
