"""Analytic leg inverse kinematics from Cartesian pelvis and foot targets (Paper II, Fig. 3 B).

Paper II converts the Cartesian 3LP gait (pelvis and feet) into joint angles with inverse
kinematics. COMAN's legs (as modelled in ``robots/coman``) are a yaw–roll–pitch hip whose
axes meet at one point, a knee, and a pitch–roll ankle whose axes meet at one point, so the
closed-form six-joint solution (Kajita et al., *Introduction to Humanoid Robotics*, §2.5)
is exact and costs a few microseconds. The geometry is read from the robot model, and
:func:`forward` (Pinocchio) checks it in the tests.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from walkrepro.robot import Robot

#: Leg joints in actuator order, per side (the coman convention).
LEG_JOINTS = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
SIDES = ("l", "r")
SOLE_FRAMES = {"l": "left_sole", "r": "right_sole"}


@dataclass(frozen=True)
class LegGeometry:
    """Lengths of one leg, read from the rigid-twin Pinocchio model at zero joint angles.

    Attributes:
        hip: hip joint centre in the pelvis frame, shape (3,) [m].
        thigh: hip-to-knee length A [m].
        shank: knee-to-ankle length B [m].
        sole: sole point (the paper's "foot position": the ankle axis shifted forward to
            mid-foot) relative to the ankle centre in the foot frame, shape (3,) [m].
    """

    hip: np.ndarray
    thigh: float
    shank: float
    sole: np.ndarray

    @classmethod
    def from_robot(cls, robot: Robot, side: str) -> LegGeometry:
        """Read the geometry of leg ``side`` ("l" or "r") from ``robot.pin_model``."""
        model = robot.pin_model
        data = model.createData()
        q = pin.neutral(model)
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacements(model, data)
        pos = {
            j: data.oMi[model.getJointId(f"{side}_{j}")].translation.copy()
            for j in ("hip_yaw", "knee", "ankle_pitch")
        }
        base = data.oMi[1].translation
        sole = data.oMf[model.getFrameId(SOLE_FRAMES[side])].translation
        return cls(
            hip=pos["hip_yaw"] - base,
            thigh=float(np.linalg.norm(pos["knee"] - pos["hip_yaw"])),
            shank=float(np.linalg.norm(pos["ankle_pitch"] - pos["knee"])),
            sole=sole - pos["ankle_pitch"],
        )


def _rx(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_rpy(roll: float, pitch: float) -> np.ndarray:
    """Rotation R_y(pitch) R_x(roll) (no yaw), shape (3, 3)."""
    return _ry(pitch) @ _rx(roll)


def leg_ik(
    geom: LegGeometry, sole_in_pelvis: np.ndarray, foot_rot_in_pelvis: np.ndarray
) -> np.ndarray:
    """Joint angles of one leg that put its sole point at a pose in the pelvis frame.

    Args:
        geom: the leg's geometry.
        sole_in_pelvis: sole-point position in the pelvis frame, shape (3,) [m].
        foot_rot_in_pelvis: foot orientation in the pelvis frame, shape (3, 3).

    Returns:
        [hip yaw, hip roll, hip pitch, knee, ankle pitch, ankle roll] [rad]; the knee is
        clipped to the reachable range (stretched leg at worst).
    """
    a, b = geom.thigh, geom.shank
    ankle = sole_in_pelvis - foot_rot_in_pelvis @ geom.sole
    r = foot_rot_in_pelvis.T @ (geom.hip - ankle)  # ankle -> hip, in the foot frame
    c = float(np.linalg.norm(r))
    c = min(c, a + b - 1e-9)
    cos_knee = (c * c - a * a - b * b) / (2.0 * a * b)
    knee = float(np.arccos(np.clip(cos_knee, -1.0, 1.0)))
    alpha = float(np.arcsin(np.clip(a * np.sin(np.pi - knee) / c, -1.0, 1.0)))
    ankle_pitch = -float(np.arctan2(r[0], np.sign(r[2]) * np.hypot(r[1], r[2]))) - alpha
    ankle_roll = float(np.arctan2(r[1], r[2]))
    rot = foot_rot_in_pelvis @ _rx(-ankle_roll) @ _ry(-knee - ankle_pitch)
    yaw = float(np.arctan2(-rot[0, 1], rot[1, 1]))
    cy, sy = np.cos(yaw), np.sin(yaw)
    roll = float(np.arctan2(rot[2, 1], -rot[0, 1] * sy + rot[1, 1] * cy))
    pitch = float(np.arctan2(-rot[2, 0], rot[2, 2]))
    return np.array([yaw, roll, pitch, knee, ankle_pitch, ankle_roll])


def forward(robot: Robot, joint_pos: np.ndarray, side: str) -> tuple[np.ndarray, np.ndarray]:
    """Sole pose of leg ``side`` in the pelvis frame by Pinocchio (for tests and checks).

    Args:
        robot: the robot.
        joint_pos: link-side joint angles in actuator order, shape (n,) [rad].
        side: "l" or "r".

    Returns:
        Position, shape (3,) [m], and rotation, shape (3, 3), in the pelvis frame.
    """
    model = robot.pin_model
    data = model.createData()
    q = pin.neutral(model)
    q[robot.pin_q_idx] = joint_pos
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    frame = data.oMf[model.getFrameId(SOLE_FRAMES[side])]
    return frame.translation.copy(), frame.rotation.copy()
