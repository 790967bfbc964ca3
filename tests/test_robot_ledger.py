"""The robots' provenance ledgers: robots/<robot>/parameters.yaml, and robots/build_models.py
with its builders (robots/builders/)."""

from __future__ import annotations

import ast
import importlib.util
import re
import sys
from pathlib import Path
from types import ModuleType

import pytest

from walkrepro import ROBOTS_DIR

BUILD_MODELS = ROBOTS_DIR / "build_models.py"
#: The script and every builder module it runs: where a physical literal must not hide.
BUILDER_FILES = (BUILD_MODELS, *sorted((ROBOTS_DIR / "builders").glob("*.py")))
ROBOTS = sorted(p.parent.name for p in ROBOTS_DIR.glob("*/robot.xml"))

#: Numeric literals build_models.py may hold anywhere: structural, not physical.
STRUCTURAL = {0, 1, 2, 0.5}
#: Further literals allowed in one function only (by qualified name), each with its reason.
ALLOWED_IN = {
    "Shape.own_inertia": {3, 4, 5, 8, 12},  # the solids' inertia formulas (m/12, 2/5, 4/3, 3/8)
    "Shape.rotation": {3, 0.9},  # 3 x 3 identity; a helper axis not parallel to the segment
    "composite_inertia": {3},  # 3 x 3 tensors
    "preload_springs": {3, 1e-6, 1e-9},  # 3 x nv Jacobians; equilibrium assertions
    "solve_home": {1e-12, 1e-13},  # symmetry assertion; brentq tolerance
    "fmt": {6, 1e-12},  # significant digits; round-off of zero
    "fvec": {6},  # significant digits
    "dyros_leg_dims": {3},  # x, y, z per link in the flat list leg_link_coms
    "build_xml": {10},  # keyframe digits
    "body_element": {6, 10},  # digits of derived inertials; of a source's (written in full)
    "format_ledger_value": {10},  # README table digits
}
#: Strings made only of numbers that build_models.py may hold: colours, the site marker size,
#: unit gains (ctrl is the torque) and the text of zero.
ALLOWED_STRINGS = {
    "0",
    "-0",
    "1",
    "0.01",
    "0.15 0.15 0.15 1",
    "0.75 0.15 0.15 1",
    "0.2 0.35 0.7 1",
    "0.25 0.55 0.3 1",
}
NUMERIC_STRING = re.compile(
    r"^\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?(\s+[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?)*\s*$"
)


def build_models_module() -> ModuleType:
    spec = importlib.util.spec_from_file_location("build_models", BUILD_MODELS)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses resolve annotations through sys.modules
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def bm() -> ModuleType:
    return build_models_module()


def physical_literals(source: str) -> list[tuple[int, str, object]]:
    """(line, function, value) of every numeric literal in ``source`` that is not allowed.

    Not counted: subscripts and slice bounds, the length argument of ``Ledger.vec``, a
    number compared with ``len(...)``, booleans, and the allowlists above.
    """
    tree = ast.parse(source)
    parents: dict[ast.AST, ast.AST] = {}
    scope: dict[ast.AST, str] = {}

    def walk(node: ast.AST, qual: list[str]) -> None:
        for child in ast.iter_child_nodes(node):
            parents[child] = node
            inner = qual
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                inner = [*qual, child.name]
            scope[child] = ".".join(inner)
            walk(child, inner)

    walk(tree, [])

    def exempt(node: ast.Constant) -> bool:
        parent = parents.get(node)
        if isinstance(parent, ast.UnaryOp):  # -1 is the literal 1
            node, parent = parent, parents.get(parent)  # type: ignore[assignment]
        if isinstance(parent, ast.Slice):
            return True
        if isinstance(parent, ast.Subscript) and parent.slice is node:
            return True
        if (
            isinstance(parent, ast.Call)
            and isinstance(parent.func, ast.Attribute)
            and parent.func.attr == "vec"
            and node in parent.args[1:]
        ):
            return True
        if isinstance(parent, ast.Compare):
            sides = [parent.left, *parent.comparators]
            return any(
                isinstance(s, ast.Call) and isinstance(s.func, ast.Name) and s.func.id == "len"
                for s in sides
            )
        return False

    found = []
    for node, where in scope.items():
        if not isinstance(node, ast.Constant) or isinstance(node.value, bool):
            continue
        value = node.value
        if isinstance(value, str):
            if NUMERIC_STRING.match(value) and value not in ALLOWED_STRINGS:
                found.append((node.lineno, where, value))
            continue
        if not isinstance(value, int | float) or exempt(node):
            continue
        if value in STRUCTURAL or value in ALLOWED_IN.get(where, set()):
            continue
        found.append((node.lineno, where, value))
    return sorted(found, key=lambda f: f[0])


def write_ledger(directory: Path, robot: str, text: str) -> Path:
    (directory / robot).mkdir(parents=True, exist_ok=True)
    path = directory / robot / "parameters.yaml"
    path.write_text(text)
    return path


# ---- the ledgers ------------------------------------------------------------------------


def test_every_robot_has_a_ledger() -> None:
    """Every robot directory with a robot.xml has a parameters.yaml, and build_models builds each."""
    assert ROBOTS
    for robot in ROBOTS:
        assert (ROBOTS_DIR / robot / "parameters.yaml").is_file(), robot
    assert sorted(build_models_module().BUILDERS) == ROBOTS


@pytest.mark.parametrize("robot", ROBOTS)
def test_every_entry_has_a_valid_class_and_a_source(bm: ModuleType, robot: str) -> None:
    """Each entry has value, unit, a class among the four, a non-empty source, and the top-level shape."""
    data = bm.read_ledger_file(ROBOTS_DIR / robot / "parameters.yaml")
    assert data["robot"] == robot
    for name, entry in data["parameters"].items():
        assert entry["class"] in ("paper", "source", "assumed", "calibrated"), name
        assert entry["source"].strip() and isinstance(entry["unit"], str), name
        assert re.fullmatch(r"[a-z][a-z0-9_]*", name), name
        if "source_value" in entry:
            assert entry["source_value"]["source"].strip(), name


@pytest.mark.parametrize("robot", ROBOTS)
def test_every_entry_sets_a_number_of_its_robot(bm: ModuleType, robot: str) -> None:
    """Building the robot reads every entry of its resolved ledger (own and inherited)."""
    design = bm.BUILDERS[robot]()
    assert design.ledger.robot == robot
    assert design.ledger.unused() == [], f"{robot}: entries no number uses"


def test_a_variant_replaces_and_inherits(bm: ModuleType) -> None:
    """A variant's entry replaces its parent's and the others come from the parent's file."""
    ledger = bm.load_ledger("dyros_red_actuated_9_9")
    assert ledger.files["friction"].parent.name == "dyros_red_actuated_9_9"
    assert ledger.files["armature"].parent.name == "dyros_red_armature"
    assert ledger.files["thigh"].parent.name == "dyros_red"
    assert ledger.entries["friction"]["value"]["knee"] == 9.9
    assert bm.load_ledger("dyros_red").entries["armature"]["value"] == 0.0


def test_no_physical_literal_left_in_build_models() -> None:
    """build_models.py and its builders hold no numeric literal that sets physics outside the
    ledgers."""
    assert len(BUILDER_FILES) > 1, "the builders' modules are not where the check looks"
    found = [
        (path.name, *hit) for path in BUILDER_FILES for hit in physical_literals(path.read_text())
    ]
    assert not found, f"literals outside the ledger (file, line, function, value): {found}"


def test_the_literal_check_finds_a_physical_number() -> None:
    """The AST check flags a mass, a size and a numeric attribute string, not indices or 0/1/2."""
    snippet = (
        "def build_x(p):\n"
        "    dims = p.vec('shape', 3)\n"
        "    first = dims[3] if len(dims) == 4 else 0\n"
        "    a = Shape('box', 8.0, (0.1, dims[1], 2 * first), (0, 0, -1))\n"
        "    attrs = {'friction': '1 0.005 0.0001', 'gear': '1'}\n"
        "    return a, attrs\n"
    )
    assert physical_literals(snippet) == [
        (4, "build_x", 8.0),
        (4, "build_x", 0.1),
        (5, "build_x", "1 0.005 0.0001"),
    ]


# ---- the validator ----------------------------------------------------------------------


GOOD = """robot: {robot}
inherits: {parent}
parameters:
  thigh:
    value: 0.35
    unit: m
    class: {cls}
    source: "a document"
    description: hip pitch axis to knee axis
"""


def test_a_bad_class_names_file_and_entry(bm: ModuleType, tmp_path: Path) -> None:
    """A ledger entry whose class is not one of the four raises, naming the file and the entry."""
    path = write_ledger(tmp_path, "toy", GOOD.format(robot="toy", parent="null", cls="guessed"))
    with pytest.raises(bm.LedgerError) as info:
        bm.load_ledger("toy", tmp_path)
    assert str(path) in str(info.value)
    assert "parameters.thigh" in str(info.value) and "guessed" in str(info.value)
    write_ledger(tmp_path, "toy", GOOD.format(robot="toy", parent="null", cls="assumed"))
    assert bm.load_ledger("toy", tmp_path)["thigh"] == 0.35


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ("    value: 0.35\n    unit: m\n    class: paper\n", "missing source"),
        ('    value: 0.35\n    unit: m\n    class: paper\n    source: " "\n', "source is empty"),
        ('    value: "0.35"\n    unit: m\n    class: paper\n    source: x\n', "value must be"),
        ("    value: 0.35\n    unit: m\n    class: paper\n    source: x\n    note: y\n", "note"),
    ],
)
def test_a_malformed_entry_is_refused(
    bm: ModuleType, tmp_path: Path, entry: str, message: str
) -> None:
    """A missing field, an empty source, a string value or an unknown field raises, naming the entry."""
    write_ledger(tmp_path, "toy", f"robot: toy\ninherits: null\nparameters:\n  thigh:\n{entry}")
    with pytest.raises(bm.LedgerError, match=f"parameters.thigh: .*{message}"):
        bm.load_ledger("toy", tmp_path)


def test_inherits_follows_the_chain_and_refuses_a_cycle(bm: ModuleType, tmp_path: Path) -> None:
    """A child's entries replace its parent's; a cycle of inherits is an error."""
    write_ledger(tmp_path, "base", GOOD.format(robot="base", parent="null", cls="paper"))
    write_ledger(tmp_path, "child", GOOD.format(robot="child", parent="base", cls="calibrated"))
    ledger = bm.load_ledger("child", tmp_path)
    assert ledger.entries["thigh"]["class"] == "calibrated"
    write_ledger(tmp_path, "base", GOOD.format(robot="base", parent="child", cls="paper"))
    with pytest.raises(bm.LedgerError, match="cycle"):
        bm.load_ledger("child", tmp_path)


def test_an_unread_entry_is_reported(bm: ModuleType) -> None:
    """The loader records the entries read, so an entry no number uses is listed as unused."""
    ledger = bm.load_ledger("coman")
    ledger.num("thigh")
    assert "thigh" not in ledger.unused() and "shank" in ledger.unused()


# ---- the READMEs ------------------------------------------------------------------------


@pytest.mark.parametrize("robot", ROBOTS)
def test_readme_block_is_current(bm: ModuleType, robot: str) -> None:
    """Each robot README's parameter block is what the ledger generates now."""
    path, text = bm.readme_text(robot)
    assert path.read_text() == text, f"stale {path} (run python robots/build_models.py --readme)"
    block = text[text.index(bm.README_BEGIN) : text.index(bm.README_END)]
    assert "| name | value | unit | class | source |" in block


def test_a_stale_readme_block_fails_the_check(bm: ModuleType, tmp_path: Path) -> None:
    """A README block that differs from its ledger is stale; one without the markers is an error."""
    robots = tmp_path / "robots"
    write_ledger(robots, "toy", GOOD.format(robot="toy", parent="null", cls="paper"))
    readme = robots / "toy" / "README.md"
    readme.write_text(f"# toy\n\nprose\n\n{bm.README_BEGIN}\nold\n{bm.README_END}\n")
    _, text = bm.readme_text("toy", robots)
    assert text != readme.read_text() and "| `thigh` | 0.35 | m | paper |" in text
    readme.write_text(text)
    assert bm.readme_text("toy", robots)[1] == readme.read_text()
    readme.write_text("# toy\n")
    with pytest.raises(bm.LedgerError, match="README.md"):
        bm.readme_text("toy", robots)


def test_every_shipped_ledger_number_is_in_its_units_range() -> None:
    """Every robot's ledger loads through the model that checks each unit's physical range."""
    from walkrepro.publish.ledger import robot_ledger

    robots = [p.name for p in ROBOTS_DIR.iterdir() if (p / "parameters.yaml").is_file()]
    assert len(robots) >= 5
    for robot in robots:
        assert robot_ledger(robot)


@pytest.mark.parametrize(
    ("unit", "value", "interval"),
    [("kg", -3.0, "[1e-06, 1000]"), ("rad", 7.0, "[-3.14159, 3.14159]"), ("s", 0.0, "[1e-06, 1]")],
)
def test_an_out_of_range_ledger_number_names_file_field_and_range(
    tmp_path: Path, unit: str, value: float, interval: str
) -> None:
    """A mass, angle or time outside its unit's range is a clean error with file, field and
    range."""
    from walkrepro.errors import SpecError
    from walkrepro.publish.ledger import robot_ledger

    (tmp_path / "bot").mkdir()
    (tmp_path / "bot" / "parameters.yaml").write_text(
        "robot: bot\nparameters:\n"
        f"  thing:\n    value: {value}\n    unit: {unit}\n    class: assumed\n"
        "    source: a test\n"
    )
    with pytest.raises(SpecError) as err:
        robot_ledger("bot", tmp_path)
    message = str(err.value)
    assert "parameters.yaml" in message and "parameters.thing" in message
    assert f"must be in {interval}" in message, message
