"""Scene building: floor, obstacles, physics options, actuator settings."""

from __future__ import annotations

import mujoco
import numpy as np

from walkrepro.sim.robot import load_robot
from walkrepro.sim.world import build_scene
from walkrepro.specs.models import ExperimentSpec


def make_spec(**extra: object) -> ExperimentSpec:
    base = {
        "name": "t",
        "description": "d",
        "paper": {"key": "walkrepro"},
        "robot": "coman",
        "controller": {"type": "posture"},
        "sim": {"duration": 1.0, "timestep": 0.001, "control_period": 0.002},
    }
    return ExperimentSpec.model_validate({**base, **extra})


def test_scene_has_floor_obstacle_and_timestep() -> None:
    """The scene adds the floor and a tilted box obstacle, and uses the spec's timestep."""
    spec = make_spec(
        world={
            "obstacles": [
                {
                    "name": "obstacle_step",
                    "size": [0.4, 0.6, 0.05],
                    "position": [0.3, 0, 0.025],
                    "tilt_x_deg": 20,
                }
            ]
        }
    )
    scene = build_scene(load_robot("coman"), spec)
    m = scene.model
    assert m.opt.timestep == 0.001
    assert m.geom("floor").type == mujoco.mjtGeom.mjGEOM_PLANE
    box = m.geom("obstacle_step")
    assert np.allclose(m.geom_size[box.id], [0.2, 0.3, 0.025])
    quat = m.body("obstacle_step").quat
    assert np.isclose(2 * np.degrees(np.arccos(quat[0])), 20.0)  # 20 degrees about x
    again = mujoco.MjModel.from_xml_string(scene.xml)
    assert again.nbody == m.nbody and again.ngeom == m.ngeom


def test_position_gain_override_sets_servo_stiffness() -> None:
    """actuators.position_gain sets kp of the matching position servos only."""
    spec = make_spec(actuators={"position_gain": {"*ankle_roll": 500.0}})
    m = build_scene(load_robot("coman"), spec).model
    roll = m.actuator("l_ankle_roll").id
    pitch = m.actuator("l_ankle_pitch").id
    assert m.actuator_gainprm[roll, 0] == 500.0 and m.actuator_biasprm[roll, 1] == -500.0
    default = load_robot("coman").mj_model
    assert m.actuator_gainprm[pitch, 0] == default.actuator_gainprm[pitch, 0]


def test_drive_friction_and_torque_lag_overrides() -> None:
    """actuators.friction_loss sets the Coulomb friction of the DoF each actuator drives (the
    motor DoF of a drive), actuators.torque_lag the time constant of filtered actuators."""
    robot = load_robot("dyros_red_actuated")
    spec = make_spec(
        robot="dyros_red_actuated",
        controller={"type": "efsm"},
        actuators={"friction_loss": 0.25, "torque_lag": 0.002},
    )
    m = build_scene(robot, spec).model
    default = robot.mj_model
    for i in range(m.nu):
        driven = m.actuator_trnid[i, 0]
        assert m.joint(driven).name.endswith("_motor")
        assert m.dof_frictionloss[m.jnt_dofadr[driven]] == 0.25
        assert m.actuator_dynprm[i, 0] == 0.002
    gear = m.jnt_dofadr[m.joint("l_knee").id]  # the gear DoF keeps the robot's value
    assert m.dof_frictionloss[gear] == default.dof_frictionloss[default.joint("l_knee").dofadr[0]]
    unset = build_scene(robot, make_spec(robot="dyros_red_actuated", controller={"type": "efsm"}))
    assert np.array_equal(unset.model.dof_frictionloss, default.dof_frictionloss)
    assert np.array_equal(unset.model.actuator_dynprm, default.actuator_dynprm)


def test_obstacle_friction_takes_precedence() -> None:
    """An obstacle's own friction is the one MuJoCo uses against the robot's feet."""
    spec = make_spec(
        world={
            "obstacles": [
                {
                    "name": "obstacle_slick",
                    "size": [0.2, 0.2, 0.1],
                    "position": [1, 0, 0.05],
                    "friction": 0.2,
                }
            ]
        }
    )
    m = build_scene(load_robot("coman"), spec).model
    slick = m.geom("obstacle_slick").id
    assert m.geom_friction[slick, 0] == 0.2
    foot_geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] == m.body("left_foot").id]
    assert all(m.geom_priority[slick] > m.geom_priority[g] for g in foot_geoms)


def test_floor_friction_acts_on_the_soles() -> None:
    """world.floor_friction is the friction of every sole-floor contact, also below the
    soles' own 1.0 (MuJoCo would otherwise take the larger of the two), and a free obstacle
    keeps its own friction against the floor."""
    box = {"name": "obstacle_free", "size": [0.2, 0.2, 0.1], "position": [1, 0, 0.05]}
    for mu in (0.3, 1.0):
        spec = make_spec(
            world={"floor_friction": mu, "obstacles": [{**box, "fixed": False, "mass": 5.0}]}
        )
        m = build_scene(load_robot("coman"), spec).model
        d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
        d.qpos[2] -= 0.002  # press the soles 2 mm into the floor
        mujoco.mj_forward(m, d)
        floor = m.geom("floor").id
        soles = {m.geom("left_foot_sole").id, m.geom("right_foot_sole").id}
        on_floor = [c for c in d.contact[: d.ncon] if floor in (c.geom1, c.geom2)]
        sole_contacts = [c for c in on_floor if soles & {c.geom1, c.geom2}]
        assert sole_contacts and all(c.friction[0] == mu for c in sole_contacts)
        box_id = m.geom("obstacle_free").id
        assert m.geom_priority[box_id] > m.geom_priority[floor]


def test_top_anchored_obstacle_tilts_about_its_top_face_centre() -> None:
    """With anchor: top the top face's centre stays at ``position`` whatever the tilt."""
    for tilt in (0.0, 10.0, 20.0):
        box = {"name": "obstacle_step", "size": [0.3, 0.16, 0.2], "position": [0.5, -0.09, 0.05]}
        spec = make_spec(world={"obstacles": [{**box, "anchor": "top", "tilt_y_deg": -tilt}]})
        m = build_scene(load_robot("coman"), spec).model
        d = mujoco.MjData(m)
        mujoco.mj_kinematics(m, d)
        g = m.geom("obstacle_step").id
        top = d.geom_xpos[g] + d.geom_xmat[g].reshape(3, 3)[:, 2] * m.geom_size[g, 2]
        assert np.allclose(top, [0.5, -0.09, 0.05], atol=1e-12)
        normal = d.geom_xmat[g].reshape(3, 3)[:, 2]
        assert np.isclose(np.degrees(np.arccos(normal[2])), tilt)
        assert normal[0] <= 1e-12  # front up: the top face's normal leans backwards


def test_obstacle_solref_sets_its_contacts_stiffness() -> None:
    """An obstacle's own solref (with its reason) replaces the contact in force on its geom only."""
    box = {"name": "obstacle_hard", "size": [0.2, 0.2, 0.1], "position": [1, 0, 0.05]}
    own = {"solref": [0.005, 1.0], "solref_reason": "a test of the override"}
    m = build_scene(load_robot("coman"), make_spec(world={"obstacles": [{**box, **own}]})).model
    assert np.allclose(m.geom_solref[m.geom("obstacle_hard").id], [0.005, 1.0])
    assert np.allclose(m.geom_solref[m.geom("floor").id], [0.02, 1.0])


def test_the_cone_is_the_robots_unless_the_spec_sets_it() -> None:
    """Each robot's MJCF carries its cone (COMAN elliptic, KIST MuJoCo's pyramidal default);
    world.cone overrides it and world.condim sets the floor's and the obstacles' condim."""
    coman = build_scene(load_robot("coman"), make_spec()).model
    assert coman.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    kist_spec = {"robot": "kist_humanoid", "controller": {"type": "qpimpedance"}}
    kist = build_scene(load_robot("kist_humanoid"), make_spec(**kist_spec)).model
    assert kist.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    assert kist.opt.solver == mujoco.mjtSolver.mjSOL_NEWTON  # MuJoCo's default
    block = {"name": "obstacle_block", "size": [0.3, 0.16, 0.04], "position": [0.5, 0, 0.02]}
    spec = make_spec(world={"cone": "elliptic", "condim": 6, "obstacles": [block]})
    m = build_scene(load_robot("coman"), spec).model
    assert m.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert m.geom("floor").condim == 6 and m.geom("obstacle_block").condim == 6
    m = build_scene(load_robot("coman"), make_spec(world={"cone": "pyramidal"})).model
    assert m.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    assert m.geom("floor").condim == 3
