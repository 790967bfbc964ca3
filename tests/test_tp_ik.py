"""Tests of the analytic leg IK and the 3LP parameters derived from both COMAN models (Paper II)."""

from __future__ import annotations

import numpy as np
import pytest

from walkrepro.papers.faraji.ik import LegChainError, LegGeometry, forward, leg_ik
from walkrepro.papers.faraji.openloop import leg_root_body, threelp_params_from_robot
from walkrepro.sim.robot import load_robot

#: Both COMAN models: coman's yaw-roll-pitch hip and pitch-roll ankle, coman_lab's
#: pitch-roll-yaw hip (yaw axis down the thigh) and roll-pitch ankle.
COMANS = ["coman", "coman_lab"]


@pytest.mark.parametrize("name", COMANS)
@pytest.mark.parametrize("side", ["l", "r"])
def test_ik_inverts_forward_kinematics(name: str, side: str) -> None:
    """IK of a random reachable sole pose returns the joint angles that produced it."""
    robot = load_robot(name)
    geom = LegGeometry.from_robot(robot, side)
    rng = np.random.default_rng(1)
    first = 0 if side == "l" else 6
    for _ in range(20):
        q = robot.home_joint_pos.copy()
        q[first : first + 6] += rng.uniform(-0.25, 0.25, 6)
        q[first + 3] = abs(q[first + 3]) + 0.1  # knee bent: the IK's branch
        pos, rot = forward(robot, q, side)
        np.testing.assert_allclose(leg_ik(geom, pos, rot), q[first : first + 6], atol=1e-9)


def test_the_chain_is_read_from_each_model() -> None:
    """The leg chain, its order and its hip centre come from the model, not from names."""
    coman, lab = (LegGeometry.from_robot(load_robot(n), "l") for n in COMANS)
    assert coman.names == tuple(
        f"l_{j}" for j in ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
    )
    assert lab.names == tuple(
        f"l_{j}" for j in ("hip_pitch", "hip_roll", "hip_yaw", "knee", "ankle_roll", "ankle_pitch")
    )
    # Actuator order (hip yaw, roll, pitch, knee, ankle pitch, roll) of each chain joint.
    assert coman.order == (0, 1, 2, 3, 4, 5) and lab.order == (2, 1, 0, 3, 5, 4)
    # coman_lab's hip centre is the roll joint (0.0726 m out), not the pitch joint (0.023 m).
    np.testing.assert_allclose(lab.hip, [0.0, 0.0726, 0.0], atol=1e-12)
    assert lab.thigh == pytest.approx(0.2258) and lab.shank == pytest.approx(0.201)


def test_ik_rejects_a_leg_it_cannot_solve() -> None:
    """A leg whose hip axes do not meet is refused with the joints named, not mis-solved."""
    import dataclasses

    robot = load_robot("coman_lab")
    model = robot.pin_model.copy()
    jid = model.getJointId("l_hip_yaw")
    placement = model.jointPlacements[jid].copy()
    placement.translation[0] += 0.01  # the yaw axis 1 cm in front of the hip centre
    model.jointPlacements[jid] = placement
    broken = dataclasses.replace(robot, pin_model=model)
    with pytest.raises(LegChainError, match="l_hip_pitch, l_hip_roll, l_hip_yaw"):
        LegGeometry.from_robot(broken, "l")


@pytest.mark.parametrize(("name", "half_width"), [("coman", 0.07), ("coman_lab", 0.0726)])
def test_threelp_params_follow_the_model(name: str, half_width: float) -> None:
    """The 3LP masses add up to the robot and the heights match the home posture."""
    robot = load_robot(name)
    p = threelp_params_from_robot(robot)
    assert p.m1 + 2 * p.m2 == pytest.approx(robot.total_mass)
    assert p.m2 / robot.total_mass == pytest.approx(0.225, abs=0.01)  # Paper II: 22.5 %
    assert p.h1 == pytest.approx(robot.nominal_pelvis_height)
    assert 0 < p.h2 < p.h1 and p.h3 > 0
    assert p.pw == pytest.approx(half_width)  # the hip centres' spacing / 2


@pytest.mark.parametrize("name", COMANS)
def test_level_ik_matches_the_general_ik(name: str) -> None:
    """LegIk.solve_level (floats, per tick) equals LegIk.solve with a level pelvis."""
    from walkrepro.papers.faraji.openloop import LegIk, LegTargets

    ik = LegIk(load_robot(name))
    rng = np.random.default_rng(2)
    for _ in range(20):
        roll, lp, rp = rng.uniform(-0.15, 0.15, 3)
        left = (rng.uniform(-0.1, 0.1), 0.1 + rng.uniform(-0.03, 0.03), -0.5 + rng.uniform(0, 0.05))
        right = (rng.uniform(-0.1, 0.1), -0.1 + rng.uniform(-0.03, 0.03), -0.5)
        targets = LegTargets(roll, np.array(left), np.array(right), lp, rp)
        fast = ik.solve_level(roll, left, right, lp, rp)
        assert all(type(v) is float for v in fast)
        np.testing.assert_allclose(fast, ik.solve(targets), atol=1e-12)


@pytest.mark.parametrize("name", COMANS)
def test_leg_inertia_is_the_legs_pitch_inertia_about_its_com(name: str) -> None:
    """I2 = I3 is the leg subtree's pitch inertia about its own CoM; off, the legs are points."""
    import mujoco

    robot = load_robot(name)
    p = threelp_params_from_robot(robot)
    model = robot.mj_model
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    # Independent check: the leg's angular momentum about its CoM for a unit pitch rate of
    # the whole leg rotating rigidly about that CoM.
    leg = leg_root_body(robot, "l")
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
