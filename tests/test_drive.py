"""Tests of the DYROS RED joint drive model (robots/dyros_red_actuated, Lee et al. §V-A)."""

from __future__ import annotations

import math

import mujoco
import numpy as np

from walkrepro.robot import MOTOR_SUFFIX, load_robot

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
