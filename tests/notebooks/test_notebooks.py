"""Every notebook in notebooks/ executes from a clean state with its default parameters, from
the notebooks/ folder as Jupyter starts it, and leaves the checkout as it found it: whatever it
writes goes to a temporary (or an ignored) folder."""

import fnmatch
import hashlib
import os
import shutil
import subprocess
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
# new, changed and deleted files, each one (ignored files are not listed), paths from the top
GIT_STATUS = ["--porcelain=v1", "-z", "--untracked-files=all", "--ignore-submodules"]


def _digest(path: Path) -> str | None:
    """The content's hash of a file, None for a file that is not there (or not a file)."""
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except (FileNotFoundError, IsADirectoryError, NotADirectoryError):
        return None


def _git_listing(root: Path) -> dict[str, tuple[str, str | None]] | None:
    """Every file of the checkout that git reports as new, changed or deleted (ignored files
    are not reported), with its status and content hash: a second change to a file that was
    already changed shows too. None where git or a git checkout is missing."""
    git = shutil.which("git")
    if git is None:
        return None
    options = {"cwd": root, "capture_output": True, "check": True, "timeout": 120}
    try:
        status = subprocess.run(
            [git, "--no-optional-locks", "status", *GIT_STATUS, "--", "."],
            **options,
        ).stdout.decode()
        top = subprocess.run([git, "rev-parse", "--show-toplevel"], **options).stdout
    except (subprocess.CalledProcessError, OSError, subprocess.TimeoutExpired):
        return None
    listing = {}
    entries = iter(status.split("\0"))
    for entry in entries:
        if not entry:
            continue
        code, path = entry[:2], entry[3:]
        if "R" in code or "C" in code:
            next(entries, None)  # the source path of a rename or copy follows
        listing[path] = (code, _digest(Path(top.decode().strip()) / path))
    return listing


def _ignore_patterns(root: Path) -> list[tuple[str, bool]]:
    """The name patterns of .gitignore, read simply: (pattern, only at the top level)."""
    patterns = []
    gitignore = root / ".gitignore"
    lines = gitignore.read_text().splitlines() if gitignore.is_file() else []
    for line in [*lines, ".git"]:
        line = line.strip()
        if line and not line.startswith(("#", "!")):
            patterns.append((line.strip("/"), line.startswith("/")))
    return patterns


def _walk_listing(root: Path) -> dict[str, tuple[str, str | None]]:
    """Without git: every file under the checkout with its content hash, skipping the names
    that .gitignore ignores (caches, build folders, results)."""
    patterns = _ignore_patterns(root)

    def ignored(name: str, top: bool) -> bool:
        return any(fnmatch.fnmatch(name, p) for p, only_top in patterns if top or not only_top)

    listing = {}
    for folder, dirs, files in os.walk(root):
        top = Path(folder) == root
        dirs[:] = [d for d in dirs if not ignored(d, top)]
        for name in files:
            if not ignored(name, top):
                path = Path(folder) / name
                listing[path.relative_to(root).as_posix()] = ("", _digest(path))
    return listing


def checkout_listing(root: Path = ROOT) -> dict[str, tuple[str, str | None]]:
    """A listing of the checkout's files to compare before and after a run."""
    listing = _git_listing(root)
    return _walk_listing(root) if listing is None else listing


def test_notebooks_exist():
    assert len(NOTEBOOKS) >= 5


def test_checkout_listing_sees_a_new_file(tmp_path):
    """Both listings see a file added under a checkout, and neither sees an ignored one."""
    (tmp_path / ".gitignore").write_text("results/\n")
    (tmp_path / "notebooks").mkdir()
    (tmp_path / "notebooks" / "a.ipynb").write_text("{}")
    listings = [_walk_listing]
    if shutil.which("git"):
        subprocess.run(["git", "init", "-q"], cwd=tmp_path, check=True)
        listings.append(_git_listing)
    for listing in listings:
        before = listing(tmp_path)
        (tmp_path / "notebooks" / "results").mkdir(exist_ok=True)
        (tmp_path / "notebooks" / "results" / "ignored.csv").write_text("x")
        assert listing(tmp_path) == before, listing.__name__
        (tmp_path / "notebooks" / "out").mkdir(exist_ok=True)
        (tmp_path / "notebooks" / "out" / "new.csv").write_text("x")
        after = listing(tmp_path)
        assert set(after) - set(before) >= {"notebooks/out/new.csv"}, listing.__name__
        shutil.rmtree(tmp_path / "notebooks" / "out")


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs(path, tmp_path, monkeypatch):
    # the kernel inherits TMPDIR: the temporary folders the notebook makes go to pytest's
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    notebook = nbformat.read(path, as_version=4)
    assert all(not cell.get("outputs") for cell in notebook.cells if cell.cell_type == "code"), (
        f"{path.name} has committed outputs: strip them"
    )
    before = checkout_listing()
    client = NotebookClient(
        notebook,
        timeout=300,
        kernel_name="python3",
        # the notebook's own folder, as Jupyter starts it: a file written to a relative path
        # lands in the checkout and fails the check below
        resources={"metadata": {"path": str(path.parent)}},
    )
    client.execute()
    after = checkout_listing()
    changed = sorted(p for p in before.keys() | after.keys() if before.get(p) != after.get(p))
    assert not changed, (
        f"running {path.name} added or changed files in the checkout (write them to a "
        f"temporary folder): {changed}"
    )
