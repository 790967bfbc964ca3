"""Tests of the DYROS RED joint drive model (robots/dyros_red_actuated, Lee et al. §V-A)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from walkrepro.sim.robot import MOTOR_SUFFIX, load_robot

JOINT = "l_knee"


def _drive_values() -> dict[str, float]:
    """The knee's drive as the robot's MJCF gives it."""
    model = load_robot("dyros_red_actuated").mj_model
    motor, spring = model.joint(JOINT + MOTOR_SUFFIX), model.joint(JOINT)
    act = model.actuator(JOINT)
    return {
        "j_m": float(model.dof_armature[motor.dofadr[0]]),
        "b_m": float(model.dof_damping[motor.dofadr[0]]),
        "k": float(model.jnt_stiffness[spring.id]),
        "b_s": float(model.dof_damping[spring.dofadr[0]]),
        "tau_c": float(act.dynprm[0]),
    }


def _bench(v: dict[str, float], dt: float) -> mujoco.MjModel:
    """One drive whose link is held (a link inertia of 1e6 kg m²), without Coulomb friction."""
    xml = f"""
    <mujoco>
      <option timestep="{dt}" gravity="0 0 0"/>
      <worldbody>
        <body name="link">
          <joint name="m" type="hinge" axis="0 1 0" armature="{v["j_m"]}" damping="{v["b_m"]}"/>
          <joint name="s" type="hinge" axis="0 1 0" stiffness="{v["k"]}" damping="{v["b_s"]}"/>
          <inertial pos="0 0 0" mass="1" diaginertia="1e6 1e6 1e6"/>
        </body>
      </worldbody>
      <actuator>
        <general name="a" joint="m" dyntype="filterexact" dynprm="{v["tau_c"]}" gainprm="1"/>
      </actuator>
    </mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


def _peaks(x: np.ndarray) -> np.ndarray:
    return np.flatnonzero((x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:])) + 1


def test_motor_torque_step_rings_at_the_closed_form_frequency_and_decay() -> None:
    """A motor-side torque step rings through the gear at ω_d = ω_n √(1−ζ²), decaying as e^(−ζω_n t)."""
    v = _drive_values()
    dt, tau0 = 1e-5, 50.0
    model = _bench(v, dt)
    data = mujoco.MjData(model)
    n = int(0.1 / dt)
    link_torque = np.empty(n)
    for i in range(n):
        data.qfrc_applied[0] = tau0  # the step on the motor DoF [Nm]
        mujoco.mj_step(model, data)
        # The gear's torque on the link: the spring DoF's passive force, sign reversed.
        link_torque[i] = v["k"] * -data.qpos[1] - v["b_s"] * data.qvel[1]
    w_n = math.sqrt(v["k"] / v["j_m"])  # link held: the rotor rings on the gear spring
    zeta = (v["b_m"] + v["b_s"]) / (2.0 * math.sqrt(v["k"] * v["j_m"]))
    w_d = w_n * math.sqrt(1.0 - zeta**2)
    peaks = _peaks(link_torque)
    assert len(peaks) >= 4
    period = float(np.mean(np.diff(peaks[:4]))) * dt
    assert abs(period - 2 * math.pi / w_d) / (2 * math.pi / w_d) < 0.01
    over = link_torque[peaks[:4]] - tau0  # overshoots above the static torque
    ratio = float(np.mean(over[1:] / over[:-1]))
    assert abs(ratio - math.exp(-zeta * w_n * 2 * math.pi / w_d)) < 0.02
    assert abs(link_torque[-1000:].mean() - tau0) < 0.02 * tau0  # it settles on the step


def test_torque_loop_is_a_first_order_lag() -> None:
    """The commanded torque reaches the motor as 1 − e^(−t/τ_c) (the drive's torque loop)."""
    v = _drive_values()
    dt = 1e-5
    model = _bench(v, dt)
    data = mujoco.MjData(model)
    data.ctrl[0] = 10.0
    t_end = v["tau_c"]
    for _ in range(round(t_end / dt)):
        mujoco.mj_step(model, data)
    assert abs(data.act[0] - 10.0 * (1 - math.exp(-1.0))) < 1e-6  # filterexact: exact


def test_encoders_read_the_motor_side() -> None:
    """dyros_red_actuated's encoders read the motor DoF; dyros_red's read the link."""
    actuated, rigid = load_robot("dyros_red_actuated"), load_robot("dyros_red")
    assert actuated.encoders_motor_side and not rigid.encoders_motor_side
    assert actuated.control_mode == "torque"
    qpos = actuated.home_qpos.copy()
    spring = actuated.mj_model.joint(JOINT)
    qpos[spring.qposadr[0]] += 0.01  # twist the gear: the link moves, the motor does not
    enc = actuated.encoder_qpos_adr().link_values(qpos)
    link = actuated.link_joint_pos(qpos)
    i = actuated.joint_names.index(JOINT)
    assert abs((link[i] - enc[i]) - (0.01 + actuated.home_qpos[spring.qposadr[0]])) < 1e-12


# ---- the lab's published drive values, per joint kind (issue 29) -----------------------

#: Reflected rotor inertia [kg m²] of the lab's TOCABI Isaac Lab configuration.
ARMATURE = {
    "hip_yaw": 0.614,
    "hip_roll": 0.862,
    "hip_pitch": 1.09,
    "knee": 1.09,
    "ankle_pitch": 1.09,
    "ankle_roll": 0.360,
}
#: (damping [Nms/rad], friction [Nm]) of the lab's TOCABI joint classes: SHG-20, SHD-20.
SHG20, SHD20 = (0.0248, 0.9), (0.0161, 22.0)


def _motor_dof(model: mujoco.MjModel, joint: str) -> int:
    return int(model.joint(joint + MOTOR_SUFFIX).dofadr[0])


def test_each_joint_kind_carries_the_labs_published_drive_values() -> None:
    """Every motor DoF has its joint kind's armature, damping and friction (SHD-20 at the ankle roll)."""
    model = load_robot("dyros_red_actuated").mj_model
    for side in "lr":
        for kind, armature in ARMATURE.items():
            damping, friction = SHD20 if kind == "ankle_roll" else SHG20
            dof = _motor_dof(model, f"{side}_{kind}")
            assert model.dof_armature[dof] == armature
            assert model.dof_damping[dof] == damping
            assert model.dof_frictionloss[dof] == friction


def test_variants_differ_from_the_drive_model_only_where_they_say() -> None:
    """dyros_red_actuated_9_9 changes only the SHG-20 friction; dyros_red_armature only dyros_red's armature."""
    base = load_robot("dyros_red_actuated").mj_model
    f99 = load_robot("dyros_red_actuated_9_9").mj_model
    changed = np.flatnonzero(base.dof_frictionloss != f99.dof_frictionloss)
    expected = sorted(
        _motor_dof(base, f"{s}_{k}") for s in "lr" for k in ARMATURE if k != "ankle_roll"
    )
    assert changed.tolist() == expected
    assert np.all(f99.dof_frictionloss[changed] == 9.9)
    assert np.array_equal(base.dof_armature, f99.dof_armature)
    assert np.array_equal(base.dof_damping, f99.dof_damping)
    rigid, armature = load_robot("dyros_red"), load_robot("dyros_red_armature")
    assert np.array_equal(rigid.mj_model.dof_damping, armature.mj_model.dof_damping)
    for side in "lr":
        for kind, value in ARMATURE.items():
            dof = int(armature.mj_model.joint(f"{side}_{kind}").dofadr[0])
            assert armature.mj_model.dof_armature[dof] == value
            # The controller's Pinocchio model carries the same rotor inertia.
            idx_v = armature.pin_model.joints[armature.pin_model.getJointId(f"{side}_{kind}")].idx_v
            assert armature.pin_model.armature[idx_v] == value


def test_per_joint_value_needs_every_joint_kind() -> None:
    """A per-joint drive value is read per joint kind; a kind it does not name is an error."""
    import importlib.util
    import sys

    from walkrepro import ROBOTS_DIR

    spec = importlib.util.spec_from_file_location("build_models", ROBOTS_DIR / "build_models.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses resolve annotations through sys.modules
    spec.loader.exec_module(module)
    assert module.per_joint(0.5, "knee") == 0.5
    assert module.per_joint(module.shg20_shd20(0.9, 22.0), "ankle_roll") == 22.0
    assert module.per_joint(module.shg20_shd20(0.9, 22.0), "hip_yaw") == 0.9
    with pytest.raises(KeyError):
        module.per_joint({"knee": 1.0}, "ankle_roll")
