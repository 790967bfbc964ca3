"""Fuzz: seeded mutations of every shipped spec, and bad ``--set`` values, never end in a traceback.

Every case either fails validation with a one-paragraph user error (exit code 2 on the CLI)
or is a valid spec; the valid ones (up to :data:`MAX_RUNS`) are then run for a few control
ticks through the CLI, which must finish without a traceback. Cases are a pure function of
:data:`SEED`, so a failure names a case that can be replayed (``FuzzCase.name``).

Input classes: wrong types (string, boolean, list, mapping, null), NaN, ±inf, huge and
negative numbers, missing fields, unknown fields, duplicate YAML keys, bad names, and a few
malformed files (invalid UTF-8, binary, deep nesting, alias bombs and loops, tabs, empty,
not a mapping).
"""

from __future__ import annotations

import copy
import random
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml
from typer.testing import CliRunner

from walkrepro import EXPERIMENTS_DIR
from walkrepro.cli import app
from walkrepro.errors import WalkreproError
from walkrepro.runs.resolve import resolve_spec
from walkrepro.specs import yamlload
from walkrepro.specs.files import load_spec

#: Seed of every mutation; change it to explore other cases.
SEED = 32
#: Mutations per shipped spec (43 specs: 344 cases, plus the malformed files).
PER_SPEC = 8
#: Random ``--set`` cases on top of the hand-written ones.
RANDOM_SETS = 40
#: At most this many valid cases of each test are run (the rest are only validated).
MAX_RUNS = 20
#: Simulated time of a fuzz run [s]: a few control ticks.
RUN_DURATION = 0.01

BAD_NUMBERS: tuple[Any, ...] = (
    float("nan"),
    float("inf"),
    float("-inf"),
    1e12,
    -1e12,
    1e308,
    -1.0,
    0,
)
BAD_TYPES: tuple[Any, ...] = ("abc", True, False, [1, 2], {"a": 1}, None, "")
BAD_NAMES: tuple[str, ...] = (
    "",
    "no_such_name",
    "x" * 300,
    "ロボット",
    "../../etc/passwd",
    " pelvis",
)
#: Fields whose string value is a name looked up in a registry or the model.
NAME_KEYS = {"robot", "type", "body", "frame", "metric", "name", "key", "experiment"}


@dataclass(frozen=True)
class FuzzCase:
    """One fuzz input.

    Attributes:
        name: stable id, e.g. ``walk_0p1-3-nan`` (experiment, index, mutation kind).
        kind: the input class (``nan``, ``inf``, ``huge``, ``type``, ``missing``, ...).
        text: the spec file's bytes, or None to use the shipped experiment itself.
        experiment: the shipped experiment mutated.
        overrides: ``--set`` strings.
    """

    name: str
    kind: str
    text: bytes | None
    experiment: str
    overrides: tuple[str, ...] = ()

    @property
    def must_fail(self) -> bool:
        """Whether the case must be rejected: a non-finite number or a duplicate key."""
        return self.kind in ("nan", "inf", "duplicate", "utf8", "deep")


def _leaves(data: Any, path: tuple[Any, ...] = ()) -> Iterator[tuple[tuple[Any, ...], Any]]:
    """Every (path, value) of the parsed spec, containers included."""
    yield path, data
    if isinstance(data, dict):
        for key, value in data.items():
            yield from _leaves(value, (*path, key))
    elif isinstance(data, list):
        for i, value in enumerate(data):
            yield from _leaves(value, (*path, i))


def _set_at(data: Any, path: tuple[Any, ...], value: Any) -> None:
    node = data
    for part in path[:-1]:
        node = node[part]
    node[path[-1]] = value


def _delete_at(data: Any, path: tuple[Any, ...]) -> None:
    node = data
    for part in path[:-1]:
        node = node[part]
    del node[path[-1]]


def _dump(data: Any) -> bytes:
    return yaml.safe_dump(data, sort_keys=False, allow_unicode=True).encode()


def _mutate(rng: random.Random, name: str, text: str, index: int) -> FuzzCase:
    """One seeded mutation of a shipped spec (``text``)."""
    data = yamlload.load(text)
    leaves = list(_leaves(data))
    numbers = [
        (p, v) for p, v in leaves if isinstance(v, int | float) and not isinstance(v, bool) and p
    ]
    names = [(p, v) for p, v in leaves if p and isinstance(v, str) and p[-1] in NAME_KEYS]
    mappings = [p for p, v in leaves if isinstance(v, dict)]
    kind = rng.choice(("number", "number", "type", "missing", "unknown", "duplicate", "name"))
    mutated = copy.deepcopy(data)
    if kind == "number" and numbers:
        path, _ = rng.choice(numbers)
        value = rng.choice(BAD_NUMBERS)
        _set_at(mutated, path, value)
        kind = "nan" if value != value else "inf" if abs(value) == float("inf") else "bad_number"
    elif kind == "type":
        path, _ = rng.choice([(p, v) for p, v in leaves if p])
        _set_at(mutated, path, copy.deepcopy(rng.choice(BAD_TYPES)))
    elif kind == "missing":
        path, _ = rng.choice([(p, v) for p, v in leaves if p])
        _delete_at(mutated, path)
    elif kind == "unknown":
        path = rng.choice(mappings)
        node = mutated
        for part in path:
            node = node[part]
        node[rng.choice(("bogus_field", "durration", "Robot", "force_"))] = rng.choice((1, "x"))
    elif kind == "duplicate":
        lines = text.splitlines(keepends=True)
        i = rng.choice(_key_lines(text))
        lines.insert(i + 1, lines[i])
        return FuzzCase(f"{name}-{index}-duplicate", "duplicate", "".join(lines).encode(), name)
    elif kind == "name" and names:
        path, _ = rng.choice(names)
        _set_at(mutated, path, rng.choice(BAD_NAMES))
    else:  # nothing of that kind in this spec: drop a top-level field instead
        kind = "missing"
        del mutated[rng.choice(list(mutated))]
    return FuzzCase(f"{name}-{index}-{kind}", kind, _dump(mutated), name)


def _key_lines(text: str) -> list[int]:
    """0-based lines holding a whole ``key: value`` of a block mapping (value on that line)."""
    out = []
    stack = [yaml.compose(text, Loader=yamlload.Loader)]
    while stack:
        node = stack.pop()
        if isinstance(node, yaml.MappingNode):
            for key, value in node.value:
                one_line = value.start_mark.line == value.end_mark.line == key.start_mark.line
                if not node.flow_style and isinstance(value, yaml.ScalarNode) and one_line:
                    out.append(key.start_mark.line)
                stack.append(value)
        elif isinstance(node, yaml.SequenceNode):
            stack.extend(node.value)
    return sorted(out)


def _malformed(text: str, name: str) -> list[FuzzCase]:
    """Files that are not specs at all."""
    deep_list = "[" * 5000 + "]" * 5000
    deep_map = "".join(f"{' ' * i}k{i}:\n" for i in range(600)) + " " * 600 + "k: 1\n"
    return [
        FuzzCase("utf8", "utf8", text.encode()[:200] + b"\xff\xfe\xc3(\n" + text.encode(), name),
        FuzzCase("deep_list", "deep", f"{text}\nextra: {deep_list}\n".encode(), name),
        FuzzCase("deep_map", "deep", (text + "\n" + deep_map).encode(), name),
        FuzzCase(
            "deep_params",
            "deep",
            text.replace("params:", f"params: {{x: {deep_list}}}\n  old:", 1).encode(),
            name,
        ),
        FuzzCase("empty", "malformed", b"", name),
        FuzzCase("list", "malformed", b"- 1\n- 2\n", name),
        FuzzCase("scalar", "malformed", b"42\n", name),
        FuzzCase("binary", "malformed", bytes(range(256)), name),
        FuzzCase("tabs", "malformed", text.replace("  ", "\t", 3).encode(), name),
        FuzzCase("alias_bomb", "malformed", (text + _alias_bomb()).encode(), name),
        FuzzCase(
            "alias_loop",
            "deep",
            text.replace("params:", "params: &p [*p]\n  old:", 1).encode(),
            name,
        ),
    ]


def _alias_bomb() -> str:
    """YAML whose aliases expand to 9**9 values (a "billion laughs")."""
    levels = ["bomb0: &b0 [1, 1, 1, 1, 1, 1, 1, 1, 1]"]
    levels += [f"bomb{i}: &b{i} [{', '.join([f'*b{i - 1}'] * 9)}]" for i in range(1, 9)]
    return "\n" + "\n".join(levels) + "\n"


def spec_cases() -> list[FuzzCase]:
    """Every spec-file fuzz case, in a fixed order."""
    rng = random.Random(SEED)
    cases = []
    paths = sorted(EXPERIMENTS_DIR.glob("*.yaml"))
    for path in paths:
        text = path.read_text()
        cases.extend(_mutate(rng, path.stem, text, i) for i in range(PER_SPEC))
    cases.extend(_malformed(paths[0].read_text(), paths[0].stem))
    return cases


#: Hand-written ``--set`` cases: (experiment, override).
SET_CASES: tuple[tuple[str, str], ...] = (
    ("forward_walk", "sim.duration=.inf"),
    ("forward_walk", "sim.duration=-.inf"),
    ("forward_walk", "sim.duration=.nan"),
    ("forward_walk", "sim.duration=1e12"),
    ("forward_walk", "sim.duration=1e308"),
    ("forward_walk", "sim.duration=true"),
    ("forward_walk", "sim.duration=abc"),
    ("forward_walk", "sim.duration=[1, 2]"),
    ("forward_walk", "sim.duration.a.b=1"),
    ("forward_walk", "sim.duration.0=1"),
    ("forward_walk", "sim.control_period=.inf"),
    ("forward_walk", "sim.control_period=1e-300"),
    ("forward_walk", "sim.timestep=1e-12"),
    ("forward_walk", "sim.timestep=0"),
    ("forward_walk", "sim.seed=-1"),
    ("forward_walk", "sim.seed=1e30"),
    ("forward_walk", "sim.seed=1.5"),
    ("forward_walk", "sim.seed=true"),
    ("walk_0p1", "controller.params.speed=.nan"),
    ("walk_0p1", "controller.params.speed=.inf"),
    ("walk_0p1", "controller.params.speed=1e12"),
    ("walk_0p1", "controller.params.speed=nan"),
    ("walk_0p1", "controller.params.n_steps=1e30"),
    ("forward_walk", "world.floor_friction=1e12"),
    ("forward_walk", "world.floor_friction=.nan"),
    ("forward_walk", "sensors.delay=1e12"),
    ("forward_walk", "sensors.delay=0.0013"),
    ("forward_walk", "sensors.imu_gyro_noise=.inf"),
    ("forward_walk", "sensors.joint_backlash={'*knee*': .nan}"),
    ("obstacle_4cm", "world.obstacles.0.size=[.inf, .inf, .inf]"),
    ("obstacle_4cm", "world.obstacles.0.position.0=.nan"),
    ("obstacle_4cm", "world.obstacles.0.tilt_x_deg=.nan"),
    ("obstacle_4cm", "world.obstacles.0.size=[1, 1, 1]"),
    ("obstacle_4cm", "world.obstacles.0.position=[0, 0, 0]"),
    ("obstacle_4cm", "world.obstacles.0.mass=1e300"),
    ("obstacle_4cm", "world.obstacles.7.size.0=1"),
    ("push_recovery_forward", "disturbances.0.force=[1e9, 0, 0]"),
    ("push_recovery_forward", "disturbances.0.force.0=.nan"),
    ("push_recovery_forward", "disturbances.0.force.0=-.inf"),
    ("push_recovery_forward", "disturbances.0.torque=[0, 0, 1e9]"),
    ("push_recovery_forward", "disturbances.0.start=1e12"),
    ("push_recovery_forward", "disturbances.0.duration=.inf"),
    ("in_place", "actuators.position_gain={'*': .nan}"),
    ("in_place", "actuators.position_gain={'*': 1e30}"),
    ("in_place", "expect.0.value=.nan"),
    ("in_place", "expect.0.value=[.nan, 1]"),
    ("in_place", "sim=1"),
    ("in_place", "sim="),
    ("in_place", "=1"),
    ("in_place", "sim.duration"),
    ("in_place", "..=1"),
    ("in_place", "sim..duration=1"),
    ("in_place", "0=1"),
    ("in_place", "expect.99.value=1"),
    ("in_place", "expect.x.value=1"),
    ("in_place", "robot=no_such_robot"),
    ("in_place", "robot=[dyros_red]"),
    ("in_place", "name=../../x"),
    ("in_place", "sim.duration=" + "[" * 5000 + "]" * 5000),
    ("in_place", "sim.duration={a: [1, {b: 2}]}"),
)


def set_cases() -> list[FuzzCase]:
    """The hand-written ``--set`` cases plus seeded random ones on shipped fields."""
    cases = [
        FuzzCase(f"set-{i}-{experiment}", _set_kind(item), None, experiment, (item,))
        for i, (experiment, item) in enumerate(SET_CASES)
    ]
    rng = random.Random(SEED + 1)
    paths = sorted(EXPERIMENTS_DIR.glob("*.yaml"))
    for i in range(RANDOM_SETS):
        path = rng.choice(paths)
        data = yamlload.load(path.read_text())
        fields = [p for p, v in _leaves(data) if p and not isinstance(v, dict | list)]
        field = ".".join(str(p) for p in rng.choice(fields))
        value = rng.choice((".nan", ".inf", "-.inf", "1e12", "-1e12", "true", "abc", "[1]", "{}"))
        item = f"{field}={value}"
        cases.append(
            FuzzCase(f"set-random-{i}-{path.stem}", _set_kind(item), None, path.stem, (item,))
        )
    return cases


def _set_kind(item: str) -> str:
    """``nan``/``inf`` for an override that sets a non-finite number, ``deep`` for deep
    nesting, else ``set``."""
    value = item.partition("=")[2].lower()
    if "nan" in value:
        return "nan"
    if "inf" in value:
        return "inf"
    return "deep" if value.startswith("[[[[") else "set"


def validate(case: FuzzCase, tmp_path: Path) -> str:
    """``"ok"`` if the case resolves, ``"error"`` for a user error; other exceptions propagate."""
    target: str = case.experiment
    if case.text is not None:
        path = tmp_path / f"{case.experiment}.yaml"
        path.write_bytes(case.text)
        target = str(path)
    try:
        resolve_spec(load_spec(target, case.overrides))
    except WalkreproError as exc:
        message = str(exc)
        assert message and "Traceback" not in message, case.name
        return "error"
    return "ok"


SPEC_CASES = spec_cases()
ALL_SET_CASES = set_cases()


def test_enough_cases() -> None:
    """The fuzz covers at least 300 spec mutations and 30 ``--set`` values."""
    assert len(SPEC_CASES) >= 300
    assert len(ALL_SET_CASES) >= 30
    kinds = {c.kind for c in SPEC_CASES}
    assert {"nan", "inf", "bad_number", "type", "missing", "unknown", "duplicate", "name"} <= kinds


def _run_cli(case: FuzzCase, tmp_path: Path) -> None:
    """Run a valid case for :data:`RUN_DURATION` through the CLI: exit 0 or 1, no traceback."""
    target = case.experiment
    if case.text is not None:
        target = str(tmp_path / f"{case.experiment}.yaml")
    loaded = load_spec(target, case.overrides)
    shorten = [f"sim.duration={RUN_DURATION}"]
    # Disturbances must start inside the shortened run.
    shorten += [f"disturbances.{i}.start=0.0" for i in range(len(loaded.spec.disturbances))]
    args = ["run", target, "--out", str(tmp_path / "runs"), "--no-figures"]
    for item in (*case.overrides, *shorten):
        args += ["--set", item]
    result = CliRunner().invoke(app, args)
    assert "Traceback" not in result.output, f"{case.name}:\n{result.output}"
    assert result.exception is None or isinstance(result.exception, SystemExit), (
        f"{case.name}: {result.exception!r}"
    )
    assert result.exit_code in (0, 1), f"{case.name}: exit {result.exit_code}\n{result.output}"


def _check_cases(cases: list[FuzzCase], tmp_path: Path) -> None:
    """Validate every case (refused or valid, never another exception; a non-finite number,
    duplicate key or deep nesting always refused), then run up to :data:`MAX_RUNS` valid ones."""
    valid = []
    for case in cases:
        outcome = validate(case, tmp_path / case.name)
        if case.must_fail:
            assert outcome == "error", f"{case.name}: accepted, must be refused"
        if outcome == "ok":
            valid.append(case)
    assert valid, "no case validated: the run phase would test nothing"
    # Evenly spread over the experiments, so every robot and controller gets runs.
    for case in valid[:: max(1, len(valid) // MAX_RUNS)][:MAX_RUNS]:
        _run_cli(case, tmp_path / case.name)


@pytest.mark.slow
def test_spec_mutations_never_raise_a_traceback(tmp_path: Path) -> None:
    """Every spec mutation is either refused with a user error or runs cleanly."""
    for case in SPEC_CASES:
        (tmp_path / case.name).mkdir()
    _check_cases(SPEC_CASES, tmp_path)


@pytest.mark.slow
def test_set_values_never_raise_a_traceback(tmp_path: Path) -> None:
    """Every bad ``--set`` value is refused with a user error, or the run is clean."""
    for case in ALL_SET_CASES:
        (tmp_path / case.name).mkdir()
    _check_cases(ALL_SET_CASES, tmp_path)


def test_errors_reach_the_cli_as_exit_2(tmp_path: Path) -> None:
    """A sample of refused cases gives exit code 2 on the CLI and no traceback."""
    sample = [c for c in (*SPEC_CASES, *ALL_SET_CASES) if c.must_fail][::15]
    assert len(sample) >= 5
    for case in sample:
        target = case.experiment
        if case.text is not None:
            path = tmp_path / f"{case.name}.yaml"
            path.write_bytes(case.text)
            target = str(path)
        args = ["run", target, "--out", str(tmp_path / "runs")]
        for item in case.overrides:
            args += ["--set", item]
        result = CliRunner().invoke(app, args)
        assert result.exit_code == 2, f"{case.name}:\n{result.output}"
        assert "Traceback" not in result.output


# --------------------------------------------------------------------------------------
# Physical ranges of every controller parameter


def _numeric_leaves(model: type, prefix: tuple[Any, ...] = ()) -> Iterator[tuple[Any, ...]]:
    """The path of every number a controller's ``Params`` model holds: a numeric field, or
    each item of a tuple of numbers (booleans and names are not numbers)."""
    import types
    import typing

    for name, field in model.model_fields.items():
        annotation = field.annotation
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        if typing.get_origin(annotation) in (typing.Union, types.UnionType) and len(args) == 1:
            annotation = args[0]
        if annotation in (int, float):
            yield (*prefix, name)
        elif typing.get_origin(annotation) is tuple:
            for i, item in enumerate(typing.get_args(annotation)):
                if typing.get_origin(item) is typing.Annotated:
                    item = typing.get_args(item)[0]
                assert item in (int, float), f"{model.__name__}.{name}: item {i} is {item}"
                yield (*prefix, name, i)
        else:
            assert annotation in (bool, str) or typing.get_origin(annotation) is typing.Literal, (
                f"{model.__name__}.{name}: {annotation} is neither a number nor a choice"
            )


def _params_models() -> dict[str, type]:
    """Every registered controller's parameter model, by ``controller.type``."""
    from walkrepro.controllers import controller_class, controller_names

    return {name: controller_class(name).Params for name in controller_names()}


def _experiment_of(controller: str) -> str:
    """A shipped experiment that runs ``controller``."""
    for path in sorted(EXPERIMENTS_DIR.glob("*.yaml")):
        if yamlload.load(path.read_text())["controller"]["type"] == controller:
            return path.stem
    raise AssertionError(f"no shipped experiment runs {controller!r}")


def test_every_controller_parameter_has_a_physical_range() -> None:
    """Every number of every controller's parameters has a lower and an upper bound."""
    from walkrepro.specs.models import field_bounds

    models = _params_models()
    assert {"efsm", "timeprojection", "qpimpedance", "posture"} <= set(models)
    unbounded = []
    count = 0
    for name, model in models.items():
        for path in _numeric_leaves(model):
            count += 1
            bounds = field_bounds(model, path)
            if bounds is None or bounds.lower is None or bounds.upper is None:
                unbounded.append(f"{name}: {'.'.join(map(str, path))} {bounds}")
    assert count > 80, count
    assert not unbounded, "numbers without a two-sided range:\n" + "\n".join(unbounded)


def _outside(bounds: Any, above: bool, integer: bool) -> float:
    """A value just outside ``bounds``: past the upper bound (``above``) or below the lower."""
    edge = bounds.upper if above else bounds.lower
    step = max(1.0, abs(edge))
    value = edge + step if above else edge - step
    return int(value) if integer else value


def test_out_of_range_parameters_are_clean_errors_naming_the_range() -> None:
    """Above its upper bound and below its lower one, every controller number is refused
    with a user error that names the field and its range."""
    from walkrepro.specs.models import field_bounds

    for controller, model in _params_models().items():
        experiment = _experiment_of(controller)
        defaults = model()
        for path in _numeric_leaves(model):
            bounds = field_bounds(model, path)
            assert bounds is not None
            field = model.model_fields[path[0]]
            integer = field.annotation is int or getattr(defaults, path[0]).__class__ is int
            for above in (True, False):
                value = _outside(bounds, above, integer)
                if len(path) == 2:  # one item of a tuple, the others as the defaults
                    default = getattr(defaults, path[0])  # None: an optional pair, say
                    size = sum(1 for q in _numeric_leaves(model) if q[0] == path[0])
                    items = list(default) if default is not None else [0.0] * size
                    items[path[1]] = value
                    item = f"controller.params.{path[0]}={items}"
                else:
                    item = f"controller.params.{path[0]}={value!r}"
                with pytest.raises(WalkreproError) as err:
                    resolve_spec(load_spec(experiment, (item,)))
                message = str(err.value)
                dotted = "controller.params." + ".".join(map(str, path))
                assert dotted in message, f"{item}: {message}"
                assert f"must be in {bounds.text}" in message, f"{item}: {message}"
                assert "Traceback" not in message


def test_stance_ankle_bias_of_1e9_is_refused_on_the_cli() -> None:
    """The issue's probe: ``--set controller.params.stance_ankle_bias=1e9`` exits 2 with
    the field and its range."""
    args = ["run", "in_place", "--set", "controller.params.stance_ankle_bias=1e9"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2, result.output
    assert "stance_ankle_bias" in result.output
    assert "[-0.2, 0.2]" in result.output
    assert "Traceback" not in result.output
