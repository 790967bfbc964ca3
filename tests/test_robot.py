"""Tests of walkrepro.sim.robot and the MJCF reconstructions in robots/.

MuJoCo and Pinocchio must describe the same robot (mass, CoM, frames, mass matrix,
forward dynamics), the models must match the published figures, and the home keyframe
must stand on the ground.
"""

from __future__ import annotations

import importlib.util
import sys
import xml.etree.ElementTree as ET
from types import ModuleType

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from walkrepro import ROBOTS_DIR
from walkrepro.errors import UnknownNameError
from walkrepro.publish.ledger import robot_ledger
from walkrepro.sim import contact_law
from walkrepro.sim.robot import (
    FRAME_NAMES,
    SENSOR_NAMES,
    Robot,
    leg_actuators,
    list_robots,
    load_robot,
    with_servo_gains,
)
from walkrepro.sim.springs import spring_law

ROBOTS = (
    "coman",
    "coman_lab",
    "dyros_red",
    "dyros_red_actuated",
    "dyros_red_actuated_9_9",
    "dyros_red_armature",
    "kist_humanoid",
)
GRAVITY = 9.81
FLOOR = '<geom name="floor" type="plane" size="0 0 1" contype="1" conaffinity="3"/>'
LEG = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
ARM = ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow")
TRUNK = {
    "dyros_red": (),
    "dyros_red_actuated": (),
    "dyros_red_actuated_9_9": (),
    "dyros_red_armature": (),
    "coman": ("waist_yaw", "waist_roll", "waist_pitch"),
    "coman_lab": ("waist_yaw", "waist_roll", "waist_pitch"),
    "kist_humanoid": ("waist_yaw", "waist_pitch"),
}
HAS_ARMS = {
    "dyros_red": False,
    "dyros_red_actuated": False,
    "dyros_red_actuated_9_9": False,
    "dyros_red_armature": False,
    "coman": True,
    "coman_lab": True,
    "kist_humanoid": True,
}
#: The joint that moves the foot body: the last of the ankle's two (the lab's COMAN turns
#: roll then pitch, the other robots pitch then roll).
FOOT_JOINT = {"coman_lab": "ankle_pitch"}
#: The series-elastic COMAN models (paper's motor side and gains on both).
COMANS = ("coman", "coman_lab")


# ---- helpers ----------------------------------------------------------------------------


def scene_model(robot: Robot) -> mujoco.MjModel:
    """The robot with a floor, at the papers' physics rate (2 kHz); 4 kHz for a robot on the
    lab's ground law, which MuJoCo's Euler integrates stably only at 0.25 ms on coman_lab
    (robots/coman_lab/README.md, Integration step)."""
    xml = robot.xml_path.read_text().replace("<worldbody>", "<worldbody>" + FLOOR, 1)
    model = mujoco.MjModel.from_xml_string(xml)
    model.opt.timestep = 0.0005 if contact_law.from_model(model) is None else 0.00025
    return model


def random_state(robot: Robot, seed: int) -> mujoco.MjData:
    """Random base pose/velocity and joint positions inside their ranges (no limit active)."""
    model = robot.mj_model
    rng = np.random.default_rng(seed)
    data = mujoco.MjData(model)
    quat = rng.standard_normal(4)
    data.qpos[0:7] = (*rng.uniform(-1, 1, 3), *(quat / np.linalg.norm(quat)))
    for j in range(1, model.njnt):
        lo, hi = model.jnt_range[j]
        margin = 0.05 * (hi - lo)
        data.qpos[model.jnt_qposadr[j]] = rng.uniform(lo + margin, hi - margin)
    data.qvel[:] = rng.standard_normal(model.nv)
    data.ctrl[:] = rng.uniform(-1, 1, model.nu) * (10.0 if robot.control_mode == "torque" else 0.3)
    if robot.control_mode == "position":
        data.ctrl[:] += robot.link_joint_pos(data.qpos)  # targets near the current posture
    mujoco.mj_forward(model, data)
    limits = int(np.sum(data.efc_type[: data.nefc] == mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT))
    assert limits == 0, "a joint limit is active; the comparison would include its force"
    return data


def velocity_map(robot: Robot, data: mujoco.MjData, component: str = "motor") -> np.ndarray:
    """S (nv_mj, nv_pin) with qvel = S v for a link joint motion carried by one component.

    MuJoCo's free-joint linear velocity is in the world frame, Pinocchio's in the pelvis
    frame: qvel[0:3] = R v[0:3]. A link joint's velocity goes into its motor DoF (rigid
    spring: the rigid twin) or, with ``component="spring"``, into its spring DoF.
    """
    pm = robot.pin_model
    s = np.zeros((robot.mj_model.nv, pm.nv))
    s[0:3, 0:3] = data.xmat[robot.mj_model.body("pelvis").id].reshape(3, 3)
    s[3:6, 3:6] = np.eye(3)
    adr = robot.link_joint_qvel_adr()
    pick = adr.starts if component == "motor" else np.r_[adr.starts[1:], adr.adr.size] - 1
    s[adr.adr[pick], robot.pin_v_idx] = 1.0
    return s


def full_inertia(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    m = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, m)
    return m


def build_models_module() -> ModuleType:
    spec = importlib.util.spec_from_file_location("build_models", ROBOTS_DIR / "build_models.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses resolve annotations through sys.modules
    spec.loader.exec_module(module)
    return module


def vertical_extent(
    model: mujoco.MjModel, data: mujoco.MjData, geoms: list[int]
) -> tuple[float, float]:
    """Lowest and highest z of the given geoms [m]."""
    lo, hi = np.inf, -np.inf
    for g in geoms:
        pos, rot, size = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3), model.geom_size[g]
        kind = model.geom_type[g]
        if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
            half = size[0]
        elif kind == mujoco.mjtGeom.mjGEOM_BOX:
            half = float(np.abs(rot[2]) @ size)
        elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
            half = abs(rot[2, 2]) * size[1] + size[0]
        else:  # cylinder: half-length along the axis plus the rim radius
            half = abs(rot[2, 2]) * size[1] + size[0] * np.sqrt(max(0.0, 1 - rot[2, 2] ** 2))
        lo, hi = min(lo, pos[2] - half), max(hi, pos[2] + half)
    return lo, hi


def robot_geoms(model: mujoco.MjModel) -> list[int]:
    """Geoms of the robot's tree (not the floor)."""
    pelvis = model.body("pelvis").id
    return [g for g in range(model.ngeom) if model.body_rootid[model.geom_bodyid[g]] == pelvis]


def subtree_mass(model: mujoco.MjModel, body: str) -> float:
    return float(model.body_subtreemass[model.body(body).id])


def anchor(model: mujoco.MjModel, data: mujoco.MjData, joint: str) -> np.ndarray:
    return data.xanchor[model.joint(joint).id]


# ---- registry ---------------------------------------------------------------------------


def test_list_robots() -> None:
    """Every robot folder with a robot.xml is listed, sorted."""
    assert list_robots() == sorted(ROBOTS)


def test_unknown_robot_lists_valid_ones() -> None:
    """An unknown robot name raises UnknownNameError naming every valid robot."""
    with pytest.raises(UnknownNameError) as info:
        load_robot("asimo")
    assert all(name in str(info.value) for name in ROBOTS)


def test_committed_xml_is_generator_output() -> None:
    """Regenerating the models with robots/build_models.py gives the committed XML exactly."""
    module = build_models_module()
    for name, build in module.BUILDERS.items():
        assert module.generate(build()) == (ROBOTS_DIR / name / "robot.xml").read_text(), name


# ---- conventions ------------------------------------------------------------------------


@pytest.mark.parametrize("name", ROBOTS)
def test_names_and_order_follow_the_conventions(name: str) -> None:
    """Actuators, sensors, sites and feet carry the exact names and order other modules use."""
    robot = load_robot(name)
    model = robot.mj_model
    arms = [f"{s}_{j}" for s in "lr" for j in ARM] if HAS_ARMS[name] else []
    expected = [f"{s}_{j}" for s in "lr" for j in LEG] + list(TRUNK[name]) + arms
    assert list(robot.joint_names) == expected
    assert sorted(model.sensor(i).name for i in range(model.nsensor)) == sorted(SENSOR_NAMES)
    for side in ("left", "right"):
        foot = model.body(f"{side}_foot").id
        foot_joint = f"{side[0]}_{FOOT_JOINT.get(name, 'ankle_roll')}"
        assert model.jnt_bodyid[model.joint(foot_joint).id] == foot
        for site in (f"{side}_sole", f"{side}_foot_ft"):
            assert model.site_bodyid[model.site(site).id] == foot
    imu_body = {
        "dyros_red": "pelvis",
        "dyros_red_actuated": "pelvis",
        "dyros_red_actuated_9_9": "pelvis",
        "dyros_red_armature": "pelvis",
        "coman": "pelvis",
        "coman_lab": "pelvis",
        "kist_humanoid": "torso",
    }[name]
    assert model.body(model.site_bodyid[model.site("imu").id]).name == imu_body
    text = robot.xml_path.read_text()
    assert '<compiler angle="radian" autolimits="true" />' in text
    assert "<light" not in text and "floor" not in text
    # The only <option> is the robot's ledger's (option_<attribute>): its lab's simulator's
    # cone (and, for DYROS RED, its lab's solver settings), each attribute as the ledger gives it.
    options = [line.strip() for line in text.splitlines() if "<option" in line]
    assert len(options) == 1
    ledger = robot_ledger(name) or {}
    in_ledger = {
        key.removeprefix("option_"): entry.value
        for key, entry in ledger.items()
        if key.startswith("option_")
    }
    in_xml = ET.fromstring(options[0]).attrib
    assert set(in_xml) == set(in_ledger)
    for attribute, value in in_ledger.items():
        if isinstance(value, str):
            assert in_xml[attribute] == value
        else:
            assert float(in_xml[attribute]) == pytest.approx(float(value), rel=1e-6)
    cone = "pyramidal" if name == "kist_humanoid" else "elliptic"
    assert in_xml["cone"] == cone


@pytest.mark.parametrize("name", ROBOTS)
def test_leg_actuators_are_the_legs_joints(name: str) -> None:
    """A leg's actuators are the hip-to-ankle joints of that side, in actuator order."""
    robot = load_robot(name)
    for side in ("left", "right"):
        ids = leg_actuators(robot.mj_model, f"{side}_foot")
        assert [robot.joint_names[i] for i in ids] == [f"{side[0]}_{j}" for j in LEG]


def test_leg_actuators_unknown_foot_lists_the_feet() -> None:
    """An unknown foot name lists the valid ones."""
    with pytest.raises(UnknownNameError, match="left_foot, right_foot"):
        leg_actuators(load_robot("dyros_red").mj_model, "pelvis")


@pytest.mark.parametrize("name", ROBOTS)
def test_collision_geoms_touch_the_world_but_not_each_other(name: str) -> None:
    """Robot geoms are contype 2 / conaffinity 1 (or visual-only); only feet own the soles."""
    model = load_robot(name).mj_model
    feet = {model.body("left_foot").id, model.body("right_foot").id}
    for g in range(model.ngeom):
        pair = (model.geom_contype[g], model.geom_conaffinity[g])
        assert pair in ((2, 1), (0, 0))
        if model.geom_bodyid[g] in feet and pair == (2, 1):
            assert model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX
            assert model.geom_condim[g] == 3 and model.geom_friction[g][0] == 1.0
    # A fall shows up as a contact of some other body with the floor.
    assert sum(model.geom_contype[g] == 2 for g in range(model.ngeom)) > 6


@pytest.mark.parametrize("name", ROBOTS)
def test_pinocchio_joints_match_mujoco(name: str) -> None:
    """Pinocchio has a free-flyer root and the link joints with MuJoCo's ranges."""
    robot = load_robot(name)
    pm, model = robot.pin_model, robot.mj_model
    assert pm.joints[1].shortname() == "JointModelFreeFlyer"
    assert pm.nq == 7 + robot.n_joints and pm.nv == 6 + robot.n_joints
    suffix = "_motor" if robot.is_series_elastic else ""
    for j, name_j in enumerate(robot.joint_names):
        lo, hi = model.jnt_range[model.joint(name_j + suffix).id]
        assert pm.lowerPositionLimit[robot.pin_q_idx[j]] == pytest.approx(lo)
        assert pm.upperPositionLimit[robot.pin_q_idx[j]] == pytest.approx(hi)
    for frame in FRAME_NAMES:
        robot.pin_frame_id(frame)  # exists
    with pytest.raises(UnknownNameError):
        robot.pin_frame_id("nose")


# ---- MuJoCo and Pinocchio agree -----------------------------------------------------------


@pytest.mark.parametrize("name", ROBOTS)
def test_total_mass_agrees(name: str) -> None:
    """MuJoCo and Pinocchio give the same total mass."""
    robot = load_robot(name)
    pin_mass = sum(inertia.mass for inertia in robot.pin_model.inertias)
    assert pin_mass == pytest.approx(robot.total_mass, abs=1e-9)
    assert robot.total_mass == pytest.approx(float(np.sum(robot.mj_model.body_mass)))


@pytest.mark.parametrize("name", ROBOTS)
def test_com_agrees_at_home_and_random_configurations(name: str) -> None:
    """The whole-body CoM from MuJoCo and Pinocchio agree at home and at random states."""
    robot = load_robot(name)
    model, pm = robot.mj_model, robot.pin_model
    pdata = pm.createData()
    home = mujoco.MjData(model)
    home.qpos[:] = robot.home_qpos
    mujoco.mj_forward(model, home)
    for data in [home] + [random_state(robot, seed) for seed in range(5)]:
        q, _ = robot.pin_state_from_mujoco(data.qpos, data.qvel)
        com_pin = pin.centerOfMass(pm, pdata, q)
        np.testing.assert_allclose(com_pin, data.subtree_com[model.body("pelvis").id], atol=1e-9)
    assert robot.nominal_com_height == pytest.approx(home.subtree_com[1][2])


@pytest.mark.parametrize("name", ROBOTS)
def test_frame_poses_agree_at_random_configurations(name: str) -> None:
    """Feet, soles, F/T sensors and IMU have the same world pose in MuJoCo and Pinocchio."""
    robot = load_robot(name)
    model, pm = robot.mj_model, robot.pin_model
    pdata = pm.createData()
    for seed in range(5):
        data = random_state(robot, seed)
        q, _ = robot.pin_state_from_mujoco(data.qpos, data.qvel)
        pin.framesForwardKinematics(pm, pdata, q)
        for frame in FRAME_NAMES:
            placement = pdata.oMf[robot.pin_frame_id(frame)]
            if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, frame) >= 0:
                pos, rot = data.site(frame).xpos, data.site(frame).xmat.reshape(3, 3)
            else:
                pos, rot = data.body(frame).xpos, data.body(frame).xmat.reshape(3, 3)
            np.testing.assert_allclose(placement.translation, pos, atol=1e-9, err_msg=frame)
            np.testing.assert_allclose(placement.rotation, rot, atol=1e-9, err_msg=frame)


@pytest.mark.parametrize("name", ROBOTS)
def test_mass_matrix_agrees_at_random_configurations(name: str) -> None:
    """Sᵀ M_mujoco S = M_pinocchio, S mapping Pinocchio's local base velocity to MuJoCo's.

    Both include the armature (Pinocchio's crba adds model.armature). For COMAN the link
    motion is put in the motor DoF, whose armature J_m the rigid twin carries.
    """
    robot = load_robot(name)
    pm = robot.pin_model
    pdata = pm.createData()
    for seed in range(5):
        data = random_state(robot, seed)
        q, _ = robot.pin_state_from_mujoco(data.qpos, data.qvel)
        m_pin = pin.crba(pm, pdata, q)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T  # crba fills the upper triangle
        m_mj = full_inertia(robot.mj_model, data)
        s = velocity_map(robot, data)
        np.testing.assert_allclose(s.T @ m_mj @ s, m_pin, atol=1e-9)
        # Armature excluded on both sides, whichever component carries the link motion.
        m_mj_bare = m_mj - np.diag(robot.mj_model.dof_armature)
        m_pin_bare = m_pin - np.diag(pm.armature)
        s = velocity_map(robot, data, component="spring")
        np.testing.assert_allclose(s.T @ m_mj_bare @ s, m_pin_bare, atol=1e-9)


@pytest.mark.parametrize("name", ["dyros_red", "kist_humanoid"])
def test_forward_dynamics_agree_for_torque_robots(name: str) -> None:
    """MuJoCo's qacc equals Pinocchio's ABA with τ = ctrl − damping·q̇, base included."""
    robot = load_robot(name)
    pm = robot.pin_model
    for seed in range(3):
        data = random_state(robot, seed)
        q, v = robot.pin_state_from_mujoco(data.qpos, data.qvel)
        tau = np.zeros(pm.nv)
        tau[robot.pin_v_idx] = data.ctrl - pm.damping[robot.pin_v_idx] * v[robot.pin_v_idx]
        a = pin.aba(pm, pm.createData(), q, v, tau)
        np.testing.assert_allclose(a[robot.pin_v_idx], data.qacc[6:], atol=1e-8)
        assert_base_acceleration_agrees(robot, data, v, a)


def assert_base_acceleration_agrees(
    robot: Robot, data: mujoco.MjData, v: np.ndarray, a: np.ndarray
) -> None:
    """MuJoCo: d/dt of the world-frame velocity; Pinocchio: d/dt of the pelvis-frame one."""
    rot = data.xmat[robot.mj_model.body("pelvis").id].reshape(3, 3)
    np.testing.assert_allclose(rot @ (a[0:3] + np.cross(v[3:6], v[0:3])), data.qacc[0:3], atol=1e-8)
    np.testing.assert_allclose(a[3:6], data.qacc[3:6], atol=1e-8)


# ---- COMAN's series-elastic joints --------------------------------------------------------


@pytest.mark.parametrize("name", COMANS)
def test_coman_motor_dof_is_driven_by_servo_and_spring_only(name: str) -> None:
    """Each COMAN motor DoF obeys J_m θ̈_m = τ_m − (α/β) θ̇_m + k q_s + b_s q̇_s."""
    robot = load_robot(name)
    model = robot.mj_model
    for seed in range(3):
        data = random_state(robot, seed)
        for name in robot.joint_names:
            motor, spring = model.joint(f"{name}_motor"), model.joint(name)
            m, s = motor.dofadr[0], spring.dofadr[0]
            lhs = model.dof_armature[m] * data.qacc[m] - model.dof_armature[s] * data.qacc[s]
            rhs = (
                data.qfrc_actuator[m]
                - model.dof_damping[m] * data.qvel[m]
                - data.qfrc_spring[s]  # the spring's torque (linear or dead band) on the link
                + model.dof_damping[s] * data.qvel[s]
            )
            assert lhs == pytest.approx(rhs, abs=1e-8), name
            assert model.dof_armature[s] == 0.0


@pytest.mark.parametrize("name", COMANS)
def test_coman_links_move_like_the_rigid_twin_driven_by_spring_torques(name: str) -> None:
    """COMAN's link accelerations equal the rigid twin's ABA under τ = −k q_s − b_s q̇_s."""
    robot = load_robot(name)
    model = robot.mj_model
    twin = pin.Model(robot.pin_model)
    twin.armature[:] = 0.0  # the motor inertia sits behind the spring, not on the link
    qvel_adr = robot.link_joint_qvel_adr()
    spring_v = qvel_adr.adr[qvel_adr.starts + 1]
    for seed in range(3):
        data = random_state(robot, seed)
        q, v = robot.pin_state_from_mujoco(data.qpos, data.qvel)
        tau = np.zeros(twin.nv)
        damping_s = model.dof_damping[spring_v]
        tau[robot.pin_v_idx] = data.qfrc_spring[spring_v] - damping_s * data.qvel[spring_v]
        a = pin.aba(twin, twin.createData(), q, v, tau)
        np.testing.assert_allclose(a[robot.pin_v_idx], qvel_adr.link_values(data.qacc), atol=1e-8)
        assert_base_acceleration_agrees(robot, data, v, a)


@pytest.mark.parametrize("name", COMANS)
def test_coman_actuators_follow_the_voltage_model(name: str) -> None:
    """Servo gain k_d/β (10, 100, 500 V/rad), torque limit 15 V/β, J_m 0.23, damping α/β."""
    robot = load_robot(name)
    model = robot.mj_model
    beta = 0.45
    for i, name in enumerate(robot.joint_names):
        kd = 10.0 if name.endswith("ankle_roll") else 100.0 if name.endswith("hip_pitch") else 500.0
        assert model.actuator_gainprm[i, 0] == pytest.approx(kd / beta, rel=1e-5)
        assert model.actuator_biasprm[i, 1] == pytest.approx(-kd / beta, rel=1e-5)
        np.testing.assert_allclose(model.actuator_forcerange[i], [-15 / beta, 15 / beta], rtol=1e-5)
        motor = model.joint(f"{name}_motor")
        assert model.dof_armature[motor.dofadr[0]] == pytest.approx(0.23)
        assert model.dof_damping[motor.dofadr[0]] == pytest.approx(5.42 / beta, rel=1e-5)
        assert model.jnt_stiffness[motor.id] == 0.0 and spring_law(model, name)[0] > 0
    assert robot.control_mode == "position"


def test_coman_ankle_is_soft_and_other_springs_stiffer() -> None:
    """Ankle spring + stiffest servo in series ≈ 112 Nm/rad; the other springs are stiffer.

    Its apparent stiffness, series − m g h_c / 2 (gravity's share per ankle, h_c the CoM
    height above the ankle axis), bounds the whole robot's from above: knees and hips add
    compliance (the neck-pull test below measures the whole robot).
    """
    robot = load_robot("coman")
    k = dict(zip(robot.joint_names, robot.spring_stiffness, strict=True))
    series = 1 / (1 / k["l_ankle_pitch"] + 1 / (500 / 0.45))
    ankle_z = 0.06
    apparent_upper = series - robot.total_mass * GRAVITY * (robot.nominal_com_height - ankle_z) / 2
    assert 100 < series < 125
    assert 31 < apparent_upper < 60
    for name in ("l_hip_pitch", "l_hip_roll", "l_knee", "waist_pitch"):
        assert k[name] >= 2 * k["l_ankle_pitch"]


@pytest.mark.parametrize("name", COMANS)
def test_coman_home_springs_are_preloaded(name: str) -> None:
    """At COMAN's home keyframe the link angles are the posture and the springs carry the load."""
    robot = load_robot(name)
    model = robot.mj_model
    adr = robot.link_joint_qpos_adr()
    spring = robot.home_qpos[adr.adr[adr.starts + 1]]
    knees = [robot.joint_names.index(j) for j in ("l_knee", "r_knee")]
    np.testing.assert_allclose(robot.home_joint_pos[knees], 0.4)  # paper: knee ≈ 0.4 rad
    assert np.all(spring[knees] > 0.005)  # the knee springs deflect under the body weight
    # Servo torque kp (ctrl − q_m) balances the spring torque on every joint (−k q_s, or
    # the dead-band law's where the drive has a backlash: walkrepro.sim.springs).
    motor = robot.home_qpos[adr.adr[adr.starts]]
    servo = model.actuator_gainprm[:, 0] * (robot.home_ctrl - motor)
    data = mujoco.MjData(model)
    data.qpos[:] = robot.home_qpos
    mujoco.mj_forward(model, data)
    spring_v = robot.link_joint_qvel_adr()
    np.testing.assert_allclose(
        servo, data.qfrc_spring[spring_v.adr[spring_v.starts + 1]], atol=1e-6
    )


# ---- published figures -------------------------------------------------------------------


def straight_standing(robot: Robot) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """All joints at zero, pelvis upright, soles on z = 0."""
    model = robot.mj_model
    data = mujoco.MjData(model)
    data.qpos[3] = 1.0
    mujoco.mj_forward(model, data)
    data.qpos[2] = -data.site("left_sole").xpos[2]
    mujoco.mj_forward(model, data)
    return model, data


def test_dyros_red_matches_published_figures() -> None:
    """DYROS RED: 89.6 kg, 1.43 m, 0.30 x 0.15 m feet, the lab model's leg lengths, link masses and centres of mass."""
    robot = load_robot("dyros_red")
    model, data = straight_standing(robot)
    assert robot.total_mass == pytest.approx(89.6)
    assert vertical_extent(model, data, robot_geoms(model))[1] == pytest.approx(1.43, abs=1e-6)
    assert robot.sole_size == pytest.approx((0.30, 0.15))
    assert robot.n_joints == 12 and robot.control_mode == "torque"
    for s, y in (("l", 0.1025), ("r", -0.1025)):
        hip = anchor(model, data, f"{s}_hip_pitch") - data.qpos[:3]
        np.testing.assert_allclose(hip, [0, y, -0.1225], atol=1e-9)
        knee, ankle = anchor(model, data, f"{s}_knee"), anchor(model, data, f"{s}_ankle_pitch")
        assert np.linalg.norm(knee - anchor(model, data, f"{s}_hip_pitch")) == pytest.approx(0.35)
        assert np.linalg.norm(ankle - knee) == pytest.approx(0.35)
        sole = data.site("left_sole" if s == "l" else "right_sole").xpos
        assert ankle[2] - sole[2] == pytest.approx(0.1368)
        assert sole[0] - ankle[0] == pytest.approx(0.0317)
        masses = [
            model.body(b).mass[0]
            for b in (
                f"{s}_hip_yaw_link",
                f"{s}_hip_roll_link",
                f"{s}_thigh",
                f"{s}_shank",
                f"{s}_ankle_pitch_link",
            )
        ]
        foot = model.body("left_foot" if s == "l" else "right_foot").mass[0]
        np.testing.assert_allclose([*masses, foot], [2.679, 2.67, 5.366, 3.883, 2.51, 3.464])
        thigh_com = model.body(f"{s}_thigh").ipos
        np.testing.assert_allclose(
            thigh_com, [-0.00042, 0.00032 if s == "l" else -0.00032, -0.18904]
        )
    for j in robot.joint_names:
        dof = model.joint(j).dofadr[0]
        assert model.dof_damping[dof] == pytest.approx(2.0)
    np.testing.assert_allclose(model.actuator_ctrlrange, np.tile([-300.0, 300.0], (12, 1)))
    assert 0.8 <= robot.nominal_com_height <= 0.9


def test_coman_matches_published_figures() -> None:
    """COMAN: 30 kg, 0.9 m, 23 joints, each leg 22.5 % of the mass, 0.14 m pelvis, 0.25 m shank."""
    robot = load_robot("coman")
    model, data = straight_standing(robot)
    assert robot.total_mass == pytest.approx(30.0)
    assert vertical_extent(model, data, robot_geoms(model))[1] == pytest.approx(0.90, abs=1e-6)
    assert robot.n_joints == 23 and model.njnt == 1 + 2 * 23
    for side in ("l", "r"):
        assert subtree_mass(model, f"{side}_hip_yaw_link") / robot.total_mass == pytest.approx(
            0.225
        )
    width = anchor(model, data, "l_hip_roll") - anchor(model, data, "r_hip_roll")
    assert np.linalg.norm(width) == pytest.approx(0.14)
    shank = anchor(model, data, "l_knee") - anchor(model, data, "l_ankle_pitch")
    assert np.linalg.norm(shank) == pytest.approx(0.25)
    ahead = data.site("left_sole").xpos - anchor(model, data, "l_ankle_pitch")
    assert ahead[0] == pytest.approx(0.03)


def test_coman_lab_matches_the_labs_robotran_model() -> None:
    """coman_lab has the totals of the lab's rigid-feet Robotran model (CoManRobotran @
    0207863b, dataR/CoMan_versions/Rigid_feet/CoMan_23Dof_V4.mbs), summed from its bodies:
    28.35740094 kg, each leg 6.42351182 kg (22.65 %), the upper body 15.5103773 kg with its CoM
    0.2306 m above the hip axis and 0.994 kg m² of pitch inertia about it, hips 0.5268 m
    above the soles at q = 0 (the model's initial T3)."""
    robot = load_robot("coman_lab")
    model, data = straight_standing(robot)
    assert robot.n_joints == 23 and model.njnt == 1 + 2 * 23
    assert robot.total_mass == pytest.approx(28.35740094, abs=1e-9)
    hip_axis = data.xpos[model.body("pelvis").id]  # the pelvis origin: midway between hips
    assert hip_axis[2] == pytest.approx(0.5268, abs=1e-12)
    legs = [f"{s}_hip_pitch_link" for s in "lr"]
    for leg in legs:
        assert subtree_mass(model, leg) == pytest.approx(6.42351182, abs=1e-9)
        assert subtree_mass(model, leg) / robot.total_mass == pytest.approx(0.22652, abs=1e-5)
    upper = [
        b
        for b in range(1, model.nbody)
        if all(
            model.body_rootid[b] == model.body("pelvis").id
            and not _in_subtree(model, b, model.body(leg).id)
            for leg in legs
        )
    ]
    m_upper = float(sum(model.body_mass[b] for b in upper))
    com = sum(model.body_mass[b] * data.xipos[b] for b in upper) / m_upper
    assert m_upper == pytest.approx(15.5103773, abs=1e-9)
    assert com[2] - hip_axis[2] == pytest.approx(0.2306, abs=5e-5)
    pitch = 0.0
    for b in upper:
        rot = data.ximat[b].reshape(3, 3)
        d = data.xipos[b] - hip_axis
        pitch += (rot @ np.diag(model.body_inertia[b]) @ rot.T)[1, 1]
        pitch += model.body_mass[b] * (d[0] ** 2 + d[2] ** 2)
    assert pitch == pytest.approx(0.994, abs=5e-4)
    # The lab's sole: 200 points on a 1 cm grid, x -0.06...0.13, y ±0.045, 0.1 m below the ankle.
    law = contact_law.from_model(model)
    assert law is not None
    for foot in ("left_foot", "right_foot"):
        points = law.points[foot]
        assert points.shape == (200, 3)
        np.testing.assert_allclose(points.min(axis=0), [-0.06, -0.045, -0.1], atol=1e-12)
        np.testing.assert_allclose(points.max(axis=0), [0.13, 0.045, -0.1], atol=1e-12)
    assert (law.law.stiffness, law.law.velocity_scale, law.law.friction) == (27818.0, 0.3, 0.9)
    assert (law.law.tangential_stiffness, law.law.tangential_damping) == (1e4, 10.0)


def _in_subtree(model: mujoco.MjModel, body: int, root: int) -> bool:
    """Whether ``body`` is ``root`` or below it."""
    while body > 0:
        if body == root:
            return True
        body = int(model.body_parentid[body])
    return False


def test_coman_lab_springs_are_the_labs() -> None:
    """coman_lab's springs and their damping are the lab's (init_actuator_model.c), per joint."""
    robot = load_robot("coman_lab")
    model = robot.mj_model
    lab = {
        "hip_pitch": (395.46, 0.198),
        "hip_roll": (8400, 4.2),
        "hip_yaw": (8400, 4.2),
        "knee": (395.46, 0.198),
        "ankle_pitch": (395.46, 0.198),
        "ankle_roll": (8400, 4.2),
        "waist_pitch": (395.46, 0.198),
        "waist_roll": (8400, 4.2),
        "waist_yaw": (395.46, 0.198),
        "shoulder_pitch": (120, 0.198),
        "shoulder_roll": (120, 0.198),
        "shoulder_yaw": (8400, 4.2),
        "elbow": (120, 0.198),
    }
    for name in robot.joint_names:
        base = name[2:] if name[:2] in ("l_", "r_") else name
        spring = model.joint(name)
        assert spring_law(model, name)[0] == pytest.approx(lab[base][0]), name
        assert model.dof_damping[spring.dofadr[0]] == pytest.approx(lab[base][1]), name
        assert not model.jnt_limited[spring.id]  # the lab's springs have no stop


def test_coman_lab_ft_sensors_see_the_ground_law() -> None:
    """Standing on the lab's law, the two F/T sensors of walkrepro's sensor model carry the
    robot's weight above the feet (MuJoCo's own force sensors leave out the law's force, a
    generalized force; the sensor model adds it)."""
    from walkrepro.sim.sensors import SensorModel
    from walkrepro.specs.models import SensorsSpec

    robot = load_robot("coman_lab")
    model = scene_model(robot)
    data = mujoco.MjData(model)
    data.qpos[:] = robot.home_qpos
    data.ctrl[:] = robot.home_ctrl
    with contact_law.applied_to(model):
        for _ in range(400):
            mujoco.mj_step(model, data)
    snapshot = SensorModel(robot, model, SensorsSpec(), model.opt.timestep, 0).read(model, data)
    foot_weight = model.body("left_foot").mass[0] * GRAVITY
    fz = snapshot.left_ft[2] + snapshot.right_ft[2]
    assert fz == pytest.approx(robot.total_mass * GRAVITY - 2 * foot_weight, rel=0.02)


def test_kist_humanoid_matches_published_figures() -> None:
    """KIST: 57 kg = trunk 20 + head 5 + legs 2x10 + arms 2x6, 22 joints, F/T below the ankles."""
    robot = load_robot("kist_humanoid")
    model, data = straight_standing(robot)
    assert robot.total_mass == pytest.approx(57.0)
    assert robot.n_joints == 22 and robot.control_mode == "torque"
    head = subtree_mass(model, "head")
    trunk = (
        robot.total_mass
        - head
        - sum(
            subtree_mass(model, f"{s}_{b}")
            for s in "lr"
            for b in ("hip_yaw_link", "shoulder_pitch_link")
        )
    )
    assert (trunk, head) == pytest.approx((20.0, 5.0))
    for s in "lr":
        assert subtree_mass(model, f"{s}_hip_yaw_link") == pytest.approx(10.0)
        assert subtree_mass(model, f"{s}_shoulder_pitch_link") == pytest.approx(6.0)
        thigh = np.linalg.norm(
            anchor(model, data, f"{s}_knee") - anchor(model, data, f"{s}_hip_pitch")
        )
        shank = np.linalg.norm(
            anchor(model, data, f"{s}_ankle_pitch") - anchor(model, data, f"{s}_knee")
        )
        assert 0.3 <= thigh <= 0.35 and 0.3 <= shank <= 0.35
        side = "left" if s == "l" else "right"
        ankle_z = anchor(model, data, f"{s}_ankle_roll")[2]
        assert data.site(f"{side}_sole").xpos[2] < data.site(f"{side}_foot_ft").xpos[2] < ankle_z
    assert 1.5 <= vertical_extent(model, data, robot_geoms(model))[1] <= 1.6


# ---- home keyframe and physics -------------------------------------------------------------


@pytest.mark.parametrize("name", ROBOTS)
def test_home_stands_flat_on_the_ground(name: str) -> None:
    """At home the soles lie flat at z = 0 (±1 mm, not below); nothing else nears the floor."""
    robot = load_robot(name)
    model = scene_model(robot)
    data = mujoco.MjData(model)
    data.qpos[:] = robot.home_qpos
    data.ctrl[:] = robot.home_ctrl
    mujoco.mj_forward(model, data)
    sole_geoms = [model.geom(f"{side}_foot_sole").id for side in ("left", "right")]
    lowest, _ = vertical_extent(model, data, sole_geoms)
    assert -1e-6 <= lowest <= 1e-3
    for side in ("left", "right"):
        assert abs(data.site(f"{side}_sole").xpos[2]) < 1e-3
        np.testing.assert_allclose(
            data.site(f"{side}_sole").xmat.reshape(3, 3), np.eye(3), atol=1e-9
        )
    others = [g for g in robot_geoms(model) if g not in sole_geoms and model.geom_contype[g]]
    assert vertical_extent(model, data, others)[0] > 0.02
    # Balanced: the CoM is above the midpoint of the sole centres, which is the origin.
    mid = (data.site("left_sole").xpos + data.site("right_sole").xpos) / 2
    np.testing.assert_allclose(mid[:2], 0.0, atol=1e-9)
    com = data.subtree_com[model.body("pelvis").id]
    assert com[0] == pytest.approx(0.0, abs=1e-6)
    # The lab's COMAN is not left/right symmetric: its CoM is 0.13 mm right of the middle
    # (the feet share the weight so that their centre of pressure is under it).
    assert com[1] == pytest.approx(0.0, abs=2e-4 if name == "coman_lab" else 1e-6)
    assert robot.nominal_pelvis_height == pytest.approx(robot.home_qpos[2])


def static_torque(robot: Robot) -> np.ndarray:
    """Joint torques that hold home with each foot carrying half the weight at its sole centre."""
    pm = robot.pin_model
    pdata = pm.createData()
    q, _ = robot.pin_state_from_mujoco(robot.home_qpos, np.zeros(robot.mj_model.nv))
    g = pin.computeGeneralizedGravity(pm, pdata, q)
    pin.computeJointJacobians(pm, pdata, q)
    pin.updateFramePlacements(pm, pdata)
    tau = g.copy()
    for sole in ("left_sole", "right_sole"):
        jac = pin.getFrameJacobian(
            pm, pdata, robot.pin_frame_id(sole), pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        )
        tau -= jac[:3].T @ np.array([0.0, 0.0, robot.total_mass * GRAVITY / 2])
    np.testing.assert_allclose(tau[:6], 0.0, atol=1e-6)  # the base is in equilibrium
    return tau[robot.pin_v_idx]


@pytest.mark.parametrize("name", ROBOTS)
def test_robot_holds_home_for_one_second(name: str) -> None:
    """Held at home (PD + static torques, or COMAN's servos), the robot stands for 1 s."""
    robot = load_robot(name)
    model = scene_model(robot)
    data = mujoco.MjData(model)
    data.qpos[:] = robot.home_qpos
    data.ctrl[:] = robot.home_ctrl
    qpos_adr, qvel_adr = robot.link_joint_qpos_adr(model), robot.link_joint_qvel_adr(model)
    tau_home = static_torque(robot) if robot.control_mode == "torque" else None
    floor = model.geom("floor").id
    feet = {model.body("left_foot").id, model.body("right_foot").id}
    worst = 0.0
    with contact_law.applied_to(model):  # the lab's ground law, if the robot carries it
        for _ in range(round(1.0 / model.opt.timestep)):
            if tau_home is not None:
                error = robot.home_joint_pos - qpos_adr.link_values(data.qpos)
                data.ctrl[:] = tau_home + 300.0 * error - 20.0 * qvel_adr.link_values(data.qvel)
            mujoco.mj_step(model, data)
            link = qpos_adr.link_values(data.qpos)
            worst = max(worst, float(np.max(np.abs(link - robot.home_joint_pos))))
    assert worst < 0.02
    np.testing.assert_allclose(data.qpos[:3], robot.home_qpos[:3], atol=0.005)
    for c in data.contact[: data.ncon]:
        other = c.geom2 if c.geom1 == floor else c.geom1
        assert model.geom_bodyid[other] in feet
    if contact_law.from_model(model) is not None:
        return  # MuJoCo's raw F/T sensors leave out the law's force (the sensor model adds it)
    # F/T: MuJoCo reports the force the leg exerts on the foot: fz ≈ −(load − foot weight).
    foot_weight = model.body("left_foot").mass[0] * GRAVITY
    fz = data.sensor("left_foot_force").data[2] + data.sensor("right_foot_force").data[2]
    assert fz == pytest.approx(-(robot.total_mass * GRAVITY - 2 * foot_weight), rel=0.02)


def test_coman_neck_pull_reproduces_the_ankle_stiffness_experiment() -> None:
    """Faraji Fig. 20: with the stiffest gains, 7 N at the neck moves the pelvis ≈ 5 cm.

    Paper: pelvis ≈ 5 cm, torso ≈ 9 cm, apparent stiffness F·h / (2Δθ) ≈ 31 Nm/rad per
    ankle; TARGETS.md band 20-45 Nm/rad.
    """
    robot = load_robot("coman")
    model = scene_model(robot)
    kp = 500.0 / 0.45  # paper: k_d = 500 V/rad everywhere, 1/β ≈ 2.2
    model.actuator_gainprm[:, 0] = kp
    model.actuator_biasprm[:, 1] = -kp
    torso, pelvis = model.body("torso").id, model.body("pelvis").id
    neck_in_torso = np.array([0.0, 0.0, 0.17])  # top of the torso box, below the head

    def settled(force: float) -> tuple[float, float, float]:
        """Mean pelvis and neck x [m] over 2-4 s of a pull ramped up in 1 s; neck height [m]."""
        data = mujoco.MjData(model)
        data.qpos[:] = robot.home_qpos
        data.ctrl[:] = robot.home_ctrl
        pelvis_x, neck_x = [], []
        for i in range(8000):
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            neck = data.xpos[torso] + data.xmat[torso].reshape(3, 3) @ neck_in_torso
            f = np.array([force * min(1.0, i / 2000), 0.0, 0.0])
            data.xfrc_applied[torso, :3] = f
            data.xfrc_applied[torso, 3:] = np.cross(neck - data.xipos[torso], f)
            mujoco.mj_step(model, data)
            if i >= 4000:
                pelvis_x.append(data.xpos[pelvis, 0])
                neck_x.append(neck[0])
        return float(np.mean(pelvis_x)), float(np.mean(neck_x)), float(neck[2])

    p0, n0, neck_z = settled(0.0)
    p1, n1, _ = settled(7.0)
    ankle_z = 0.06
    lean = (p1 - p0) / (robot.nominal_pelvis_height - ankle_z)  # [rad]
    apparent = 7.0 * (neck_z - ankle_z) / (2 * lean)  # the paper's F·h / (2 Δθ) [Nm/rad]
    assert 0.03 < p1 - p0 < 0.07
    assert 0.05 < n1 - n0 < 0.11
    assert 20.0 < apparent < 45.0


@pytest.mark.parametrize("name", ["dyros_red", "coman", "kist_humanoid"])
def test_pin_state_is_pinocchios_rotation(name: str) -> None:
    """The compiled (q, v) equals the formula written with Pinocchio's own quaternion to 1e-12,
    for random and near-upright base states. A tolerance, not bit for bit: Pinocchio's
    rotation rounds differently between its builds (4.x against 3.x)."""
    robot = load_robot(name)
    rng = np.random.default_rng(8)
    n = len(robot.joint_names)
    for k in range(300):
        quat = rng.standard_normal(4) if k % 2 else np.r_[1.0, 0, 0, 0] + 0.02 * rng.normal(size=4)
        pos, linvel, angvel = rng.normal(size=(3, 3))
        joint_pos, joint_vel = rng.normal(size=(2, n))
        q, v = robot.pin_state(pos, quat, linvel, angvel, joint_pos, joint_vel)
        w, x, y, z = quat
        rot = pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()
        q_ref, v_ref = np.zeros(robot.pin_model.nq), np.zeros(robot.pin_model.nv)
        q_ref[0:3], q_ref[3:7], q_ref[robot.pin_q_idx] = pos, (x, y, z, w), joint_pos
        v_ref[0:3], v_ref[3:6], v_ref[robot.pin_v_idx] = rot.T @ linvel, angvel, joint_vel
        np.testing.assert_allclose(q, q_ref, rtol=0, atol=1e-12)
        np.testing.assert_allclose(v, v_ref, rtol=0, atol=1e-12)
        assert np.array_equal(robot.pin_configuration(pos, quat, joint_pos), q)


def test_controller_robot_carries_the_specs_servo_gains() -> None:
    """with_servo_gains copies the scene's servo gains (a spec's actuators.position_gain:
    the coman ablation in_place_paper_eq21 runs its hip pitch at 1111 Nm/rad, the robot model at 222) into a copy of the
    robot; the cached robot keeps its own, and a torque robot comes back unchanged."""
    from walkrepro.sim.world import build_scene
    from walkrepro.specs.files import load_spec

    robot = load_robot("coman")
    scene = build_scene(robot, load_spec("in_place_paper_eq21").spec)
    seen = with_servo_gains(robot, scene.model)
    assert seen is not robot
    assert seen.mj_model.actuator("l_hip_pitch").gainprm[0] == pytest.approx(1111.1)
    assert seen.mj_model.actuator("l_hip_pitch").biasprm[1] == pytest.approx(-1111.1)
    assert seen.mj_model.actuator("l_knee").gainprm[0] == pytest.approx(1111.11)
    assert robot.mj_model.actuator("l_hip_pitch").gainprm[0] == pytest.approx(222.222)
    assert load_robot("coman").mj_model.actuator("l_hip_pitch").gainprm[0] == pytest.approx(222.222)
    torque = load_robot("dyros_red")
    assert (
        with_servo_gains(torque, build_scene(torque, load_spec("forward_walk").spec).model)
        is torque
    )


def test_log3_agrees_with_pinocchio() -> None:
    """walkrepro's one log₃ (robot.log3, inlined in the whole-body ticks as log3_entries)
    equals pin.log3 to 1e-12 near identity (its series), in between, and near a half turn
    (the axis from the largest diagonal term), on random axes."""
    from walkrepro.sim.robot import log3

    rng = np.random.default_rng(8)
    angles = [0.0, 1e-9, 1e-6, 1e-3, 0.3, 2.0, np.pi - 1e-3, np.pi - 1e-7, np.pi]
    angles += list(rng.uniform(0, np.pi, 200))
    out = np.empty(3)
    for angle in angles:
        for _ in range(5):
            axis = rng.normal(size=3)
            rotation = pin.exp3(angle * axis / np.linalg.norm(axis))
            log3(np.asfortranarray(rotation), out)  # Data's matrices are column-major
            np.testing.assert_allclose(out, pin.log3(rotation), rtol=0, atol=1e-12)
            log3(np.ascontiguousarray(rotation), out)
            np.testing.assert_allclose(out, pin.log3(rotation), rtol=0, atol=1e-12)
