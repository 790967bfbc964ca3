"""Spec loading: schema, line numbers in errors, --set overrides, name resolution."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from walkrepro import EXPERIMENTS_DIR
from walkrepro.errors import SpecError, UnknownNameError
from walkrepro.spec import experiment_names, load_spec, resolve_spec

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
    from walkrepro.spec import load_spec, resolve_spec

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
