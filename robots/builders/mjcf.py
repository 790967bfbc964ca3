"""The design written as MJCF: bodies, joints, actuators, sensors and springs; the home
keyframe solved on the compiled model (and the springs' pre-load that holds it)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import TYPE_CHECKING

import mujoco
import numpy as np
from scipy.optimize import brentq

from builders.core import ROBOT_CONAFFINITY, ROBOT_CONTYPE, composite_inertia, mirror_range
from builders.ledger import fmt, fvec
from walkrepro.sim import contact_law
from walkrepro.sim.springs import SPRING_TENDON_SUFFIX, preload_deflection, spring_law

if TYPE_CHECKING:
    from builders.core import Body, Joint, RobotDesign


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


def actuator_elements(root: ET.Element, robot: RobotDesign) -> None:
    """The ``<actuator>`` section: a torque-loop filter on the motor DoF per joint for a
    robot with drives, a motor per joint for ideal torques, a position servo on the motor
    DoF for the series-elastic robot (its stiffness and torque limit from the servo model)."""
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


def sensor_elements(root: ET.Element) -> None:
    """The ``<sensor>`` section: the IMU's orientation, gyro and accelerometer, and each
    foot's force/torque sensor."""
    sensor = ET.SubElement(root, "sensor")
    ET.SubElement(sensor, "framequat", {"name": "imu_quat", "objtype": "site", "objname": "imu"})
    ET.SubElement(sensor, "gyro", {"name": "imu_gyro", "site": "imu"})
    ET.SubElement(sensor, "accelerometer", {"name": "imu_acc", "site": "imu"})
    for side in ("left", "right"):
        ET.SubElement(sensor, "force", {"name": f"{side}_foot_force", "site": f"{side}_foot_ft"})
        ET.SubElement(sensor, "torque", {"name": f"{side}_foot_torque", "site": f"{side}_foot_ft"})


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
    actuator_elements(root, robot)
    if robot.drive is not None:
        # Encoders before the gear (§V-A): the sensors read the motor DoF (walkrepro/sim/robot.py).
        custom = ET.SubElement(root, "custom")
        ET.SubElement(custom, "text", {"name": "walkrepro_encoders", "data": "motor"})
    sensor_elements(root)
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
