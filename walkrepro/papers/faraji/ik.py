"""Analytic leg inverse kinematics from Cartesian pelvis and foot targets (Paper II, Fig. 3 B).

Paper II converts the Cartesian 3LP gait (pelvis and feet) into joint angles with inverse
kinematics. COMAN's legs (as modelled in ``robots/coman``) are a yaw–roll–pitch hip whose
axes meet at one point, a knee, and a pitch–roll ankle whose axes meet at one point, so the
closed-form six-joint solution (Kajita et al., *Introduction to Humanoid Robotics*, §2.5)
is exact and costs a few microseconds. The geometry is read from the robot model, and
:func:`forward` (Pinocchio) checks it in the tests.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

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
    x, y, z = np.asarray(sole_in_pelvis, dtype=float).tolist()
    rot = tuple(np.asarray(foot_rot_in_pelvis, dtype=float).ravel().tolist())
    return np.array(leg_ik_scalar(LegConstants.from_geometry(geom), x, y, z, rot))


class LegConstants(NamedTuple):
    """A :class:`LegGeometry` as plain floats, for :func:`leg_ik_scalar`'s per-tick use."""

    hip_x: float
    """Hip centre in the pelvis frame, x [m]."""
    hip_y: float
    """Hip centre, y [m]."""
    hip_z: float
    """Hip centre, z [m]."""
    thigh: float
    """Hip-to-knee length A [m]."""
    shank: float
    """Knee-to-ankle length B [m]."""
    sole_x: float
    """Sole point relative to the ankle centre in the foot frame, x [m]."""
    sole_y: float
    """Sole point, y [m]."""
    sole_z: float
    """Sole point, z [m]."""

    @classmethod
    def from_geometry(cls, geom: LegGeometry) -> LegConstants:
        """Unpack ``geom`` into floats."""
        hx, hy, hz = (float(v) for v in geom.hip)
        sx, sy, sz = (float(v) for v in geom.sole)
        return cls(hx, hy, hz, float(geom.thigh), float(geom.shank), sx, sy, sz)


def leg_ik_scalar(
    leg: LegConstants, x: float, y: float, z: float, rot: Sequence[float]
) -> tuple[float, float, float, float, float, float]:
    """:func:`leg_ik` on plain floats (a control tick calls it twice; no numpy overhead).

    Args:
        leg: the leg's geometry as floats.
        x, y, z: sole-point position in the pelvis frame [m].
        rot: foot orientation R in the pelvis frame, row-major, 9 floats.

    Returns:
        (hip yaw, hip roll, hip pitch, knee, ankle pitch, ankle roll) [rad].
    """
    hx, hy, hz, a, b, sx, sy, sz = leg
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rot
    # Ankle centre = sole − R·sole, then r = Rᵀ (hip − ankle): ankle → hip in the foot frame.
    dx = hx - (x - (r00 * sx + r01 * sy + r02 * sz))
    dy = hy - (y - (r10 * sx + r11 * sy + r12 * sz))
    dz = hz - (z - (r20 * sx + r21 * sy + r22 * sz))
    rx = r00 * dx + r10 * dy + r20 * dz
    ry = r01 * dx + r11 * dy + r21 * dz
    rz = r02 * dx + r12 * dy + r22 * dz
    c = min(math.sqrt(rx * rx + ry * ry + rz * rz), a + b - 1e-9)
    cos_knee = (c * c - a * a - b * b) / (2.0 * a * b)
    knee = math.acos(min(max(cos_knee, -1.0), 1.0))
    alpha = math.asin(min(max(a * math.sin(math.pi - knee) / c, -1.0), 1.0))
    sign_z = 1.0 if rz > 0.0 else (-1.0 if rz < 0.0 else 0.0)
    ankle_pitch = -math.atan2(rx, sign_z * math.hypot(ry, rz)) - alpha
    ankle_roll = math.atan2(ry, rz)
    # Hip rotation R · R_x(−ankle_roll) · R_y(−knee − ankle_pitch): only the entries the hip
    # angles need, its middle column (01, 11, 21) and its bottom row's ends (20, 22).
    ca, sa = math.cos(-ankle_roll), math.sin(-ankle_roll)
    m01, m11, m21 = r01 * ca + r02 * sa, r11 * ca + r12 * sa, r21 * ca + r22 * sa
    m22 = r22 * ca - r21 * sa
    th = -knee - ankle_pitch
    ct, st = math.cos(th), math.sin(th)
    h20 = r20 * ct - m22 * st
    h22 = r20 * st + m22 * ct
    yaw = math.atan2(-m01, m11)
    roll = math.atan2(m21, -m01 * math.sin(yaw) + m11 * math.cos(yaw))
    pitch = math.atan2(-h20, h22)
    return yaw, roll, pitch, knee, ankle_pitch, ankle_roll


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
