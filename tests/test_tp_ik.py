"""Tests of the analytic leg IK and the 3LP parameters derived from coman (Paper II)."""

from __future__ import annotations

import numpy as np
import pytest

from walkrepro.papers.faraji.ik import LegGeometry, forward, leg_ik
from walkrepro.papers.faraji.openloop import threelp_params_from_robot
from walkrepro.robot import load_robot


@pytest.mark.parametrize("side", ["l", "r"])
def test_ik_inverts_forward_kinematics(side: str) -> None:
    """IK of a random reachable sole pose returns the joint angles that produced it."""
    robot = load_robot("coman")
    geom = LegGeometry.from_robot(robot, side)
    rng = np.random.default_rng(1)
    first = 0 if side == "l" else 6
    for _ in range(10):
        q = robot.home_joint_pos.copy()
        q[first : first + 6] += rng.uniform(-0.25, 0.25, 6)
        q[first + 3] = abs(q[first + 3]) + 0.1  # knee bent: the IK's branch
        pos, rot = forward(robot, q, side)
        np.testing.assert_allclose(leg_ik(geom, pos, rot), q[first : first + 6], atol=1e-9)


def test_threelp_params_follow_the_model() -> None:
    """The 3LP masses add up to the robot and the heights match the home posture."""
    robot = load_robot("coman")
    p = threelp_params_from_robot(robot)
    assert p.m1 + 2 * p.m2 == pytest.approx(robot.total_mass)
    assert p.m2 / robot.total_mass == pytest.approx(0.225, abs=0.01)  # Paper II: 22.5 %
    assert p.h1 == pytest.approx(robot.nominal_pelvis_height)
    assert 0 < p.h2 < p.h1 and p.h3 > 0
    assert p.pw == pytest.approx(0.07)  # hips 14 cm apart


def test_level_ik_matches_the_general_ik() -> None:
    """LegIk.solve_level (floats, per tick) equals LegIk.solve with a level pelvis."""
    from walkrepro.papers.faraji.openloop import LegIk, LegTargets

    ik = LegIk(load_robot("coman"))
    rng = np.random.default_rng(2)
    for _ in range(20):
        roll, lp, rp = rng.uniform(-0.15, 0.15, 3)
        left = (rng.uniform(-0.1, 0.1), 0.1 + rng.uniform(-0.03, 0.03), -0.5 + rng.uniform(0, 0.05))
        right = (rng.uniform(-0.1, 0.1), -0.1 + rng.uniform(-0.03, 0.03), -0.5)
        targets = LegTargets(roll, np.array(left), np.array(right), lp, rp)
        fast = ik.solve_level(roll, left, right, lp, rp)
        assert all(type(v) is float for v in fast)
        np.testing.assert_allclose(fast, ik.solve(targets), atol=1e-12)


def test_leg_inertia_is_the_legs_pitch_inertia_about_its_com() -> None:
    """I2 = I3 is the leg subtree's pitch inertia about its own CoM; off, the legs are points."""
    import mujoco

    robot = load_robot("coman")
    p = threelp_params_from_robot(robot)
    model = robot.mj_model
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    # Independent check: the leg's angular momentum about its CoM for a unit pitch rate of
    # the whole leg rotating rigidly about that CoM.
    leg = model.body("l_hip_yaw_link").id
    com = data.subtree_com[leg]
    h = 0.0
    for b in range(leg, model.body("left_foot").id + 1):
        r = data.xipos[b] - com
        rot = data.ximat[b].reshape(3, 3)
        inertia = rot @ np.diag(model.body_inertia[b]) @ rot.T
        v = np.cross([0.0, 1.0, 0.0], r)
        h += (inertia @ [0.0, 1.0, 0.0])[1] + model.body_mass[b] * np.cross(r, v)[1]
    assert p.I2 == pytest.approx(h, rel=1e-9) and p.I3 == p.I2
    assert 0.1 < p.I2 < 0.5
    assert threelp_params_from_robot(robot, leg_inertia=False).I2 == 0.0
