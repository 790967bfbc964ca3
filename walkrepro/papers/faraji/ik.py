"""Analytic leg inverse kinematics from Cartesian pelvis and foot targets (Paper II, Fig. 3 B).

Paper II converts the Cartesian 3LP gait (pelvis and feet) into joint angles with inverse
kinematics. A COMAN leg is a three-axis hip whose axes meet at one point (the hip centre),
a knee, and a two-axis ankle whose axes meet at one point (the ankle centre), so a
closed-form six-joint solution exists (Kajita et al., *Introduction to Humanoid Robotics*,
§2.5, generalised to any order of the axes). The two COMAN models order them differently:
``robots/coman`` has a yaw–roll–pitch hip and a pitch–roll ankle, ``robots/coman_lab`` (the
lab's Robotran model) a pitch–roll–yaw hip, its yaw axis running down the thigh, and a
roll–pitch ankle. Nothing here names a joint: :meth:`LegGeometry.from_robot` walks the
rigid-twin Pinocchio model from the leg's sole frame up to the floating base and reads each
joint's axis and anchor at zero angles, the hip and ankle centres and the segment vectors.
The solution is the product of exponentials R = R₁(q₁) ⋯ R₆(q₆) (axes aᵢ in the pelvis frame
at zero angles) solved by Paden–Kahan subproblems: the knee from the hip–ankle distance,
the ankle pair by subproblem 2, the hip triple by an Euler decomposition in the model's
order. :func:`forward` (Pinocchio) checks it in the tests on both robots.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from walkrepro.sim.robot import Robot

SIDES = ("l", "r")
#: The sole frame of each leg (the paper's "foot position": mid-foot on the ground); the
#: leg's chain is the joints between it and the floating base.
SOLE_FRAMES = {"l": "left_sole", "r": "right_sole"}
#: Tolerance of the geometric assumptions (intersecting, perpendicular axes) [m or 1].
_GEOM_TOL = 1e-6

Vec = tuple[float, float, float]


class LegChainError(ValueError):
    """A leg whose joints are not a three-axis hip, a knee and a two-axis ankle."""


@dataclass(frozen=True)
class LegGeometry:
    """One leg's kinematics, read from the rigid-twin Pinocchio model at zero joint angles.

    All vectors are in the pelvis frame at zero joint angles.

    Attributes:
        hip: hip centre (the point where the three hip axes meet), shape (3,) [m].
        thigh_vec: hip centre → knee axis, t₀, shape (3,) [m].
        shank_vec: knee axis → ankle centre, s₀, shape (3,) [m].
        sole: ankle centre → sole point, shape (3,) [m].
        axes: unit joint axes a₁ … a₆ in chain order (pelvis to foot), shape (6, 3).
        order: the chain's joints as indices into the leg's six actuators (actuator order),
            shape (6,).
        knee_sign: the sign of a bent knee's angle (the home keyframe's), ±1.
        names: the chain's joint names, pelvis to foot.
    """

    hip: np.ndarray
    thigh_vec: np.ndarray
    shank_vec: np.ndarray
    sole: np.ndarray
    axes: np.ndarray
    order: tuple[int, ...]
    knee_sign: float
    names: tuple[str, ...]

    @property
    def thigh(self) -> float:
        """Hip-to-knee length A [m]."""
        return float(np.linalg.norm(self.thigh_vec))

    @property
    def shank(self) -> float:
        """Knee-to-ankle length B [m]."""
        return float(np.linalg.norm(self.shank_vec))

    @classmethod
    def from_robot(cls, robot: Robot, side: str) -> LegGeometry:
        """Read the geometry of leg ``side`` ("l" or "r") from ``robot.pin_model``.

        Raises:
            LegChainError: the leg is not six revolute joints (three intersecting
                perpendicular hip axes, a knee perpendicular to a straight leg, two
                intersecting perpendicular ankle axes) between the pelvis and the sole.
        """
        if side not in SOLE_FRAMES:
            raise LegChainError(f"unknown leg side {side!r}; valid: {', '.join(SOLE_FRAMES)}")
        model = robot.pin_model
        data = model.createData()
        pin.forwardKinematics(model, data, pin.neutral(model))
        pin.updateFramePlacements(model, data)
        frame = model.frames[robot.pin_frame_id(SOLE_FRAMES[side])]
        chain: list[int] = []
        jid = int(frame.parentJoint)
        while jid > 0 and model.joints[jid].nq == 1:
            chain.append(jid)
            jid = int(model.parents[jid])
        chain.reverse()
        names = tuple(model.names[j] for j in chain)
        if len(chain) != 6:
            raise LegChainError(
                f"{robot.name}: leg {side!r} has {len(chain)} revolute joints between the "
                f"pelvis and {SOLE_FRAMES[side]} ({', '.join(names)}); the IK needs 6"
            )
        base = data.oMi[int(model.parents[chain[0]])]
        anchors, axes = [], []
        for j in chain:
            placement = base.actInv(data.oMi[j])
            axis = _revolute_axis(model.joints[j].shortname())
            if axis is None:
                raise LegChainError(
                    f"{robot.name}: joint {model.names[j]} is {model.joints[j].shortname()}, "
                    "not a revolute joint about a coordinate axis"
                )
            anchors.append(placement.translation.copy())
            axes.append(placement.rotation @ axis)
        anchors_a, axes_a = np.array(anchors), np.array(axes)
        hip = _meeting_point(anchors_a[:3], axes_a[:3], f"{robot.name} {side} hip", names[:3])
        ankle = _meeting_point(anchors_a[4:], axes_a[4:], f"{robot.name} {side} ankle", names[4:])
        knee = anchors_a[3]
        thigh_vec, shank_vec = knee - hip, ankle - knee
        # The knee's axis crosses the leg line (hip → ankle) and is perpendicular to it.
        leg_dir = (ankle - hip) / np.linalg.norm(ankle - hip)
        off_line = np.linalg.norm(np.cross(thigh_vec, leg_dir))
        if off_line > _GEOM_TOL or abs(float(axes_a[3] @ leg_dir)) > _GEOM_TOL:
            raise LegChainError(
                f"{robot.name}: knee {names[3]} is not on a straight leg at zero angles, "
                "perpendicular to it"
            )
        sole_placement = base.actInv(data.oMf[robot.pin_frame_id(SOLE_FRAMES[side])])
        if not np.allclose(sole_placement.rotation, np.eye(3), atol=_GEOM_TOL):
            raise LegChainError(
                f"{robot.name}: {SOLE_FRAMES[side]} is rotated from the pelvis at zero angles"
            )
        sole = sole_placement.translation
        actuators = list(robot.joint_names)
        try:
            order = tuple(actuators.index(n) for n in names)
        except ValueError as exc:
            raise LegChainError(f"{robot.name}: a leg joint has no actuator ({exc})") from None
        first = min(order)
        knee_home = float(robot.home_joint_pos[order[3]])
        return cls(
            hip=hip,
            thigh_vec=thigh_vec,
            shank_vec=shank_vec,
            sole=sole - ankle,
            axes=axes_a,
            order=tuple(i - first for i in order),
            knee_sign=1.0 if knee_home >= 0.0 else -1.0,
            names=names,
        )


def _revolute_axis(shortname: str) -> np.ndarray | None:
    """The unit axis of a Pinocchio revolute joint about x, y or z in its own frame."""
    axis = {"JointModelRX": 0, "JointModelRY": 1, "JointModelRZ": 2}.get(shortname)
    return None if axis is None else np.eye(3)[axis]


def _meeting_point(
    anchors: np.ndarray, axes: np.ndarray, what: str, names: Sequence[str]
) -> np.ndarray:
    """The point where all the axes (lines through ``anchors``) meet, pairwise perpendicular.

    The anchor of one of them lies on every other axis (the COMAN models: coman's hip at
    its yaw joint, coman_lab's at its roll joint).
    """
    for i in range(len(axes)):
        for j in range(i + 1, len(axes)):
            if abs(float(axes[i] @ axes[j])) > _GEOM_TOL:
                raise LegChainError(f"{what}: axes of {names[i]} and {names[j]} not perpendicular")
    for point in anchors:
        if all(
            np.linalg.norm(np.cross(point - anchor, axis)) <= _GEOM_TOL
            for anchor, axis in zip(anchors, axes, strict=True)
        ):
            return point.copy()
    raise LegChainError(f"{what}: the axes of {', '.join(names)} do not meet at a joint anchor")


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
        The leg's six joint angles in actuator order (both COMAN models: hip yaw, hip roll,
        hip pitch, knee, ankle pitch, ankle roll) [rad]; the knee is clipped to the reachable
        range (stretched leg at worst).
    """
    x, y, z = np.asarray(sole_in_pelvis, dtype=float).tolist()
    rot = tuple(np.asarray(foot_rot_in_pelvis, dtype=float).ravel().tolist())
    return np.array(leg_ik_scalar(LegConstants.from_geometry(geom), x, y, z, rot))


class LegConstants(NamedTuple):
    """A :class:`LegGeometry` as plain floats, for :func:`leg_ik_scalar`'s per-tick use."""

    hip: Vec
    """Hip centre in the pelvis frame [m]."""
    thigh: Vec
    """Hip centre → knee, t₀ [m]."""
    shank: Vec
    """Knee → ankle centre, s₀ [m]."""
    sole: Vec
    """Ankle centre → sole point at zero angles [m]."""
    axes: tuple[Vec, Vec, Vec, Vec, Vec, Vec]
    """Unit axes a₁ … a₆, chain order."""
    order: tuple[int, ...]
    """Actuator index of each chain joint within the leg."""
    knee_sign: float
    """Sign of a bent knee's angle."""
    thigh_len: float
    """|t₀| = A [m]."""
    shank_len: float
    """|s₀| = B [m]."""
    hip_det: float
    """a₁ · (a₂ × a₃), ±1: the handedness of the hip's axis order."""

    @classmethod
    def from_geometry(cls, geom: LegGeometry) -> LegConstants:
        """Unpack ``geom`` into floats."""

        def vec(v: np.ndarray) -> Vec:
            return (float(v[0]), float(v[1]), float(v[2]))

        axes = tuple(vec(a) for a in geom.axes)
        return cls(
            vec(geom.hip),
            vec(geom.thigh_vec),
            vec(geom.shank_vec),
            vec(geom.sole),
            axes,  # type: ignore[arg-type]
            tuple(geom.order),
            float(geom.knee_sign),
            geom.thigh,
            geom.shank,
            float(np.dot(geom.axes[0], np.cross(geom.axes[1], geom.axes[2]))),
        )


def _dot(a: Vec, b: Vec) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _rotate(axis: Vec, angle: float, v: Vec) -> Vec:
    """Rodrigues: R_axis(angle) v, a unit axis."""
    c, s = math.cos(angle), math.sin(angle)
    k = _dot(axis, v) * (1.0 - c)
    cx, cy, cz = _cross(axis, v)
    return (
        v[0] * c + cx * s + axis[0] * k,
        v[1] * c + cy * s + axis[1] * k,
        v[2] * c + cz * s + axis[2] * k,
    )


def _angle_about(axis: Vec, u: Vec, w: Vec) -> float:
    """Paden–Kahan subproblem 1: the angle θ with R_axis(θ) u = w (u, w of equal axial part)."""
    au, aw = _dot(axis, u), _dot(axis, w)
    return math.atan2(_dot(axis, _cross(u, w)), _dot(u, w) - au * aw)


def leg_ik_scalar(
    leg: LegConstants, x: float, y: float, z: float, rot: Sequence[float]
) -> tuple[float, float, float, float, float, float]:
    """:func:`leg_ik` on plain floats (a control tick calls it twice; no numpy overhead).

    With R = R₁ ⋯ R₆ the foot's orientation and H the hip centre, the ankle centre is
    A = p − R·sole and H − A = −R₁R₂R₃ (t₀ + R₄ s₀), so in the foot frame
    r = Rᵀ(H − A) satisfies R₅R₆ r = v(q₄) = −(R₄ᵀ t₀ + s₀):

    1. knee: |v| = |r|, cos q₄ = (|r|² − A² − B²) / (2AB) (a straight leg at zero);
    2. ankle (subproblem 2): w = R₆ r = R₅ᵀ v has a₆·w = a₆·r, a₅·w = a₅·v and |w| = |r|,
       the root nearer r (small angles);
    3. hip: M = R R₆ᵀR₅ᵀR₄ᵀ = R₁R₂R₃, sin q₂ = (a₁·(a₂×a₃)) a₁ᵀ M a₃, then q₁ from
       R₁ (R₂ a₃) = M a₃ and q₃ from R₃ (Mᵀ a₁) = R₂ᵀ a₁.

    Args:
        leg: the leg's geometry as floats.
        x, y, z: sole-point position in the pelvis frame [m].
        rot: foot orientation R in the pelvis frame, row-major, 9 floats.

    Returns:
        The six joint angles in actuator order [rad].
    """
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rot
    a1, a2, a3, a4, a5, a6 = leg.axes
    sx, sy, sz = leg.sole
    hx, hy, hz = leg.hip
    # Ankle → hip in the pelvis frame, then in the foot frame (Rᵀ d).
    dx = hx - (x - (r00 * sx + r01 * sy + r02 * sz))
    dy = hy - (y - (r10 * sx + r11 * sy + r12 * sz))
    dz = hz - (z - (r20 * sx + r21 * sy + r22 * sz))
    r = (
        r00 * dx + r10 * dy + r20 * dz,
        r01 * dx + r11 * dy + r21 * dz,
        r02 * dx + r12 * dy + r22 * dz,
    )
    a, b = leg.thigh_len, leg.shank_len
    c = min(math.sqrt(_dot(r, r)), a + b - 1e-9)
    knee = leg.knee_sign * math.acos(min(max((c * c - a * a - b * b) / (2.0 * a * b), -1.0), 1.0))
    t4 = _rotate(a4, -knee, leg.thigh)  # R₄ᵀ t₀
    s0 = leg.shank
    v = (-(t4[0] + s0[0]), -(t4[1] + s0[1]), -(t4[2] + s0[2]))
    # Ankle, subproblem 2 on perpendicular axes: w = α a₅ + β a₆ + γ (a₅ × a₆).
    n = _cross(a5, a6)
    alpha, beta = _dot(a5, v), _dot(a6, r)
    gamma = math.sqrt(max(_dot(r, r) - alpha * alpha - beta * beta, 0.0))
    if _dot(n, r) < 0.0:
        gamma = -gamma
    w = (
        alpha * a5[0] + beta * a6[0] + gamma * n[0],
        alpha * a5[1] + beta * a6[1] + gamma * n[1],
        alpha * a5[2] + beta * a6[2] + gamma * n[2],
    )
    q6 = _angle_about(a6, r, w)
    q5 = _angle_about(a5, w, v)
    # Hip: M = R R₆ᵀ R₅ᵀ R₄ᵀ; M a₃ and Mᵀ a₁ by rotating vectors.
    m_a3 = _rotate(a6, -q6, _rotate(a5, -q5, _rotate(a4, -knee, a3)))
    m_a3 = (
        r00 * m_a3[0] + r01 * m_a3[1] + r02 * m_a3[2],
        r10 * m_a3[0] + r11 * m_a3[1] + r12 * m_a3[2],
        r20 * m_a3[0] + r21 * m_a3[1] + r22 * m_a3[2],
    )
    rt_a1 = (
        r00 * a1[0] + r10 * a1[1] + r20 * a1[2],
        r01 * a1[0] + r11 * a1[1] + r21 * a1[2],
        r02 * a1[0] + r12 * a1[1] + r22 * a1[2],
    )
    mt_a1 = _rotate(a4, knee, _rotate(a5, q5, _rotate(a6, q6, rt_a1)))
    q2 = math.asin(min(max(leg.hip_det * _dot(a1, m_a3), -1.0), 1.0))
    q1 = _angle_about(a1, _rotate(a2, q2, a3), m_a3)
    q3 = _angle_about(a3, mt_a1, _rotate(a2, -q2, a1))
    angles = [0.0] * 6  # actuator order
    for i, q in zip(leg.order, (q1, q2, q3, knee, q5, q6), strict=True):
        angles[i] = q
    return angles[0], angles[1], angles[2], angles[3], angles[4], angles[5]


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
