"""Paper II (Faraji et al.) claim metrics on synthetic logs: the starting swing foot's load
and toe contact in early swing (Figs. 11-12) and the resting posture's CoM against its ghost
(Fig. 5), each where the claim holds and where it does not."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from test_metrics import (
    DT,
    Tick,
    floor_wrench,
    home_sole,
    make_spec,
    measured,
    standing_pairs,
    unmeasurable_reason,
    write_log,
)

from walkrepro.evaluation.metrics import GRAVITY, MetricArgError, check_metric_arg
from walkrepro.papers.faraji.metrics import early_swing_loads, spring_joints
from walkrepro.sim.robot import load_robot

ROBOT = "coman_lab"
STEP = 0.4  # [s] (Paper II's T)
START = 0.5  # [s] first phase change
N_STEPS = 4
FEET = ("left_foot", "right_foot")


def _weight() -> float:
    return load_robot(ROBOT).total_mass * GRAVITY


def _early_swing_log(path: Path, release: float, toe: float, outcome: str = "complete"):
    """Phase changes every 0.4 s from 0.5 s, the left foot swinging first. The foot that
    begins its swing keeps half the weight for ``release`` [s] after the phase change, its
    centre of pressure ``toe`` [m] ahead of its sole centre (negative: behind), then carries
    nothing until the next phase change."""
    weight = _weight()
    duration = START + STEP * N_STEPS
    ticks = []
    for k in range(int(round(duration / DT)) + 1):
        t = round(k * DT, 6)
        j = int(math.floor((t - START) / STEP + 1e-9))
        events = []
        if t >= START - 1e-9 and abs((t - START) / STEP - round((t - START) / STEP)) < 1e-6:
            events = [{"kind": "phase", "step": j, "swing": "left" if j % 2 == 0 else "right"}]
        pairs = standing_pairs(ROBOT)
        if 0 <= j < N_STEPS:
            swing, stance = FEET[j % 2], FEET[1 - j % 2]
            sx, sy, _ = home_sole(ROBOT, swing)
            tx, ty, _ = home_sole(ROBOT, stance)
            early = t - (START + j * STEP) < release - 1e-9
            share = 0.5 if early else 0.0
            pairs = {f"{stance}/floor": floor_wrench(tx, ty, weight * (1 - share))}
            if share:
                pairs[f"{swing}/floor"] = floor_wrench(sx + toe, sy, weight * share)
        ticks.append(Tick(t, pairs=pairs, events=events))
    spec = make_spec(ROBOT, duration, controller={"type": "timeprojection", "params": {}})
    return write_log(path, ticks, spec, outcome)


def test_toes_still_touch_at_a_tenth_of_the_step(tmp_path: Path) -> None:
    """A foot whose toes carry load for 60 ms after the phase change touches at t = 0.1 T."""
    d = _early_swing_log(tmp_path / "toes.mcap", release=0.06, toe=0.05)
    assert measured(d, "swing_toe_load:0.1") == pytest.approx(0.5, abs=0.01)
    assert measured(d, "swing_foot_load:0.1") == pytest.approx(0.5, abs=0.01)


def test_toes_released_before_a_tenth_of_the_step(tmp_path: Path) -> None:
    """A foot that leaves the ground 20 ms after the phase change is clear at t = 0.1 T."""
    d = _early_swing_log(tmp_path / "quick.mcap", release=0.02, toe=0.05)
    assert measured(d, "swing_toe_load:0.1") == 0.0
    assert measured(d, "swing_toe_load:0.0") == pytest.approx(0.5, abs=0.01)


def test_heel_contact_is_no_toe_contact(tmp_path: Path) -> None:
    """A starting swing foot loaded on its heel half counts as load, not as toe contact."""
    d = _early_swing_log(tmp_path / "heel.mcap", release=0.06, toe=-0.05)
    assert measured(d, "swing_toe_load:0.1") == 0.0
    assert measured(d, "swing_foot_load:0.1") == pytest.approx(0.5, abs=0.01)


def test_clearance_at_a_fifth_of_the_step(tmp_path: Path) -> None:
    """A foot still loaded at t = 0.2 T has no ground clearance; one released earlier has."""
    held = _early_swing_log(tmp_path / "held.mcap", release=0.1, toe=0.0)
    assert measured(held, "swing_foot_load:0.2") == pytest.approx(0.5, abs=0.01)
    clear = _early_swing_log(tmp_path / "clear.mcap", release=0.06, toe=0.0)
    assert measured(clear, "swing_foot_load:0.2") == 0.0


def test_early_swing_window_past_the_data_not_measurable(tmp_path: Path) -> None:
    """Phase changes asked for past a fall are not measured."""
    d = _early_swing_log(tmp_path / "fell.mcap", release=0.06, toe=0.05, outcome="fell")
    assert "before" in unmeasurable_reason(d, "swing_toe_load:0.1@0.5-5")


def test_early_swing_loads_keep_only_toes() -> None:
    """Loads are fractions of the weight; with a CoP, only contacts ahead of the centre count."""
    loads = early_swing_loads(np.array([100.0, 50.0, -1.0]), np.array([0.02, -0.01, 0.03]), 200.0)
    assert loads.tolist() == [0.5, 0.0, 0.0]
    assert early_swing_loads(np.array([100.0]), None, 200.0).tolist() == [0.5]


def test_swing_load_arguments() -> None:
    """The argument is a fraction of the step time in [0, 1], then optionally a window."""
    check_metric_arg("swing_toe_load:0.1@4.1-4.9")
    check_metric_arg("swing_foot_load:0.2")
    for bad in ("swing_toe_load", "swing_toe_load:x", "swing_foot_load:1.5@1-2"):
        with pytest.raises(MetricArgError):
            check_metric_arg(bad)


# ---- the resting posture against its ghost (Fig. 5) ------------------------------------------


def _spring(model: mujoco.MjModel, name: str) -> tuple[int, int]:
    return (
        int(model.jnt_qposadr[model.joint(f"{name}_motor").id]),
        int(model.jnt_qposadr[model.joint(name).id]),
    )


def _rest_log(path: Path, knee: float, ankle: float) -> object:
    """Standing at home for 1 s with both knee springs deflected ``knee`` [rad] and both
    ankle pitch springs ``ankle`` [rad] (link − motor), the link posture unchanged."""
    robot = load_robot(ROBOT)
    model = mujoco.MjModel.from_xml_path(str(robot.xml_path))
    qpos = robot.home_qpos.copy()
    for side in "lr":
        for joint, deflection in (("knee", knee), ("ankle_pitch", ankle)):
            motor, spring = _spring(model, f"{side}_{joint}")
            link = qpos[motor] + qpos[spring]
            qpos[spring] = deflection
            qpos[motor] = link - deflection
    ticks = [Tick(round(k * DT, 6), qpos=qpos) for k in range(101)]
    return write_log(path, ticks, make_spec(ROBOT, 1.0))


def test_compressed_knees_move_the_com_back(tmp_path: Path) -> None:
    """Knees bent further than their motors (compressed springs) put the actual CoM 1-2 cm
    behind the ghost's, as the paper says, for a 0.05 rad compression on a 0.25 m shank."""
    d = _rest_log(tmp_path / "knees.mcap", knee=0.05, ankle=0.0)
    assert -0.02 <= measured(d, "ghost_com_offset") <= -0.01


def test_compressed_ankles_move_the_com_forward(tmp_path: Path) -> None:
    """Ankles bent further forward than their motors lean the robot forward: the claim's
    backward shift is missed."""
    d = _rest_log(tmp_path / "ankles.mcap", knee=0.0, ankle=-0.05)
    assert measured(d, "ghost_com_offset") > 0.01


def test_springs_at_rest_give_no_offset(tmp_path: Path) -> None:
    """With every spring at rest the robot is its ghost."""
    robot = load_robot(ROBOT)
    model = mujoco.MjModel.from_xml_path(str(robot.xml_path))
    qpos = robot.home_qpos.copy()
    qpos[spring_joints(model)] = 0.0
    d = write_log(tmp_path / "rest.mcap", [Tick(0.0, qpos=qpos)], make_spec(ROBOT, DT))
    assert measured(d, "ghost_com_offset") == pytest.approx(0.0, abs=1e-12)


def test_ghost_needs_springs(tmp_path: Path) -> None:
    """A robot without series springs has no ghost to compare with."""
    d = write_log(tmp_path / "rigid.mcap", [Tick(0.0), Tick(DT)], make_spec("dyros_red", DT))
    assert "series-elastic" in unmeasurable_reason(d, "ghost_com_offset")
