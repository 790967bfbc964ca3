"""The provenance ledger: every number a run uses has a class (walkrepro/publish/ledger.py)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from pydantic import Field

from walkrepro.controllers import controller_class, controller_names
from walkrepro.controllers.base import ControllerParams
from walkrepro.errors import SpecError, WalkreproError
from walkrepro.publish.ledger import (
    OVERRIDE,
    UNCLASSIFIED,
    counts,
    experiment_ledger,
    experiment_numbers,
    robot_ledger,
    unclassified_fields,
    undeclared_calibrated,
    unused_entries,
)
from walkrepro.runs.resolve import resolve_spec
from walkrepro.sim.robot import load_robot
from walkrepro.sim.world import build_scene
from walkrepro.specs import yamlload
from walkrepro.specs.files import find_spec_file, load_spec, shipped_experiment_names
from walkrepro.specs.origin import CLASSES, assumed, paper, scenario


@pytest.mark.parametrize("name", controller_names())
def test_every_controller_parameter_has_a_class(name: str) -> None:
    """Each registered controller's every parameter default carries a class or is scenario."""
    assert unclassified_fields(controller_class(name).Params) == []


def test_a_parameter_without_a_class_is_found() -> None:
    """A parameter model with an unclassed field is reported, classed ones are not."""

    class Params(ControllerParams):
        a: float = Field(1.0, json_schema_extra=paper("§1"))
        b: float = Field(2.0, json_schema_extra=scenario("the setup"))
        c: float = Field(3.0)

    assert unclassified_fields(Params) == ["c"]


def test_origin_helpers_refuse_unknown_classes_and_empty_sources() -> None:
    """A class outside the four and a provenance without its source are errors."""
    from walkrepro.specs.origin import _origin

    with pytest.raises(ValueError, match="unknown provenance class"):
        _origin("guessed", "x")
    with pytest.raises(ValueError, match="needs its source"):
        assumed("  ")
    assert set(CLASSES) == {"paper", "source", "assumed", "calibrated"}


def _numbers(text: str, overrides: tuple[str, ...] = (), tmp: Path | None = None):
    assert tmp is not None
    path = tmp / "spec.yaml"
    path.write_text(text)
    raw, _ = yamlload.load_with_node(text)
    loaded = resolve_spec(load_spec(str(path), overrides))
    scene = build_scene(load_robot(loaded.spec.robot), loaded.spec)
    return (
        {f"{n.group}.{n.name}": n for n in experiment_numbers(loaded, raw, scene.model)},
        loaded,
        raw,
    )


SPEC = """
name: ledger_probe
description: probe
paper: {key: walkrepro}
robot: dyros_red
controller: {type: posture, params: {kp: 250.0}}
sim: {timestep: 0.0005, control_period: 0.0005, duration: 0.1}
sensors: {imu_gyro_noise: 0.01}
"""


def test_a_value_the_spec_sets_without_a_class_is_unclassified(tmp_path: Path) -> None:
    """A controller gain and a sensor noise a spec sets with no class are unclassified."""
    numbers, _, _ = _numbers(SPEC, tmp=tmp_path)
    assert numbers["controller.params.kp"].klass == UNCLASSIFIED
    assert numbers["sensors.imu_gyro_noise"].klass == UNCLASSIFIED
    assert numbers["controller.params.kd"].klass == "assumed"  # a default keeps its class
    assert numbers["sim.duration"].klass == "scenario"


def test_the_spec_provenance_block_classes_its_values(tmp_path: Path) -> None:
    """A spec's own provenance entries class its values; an entry with no value is found."""
    text = (
        SPEC
        + "provenance:\n"
        + "  controller.params.kp: {class: calibrated, source: chosen on the sway}\n"
        + "  sensors.imu_gyro_noise: {class: source, source: a datasheet}\n"
        + "  sensors.imu_acc_noise: {class: assumed, source: nothing sets it}\n"
    )
    numbers, loaded, raw = _numbers(text, tmp=tmp_path)
    assert numbers["controller.params.kp"].klass == "calibrated"
    assert numbers["sensors.imu_gyro_noise"].klass == "source"
    assert unused_entries(loaded, raw) == ["sensors.imu_acc_noise"]


def test_a_command_line_override_is_listed_as_such(tmp_path: Path) -> None:
    """A --set value is the user's: listed as an override, not given the default's class."""
    numbers, _, _ = _numbers(SPEC, ("controller.params.kd=5",), tmp=tmp_path)
    assert numbers["controller.params.kd"].klass == OVERRIDE


def test_scene_options_away_from_mujoco_defaults_need_a_declaration(tmp_path: Path) -> None:
    """The robot's ledger declares its elliptic cone; MuJoCo's defaults are classed as such."""
    numbers, _, _ = _numbers(SPEC, tmp=tmp_path)
    assert numbers["scene.option.cone"].value == "1"  # elliptic, DYROS RED's lab's file
    assert numbers["scene.option.cone"].klass == "source"
    assert "option_cone" in numbers["scene.option.cone"].source
    assert "MuJoCo's default" in numbers["scene.option.integrator"].source
    assert "robot.option_cone" not in numbers  # listed once, with the scene


def test_paper_iii_scene_is_the_papers_simulators_default() -> None:
    """Every KIST scene option and floor or obstacle contact value is MuJoCo's default,
    classed as the paper's simulator's default (Paper III ran in MuJoCo), cone included."""
    scene = [n for n in experiment_ledger("obstacle_4cm") if n.group == "scene"]
    by_name = {n.name: n for n in scene}
    assert by_name["option.cone"].value == "0"  # pyramidal
    assert by_name["obstacle_block.solref"].value == "[0.02, 1]"
    for number in scene:
        assert number.klass == "assumed", number
        assert "the paper's simulator's default" in number.source, number


@pytest.mark.parametrize(("field", "value"), [("cone", "elliptic"), ("condim", "6")])
def test_a_spec_contact_setting_is_listed_under_its_field(field: str, value: str) -> None:
    """world.cone / world.condim set the scene's cone or every contact's condim, and the
    scene rows name the spec field instead of calling them undeclared departures."""
    numbers = experiment_ledger("obstacle_4cm", (f"world.{field}={value}",))
    scene = {n.name: n for n in numbers if n.group == "scene"}
    rows = ["option.cone"] if field == "cone" else ["floor.condim", "obstacle_block.condim"]
    for row in rows:
        assert scene[row].klass == "scenario"
        assert scene[row].value == ("1" if field == "cone" else "6")
    world = {n.name: n for n in numbers if n.group == "world"}
    assert world[field].klass == OVERRIDE


def test_a_robot_ledger_with_a_bad_class_names_file_and_entry(tmp_path: Path) -> None:
    """A ledger entry with a class outside the four is an error naming the file and field."""
    (tmp_path / "bot").mkdir()
    (tmp_path / "bot" / "parameters.yaml").write_text(
        yaml.safe_dump(
            {
                "robot": "bot",
                "parameters": {"mass": {"value": 1, "unit": "kg", "class": "guess", "source": "x"}},
            }
        )
    )
    with pytest.raises(SpecError, match=r"parameters\.yaml, field parameters\.mass\.class"):
        robot_ledger("bot", tmp_path)


def test_a_variant_ledger_extends_the_one_it_inherits(tmp_path: Path) -> None:
    """A variant's entries add to and replace those of the robot it inherits."""
    for robot, inherits, params in (
        ("base", None, {"a": 1.0, "b": 2.0}),
        ("variant", "base", {"b": 3.0}),
    ):
        (tmp_path / robot).mkdir()
        entries = {
            k: {"value": v, "unit": "m", "class": "assumed", "source": "s"}
            for k, v in params.items()
        }
        (tmp_path / robot / "parameters.yaml").write_text(
            yaml.safe_dump({"robot": robot, "inherits": inherits, "parameters": entries})
        )
    ledger = robot_ledger("variant", tmp_path)
    assert ledger is not None
    assert {k: e.value for k, e in ledger.items()} == {"a": 1.0, "b": 3.0}


@pytest.mark.parametrize("name", shipped_experiment_names())
def test_every_number_of_every_shipped_experiment_has_a_class(name: str) -> None:
    """No shipped experiment uses a number (robot, scene, spec, controller) without a class."""
    numbers = experiment_ledger(name)
    missing = [
        f"{n.group} {n.name} = {n.value}: {n.source}" for n in numbers if n.klass == UNCLASSIFIED
    ]
    assert missing == []
    assert counts(numbers)[OVERRIDE] == 0


@pytest.mark.parametrize("name", shipped_experiment_names())
def test_every_spec_provenance_entry_names_a_value(name: str) -> None:
    """A spec's provenance block has no entry for a value the spec does not set."""
    path = find_spec_file(name)
    raw, _ = yamlload.load_with_node(path.read_text(encoding="utf-8"))
    assert unused_entries(load_spec(name), raw) == []


def test_update_reference_refuses_uncommitted_changes(monkeypatch: pytest.MonkeyPatch) -> None:
    """Writing references from a dirty tree is refused, unless --allow-dirty says so."""
    from walkrepro.cli import common
    from walkrepro.runs import provenance

    monkeypatch.setattr(provenance, "dirty_paths", lambda folders: ["robots/build_models.py"])
    with pytest.raises(WalkreproError, match="uncommitted changes.*build_models"):
        common.needs_clean_tree("check --update-reference", allow_dirty=False)
    common.needs_clean_tree("check --update-reference", allow_dirty=True)
    monkeypatch.setattr(provenance, "dirty_paths", lambda folders: [])
    common.needs_clean_tree("check --update-reference", allow_dirty=False)


PUSH = """
disturbances:
  - {name: shove, body: pelvis, force: [30, 0, 0], start: 0.02, duration: 0.05}
"""


def test_a_disturbance_number_without_a_class_is_unclassified(tmp_path: Path) -> None:
    """A push's force, start and duration the spec sets with no class are unclassified; its
    unset torque keeps the field's class (a push is a force)."""
    numbers, _, _ = _numbers(SPEC + PUSH, tmp=tmp_path)
    for field in ("force", "start", "duration"):
        assert numbers[f"disturbance.shove.{field}"].klass == UNCLASSIFIED
    assert numbers["disturbance.shove.torque"].klass == "assumed"
    assert "disturbance.shove.ramp_time" not in numbers  # a constant push has no ramp


def test_the_spec_provenance_block_classes_disturbance_numbers(tmp_path: Path) -> None:
    """``disturbances.<name>.<field>`` in the spec's provenance block classes that number, and
    names a value the spec sets; an entry for a field the disturbance does not use is found."""
    text = (
        SPEC
        + PUSH
        + "provenance:\n"
        + "  disturbances.shove.force: {class: paper, source: the paper's push}\n"
        + "  disturbances.shove.start: {class: assumed, source: after the start-up}\n"
        + "  disturbances.shove.duration: {class: calibrated, source: chosen on a fall}\n"
        + "  disturbances.shove.stiffness: {class: assumed, source: a push has none}\n"
    )
    numbers, loaded, raw = _numbers(text, tmp=tmp_path)
    assert numbers["disturbance.shove.force"].klass == "paper"
    assert numbers["disturbance.shove.start"].klass == "assumed"
    assert numbers["disturbance.shove.duration"].klass == "calibrated"
    assert unused_entries(loaded, raw) == ["disturbances.shove.stiffness"]


def test_a_disturbance_override_is_listed_as_such(tmp_path: Path) -> None:
    """A --set on a disturbance's number is the user's."""
    numbers, _, _ = _numbers(SPEC + PUSH, ("disturbances.0.force.0=40",), tmp=tmp_path)
    assert numbers["disturbance.shove.force"].klass == OVERRIDE
    assert numbers["disturbance.shove.start"].klass == UNCLASSIFIED


def test_every_number_of_the_hand_is_classed() -> None:
    """human_push lists the hand's stiffness, damping, cap, anchor offset (calibrated), grab
    time (calibrated: chosen after runs), duration and ramp, each with a class."""
    numbers = {n.name: n for n in experiment_ledger("human_push") if n.group == "disturbance"}
    assert set(numbers) == {
        f"human_hold.{f}"
        for f in ("stiffness", "damping", "max_force", "hold_offset", "start", "duration")
    } | {"human_hold.ramp_time"}
    assert numbers["human_hold.stiffness"].value == "2000"
    assert numbers["human_hold.damping"].value == "580"
    assert numbers["human_hold.max_force"].value == "200"
    assert numbers["human_hold.hold_offset"].klass == "calibrated"
    assert "hold_offset" in numbers["human_hold.hold_offset"].source
    assert numbers["human_hold.start"].klass == "calibrated"
    assert all(n.klass in CLASSES for n in numbers.values())


def test_provenance_of_the_issue_experiments_has_no_unclassified_number() -> None:
    """``walkrepro provenance human_push continuous_drag forward_walk`` exits 0, lists every
    disturbance number with its class, 0 unclassified, and step_width is not scenario."""
    from typer.testing import CliRunner

    from walkrepro.cli import app

    result = CliRunner().invoke(
        app, ["provenance", "human_push", "continuous_drag", "forward_walk"], env={"COLUMNS": "300"}
    )
    assert result.exit_code == 0, result.output
    for name in ("human_push", "continuous_drag", "forward_walk"):
        assert f"{name}: " in result.output
    assert result.output.count(" 0 unclassified") == 3
    drag = {n.name: n for n in experiment_ledger("continuous_drag")}
    assert drag["drag_forward.force"].klass == "calibrated"
    assert drag["drag_backward.force"].klass == "calibrated"
    for name in ("forward_walk", "human_push"):
        width = {n.name: n for n in experiment_ledger(name)}["params.step_width"]
        assert width.klass == "calibrated", width


def test_paper_i_time_step_and_torque_limit_are_the_labs() -> None:
    """Paper I's 0.5 ms physics step and the E-FSM's 300 Nm torque limit are source: the lab's
    MJCF (saga0619/dyros_red), not the paper's 2 kHz EtherCAT loop or an assumption."""
    numbers = {f"{n.group}.{n.name}": n for n in experiment_ledger("forward_walk")}
    for name in ("sim.timestep", "controller.params.torque_limit"):
        assert numbers[name].klass == "source", numbers[name]
        assert "saga0619/dyros_red" in numbers[name].source


COMAN_EXPERIMENTS = [n for n in shipped_experiment_names() if load_spec(n).spec.robot == "coman"]


@pytest.mark.parametrize("name", COMAN_EXPERIMENTS)
def test_every_calibrated_value_of_the_coman_ablations_is_declared(name: str) -> None:
    """Every calibrated number of a run on robots/coman (its ledger's springs, damping and
    sole; its specs' departures from the paper's controller) is declared, with the value in
    force, in experiments/calibration/robots/coman.yaml."""
    assert undeclared_calibrated(experiment_ledger(name), "coman") == []


def test_an_undeclared_calibrated_value_is_found(tmp_path: Path) -> None:
    """A declaration that leaves out a calibrated ledger entry, or declares another value
    than the one in force, leaves it undeclared; the robot's ledger rows cite a declaration."""
    from walkrepro.specs.calibration_files import ROBOT_CALIBRATION_DIR

    numbers = experiment_ledger("stand_coman")
    data = yaml.safe_load((ROBOT_CALIBRATION_DIR / "coman.yaml").read_text())
    data["values"] = [v for v in data["values"] if v["name"] != "spring_knee"]
    for v in data["values"]:
        if v["name"] == "foot_length":
            v["value"] = 0.18
    (tmp_path / "coman.yaml").write_text(yaml.safe_dump(data, allow_unicode=True))
    missing = undeclared_calibrated(numbers, "coman", tmp_path)
    assert sorted(m.split(" =")[0] for m in missing) == ["robot foot_length", "robot spring_knee"]
    knee = {n.name: n for n in numbers}["spring_knee"]
    assert "experiments/calibration/robots/coman.yaml: spring_knee" in knee.source


def test_a_robot_declaration_names_file_line_and_field(tmp_path: Path) -> None:
    """A declared value with neither a ledger entry nor a spec path is an error naming the
    file and the field; so is a file named after another robot."""
    from walkrepro.specs.calibration_files import robot_calibration

    value = {
        "name": "k",
        "value": 1.0,
        "unit": "Nm/rad",
        "criterion": {"kind": "result", "quote": "q", "section": "s"},
        "how": "h",
    }
    (tmp_path / "bot.yaml").write_text(
        yaml.safe_dump({"robot": "bot", "description": "d", "values": [value]})
    )
    with pytest.raises(SpecError, match=r"bot\.yaml.*values\.0.*exactly one of ledger"):
        robot_calibration("bot", tmp_path)
    value["ledger"] = "k"
    (tmp_path / "other.yaml").write_text(
        yaml.safe_dump({"robot": "bot", "description": "d", "values": [value]})
    )
    with pytest.raises(SpecError, match="must be named bot.yaml"):
        robot_calibration("other", tmp_path)
    assert robot_calibration("nobody", tmp_path) is None
