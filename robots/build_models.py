#!/usr/bin/env python3
"""Generate the MJCF reconstructions ``robots/<name>/robot.xml`` from published figures.

Usage::

    python robots/build_models.py            # (re)write every robot.xml
    python robots/build_models.py --check    # exit 1 if a committed robot.xml is stale

The committed XML files are exactly this script's output (``tests/test_robot.py`` checks
it), so every number that sets a mass, a length, a gain or a spring lives here, next to
where it comes from; each robot's README has the full table.

What the script does for each robot:

1. It builds the robot as a tree of :class:`Body` objects drawn with primitive shapes.
2. It derives each body's ``<inertial>`` (mass, centre of mass, full inertia tensor) from
   the shapes, each shape being a uniform solid of a stated mass. Body masses are therefore
   exact, and inertias agree with the drawn geometry.
3. It compiles the model in MuJoCo and solves the ``home`` keyframe: the given knee bend,
   torso upright, feet flat, sole bottoms exactly at z = 0, the whole-body centre of mass
   above the midpoint of the two sole centres (so home is statically balanced), and the
   sole-centre midpoint at the world origin. For the series-elastic COMAN it also solves
   the spring pre-load and the servo targets that hold this posture in static equilibrium.
"""

from __future__ import annotations

import argparse
import math
import sys
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import mujoco
import numpy as np
from scipy.optimize import brentq

ROBOTS_DIR = Path(__file__).resolve().parent
Vec3 = tuple[float, float, float]

# Collision filtering shared with walkrepro.world: robot geoms touch world geoms
# (contype=1, conaffinity=3) but never each other.
ROBOT_CONTYPE = 2
ROBOT_CONAFFINITY = 1
SOLE_FRICTION = "1 0.005 0.0001"  # sliding 1.0 (project convention), MuJoCo default torsion/rolling

LEG_JOINTS = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
ARM_JOINTS = ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow")
AXIS = {
    "hip_yaw": (0, 0, 1),
    "hip_roll": (1, 0, 0),
    "hip_pitch": (0, 1, 0),
    "knee": (0, 1, 0),
    "ankle_pitch": (0, 1, 0),
    "ankle_roll": (1, 0, 0),
    "waist_yaw": (0, 0, 1),
    "waist_roll": (1, 0, 0),
    "waist_pitch": (0, 1, 0),
    "shoulder_pitch": (0, 1, 0),
    "shoulder_roll": (1, 0, 0),
    "shoulder_yaw": (0, 0, 1),
    "elbow": (0, 1, 0),
}
# Sign conventions (right-hand rule about x forward, y left, z up): positive hip pitch swings
# the leg backward, positive knee bends the knee (shank backward), positive ankle pitch turns
# the toes down, so a flat foot under a level pelvis needs hip + knee + ankle pitch = 0.
# Positive roll of a left joint moves the limb outward (to +y); the right side mirrors the
# ranges of roll and yaw joints so that both sides have the same outward/inward limits.
MIRRORED = ("hip_yaw", "hip_roll", "ankle_roll", "shoulder_roll", "shoulder_yaw")


def fmt(x: float, digits: int = 6) -> str:
    """Compact decimal text of ``x`` with ``digits`` significant digits, never ``-0``.

    Values below 1e-12 in magnitude are round-off of zero (e.g. symmetric sums) and are
    written as 0 so the file reads cleanly and regenerates identically.
    """
    if abs(x) < 1e-12:
        return "0"
    s = f"{x:.{digits}g}"
    return "0" if s in ("-0", "0") else s


def fvec(v: object, digits: int = 6) -> str:
    return " ".join(fmt(float(x), digits) for x in np.asarray(v, dtype=float).ravel())


# --------------------------------------------------------------------------------------
# Geometry and inertia
# --------------------------------------------------------------------------------------


@dataclass
class Shape:
    """A primitive solid of uniform density: drawn as a geom and counted in the inertia.

    Attributes:
        kind: "box", "sphere", "capsule" or "cylinder".
        mass: mass of this solid [kg].
        size: box half-extents (3,), sphere radius (1,), capsule/cylinder radius (1,) [m].
        pos: centre in the body frame (box, sphere) [m].
        fromto: capsule/cylinder segment end points in the body frame (6,) [m].
        collide: collision geom against the world (else visual only).
        name: geom name, or None.
        sole: a foot sole (condim 3, friction 1.0).
    """

    kind: str
    mass: float
    size: tuple[float, ...]
    pos: Vec3 = (0.0, 0.0, 0.0)
    fromto: tuple[float, ...] | None = None
    collide: bool = True
    name: str | None = None
    sole: bool = False

    def centre(self) -> np.ndarray:
        if self.fromto is not None:
            a, b = np.array(self.fromto[:3]), np.array(self.fromto[3:])
            return (a + b) / 2
        return np.array(self.pos, dtype=float)

    def rotation(self) -> np.ndarray:
        """Body-from-shape rotation; a capsule/cylinder's own z is its segment."""
        if self.fromto is None:
            return np.eye(3)
        d = np.array(self.fromto[3:]) - np.array(self.fromto[:3])
        z = d / np.linalg.norm(d)
        helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
        x = np.cross(helper, z)
        x /= np.linalg.norm(x)
        return np.column_stack([x, np.cross(z, x), z])

    def own_inertia(self) -> np.ndarray:
        """Inertia about the shape's centre in its own frame [kg m^2]."""
        m = self.mass
        if self.kind == "box":
            a, b, c = (2 * s for s in self.size)  # full edge lengths
            return m / 12 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
        if self.kind == "sphere":
            return 2 / 5 * m * self.size[0] ** 2 * np.eye(3)
        assert self.fromto is not None
        r = self.size[0]
        length = float(np.linalg.norm(np.array(self.fromto[3:]) - np.array(self.fromto[:3])))
        if self.kind == "cylinder":
            ixx = m * (3 * r * r + length * length) / 12
            return np.diag([ixx, ixx, m * r * r / 2])
        # Capsule: a cylinder plus two hemispheres, mass shared by volume.
        v_cyl, v_sph = math.pi * r * r * length, 4 / 3 * math.pi * r**3
        mc, ms = m * v_cyl / (v_cyl + v_sph), m * v_sph / (v_cyl + v_sph)
        izz = mc * r * r / 2 + ms * 2 / 5 * r * r
        ixx = mc * (r * r / 4 + length**2 / 12) + ms * (
            2 / 5 * r * r + length**2 / 4 + 3 / 8 * length * r
        )
        return np.diag([ixx, ixx, izz])


def composite_inertia(shapes: list[Shape]) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass [kg], centre of mass (3,) [m] and inertia about it (3, 3) [kg m^2] of shapes."""
    mass = sum(s.mass for s in shapes)
    com = sum(s.mass * s.centre() for s in shapes) / mass
    inertia = np.zeros((3, 3))
    for s in shapes:
        rot = s.rotation()
        d = s.centre() - com
        # Rotate the shape's own inertia into the body frame, then Steiner to the CoM.
        inertia += rot @ s.own_inertia() @ rot.T + s.mass * (d @ d * np.eye(3) - np.outer(d, d))
    return mass, com, inertia


# --------------------------------------------------------------------------------------
# Robot tree
# --------------------------------------------------------------------------------------


@dataclass
class Joint:
    """A hinge joint. ``stiffness`` > 0 makes it the spring DoF of a series-elastic joint."""

    name: str
    axis: tuple[int, int, int]
    range: tuple[float, float]
    damping: float
    armature: float
    stiffness: float = 0.0
    frictionloss: float = 0.0


@dataclass
class Site:
    name: str
    pos: Vec3


@dataclass
class Body:
    name: str
    pos: Vec3
    shapes: list[Shape]
    joints: list[Joint] = field(default_factory=list)
    sites: list[Site] = field(default_factory=list)
    children: list[Body] = field(default_factory=list)


@dataclass(frozen=True)
class JointSpec:
    """Range and drive of one link-side joint (left-side range; right mirrored if needed)."""

    range: tuple[float, float]
    damping: float
    armature: float
    ctrl_limit: float = 0.0  # |torque| limit of the <motor> [Nm] (torque robots)
    spring: float = 0.0  # spring constant of the series elastic element [Nm/rad] (COMAN)
    kd: float = 0.0  # COMAN position gain k_d [V/rad]


@dataclass
class RobotDesign:
    """Everything that goes into one robot.xml."""

    name: str
    title: str
    pelvis: Body
    joints: dict[str, JointSpec]  # link-side joint name -> spec, in actuator order
    home_knee: float  # [rad]
    home_fixed: dict[str, float]  # other non-zero home joint angles [rad]
    rgba: str
    sea: SeaModel | None = None
    drive: DriveModel | None = None


@dataclass(frozen=True)
class SeaModel:
    """COMAN's series-elastic actuation (Faraji et al., motor model Eqs. 19-20).

    Attributes:
        motor_armature: reflected motor inertia J_m [Nms^2/rad].
        motor_damping: back-EMF damping alpha / beta [Nms/rad].
        spring_damping: damping of the spring element [Nms/rad] (assumed, small).
        spring_range: deflection limit of the spring element [rad] (assumed).
        beta: voltage-torque coefficient beta [V/Nm].
        supply: supply voltage limit [V].
    """

    motor_armature: float
    motor_damping: float
    spring_damping: float
    spring_range: float
    beta: float
    supply: float


#: A drive value: one number for every joint, or one per joint kind (``hip_yaw`` … ``ankle_roll``).
PerJoint = float | dict[str, float]


def per_joint(value: PerJoint, base: str) -> float:
    """``value`` itself, or its entry for the joint kind ``base`` (e.g. ``knee``)."""
    return float(value) if isinstance(value, int | float) else float(value[base])


@dataclass(frozen=True)
class DriveModel:
    """DYROS RED's joint drive (Lee et al. §V-A): motor, 100:1 harmonic drive, current loop.

    Each joint becomes a motor DoF (the rotor, in link-side units: its angle divided by the
    gear ratio) and a spring DoF on the same axis (the harmonic drive's torsional
    compliance; link angle = motor + spring). The commanded joint torque acts on the motor
    DoF through a first-order lag (the drive's current/torque loop). See
    robots/dyros_red_actuated/README.md for every value and its source.

    Attributes:
        gear_ratio: N (paper §V-A: 100:1).
        armature: rotor inertia reflected to the link, J_rotor N² [kg m^2], per joint kind.
        motor_damping: viscous friction of motor and gear, link side [Nms/rad], per joint kind.
        friction: Coulomb friction of motor and gear, link side [Nm], per joint kind.
        stiffness: harmonic-drive torsional stiffness [Nm/rad].
        gear_damping: damping of the torsional compliance [Nms/rad].
        torque_lag: time constant of the torque loop [s].
        spring_range: deflection limit of the gear [rad].
    """

    gear_ratio: float
    armature: PerJoint
    motor_damping: PerJoint
    friction: PerJoint
    stiffness: float
    gear_damping: float
    torque_lag: float
    spring_range: float


def side_name(side: int) -> str:
    return "l" if side > 0 else "r"


def mirror_range(joint: str, rng: tuple[float, float], side: int) -> tuple[float, float]:
    if side < 0 and joint in MIRRORED:
        return (-rng[1], -rng[0])
    return rng


def joint_for(robot_joints: dict[str, JointSpec], name: str, base: str, side: int) -> list[Joint]:
    return rigid_joint_for(robot_joints, name, base, side)


def drive_joint(
    joints: dict[str, JointSpec], name: str, base: str, side: int, drive: DriveModel
) -> list[Joint]:
    """Motor DoF (rotor, friction) then gear-compliance DoF on the same axis."""
    rng = mirror_range(base, joints[name].range, side)
    return [
        Joint(
            f"{name}_motor",
            AXIS[base],
            rng,
            per_joint(drive.motor_damping, base),
            per_joint(drive.armature, base),
            frictionloss=per_joint(drive.friction, base),
        ),
        Joint(
            name,
            AXIS[base],
            (-drive.spring_range, drive.spring_range),
            drive.gear_damping,
            0.0,
            drive.stiffness,
        ),
    ]


def rigid_joint_for(
    robot_joints: dict[str, JointSpec], name: str, base: str, side: int
) -> list[Joint]:
    """The MuJoCo hinge of one rigid link-side joint (see :func:`sea_joint` for COMAN)."""
    spec = robot_joints[name]
    rng = mirror_range(base, spec.range, side)
    return [Joint(name, AXIS[base], rng, spec.damping, spec.armature)]


@dataclass(frozen=True)
class LegDims:
    """A 6-joint leg (hip yaw, roll, pitch, knee, ankle pitch, roll) made of primitives.

    Masses in [kg], lengths in [m]. Shapes are given in the frame of the link that carries
    them and are symmetric in y, so both legs use them; only ``hip``'s y is mirrored for the
    right leg. Hip roll and pitch sit at the hip-yaw origin and the ankle axes intersect.
    """

    hip: tuple[float, float]  # (y, z) of the left hip-yaw joint in the pelvis frame
    thigh_length: float  # hip pitch axis to knee axis
    shank_length: float  # knee axis to ankle pitch axis
    hip_yaw_shapes: tuple[Shape, ...]
    hip_roll_shapes: tuple[Shape, ...]
    thigh_shapes: tuple[Shape, ...]
    shank_shapes: tuple[Shape, ...]
    ankle_shapes: tuple[Shape, ...]  # the ankle pitch link
    foot_mass: float  # F/T housing + sole box (the sole takes the rest)
    ft_housing: Shape  # F/T sensor housing in the foot frame, visual only (collide=False)
    ft_site_z: float  # the <side>_foot_ft site, below the ankle axes (negative z)
    foot_size: tuple[float, float]  # sole length (x) and width (y)
    sole_half_thickness: float
    ankle_height: float  # ankle axes above the sole bottom
    foot_ahead: float  # sole centre ahead (x) of the ankle axes


def leg(side: int, dims: LegDims, joint: Callable[[str, str], list[Joint]]) -> Body:
    """The leg chain shared by every robot; ``joint(name, base)`` makes its joints.

    Hip yaw link → hip roll link → thigh → shank → ankle pitch link → foot; the foot has
    the F/T housing, the sole box ``<side>_foot_sole`` and the sites ``<side>_foot_ft``
    (force/torque sensor) and ``<side>_sole`` (sole centre, on the sole bottom).
    """
    s = side_name(side)
    lr = "left" if side > 0 else "right"
    half_t = dims.sole_half_thickness
    foot = Body(
        f"{lr}_foot",
        (0, 0, 0),  # ankle pitch and roll axes intersect
        [
            dims.ft_housing,
            Shape(
                "box",
                dims.foot_mass - dims.ft_housing.mass,
                (dims.foot_size[0] / 2, dims.foot_size[1] / 2, half_t),
                (dims.foot_ahead, 0, -dims.ankle_height + half_t),
                name=f"{lr}_foot_sole",
                sole=True,
            ),
        ],
        joint(f"{s}_ankle_roll", "ankle_roll"),
        [
            Site(f"{lr}_foot_ft", (0, 0, dims.ft_site_z)),
            Site(f"{lr}_sole", (dims.foot_ahead, 0, -dims.ankle_height)),
        ],
    )
    ankle = Body(
        f"{s}_ankle_pitch_link",
        (0, 0, -dims.shank_length),
        list(dims.ankle_shapes),
        joint(f"{s}_ankle_pitch", "ankle_pitch"),
        children=[foot],
    )
    shank = Body(
        f"{s}_shank",
        (0, 0, -dims.thigh_length),
        list(dims.shank_shapes),
        joint(f"{s}_knee", "knee"),
        children=[ankle],
    )
    thigh = Body(
        f"{s}_thigh",
        (0, 0, 0),
        list(dims.thigh_shapes),
        joint(f"{s}_hip_pitch", "hip_pitch"),
        children=[shank],
    )
    roll = Body(
        f"{s}_hip_roll_link",
        (0, 0, 0),
        list(dims.hip_roll_shapes),
        joint(f"{s}_hip_roll", "hip_roll"),
        children=[thigh],
    )
    y, z = dims.hip
    return Body(
        f"{s}_hip_yaw_link",
        (0, side * y, z),
        list(dims.hip_yaw_shapes),
        joint(f"{s}_hip_yaw", "hip_yaw"),
        children=[roll],
    )


# --------------------------------------------------------------------------------------
# DYROS RED (Paper I, Lee et al. 2021)
# --------------------------------------------------------------------------------------

DYROS_HIP_Y = 0.1025  # notes: hips ±0.1025 m lateral ...
DYROS_HIP_Z = -0.1225  # ... and 0.1225 m below the pelvis origin
DYROS_THIGH = 0.35  # notes: hip pitch to knee
DYROS_SHANK = 0.35  # notes: knee to ankle pitch
DYROS_SOLE_DEPTH = 0.137  # notes: sole 0.137 m below the (intersecting) ankle axes
DYROS_FOOT = (0.30, 0.15)  # paper §V-A: foot 0.30 m x 0.15 m
DYROS_HEIGHT = 1.43  # paper §V-A
DYROS_LEG_MASSES = (2.68, 2.67, 5.37, 3.88, 2.51, 3.46)  # notes: hip to foot [kg]
DYROS_TOTAL_MASS = 89.6  # paper §V-A
DYROS_WAIST_Z = 0.18  # notes: waist 0.18 m above the pelvis origin

DYROS_LEG = LegDims(
    hip=(DYROS_HIP_Y, DYROS_HIP_Z),
    thigh_length=DYROS_THIGH,
    shank_length=DYROS_SHANK,
    # Link masses from DYROS_LEG_MASSES (hip yaw, hip roll, thigh, shank, ankle, foot).
    hip_yaw_shapes=(
        Shape("cylinder", DYROS_LEG_MASSES[0], (0.05,), fromto=(0, 0, 0.0, 0, 0, 0.08)),
    ),
    hip_roll_shapes=(Shape("box", DYROS_LEG_MASSES[1], (0.06, 0.045, 0.045), (0, 0, 0)),),
    thigh_shapes=(
        Shape("capsule", DYROS_LEG_MASSES[2], (0.06,), fromto=(0, 0, -0.06, 0, 0, -0.30)),
    ),
    shank_shapes=(
        Shape("capsule", DYROS_LEG_MASSES[3], (0.05,), fromto=(0, 0, -0.05, 0, 0, -0.29)),
    ),
    ankle_shapes=(Shape("box", DYROS_LEG_MASSES[4], (0.045, 0.04, 0.035), (0, 0, 0)),),
    foot_mass=DYROS_LEG_MASSES[5],
    # F/T sensor and ankle roll housing.
    ft_housing=Shape("box", 1.46, (0.05, 0.05, 0.03), (0, 0, -0.07), collide=False),
    ft_site_z=-0.09,
    foot_size=DYROS_FOOT,
    sole_half_thickness=0.01,
    ankle_height=DYROS_SOLE_DEPTH,
    foot_ahead=0,
)


def dyros_leg(side: int, joints: dict[str, JointSpec], drive: DriveModel | None = None) -> Body:
    """One DYROS RED leg: rigid joints, or with ``drive`` motor and gear-compliance DoFs."""

    def joint(name: str, base: str) -> list[Joint]:
        if drive is None:
            return rigid_joint_for(joints, name, base, side)
        return drive_joint(joints, name, base, side, drive)

    return leg(side, DYROS_LEG, joint)


def build_dyros(
    drive: DriveModel | None = None,
    armature: PerJoint = 0.1,
    name: str = "",
    description: str = "",
) -> RobotDesign:
    """DYROS RED: rigid torque-driven joints, or with ``drive`` each joint's drive model.

    Args:
        drive: the joint drives (motor and gear DoFs); None for rigid joints.
        armature: reflected rotor inertia of the rigid joints [kg m^2], per joint kind.
        name: the robot's name (default ``dyros_red``, or ``dyros_red_actuated`` with a drive).
        description: the robot's one-line description (default by the same rule).
    """
    leg_mass = sum(DYROS_LEG_MASSES)
    upper = DYROS_TOTAL_MASS - 2 * leg_mass  # rigid pelvis + torso + head + arms [kg]
    straight_pelvis_z = DYROS_SOLE_DEPTH + DYROS_SHANK + DYROS_THIGH - DYROS_HIP_Z
    head_r = 0.06
    head_z = DYROS_HEIGHT - straight_pelvis_z - head_r  # head top at 1.43 m standing straight
    arm_upper, arm_fore = 2.5, 2.23
    pelvis_shapes = [
        Shape("box", 8.0, (0.10, 0.15, 0.06), (0, 0, -0.03)),  # pelvis frame and hip motors
        # Waist block up to the waist (DYROS_WAIST_Z), then the torso above it.
        Shape(
            "box", 4.0, (0.07, 0.10, (DYROS_WAIST_Z - 0.03) / 2), (0, 0, (DYROS_WAIST_Z + 0.03) / 2)
        ),
        Shape(
            "box",
            upper - 8.0 - 4.0 - 3.0 - 2 * (arm_upper + arm_fore),
            (0.11, 0.16, 0.10),
            (0, 0, 0.26),
        ),
        Shape("sphere", 3.0, (head_r,), (0, 0, head_z)),
    ]
    for side in (1, -1):
        y = side * 0.21
        pelvis_shapes += [
            Shape("capsule", arm_upper, (0.045,), fromto=(0, y, 0.31, 0, y, 0.07)),
            Shape("capsule", arm_fore, (0.04,), fromto=(0.01, y, 0.05, 0.04, y, -0.16)),
        ]
    joints: dict[str, JointSpec] = {}
    leg_ranges = {
        "hip_yaw": (-0.75, 0.75),
        "hip_roll": (-0.4, 0.6),
        "hip_pitch": (-1.8, 0.6),
        "knee": (0.0, 2.4),
        "ankle_pitch": (-1.0, 0.8),
        "ankle_roll": (-0.45, 0.45),
    }
    for s in ("l", "r"):
        for j in LEG_JOINTS:
            # lab's model (robots/dyros_red/README.md): damping 2.0 Nms/rad, ±300 Nm;
            # armature 0.1 kg m^2 assumed by default (the lab's model has none).
            joints[f"{s}_{j}"] = JointSpec(
                leg_ranges[j], damping=2.0, armature=per_joint(armature, j), ctrl_limit=300.0
            )
    pelvis = Body(
        "pelvis",
        (0, 0, 0),
        pelvis_shapes,
        sites=[Site("imu", (0, 0, 0.05))],
        children=[dyros_leg(1, joints, drive), dyros_leg(-1, joints, drive)],
    )
    if drive is not None:
        return RobotDesign(
            name or "dyros_red_actuated",
            description
            or "DYROS RED with its joint drives: rotor, harmonic-drive compliance, torque loop",
            pelvis,
            joints,
            home_knee=0.4,
            home_fixed={},
            rgba="0.75 0.15 0.15 1",
            drive=drive,
        )
    return RobotDesign(
        name or "dyros_red",
        description or "DYROS RED (12-DoF legs, rigid upper body)",
        pelvis,
        joints,
        home_knee=0.4,
        home_fixed={},
        rgba="0.75 0.15 0.15 1",
    )


# The lab's published drive values (facts with citations; repositories, paths and commits in
# robots/dyros_red_actuated/README.md). DYROS RED's legs are TOCABI's: the lab's TOCABI model
# repeats RED's leg link masses, and names each leg joint's Harmonic Drive unit (100:1):
# SHG-20-100 at hip yaw, hip roll, hip pitch, knee and ankle pitch, SHD-20-100 at the ankle roll.
DYROS_SHG20 = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch")


def shg20_shd20(shg20: float, shd20: float) -> dict[str, float]:
    """One value per leg joint kind: ``shg20`` at the SHG-20-100 joints, ``shd20`` at the ankle roll."""
    return {**dict.fromkeys(DYROS_SHG20, shg20), "ankle_roll": shd20}


#: Reflected rotor inertia, link side [kg m^2]: the TOCABI Isaac Lab configuration's armature.
DYROS_ARMATURE = {
    "hip_yaw": 0.614,
    "hip_roll": 0.862,
    "hip_pitch": 1.09,
    "knee": 1.09,
    "ankle_pitch": 1.09,
    "ankle_roll": 0.360,
}

#: DYROS RED's drives (Lee et al. §V-A; values and sources: robots/dyros_red_actuated/README.md).
DYROS_DRIVE = DriveModel(
    gear_ratio=100.0,  # paper §V-A: 100:1 harmonic gear
    armature=DYROS_ARMATURE,  # TOCABI Isaac Lab armature (rotor through 100:1), link side
    # TOCABI simulation scene, joint classes shg20_100_2so / shd20_100_2sh: damping [Nms/rad]
    # and frictionloss [Nm] as the lab's model applies them, at the link-side joint.
    motor_damping=shg20_shd20(0.0248, 0.0161),
    friction=shg20_shd20(0.9, 22.0),
    # Harmonic Drive size 32, ratio > 50 (CHA-32A data sheet, Harmonic Drive AG 1018854):
    # K1 = 6.7e4 Nm/rad below T1 = 29 Nm (K2 = 1.1e5 to T2 = 108 Nm, K3 = 1.2e5 above);
    # one linear spring, the low-torque K1 [Nm/rad].
    stiffness=6.7e4,
    gear_damping=7.0,  # assumed: light damping of the gear's compliance (README)
    torque_lag=0.5e-3,  # assumed: torque-loop time constant (≈ 320 Hz bandwidth) [s]
    spring_range=0.05,  # deflection limit [rad]: 3350 Nm at 6.7e4 Nm/rad, never reached
)

#: As DYROS_DRIVE with the SHG-20's friction of the other copies of the lab's scene (9.9 Nm).
DYROS_DRIVE_FRICTION_9_9 = replace(DYROS_DRIVE, friction=shg20_shd20(9.9, 22.0))


def build_dyros_actuated() -> RobotDesign:
    return build_dyros(DYROS_DRIVE)


def build_dyros_actuated_9_9() -> RobotDesign:
    return build_dyros(
        DYROS_DRIVE_FRICTION_9_9,
        name="dyros_red_actuated_9_9",
        description="dyros_red_actuated with 9.9 Nm of Coulomb friction at the SHG-20 joints",
    )


def build_dyros_armature() -> RobotDesign:
    return build_dyros(
        armature=DYROS_ARMATURE,
        name="dyros_red_armature",
        description="dyros_red (ideal torques) with the lab's published reflected rotor inertia",
    )


# --------------------------------------------------------------------------------------
# COMAN (Paper II, Faraji et al.)
# --------------------------------------------------------------------------------------

COMAN_TOTAL_MASS = 30.0  # paper: ≈ 30 kg
COMAN_LEG_SHARE = 0.225  # paper: each leg ≈ 22.5 % of the body mass (human: 17.3 %)
COMAN_HIP_Y = 0.07  # paper: pelvis (hip-to-hip) width ≈ 0.14 m
COMAN_THIGH = 0.22  # assumed
COMAN_SHANK = 0.25  # paper: shank ≈ 0.25 m
COMAN_ANKLE_H = 0.06  # assumed: ankle axis above the sole bottom
COMAN_FOOT = (0.22, 0.10)  # assumed (see README: the Fig. 20 lean needs ≈ 8 cm of CoP travel)
COMAN_FOOT_AHEAD = 0.03  # paper: foot centre 3 cm ahead of the ankle axis
COMAN_HEIGHT = 0.90  # paper: ≈ 0.9 m
COMAN_WAIST_Z = 0.08  # assumed: waist joints above the hip midpoint
COMAN_SEA = SeaModel(
    motor_armature=0.23,  # paper Eq. 19: J_m ≈ 0.23 Nms^2/rad
    motor_damping=5.42 / 0.45,  # paper: alpha / beta = 5.42 / 0.45 ≈ 12.04 Nms/rad
    spring_damping=3.0,  # assumed: small (a quarter of alpha/beta)
    spring_range=0.35,  # assumed: spring deflection limit
    beta=0.45,  # paper: beta ≈ 0.45 V/Nm
    supply=15.0,  # paper: 15 V supply
)
# Spring constants [Nm/rad]. Published source for COMAN's joint springs: the COMAN Robotran
# simulator of Van der Noot & Barrea (UCLouvain), github.com/NicolasVdN/CoManRobotran,
# Standalone/src/project/simulation_files/init_actuator_model.c (commit 0207863b): 395.46 at
# hip pitch, knee, ankle pitch, waist pitch and waist yaw; 120 at shoulder pitch and roll and
# the elbow; 8400 (effectively rigid) at hip roll and yaw, ankle roll, waist roll and shoulder
# yaw. IIT's CoMan simulator agrees on the leg SEA (github.com/HDallali/CoManRobotranSimulator,
# Standalone/src/project/project_files/ActuatorStruct.c: Kollmorgen RBE1211 + CSD17, 390).
# A sourced value replaced an assumption only if every coman expectation that reproduced
# still reproduced with it (README, Known deviations, Paper II; robots/coman/README.md has
# the measurements). Not adopted: ankle pitch (125 is derived from the paper's own Fig. 20
# measurement: the paper's ≈ 31 Nm/rad per ankle is the apparent stiffness F·h / (2Δθ) of
# the standing robot under a neck pull, which includes gravity's destabilising m g h_c);
# knee (395.46 breaks the forward push's corrective-step count; the paper's knee springs were
# worn, "lose their original stiffness"); the rigid 8400 joints (they break the pushes and
# the drag, though a rigid ankle roll lets the paper's hip gain and delay walk).
COMAN_SPRINGS = {
    "hip_yaw": 400.0,  # assumed (source: 8400, not adopted)
    "hip_roll": 400.0,  # assumed (source: 8400, not adopted)
    "hip_pitch": 395.46,  # source
    "knee": 300.0,  # assumed (source: 395.46, not adopted)
    "ankle_pitch": 125.0,  # derived from paper Fig. 20 (source: 395.46, not adopted)
    "ankle_roll": 125.0,  # assumed: as ankle pitch (source: 8400, not adopted)
    "waist_yaw": 395.46,  # source
    "waist_roll": 400.0,  # assumed (source: 8400, not adopted)
    "waist_pitch": 395.46,  # source
    "shoulder_pitch": 120.0,  # source
    "shoulder_roll": 120.0,  # source
    "shoulder_yaw": 100.0,  # assumed (source: 8400, not adopted)
    "elbow": 120.0,  # source
}
# Position gains k_d [V/rad] (paper): 10 ankle roll, 100 hip pitch, 500 elsewhere.
COMAN_KD = {"ankle_roll": 10.0, "hip_pitch": 100.0}
COMAN_KD_DEFAULT = 500.0


COMAN_LEG_LINK_MASSES = (0.9, 0.9, 2.0, 1.5, 0.55)  # assumed: hip yaw to ankle [kg]
COMAN_LEG = LegDims(
    hip=(COMAN_HIP_Y, 0),
    thigh_length=COMAN_THIGH,
    shank_length=COMAN_SHANK,
    hip_yaw_shapes=(
        Shape("cylinder", COMAN_LEG_LINK_MASSES[0], (0.035,), fromto=(0, 0, -0.01, 0, 0, 0.05)),
    ),
    hip_roll_shapes=(Shape("box", COMAN_LEG_LINK_MASSES[1], (0.04, 0.03, 0.03), (0, 0, -0.01)),),
    thigh_shapes=(
        Shape("capsule", COMAN_LEG_LINK_MASSES[2], (0.04,), fromto=(0, 0, -0.04, 0, 0, -0.18)),
    ),
    shank_shapes=(
        Shape("capsule", 0.9, (0.035,), fromto=(0, 0, -0.035, 0, 0, -0.2)),
        # The ankle motors sit on the shank, distal to the knee (paper).
        Shape("box", COMAN_LEG_LINK_MASSES[3] - 0.9, (0.04, 0.035, 0.04), (0, 0, -0.17)),
    ),
    ankle_shapes=(Shape("box", COMAN_LEG_LINK_MASSES[4], (0.03, 0.03, 0.025)),),
    foot_mass=COMAN_LEG_SHARE * COMAN_TOTAL_MASS - sum(COMAN_LEG_LINK_MASSES),
    ft_housing=Shape("box", 0.3, (0.03, 0.03, 0.015), (0, 0, -0.03), collide=False),
    ft_site_z=-0.04,
    foot_size=COMAN_FOOT,
    sole_half_thickness=0.0075,
    ankle_height=COMAN_ANKLE_H,
    foot_ahead=COMAN_FOOT_AHEAD,
)


def coman_leg(side: int, joints: dict[str, JointSpec]) -> Body:
    """One COMAN leg, every joint series-elastic (:func:`sea_joint`)."""
    return leg(side, COMAN_LEG, lambda name, base: sea_joint(joints, name, base, side))


@dataclass(frozen=True)
class ArmDims:
    """A 4-joint arm (shoulder pitch, roll, yaw, elbow) made of primitives.

    Masses in [kg], lengths in [m]. ``shoulder`` is the shoulder-pitch joint position in the
    trunk frame for the left arm (y is mirrored for the right arm).
    """

    shoulder: tuple[float, float]  # (y, z) of the left shoulder
    shoulder_masses: tuple[float, float]  # pitch link, roll link
    shoulder_radii: tuple[float, float]
    upper_mass: float
    upper: tuple[float, float, float]  # radius, top offset, bottom offset (negative z)
    elbow_z: float
    forearm_mass: float
    forearm: tuple[float, float, float]  # radius, top offset, bottom offset (negative z)


def arm(side: int, dims: ArmDims, joint: Callable[[str, str], list[Joint]]) -> Body:
    """The arm chain shared by coman and kist_humanoid; ``joint(name, base)`` makes its joints."""
    s = side_name(side)
    r_f, top_f, bottom_f = dims.forearm
    forearm = Body(
        f"{s}_forearm",
        (0, 0, dims.elbow_z),
        [Shape("capsule", dims.forearm_mass, (r_f,), fromto=(0, 0, top_f, 0, 0, bottom_f))],
        joint(f"{s}_elbow", "elbow"),
    )
    r_u, top_u, bottom_u = dims.upper
    upper = Body(
        f"{s}_upper_arm",
        (0, 0, 0),
        [Shape("capsule", dims.upper_mass, (r_u,), fromto=(0, 0, top_u, 0, 0, bottom_u))],
        joint(f"{s}_shoulder_yaw", "shoulder_yaw"),
        children=[forearm],
    )
    roll = Body(
        f"{s}_shoulder_roll_link",
        (0, 0, 0),
        [Shape("sphere", dims.shoulder_masses[1], (dims.shoulder_radii[1],))],
        joint(f"{s}_shoulder_roll", "shoulder_roll"),
        children=[upper],
    )
    y, z = dims.shoulder
    return Body(
        f"{s}_shoulder_pitch_link",
        (0, side * y, z),
        [Shape("sphere", dims.shoulder_masses[0], (dims.shoulder_radii[0],))],
        joint(f"{s}_shoulder_pitch", "shoulder_pitch"),
        children=[roll],
    )


COMAN_ARM = ArmDims(
    shoulder=(0.15, 0.17),
    shoulder_masses=(0.4, 0.4),
    shoulder_radii=(0.035, 0.03),
    upper_mass=0.7,
    upper=(0.03, -0.03, -0.15),
    elbow_z=-0.17,
    forearm_mass=0.7,
    forearm=(0.025, -0.02, -0.17),
)


def coman_arm(side: int, joints: dict[str, JointSpec]) -> Body:
    return arm(side, COMAN_ARM, lambda name, base: sea_joint(joints, name, base, side))


def sea_joint(joints: dict[str, JointSpec], name: str, base: str, side: int) -> list[Joint]:
    """Motor DoF then spring DoF on the same axis (link angle = motor + spring)."""
    spec = joints[name]
    sea = COMAN_SEA
    rng = mirror_range(base, spec.range, side)
    return [
        Joint(f"{name}_motor", AXIS[base], rng, sea.motor_damping, sea.motor_armature),
        Joint(
            name,
            AXIS[base],
            (-sea.spring_range, sea.spring_range),
            sea.spring_damping,
            0.0,
            spec.spring,
        ),
    ]


def build_coman() -> RobotDesign:
    leg_ranges = {
        "hip_yaw": (-0.6, 0.6),
        "hip_roll": (-0.35, 0.6),
        "hip_pitch": (-1.8, 0.6),
        "knee": (0.0, 2.2),
        "ankle_pitch": (-1.0, 0.8),
        "ankle_roll": (-0.45, 0.45),
    }
    trunk_ranges = {"waist_yaw": (-0.8, 0.8), "waist_roll": (-0.4, 0.4), "waist_pitch": (-0.4, 0.9)}
    arm_ranges = {
        "shoulder_pitch": (-2.5, 1.0),
        "shoulder_roll": (-0.2, 1.8),
        "shoulder_yaw": (-1.5, 1.5),
        "elbow": (-2.3, 0.0),
    }
    joints: dict[str, JointSpec] = {}

    def add(name: str, base: str, rng: tuple[float, float]) -> None:
        joints[name] = JointSpec(
            rng,
            COMAN_SEA.motor_damping,
            COMAN_SEA.motor_armature,
            spring=COMAN_SPRINGS[base],
            kd=COMAN_KD.get(base, COMAN_KD_DEFAULT),
        )

    for s in ("l", "r"):
        for j in LEG_JOINTS:
            add(f"{s}_{j}", j, leg_ranges[j])
    for j, rng in trunk_ranges.items():
        add(j, j, rng)
    for s in ("l", "r"):
        for j in ARM_JOINTS:
            add(f"{s}_{j}", j, arm_ranges[j])

    leg_mass = COMAN_LEG_SHARE * COMAN_TOTAL_MASS
    m_pelvis, m_waist_yaw, m_waist_roll, m_arm = 3.5, 0.5, 0.5, 2.2
    m_torso = COMAN_TOTAL_MASS - 2 * leg_mass - m_pelvis - m_waist_yaw - m_waist_roll - 2 * m_arm
    straight_pelvis_z = COMAN_ANKLE_H + COMAN_SHANK + COMAN_THIGH
    head_r = 0.06
    head_z = COMAN_HEIGHT - straight_pelvis_z - COMAN_WAIST_Z - head_r  # in the torso frame
    torso = Body(
        "torso",
        (0, 0, 0),
        [
            Shape("box", m_torso - 1.0, (0.07, 0.11, 0.09), (0, 0, 0.11)),
            Shape("sphere", 1.0, (head_r,), (0, 0, head_z)),
        ],
        sea_joint(joints, "waist_pitch", "waist_pitch", 1),
        children=[coman_arm(1, joints), coman_arm(-1, joints)],
    )
    waist_roll = Body(
        "waist_roll_link",
        (0, 0, 0),
        [Shape("box", m_waist_roll, (0.035, 0.05, 0.02))],
        sea_joint(joints, "waist_roll", "waist_roll", 1),
        children=[torso],
    )
    waist_yaw = Body(
        "waist_yaw_link",
        (0, 0, COMAN_WAIST_Z),
        [Shape("box", m_waist_yaw, (0.04, 0.05, 0.02), (0, 0, -0.02))],
        sea_joint(joints, "waist_yaw", "waist_yaw", 1),
        children=[waist_roll],
    )
    pelvis = Body(
        "pelvis",
        (0, 0, 0),
        [Shape("box", m_pelvis, (0.06, 0.10, 0.045), (0, 0, 0.03))],
        sites=[Site("imu", (0, 0, 0.03))],  # paper: the IMU is on the pelvis
        children=[coman_leg(1, joints), coman_leg(-1, joints), waist_yaw],
    )
    return RobotDesign(
        "coman",
        "COMAN (series-elastic, motor-side position control)",
        pelvis,
        joints,
        home_knee=0.4,  # paper: nominal knee angle ≈ 0.4 rad
        home_fixed={
            "l_shoulder_roll": 0.1,
            "r_shoulder_roll": -0.1,
            "l_elbow": -0.3,
            "r_elbow": -0.3,
        },
        rgba="0.2 0.35 0.7 1",
        sea=COMAN_SEA,
    )


# --------------------------------------------------------------------------------------
# KIST humanoid (Paper III, Jo & Oh)
# --------------------------------------------------------------------------------------

KIST_HIP_Y = 0.09  # assumed
KIST_HIP_Z = -0.08  # assumed
KIST_THIGH = 0.32  # assumed (brief: leg links ≈ 0.3-0.35 m)
KIST_SHANK = 0.32  # assumed
KIST_ANKLE_H = 0.10  # assumed: ankle axis above the sole; the F/T sensor sits in between
KIST_FOOT = (0.24, 0.13)  # assumed
KIST_FOOT_AHEAD = 0.02  # assumed: sole centre ahead of the ankle axis
KIST_HEIGHT = 1.55  # assumed: adult-size 1.5-1.6 m
KIST_LEG_MASS = 10.0  # paper: each leg 10 kg
KIST_ARM_MASS = 6.0  # paper: each arm 6 kg
KIST_BODY_MASS = 20.0  # paper: body 20 kg (pelvis + waist + torso here)
KIST_HEAD_MASS = 5.0  # paper: the remaining ≈ 5 kg (head)


KIST_LEG_LINK_MASSES = (1.2, 1.3, 3.0, 2.3, 0.8)  # assumed: hip yaw to ankle [kg]
KIST_LEG = LegDims(
    hip=(KIST_HIP_Y, KIST_HIP_Z),
    thigh_length=KIST_THIGH,
    shank_length=KIST_SHANK,
    hip_yaw_shapes=(
        Shape("cylinder", KIST_LEG_LINK_MASSES[0], (0.045,), fromto=(0, 0, 0.0, 0, 0, 0.07)),
    ),
    hip_roll_shapes=(Shape("box", KIST_LEG_LINK_MASSES[1], (0.06, 0.045, 0.045)),),
    thigh_shapes=(
        Shape("capsule", KIST_LEG_LINK_MASSES[2], (0.06,), fromto=(0, 0, -0.05, 0, 0, -0.27)),
    ),
    shank_shapes=(
        Shape("capsule", KIST_LEG_LINK_MASSES[3], (0.05,), fromto=(0, 0, -0.05, 0, 0, -0.27)),
    ),
    ankle_shapes=(Shape("box", KIST_LEG_LINK_MASSES[4], (0.04, 0.04, 0.035)),),
    foot_mass=KIST_LEG_MASS - sum(KIST_LEG_LINK_MASSES),
    # The 6-axis F/T sensor between ankle and sole (paper: below the ankles).
    ft_housing=Shape("box", 0.4, (0.04, 0.04, 0.015), (0, 0, -0.06), collide=False),
    ft_site_z=-0.06,
    foot_size=KIST_FOOT,
    sole_half_thickness=0.0125,
    ankle_height=KIST_ANKLE_H,
    foot_ahead=KIST_FOOT_AHEAD,
)


def kist_leg(side: int, joints: dict[str, JointSpec]) -> Body:
    """One KIST humanoid leg, every joint a rigid torque-driven hinge."""
    return leg(side, KIST_LEG, lambda name, base: joint_for(joints, name, base, side))


KIST_ARM = ArmDims(
    shoulder=(0.21, 0.34),
    shoulder_masses=(0.8, 0.8),
    shoulder_radii=(0.05, 0.045),
    upper_mass=2.2,
    upper=(0.045, -0.04, -0.22),
    elbow_z=-0.26,
    forearm_mass=2.2,
    forearm=(0.04, -0.03, -0.26),
)


def kist_arm(side: int, joints: dict[str, JointSpec]) -> Body:
    return arm(side, KIST_ARM, lambda name, base: joint_for(joints, name, base, side))


def build_kist() -> RobotDesign:
    leg_ranges = {
        "hip_yaw": (-0.75, 0.75),
        "hip_roll": (-0.4, 0.6),
        "hip_pitch": (-1.8, 0.6),
        "knee": (0.0, 2.4),
        "ankle_pitch": (-1.0, 0.8),
        "ankle_roll": (-0.45, 0.45),
    }
    trunk_ranges = {"waist_yaw": (-1.0, 1.0), "waist_pitch": (-0.4, 1.0)}
    arm_ranges = {
        "shoulder_pitch": (-3.0, 1.2),
        "shoulder_roll": (-0.2, 2.0),
        "shoulder_yaw": (-1.6, 1.6),
        "elbow": (-2.4, 0.0),
    }
    # All assumed: damping 1 Nms/rad; reflected inertia 0.1 (legs, trunk) / 0.05 (arms)
    # kg m^2; torque limits sized for a 57 kg robot.
    joints: dict[str, JointSpec] = {}
    for s in ("l", "r"):
        for j in LEG_JOINTS:
            joints[f"{s}_{j}"] = JointSpec(leg_ranges[j], 1.0, 0.1, ctrl_limit=300.0)
    for j, rng in trunk_ranges.items():
        joints[j] = JointSpec(rng, 1.0, 0.1, ctrl_limit=200.0)
    for s in ("l", "r"):
        for j in ARM_JOINTS:
            joints[f"{s}_{j}"] = JointSpec(arm_ranges[j], 1.0, 0.05, ctrl_limit=100.0)

    m_pelvis, m_waist = 8.0, 2.0
    m_torso = KIST_BODY_MASS - m_pelvis - m_waist
    straight_pelvis_z = KIST_ANKLE_H + KIST_SHANK + KIST_THIGH - KIST_HIP_Z
    # Trunk frames above the pelvis origin: waist yaw 0.10, waist pitch 0.16, head 0.58.
    head_r = 0.10
    head_center_z = KIST_HEIGHT - straight_pelvis_z - 0.58 - head_r  # in the head frame
    head = Body(
        "head",
        (0, 0, 0.42),
        [
            Shape("cylinder", 1.0, (0.04,), fromto=(0, 0, -0.04, 0, 0, 0.0)),
            Shape("sphere", KIST_HEAD_MASS - 1.0, (head_r,), (0, 0, head_center_z)),
        ],
    )
    torso = Body(
        "torso",
        (0, 0, 0.06),
        [Shape("box", m_torso, (0.11, 0.16, 0.19), (0, 0, 0.21))],
        joint_for(joints, "waist_pitch", "waist_pitch", 1),
        sites=[Site("imu", (0, 0, 0.15))],
        children=[head, kist_arm(1, joints), kist_arm(-1, joints)],
    )
    waist = Body(
        "waist_yaw_link",
        (0, 0, 0.10),
        [Shape("box", m_waist, (0.06, 0.08, 0.03), (0, 0, 0.03))],
        joint_for(joints, "waist_yaw", "waist_yaw", 1),
        children=[torso],
    )
    pelvis = Body(
        "pelvis",
        (0, 0, 0),
        [Shape("box", m_pelvis, (0.09, 0.14, 0.07))],
        children=[kist_leg(1, joints), kist_leg(-1, joints), waist],
    )
    return RobotDesign(
        "kist_humanoid",
        "KIST humanoid (22 joints, torque-controlled)",
        pelvis,
        joints,
        home_knee=0.6,
        home_fixed={
            "l_shoulder_roll": 0.1,
            "r_shoulder_roll": -0.1,
            "l_elbow": -0.3,
            "r_elbow": -0.3,
        },
        rgba="0.25 0.55 0.3 1",
    )


# --------------------------------------------------------------------------------------
# MJCF writing
# --------------------------------------------------------------------------------------


def body_element(body: Body, rgba: str) -> ET.Element:
    el = ET.Element("body", {"name": body.name, "pos": fvec(body.pos)})
    mass, com, inertia = composite_inertia(body.shapes)
    ET.SubElement(
        el,
        "inertial",
        {
            "pos": fvec(com),
            "mass": fmt(mass),
            "fullinertia": fvec(
                [
                    inertia[0, 0],
                    inertia[1, 1],
                    inertia[2, 2],
                    inertia[0, 1],
                    inertia[0, 2],
                    inertia[1, 2],
                ]
            ),
        },
    )
    for j in body.joints:
        attrs = {
            "name": j.name,
            "type": "hinge",
            "axis": fvec(j.axis),
            "range": fvec(j.range),
            "damping": fmt(j.damping),
            "armature": fmt(j.armature),
        }
        if j.stiffness:
            attrs["stiffness"] = fmt(j.stiffness)
        if j.frictionloss:
            attrs["frictionloss"] = fmt(j.frictionloss)
        ET.SubElement(el, "joint", attrs)
    for s in body.shapes:
        attrs: dict[str, str] = {}
        if s.name:
            attrs["name"] = s.name
        attrs["type"] = s.kind
        attrs["size"] = fvec(s.size)
        if s.fromto is not None:
            attrs["fromto"] = fvec(s.fromto)
        else:
            attrs["pos"] = fvec(s.pos)
        # Explicit collision attributes on every geom: the world builder composes this file
        # with its own geoms, so nothing may rely on <default> classes leaking between them.
        attrs["contype"] = str(ROBOT_CONTYPE if s.collide else 0)
        attrs["conaffinity"] = str(ROBOT_CONAFFINITY if s.collide else 0)
        attrs["condim"] = "3"
        attrs["friction"] = SOLE_FRICTION
        attrs["rgba"] = "0.15 0.15 0.15 1" if s.sole else rgba
        ET.SubElement(el, "geom", attrs)
    for site in body.sites:
        ET.SubElement(el, "site", {"name": site.name, "pos": fvec(site.pos), "size": "0.01"})
    for child in body.children:
        el.append(body_element(child, rgba))
    return el


def build_xml(robot: RobotDesign, keyframe: tuple[np.ndarray, np.ndarray] | None) -> str:
    root = ET.Element("mujoco", {"model": robot.name})
    root.append(
        ET.Comment(
            f" {robot.title}. GENERATED by robots/build_models.py: edit the script, not this. "
        )
    )
    ET.SubElement(root, "compiler", {"angle": "radian", "autolimits": "true"})
    world = ET.SubElement(root, "worldbody")
    pelvis = body_element(robot.pelvis, robot.rgba)
    pelvis.insert(1, ET.Element("freejoint", {"name": "root"}))
    world.append(pelvis)

    act = ET.SubElement(root, "actuator")
    for name, spec in robot.joints.items():
        if robot.drive is not None:
            lim = fmt(spec.ctrl_limit)
            ET.SubElement(
                act,
                "general",
                {
                    "name": name,
                    "joint": f"{name}_motor",
                    "dyntype": "filterexact",
                    "dynprm": fmt(robot.drive.torque_lag),
                    "gainprm": "1",
                    "ctrlrange": f"-{lim} {lim}",
                },
            )
        elif robot.sea is None:
            lim = fmt(spec.ctrl_limit)
            ET.SubElement(
                act,
                "motor",
                {"name": name, "joint": name, "gear": "1", "ctrlrange": f"-{lim} {lim}"},
            )
        else:
            sea = robot.sea
            kp = spec.kd / sea.beta  # servo stiffness k_d / beta [Nm/rad]
            tmax = sea.supply / sea.beta  # 15 V supply limit as a torque [Nm]
            side = 1 if not name.startswith("r_") else -1
            base = name[2:] if name[:2] in ("l_", "r_") else name
            rng = mirror_range(base, spec.range, side)
            ET.SubElement(
                act,
                "position",
                {
                    "name": name,
                    "joint": f"{name}_motor",
                    "kp": fmt(kp),
                    "ctrlrange": fvec(rng),
                    "forcerange": f"{fmt(-tmax)} {fmt(tmax)}",
                },
            )
    if robot.drive is not None:
        # Encoders before the gear (§V-A): the sensors read the motor DoF (walkrepro/robot.py).
        custom = ET.SubElement(root, "custom")
        ET.SubElement(custom, "text", {"name": "walkrepro_encoders", "data": "motor"})
    sensor = ET.SubElement(root, "sensor")
    ET.SubElement(sensor, "framequat", {"name": "imu_quat", "objtype": "site", "objname": "imu"})
    ET.SubElement(sensor, "gyro", {"name": "imu_gyro", "site": "imu"})
    ET.SubElement(sensor, "accelerometer", {"name": "imu_acc", "site": "imu"})
    for side in ("left", "right"):
        ET.SubElement(sensor, "force", {"name": f"{side}_foot_force", "site": f"{side}_foot_ft"})
        ET.SubElement(sensor, "torque", {"name": f"{side}_foot_torque", "site": f"{side}_foot_ft"})
    if keyframe is not None:
        qpos, ctrl = keyframe
        keys = ET.SubElement(root, "keyframe")
        ET.SubElement(keys, "key", {"name": "home", "qpos": fvec(qpos, 10), "ctrl": fvec(ctrl, 10)})
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"


# --------------------------------------------------------------------------------------
# Home keyframe
# --------------------------------------------------------------------------------------


def link_joints(model: mujoco.MjModel, names: list[str]) -> list[int]:
    return [model.joint(n).id for n in names]


def solve_home(robot: RobotDesign, model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """Home qpos and ctrl: balanced, feet flat, soles at z = 0 (module docstring, step 3)."""
    data = mujoco.MjData(model)
    names = list(robot.joints)
    sea = robot.sea is not None or robot.drive is not None

    def configure(ankle: float) -> np.ndarray:
        """qpos with the pelvis at the origin; for a SEA the link angle sits in the motor DoF."""
        q = model.qpos0.copy()
        q[:7] = (0, 0, 0, 1, 0, 0, 0)
        angles = dict(robot.home_fixed)
        for s in ("l", "r"):
            angles[f"{s}_knee"] = robot.home_knee
            angles[f"{s}_ankle_pitch"] = ankle
            angles[f"{s}_hip_pitch"] = -(robot.home_knee + ankle)  # feet flat, pelvis level
        for name in names:
            jn = f"{name}_motor" if sea else name
            q[model.joint(jn).qposadr[0]] = angles.get(name, 0.0)
            if sea:
                q[model.joint(name).qposadr[0]] = 0.0
        return q

    def soles(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        return data.site("left_sole").xpos.copy(), data.site("right_sole").xpos.copy()

    def com_offset(ankle: float) -> float:
        left, right = soles(configure(ankle))
        return float(data.subtree_com[model.body("pelvis").id][0] - (left[0] + right[0]) / 2)

    ankle = brentq(com_offset, -robot.home_knee, 0.0, xtol=1e-13)
    q = configure(ankle)
    left, right = soles(q)
    assert abs(left[2] - right[2]) < 1e-12, "home posture must be left/right symmetric"
    q[:3] = (-(left[0] + right[0]) / 2, 0.0, -left[2])  # sole-centre midpoint at the origin
    ctrl = np.zeros(model.nu)
    if sea:
        q, ctrl = preload_springs(robot, model, q)
    return q, ctrl


def preload_springs(
    robot: RobotDesign, model: mujoco.MjModel, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Spring deflections and servo targets that hold the home posture at rest.

    Each foot carries half the weight as a pure vertical force at its sole centre (the CoM
    is above their midpoint, so this satisfies the floating base's equilibrium). At rest the
    link-side torque each joint must supply is τ = g(q) − J_cᵀ f (MuJoCo's qfrc_bias minus
    the contact generalized forces). The spring DoF supplies it, −k q_s = τ, and the motor
    DoF, which sees the same τ, is held by its servo, kp (ctrl − q_m) = τ. With the link
    angle fixed at home: q_m = q_link − q_s.
    """
    assert robot.sea is not None or robot.drive is not None
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_forward(model, data)
    weight = float(np.sum(model.body_mass)) * float(np.linalg.norm(model.opt.gravity))
    tau = data.qfrc_bias.copy()
    for side in ("left", "right"):
        jacp = np.zeros((3, model.nv))
        mujoco.mj_jacSite(model, data, jacp, None, model.site(f"{side}_sole").id)
        tau -= jacp.T @ np.array([0.0, 0.0, weight / 2])
    assert np.max(np.abs(tau[:6])) < 1e-6, f"floating base not in equilibrium: {tau[:6]}"
    ctrl = np.zeros(model.nu)
    for i, name in enumerate(robot.joints):
        motor, spring = model.joint(f"{name}_motor"), model.joint(name)
        t = tau[spring.dofadr[0]]
        assert abs(t - tau[motor.dofadr[0]]) < 1e-9  # same axis, same subtree
        q_link = q[motor.qposadr[0]]
        q_s = -t / model.jnt_stiffness[spring.id]
        q_m = q_link - q_s
        q[spring.qposadr[0]] = q_s
        q[motor.qposadr[0]] = q_m
        if robot.drive is not None:
            continue  # torque drive: the controller supplies τ, ctrl stays 0
        kp = model.actuator_gainprm[i, 0]
        ctrl[i] = q_m + t / kp
        assert abs(t) < model.actuator_forcerange[i, 1], f"{name}: home needs {t:.1f} Nm"
    return q, ctrl


def generate(robot: RobotDesign) -> str:
    """The robot.xml text: write once without the keyframe, compile, solve home, write again."""
    model = mujoco.MjModel.from_xml_string(build_xml(robot, None))
    return build_xml(robot, solve_home(robot, model))


BUILDERS = {
    "dyros_red": build_dyros,
    "dyros_red_actuated": build_dyros_actuated,
    "dyros_red_actuated_9_9": build_dyros_actuated_9_9,
    "dyros_red_armature": build_dyros_armature,
    "coman": build_coman,
    "kist_humanoid": build_kist,
}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--check", action="store_true", help="only compare with the committed files"
    )
    args = parser.parse_args(argv)
    stale = []
    for name, build in BUILDERS.items():
        text = generate(build())
        path = ROBOTS_DIR / name / "robot.xml"
        if args.check:
            if not path.exists() or path.read_text() != text:
                stale.append(name)
        else:
            path.parent.mkdir(exist_ok=True)
            path.write_text(text)
            print(f"wrote {path.relative_to(ROBOTS_DIR.parent)}")
    if stale:
        print(f"stale robot.xml (run python robots/build_models.py): {', '.join(stale)}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
