"""Spec loading: schema, line numbers in errors, --set overrides, name resolution."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from walkrepro import EXPERIMENTS_DIR
from walkrepro.errors import SpecError, UnknownNameError
from walkrepro.runs.resolve import resolve_spec
from walkrepro.specs.files import experiment_names, load_spec

GOOD = """\
name: tiny
description: a small valid spec
paper: {key: walkrepro}
robot: dyros_red
controller:
  type: posture
  params: {kp: 200}
sim:
  timestep: 0.0005
  control_period: 0.001
  duration: 0.5
disturbances:
  - name: shove
    body: pelvis
    force: [10, 0, 0]
    start: 0.1
    duration: 0.1
expect:
  - {metric: fell, op: "==", value: 0, source: test}
"""


def write(tmp_path: Path, text: str, name: str = "spec.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def error_of(tmp_path: Path, text: str, overrides: tuple[str, ...] = ()) -> str:
    path = write(tmp_path, text)
    with pytest.raises((SpecError, UnknownNameError)) as info:
        resolve_spec(load_spec(str(path), overrides))
    return str(info.value)


def test_valid_spec_loads_with_defaults(tmp_path: Path) -> None:
    """A valid spec loads, and unspecified sections take their defaults."""
    loaded = resolve_spec(load_spec(str(write(tmp_path, GOOD))))
    spec = loaded.spec
    assert spec.sim.substeps == 2
    assert spec.sim.n_steps == 1000
    assert spec.world.floor_friction == 1.0
    assert spec.controller.params["kp"] == 200
    assert spec.controller.params["kd"] == 20.0  # filled in by the controller's own model


def test_yaml_syntax_error_names_file_and_line(tmp_path: Path) -> None:
    """A YAML syntax error names the file and the line of the problem."""
    msg = error_of(tmp_path, GOOD.replace("  duration: 0.5", "  duration: [0.5"))
    assert "spec.yaml" in msg and "line 12" in msg and "YAML syntax error" in msg


def test_unknown_field_names_line_and_field(tmp_path: Path) -> None:
    """A misspelt field is rejected with its line and dotted path."""
    msg = error_of(tmp_path, GOOD.replace("  duration: 0.5", "  durration: 0.5"))
    assert "line 11" in msg and "sim.durration" in msg and "unknown field" in msg


def test_wrong_type_names_field_and_value(tmp_path: Path) -> None:
    """A value of the wrong type names the field and echoes the value."""
    msg = error_of(tmp_path, GOOD.replace("duration: 0.5", "duration: fast"))
    assert "line 11" in msg and "sim.duration" in msg and "'fast'" in msg


def test_negative_duration_rejected(tmp_path: Path) -> None:
    """A negative duration is rejected with the bound."""
    msg = error_of(tmp_path, GOOD.replace("duration: 0.5", "duration: -1"))
    assert "sim.duration" in msg and "greater than 0" in msg


def test_control_period_must_be_multiple_of_timestep(tmp_path: Path) -> None:
    """A control period that is not a whole multiple of the timestep is rejected."""
    msg = error_of(tmp_path, GOOD.replace("control_period: 0.001", "control_period: 0.0007"))
    assert "line 10" in msg and "sim.control_period" in msg and "multiple" in msg


def test_unknown_robot_lists_valid_robots(tmp_path: Path) -> None:
    """An unknown robot lists the robots that exist."""
    msg = error_of(tmp_path, GOOD.replace("robot: dyros_red", "robot: asimo"))
    assert "line 4" in msg and "'asimo'" in msg and "dyros_red" in msg and "coman" in msg


def test_unknown_body_lists_valid_bodies(tmp_path: Path) -> None:
    """An unknown disturbance body lists the robot's bodies."""
    msg = error_of(tmp_path, GOOD.replace("body: pelvis", "body: torsoo"))
    assert "line 14" in msg and "'torsoo'" in msg and "left_foot" in msg
    assert "Valid bodies:" in msg


def test_backlash_names_actuators_and_is_non_negative(tmp_path: Path) -> None:
    """sensors.joint_backlash keys must match an actuator (the error lists them), values >= 0."""
    msg = error_of(tmp_path, GOOD, ('sensors.joint_backlash={"*kneee": 0.01}',))
    assert "'*kneee'" in msg and "Valid actuators:" in msg
    msg = error_of(tmp_path, GOOD, ('sensors.joint_backlash={"*knee*": -0.01}',))
    assert "backlash must be in [0, 1]" in msg


def test_torque_lag_needs_filtered_actuators(tmp_path: Path) -> None:
    """actuators.torque_lag on a robot whose torques act without dynamics is an error naming
    the field; on dyros_red_actuated it is accepted, and an exponent-only number is a float."""
    msg = error_of(tmp_path, GOOD, ("actuators.torque_lag=0.002",))
    assert "actuators.torque_lag" in msg and "no torque-loop dynamics" in msg
    path = write(tmp_path, GOOD.replace("robot: dyros_red", "robot: dyros_red_actuated"))
    loaded = load_spec(path, ("actuators.torque_lag=5e-05", "actuators.friction_loss=1e-1"))
    resolve_spec(loaded)
    assert loaded.spec.actuators.torque_lag == 5e-05
    assert loaded.spec.actuators.friction_loss == 0.1
    msg = error_of(tmp_path, GOOD, ("actuators.friction_loss=-1",))
    assert "actuators.friction_loss" in msg


def test_unknown_metric_lists_valid_metrics(tmp_path: Path) -> None:
    """An unknown metric lists the registered metrics."""
    msg = error_of(tmp_path, GOOD.replace("metric: fell", "metric: fel"))
    assert "line 19" in msg and "'fel'" in msg and "pelvis_drift" in msg


def test_malformed_metric_argument_named_at_load(tmp_path: Path) -> None:
    """A metric argument the metric cannot read (a window that is not t0-t1) is a spec
    error naming file, line and field, before anything runs."""
    msg = error_of(tmp_path, GOOD.replace("metric: fell", "metric: mean_forward_speed:2-x"))
    assert "line 19" in msg and "expect.0.metric" in msg and "'2-x'" in msg and "t0-t1" in msg
    msg = error_of(tmp_path, GOOD.replace("metric: fell", "metric: footsteps:left"))
    assert "line 19" in msg and "left_foot, right_foot" in msg


def test_map_claim_metric_checked_at_load(tmp_path: Path) -> None:
    """A declared map's claim names a metric as an expectation does, checked the same way."""
    sweep = """sweeps:
  - name: m
    grid: {disturbances.0.start: "0.1,0.2"}
    claims:
      - {kind: everywhere, region: {metric: "REGION", op: ">", value: 0}, source: t}
"""
    msg = error_of(tmp_path, GOOD + sweep.replace("REGION", "mean_forward_speed:1-x"))
    assert "sweeps.0.claims.0.region.metric" in msg and "'1-x'" in msg
    msg = error_of(tmp_path, GOOD + sweep.replace("REGION", "fel"))
    assert "sweeps.0.claims.0.region.metric" in msg and "'fel'" in msg


@pytest.mark.parametrize("selector", ["where", "than"])
def test_map_claim_selector_names_a_grid_field(tmp_path: Path, selector: str) -> None:
    """A claim's selector on a field the grid does not vary would match no cell, and a claim
    over no cells holds whatever the map shows: it is a spec error naming file, line and
    field, and the grid's fields."""
    sweep = """sweeps:
  - name: m
    grid: {disturbances.0.start: "0.1,0.2", sim.seed: "0,1"}
    claims:
      - kind: paired
        region: {metric: fell, op: "<=", value: 1}
        where: {WHERE: 0}
        than: {THAN: 1}
        source: t
"""
    good = sweep.replace("WHERE", "sim.seed").replace("THAN", "sim.seed")
    typo = "sim.sed"
    bad = (
        good.replace("where: {sim.seed", f"where: {{{typo}")
        if selector == "where"
        else (good.replace("than: {sim.seed", f"than: {{{typo}"))
    )
    resolve_spec(load_spec(str(write(tmp_path, GOOD + good))))  # grid fields: it loads
    msg = error_of(tmp_path, GOOD + bad)
    assert f"sweeps.0.claims.0.{selector}" in msg and f"'{typo}'" in msg
    assert "disturbances.0.start, sim.seed" in msg


def test_unknown_controller_and_bad_param(tmp_path: Path) -> None:
    """Unknown controllers and invalid controller params are named precisely."""
    msg = error_of(tmp_path, GOOD.replace("type: posture", "type: mpc"))
    assert "line 6" in msg and "'mpc'" in msg and "posture" in msg
    msg = error_of(tmp_path, GOOD.replace("params: {kp: 200}", "params: {kp: -5}"))
    assert "controller.params.kp" in msg and "line 7" in msg


def test_missing_file_and_unknown_experiment(tmp_path: Path) -> None:
    """A missing file is named; an unknown experiment lists the shipped ones."""
    with pytest.raises(SpecError, match="no such spec file"):
        load_spec(str(tmp_path / "nope.yaml"))
    with pytest.raises(UnknownNameError) as info:
        load_spec("stand_asimo")
    assert "stand_dyros_red" in str(info.value)


def test_set_overrides_are_validated_like_the_file(tmp_path: Path) -> None:
    """--set changes a field, and a bad --set value is reported as coming from --set."""
    path = str(write(tmp_path, GOOD))
    spec = load_spec(path, ["controller.params.kp=50", "sim.duration=2", "expect.0.value=1"]).spec
    assert spec.controller.params["kp"] == 50 and spec.sim.duration == 2.0
    assert spec.expect[0].value == 1.0
    with pytest.raises(SpecError, match=r"sim\.duration \(set with --set\)"):
        load_spec(path, ["sim.duration=-3"])
    with pytest.raises(SpecError, match="FIELD=VALUE"):
        load_spec(path, ["sim.duration"])


def test_between_needs_two_values(tmp_path: Path) -> None:
    """'between' needs [low, high] and other operators a single number."""
    msg = error_of(tmp_path, GOOD.replace('op: "==", value: 0', "op: between, value: 3"))
    assert "between" in msg and "expect.0" in msg


def test_every_shipped_experiment_resolves() -> None:
    """Every spec in experiments/ validates and resolves against the registries."""
    names = experiment_names()
    assert "stand_dyros_red" in names
    for name in names:
        loaded = resolve_spec(load_spec(name))
        assert loaded.spec.name == name, "a spec's name must match its file name"


def test_resolved_spec_round_trips_through_yaml(tmp_path: Path) -> None:
    """The resolved spec written as YAML loads back to the same spec."""
    spec = resolve_spec(load_spec(str(write(tmp_path, GOOD)))).spec
    again = load_spec(str(write(tmp_path, spec.to_yaml(), "again.yaml"))).spec
    assert again == spec


def test_relative_expectation_must_name_a_shipped_experiment(tmp_path: Path) -> None:
    """relative_to names an experiment that exists, or the error lists the valid ones."""
    text = GOOD.replace(
        'expect:\n  - {metric: fell, op: "==", value: 0, source: test}',
        'expect:\n  - {metric: fell, op: "<=", relative_to: {experiment: no_such}, source: test}',
    )
    msg = error_of(tmp_path, text)
    assert "unknown experiment 'no_such'" in msg and "stand_coman" in msg and "line 19" in msg


def test_a_spec_known_deviation_needs_its_observed_band(tmp_path: Path) -> None:
    """A spec whose known deviation gives only a reason is refused at resolution, naming the field."""
    from walkrepro.errors import SpecError
    from walkrepro.runs.resolve import resolve_spec
    from walkrepro.specs.files import load_spec

    text = (EXPERIMENTS_DIR / "stand_dyros_red.yaml").read_text()
    text = text.replace(
        'source: "walkrepro sanity',
        'known_deviation: "only a reason"\n    source: "walkrepro sanity',
        1,
    )
    path = tmp_path / "stand_dyros_red.yaml"
    path.write_text(text)
    with pytest.raises(SpecError, match="expect.0.known_deviation.*observed"):
        resolve_spec(load_spec(str(path)))


@pytest.mark.parametrize("name", experiment_names())
def test_sources_cite_the_paper_not_internal_documents(name: str) -> None:
    """No expectation's source (or the paper section) names an internal document (issue, TARGETS, README)."""
    spec = load_spec(name).spec
    internal = re.compile(r"\b(issue|TARGETS|README|GUIDE)\b", re.IGNORECASE)
    assert not internal.search(spec.paper.section), spec.paper.section
    for e in spec.expect:
        assert not internal.search(e.source), (e.metric, e.source)


# --------------------------------------------------------------------------------------
# Every number checked (issue 32)

OBSTACLE = """\
world:
  obstacles:
    - {name: obstacle_box, size: [0.2, 0.2, 0.04], position: [0.5, 0.0, 0.02]}
"""


@pytest.mark.parametrize(
    ("override", "needle"),
    [
        ("sim.duration=.inf", "sim.duration"),
        ("sim.control_period=.inf", "sim.control_period"),
        ("sim.duration=.nan", "sim.duration"),
        ("controller.params.kp=.nan", "controller.params.kp"),
        ("controller.params.kp=nan", "controller.params.kp"),  # a string the model reads
        ("disturbances.0.force.0=.nan", "disturbances.0.force.0"),
        ("disturbances.0.torque=[0, -.inf, 0]", "disturbances.0.torque.1"),
        ("sensors.imu_gyro_noise=.inf", "sensors.imu_gyro_noise"),
        ("expect.0.value=.nan", "expect.0.value"),
        ("actuators.position_gain={'*': .nan}", "actuators.position_gain.*"),
        ("world.obstacles.0.size=[.inf, .inf, .inf]", "world.obstacles.0.size.0"),
        ("world.obstacles.0.position.0=.nan", "world.obstacles.0.position.0"),
        ("world.obstacles.0.tilt_x_deg=.nan", "world.obstacles.0.tilt_x_deg"),
    ],
)
def test_non_finite_numbers_are_refused(tmp_path: Path, override: str, needle: str) -> None:
    """NaN and ±inf are refused anywhere in a spec, naming the field; the spec without them loads."""
    resolve_spec(load_spec(str(write(tmp_path, GOOD + OBSTACLE))))
    msg = error_of(tmp_path, GOOD + OBSTACLE, (override,))
    assert needle in msg and "--set" in msg, msg
    assert "finite" in msg, msg


def test_non_finite_number_in_the_file_names_its_line(tmp_path: Path) -> None:
    """A NaN written in the file is reported with its line."""
    msg = error_of(tmp_path, GOOD.replace("duration: 0.5", "duration: .nan"))
    assert "line 11, field sim.duration" in msg and "finite" in msg


@pytest.mark.parametrize(
    ("old", "new", "needle"),
    [
        ("duration: 0.5", "duration: true", "not a boolean"),
        ("params: {kp: 200}", "params: {kp: true}", "not a boolean"),
        ("force: [10, 0, 0]", "force: [false, 0, 0]", "not a boolean"),
    ],
)
def test_booleans_are_not_numbers(tmp_path: Path, old: str, new: str, needle: str) -> None:
    """``true``/``false`` where a number is expected is an error, not 1 or 0."""
    msg = error_of(tmp_path, GOOD.replace(old, new))
    assert needle in msg, msg


@pytest.mark.parametrize(
    ("override", "needle"),
    [
        ("sim.duration=3600.5", "less than or equal to 3600"),
        ("sim.duration=1e12", "less than or equal to 3600"),
        ("sim.timestep=1e-12", "sim.timestep"),
        ("sim.seed=1e30", "sim.seed"),
        ("world.floor_friction=1e12", "world.floor_friction"),
        ("sensors.delay=1e12", "sensors.delay"),
        ("sensors.delay=0.0013", "whole number of control periods"),
        ("sensors.joint_backlash={'*knee*': 2}", "backlash"),
        ("disturbances.0.force=[1e9, 0, 0]", "norm must be <= 10000 [N]"),
        ("disturbances.0.force=[8000, 8000, 0]", "norm must be <= 10000 [N]"),
        ("disturbances.0.torque=[0, 0, 1e9]", "norm must be <= 1000 [Nm]"),
        ("disturbances.0.start=1e12", "disturbances.0.start"),
        ("actuators.friction_loss=1e9", "actuators.friction_loss"),
        ("world.obstacles.0.size=[1e9, 1, 1]", "size component must be <= 100"),
        ("world.obstacles.0.position=[1e9, 0, 0]", "position component must be within"),
        ("world.obstacles.0.tilt_y_deg=400", "world.obstacles.0.tilt_y_deg"),
        ("world.obstacles.0.solref=[0, 1]", "solref"),
    ],
)
def test_numbers_out_of_physical_range_are_refused(
    tmp_path: Path, override: str, needle: str
) -> None:
    """Durations, forces, frictions, noise, delays, gains and obstacle geometry have documented ranges."""
    msg = error_of(tmp_path, GOOD + OBSTACLE, (override,))
    assert needle in msg, msg


def test_values_inside_the_ranges_load(tmp_path: Path) -> None:
    """Values at the ends of the documented ranges load: an hour at 1 kHz, a 0.02 s delay, 10 kN."""
    path = str(write(tmp_path, GOOD + OBSTACLE))
    spec = load_spec(
        path,
        [
            "sim.duration=3600",
            "sensors.delay=0.02",
            "disturbances.0.force=[10000, 0, 0]",
            "world.floor_friction=10",
            "world.obstacles.0.tilt_x_deg=-90",
        ],
    ).spec
    assert spec.sim.duration == 3600.0 and spec.sensors.delay == 0.02


def test_run_memory_is_checked_before_allocation(tmp_path: Path) -> None:
    """A run whose per-tick clock would not fit in memory is refused, naming the fields to change."""
    msg = error_of(
        tmp_path, GOOD, ("sim.timestep=1e-6", "sim.control_period=1e-6", "sim.duration=3600")
    )
    assert "line 8, field sim:" in msg and "GiB" in msg and "sim.control_period" in msg, msg
    load_spec(str(write(tmp_path, GOOD)), ["sim.timestep=1e-5", "sim.control_period=1e-5"])


def test_duplicate_yaml_keys_are_errors(tmp_path: Path) -> None:
    """A key given twice is an error naming both lines, not a silent last-one-wins."""
    msg = error_of(tmp_path, GOOD.replace("robot: dyros_red\n", "robot: dyros_red\nrobot: coman\n"))
    assert "line 5" in msg and "duplicate key 'robot'" in msg and "line 4" in msg, msg
    msg = error_of(tmp_path, GOOD.replace("duration: 0.5", "duration: 0.5\n  timestep: 0.001"))
    assert "duplicate key 'timestep'" in msg, msg
    with pytest.raises(SpecError, match="duplicate key 'a'"):
        load_spec(str(write(tmp_path, GOOD)), ["controller.params={a: 1, a: 2}"])


def test_non_utf8_file_names_the_line(tmp_path: Path) -> None:
    """A file that is not UTF-8 is refused with the line of the first bad byte."""
    path = tmp_path / "latin1.yaml"
    path.write_bytes(GOOD.replace("a small valid spec", "caf\xe9").encode("latin-1"))
    with pytest.raises(SpecError, match=r"latin1.yaml, line 2: not UTF-8 text \(byte 0xe9"):
        load_spec(str(path))


@pytest.mark.parametrize("depth", [40, 5000])
def test_deep_nesting_is_refused(tmp_path: Path, depth: int) -> None:
    """Nesting far beyond any spec's is refused in one paragraph, not a RecursionError."""
    text = GOOD.replace("params: {kp: 200}", f"params: {{kp: {'[' * depth}{']' * depth}}}")
    msg = error_of(tmp_path, text)
    assert "nested" in msg, msg
    with pytest.raises(SpecError, match="nested"):
        load_spec(str(write(tmp_path, GOOD)), [f"sim.duration={'[' * depth}{']' * depth}"])


def test_alias_bomb_is_refused_quickly(tmp_path: Path) -> None:
    """YAML aliases that expand to millions of values are refused, not expanded."""
    levels = ["a0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1]"]
    levels += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, 9)]
    msg = error_of(tmp_path, GOOD + "\n".join(levels) + "\n")
    assert "more than 100000 values" in msg, msg


@pytest.mark.parametrize(
    "override", ["sim.duration.a.b=1", "sim.duration.0=1", "name.x=1", "description.a.b.c=2"]
)
def test_set_into_a_single_value_is_an_error(tmp_path: Path, override: str) -> None:
    """--set a.b=... where a is a number or text names the value, not a TypeError."""
    with pytest.raises(SpecError, match="single value"):
        load_spec(str(write(tmp_path, GOOD)), [override])


def test_obstacle_overlapping_the_robot_is_an_error(tmp_path: Path) -> None:
    """A box around the feet at the home pose is refused, naming the obstacle and the robot's geoms."""
    text = GOOD + OBSTACLE.replace("position: [0.5, 0.0, 0.02]", "position: [0.0, 0.0, 0.02]")
    msg = error_of(tmp_path, text)
    assert "line 22, field world.obstacles.0" in msg and "obstacle_box" in msg, msg
    assert "overlaps the robot" in msg and "foot" in msg and "allow_overlap" in msg, msg


def test_obstacle_overlap_allowed_explicitly_warns(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``allow_overlap: true`` lets an overlapping obstacle load, with a warning on stderr."""
    text = GOOD + OBSTACLE.replace(
        "position: [0.5, 0.0, 0.02]}", "position: [0.0, 0.0, 0.02], allow_overlap: true}"
    )
    loaded = resolve_spec(load_spec(str(write(tmp_path, text))))
    assert loaded.spec.world.obstacles[0].allow_overlap
    err = capsys.readouterr().err
    assert "warning:" in err and "obstacle_box" in err and "allow_overlap: true" in err
    assert "allow_overlap: true" in loaded.spec.to_yaml()


def test_obstacle_clear_of_the_robot_loads_silently(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An obstacle ahead of the feet loads with no warning, and its YAML has no allow_overlap."""
    loaded = resolve_spec(load_spec(str(write(tmp_path, GOOD + OBSTACLE))))
    assert "warning" not in capsys.readouterr().err
    assert "allow_overlap" not in loaded.spec.to_yaml()


def test_scene_refuses_a_non_finite_obstacle() -> None:
    """A spec built in code with a NaN obstacle never reaches MuJoCo (world.py's own guard)."""
    from walkrepro.sim.robot import load_robot
    from walkrepro.sim.world import build_scene
    from walkrepro.specs.models import ObstacleSpec

    spec = load_spec("stand_dyros_red").spec
    bad = ObstacleSpec.model_construct(
        name="obstacle_nan",
        size=(0.1, 0.1, 0.1),
        position=(float("nan"), 0.0, 0.0),
        anchor="center",
        tilt_x_deg=0.0,
        tilt_y_deg=0.0,
        fixed=True,
        mass=None,
        friction=None,
        allow_overlap=False,
        solref=None,
        solref_reason=None,
    )
    world = spec.world.model_copy(update={"obstacles": [bad]})
    with pytest.raises(SpecError, match="obstacle_nan.*finite"):
        build_scene(load_robot(spec.robot), spec.model_copy(update={"world": world}))


def test_experiment_name_fits_a_folder_name(tmp_path: Path) -> None:
    """An experiment name names the run's folder: 100 characters load, 300 are refused before running."""
    load_spec(str(write(tmp_path, GOOD)), ["name=" + "x" * 100])
    msg = error_of(tmp_path, GOOD, ("name=" + "x" * 300,))
    assert "field name (set with --set)" in msg and "at most 100" in msg, msg
