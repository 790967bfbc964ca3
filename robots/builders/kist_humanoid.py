"""The KIST humanoid (Paper III, Jo & Oh): ``robots/kist_humanoid/parameters.yaml``."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from builders.core import (
    ARM_JOINTS,
    LEG_JOINTS,
    Body,
    JointSpec,
    RobotDesign,
    Shape,
    Site,
    arm,
    arm_dims,
    box_at_z,
    contact,
    home_arms,
    joint_for,
    joint_ranges,
    leg,
    leg_dims,
    z_segment,
)
from builders.ledger import load_ledger

if TYPE_CHECKING:
    from builders.core import Joint
    from builders.ledger import Ledger


def kist_joints(p: Ledger) -> dict[str, JointSpec]:
    """The KIST humanoid's torque-controlled joints, legs, trunk then arms: ranges, one
    damping, and the armature and torque limit of their group (leg, trunk, arm)."""
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
    return joints


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
    joints = kist_joints(p)

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
