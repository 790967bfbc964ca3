"""Tests of the E-FSM controller's swing-foot force (Lee et al. 2021, §IV-C and §V-B)."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pinocchio as pin

from walkrepro.controllers.ranges import MAX_FORCE, MAX_TORQUE
from walkrepro.papers.lee2021.controller import EfsmController, EfsmParams
from walkrepro.papers.lee2021.fsm import Phase
from walkrepro.sim.robot import load_robot


def _controller(**params: object) -> EfsmController:
    ctrl = EfsmController.__new__(EfsmController)
    ctrl._p = EfsmParams(**params)
    return ctrl


def _coupled_lambda(seed: int = 0) -> np.ndarray:
    """A task-2 inertia (3 CoM/yaw rows + 6 swing rows) with linear–angular coupling."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(9, 9))
    lam = a @ a.T + 9.0 * np.eye(9)
    lam[3:6, 3:6] += 10.0 * np.eye(3)  # the swing foot's mass [kg]
    return lam


def test_saturated_force_keeps_orientation_acceleration() -> None:
    """With the force rows saturated, the swing foot still gets its orientation acceleration."""
    lam = _coupled_lambda()
    acc = np.r_[0.1, -0.2, 0.05, 20.0, -15.0, 5.0, 0.3, -0.2, 0.1]  # large linear ẍ*
    ctrl = _controller(fs_max_force=30.0, fs_max_moment=1e3)
    f2 = ctrl._task2_force(lam, acc, False, 1.0, Phase.SSD)
    fs = f2[3:]
    assert np.all(np.abs(fs[:3]) <= 30.0 + 1e-9)
    acc_s = np.linalg.solve(lam[3:, 3:], fs - lam[3:, :3] @ acc[:3])
    np.testing.assert_allclose(acc_s[3:], acc[6:], atol=1e-9)


def test_uniform_saturation_keeps_swing_acceleration_direction() -> None:
    """The uniform bound scales the commanded linear swing acceleration, never turns it."""
    lam = _coupled_lambda(3)
    acc = np.r_[0.1, -0.2, 0.05, 20.0, 0.0, 5.0, 0.3, -0.2, 0.1]  # forward and up, far away
    ctrl = _controller(fs_max_force=30.0, fs_max_moment=1e3, fs_saturation="uniform")
    fs = ctrl._task2_force(lam, acc, False, 1.0, Phase.SSD)[3:]
    assert np.isclose(np.max(np.abs(fs[:3])), 30.0)  # the largest component meets the bound
    acc_s = np.linalg.solve(lam[3:, 3:], fs - lam[3:, :3] @ acc[:3])
    scale = acc_s[0] / acc[3]
    assert 0.0 < scale < 1.0
    np.testing.assert_allclose(acc_s[:3], scale * acc[3:6], atol=1e-9)


def test_componentwise_clip_turns_swing_acceleration() -> None:
    """Clipping each force row alone changes the acceleration's direction (why 'uniform')."""
    lam = _coupled_lambda(3)
    acc = np.r_[0.1, -0.2, 0.05, 20.0, 0.0, 5.0, 0.3, -0.2, 0.1]
    ctrl = _controller(fs_max_force=30.0, fs_max_moment=1e3, fs_saturation="component")
    fs = ctrl._task2_force(lam, acc, False, 1.0, Phase.SSD)[3:]
    acc_s = np.linalg.solve(lam[3:, 3:], fs - lam[3:, :3] @ acc[:3])
    ratio = acc_s[2] / acc_s[0]
    assert abs(ratio - acc[5] / acc[3]) > 0.05


def test_unsaturated_force_is_lambda_times_acceleration() -> None:
    """Below the bound, F_s is Λ ẍ* (Eq. 6) whichever saturation is used."""
    lam = _coupled_lambda(1)
    acc = np.r_[0.1, -0.2, 0.05, 0.2, -0.1, 0.1, 0.3, -0.2, 0.1]
    for decoupled in (True, False):
        ctrl = _controller(
            fs_max_force=MAX_FORCE, fs_max_moment=MAX_TORQUE, fs_decoupled_saturation=decoupled
        )
        f2 = ctrl._task2_force(lam, acc, False, 1.0, Phase.SSD)
        np.testing.assert_allclose(f2[3:], lam[3:] @ acc, atol=1e-9)


def test_epsilon_scales_swing_force_in_ssa() -> None:
    """ε multiplies F_s in SSA (§IV-C): ε = 0 gives no swing-foot force."""
    lam = _coupled_lambda(2)
    acc = np.r_[0.1, -0.2, 0.05, 2.0, -1.0, 1.0, 0.3, -0.2, 0.1]
    f2 = _controller()._task2_force(lam, acc, False, 0.0, Phase.SSA)
    np.testing.assert_allclose(f2[3:], 0.0, atol=1e-12)


def _measured_cop_reference(ctrl: EfsmController, fts: dict[str, np.ndarray]) -> np.ndarray:
    """The CoP of §VI-D2 from the summed world wrench, written with full 3-D vectors."""
    model, data = ctrl._model, ctrl._data
    force, moment = np.zeros(3), np.zeros(3)
    for f in ("left", "right"):
        m_ft = data.oMf[ctrl._ft[f]]
        fw, tw = m_ft.rotation @ fts[f][:3], m_ft.rotation @ fts[f][3:]
        foot_joint = ctrl._robot.pin_joint_id(f"{f[0]}_ankle_roll")
        inertia = model.inertias[foot_joint]
        weight = np.array([0.0, 0.0, inertia.mass * 9.81])
        com_foot = data.oMi[foot_joint].act(inertia.lever)
        if (fw + weight)[2] <= 0.0:
            continue
        force += fw + weight
        moment += tw + np.cross(m_ft.translation, fw) + np.cross(com_foot, weight)
    if force[2] <= 1e-6:
        return np.array([np.nan, np.nan])
    return np.array([-moment[1] / force[2], moment[0] / force[2]])


def test_measured_cop_matches_the_wrench_sum() -> None:
    """The F/T CoP (§VI-D2) equals the one from the summed 3-D wrenches, feet unloaded or not."""
    robot = load_robot("dyros_red")
    ctrl = EfsmController()
    ctrl.reset(robot, EfsmParams(), 0.0005)
    rng = np.random.default_rng(7)
    qpos = robot.home_qpos.copy()
    qpos[7:] += rng.normal(scale=0.05, size=qpos.size - 7)
    q, _ = robot.pin_state_from_mujoco(qpos, np.zeros(robot.mj_model.nv))
    pin.forwardKinematics(ctrl._model, ctrl._data, q)
    pin.updateFramePlacements(ctrl._model, ctrl._data)
    down = np.array([0.0, 0.0, -1.0])  # the ankle frames are roughly level
    for loads in ((300.0, 200.0), (300.0, -50.0), (-50.0, -50.0)):
        fts = {}
        for f, load in zip(("left", "right"), loads, strict=True):
            rot = ctrl._data.oMf[ctrl._ft[f]].rotation
            fts[f] = np.r_[rot.T @ (load * -down) + rng.normal(size=3), rng.normal(size=3)]
        sensors = SimpleNamespace(left_ft=fts["left"], right_ft=fts["right"])
        cop = ctrl._measured_cop(sensors)  # type: ignore[arg-type]
        np.testing.assert_allclose(cop, _measured_cop_reference(ctrl, fts), rtol=1e-12, atol=1e-15)


def test_pin_state_buffers_equal_the_snapshot_state() -> None:
    """The tick's reused (q, v) buffers hold exactly what sensors.pinocchio_state gives."""
    import dataclasses

    robot = load_robot("dyros_red")
    ctrl = EfsmController()
    ctrl.reset(robot, EfsmParams(), 0.0005)
    home = ctrl._home_snapshot()
    rng = np.random.default_rng(3)
    for _ in range(3):
        quat = rng.normal(size=4)
        snap = dataclasses.replace(
            home,
            joint_pos=home.joint_pos + rng.normal(scale=0.1, size=home.joint_pos.size),
            joint_vel=rng.normal(size=home.joint_vel.size),
            base_pos=rng.normal(size=3),
            base_quat=quat / np.linalg.norm(quat),
            base_linvel=rng.normal(size=3),
            base_angvel=rng.normal(size=3),
        )
        q, v = ctrl._pin_state(snap)
        q_ref, v_ref = snap.pinocchio_state(robot)
        assert np.array_equal(q, q_ref) and np.array_equal(v, v_ref)


def test_ow_frame_matches_the_rotation_it_writes() -> None:
    """ow_frame's CoM, velocity and x_s are Rᵀ (· − p_sup) with the rotation it writes."""
    from walkrepro.papers.lee2021.kernels import ow_frame

    rng = np.random.default_rng(5)
    for _ in range(5):
        p_sup, p_sw, com, vcom = rng.normal(size=(4, 3))
        rot = np.full((3, 3), np.nan)
        yaw, com_w, vcom_w, x_s = ow_frame(p_sup, p_sw, com, vcom, rot)
        np.testing.assert_allclose(rot.T @ rot, np.eye(3), atol=1e-15)
        assert np.linalg.det(rot) > 0 and rot[2, 2] == 1.0
        assert (np.cos(yaw), np.sin(yaw)) == (rot[0, 0], rot[1, 0])
        np.testing.assert_allclose(com_w, rot.T @ (com - p_sup), atol=1e-12)
        np.testing.assert_allclose(vcom_w, rot.T @ vcom, atol=1e-12)
        np.testing.assert_allclose([x_s, 0.0], (rot.T @ (p_sw - p_sup))[:2], atol=1e-12)


def test_signals_follow_the_kernel_layout() -> None:
    """Each logged signal reads the field of the record the tick wrote it into by name."""
    from walkrepro.papers.lee2021.kernels import SIGNALS

    robot = load_robot("dyros_red")
    ctrl = EfsmController()
    ctrl.reset(robot, EfsmParams(), 0.0005)
    signals = ctrl.step(0.0, ctrl._home_snapshot()).signals
    assert list(signals) == [name for name, _, _ in SIGNALS]
    record = ctrl._signal_record[0]
    for name, _, integer in SIGNALS:
        want = record[name].tolist()
        got = signals[name]
        if integer:
            assert isinstance(got, int) and got == want, name
        else:
            assert got == want, name
    assert signals["tau_ref"] == ctrl._tau.tolist()
    assert signals["steps_done"] == 0 and signals["efsm_phase"] == int(Phase.DS)


def test_first_ds_weight_shift_holds_double_support_for_its_time() -> None:
    """EfsmParams.first_ds_shift: the first DS lasts at least the shift's ticks (the lab's
    1.0 s start-up), its x_p^des between the two sole centres; without the shift the same
    standing robot leaves the first DS by Eq. 4 after ≈ 0.1 m / Δx_p^des ticks."""
    robot = load_robot("dyros_red")
    home = EfsmController()
    home.reset(robot, EfsmParams(), 0.0005)
    snapshot = home._home_snapshot()
    for shift, ticks, still_ds in ((0.1, 200, True), (0.0, 200, False)):
        ctrl = EfsmController()
        ctrl.reset(robot, EfsmParams(first_ds_shift=shift), 0.0005)
        assert ctrl._params.shift_ticks == round(shift / 0.0005)
        for k in range(ticks):
            ctrl.step(k * 0.0005, snapshot)
            if still_ds:
                assert ctrl._st["phase"] == int(Phase.DS)
                assert ctrl._st["steps_done"] == 0
                assert 0.0 <= ctrl._st["xp_des"] <= 0.21
        assert bool(ctrl._st["steps_done"] == 0) == still_ds


class _NoUpperBodyTask(EfsmController):
    """Paper I's controller without task 3 (the upper body's roll and pitch)."""

    TASKS = tuple(t for t in EfsmController.TASKS if t.name != "upper_body_roll_pitch")


def test_controller_without_the_upper_body_task_builds_and_runs() -> None:
    """Removing a task from the hierarchy is one edit: the controller resets and ticks, with
    finite torques that differ from those of the full hierarchy."""
    robot = load_robot("dyros_red")
    torques = []
    for cls in (EfsmController, _NoUpperBodyTask):
        ctrl = cls()
        ctrl.reset(robot, EfsmParams(), 0.0005)
        # The upper body rolling and pitching: task 3 has a force to make.
        home = dataclasses.replace(ctrl._home_snapshot(), base_angvel=np.array([0.1, -0.2, 0]))
        ctrl._st["phase"] = Phase.SSD
        torques.append([ctrl.step(k * 0.0005, home).ctrl for k in range(5)])
    assert np.all(np.isfinite(torques[1]))
    assert not np.allclose(torques[0], torques[1])
