"""What the docs show as code, files and messages is what the code has (fast: nothing runs
longer than a registry lookup)."""

from __future__ import annotations

import ast
import re
import tomllib
from importlib import resources
from pathlib import Path

import pytest

import brdf

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]


def fenced(page: Path, language: str) -> list[tuple[int, str]]:
    """``(line, code)`` of the page's code blocks in ``language``."""
    text = page.read_text()
    return [
        (text[: match.start()].count("\n") + 2, match.group(1))
        for match in re.finditer(rf"^```{language}\n(.*?)^```", text, re.S | re.M)
    ]


PYTHON = [
    (f"{page.name}:{line}", code)
    for page in PAGES
    for line, code in fenced(page, "python")
    if not code.lstrip().startswith(">>>")  # an interactive session with its error shown
]


@pytest.mark.parametrize(("where", "code"), PYTHON, ids=[where for where, _ in PYTHON])
def test_python_example_is_valid_python(where, code):
    ast.parse(code, filename=where)


def test_the_conditions_example_is_the_half_metre_preset():
    (example,) = (code for _, code in fenced(DOCS / "formats.md", "toml"))
    preset = resources.files("lightcurve") / "data" / "telescopes" / "half_metre.toml"
    assert tomllib.loads(example) == tomllib.loads(preset.read_text(encoding="utf-8"))


def test_the_brdf_page_shows_the_registry_as_it_is():
    text = (DOCS / "brdf.md").read_text()
    assert f"brdf.available()  # {brdf.available()!r}" in text
    for name, params in (
        ("cook-torrance", {"m": 0}),
        ("phong", {"rd": 0.6, "rs": 0.5}),
        ("phong", {"shininess": 3}),
        ("oren-nayar", {}),
    ):
        with pytest.raises(brdf.BRDFParameterError) as error:
            brdf.get(name, **params)
        assert f"\n{error.value}\n" in text


def test_the_csv_example_is_a_valid_observation_file(tmp_path):
    from lightcurve import io

    text = (DOCS / "formats.md").read_text()
    example = re.search(r"^### CSV\n.*?^```\n(.*?)^```", text, re.S | re.M).group(1)
    (tmp_path / "example.csv").write_text(example)
    observations = io.read(tmp_path / "example.csv")
    assert len(observations) == 1 and observations.meta["frame"] == "GCRS"
    io.write(observations, tmp_path / "written.csv")
    assert example.splitlines()[-1].split(",")[0] in (tmp_path / "written.csv").read_text()


FENCED = re.compile(r"^```.*?^```", re.S | re.M)


def anchors(page: Path) -> set[str]:
    """GitHub's anchors of a page's headings: lower case, punctuation dropped, spaces → '-'."""
    found = set()
    for heading in re.findall(r"^#+ (.+)$", FENCED.sub("", page.read_text()), re.M):
        found.add(re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-"))
    return found


def test_links_between_pages_resolve():
    broken = []
    for page in PAGES:
        for target in re.findall(r"\]\(([^)\s]+)\)", FENCED.sub("", page.read_text())):
            if target.startswith(("http://", "https://")):
                continue
            path, _, anchor = target.partition("#")
            linked = (page.parent / path) if path else page
            if not linked.exists():
                broken.append(f"{page.name}: {target} (no such file)")
            elif anchor and linked.suffix == ".md" and anchor not in anchors(linked):
                broken.append(f"{page.name}: {target} (no such heading)")
    assert not broken


def test_every_docs_page_is_linked_from_the_guide_or_readme():
    linked = (DOCS / "index.md").read_text() + (ROOT / "README.md").read_text()
    assert [
        p.name for p in DOCS.glob("*.md") if p.name != "index.md" and p.name not in linked
    ] == []
