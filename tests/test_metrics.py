"""Metrics from a synthetic log whose answers are known."""

from __future__ import annotations

import math

import numpy as np
import pytest

from walkrepro import record
from walkrepro.metrics import LogData, compute, default_metric_names
from walkrepro.provenance import run_metadata
from walkrepro.robot import load_robot
from walkrepro.spec import ExperimentSpec
from walkrepro.world import build_scene

DT = 0.01  # [s] between synthetic messages
SPEED = 0.1  # [m/s] of the synthetic pelvis
LIFT = {"left_foot": (0.5, 0.7), "right_foot": (1.0, 1.2)}  # unloaded windows [s]


@pytest.fixture(scope="module")
def log(tmp_path_factory: pytest.TempPathFactory) -> LogData:
    """A 2 s log: the robot slides forward at SPEED, each foot lifts once, a 40 N push, an FSM signal."""
    spec = ExperimentSpec.model_validate(
        {
            "name": "synthetic",
            "description": "d",
            "paper": {"key": "walkrepro"},
            "robot": "dyros_red",
            "controller": {"type": "posture"},
            "sim": {"duration": 2.0, "timestep": DT, "control_period": DT},
            "world": {
                "obstacles": [
                    {"name": "obstacle_box", "size": [0.1, 0.1, 0.1], "position": [1, 0, 0.05]}
                ]
            },
        }
    )
    robot = load_robot("dyros_red")
    scene = build_scene(robot, spec)
    path = tmp_path_factory.mktemp("log") / "log.mcap"
    weight = robot.total_mass * 9.81
    with record.LogWriter(
        path, scene_xml=scene.xml, spec_yaml=spec.to_yaml(), metadata=run_metadata(spec)
    ) as w:
        for step in range(201):
            t = step * DT
            qpos = robot.home_qpos.copy()
            qpos[0] += SPEED * t
            w.write(
                record.TOPIC_STATE,
                {
                    "step": step,
                    "t": t,
                    "qpos": qpos.tolist(),
                    "qvel": [0.0] * scene.model.nv,
                    "act": [],
                },
                t,
            )
            pairs = {}
            for foot, (lo, hi) in LIFT.items():
                if not lo <= t < hi:
                    pairs[f"{foot}/floor"] = [0.0, 0.0, weight / 2, 0.0, 0.0, 0.0]
            if 1.5 <= t < 1.6:
                pairs["right_foot/obstacle_box"] = [30.0, 0.0, 40.0, 0.0, 0.0, 0.0]
            w.write(record.TOPIC_CONTACTS, {"step": step, "t": t, "pairs": pairs}, t)
            w.write(record.TOPIC_SIGNALS, {"t": t, "fsm_state": -1.0 if t < 0.5 else 1.0}, t)
            xfrc = {"pelvis": [0.0, 40.0, 0.0, 0.0, 0.0, 0.0]} if 1.0 <= t < 1.1 else {}
            if step < 200:
                w.write(
                    record.TOPIC_INPUTS,
                    {"step": step, "ctrl": [0.0] * scene.model.nu, "xfrc": xfrc},
                    t,
                )
        w.close("complete")
    return LogData.from_path(path)


def test_touchdowns_found_where_feet_reload(log: LogData) -> None:
    """A touchdown is detected where each foot is loaded again, and standing at t = 0 is not one."""
    steps = log.footsteps
    assert [s.foot for s in steps] == ["left_foot", "right_foot"]
    assert [round(s.t, 2) for s in steps] == [0.7, 1.2]
    assert steps[0].position[1] > 0 > steps[1].position[1]  # left foot at +y


def test_speed_drift_and_step_metrics(log: LogData) -> None:
    """Speed, drift, step length and step timing match the synthetic motion."""
    m = compute(
        log,
        [
            "mean_forward_speed",
            "pelvis_drift",
            "mean_step_length",
            "footsteps",
            "footsteps:left_foot",
            "mean_step_duration",
            "fell",
            "fall_time",
            "sim_time",
        ],
    )
    assert m["mean_forward_speed"] == pytest.approx(SPEED)
    assert m["pelvis_drift"] == pytest.approx(SPEED * 2.0)
    assert m["footsteps"] == 2 and m["footsteps:left_foot"] == 1
    # The right foot touches down 0.5 s later, 0.05 m further forward, on the other side.
    assert m["mean_step_length"] == pytest.approx(SPEED * 0.5, abs=1e-9)
    assert m["mean_step_duration"] == pytest.approx(0.5)
    assert m["fell"] == 0 and math.isnan(m["fall_time"]) and m["sim_time"] == pytest.approx(2.0)


def test_windowed_speed(log: LogData) -> None:
    """A speed window restricts the average to that interval."""
    assert compute(log, ["mean_forward_speed:0.5-1.5"])[
        "mean_forward_speed:0.5-1.5"
    ] == pytest.approx(SPEED)


def test_peak_forces(log: LogData) -> None:
    """Peak obstacle contact force and peak external force are the injected ones."""
    m = compute(
        log,
        [
            "peak_contact_force:right_foot/obstacle_box",
            "peak_contact_force:left_foot/obstacle*",
            "peak_external_force",
        ],
    )
    assert m["peak_contact_force:right_foot/obstacle_box"] == pytest.approx(50.0)
    assert m["peak_contact_force:left_foot/obstacle*"] == 0.0
    assert m["peak_external_force"] == pytest.approx(40.0)


def test_state_time(log: LogData) -> None:
    """Time spent in each FSM state adds up from the logged signal."""
    m = compute(log, ["state_time:-1", "state_time:1"])
    assert m["state_time:-1"] == pytest.approx(0.5, abs=DT)
    assert m["state_time:1"] == pytest.approx(1.5, abs=2 * DT)


def test_default_metrics_cover_obstacles_and_expectations(log: LogData) -> None:
    """Every run reports each foot's peak force on each obstacle."""
    names = default_metric_names(log.spec)
    assert "peak_contact_force:right_foot/obstacle_box" in names
    assert "peak_contact_force:left_foot/obstacle_box" in names
    values = compute(log, names)
    assert np.isfinite(values["mean_forward_speed"])
