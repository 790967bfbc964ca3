"""COMAN from its lab's Robotran model (Paper II): ``robots/coman_lab/parameters.yaml``."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from builders.coman import coman_actuator_order, sea_joint
from builders.core import (
    ARM_JOINTS,
    LEG_JOINTS,
    Body,
    GroundLaw,
    Inertial,
    JointSpec,
    RobotDesign,
    SeaModel,
    Shape,
    Site,
    contact,
    side_name,
)
from builders.ledger import load_ledger
from walkrepro.sim import contact_law
from walkrepro.sim.contact_law import PointContactLaw

if TYPE_CHECKING:
    from builders.core import Joint, Vec3
    from builders.ledger import Ledger


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


def lab_sea(p: Ledger) -> SeaModel:
    """The paper's drives on the lab's model: the motors' armature and back-EMF damping,
    the servo's β and supply; the springs' damping and stops are per joint."""
    return SeaModel(
        motor_armature=p.num("motor_armature"),
        motor_damping=p.num("alpha") / p.num("beta"),  # back-EMF alpha / beta [Nms/rad]
        spring_damping=0.0,  # unused: every joint has its own (JointSpec.spring_damping)
        spring_range=None,  # the lab's springs have no deflection stop
        beta=p.num("beta"),
        supply=p.num("supply"),
    )


def lab_joints(p: Ledger, sea: SeaModel) -> dict[str, JointSpec]:
    """The lab model's joints in robots/coman's actuator order: ranges, springs, their
    damping and backlash (the lab's), and the paper's servo gains."""
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
    return joints


def lab_ground(p: Ledger) -> GroundLaw:
    """The lab's ground law (stiffness, damping by velocity scale, tangential spring and
    damper, friction) on a grid of points under each sole."""
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
    return GroundLaw(law, {"left_foot": points, "right_foot": points})


def build_coman_lab() -> RobotDesign:
    """COMAN from its lab's Robotran model (rigid feet), the paper's drives and gains, and
    the lab's ground law on the soles (robots/coman_lab/README.md)."""
    p = load_ledger("coman_lab")
    sea = lab_sea(p)
    joints = lab_joints(p, sea)

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
        ground=lab_ground(p),
    )
