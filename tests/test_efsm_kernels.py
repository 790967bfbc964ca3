"""The compiled tick of the E-FSM controller (``lee2021/kernels.py``): its ports of
Pinocchio's last steps against Pinocchio, its footstep planner, and the whole tick against
the same tick composed of Pinocchio's frames, A⁻¹ and J̇ q̇ and the package's E-FSM and WBC."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest

from walkrepro.papers.lee2021 import kernels, wbc
from walkrepro.papers.lee2021.controller import EfsmController, EfsmParams
from walkrepro.papers.lee2021.fsm import (
    DS_TO_SSD,
    SSA_TO_DS,
    SSD_TO_SSA,
    FsmInput,
    FsmParams,
    Phase,
    capture_point,
    epsilon,
    fsm_step,
)
from walkrepro.sim.robot import frame_jacobian, load_robot

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
FEET = ("left_sole", "right_sole")


def _close(actual: np.ndarray, expected: np.ndarray, rel: float = 1e-9) -> None:
    """Equal up to rounding, relative to the largest entry."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    assert actual.shape == expected.shape
    scale = max(float(np.abs(expected).max(initial=0.0)), 1e-300)
    np.testing.assert_allclose(actual, expected, rtol=0, atol=rel * scale)


def test_frame_jacobian_matches_pinocchio() -> None:
    """The sole Jacobians built from data.J equal pinocchio.getFrameJacobian (LWA)."""
    robot, model, data, v = _moving_dyros(40, joint_scale=0.03, velocity_scale=0.3)
    for name in FEET:
        frame = robot.pin_frame_id(name)
        want = pin.getFrameJacobian(model, data, frame, LWA)
        chain = np.any(want != 0.0, axis=0)
        out = np.empty((6, v.size))
        frame_jacobian(data.J, chain, data.oMf[frame].translation, out)
        _close(out, want, rel=1e-14)


def test_warm_up_compiles_what_a_tick_uses() -> None:
    """After reset, ticks in and out of DS compile nothing more (the first tick is not slow)."""
    robot = load_robot("dyros_red")
    ctrl = EfsmController()
    ctrl.reset(robot, EfsmParams(), 0.0005)
    compiled = len(kernels.tick.signatures)
    home = ctrl._home_snapshot()
    ctrl.step(0.0, home)
    ctrl._st["phase"] = Phase.SSD
    cmd = ctrl.step(0.0005, home)
    assert cmd.signals["efsm_phase"] != int(Phase.DS)
    assert len(kernels.tick.signatures) == compiled


def test_fresh_reads_give_the_same_tick_as_views() -> None:
    """Where views of Pinocchio's Data could not be trusted, fresh reads give the same tick."""
    robot = load_robot("dyros_red")
    ticks = []
    for refresh in (False, True):
        ctrl = EfsmController()
        ctrl.reset(robot, EfsmParams(), 0.0005)
        assert not ctrl._refresh_pose  # this Pinocchio returns views of Data
        ctrl._refresh_pose = refresh
        home = ctrl._home_snapshot()
        ticks.append([ctrl.step(0.0, home).ctrl, ctrl.step(0.0005, home).ctrl])
    np.testing.assert_array_equal(ticks[0], ticks[1])


# ---- Pinocchio's last steps, the E-FSM and the whole tick, compiled -----------------------


def _moving_dyros(seed: int, joint_scale: float = 0.05, velocity_scale: float = 0.5) -> tuple:
    """dyros_red near home with random joint offsets and velocities (standard deviations
    ``joint_scale`` [rad], ``velocity_scale``); computeAllTerms, computeMinverse and the
    frames updated. Returns robot, Pinocchio model and data, and the velocity v."""
    robot = load_robot("dyros_red")
    model, data = robot.pin_model, robot.pin_model.createData()
    rng = np.random.default_rng(seed)
    qpos = robot.home_qpos.copy()
    qpos[7:] += rng.normal(scale=joint_scale, size=qpos.size - 7)
    q, v = robot.pin_state_from_mujoco(
        qpos, rng.normal(scale=velocity_scale, size=robot.mj_model.nv)
    )
    pin.computeAllTerms(model, data, q, v)
    pin.computeMinverse(model, data, q)
    pin.updateFramePlacements(model, data)
    return robot, model, data, v


@pytest.mark.parametrize("seed", range(3))
def test_inverse_inertia_is_pinocchios(seed: int) -> None:
    """The tick's A⁻¹ (computeMinverse's upper triangle, mirrored) is symmetric and agrees
    with Pinocchio's cholesky.decompose + computeMinv and with A's inverse."""
    _, model, data, _ = _moving_dyros(seed)
    out = kernels.symmetric_from_upper(data.Minv)
    np.testing.assert_array_equal(out, out.T)
    pin.cholesky.decompose(model, data)
    _close(out, pin.cholesky.computeMinv(model, data), rel=1e-10)
    _close(out @ kernels.symmetric_from_upper(data.M), np.eye(model.nv), rel=1e-9)


@pytest.mark.parametrize("seed", range(3))
def test_frames_match_pinocchio(seed: int) -> None:
    """The sole and F/T placements agree with Pinocchio's updateFramePlacements. Their J̇ q̇ comes from robot.frame_classical_acceleration,
    tested against Pinocchio in test_qpimpedance_tasks.py."""
    robot, model, data, _ = _moving_dyros(seed)
    for name in ("left_sole", "right_sole", "left_foot_ft", "right_foot_ft"):
        frame = model.frames[robot.pin_frame_id(name)]
        joint = frame.parentJoint
        rot, pos = kernels.frame_placement(
            data.oMi[joint].rotation,
            data.oMi[joint].translation,
            frame.placement.rotation,
            frame.placement.translation,
        )
        want = data.oMf[robot.pin_frame_id(name)]
        _close(rot, want.rotation, rel=1e-14)
        _close(pos, want.translation, rel=1e-14)


def test_next_swing_target_is_the_planned_step() -> None:
    """The planner's target: step_length ahead, width aside, in place after n_steps."""
    p_sup, heading, lateral = (
        np.array([0.3, -0.14, 0.0]),
        np.array([1.0, 0, 0]),
        np.array([0, 1.0, 0]),
    )
    ahead = kernels.next_swing_target(p_sup, 0, 3, 0.1, 12, 0.28, heading, lateral)
    np.testing.assert_allclose(ahead, [0.4, 0.14, 0.0])
    in_place = kernels.next_swing_target(p_sup, 1, 13, 0.1, 12, 0.28, heading, lateral)
    np.testing.assert_allclose(in_place, [0.3, -0.42, 0.0])
    unlimited = kernels.next_swing_target(p_sup, 0, 99, 0.1, -1, 0.28, heading, lateral)
    np.testing.assert_allclose(unlimited, [0.4, 0.14, 0.0])


def test_next_swing_target_first_step_scaled() -> None:
    """EfsmParams.first_step_scale scales the first footstep only (the lab's half step)."""
    p_sup, heading, lateral = np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    first = kernels.next_swing_target(p_sup, 1, 1, 0.1, 12, 0.2, heading, lateral, 0.5)
    np.testing.assert_allclose(first, [0.05, -0.2, 0.0])
    second = kernels.next_swing_target(p_sup, 0, 2, 0.1, 12, 0.2, heading, lateral, 0.5)
    np.testing.assert_allclose(second, [0.1, 0.2, 0.0])


SIDES = ("left", "right")


def _reference_tick(ctrl: EfsmController, sensors, state: np.ndarray) -> tuple:
    """One tick composed in Python: Pinocchio's frames, J̇ q̇ and A⁻¹ (cholesky, computeMinv),
    the package's E-FSM step and whole_body_torques, the footstep planner's formula and the
    F/T CoP. Returns Γ, the signals by name, and the transition bits."""
    st, p, model, data = state[0], ctrl._p, ctrl._model, ctrl._data
    targets, feet = ctrl._targets, ctrl._params.feet
    q, v = sensors.pinocchio_state(ctrl._robot)
    pin.computeAllTerms(model, data, q, v)
    pin.updateFramePlacements(model, data)
    soles = [data.oMf[ctrl._sole[f]] for f in SIDES]
    params = FsmParams(p.zeta, p.r, p.dxp, p.d_thr, p.v_stop, p.use_epsilon)
    sup = int(st["support"])
    sw = 1 - sup
    com, vcom, rot, z_m0 = data.com[0], data.vcom[0], st["rot_w"].copy(), targets.z_m0
    ow = kernels.ow_frame(soles[sup].translation, soles[sw].translation, com, vcom, rot)
    x_cp = capture_point(ow.com_w[0], ow.vcom_w[0], z_m0)
    out = fsm_step(
        int(st["phase"]),
        float(st["xp_des"]),
        FsmInput(ow.com_w[0], ow.vcom_w[0], x_cp, ow.x_s),
        params,
    )
    xp_des, target, steps = out.xp_des, st["swing_target"].copy(), int(st["steps_done"])
    if out.transitions & DS_TO_SSD:
        sup, sw, steps = sw, sup, steps + 1
        length = p.step_length if p.n_steps is None or steps <= p.n_steps else 0.0
        side = 1.0 if sw == 0 else -1.0
        target = soles[sup].translation + targets.heading * length
        target = target + side * targets.width * targets.lateral
        ow = kernels.ow_frame(soles[sup].translation, soles[sw].translation, com, vcom, rot)
        x_cp = capture_point(ow.com_w[0], ow.vcom_w[0], z_m0)
        xp_des = 0.0
    com_w, vcom_w, x_s, double = ow.com_w, ow.vcom_w, ow.x_s, out.phase == Phase.DS
    c, s = math.cos(ow.yaw), math.sin(ow.yaw)
    p_sup, p_sw = soles[sup].translation, soles[sw].translation
    h = p.raise_height if out.phase == Phase.SSD else p.land_height
    sw_ref = np.array([target[0], target[1], p_sup[2] + h])
    eps_on, ds_start = 1.0, float(st["ds_start_xp"])
    if double:
        ds_start = xp_des if math.isnan(ds_start) else ds_start
        eps_on = epsilon(abs(xp_des - ds_start), p.d_thr)
    contacts = (sup, sw) if double else (sup,)
    jc_dot_v = np.concatenate(
        [pin.getFrameClassicalAcceleration(model, data, ctrl._sole[SIDES[f]], LWA).vector
         for f in contacts]
    )  # fmt: skip
    pin.cholesky.decompose(model, data)
    tau = np.empty(st["tau"].size)
    minv = pin.cholesky.computeMinv(model, data)
    report = wbc.whole_body_torques(
        wbc.WbcDynamics(
            np.triu(minv) + np.triu(minv, 1).T, data.nle, jc_dot_v, data.J, data.Jcom, com,
            vcom, v,
        ),
        wbc.WbcFrames(
            rot, p_sup, p_sw, soles[sup].rotation, soles[sw].rotation, data.oMi[1].rotation,
            feet.sole_chain[sup], feet.sole_chain[sw],
        ),
        wbc.WbcTargets(
            targets.rot_des_pelvis, targets.rot_des_swing,
            p_sup + rot @ np.array([com_w[0], 0.0, z_m0]), sw_ref, int(out.phase), out.epsilon,
            eps_on, xp_des, x_s,
        ),
        ctrl._params.wbc,
        tau,
    )  # fmt: skip
    meas = ctrl._measured_cop(sensors)
    valid = all(math.isfinite(x) for x in meas)
    cop = (report.cop_exp_x, report.cop_exp_y)
    signals = {
        "fsm_state": 0 if double else (1 if sup == 0 else -1),
        "efsm_phase": int(out.phase),
        "epsilon": out.epsilon,
        "epsilon_onset": eps_on,
        "d": out.d if math.isfinite(out.d) else 1.0,
        "com_w": list(com_w),
        "com_vel_w": list(vcom_w),
        "com_world": list(com),
        "com_vel_world": list(vcom),
        "cp_w": x_cp,
        "cp_ref_w": x_s - p.r,
        "x_s_w": x_s,
        "xp_des_w": xp_des,
        "xp_des_world": [p_sup[0] + c * xp_des, p_sup[1] + s * xp_des],
        "cop_exp_w": list(cop),
        "cop_exp_world": [
            p_sup[0] + (c * cop[0] - s * cop[1]),
            p_sup[1] + (s * cop[0] + c * cop[1]),
        ],
        "cop_meas_world": list(meas if valid else (0.0, 0.0)),
        "cop_meas_valid": int(valid),
        "swing_pos_world": list(p_sw),
        "swing_ref_world": list(sw_ref),
        "swing_foot": 0 if double else (1 if sw == 1 else -1),
        "support_pos_world": list(p_sup),
        "ow_yaw": ow.yaw,
        "com_force_x": report.com_force_x,
        "balancing": int(report.balancing),
        "steps_done": steps,
        "tau_ref": list(tau),
    }
    return tau, signals, out.transitions


@pytest.mark.parametrize("case", ["SSD", "SSA", "DS", "DS_ends"])
def test_tick_matches_the_reference_composition(case: str) -> None:
    """The compiled tick (O_w, E-FSM, footsteps, WBC, CoPs) equals the tick composed of the
    references, in each phase and when DS ends (the feet swap roles, the next step is planned)."""
    robot = load_robot("dyros_red")
    ctrl = EfsmController()
    ctrl.reset(robot, EfsmParams(step_length=0.1, step_width=0.28, n_steps=3), 0.0005)
    home = ctrl._home_snapshot()
    ctrl.step(0.0, home)  # the first tick: the initial targets
    rng = np.random.default_rng(len(case))
    sensors = dataclasses.replace(
        home,
        joint_pos=home.joint_pos + rng.normal(scale=0.02, size=home.joint_pos.size),
        joint_vel=rng.normal(scale=0.3, size=home.joint_vel.size),
        base_linvel=rng.normal(scale=0.1, size=3),
        left_ft=np.r_[0.0, 0.0, 300.0, rng.normal(size=3)],
        right_ft=np.r_[0.0, 0.0, 200.0, rng.normal(size=3)],
    )
    st = ctrl._st
    st["phase"] = int(Phase[case.removesuffix("_ends")])
    st["swing_target"] = [0.1, 0.14, 0.0]
    if case == "DS_ends":  # x_p^des one Δ short of x_s: the ramp ends this tick
        q, v = sensors.pinocchio_state(robot)
        pin.computeAllTerms(ctrl._model, ctrl._data, q, v)
        pin.updateFramePlacements(ctrl._model, ctrl._data)
        sup = int(st["support"])
        p_sup, p_sw = (ctrl._data.oMf[ctrl._sole[SIDES[f]]].translation for f in (sup, 1 - sup))
        x_s = kernels.ow_frame(p_sup, p_sw, ctrl._data.com[0], ctrl._data.vcom[0], np.eye(3)).x_s
        st["xp_des"], st["ds_start_xp"] = x_s - 0.5 * ctrl._p.dxp, x_s - 0.05
    state = ctrl._state.copy()
    tau_want, signals_want, transitions = _reference_tick(ctrl, sensors, state)
    cmd = ctrl.step(0.0005, sensors)
    bits = {SSD_TO_SSA: ("SSD", "SSA"), SSA_TO_DS: ("SSA", "DS"), DS_TO_SSD: ("DS", "SSD")}
    assert [(e["from"], e["to"]) for e in cmd.events if e["kind"] == "fsm"] == [
        names for bit, names in bits.items() if transitions & bit
    ]
    assert (case == "DS_ends") == any(e["kind"] == "support" for e in cmd.events)
    _close(cmd.ctrl, tau_want, rel=1e-9)
    assert list(cmd.signals) == list(signals_want)
    for name, want in signals_want.items():
        got = cmd.signals[name]
        if isinstance(want, int):
            assert got == want, name
        else:
            _close(np.asarray(got, dtype=float), np.asarray(want, dtype=float), rel=1e-9)
