"""The package's import graph, read from the source (nothing is imported): no circle, and the
core never imports a paper (walkrepro/papers/ is reached through the plugin registry)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "walkrepro"
PAPERS = "walkrepro.papers"


def module_files(package: Path = PACKAGE) -> dict[str, Path]:
    """Every module of the package by dotted name (a package by its ``__init__.py``)."""
    found = {}
    for file in sorted(package.rglob("*.py")):
        parts = file.relative_to(package.parent).with_suffix("").parts
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = file
    return found


def _runtime_imports(tree: ast.AST) -> list[ast.Import | ast.ImportFrom]:
    """Every import statement that runs, at any depth (in functions too), without the
    ``if TYPE_CHECKING:`` blocks, which never run."""
    found, todo = [], [tree]
    while todo:
        node = todo.pop()
        if isinstance(node, ast.Import | ast.ImportFrom):
            found.append(node)
        for child in ast.iter_child_nodes(node):
            test = getattr(child, "test", None) if isinstance(child, ast.If) else None
            if (getattr(test, "id", None) or getattr(test, "attr", None)) == "TYPE_CHECKING":
                todo.extend(child.orelse)
            else:
                todo.append(child)
    return found


def import_graph(modules: dict[str, Path]) -> dict[str, set[str]]:
    """module -> the package's modules it imports. ``from p import m`` with ``m`` a module is
    an edge to ``p.m`` alone (Python runs ``p``'s ``__init__`` first, but a package that
    gathers its submodules is not a dependency of theirs); ``from p import name`` is an edge
    to ``p``."""
    graph: dict[str, set[str]] = {}
    for name, file in modules.items():
        is_package = file.name == "__init__.py"
        edges: set[str] = set()
        for node in _runtime_imports(ast.parse(file.read_text(), str(file))):
            if isinstance(node, ast.Import):
                edges.update(alias.name for alias in node.names)
                continue
            if node.level:
                parts = name.split(".")[: len(name.split(".")) - node.level + is_package]
                base = ".".join([*parts, *([node.module] if node.module else [])])
            else:
                base = node.module or ""
            for alias in node.names:
                edges.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base)
        graph[name] = {e for e in edges if e in modules and e != name}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The graph's circles: its strongly connected components of more than one module."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_package_has_no_import_circle() -> None:
    assert cycles(import_graph(module_files())) == []


def test_the_core_never_imports_a_paper() -> None:
    graph = import_graph(module_files())
    core = {m for m in graph if m != PAPERS and not m.startswith(f"{PAPERS}.")}
    offenders = {m: sorted(e for e in graph[m] if e.startswith(PAPERS)) for m in core}
    assert {m: e for m, e in offenders.items() if e} == {}


def test_spec_is_a_leaf_of_walkrepro() -> None:
    """The data model imports nothing that could import it back: only leaves of its own (the
    plugin registry, which says which papers exist, imports only the errors)."""
    graph = import_graph(module_files())
    assert graph["walkrepro.plugins"] <= {"walkrepro.errors"}
    assert graph["walkrepro.specs.models"] <= {
        "walkrepro",
        "walkrepro.plugins",
        "walkrepro.locations",
        "walkrepro.specs.yamlload",
        "walkrepro.specs.deviation",
        "walkrepro.errors",
        "walkrepro.specs.origin",
        "walkrepro.specs.sweeps",
        "walkrepro.specs.tags",
    }


#: The package's floors, from the ground up (docs/architecture.md): a module imports modules of
#: its own package or of a lower floor, never a higher floor's nor a neighbour's on its own.
FLOORS = (
    ("walkrepro._version", "walkrepro.errors", "walkrepro.locations"),
    ("walkrepro.plugins", "walkrepro.runtime"),
    ("walkrepro.log",),
    ("walkrepro.specs",),
    ("walkrepro.sim", "walkrepro.evaluation"),
    ("walkrepro.controllers", "walkrepro.present"),
    ("walkrepro.runs", PAPERS),
    ("walkrepro.studies",),
    ("walkrepro.publish",),
    ("walkrepro.api",),
    ("walkrepro.cli", "walkrepro"),
    ("walkrepro.__main__",),
)


def floor_of(module: str) -> tuple[int, str]:
    """The floor and the package (the longest listed prefix) that ``module`` stands in; a
    module no row names stands with the package root, on the floor of the command."""
    found = [
        (len(part), floor, part)
        for floor, parts in enumerate(FLOORS)
        for part in parts
        if module == part or module.startswith(f"{part}.")
    ]
    _, floor, part = max(found)
    return floor, part


def imports_up_or_across(graph: dict[str, set[str]]) -> list[str]:
    """Every import that reaches a higher floor, or another package of the same floor."""
    found = []
    for module, edges in sorted(graph.items()):
        for edge in sorted(edges):
            (mine, home), (theirs, there) = floor_of(module), floor_of(edge)
            if theirs > mine or (theirs == mine and there != home):
                found.append(f"{module} -> {edge}")
    return found


def test_imports_run_down_the_floors() -> None:
    """Data flows spec -> sim -> log -> evaluation -> presentation, and each package imports
    only what stands below it: no import climbs back up a floor or crosses to a neighbour."""
    assert imports_up_or_across(import_graph(module_files())) == []


def test_the_floor_check_sees_an_import_up_and_across() -> None:
    """The checker itself: the log importing the simulation climbs; the simulation importing
    the evaluation crosses; a run importing the simulation, or the log itself, does neither."""
    graph = {
        "walkrepro.log.record": {"walkrepro.sim.robot", "walkrepro.log.signals"},
        "walkrepro.sim.robot": {"walkrepro.evaluation.metrics"},
        "walkrepro.runs.runner": {"walkrepro.sim.robot"},
    }
    assert imports_up_or_across(graph) == [
        "walkrepro.log.record -> walkrepro.sim.robot",
        "walkrepro.sim.robot -> walkrepro.evaluation.metrics",
    ]


@pytest.mark.parametrize(
    ("sources", "expected"),
    [
        (
            {"a": "from pkg import b\n", "b": "def f():\n    from pkg import a\n"},
            [["pkg.a", "pkg.b"]],
        ),
        (
            {
                "a": "from pkg import b\n",
                "b": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg import a\n",
            },
            [],
        ),
        ({"__init__": "from pkg import a\n", "a": "from pkg import b\n", "b": "X = 1\n"}, []),
        ({"__init__": "X = 1\n", "a": "from pkg import X\n", "b": "from pkg.a import f\n"}, []),
    ],
)
def test_the_graph_sees_a_circle_through_a_function_and_not_through_type_checking(
    tmp_path: Path, sources: dict[str, str], expected: list[list[str]]
) -> None:
    """The checker itself: a circle closed by an import inside a function counts; one closed
    only for the type checker does not; a package gathering its submodules is no circle."""
    package = tmp_path / "pkg"
    package.mkdir()
    (package / "__init__.py").write_text(sources.get("__init__", ""))
    for name, text in sources.items():
        if name != "__init__":
            (package / f"{name}.py").write_text(text)
    assert cycles(import_graph(module_files(package))) == expected
