"""The simulation loop: falls, broken controllers, zero-order hold, disturbances in the log."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from walkrepro.controllers.base import Command, Controller
from walkrepro.controllers.posture import PostureController
from walkrepro.evaluation.metrics import LogData, compute
from walkrepro.log import record
from walkrepro.runs import runner
from walkrepro.runs.resolve import resolve_spec
from walkrepro.sim.replay import verify_log
from walkrepro.specs.files import load_spec


def spec_of(name: str, *overrides: str):  # noqa: ANN201 - ExperimentSpec
    return resolve_spec(load_spec(name, list(overrides))).spec


def test_limp_robot_is_reported_as_fallen(tmp_path: Path) -> None:
    """With no joint torques the robot collapses, the run stops, and the log says it fell."""
    spec = spec_of(
        "stand_dyros_red",
        "sim.duration=4",
        "controller.params.kp=0",
        "controller.params.kd=0",
        "controller.params.gravity_compensation=false",
    )
    result = runner.run(spec, tmp_path / "log.mcap")
    assert result.outcome == "fell" and result.fall_time is not None
    assert result.sim_time < 4.0 and "fell at t =" in result.message
    data = LogData.from_path(tmp_path / "log.mcap")
    values = compute(data, ["fell", "fall_time"])
    assert values["fell"] == 1 and values["fall_time"] == pytest.approx(result.fall_time)
    assert data.log.metadata["outcome"] == "fell"
    assert verify_log(tmp_path / "log.mcap").ok


class _NanController(PostureController):
    """Returns NaN torques after 0.1 s."""

    def step(self, t: float, sensors) -> Command:  # noqa: ANN001
        command = super().step(t, sensors)
        return Command(ctrl=command.ctrl * np.nan) if t > 0.1 else command


def test_non_finite_command_is_a_clear_error_and_keeps_the_log(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A controller that returns NaN ends the run with outcome 'error'; the log up to then is readable."""
    monkeypatch.setattr(runner, "controller_class", lambda name: _NanController)
    result = runner.run(spec_of("stand_dyros_red", "sim.duration=1"), tmp_path / "log.mcap")
    assert result.outcome == "error" and "non-finite" in result.message
    log = record.read_log(tmp_path / "log.mcap")
    assert log.metadata["outcome"] == "error" and "non-finite" in log.metadata["message"]
    assert 150 < len(log.messages(record.TOPIC_STATE)) < 400


class _CountingController(Controller):
    """Returns a different constant command at every tick and counts its calls."""

    Params = PostureController.Params  # accepts the stand spec's params

    def reset(self, robot, params, control_period) -> None:  # noqa: ANN001
        self.calls = 0
        self.nu = robot.mj_model.nu
        self.home = robot.home_ctrl.copy()

    def step(self, t: float, sensors) -> Command:  # noqa: ANN001
        self.calls += 1
        return Command(ctrl=self.home + 1e-6 * self.calls, signals={"calls": self.calls})


def test_zero_order_hold_between_control_ticks(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The command changes only at control ticks and is held for the physics steps between."""
    monkeypatch.setattr(runner, "controller_class", lambda name: _CountingController)
    spec = spec_of("stand_coman", "sim.duration=0.1")  # 0.5 ms physics, 2 ms control
    runner.run(spec, tmp_path / "log.mcap")
    inputs = record.read_log(tmp_path / "log.mcap").messages(record.TOPIC_INPUTS)
    assert len(inputs) == 200
    ctrl = np.array([m["ctrl"][0] for m in inputs])
    changes = np.flatnonzero(np.diff(ctrl)) + 1
    assert list(changes) == list(range(4, 200, 4))


def test_disturbance_is_applied_logged_and_replayed(tmp_path: Path) -> None:
    """A spec push appears in /sim/inputs only inside its window, moves the robot, and replays exactly."""
    spec = spec_of(
        "stand_dyros_red",
        "sim.duration=0.6",
        "disturbances=[{name: shove, body: pelvis, force: [150, 0, 0], start: 0.2, duration: 0.1}]",
    )
    runner.run(spec, tmp_path / "log.mcap")
    log = record.read_log(tmp_path / "log.mcap")
    pushed = [m["step"] for m in log.messages(record.TOPIC_INPUTS) if m["xfrc"]]
    assert pushed[0] == 400 and pushed[-1] == 599 and len(pushed) == 200
    assert all(
        m["xfrc"]["pelvis"][:3] == [150.0, 0.0, 0.0]
        for m in log.messages(record.TOPIC_INPUTS)
        if m["xfrc"]
    )
    kinds = [e["kind"] for e in log.messages(record.TOPIC_EVENTS)]
    assert kinds == ["disturbance_on", "disturbance_off"]
    data = LogData.from_path(tmp_path / "log.mcap")
    assert compute(data, ["peak_external_force"])["peak_external_force"] == pytest.approx(150.0)
    assert data.qvel[-1, 0] != 0.0 or np.ptp(data.qpos[:, 0]) > 1e-4  # the push moved the pelvis
    assert verify_log(tmp_path / "log.mcap").ok


def test_a_non_foot_body_on_the_floor_is_a_fall(tmp_path: Path) -> None:
    """With the height criterion (almost) off, the limp robot's fall is seen by a knee, hip or pelvis
    geom touching the floor, and the message names that body."""
    spec = spec_of(
        "stand_dyros_red",
        "sim.duration=4",
        "sim.fall.pelvis_height_ratio=0.01",
        "controller.params.kp=0",
        "controller.params.kd=0",
        "controller.params.gravity_compensation=false",
    )
    result = runner.run(spec, tmp_path / "log.mcap")
    assert result.outcome == "fell" and "touched the floor" in result.message
    body = result.message.split("(")[1].split(" touched")[0]
    assert body not in ("left_foot", "right_foot", "floor") and body in spec_robot_bodies()


def test_the_contact_fall_criterion_can_be_turned_off(tmp_path: Path) -> None:
    """``sim.fall.non_foot_ground_contact: false`` leaves the height criterion alone: the same
    limp robot lies on the floor with its pelvis above 1 % of its height, and the run
    completes."""
    spec = spec_of(
        "stand_dyros_red",
        "sim.duration=4",
        "sim.fall.pelvis_height_ratio=0.01",
        "sim.fall.non_foot_ground_contact=false",
        "controller.params.kp=0",
        "controller.params.kd=0",
        "controller.params.gravity_compensation=false",
    )
    result = runner.run(spec, tmp_path / "log.mcap")
    assert result.outcome == "complete"
    data = LogData.from_path(tmp_path / "log.mcap")
    assert data.qpos[-1, 2] < 0.5  # it did collapse (the pelvis starts 0.95 m up)


def spec_robot_bodies() -> set[str]:
    from walkrepro.sim.robot import load_robot

    return set(load_robot("dyros_red").body_names())


def test_exploding_physics_is_a_clear_error_and_keeps_the_log(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A push far beyond anything physical makes MuJoCo reject the acceleration; the run ends
    with outcome 'error' naming the time, and the log up to then is readable and replays."""
    monkeypatch.chdir(tmp_path)  # MuJoCo appends its warning to ./MUJOCO_LOG.TXT
    spec = spec_of(
        "stand_dyros_red",
        "sim.duration=1",
        "disturbances=[{name: blast, body: pelvis, force: [1e4, 0, 0], start: 0.1, duration: 0.1}]",
    )
    # A spec refuses forces above 10 kN; only a spec built in code can reach the runner so.
    blast = spec.disturbances[0].model_copy(update={"force": (1e16, 0.0, 0.0)})
    spec = spec.model_copy(update={"disturbances": [blast]})
    result = runner.run(spec, tmp_path / "log.mcap")
    assert result.outcome == "error" and "unstable at t = 0.1000 s" in result.message
    log = record.read_log(tmp_path / "log.mcap")
    assert log.metadata["outcome"] == "error"
    assert log.messages(record.TOPIC_STATE)[-1]["t"] == pytest.approx(0.1)
    assert verify_log(tmp_path / "log.mcap").ok
