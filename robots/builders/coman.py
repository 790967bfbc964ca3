"""COMAN (Paper II, Faraji et al.): ``robots/coman/parameters.yaml``."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from builders.core import (
    ARM_JOINTS,
    AXIS,
    LEG_JOINTS,
    Body,
    Joint,
    JointSpec,
    RobotDesign,
    SeaModel,
    Shape,
    Site,
    arm,
    arm_dims,
    box_at_z,
    contact,
    home_arms,
    joint_ranges,
    leg,
    leg_dims,
    mirror_range,
    z_segment,
)
from builders.ledger import load_ledger

if TYPE_CHECKING:
    from builders.ledger import Ledger


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


def coman_joints(p: Ledger, sea: SeaModel) -> dict[str, JointSpec]:
    """COMAN's joints in actuator order, each series-elastic: its range, the motor's
    damping and armature, the spring and the servo's damping gain k_d."""
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
    return joints


def coman_waist(
    p: Ledger,
    joints: dict[str, JointSpec],
    sea: SeaModel,
    torso: Body,
    masses: tuple[float, float],
) -> Body:
    """The waist's yaw then roll link above the pelvis, carrying ``torso``; ``masses`` are
    the yaw and roll links' [kg]."""
    m_waist_yaw, m_waist_roll = masses
    waist_roll = Body(
        "waist_roll_link",
        (0, 0, 0),
        [box_at_z(m_waist_roll, p.vec("waist_roll_link_shape", 3))],
        sea_joint(joints, "waist_roll", "waist_roll", 1, sea),
        children=[torso],
    )
    return Body(
        "waist_yaw_link",
        (0, 0, p.num("waist_z")),
        [box_at_z(m_waist_yaw, p.vec("waist_yaw_link_shape", 4))],
        sea_joint(joints, "waist_yaw", "waist_yaw", 1, sea),
        children=[waist_roll],
    )


def build_coman() -> RobotDesign:
    p = load_ledger("coman")
    sea = coman_sea(p)
    total = p.num("total_mass")
    leg_mass = p.num("leg_mass_share") * total
    joints = coman_joints(p, sea)

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
    waist_yaw = coman_waist(p, joints, sea, torso, (m_waist_yaw, m_waist_roll))
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
