"""The architecture as the folders and imports show it: rooms, layers, no import circles.

The layers are drawn in ``docs/architecture.md``; this test parses every import of the four
packages (module level, inside functions and under ``TYPE_CHECKING`` alike: each is an
arrow a reader follows) and checks them against the table below.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("brdf", "shapes", "filters", "lightcurve")
#: Folders exempt from the module count: one module per command.
ONE_MODULE_PER_ITEM = {"lightcurve/commands"}
MAX_MODULES = 15

#: The rooms of ``lightcurve`` from the lowest floor up; a room imports only rooms below it.
#: The modules at the package's top are two rooms of their own: ``workflows``, which combine
#: rooms for one file or a batch (the inversion pipeline, batch runs, importing, plots), and
#: ``cli``, the command line, which hands each command to its module in ``commands/``.
LIGHTCURVE_FLOORS = (
    ("io",),
    ("sky",),
    ("photometry",),
    ("analysis", "datasets", "studies"),
    ("attitude_modes", "scenarios"),
    ("inversion",),
    ("workflows",),
    ("commands",),
    ("cli",),
)
CLI_MODULES = {"lightcurve", "lightcurve.__main__", "lightcurve.cli", "lightcurve.cli_reference"}


def _modules() -> dict[str, Path]:
    modules = {}
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            modules[".".join(parts)] = path
    return modules


MODULES = _modules()


def _resolve(name: str) -> str | None:
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def _imports(module: str, path: Path) -> set[str]:
    """The project modules ``module`` imports (``from a import b``: ``a.b`` if a module)."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    targets = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            names = [
                f"{source}.{alias.name}" if f"{source}.{alias.name}" in MODULES else source
                for alias in node.names
            ]
        else:
            continue
        for name in names:
            target = _resolve(name)
            if target and target != module:
                targets.add(target)
    return targets


GRAPH = {module: _imports(module, path) for module, path in MODULES.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in sorted(graph.get(node, ())):
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def _room(module: str) -> str:
    """The room of a ``lightcurve`` module: its sub-package, else ``cli`` or ``workflows``."""
    if module in CLI_MODULES:
        return "cli"
    parts = module.split(".")
    if len(parts) == 2 and not (ROOT / "lightcurve" / parts[1]).is_dir():
        return "workflows"
    return parts[1]


def _floor(room: str) -> int:
    for floor, rooms in enumerate(LIGHTCURVE_FLOORS):
        if room in rooms:
            return floor
    raise AssertionError(f"lightcurve/{room} is in no floor of LIGHTCURVE_FLOORS")


def test_no_import_circles():
    assert _cycles(GRAPH) == []


def test_lower_packages_do_not_import_lightcurve():
    arrows = [
        f"{module} -> {target}"
        for module, targets in GRAPH.items()
        if not module.startswith("lightcurve")
        for target in targets
        if target.startswith("lightcurve")
    ]
    assert arrows == []


def test_leaf_packages_import_no_other_project_package():
    arrows = [
        f"{module} -> {target}"
        for module, targets in GRAPH.items()
        if module.split(".")[0] != "lightcurve"
        for target in targets
        if target.split(".")[0] != module.split(".")[0]
    ]
    assert arrows == []


def test_lightcurve_rooms_import_only_rooms_below():
    arrows = []
    for module, targets in GRAPH.items():
        if not module.startswith("lightcurve"):
            continue
        room = _room(module)
        for target in targets:
            if not target.startswith("lightcurve") or target == "lightcurve":
                continue  # the root package holds only the version
            other = _room(target)
            if other != room and _floor(other) >= _floor(room):
                arrows.append(f"{module} ({room}) -> {target} ({other})")
    assert arrows == []


def test_every_room_is_on_a_floor():
    rooms = {
        path.name for path in (ROOT / "lightcurve").iterdir() if (path / "__init__.py").is_file()
    }
    for room in rooms:
        _floor(room)


def _package_folders() -> list[Path]:
    return sorted(
        path.parent for package in PACKAGES for path in (ROOT / package).rglob("__init__.py")
    )


@pytest.mark.parametrize("folder", _package_folders(), ids=lambda p: str(p.relative_to(ROOT)))
def test_rooms_are_small_and_say_what_they_hold(folder):
    name = str(folder.relative_to(ROOT))
    modules = sorted(path.stem for path in folder.glob("*.py"))
    if name not in ONE_MODULE_PER_ITEM:
        assert len(modules) <= MAX_MODULES, f"{name} has {len(modules)} modules at its top"
    docstring = ast.get_docstring(ast.parse((folder / "__init__.py").read_text())) or ""
    assert docstring, f"{name}/__init__.py has no docstring"
    children = [m for m in modules if not m.startswith("_")]
    children += [p.name for p in folder.iterdir() if (p / "__init__.py").is_file()]
    missing = [child for child in children if child not in docstring]
    assert missing == [], f"{name}/__init__.py does not list {missing}"
