"""Constants of the library's modules read from their source, without importing them.

A command's arguments list the library's choices (profiles, shadow modes, time formats…),
but importing the module that defines them can pull in pandas, trimesh or torch: seconds
before ``lightcurve <command> --help`` prints anything. These functions read the literal
assignments (and dataclass fields) from the module's source with :mod:`ast` instead, so the
argument builders import nothing heavy and the library stays the one place the values are
written. ``tests/lightcurve/test_startup.py`` checks every value read here against the
imported module.
"""

from __future__ import annotations

import ast
import importlib.machinery
import importlib.util
from functools import cache
from pathlib import Path
from typing import Any

__all__ = ["dataclass_fields", "literal", "module_literals"]


@cache
def _body(module: str) -> tuple[ast.stmt, ...]:
    """The top-level statements of a module's source, found without importing it or its
    parent packages (``importlib.util.find_spec`` of a submodule imports the parents, whose
    ``__init__`` may be heavy): the top-level package's spec, then each submodule's in its
    parent's folders."""
    parts = module.split(".")
    spec = importlib.util.find_spec(parts[0])
    for depth in range(2, len(parts) + 1):
        if spec is None or not spec.submodule_search_locations:
            spec = None
            break
        locations = list(spec.submodule_search_locations)
        spec = importlib.machinery.PathFinder.find_spec(".".join(parts[:depth]), locations)
    if spec is None or spec.origin is None:
        raise ModuleNotFoundError(f"no module named {module!r}")
    return tuple(ast.parse(Path(spec.origin).read_text(encoding="utf-8")).body)


def module_literals(module: str, names: tuple[str, ...]) -> dict[str, Any]:
    """The values of the module-level literal assignments ``NAME = …`` among ``names``."""
    values = {}
    for node in _body(module):
        if isinstance(node, ast.Assign) and len(node.targets) == 1:
            target = node.targets[0]
            if isinstance(target, ast.Name) and target.id in names:
                values[target.id] = ast.literal_eval(node.value)
    return values


def literal(module: str, name: str) -> Any:
    """The value of ``module.name``, a literal assignment (tuple, dict, string, number…).

    Raises
    ------
    LookupError
        If the module assigns no literal to ``name``.
    """
    values = module_literals(module, (name,))
    if name not in values:
        raise LookupError(f"{module} has no literal assignment to {name}")
    return values[name]


def dataclass_fields(module: str, name: str) -> tuple[str, ...]:
    """Field names, in order, of the dataclass ``module.name`` (its annotated attributes)."""
    for node in _body(module):
        if isinstance(node, ast.ClassDef) and node.name == name:
            return tuple(
                item.target.id
                for item in node.body
                if isinstance(item, ast.AnnAssign)
                and isinstance(item.target, ast.Name)
                and "ClassVar" not in ast.unparse(item.annotation)
            )
    raise LookupError(f"{module} defines no class {name}")
