"""The package's code shape, read from its source: no function takes a long argument list.

Functions that need many inputs take records instead (a ``NamedTuple``, a dataclass, a
structured array for the compiled kernels, a typer command's options dataclass).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "walkrepro"
#: The most parameters a function in the package may take (``self``/``cls`` not counted;
#: ``*args`` and ``**kwargs`` count one each).
MAX_PARAMETERS = 8


def parameter_count(node: ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda) -> int:
    """How many parameters a function declares, ``self`` or ``cls`` of a method excepted."""
    a = node.args
    names = [x.arg for x in (*a.posonlyargs, *a.args, *a.kwonlyargs)]
    count = len(names) + (a.vararg is not None) + (a.kwarg is not None)
    if names[:1] in (["self"], ["cls"]):
        count -= 1
    return count


def long_signatures(source: str, filename: str = "<source>") -> list[str]:
    """``file:line name (count)`` of every function in ``source`` with too many parameters."""
    found = []
    for node in ast.walk(ast.parse(source, filename)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            count = parameter_count(node)
            if count > MAX_PARAMETERS:
                name = getattr(node, "name", "<lambda>")
                found.append(f"{filename}:{node.lineno} {name} ({count})")
    return found


def test_no_function_in_the_package_takes_more_than_eight_parameters() -> None:
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        found += long_signatures(path.read_text(), str(path.relative_to(PACKAGE.parent)))
    assert not found, "functions with more than 8 parameters:\n" + "\n".join(found)


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        ("def f(a, b, c, d, e, f, g, h): pass", []),
        ("def f(a, b, c, d, e, f, g, h, i): pass", ["<source>:1 f (9)"]),
        ("class C:\n    def m(self, a, b, c, d, e, f, g, h): pass", []),
        ("class C:\n    def m(self, a, b, c, d, e, f, g, h, i): pass", ["<source>:2 m (9)"]),
        ("def f(a, b, c, d, e, f, g, *args, **kwargs): pass", ["<source>:1 f (9)"]),
        ("def f(a, /, b, c, d, e, *, f, g, h, i): pass", ["<source>:1 f (9)"]),
        ("def outer():\n    def inner(a, b, c, d, e, f, g, h, i): pass", ["<source>:2 inner (9)"]),
        ("g = lambda a, b, c, d, e, f, g, h, i: 0", ["<source>:1 <lambda> (9)"]),
        ("async def f(a, b, c, d, e, f, g, h, i): pass", ["<source>:1 f (9)"]),
    ],
)
def test_long_signatures_finds_exactly_the_long_ones(source: str, expected: list[str]) -> None:
    assert long_signatures(source) == expected
