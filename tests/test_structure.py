"""The library's structural rules stay true (``docs/architecture.md``).

- every function takes at most six parameters positionally (``self``/``cls`` aside); the
  compiled numba kernels are exempt, because jitted functions calling each other cannot
  bind keyword arguments;
- no module of the library is over ~600 lines unless ``docs/architecture.md`` states why.
"""

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("brdf", "shapes", "filters", "lightcurve")
MAX_POSITIONAL = 6
MAX_LINES = 600


def library_modules() -> list[Path]:
    return sorted(path for package in PACKAGES for path in (ROOT / package).rglob("*.py"))


def is_numba_kernel(function: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """Whether ``function`` is decorated with numba's ``njit``/``jit`` (bare or called)."""
    for decorator in function.decorator_list:
        target = decorator.func if isinstance(decorator, ast.Call) else decorator
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in ("njit", "jit"):
            return True
    return False


def positional_count(function: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    names = [arg.arg for arg in function.args.posonlyargs + function.args.args]
    if names and names[0] in ("self", "cls"):
        names = names[1:]
    return len(names)


def long_positional_signatures(source: str, filename: str) -> list[str]:
    """``file:line name (n)`` for every non-kernel function of ``source`` over the limit."""
    functions = [
        node
        for node in ast.walk(ast.parse(source))
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
    ]
    return [
        f"{filename}:{node.lineno} {node.name} ({positional_count(node)})"
        for node in sorted(functions, key=lambda node: node.lineno)
        if positional_count(node) > MAX_POSITIONAL and not is_numba_kernel(node)
    ]


def test_checker_counts_positional_parameters_and_exempts_numba_kernels():
    source = """
import numba
from numba import njit

def seven(a, b, c, d, e, f, g): ...
def six_and_keywords(a, b, c, d, e, f, *, g, h): ...
def positional_only(a, b, c, d, /, e, f, g): ...
class Model:
    def method(self, a, b, c, d, e, f): ...
    @classmethod
    def build(cls, a, b, c, d, e, f, g): ...
@njit(cache=True)
def kernel(a, b, c, d, e, f, g, h): ...
@numba.njit
def bare_kernel(a, b, c, d, e, f, g, h): ...
@staticmethod
def decorated(a, b, c, d, e, f, g): ...
"""
    found = long_positional_signatures(source, "example.py")
    assert [entry.split()[1] for entry in found] == [
        "seven",
        "positional_only",
        "build",
        "decorated",
    ]
    assert found[0] == "example.py:5 seven (7)"


def test_no_function_takes_more_than_six_positional_parameters():
    offenders = [
        entry
        for path in library_modules()
        for entry in long_positional_signatures(path.read_text(), str(path.relative_to(ROOT)))
    ]
    assert offenders == [], "pass these parameters by keyword (after `*`):\n" + "\n".join(offenders)


def stated_size_exceptions() -> set[str]:
    """Modules ``docs/architecture.md`` names, with a reason, in its paragraph on sizes."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    match = re.search(r"Module sizes:(.+?)\n\n", text, re.S)
    assert match, "docs/architecture.md has no 'Module sizes:' paragraph"
    return set(re.findall(r"`([\w/]+\.py)`\s*\(~\d+", match.group(1)))


def test_modules_are_small_or_have_a_stated_reason():
    stated = stated_size_exceptions()
    oversized = [
        f"{path.relative_to(ROOT)} ({len(path.read_text().splitlines())} lines)"
        for path in library_modules()
        if len(path.read_text().splitlines()) > MAX_LINES
        and str(path.relative_to(ROOT)) not in stated
    ]
    assert oversized == [], (
        "split these by job or state the reason in docs/architecture.md ('Module sizes'):\n"
        + "\n".join(oversized)
    )
