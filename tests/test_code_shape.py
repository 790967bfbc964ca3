"""The package's shape, read from the source: functions a reader can hold, a small CLI module,
and controllers whose task rows and axes are named, never typed as numbers (GUIDE.md, "Fast
code that stays readable": names, not positions; tasks declared, offsets computed)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "walkrepro"
#: A function longer than this many lines (decorators excluded, docstring included) is too long.
MAX_FUNCTION_LINES = 80
#: The CLI's top module holds the app and the registration of its command groups.
MAX_CLI_LINES = 300
#: The controllers' modules: where task rows, QP rows, axes and joints are indexed.
CONTROLLER_MODULES = (
    "papers/lee2021/wbc.py",
    "papers/lee2021/kernels.py",
    "papers/lee2021/controller.py",
    "papers/lee2021/fsm.py",
    "papers/jo_oh/tasks.py",
    "papers/jo_oh/centroidal_qp.py",
    "papers/jo_oh/controller.py",
    "papers/jo_oh/condensed.py",
    "papers/faraji/controller.py",
)


def long_functions(source: str, limit: int = MAX_FUNCTION_LINES) -> list[tuple[str, int]]:
    """(name, lines) of every function or method longer than ``limit`` lines."""
    return [
        (node.name, node.end_lineno - node.lineno + 1)
        for node in ast.walk(ast.parse(source))
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
        and node.end_lineno - node.lineno + 1 > limit
    ]


def _typed(node: ast.expr | None) -> bool:
    """A typed position: an integer literal other than 0, or arithmetic with a literal."""
    if node is None:
        return False
    if isinstance(node, ast.Constant):
        return isinstance(node.value, int) and not isinstance(node.value, bool) and node.value != 0
    if isinstance(node, ast.UnaryOp):
        return _typed(node.operand)
    if isinstance(node, ast.BinOp):
        return any(isinstance(n, ast.Constant) and isinstance(n.value, int) for n in ast.walk(node))
    return False


def _typed_index(index: ast.expr) -> bool:
    if isinstance(index, ast.Slice):
        return _typed(index.lower) or _typed(index.upper)
    if isinstance(index, ast.Tuple):
        return any(_typed_index(element) for element in index.elts)
    return _typed(index)


def typed_offsets(source: str) -> list[tuple[int, str]]:
    """(line, text) of every subscript that types a row, axis or joint as a number
    (``j[4:10]``, ``f[2]``, ``acc[2 + i]``, ``k[4, 0]``); ``x.shape[1]`` is a size, not a row."""
    lines = source.splitlines()
    return sorted(
        {
            (node.lineno, lines[node.lineno - 1].strip())
            for node in ast.walk(ast.parse(source))
            if isinstance(node, ast.Subscript)
            and _typed_index(node.slice)
            and not (isinstance(node.value, ast.Attribute) and node.value.attr == "shape")
        }
    )


def import_time_side_effects(source: str) -> list[str]:
    """Module-level calls that change the process for everyone who imports the module
    (a global warnings filter)."""
    found = []
    for node in ast.parse(source).body:
        call = node.value if isinstance(node, ast.Expr) else None
        if isinstance(call, ast.Call) and isinstance(call.func, ast.Attribute):
            if call.func.attr in {"filterwarnings", "simplefilter", "resetwarnings"}:
                found.append(ast.unparse(call.func))
    return found


def structref_imports(source: str) -> list[str]:
    """Imports of numba's StructRef machinery (kept in walkrepro/runtime/records.py)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith(
            "numba.experimental"
        ):
            found.append(f"from {node.module} import {', '.join(a.name for a in node.names)}")
        elif isinstance(node, ast.Import):
            found += [a.name for a in node.names if a.name.startswith("numba.experimental")]
    return found


# ---- the checks fail where they should --------------------------------------------------


def test_a_long_function_is_found():
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES))
    assert long_functions(f"def f():\n{body}\n") == [("f", MAX_FUNCTION_LINES + 1)]
    assert long_functions(f"def f():\n{body[: body.rfind(chr(10))]}\n") == []


@pytest.mark.parametrize(
    "line",
    [
        "y = j[4:10]",
        "y = acc2[6:9]",
        "y = k[4, 0]",
        "y = f[2]",
        "y = a[2 + i]",
        "a[3 * h + i] = 1",
        "y = x[:, :6]",
        "y = x[-1]",
    ],
)
def test_a_typed_offset_is_found(line):
    assert typed_offsets(line) == [(1, line)]


@pytest.mark.parametrize(
    "line",
    ["y = j[rows]", "y = j[task.rows]", "y = f[Z]", "y = x[0]", "y = x.shape[1]", "y = x[:n]"],
)
def test_a_named_or_computed_index_is_not_an_offset(line):
    assert typed_offsets(line) == []


def test_a_global_warnings_filter_and_a_structref_import_are_found():
    source = "import warnings\nfrom numba.experimental import structref\nwarnings.filterwarnings('ignore')\n"
    assert import_time_side_effects(source) == ["warnings.filterwarnings"]
    assert structref_imports(source) == ["from numba.experimental import structref"]
    assert import_time_side_effects("def f():\n    warnings.simplefilter('ignore')\n") == []


# ---- the shipped package -----------------------------------------------------------------


def test_no_function_in_the_package_is_longer_than_a_reader_can_hold():
    found = {
        f"{file.relative_to(PACKAGE)}:{name}": lines
        for file in sorted(PACKAGE.rglob("*.py"))
        for name, lines in long_functions(file.read_text())
    }
    assert found == {}


def test_the_cli_module_is_the_app_and_its_command_groups():
    # The CLI is the package cli/ (its command groups are its modules, which the layers of
    # tests/test_imports.py allow only inside it); its top module is __init__.py.
    assert len((PACKAGE / "cli" / "__init__.py").read_text().splitlines()) < MAX_CLI_LINES


@pytest.mark.parametrize("module", CONTROLLER_MODULES)
def test_the_controllers_name_their_rows_and_axes(module):
    assert typed_offsets((PACKAGE / module).read_text()) == []


def test_the_papers_leave_numba_plumbing_and_the_process_alone():
    found = {
        str(file.relative_to(PACKAGE)): structref_imports(text) + import_time_side_effects(text)
        for file in sorted((PACKAGE / "papers").rglob("*.py"))
        if (text := file.read_text())
    }
    assert {k: v for k, v in found.items() if v} == {}
