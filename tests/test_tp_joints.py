"""Tests of Paper II's joints found by name (walkrepro/papers/faraji/joints.py)."""

from __future__ import annotations

import dataclasses

import pytest

from walkrepro.errors import UnknownNameError
from walkrepro.papers.faraji.joints import LEFT, RIGHT, leg_joints
from walkrepro.sim.robot import load_robot


@pytest.mark.parametrize("name", ["coman", "coman_lab"])
def test_named_joints_sit_where_their_names_are(name: str) -> None:
    """Each named joint's leg-vector position drives the actuator of that name."""
    robot = load_robot(name)
    joints = leg_joints(robot)
    for joint in ("hip_pitch", "knee", "ankle_pitch"):
        for side, prefix in ((LEFT, "l"), (RIGHT, "r")):
            at = joints.actuator_list[getattr(joints, joint)[side]]
            assert robot.joint_names[at] == f"{prefix}_{joint}"
    assert robot.joint_names[joints.waist_roll] == "waist_roll"
    for side, prefix in ((LEFT, "l"), (RIGHT, "r")):
        assert robot.joint_names[joints.hip_pitch_actuator[side]] == f"{prefix}_hip_pitch"
        assert all(joints.leg_of[i] == side for i in joints.legs[side])
        leg = [robot.joint_names[joints.actuator_list[i]] for i in joints.legs[side]]
        assert all(n.startswith(prefix + "_") for n in leg)


def test_a_missing_joint_names_the_valid_ones() -> None:
    """A robot without a joint the controller needs fails with the robot's joint names."""
    robot = load_robot("coman")
    names = tuple("torso_roll" if n == "waist_roll" else n for n in robot.joint_names)
    with pytest.raises(UnknownNameError, match="waist_roll.*l_hip_pitch"):
        leg_joints(dataclasses.replace(robot, joint_names=names))
