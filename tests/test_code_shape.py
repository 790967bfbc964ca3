"""The papers' code shape, read from its source: names, not positions, and no numba internals.

Parameters, per-tick state and signals are records with named fields (named tuples, numba
StructRefs, structured records), so a reader sees ``gains.kp_swing`` or
``signals.left.fz``, never ``params[3]`` or ``out[17]``; and compiled kernels are called
through numba's public interface only.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PAPERS = Path(__file__).resolve().parents[1] / "walkrepro" / "papers"
#: Containers that hold signals or parameters, by the name they go by: ``out`` (a kernel's
#: output vector), or a name with one of these parts.
RECORD_WORDS = ("signal", "param", "scalar", "gain")
#: numba's attributes and modules that are not its public interface (the dispatcher's
#: ``compile`` and ``typeof_pyval``, its overloads table; ``numba.core`` except the types
#: its documented StructRef API is written with).
NUMBA_INTERNALS = ("compile", "typeof_pyval", "overloads", "get_compile_result")
NUMBA_CORE_ALLOWED = ("types",)
#: Decorators that make a compiled kernel.
KERNEL_DECORATORS = ("njit", "jit", "_jit")
#: Papers whose code still keeps positions, each with the reason.
PENDING: dict[str, str] = {}


def _name(node: ast.AST) -> str:
    """The last name of a container expression: ``self._signals`` -> ``_signals``,
    ``st["params"]`` -> ``params``."""
    while isinstance(node, ast.Subscript):
        key = node.slice
        if isinstance(key, ast.Constant) and isinstance(key.value, str):
            return key.value
        node = node.value
    if isinstance(node, ast.Attribute):
        return node.attr
    if isinstance(node, ast.Name):
        return node.id
    return ""


def _is_record_container(name: str) -> bool:
    lower = name.lower()
    return lower == "out" or any(word in lower for word in RECORD_WORDS)


def _positional(index: ast.AST) -> bool:
    """An index by position: an integer, arithmetic on one, a slice, or a tuple holding one."""
    if isinstance(index, ast.Constant):
        return isinstance(index.value, int) and not isinstance(index.value, bool)
    if isinstance(index, (ast.BinOp, ast.Slice)):
        return True
    if isinstance(index, ast.UnaryOp):
        return _positional(index.operand)
    if isinstance(index, ast.Tuple):
        return any(_positional(e) for e in index.elts)
    return False


def _kernels(tree: ast.AST) -> list[ast.FunctionDef]:
    """The functions decorated as numba kernels (``@numba.njit(...)``, ``@_jit`` …)."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef):
            for deco in node.decorator_list:
                target = deco.func if isinstance(deco, ast.Call) else deco
                if _name(target) in KERNEL_DECORATORS:
                    found.append(node)
    return found


def positions(source: str, filename: str = "<source>") -> list[str]:
    """``file:line what`` of every place in ``source`` that uses positions for names:

    - a write into a signal or parameter container (``out``, ``*signal*``, ``*param*``,
      ``*scalar*``, ``*gain*``) by position (``out[3] = …``, ``signals[k + 1] = …``);
    - a compiled kernel reading one of its own such parameters by position
      (``gains[3, i]``: a positional float vector of parameters).
    """
    tree = ast.parse(source, filename)
    found = []
    for node in ast.walk(tree):
        targets: list[ast.AST] = []
        if isinstance(node, ast.Assign):
            targets = list(node.targets)
        elif isinstance(node, (ast.AugAssign, ast.AnnAssign)):
            targets = [node.target]
        for target in targets:
            elements = target.elts if isinstance(target, ast.Tuple) else [target]
            for t in elements:
                if (
                    isinstance(t, ast.Subscript)
                    and _is_record_container(_name(t.value))
                    and _positional(t.slice)
                ):
                    found.append(f"{filename}:{t.lineno} {ast.unparse(t)} = (written by position)")
    for kernel in _kernels(tree):
        arguments = {a.arg for a in (*kernel.args.posonlyargs, *kernel.args.args)}
        for node in ast.walk(kernel):
            if (
                isinstance(node, ast.Subscript)
                and isinstance(node.ctx, ast.Load)
                and isinstance(node.value, ast.Name)
                and node.value.id in arguments
                and _is_record_container(node.value.id)
                and _positional(node.slice)
            ):
                found.append(
                    f"{filename}:{node.lineno} {ast.unparse(node)} (kernel {kernel.name} reads "
                    "a parameter vector by position)"
                )
    return found


def numba_internals(source: str, filename: str = "<source>") -> list[str]:
    """``file:line what`` of every use of numba's internals in ``source``: the attributes of
    :data:`NUMBA_INTERNALS` (``kernel.compile(…)``; ``re.compile`` and MuJoCo's
    ``spec.compile`` are not numba's and not used in the papers), ``numba.core`` beyond
    :data:`NUMBA_CORE_ALLOWED`."""
    tree = ast.parse(source, filename)
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and node.attr in NUMBA_INTERNALS:
            found.append(f"{filename}:{node.lineno} .{node.attr}")
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("numba.core"):
            names = [a.name for a in node.names]
            if node.module != "numba.core" or set(names) - set(NUMBA_CORE_ALLOWED):
                found.append(f"{filename}:{node.lineno} from {node.module} import {names}")
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("numba.core"):
                    found.append(f"{filename}:{node.lineno} import {alias.name}")
    return found


def _paper_files(paper: str) -> list[tuple[str, str]]:
    return [
        (path.read_text(), str(path.relative_to(PAPERS.parent.parent)))
        for path in sorted((PAPERS / paper).rglob("*.py"))
    ]


def _papers() -> list:
    return [
        pytest.param(p.name, marks=pytest.mark.xfail(reason=PENDING[p.name], strict=False))
        if p.name in PENDING
        else p.name
        for p in sorted(PAPERS.iterdir())
        if (p / "__init__.py").is_file()
    ]


@pytest.mark.parametrize("paper", _papers())
def test_a_papers_signals_and_parameters_go_by_name(paper: str) -> None:
    """No paper writes its signals or parameters by position, and no compiled kernel reads a
    positional vector of parameters."""
    found = [hit for source, name in _paper_files(paper) for hit in positions(source, name)]
    assert not found, "positions instead of names:\n" + "\n".join(found)


@pytest.mark.parametrize("paper", [p.name for p in sorted(PAPERS.iterdir()) if p.is_dir()])
def test_a_paper_calls_no_numba_internals(paper: str) -> None:
    """The papers call compiled kernels through numba's public interface only."""
    found = [hit for source, name in _paper_files(paper) for hit in numba_internals(source, name)]
    assert not found, "numba internals:\n" + "\n".join(found)


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        ("out[3] = x", ["<source>:1 out[3] = (written by position)"]),
        ("signals[k + 1] = x", ["<source>:1 signals[k + 1] = (written by position)"]),
        ("self._signals[0], self._signals[1] = a, b", 2),
        ("out[:3] = com", 1),
        ("st['params'][2] = 0.5", 1),
        ("signals.left.fz = fz", []),
        ("record['zmp_x_ref'] = z", []),
        ("self._signal_record[FZ_QP[side]] = fz", []),
        ("pos[0], pos[1] = x, y", []),  # a vector's components, not a record
        ("out[i] = q", []),  # by a loop index: a vector
        (
            "@numba.njit(cache=True)\ndef f(gains, x):\n    return gains[3, 0] * x[0]",
            ["<source>:3 gains[3, 0] (kernel f reads a parameter vector by position)"],
        ),
        ("@_jit\ndef f(params):\n    return params[DT + 1]", 1),
        ("def f(gains):\n    return gains[3]", []),  # not compiled: a Python sequence
        ("@numba.njit\ndef f(gains):\n    return gains.mass[0]", []),
    ],
)
def test_positions_finds_exactly_the_positional_ones(source: str, expected: list | int) -> None:
    """The rule flags positional writes to signal and parameter containers and positional
    reads of a kernel's parameter vector, and nothing named."""
    found = positions(source)
    if isinstance(expected, int):
        assert len(found) == expected, found
    else:
        assert found == expected


@pytest.mark.parametrize(
    ("source", "count"),
    [
        ("entry = kernel.compile(sig)", 1),
        ("t = kernel.typeof_pyval(x)", 1),
        ("from numba.core import types", 0),
        ("from numba.core import types, config", 1),
        ("from numba.core.typing import signature", 1),
        ("import numba.core.config", 1),
        ("from numba.experimental import structref", 0),
    ],
)
def test_numba_internals_finds_exactly_the_internal_ones(source: str, count: int) -> None:
    """The rule flags the dispatcher's compile and typeof and numba.core beyond its types."""
    assert len(numba_internals(source)) == count
