"""The robot design every builder shares: shapes and their inertias, the body tree, joints
and drives, and the leg and arm every humanoid here is drawn with (from ledger entries)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from builders.ledger import fvec, mjcf_options
from walkrepro.sim.contact_law import PointContactLaw

if TYPE_CHECKING:
    from builders.ledger import Ledger, PerJoint


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


def isotropic_inertial(mass: float, com: tuple[float, ...], inertia: float) -> Shape:
    """A source's link inertial: ``mass`` at ``com`` with the isotropic moment ``inertia``."""
    return Shape("inertial", mass, (), com, inertia=(inertia, inertia, inertia, 0, 0, 0))


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
