"""DYROS RED (Paper I, Lee et al. 2021) and its variants: ``robots/dyros_red*/parameters.yaml``."""

from __future__ import annotations

from typing import TYPE_CHECKING

from builders.core import (
    LEG_JOINTS,
    Body,
    DriveModel,
    JointSpec,
    LegDims,
    RobotDesign,
    Shape,
    Site,
    box_at_z,
    contact,
    drive_joint,
    isotropic_inertial,
    joint_ranges,
    leg,
    per_joint,
    rigid_joint_for,
    z_segment,
)
from builders.ledger import load_ledger

if TYPE_CHECKING:
    from builders.core import Joint
    from builders.ledger import Ledger


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
