#!/usr/bin/env python3
"""Generate the MJCF reconstructions ``robots/<name>/robot.xml`` from published figures.

Usage::

    python robots/build_models.py            # (re)write every robot.xml and README block
    python robots/build_models.py --readme   # only the README parameter blocks
    python robots/build_models.py --check    # exit 1 if a committed file is stale

The committed XML files are exactly this script's output (``tests/test_robot.py`` checks
it). Every number that sets a mass, a length, a spring, a gain, a damping, a limit, a sensor
or a contact parameter is an entry of the robot's provenance ledger
``robots/<name>/parameters.yaml`` (value, unit, class ``paper``/``source``/``assumed``/
``calibrated``, source), read by :func:`load_ledger`; this script holds only the structure
(axes, joint names, mirroring, formatting, collision bit masks) and what is derived
(inertias from shapes, masses that take what a total leaves, the home keyframe).
``tests/test_robot_ledger.py`` checks that every entry is read and that no physical literal
is left here. Each robot's README has the ledger as a generated table.

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
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from scipy.optimize import brentq

from walkrepro.sim import contact_law
from walkrepro.sim.contact_law import PointContactLaw
from walkrepro.sim.springs import SPRING_TENDON_SUFFIX, preload_deflection, spring_law
from walkrepro.specs.yamlload import load as load_yaml

ROBOTS_DIR = Path(__file__).resolve().parent
Vec3 = tuple[float, float, float]

# Collision filtering shared with walkrepro.sim.world: robot geoms touch world geoms
# (contype=1, conaffinity=3) but never each other.
ROBOT_CONTYPE = 2
ROBOT_CONAFFINITY = 1

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
# The provenance ledger: robots/<robot>/parameters.yaml
# --------------------------------------------------------------------------------------

#: The four provenance classes (shared/GUIDE.md, "Models around the controller").
LEDGER_CLASSES = ("paper", "source", "assumed", "calibrated")
#: Fields every ledger entry must have, and the optional ones.
LEDGER_REQUIRED = ("value", "unit", "class", "source")
LEDGER_OPTIONAL = ("description", "source_value")
#: The block of a robot README that ``--readme`` rewrites from the ledger.
README_BEGIN = "<!-- parameters: generated from parameters.yaml; do not edit -->"
README_END = "<!-- end of parameters -->"

LedgerValue = float | list[float] | dict[str, float] | str
#: Ledger entries named ``option_<attribute>`` set the robot's MJCF ``<option>`` attribute
#: (the scene's solver and friction cone, which the robot's lab's simulator decided); their
#: value may be the attribute's MuJoCo keyword (``elliptic``), not only a number.
OPTION_PREFIX = "option_"


class LedgerError(ValueError):
    """A ledger file is malformed; the message names the file and the entry."""


def _is_number(x: object) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _check_value(where: str, value: object) -> None:
    """A number, a list of numbers, or a mapping name -> number (per-joint tables)."""
    if _is_number(value):
        return
    if isinstance(value, list) and value and all(_is_number(v) for v in value):
        return
    if (
        isinstance(value, dict)
        and value
        and all(isinstance(k, str) and _is_number(v) for k, v in value.items())
    ):
        return
    raise LedgerError(
        f"{where}: value must be a number, a list of numbers or a mapping name -> number, "
        f"not {value!r}"
    )


def validate_entry(path: Path, name: object, entry: object) -> None:
    """Raise :class:`LedgerError` naming ``path`` and ``name`` unless the entry is well formed."""
    where = f"{path}: parameters.{name}"
    if not isinstance(name, str) or not name:
        raise LedgerError(f"{path}: parameter name {name!r} must be a non-empty string")
    if not isinstance(entry, dict):
        raise LedgerError(f"{where}: must be a mapping with {', '.join(LEDGER_REQUIRED)}")
    missing = [k for k in LEDGER_REQUIRED if k not in entry]
    if missing:
        raise LedgerError(f"{where}: missing {', '.join(missing)}")
    unknown = sorted(set(entry) - set(LEDGER_REQUIRED) - set(LEDGER_OPTIONAL))
    if unknown:
        raise LedgerError(f"{where}: unknown field(s) {', '.join(map(str, unknown))}")
    if entry["class"] not in LEDGER_CLASSES:
        raise LedgerError(
            f"{where}: class {entry['class']!r} is not one of {', '.join(LEDGER_CLASSES)}"
        )
    for key in ("unit", "source"):
        if not isinstance(entry[key], str):
            raise LedgerError(f"{where}: {key} must be a string")
    if not entry["source"].strip():
        raise LedgerError(f"{where}: source is empty")
    if not (name.startswith(OPTION_PREFIX) and isinstance(entry["value"], str)):
        _check_value(where, entry["value"])
    if "source_value" in entry:
        sv = entry["source_value"]
        if not (isinstance(sv, dict) and set(sv) == {"value", "source"}):
            raise LedgerError(f"{where}: source_value must be a mapping with value and source")
        _check_value(f"{where}.source_value", sv["value"])
        if not isinstance(sv["source"], str) or not sv["source"].strip():
            raise LedgerError(f"{where}: source_value.source is empty")


def read_ledger_file(path: Path) -> dict:
    """One ledger file, validated (its ``inherits`` is not followed here)."""
    if not path.exists():
        raise LedgerError(f"{path}: no such ledger")
    data = load_yaml(path.read_text())
    if not isinstance(data, dict) or set(data) != {"robot", "inherits", "parameters"}:
        raise LedgerError(f"{path}: the top level must have exactly robot, inherits, parameters")
    if data["robot"] != path.parent.name:
        raise LedgerError(f"{path}: robot {data['robot']!r} is not its directory's name")
    if data["inherits"] is not None and not isinstance(data["inherits"], str):
        raise LedgerError(f"{path}: inherits must be null or a robot name")
    params = data["parameters"]
    if not isinstance(params, dict) or not params:
        raise LedgerError(f"{path}: parameters must be a non-empty mapping")
    for name, entry in params.items():
        validate_entry(path, name, entry)
    return data


class Ledger:
    """A robot's resolved ledger: its own entries over those it inherits.

    Reading a value (``ledger["thigh"]``, :meth:`num`, :meth:`vec`, :meth:`table`) records
    the entry as used, so a test can check that every entry sets some number.
    """

    def __init__(self, robot: str, entries: dict[str, dict], files: dict[str, Path]) -> None:
        self.robot = robot
        self.entries = entries  # name -> entry, inherited ones first
        self.files = files  # name -> the ledger file that gives it
        self.accessed: set[str] = set()

    def __getitem__(self, name: str) -> LedgerValue:
        if name not in self.entries:
            raise LedgerError(f"{self.robot}: no ledger entry {name!r}")
        self.accessed.add(name)
        return self.entries[name]["value"]

    def num(self, name: str) -> float:
        """The entry's value as one number."""
        value = self[name]
        if not _is_number(value):
            raise LedgerError(f"{self.files[name]}: parameters.{name}: expected one number")
        return float(value)

    def vec(self, name: str, n: int | None = None) -> tuple[float, ...]:
        """The entry's value as a tuple of numbers (of length ``n`` if given)."""
        value = self[name]
        if not isinstance(value, list) or (n is not None and len(value) != n):
            raise LedgerError(
                f"{self.files[name]}: parameters.{name}: expected a list of {n or 'some'} numbers"
            )
        return tuple(float(v) for v in value)

    def table(self, name: str) -> dict[str, float]:
        """The entry's value as a mapping name -> number."""
        value = self[name]
        if not isinstance(value, dict):
            raise LedgerError(f"{self.files[name]}: parameters.{name}: expected a mapping")
        return {k: float(v) for k, v in value.items()}

    def per_joint(self, name: str) -> PerJoint:
        """The entry's value: one number for every joint, or a mapping per joint kind."""
        value = self[name]
        return self.table(name) if isinstance(value, dict) else self.num(name)

    def unused(self) -> list[str]:
        """Entries no number has read (yet)."""
        return [name for name in self.entries if name not in self.accessed]


def ledger_path(robot: str, robots_dir: Path = ROBOTS_DIR) -> Path:
    return robots_dir / robot / "parameters.yaml"


def load_ledger(robot: str, robots_dir: Path = ROBOTS_DIR) -> Ledger:
    """The robot's ledger, following ``inherits`` (entries here add or replace)."""
    chain: list[tuple[Path, dict]] = []
    name: str | None = robot
    while name is not None:
        path = ledger_path(name, robots_dir)
        if any(p == path for p, _ in chain):
            raise LedgerError(f"{path}: inherits forms a cycle")
        data = read_ledger_file(path)
        chain.append((path, data))
        name = data["inherits"]
    entries: dict[str, dict] = {}
    files: dict[str, Path] = {}
    for path, data in reversed(chain):
        for key, entry in data["parameters"].items():
            entries[key] = entry
            files[key] = path
    return Ledger(robot, entries, files)


# --------------------------------------------------------------------------------------
# Geometry and inertia
# --------------------------------------------------------------------------------------


@dataclass
class Shape:
    """A primitive solid of uniform density: drawn as a geom and counted in the inertia.

    The kind ``"inertial"`` is not drawn: a source's mass at ``pos`` with the source's inertia
    ``inertia`` about that point, for a body whose mass distribution a source gives (the
    drawn shapes then have mass 0).

    Attributes:
        kind: "box", "sphere", "capsule", "cylinder" or "inertial".
        mass: mass of this solid [kg].
        size: box half-extents (3,), sphere radius (1,), capsule/cylinder radius (1,) [m].
        pos: centre in the body frame (box, sphere) [m].
        fromto: capsule/cylinder segment end points in the body frame (6,) [m].
        collide: collision geom against the world (else visual only).
        name: geom name, or None.
        sole: a foot sole (condim 3, friction 1.0).
        inertia: "inertial" only: inertia about ``pos`` in the body frame, (Ixx, Iyy, Izz,
            Ixy, Ixz, Iyz) [kg m^2].
    """

    kind: str
    mass: float
    size: tuple[float, ...]
    pos: Vec3 = (0.0, 0.0, 0.0)
    fromto: tuple[float, ...] | None = None
    collide: bool = True
    name: str | None = None
    sole: bool = False
    inertia: tuple[float, ...] | None = None

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
        if self.kind == "inertial":
            assert self.inertia is not None
            xx, yy, zz, xy, xz, yz = self.inertia
            return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
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
    range: tuple[float, float] | None  # None: unlimited
    damping: float
    armature: float
    stiffness: float = 0.0
    frictionloss: float = 0.0
    # Width b [rad] of a dead band in series with the spring (backlash), or None for none.
    # With a band the spring is a fixed tendon on this DoF whose spring length is [-b/2, b/2]
    # (MuJoCo's dead-band tendon spring): zero torque inside the band, K (|q| - b/2) outside.
    backlash: float | None = None


@dataclass
class Site:
    name: str
    pos: Vec3


@dataclass(frozen=True)
class Inertial:
    """A body's mass properties given by a source (not derived from its shapes).

    Attributes:
        mass: [kg].
        com: centre of mass in the body frame (3,) [m].
        inertia: inertia about the centre of mass in the body frame, MuJoCo's
            ``fullinertia`` order (ixx, iyy, izz, ixy, ixz, iyz) [kg m^2].
    """

    mass: float
    com: tuple[float, ...]
    inertia: tuple[float, ...]


@dataclass
class Body:
    """A body; its ``<inertial>`` is ``inertial`` if given, else derived from ``shapes``
    (which are then drawn only: a shape's mass counts only when ``inertial`` is None)."""

    name: str
    pos: Vec3
    shapes: list[Shape]
    joints: list[Joint] = field(default_factory=list)
    sites: list[Site] = field(default_factory=list)
    children: list[Body] = field(default_factory=list)
    inertial: Inertial | None = None


@dataclass(frozen=True)
class JointSpec:
    """Range and drive of one link-side joint (left-side range; right mirrored if needed)."""

    range: tuple[float, float]
    damping: float
    armature: float
    ctrl_limit: float = 0.0  # |torque| limit of the <motor> [Nm] (torque robots)
    spring: float = 0.0  # spring constant of the series elastic element [Nm/rad] (COMAN)
    kd: float = 0.0  # COMAN position gain k_d [V/rad]
    spring_damping: float | None = (
        None  # this joint's spring damping [Nms/rad], else the SeaModel's
    )
    backlash: float | None = None  # dead band b in series with the spring [rad] (coman_lab)


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
    friction: str  # every geom's friction attribute (sliding, torsional, rolling)
    condim: str  # every geom's contact dimensionality
    ledger: Ledger  # the provenance ledger the numbers came from
    sea: SeaModel | None = None
    drive: DriveModel | None = None
    ground: GroundLaw | None = None  # a point-contact ground law on the soles (coman_lab)
    options: dict[str, str] = field(default_factory=dict)  # the MJCF <option> attributes

    def __post_init__(self) -> None:
        self.options = mjcf_options(self.ledger)


@dataclass(frozen=True)
class GroundLaw:
    """The lab's point-contact ground law (walkrepro.sim.contact_law) and each sole's points.

    Attributes:
        law: the law's parameters.
        points: foot body name -> (n, 3) contact points in that body's frame [m].
    """

    law: PointContactLaw
    points: dict[str, np.ndarray]


@dataclass(frozen=True)
class SeaModel:
    """COMAN's series-elastic actuation (Faraji et al., motor model Eqs. 19-20).

    Attributes:
        motor_armature: reflected motor inertia J_m [Nms^2/rad].
        motor_damping: back-EMF damping alpha / beta [Nms/rad].
        spring_damping: damping of the spring element [Nms/rad] (a joint's
            ``JointSpec.spring_damping`` overrides it).
        spring_range: deflection limit of the spring element [rad], None for none.

    Values, classes and sources: ``robots/coman/parameters.yaml``.
        beta: voltage-torque coefficient beta [V/Nm].
        supply: supply voltage limit [V].
    """

    motor_armature: float
    motor_damping: float
    spring_damping: float
    spring_range: float | None
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
    robots/dyros_red_actuated/parameters.yaml for every value and its source.

    Attributes:
        armature: rotor inertia reflected to the link, J_rotor N² [kg m^2], per joint kind.
        motor_damping: viscous friction of motor and gear, link side [Nms/rad], per joint kind.
        friction: Coulomb friction of motor and gear, link side [Nm], per joint kind.
        stiffness: harmonic-drive torsional stiffness [Nm/rad].
        gear_damping: damping of the torsional compliance [Nms/rad].
        torque_lag: time constant of the torque loop [s].
        spring_range: deflection limit of the gear [rad].
    """

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
    foot_shapes: tuple[Shape, ...] = ()  # further shapes of the foot (a source's inertial)


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
            *dims.foot_shapes,
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
# Shapes from ledger entries
# --------------------------------------------------------------------------------------


def z_segment(kind: str, mass: float, dims: tuple[float, ...]) -> Shape:
    """A capsule or cylinder along the body's z: ``dims`` = (radius, z of one end, z of the other)."""
    r, z0, z1 = dims
    return Shape(kind, mass, (r,), fromto=(0, 0, z0, 0, 0, z1))


def box_at_z(mass: float, dims: tuple[float, ...], collide: bool = True) -> Shape:
    """A box on the body's z axis: ``dims`` = (half x, half y, half z) or those and centre z."""
    z = dims[3] if len(dims) == 4 else 0
    return Shape("box", mass, dims[:3], (0, 0, z), collide=collide)


def joint_ranges(p: Ledger, joints: tuple[str, ...]) -> dict[str, tuple[float, float]]:
    """Each joint kind's left-side range, from the ledger entries ``range_<joint>``."""
    return {j: p.vec(f"range_{j}", 2) for j in joints}  # type: ignore[misc]


def contact(p: Ledger) -> tuple[str, str]:
    """Every geom's ``friction`` and ``condim`` attributes, from the ledger."""
    return fvec(p.vec("geom_friction", 3)), str(int(p.num("condim")))


def home_arms(p: Ledger) -> dict[str, float]:
    """Home arm angles: shoulder roll outward on both sides (mirrored), elbows bent."""
    roll, elbow = p.num("home_shoulder_roll"), p.num("home_elbow")
    return {"l_shoulder_roll": roll, "r_shoulder_roll": -roll, "l_elbow": elbow, "r_elbow": elbow}


def leg_dims(
    p: Ledger,
    hip: tuple[float, float],
    shank_shapes: tuple[Shape, ...],
    foot_mass: float,
    foot_size: tuple[float, float],
) -> LegDims:
    """The leg every robot builds the same way from its ledger; the caller gives the hip
    position, the shank's shapes, the foot's mass and the sole's length and width."""
    masses = p.vec("leg_link_masses")
    return LegDims(
        hip=hip,
        thigh_length=p.num("thigh"),
        shank_length=p.num("shank"),
        hip_yaw_shapes=(z_segment("cylinder", masses[0], p.vec("hip_yaw_link_shape", 3)),),
        hip_roll_shapes=(box_at_z(masses[1], p.vec("hip_roll_link_shape")),),
        thigh_shapes=(z_segment("capsule", masses[2], p.vec("thigh_shape", 3)),),
        shank_shapes=shank_shapes,
        ankle_shapes=(box_at_z(masses[4], p.vec("ankle_link_shape")),),
        foot_mass=foot_mass,
        ft_housing=box_at_z(p.num("ft_housing_mass"), p.vec("ft_housing_shape", 4), collide=False),
        ft_site_z=p.num("ft_site_z"),
        foot_size=foot_size,
        sole_half_thickness=p.num("sole_half_thickness"),
        ankle_height=p.num("ankle_height"),
        foot_ahead=p.num("foot_ahead"),
    )


# --------------------------------------------------------------------------------------
# DYROS RED (Paper I, Lee et al. 2021): robots/dyros_red*/parameters.yaml
# --------------------------------------------------------------------------------------


def isotropic_inertial(mass: float, com: tuple[float, ...], inertia: float) -> Shape:
    """A source's link inertial: ``mass`` at ``com`` with the isotropic moment ``inertia``."""
    return Shape("inertial", mass, (), com, inertia=(inertia, inertia, inertia, 0, 0, 0))


def dyros_leg_dims(p: Ledger, side: int) -> LegDims:
    """DYROS RED's leg (``side`` 1 left, -1 right): the lab model's link masses, centres of
    mass (left side; y mirrored on the right) and isotropic inertias, hip yaw, hip roll,
    thigh, shank, ankle, foot; the drawn shapes have no mass."""
    masses = p.vec("leg_link_masses", 6)
    coms = p.vec("leg_link_coms", 18)
    moments = p.vec("leg_link_inertias", 6)
    inertials = [
        isotropic_inertial(m, (coms[3 * i], side * coms[3 * i + 1], coms[3 * i + 2]), moments[i])
        for i, m in enumerate(masses)
    ]
    hip = p.vec("hip_position", 2)
    length, width = p.vec("foot_size", 2)
    return LegDims(
        hip=(hip[0], hip[1]),
        thigh_length=p.num("thigh"),
        shank_length=p.num("shank"),
        hip_yaw_shapes=(z_segment("cylinder", 0, p.vec("hip_yaw_link_shape", 3)), inertials[0]),
        hip_roll_shapes=(box_at_z(0, p.vec("hip_roll_link_shape")), inertials[1]),
        thigh_shapes=(z_segment("capsule", 0, p.vec("thigh_shape", 3)), inertials[2]),
        shank_shapes=(z_segment("capsule", 0, p.vec("shank_shape", 3)), inertials[3]),
        ankle_shapes=(box_at_z(0, p.vec("ankle_link_shape")), inertials[4]),
        foot_mass=0,
        ft_housing=box_at_z(0, p.vec("ft_housing_shape", 4), collide=False),
        ft_site_z=p.num("ft_site_z"),
        foot_size=(length, width),
        sole_half_thickness=p.num("sole_half_thickness"),
        ankle_height=p.num("ankle_height"),
        foot_ahead=p.num("foot_ahead"),
        foot_shapes=(inertials[5],),
    )


def dyros_leg(side: int, p: Ledger, joints: dict[str, JointSpec], drive: DriveModel | None) -> Body:
    """One DYROS RED leg: rigid joints, or with ``drive`` motor and gear-compliance DoFs."""

    def joint(name: str, base: str) -> list[Joint]:
        if drive is None:
            return rigid_joint_for(joints, name, base, side)
        return drive_joint(joints, name, base, side, drive)

    return leg(side, dyros_leg_dims(p, side), joint)


def dyros_drive(p: Ledger) -> DriveModel:
    """DYROS RED's drives (Lee et al. §V-A): the lab's published values and the catalogue's."""
    return DriveModel(
        armature=p.per_joint("armature"),
        motor_damping=p.per_joint("joint_damping"),
        friction=p.per_joint("friction"),
        stiffness=p.num("gear_stiffness"),
        gear_damping=p.num("gear_damping"),
        torque_lag=p.num("torque_lag"),
        spring_range=p.num("gear_range"),
    )


def build_dyros(robot: str = "dyros_red", description: str = "") -> RobotDesign:
    """DYROS RED or one of its variants, from ``robots/<robot>/parameters.yaml``.

    A ledger with a ``torque_lag`` entry has the joint drives (motor and gear DoFs); the
    others have rigid joints with ideal torques.
    """
    p = load_ledger(robot)
    drive = dyros_drive(p) if "torque_lag" in p.entries else None
    leg_mass = sum(p.vec("leg_link_masses", 6))
    upper = p.num("total_mass") - 2 * leg_mass  # rigid pelvis + torso + head + arms [kg]
    # The lab model's bodies above the hips lumped into one inertial, scaled (mass and
    # inertia, same centre of mass) to make up the paper's total.
    scale = upper / p.num("upper_body_lab_mass")
    upper_inertial = Shape(
        "inertial",
        upper,
        (),
        p.vec("upper_body_com", 3),  # type: ignore[arg-type]
        inertia=tuple(scale * i for i in p.vec("upper_body_inertia", 6)),
    )
    thigh, shank, sole_depth = p.num("thigh"), p.num("shank"), p.num("ankle_height")
    hip_z = p.vec("hip_position", 2)[1]
    waist_z = p.num("waist_height")
    straight_pelvis_z = sole_depth + shank + thigh - hip_z
    head_r = p.num("head_radius")
    head_z = p.num("height") - straight_pelvis_z - head_r  # head top at the height, legs straight
    wx, wy, w_bottom = p.vec("waist_block_shape", 3)
    # The drawn shapes have no mass: the upper body's mass is the lab's (upper_inertial).
    pelvis_shapes = [
        box_at_z(0, p.vec("pelvis_block_shape", 4)),  # pelvis frame and hip motors
        # Waist block up to the waist (waist_height), then the torso above it.
        Shape("box", 0, (wx, wy, (waist_z - w_bottom) / 2), (0, 0, (waist_z + w_bottom) / 2)),
        box_at_z(0, p.vec("torso_shape", 4)),
        Shape("sphere", 0, (head_r,), (0, 0, head_z)),
        upper_inertial,
    ]
    arm_y = p.num("arm_y")
    r_u, top_u, bottom_u = p.vec("upper_arm_shape", 3)
    r_f, x0_f, z0_f, x1_f, z1_f = p.vec("forearm_shape", 5)
    for side in (1, -1):
        y = side * arm_y
        pelvis_shapes += [
            Shape("capsule", 0, (r_u,), fromto=(0, y, top_u, 0, y, bottom_u)),
            Shape("capsule", 0, (r_f,), fromto=(x0_f, y, z0_f, x1_f, y, z1_f)),
        ]
    joints: dict[str, JointSpec] = {}
    leg_ranges = joint_ranges(p, LEG_JOINTS)
    armature = p.per_joint("armature")
    damping = None if drive is not None else p.num("joint_damping")  # drives: motor_damping
    for s in ("l", "r"):
        for j in LEG_JOINTS:
            joints[f"{s}_{j}"] = JointSpec(
                leg_ranges[j],
                damping=damping or 0.0,
                armature=per_joint(armature, j),
                ctrl_limit=p.num("torque_limit"),
            )
    pelvis = Body(
        "pelvis",
        (0, 0, 0),
        pelvis_shapes,
        sites=[Site("imu", (0, 0, p.num("imu_z")))],
        children=[dyros_leg(1, p, joints, drive), dyros_leg(-1, p, joints, drive)],
    )
    friction, condim = contact(p)
    return RobotDesign(
        robot,
        description,
        pelvis,
        joints,
        home_knee=p.num("home_knee"),
        home_fixed={},
        rgba="0.75 0.15 0.15 1",
        drive=drive,
        friction=friction,
        condim=condim,
        ledger=p,
    )


# The lab's TOCABI model names each leg joint's Harmonic Drive unit (100:1): SHG-20-100 at hip
# yaw, hip roll, hip pitch, knee and ankle pitch, SHD-20-100 at the ankle roll (sources:
# robots/dyros_red_actuated/parameters.yaml).
DYROS_SHG20 = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch")


def shg20_shd20(shg20: float, shd20: float) -> dict[str, float]:
    """One value per leg joint kind: ``shg20`` at the SHG-20-100 joints, ``shd20`` at the ankle roll."""
    return {**dict.fromkeys(DYROS_SHG20, shg20), "ankle_roll": shd20}


def build_dyros_red() -> RobotDesign:
    return build_dyros("dyros_red", "DYROS RED (12-DoF legs, rigid upper body)")


def build_dyros_actuated() -> RobotDesign:
    return build_dyros(
        "dyros_red_actuated",
        "DYROS RED with its joint drives: rotor, harmonic-drive compliance, torque loop",
    )


def build_dyros_actuated_9_9() -> RobotDesign:
    return build_dyros(
        "dyros_red_actuated_9_9",
        "dyros_red_actuated with 9.9 Nm of Coulomb friction at the SHG-20 joints",
    )


def build_dyros_armature() -> RobotDesign:
    return build_dyros(
        "dyros_red_armature",
        "dyros_red (ideal torques) with the lab's published reflected rotor inertia",
    )


# --------------------------------------------------------------------------------------
# Arms (COMAN and the KIST humanoid)
# --------------------------------------------------------------------------------------


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


def arm_dims(p: Ledger, forearm_mass: float | None = None) -> ArmDims:
    """The arm from the ledger; ``forearm_mass`` if the caller derives it from a total."""
    return ArmDims(
        shoulder=p.vec("shoulder_position", 2),  # type: ignore[arg-type]
        shoulder_masses=p.vec("shoulder_link_masses", 2),  # type: ignore[arg-type]
        shoulder_radii=p.vec("shoulder_link_radii", 2),  # type: ignore[arg-type]
        upper_mass=p.num("upper_arm_mass"),
        upper=p.vec("upper_arm_shape", 3),  # type: ignore[arg-type]
        elbow_z=p.num("elbow_z"),
        forearm_mass=p.num("forearm_mass") if forearm_mass is None else forearm_mass,
        forearm=p.vec("forearm_shape", 3),  # type: ignore[arg-type]
    )


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


# --------------------------------------------------------------------------------------
# COMAN (Paper II, Faraji et al.): robots/coman/parameters.yaml
# --------------------------------------------------------------------------------------


def coman_sea(p: Ledger) -> SeaModel:
    """COMAN's series-elastic actuation (Faraji et al., motor model Eqs. 19-20)."""
    return SeaModel(
        motor_armature=p.num("motor_armature"),
        motor_damping=p.num("alpha") / p.num("beta"),  # back-EMF alpha / beta [Nms/rad]
        spring_damping=p.num("spring_damping"),
        spring_range=p.num("spring_range"),
        beta=p.num("beta"),
        supply=p.num("supply"),
    )


def sea_joint(
    joints: dict[str, JointSpec], name: str, base: str, side: int, sea: SeaModel
) -> list[Joint]:
    """Motor DoF then spring DoF on the same axis (link angle = motor + spring)."""
    spec = joints[name]
    rng = mirror_range(base, spec.range, side)
    limit = sea.spring_range
    return [
        Joint(f"{name}_motor", AXIS[base], rng, sea.motor_damping, sea.motor_armature),
        Joint(
            name,
            AXIS[base],
            None if limit is None else (-limit, limit),
            sea.spring_damping if spec.spring_damping is None else spec.spring_damping,
            0.0,
            spec.spring,
            backlash=spec.backlash,
        ),
    ]


def coman_actuator_order() -> list[tuple[str, str]]:
    """(joint name, its base name) of COMAN's 23 actuated joints in actuator order: legs,
    waist, arms (the controllers address them by name; both COMAN models share it)."""
    legs = [(f"{s}_{j}", j) for s in ("l", "r") for j in LEG_JOINTS]
    waist = [(j, j) for j in ("waist_yaw", "waist_roll", "waist_pitch")]
    arms = [(f"{s}_{j}", j) for s in ("l", "r") for j in ARM_JOINTS]
    return legs + waist + arms


def build_coman() -> RobotDesign:
    p = load_ledger("coman")
    sea = coman_sea(p)
    total = p.num("total_mass")
    leg_mass = p.num("leg_mass_share") * total
    ranges = joint_ranges(p, LEG_JOINTS + ("waist_yaw", "waist_roll", "waist_pitch") + ARM_JOINTS)
    gains = p.table("position_gain")
    joints: dict[str, JointSpec] = {}

    def add(name: str, base: str) -> None:
        joints[name] = JointSpec(
            ranges[base],
            sea.motor_damping,
            sea.motor_armature,
            spring=p.num(f"spring_{base}"),
            kd=gains[base],
        )

    for name, base in coman_actuator_order():
        add(name, base)

    def joint(side: int) -> Callable[[str, str], list[Joint]]:
        return lambda name, base: sea_joint(joints, name, base, side, sea)

    masses = p.vec("leg_link_masses", 5)  # hip yaw to ankle [kg]; the foot takes the rest
    tube_mass = p.num("shank_tube_mass")
    shank = (
        z_segment("capsule", tube_mass, p.vec("shank_tube_shape", 3)),
        # The ankle motors sit on the shank, distal to the knee (paper).
        box_at_z(masses[3] - tube_mass, p.vec("ankle_motor_box_shape", 4)),
    )
    foot = (p.num("foot_length"), p.num("foot_width"))
    dims = leg_dims(p, (p.num("hip_y"), 0), shank, leg_mass - sum(masses), foot)
    arms = arm_dims(p)
    m_arm = arms.shoulder_masses[0] + arms.shoulder_masses[1] + arms.upper_mass + arms.forearm_mass
    m_pelvis, m_waist_yaw, m_waist_roll = (
        p.num("pelvis_mass"),
        p.num("waist_yaw_link_mass"),
        p.num("waist_roll_link_mass"),
    )
    m_torso = total - 2 * leg_mass - m_pelvis - m_waist_yaw - m_waist_roll - 2 * m_arm
    waist_z = p.num("waist_z")
    straight_pelvis_z = p.num("ankle_height") + p.num("shank") + p.num("thigh")
    head_r, m_head = p.num("head_radius"), p.num("head_mass")
    head_z = p.num("height") - straight_pelvis_z - waist_z - head_r  # in the torso frame
    torso = Body(
        "torso",
        (0, 0, 0),
        [
            box_at_z(m_torso - m_head, p.vec("torso_shape", 4)),
            Shape("sphere", m_head, (head_r,), (0, 0, head_z)),
        ],
        sea_joint(joints, "waist_pitch", "waist_pitch", 1, sea),
        children=[arm(1, arms, joint(1)), arm(-1, arms, joint(-1))],
    )
    waist_roll = Body(
        "waist_roll_link",
        (0, 0, 0),
        [box_at_z(m_waist_roll, p.vec("waist_roll_link_shape", 3))],
        sea_joint(joints, "waist_roll", "waist_roll", 1, sea),
        children=[torso],
    )
    waist_yaw = Body(
        "waist_yaw_link",
        (0, 0, waist_z),
        [box_at_z(m_waist_yaw, p.vec("waist_yaw_link_shape", 4))],
        sea_joint(joints, "waist_yaw", "waist_yaw", 1, sea),
        children=[waist_roll],
    )
    pelvis = Body(
        "pelvis",
        (0, 0, 0),
        [box_at_z(m_pelvis, p.vec("pelvis_shape", 4))],
        sites=[Site("imu", (0, 0, p.num("imu_z")))],
        children=[leg(1, dims, joint(1)), leg(-1, dims, joint(-1)), waist_yaw],
    )
    friction, condim = contact(p)
    return RobotDesign(
        "coman",
        "COMAN (series-elastic, motor-side position control)",
        pelvis,
        joints,
        home_knee=p.num("home_knee"),
        home_fixed=home_arms(p),
        rgba="0.2 0.35 0.7 1",
        sea=sea,
        friction=friction,
        condim=condim,
        ledger=p,
    )


# --------------------------------------------------------------------------------------
# COMAN from its lab's Robotran model (Paper II): robots/coman_lab/parameters.yaml
# --------------------------------------------------------------------------------------

#: The lab model's chains, root to tip, as (MJCF body, joint kind that moves it); the
#: Robotran order (hip pitch, roll, yaw; ankle roll then pitch; waist roll, pitch, yaw),
#: not robots/coman's. ``{s}`` is the side letter, ``{side}`` the side word.
LAB_LEG = (
    ("{s}_hip_pitch_link", "hip_pitch"),
    ("{s}_hip_roll_link", "hip_roll"),
    ("{s}_thigh", "hip_yaw"),
    ("{s}_shank", "knee"),
    ("{s}_ankle_roll_link", "ankle_roll"),
    ("{side}_foot", "ankle_pitch"),
)
LAB_WAIST = (
    ("waist_roll_link", "waist_roll"),
    ("waist_pitch_link", "waist_pitch"),
    ("torso", "waist_yaw"),
)
LAB_ARM = (
    ("{s}_shoulder_pitch_link", "shoulder_pitch"),
    ("{s}_shoulder_roll_link", "shoulder_roll"),
    ("{s}_upper_arm", "shoulder_yaw"),
    ("{s}_forearm", "elbow"),
)


def lab_inertial(p: Ledger, body: str) -> Inertial:
    """The lab's mass, centre of mass and inertia of ``body`` (ledger ``<body>_mass`` …)."""
    return Inertial(p.num(f"{body}_mass"), p.vec(f"{body}_com", 3), p.vec(f"{body}_inertia", 6))


def lab_links(shapes_to: list[Vec3], radius: float) -> list[Shape]:
    """Massless capsules from the body origin to each of ``shapes_to`` (its children's
    anchors), or a sphere at the origin when none is apart from it: drawn, and touching
    the ground only for the fall detector."""
    ends = [end for end in shapes_to if np.linalg.norm(end) > 0]
    if not ends:
        return [Shape("sphere", 0.0, (radius,))]
    return [Shape("capsule", 0.0, (radius,), fromto=(0, 0, 0, *end)) for end in ends]


def lab_chain(
    p: Ledger,
    links: tuple[tuple[str, str], ...],
    side: int,
    joint: Callable[[str, str], list[Joint]],
    tip: Body | None,
    tip_extent: Vec3 | None = None,
) -> Body:
    """A chain of the lab's bodies (``links`` root to tip), each at its anchor in its
    parent's frame, moved by its joint; ``tip`` hangs from the last body (the ledger's
    anchor of ``tip`` places it) and ``tip_extent`` is drawn from the last body when it
    has no child."""
    s, word = side_name(side), "left" if side > 0 else "right"
    radius = p.num("link_radius")
    child, child_pos = tip, None if tip is None else tip.pos
    for body_name, base in reversed(links):
        name = body_name.format(s=s, side=word)
        joint_name = base if base.startswith("waist") else f"{s}_{base}"
        ends = [child_pos] if child_pos is not None else [tip_extent] if tip_extent else []
        body = Body(
            name,
            p.vec(f"{name}_anchor", 3),  # type: ignore[arg-type]
            lab_links(ends, radius),  # type: ignore[arg-type]
            joint(joint_name, base),
            children=[] if child is None else [child],
            inertial=lab_inertial(p, name),
        )
        child, child_pos = body, body.pos
    assert child is not None
    return child


def lab_foot(p: Ledger, side: int, joint: Callable[[str, str], list[Joint]]) -> Body:
    """The rigid foot: the lab's inertial, a drawn sole box, the F/T and sole sites."""
    word = "left" if side > 0 else "right"
    (x0, x1), (y0, y1) = p.vec("sole_x_range", 2), p.vec("sole_y_range", 2)
    z, half_t = p.num("sole_z"), p.num("sole_half_thickness")
    centre = ((x0 + x1) / 2, (y0 + y1) / 2, z)
    sole = Shape(
        "box",
        0.0,
        ((x1 - x0) / 2, (y1 - y0) / 2, half_t),
        (centre[0], centre[1], z + half_t),
        collide=False,  # drawn only: the ground law's points hold the foot
        name=f"{word}_foot_sole",
        sole=True,
    )
    return Body(
        f"{word}_foot",
        p.vec(f"{word}_foot_anchor", 3),  # type: ignore[arg-type]
        [sole],
        joint(f"{side_name(side)}_ankle_pitch", "ankle_pitch"),
        # The lab's foot force sensor is on the sole (point Foots), so is the F/T site.
        [Site(f"{word}_foot_ft", (0, 0, z)), Site(f"{word}_sole", centre)],
        inertial=lab_inertial(p, f"{word}_foot"),
    )


def build_coman_lab() -> RobotDesign:
    """COMAN from its lab's Robotran model (rigid feet), the paper's drives and gains, and
    the lab's ground law on the soles (robots/coman_lab/README.md)."""
    p = load_ledger("coman_lab")
    sea = SeaModel(
        motor_armature=p.num("motor_armature"),
        motor_damping=p.num("alpha") / p.num("beta"),  # back-EMF alpha / beta [Nms/rad]
        spring_damping=0.0,  # unused: every joint has its own (JointSpec.spring_damping)
        spring_range=None,  # the lab's springs have no deflection stop
        beta=p.num("beta"),
        supply=p.num("supply"),
    )
    springs, spring_damping = p.table("spring"), p.table("spring_damping")
    backlash = p.table("backlash")  # knee and ankle pitch (the paper's backlashes)
    gains = p.table("position_gain")
    kinds = LEG_JOINTS + ("waist_yaw", "waist_roll", "waist_pitch") + ARM_JOINTS
    ranges = {j: tuple(math.radians(a) for a in p.vec(f"range_{j}", 2)) for j in kinds}
    joints: dict[str, JointSpec] = {}

    def add(name: str, base: str) -> None:
        joints[name] = JointSpec(
            ranges[base],  # type: ignore[arg-type]
            sea.motor_damping,
            sea.motor_armature,
            spring=springs[base],
            kd=gains[base],
            spring_damping=spring_damping[base],
            backlash=backlash.get(base),
        )

    # Actuators in robots/coman's order (the controllers address them by name).
    for name, base in coman_actuator_order():
        add(name, base)

    def joint(side: int) -> Callable[[str, str], list[Joint]]:
        return lambda name, base: sea_joint(joints, name, base, side, sea)

    legs = [
        lab_chain(p, LAB_LEG[:-1], side, joint(side), lab_foot(p, side, joint(side)))
        for side in (1, -1)
    ]
    wrist = p.vec("wrist_anchor", 3)
    arms = [lab_chain(p, LAB_ARM, side, joint(side), None, wrist) for side in (1, -1)]  # type: ignore[arg-type]
    torso_radius = p.num("link_radius")
    waist = lab_chain(p, LAB_WAIST, 1, joint(1), None)
    torso = waist.children[0].children[0]
    torso.children = arms
    torso.shapes = lab_links([arm.pos for arm in arms], torso_radius)
    pelvis = Body(
        "pelvis",
        (0, 0, 0),
        lab_links([leg.pos for leg in legs] + [waist.pos], torso_radius),
        sites=[Site("imu", (0, 0, 0))],  # the lab's base sensor MidWaist, at the origin
        children=[*legs, waist],
        inertial=lab_inertial(p, "pelvis"),
    )
    spacing = p.num("contact_grid_spacing")
    points = contact_law.sole_grid(
        p.vec("sole_x_range", 2),  # type: ignore[arg-type]
        p.vec("sole_y_range", 2),  # type: ignore[arg-type]
        p.num("sole_z"),
        spacing,
    )
    law = PointContactLaw(
        stiffness=p.num("ground_stiffness"),
        velocity_scale=p.num("ground_velocity_scale"),
        tangential_stiffness=p.num("ground_tangential_stiffness"),
        tangential_damping=p.num("ground_tangential_damping"),
        friction=p.num("ground_friction"),
    )
    friction, condim = contact(p)
    return RobotDesign(
        "coman_lab",
        "COMAN from its lab's Robotran model (series-elastic, motor-side position control)",
        pelvis,
        joints,
        home_knee=p.num("home_knee"),
        home_fixed={},  # every other joint at the lab's q = 0
        rgba="0.2 0.35 0.7 1",
        sea=sea,
        friction=friction,
        condim=condim,
        ledger=p,
        ground=GroundLaw(law, {"left_foot": points, "right_foot": points}),
    )


# --------------------------------------------------------------------------------------
# KIST humanoid (Paper III, Jo & Oh): robots/kist_humanoid/parameters.yaml
# --------------------------------------------------------------------------------------


def build_kist() -> RobotDesign:
    p = load_ledger("kist_humanoid")
    leg_total = p.num("leg_mass")
    masses = p.vec("leg_link_masses", 5)  # hip yaw to ankle [kg]; the foot takes the rest
    hip = p.vec("hip_position", 2)
    shank = (z_segment("capsule", masses[3], p.vec("shank_shape", 3)),)
    length, width = p.vec("foot_size", 2)
    dims = leg_dims(p, (hip[0], hip[1]), shank, leg_total - sum(masses), (length, width))
    m_shoulders = p.vec("shoulder_link_masses", 2)
    # The forearm (with the hand) takes what the paper's arm mass leaves.
    forearm = p.num("arm_mass") - m_shoulders[0] - m_shoulders[1] - p.num("upper_arm_mass")
    arms = arm_dims(p, forearm_mass=forearm)
    ranges = joint_ranges(p, LEG_JOINTS + ("waist_yaw", "waist_pitch") + ARM_JOINTS)
    damping = p.num("joint_damping")
    armature, limit = p.table("armature"), p.table("torque_limit")
    joints: dict[str, JointSpec] = {}

    def add(name: str, base: str, group: str) -> None:
        joints[name] = JointSpec(ranges[base], damping, armature[group], ctrl_limit=limit[group])

    for s in ("l", "r"):
        for j in LEG_JOINTS:
            add(f"{s}_{j}", j, "leg")
    for j in ("waist_yaw", "waist_pitch"):
        add(j, j, "trunk")
    for s in ("l", "r"):
        for j in ARM_JOINTS:
            add(f"{s}_{j}", j, "arm")

    def joint(side: int) -> Callable[[str, str], list[Joint]]:
        return lambda name, base: joint_for(joints, name, base, side)

    m_pelvis, m_waist = p.num("pelvis_mass"), p.num("waist_link_mass")
    m_torso = p.num("body_mass") - m_pelvis - m_waist
    straight_pelvis_z = p.num("ankle_height") + p.num("shank") + p.num("thigh") - hip[1]
    # Trunk frames: waist yaw above the pelvis origin, waist pitch above it, head above that.
    z_yaw, z_pitch, z_head = p.num("waist_yaw_z"), p.num("waist_pitch_z"), p.num("head_z")
    head_r, m_neck = p.num("head_radius"), p.num("neck_mass")
    head_center_z = p.num("height") - straight_pelvis_z - (z_yaw + z_pitch + z_head) - head_r
    head = Body(
        "head",
        (0, 0, z_head),
        [
            z_segment("cylinder", m_neck, p.vec("neck_shape", 3)),
            Shape("sphere", p.num("head_mass") - m_neck, (head_r,), (0, 0, head_center_z)),
        ],
    )
    torso = Body(
        "torso",
        (0, 0, z_pitch),
        [box_at_z(m_torso, p.vec("torso_shape", 4))],
        joint_for(joints, "waist_pitch", "waist_pitch", 1),
        sites=[Site("imu", (0, 0, p.num("imu_z")))],
        children=[head, arm(1, arms, joint(1)), arm(-1, arms, joint(-1))],
    )
    waist = Body(
        "waist_yaw_link",
        (0, 0, z_yaw),
        [box_at_z(m_waist, p.vec("waist_link_shape", 4))],
        joint_for(joints, "waist_yaw", "waist_yaw", 1),
        children=[torso],
    )
    pelvis = Body(
        "pelvis",
        (0, 0, 0),
        [box_at_z(m_pelvis, p.vec("pelvis_shape", 3))],
        children=[leg(1, dims, joint(1)), leg(-1, dims, joint(-1)), waist],
    )
    friction, condim = contact(p)
    return RobotDesign(
        "kist_humanoid",
        "KIST humanoid (22 joints, torque-controlled)",
        pelvis,
        joints,
        home_knee=p.num("home_knee"),
        home_fixed=home_arms(p),
        rgba="0.25 0.55 0.3 1",
        friction=friction,
        condim=condim,
        ledger=p,
    )


# --------------------------------------------------------------------------------------
# MJCF writing
# --------------------------------------------------------------------------------------


def body_element(body: Body, robot: RobotDesign) -> ET.Element:
    if body.inertial is not None:
        # A source's values, written at full precision (they are the model).
        mass, com, full = body.inertial.mass, body.inertial.com, body.inertial.inertia
        digits = 10
    else:
        mass, com, inertia = composite_inertia(body.shapes)
        full = (
            inertia[0, 0],
            inertia[1, 1],
            inertia[2, 2],
            inertia[0, 1],
            inertia[0, 2],
            inertia[1, 2],
        )
        digits = 6
    el = ET.Element("body", {"name": body.name, "pos": fvec(body.pos, digits)})
    ET.SubElement(
        el,
        "inertial",
        {
            "pos": fvec(com, digits),
            "mass": fmt(mass, digits),
            "fullinertia": fvec(full, digits),
        },
    )
    for j in body.joints:
        attrs = {"name": j.name, "type": "hinge", "axis": fvec(j.axis)}
        if j.range is not None:
            attrs["range"] = fvec(j.range)
        attrs |= {"damping": fmt(j.damping), "armature": fmt(j.armature)}
        if j.stiffness and j.backlash is None:  # with a dead band the tendon is the spring
            attrs["stiffness"] = fmt(j.stiffness)
        if j.frictionloss:
            attrs["frictionloss"] = fmt(j.frictionloss)
        ET.SubElement(el, "joint", attrs)
    for s in body.shapes:
        if s.kind == "inertial":
            continue  # counted in <inertial> above, not drawn
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
        attrs["condim"] = robot.condim
        attrs["friction"] = robot.friction
        attrs["rgba"] = "0.15 0.15 0.15 1" if s.sole else robot.rgba
        ET.SubElement(el, "geom", attrs)
    for site in body.sites:
        ET.SubElement(el, "site", {"name": site.name, "pos": fvec(site.pos), "size": "0.01"})
    for child in body.children:
        el.append(body_element(child, robot))
    return el


def body_joints(body: Body) -> list[Joint]:
    """Every joint of ``body``'s subtree, depth first (the MJCF's order)."""
    return [*body.joints, *(j for child in body.children for j in body_joints(child))]


def spring_tendons(root: ET.Element, pelvis: Body) -> None:
    """A fixed tendon ``<joint>_spring`` for each spring DoF with a dead band (backlash).

    The tendon's length is the spring DoF's angle q_s (coefficient 1), its stiffness the
    spring constant K and its spring length the band [-b/2, b/2] (the law:
    :mod:`walkrepro.sim.springs`).
    """
    banded = [j for j in body_joints(pelvis) if j.backlash is not None]
    if not banded:
        return
    tendons = ET.SubElement(root, "tendon")
    for j in banded:
        half = j.backlash / 2  # type: ignore[operator]
        fixed = ET.SubElement(
            tendons,
            "fixed",
            {
                "name": f"{j.name}{SPRING_TENDON_SUFFIX}",
                "stiffness": fmt(j.stiffness),
                "springlength": fvec((-half, half)),
            },
        )
        ET.SubElement(fixed, "joint", {"joint": j.name, "coef": "1"})


def mjcf_options(p: Ledger) -> dict[str, str]:
    """The ``<option>`` attributes the ledger's ``option_*`` entries set (keyword or number)."""
    out = {}
    for name in p.entries:
        if name.startswith(OPTION_PREFIX):
            value = p[name]
            out[name[len(OPTION_PREFIX) :]] = value if isinstance(value, str) else fvec(value)
    return out


def build_xml(robot: RobotDesign, keyframe: tuple[np.ndarray, np.ndarray] | None) -> str:
    root = ET.Element("mujoco", {"model": robot.name})
    root.append(
        ET.Comment(
            f" {robot.title}. GENERATED by robots/build_models.py: edit the script, not this. "
        )
    )
    ET.SubElement(root, "compiler", {"angle": "radian", "autolimits": "true"})
    if robot.options:
        ET.SubElement(root, "option", robot.options)
    world = ET.SubElement(root, "worldbody")
    pelvis = body_element(robot.pelvis, robot)
    pelvis.insert(1, ET.Element("freejoint", {"name": "root"}))
    world.append(pelvis)

    spring_tendons(root, robot.pelvis)
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
        # Encoders before the gear (§V-A): the sensors read the motor DoF (walkrepro/sim/robot.py).
        custom = ET.SubElement(root, "custom")
        ET.SubElement(custom, "text", {"name": "walkrepro_encoders", "data": "motor"})
    sensor = ET.SubElement(root, "sensor")
    ET.SubElement(sensor, "framequat", {"name": "imu_quat", "objtype": "site", "objname": "imu"})
    ET.SubElement(sensor, "gyro", {"name": "imu_gyro", "site": "imu"})
    ET.SubElement(sensor, "accelerometer", {"name": "imu_acc", "site": "imu"})
    for side in ("left", "right"):
        ET.SubElement(sensor, "force", {"name": f"{side}_foot_force", "site": f"{side}_foot_ft"})
        ET.SubElement(sensor, "torque", {"name": f"{side}_foot_torque", "site": f"{side}_foot_ft"})
    if robot.ground is not None:
        # The lab's ground law on the soles (walkrepro.sim.contact_law): its numerics, the
        # userdata its anchors need, and MuJoCo's own contact between the soles and the
        # floor switched off (the law alone holds them).
        law = ET.fromstring(f"<law>{contact_law.mjcf(robot.ground.law, robot.ground.points)}</law>")
        root.extend(list(law))
        excludes = ET.SubElement(root, "contact")
        for body in robot.ground.points:
            ET.SubElement(excludes, "exclude", {"body1": "world", "body2": body})
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

    Each foot carries a pure vertical force at its sole centre, their sum the weight and
    their centre of pressure under the CoM (which is above the soles' midpoint in x), so
    the floating base is in equilibrium. At rest the
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
    # Each foot's share: the one that puts the feet's centre of pressure under the CoM
    # (half each for a left/right symmetric robot; the lab's COMAN is off by 0.13 mm in y).
    y_com = float(data.subtree_com[model.body("pelvis").id][1])
    y_left, y_right = (float(data.site(f"{s}_sole").xpos[1]) for s in ("left", "right"))
    share_left = (y_com - y_right) / (y_left - y_right)
    tau = data.qfrc_bias.copy()
    for side, share in (("left", share_left), ("right", 1 - share_left)):
        jacp = np.zeros((3, model.nv))
        mujoco.mj_jacSite(model, data, jacp, None, model.site(f"{side}_sole").id)
        tau -= jacp.T @ np.array([0.0, 0.0, weight * share])
    assert np.max(np.abs(tau[:6])) < 1e-6, f"floating base not in equilibrium: {tau[:6]}"
    ctrl = np.zeros(model.nu)
    for i, name in enumerate(robot.joints):
        motor, spring = model.joint(f"{name}_motor"), model.joint(name)
        t = tau[spring.dofadr[0]]
        assert abs(t - tau[motor.dofadr[0]]) < 1e-9  # same axis, same subtree
        q_link = q[motor.qposadr[0]]
        q_s = preload_deflection(t, *spring_law(model, name))  # −K dz(q_s, b/2) = τ
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


# --------------------------------------------------------------------------------------
# README parameter tables, generated from the ledgers
# --------------------------------------------------------------------------------------


def format_ledger_value(value: LedgerValue) -> str:
    """A ledger value as table text: a number, ``[a, b]``, ``name value, …`` or a keyword."""
    if isinstance(value, str):
        return value
    if isinstance(value, dict):
        return ", ".join(f"{k} {fmt(float(v), 10)}" for k, v in value.items())
    if isinstance(value, list):
        return "[" + ", ".join(fmt(float(v), 10) for v in value) + "]"
    return fmt(float(value), 10)


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def class_counts(entries: dict[str, dict]) -> str:
    counts = {c: sum(e["class"] == c for e in entries.values()) for c in LEDGER_CLASSES}
    return ", ".join(f"{c} {n}" for c, n in counts.items())


def readme_block(robot: str, robots_dir: Path = ROBOTS_DIR) -> str:
    """The generated README block of ``robot``: its own ledger entries as a table, and the
    count per class (of its own entries and, for a variant, of the resolved ledger)."""
    data = read_ledger_file(ledger_path(robot, robots_dir))
    own = data["parameters"]
    lines = [
        README_BEGIN,
        "",
        "| name | value | unit | class | source |",
        "|---|---|---|---|---|",
    ]
    for name, e in own.items():
        source = e["source"]
        if "source_value" in e:
            sv = e["source_value"]
            source += (
                f" **Source value not in force:** {format_ledger_value(sv['value'])}"
                f" ({sv['source']})"
            )
        lines.append(
            f"| `{name}` | {format_ledger_value(e['value'])} | {_cell(e['unit'])} | "
            f"{e['class']} | {_cell(source)} |"
        )
    lines.append("")
    entries = "1 entry" if len(own) == 1 else f"{len(own)} entries"
    counts = f"{entries} in `robots/{robot}/parameters.yaml`: {class_counts(own)}."
    parent = data["inherits"]
    if parent is not None:
        resolved = load_ledger(robot, robots_dir).entries
        counts += (
            f" It extends `{parent}` (`robots/{parent}/README.md`): the entries above add to or "
            f"replace its ledger; the robot's {len(resolved)} entries: {class_counts(resolved)}."
        )
    lines += [counts, "", README_END]
    return "\n".join(lines)


def replace_readme_block(text: str, block: str, path: Path) -> str:
    """``text`` with its generated parameter block replaced by ``block``."""
    if text.count(README_BEGIN) != 1 or text.count(README_END) != 1:
        raise LedgerError(f"{path}: needs exactly one {README_BEGIN} ... {README_END} block")
    head, rest = text.split(README_BEGIN)
    _, tail = rest.split(README_END)
    return head + block + tail


def readme_text(robot: str, robots_dir: Path = ROBOTS_DIR) -> tuple[Path, str]:
    """The README's path and the text it must have."""
    path = robots_dir / robot / "README.md"
    return path, replace_readme_block(path.read_text(), readme_block(robot, robots_dir), path)


BUILDERS = {
    "dyros_red": build_dyros_red,
    "dyros_red_actuated": build_dyros_actuated,
    "dyros_red_actuated_9_9": build_dyros_actuated_9_9,
    "dyros_red_armature": build_dyros_armature,
    "coman": build_coman,
    "coman_lab": build_coman_lab,
    "kist_humanoid": build_kist,
}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--check",
        action="store_true",
        help="only compare with the committed robot.xml files and README parameter blocks",
    )
    parser.add_argument(
        "--readme",
        action="store_true",
        help="only rewrite the README parameter blocks from the ledgers (no robot.xml)",
    )
    args = parser.parse_args(argv)
    stale = []
    for name, build in BUILDERS.items():
        path, text = readme_text(name)
        if args.check:
            if path.read_text() != text:
                stale.append(f"{name}/README.md")
        elif path.read_text() != text:
            path.write_text(text)
            print(f"wrote {path.relative_to(ROBOTS_DIR.parent)}")
        if args.readme:
            continue
        text = generate(build())
        path = ROBOTS_DIR / name / "robot.xml"
        if args.check:
            if not path.exists() or path.read_text() != text:
                stale.append(f"{name}/robot.xml")
        else:
            path.parent.mkdir(exist_ok=True)
            path.write_text(text)
            print(f"wrote {path.relative_to(ROBOTS_DIR.parent)}")
    if stale:
        print(f"stale (run python robots/build_models.py): {', '.join(stale)}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
