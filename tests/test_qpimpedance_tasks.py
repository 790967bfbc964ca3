"""Tests of the compiled per-tick task algebra of the qpimpedance controller (tasks.py).

Each kernel is checked for its properties (the swing trajectory) or compared with a reference
on random inputs: Pinocchio's frame Jacobians and plain numpy algebra (the impedance filter's
own properties are tests/test_qpimpedance_impedance.py's).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from walkrepro.controllers import controller_class
from walkrepro.log.signals import Signals
from walkrepro.papers.jo_oh import tasks
from walkrepro.papers.jo_oh.centroidal_qp import solve_centroidal
from walkrepro.papers.jo_oh.controller import LEG_JOINTS, SIGNAL_LAYOUT
from walkrepro.sim.robot import frame_classical_acceleration, load_robot, pin_state_into

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def test_quintic_is_a_minimum_jerk_blend() -> None:
    """b(s) = u³(10 − 15u + 6u²) rises from 0 to 1 with zero rate and acceleration at both ends,
    its ḃ and b̈ are its derivatives, it is clipped outside [0, T], and a non-positive duration
    gives (1, 0, 0)."""
    duration, h = 0.6, 1e-6
    assert tasks.quintic(0.0, duration) == (0.0, 0.0, 0.0)
    np.testing.assert_allclose(tasks.quintic(duration, duration), (1.0, 0.0, 0.0), atol=1e-12)
    assert tasks.quintic(-0.2, duration) == (0.0, 0.0, 0.0)
    np.testing.assert_allclose(tasks.quintic(duration + 0.2, duration), (1.0, 0.0, 0.0))
    assert tasks.quintic(0.3, 0.0) == (1.0, 0.0, 0.0)
    np.testing.assert_allclose(tasks.quintic(duration / 2, duration)[0], 0.5, rtol=1e-14)
    for s in np.linspace(0.05, 0.55, 11):
        b, db, ddb = tasks.quintic(s, duration)
        u = s / duration
        np.testing.assert_allclose(b, u**3 * (10 - 15 * u + 6 * u**2), rtol=1e-14)
        up, down = tasks.quintic(s + h, duration), tasks.quintic(s - h, duration)
        np.testing.assert_allclose(db, (up[0] - down[0]) / (2 * h), rtol=1e-6)
        np.testing.assert_allclose(ddb, (up[1] - down[1]) / (2 * h), rtol=1e-5, atol=1e-6)


def _swing(packed: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    pos, vel, acc = np.empty(5), np.empty(5), np.empty(5)
    tasks.swing_reference(packed, t, pos, vel, acc)
    return pos, vel, acc


def test_swing_reference_lifts_off_clears_the_apex_and_lands() -> None:
    """The swing reference starts at lift-off and ends at the landing at rest, reaches the apex
    above the higher of the two at the rise fraction, and its rates and accelerations are
    the time derivatives of its positions, over random swings."""
    rng = np.random.default_rng(1)
    packed, h = np.zeros(1, dtype=tasks.SWING_PLAN), 1e-6
    for _ in range(30):
        t0, duration = rng.uniform(0, 3), rng.uniform(0.3, 0.8)
        start, target = rng.normal(0, 0.1, 5), rng.normal(0, 0.1, 5)
        apex, rise = rng.uniform(0.02, 0.15), rng.uniform(0.2, 0.8)
        tasks.pack_swing(t0, duration, start, target, apex, rise, packed)
        for t, where in ((t0, start), (t0 + duration, target), (t0 - 0.1, start)):
            pos, vel, acc = _swing(packed, t)
            np.testing.assert_allclose(pos, where, atol=1e-12)
            np.testing.assert_allclose(np.r_[vel, acc], 0.0, atol=1e-9)
        pos, vel, _ = _swing(packed, t0 + rise * duration)
        np.testing.assert_allclose(pos[2], max(start[2], target[2]) + apex, atol=1e-12)
        assert abs(vel[2]) < 1e-9
        for t in t0 + rng.uniform(0.01, duration - 0.01, 5):
            if abs(t - t0 - rise * duration) < 2 * h:
                continue  # z's two blends meet there
            (p_up, v_up, _), (p_down, v_down, _) = _swing(packed, t + h), _swing(packed, t - h)
            _, vel, acc = _swing(packed, t)
            np.testing.assert_allclose(vel, (p_up - p_down) / (2 * h), rtol=1e-5, atol=1e-6)
            np.testing.assert_allclose(acc, (v_up - v_down) / (2 * h), rtol=1e-4, atol=1e-4)


def _random_state(seed: int, data: pin.Data | None = None):  # noqa: ANN202
    """kist_humanoid's Pinocchio model and data (a new one, or ``data``) after computeAllTerms
    at a random state near home."""
    robot = load_robot("kist_humanoid")
    model = robot.pin_model
    data = model.createData() if data is None else data
    rng = np.random.default_rng(seed)
    q, _ = robot.pin_state_from_mujoco(robot.home_qpos, np.zeros(robot.mj_model.nv))
    q = pin.integrate(model, q, 0.2 * rng.standard_normal(model.nv))
    v = rng.standard_normal(model.nv)
    pin.computeAllTerms(model, data, q, v)
    pin.updateFramePlacements(model, data)
    return robot, model, data, q, v


def _random_rotations(rng: np.random.Generator) -> list[np.ndarray]:
    """Rotations of every size: identity, tiny (log₃'s series), small, large, near π."""
    rotations = [np.eye(3), pin.exp3(np.array([0.0, 0.0, np.pi]))]
    for scale in (1e-9, 1e-6, 1e-4, 1e-2, 0.3, 1.5):
        rotations += [pin.exp3(rng.normal(0, scale, 3)) for _ in range(200)]
    for _ in range(200):  # within 1e-3 rad of a half turn
        axis = rng.normal(size=3)
        rotations.append(pin.exp3((np.pi - abs(rng.normal(0, 1e-3))) * axis / np.linalg.norm(axis)))
    return rotations


def test_matrix_to_rpy_agrees_with_pinocchio() -> None:
    """The compiled roll–pitch–yaw agrees with pin.rpy.matrixToRpy to 1e-12, any yaw sign."""
    out = np.empty(3)
    rng = np.random.default_rng(11)
    rotations = _random_rotations(rng)
    rotations += [pin.rpy.rpyToMatrix(*rng.uniform(-3, 3, 3)) for _ in range(500)]
    rotations.append(pin.rpy.rpyToMatrix(0.1, np.pi / 2, -0.2))  # gimbal lock
    for rotation in rotations:
        tasks.matrix_to_rpy(np.asfortranarray(rotation), out)  # Data's matrices are column-major
        np.testing.assert_allclose(out, pin.rpy.matrixToRpy(rotation), rtol=0, atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_frame_drift_agrees_with_pinocchio(seed: int) -> None:
    """The shared kernel's frame drift from data.v, data.a (robot.frame_classical_acceleration,
    which task_rows inlines) agrees with getFrameClassicalAcceleration to 1e-12 on
    kist_humanoid."""
    robot, model, data, _, _ = _random_state(20 + seed)
    out = np.empty(6)
    for name in ("left_sole", "right_sole", "pelvis", "torso", "left_foot_ft"):
        frame = model.frames[robot.pin_frame_id(name)]
        joint = frame.parentJoint
        frame_classical_acceleration(
            data.oMi[joint].rotation,
            data.v[joint].vector,
            data.a[joint].vector,
            frame.placement.translation,
            out,
        )
        want = pin.getFrameClassicalAcceleration(model, data, robot.pin_frame_id(name), LWA)
        np.testing.assert_allclose(out, want.vector, rtol=1e-12, atol=1e-12)


def test_frame_jacobian_equals_pinocchio() -> None:
    """The kernel's frame Jacobian from data.J equals getFrameJacobian (LOCAL_WORLD_ALIGNED)."""
    robot, model, data, _, _ = _random_state(3)
    out = np.empty((6, model.nv))
    for name in ("left_sole", "right_sole", "pelvis", "torso", "left_foot_ft"):
        fid = robot.pin_frame_id(name)
        chain = tasks.kinematic_chain(model, fid)
        tasks.frame_jacobian(data.J, chain, data.oMf[fid].translation, out)
        np.testing.assert_allclose(out, pin.getFrameJacobian(model, data, fid, LWA), atol=1e-14)


def test_contact_wrench_equals_numpy() -> None:
    """The kernel's contact wrench equals the Newton–Euler expression written with numpy."""
    rng = np.random.default_rng(4)
    for _ in range(20):
        ft, acc = rng.normal(0, 50, 6), rng.normal(0, 3, 3)
        rot = pin.exp3(rng.normal(0, 0.3, 3))
        site, com, sole = rng.normal(0, 0.1, (3, 3))
        mass = 1.4
        got = tasks.contact_wrench(ft, rot, site, com, sole, acc, mass)
        gravity = np.array([0.0, 0.0, -tasks.GRAVITY])
        force = rot @ ft[:3] - mass * gravity + mass * acc
        moment = rot @ ft[3:] - np.cross(com - site, mass * (gravity - acc))
        moment += np.cross(site - sole, force)  # moved to the sole centre
        np.testing.assert_allclose(got, (force[2], moment[0], moment[1]), rtol=1e-12, atol=1e-12)


def test_desired_com_equals_numpy_interp() -> None:
    """The CoM pattern is np.interp of its samples, and rests at the last sample after the plan."""
    rng = np.random.default_rng(5)
    columns = rng.standard_normal((50, 6))  # x, ẋ, ẍ, y, ẏ, ÿ
    plan = np.zeros(50, dtype=tasks.COM_SAMPLE)
    for order, name in enumerate(("position", "velocity", "acceleration")):
        plan[name] = columns[:, [order, 3 + order]]
    dt, end, z = 0.005, 0.2, 0.8
    pos, vel, acc = np.empty(3), np.empty(3), np.empty(3)
    times = dt * np.arange(50)
    for t in rng.uniform(0, end, 30):
        tasks.desired_com(plan, t, dt, end, z, pos, vel, acc)
        want = [np.interp(t, times, columns[:, j]) for j in range(6)]
        np.testing.assert_allclose(pos, (want[0], want[3], z), rtol=1e-12)
        np.testing.assert_allclose(vel, (want[1], want[4], 0.0), rtol=1e-12)
        np.testing.assert_allclose(acc, (want[2], want[5], 0.0), rtol=1e-12)
    tasks.desired_com(plan, end, dt, end, z, pos, vel, acc)
    want_end = [columns[-1, 0], columns[-1, 3], z] + [0.0] * 6
    np.testing.assert_array_equal(np.r_[pos, vel, acc], want_end)


def _impedance_rows(impedance: np.ndarray) -> np.ndarray:
    """Each foot's (x_m, ẋ_m, ẍ_m) of the impedance records, shape (2, 3, 3)."""
    return np.stack(
        [impedance["position"], impedance["velocity"], impedance["acceleration"]], axis=1
    )


def _task_block(ctrl, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # noqa: ANN001
    """A declared task's rows (Φ_t, b_t, W_t) in the controller's stack, by the task's name."""
    names = [spec.name for spec in ctrl.tasks(ctrl._p, ctrl._robot)]
    stack = ctrl._tasks.stack
    first = stack.first_row[names.index(name)]
    later = [row for row in stack.first_row if row > first]
    last = min(later) if later else stack.rows[0]
    return stack.jacobian[first:last], stack.target[first:last], stack.weight[first:last]


def test_task_rows_equal_numpy_reference() -> None:
    """A swing tick's QP tasks (b_1; Φ_t, b_t of each task), contact stacks and signals equal the §III-D algebra written with numpy and Pinocchio."""
    robot = load_robot("kist_humanoid")
    cls = controller_class("qpimpedance")
    ctrl = cls()
    p = cls.Params()
    ctrl.reset(robot, p, 0.001)
    swing_index = next(i for i, ph in enumerate(ctrl._plan.phases) if ph.swing >= 0)
    phase = ctrl._plan.phases[swing_index]
    _, model, data, _, v = _random_state(7, ctrl._data)  # the tick reads views of this Data
    ctrl._v[:] = v
    ctrl._enter_phase(swing_index)
    rng = np.random.default_rng(8)
    state = ctrl._state
    impedance = state.impedance
    for name in ("position", "velocity", "acceleration"):
        impedance[name] = rng.normal(0, 0.1, (2, 3))
    impedance["armed"] = impedance["active"] = True  # Eq. (2) integrates this tick
    state.foot_acc_cmd[:] = rng.normal(0, 1, (2, 3))
    state.stance_z[:] = rng.normal(0, 0.05, 2)  # planned heights (0 on flat ground)
    prev_vel = state.prev_foot_vel[:] = rng.normal(0, 1, (2, 6))
    imp_before = _impedance_rows(impedance)
    acc_before = state.foot_acc_cmd.copy()
    joint_pos, joint_vel = rng.normal(0, 0.3, (2, robot.n_joints))
    fts = rng.normal(0, 50, (2, 6))
    t = phase.t0 + 0.3 * (phase.t1 - phase.t0)
    swing = phase.swing
    ctrl._task_rows(t, swing, joint_pos, joint_vel, *fts)

    qp_tasks = ctrl._tasks
    # Momentum target: b_1 = X_GBᵀ ḣ_{G,r} − C_B ξ̇ (Eq. 7).
    m = robot.total_mass
    c_d, v_d, a_d = np.empty(3), np.empty(3), np.empty(3)
    tasks.desired_com(
        ctrl._params.com_plan,
        t,
        p.preview_dt,
        ctrl._plan.end,
        ctrl._params.tick.com_z,
        c_d,
        v_d,
        a_d,
    )
    h_lin = m * (a_d + p.k_h * (v_d - data.vcom[0]) + p.k_i * (c_d - data.com[0]))
    h_ang = -p.k_h_angular * data.hg.angular + np.cross(
        data.com[0] - data.oMi[1].translation, h_lin
    )
    base_rot = data.oMi[1].rotation
    b1 = np.r_[base_rot.T @ h_lin, base_rot.T @ h_ang] - (data.nle[:6] - data.g[:6])
    np.testing.assert_allclose(qp_tasks.momentum_target, b1, rtol=1e-11, atol=1e-9)
    np.testing.assert_array_equal(qp_tasks.momentum_weight, 1.0)  # W_1 = I by default
    # Pelvis and torso: Φ_t the angular Jacobian, b_t = −K_P log R − K_V ω − Φ̇_t ξ̇.
    for frame, task, w in (
        ("pelvis", _task_block(ctrl, "pelvis"), p.w_pelvis),
        ("torso", _task_block(ctrl, "torso"), p.w_torso),
    ):
        task_jacobian, task_target, task_weight = task
        fid = robot.pin_frame_id(frame)
        jac = pin.getFrameJacobian(model, data, fid, LWA)[3:]
        drift = pin.getFrameClassicalAcceleration(model, data, fid, LWA).angular
        acc = -p.kp_orient * pin.log3(data.oMf[fid].rotation) - p.kv_orient * jac @ v
        np.testing.assert_allclose(task_jacobian, jac, rtol=1e-14, atol=1e-14)
        np.testing.assert_allclose(task_target, acc - drift, rtol=1e-11, atol=1e-9)
        np.testing.assert_array_equal(task_weight, w)
    # Posture: Φ_t selects each arm and waist joint, b_t = K_P (q_home − q) − K_V q̇.
    idx = [i for i, name in enumerate(robot.joint_names) if not name.startswith(LEG_JOINTS)]
    home = robot.home_joint_pos[idx]
    posture = p.kp_posture * (home - joint_pos[idx]) - p.kv_posture * joint_vel[idx]
    posture_jacobian, posture_target, _ = _task_block(ctrl, "posture")
    np.testing.assert_allclose(posture_target, posture, rtol=1e-14)
    np.testing.assert_array_equal(posture_jacobian, np.eye(model.nv)[robot.pin_v_idx[idx]])

    signals = dict(Signals(SIGNAL_LAYOUT, ctrl._signal_record.view(np.float64)))
    pos_d, vel_d, acc_d = _swing(state.swing_plan, t)  # tested above for its properties
    for side, name in enumerate(("left", "right")):
        fid = robot.pin_frame_id(f"{name}_sole")
        sole = data.oMf[fid]
        jac = pin.getFrameJacobian(model, data, fid, LWA)
        drift = pin.getFrameClassicalAcceleration(model, data, fid, LWA).vector
        np.testing.assert_allclose(ctrl._sole_jacobians[side], jac, atol=1e-14)
        np.testing.assert_allclose(ctrl._sole_drifts[side], drift, rtol=1e-12, atol=1e-12)
        local = ctrl._params.local_wrench_map
        np.testing.assert_allclose(
            ctrl._wrench_maps[side],
            np.r_[sole.rotation @ local[:3], sole.rotation @ local[3:]],
            atol=1e-14,
        )
        vel = jac @ v
        np.testing.assert_allclose(state.prev_foot_vel[side], vel, rtol=1e-12, atol=1e-12)
        site = data.oMf[robot.pin_frame_id(f"{name}_foot_ft")]
        foot = data.oMf[robot.pin_frame_id(f"{name}_foot")]
        foot_com = foot.act(
            model.inertias[model.frames[robot.pin_frame_id(f"{name}_foot")].parentJoint].lever
        )
        wrench = tasks.contact_wrench(
            fts[side],
            site.rotation,
            site.translation,
            foot_com,
            sole.translation,
            acc_before[side],
            ctrl._params.tick.foot_mass,
        )
        rpy = pin.rpy.matrixToRpy(sole.rotation)
        acc_meas = (vel - prev_vel[side]) / 0.001
        want = (
            *wrench,
            sole.translation[0],
            sole.translation[2],
            rpy[0],
            rpy[1],
            *vel[2:5],
            *acc_meas[2:5],
        )
        got = [signals[f"{name}_{s}"] for s in tasks.FOOT_SIGNALS.names[:13]]
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)
        refs = [
            signals[f"{name}_{axis}{kind}"]
            for kind in tasks.REFERENCE_KINDS
            for axis in tasks.IMPEDANCE_AXES
        ]
        if side != swing:
            z = state.stance_z[side]
            assert refs == [z, 0, 0] + [0] * 6 + [z, 0, 0] + [0] * 6
            assert signals[f"{name}_impedance_on"] == 0.0
            np.testing.assert_array_equal(state.foot_acc_cmd[side], 0.0)
            np.testing.assert_allclose(impedance[side]["position"], (sole.translation[2], *rpy[:2]))
            continue
        # Swing: Eq. (2) advanced from the previous state (semi-implicit Euler), then Eq. (3)
        # on all six axes.
        x_prev, v_prev, _ = imp_before[side]
        error, error_rate = pos_d[2:5] - x_prev, vel_d[2:5] - v_prev
        m_d, b_d, k_d = np.array(p.m_d), np.array(p.b_d), np.array(p.k_d)
        a_m = acc_d[2:5] + (np.array(wrench) + b_d * error_rate + k_d * error) / m_d
        v_m = v_prev + a_m * 0.001
        x_m = x_prev + v_m * 0.001
        np.testing.assert_allclose(
            _impedance_rows(impedance)[side], [x_m, v_m, a_m], rtol=1e-12, atol=1e-12
        )
        assert signals[f"{name}_impedance_on"] == 1.0
        want_refs = np.r_[pos_d[2:5], vel_d[2:5], acc_d[2:5], x_m, v_m, a_m]
        np.testing.assert_allclose(refs, want_refs, rtol=1e-12, atol=1e-12)
        x_now = np.array([sole.translation[2], rpy[0], rpy[1]])
        kp, kv = p.swing_gains
        acc_ref = np.r_[
            acc_d[:2] + kv * (vel_d[:2] - vel[:2]) + kp * (pos_d[:2] - sole.translation[:2]),
            a_m + kv * (v_m - vel[2:5]) + kp * (x_m - x_now),
            -kv * vel[5] - kp * rpy[2],
        ]
        swing_jacobian, swing_target, _ = _task_block(ctrl, "swing_foot")
        np.testing.assert_allclose(swing_jacobian, jac, atol=1e-14)
        np.testing.assert_allclose(swing_target, acc_ref - drift, rtol=1e-10, atol=1e-8)
        np.testing.assert_allclose(state.foot_acc_cmd[side], acc_ref[:3], rtol=1e-12, atol=1e-10)


def test_reset_compiles_the_tick_kernels_for_a_real_tick(kist_home_snapshot) -> None:  # noqa: ANN001
    """A tick after reset finds its kernels compiled for its argument types (no compile on tick 1)."""
    robot = load_robot("kist_humanoid")
    cls = controller_class("qpimpedance")
    ctrl = cls()
    ctrl.reset(robot, cls.Params(), 0.001)
    kernels = (tasks.task_rows, pin_state_into, solve_centroidal)
    compiled = [len(k.signatures) for k in kernels]
    snapshot = kist_home_snapshot()
    ctrl.step(0.0, snapshot)
    assert [len(k.signatures) for k in kernels] == compiled


def test_readings_of_any_layout_give_the_same_rows() -> None:
    """A strided reading (numba's dispatcher compiles task_rows for its type) gives the rows and
    signals of contiguous readings."""
    robot = load_robot("kist_humanoid")
    cls = controller_class("qpimpedance")
    rng = np.random.default_rng(3)
    joint_pos, joint_vel = rng.normal(0, 0.3, (2, robot.n_joints))
    fts = rng.normal(0, 50, (2, 6))
    outputs = []
    for strided in (False, True):
        ctrl = cls()
        ctrl.reset(robot, cls.Params(), 0.001)
        pos = np.repeat(joint_pos, 2)[::2] if strided else joint_pos
        assert pos.flags.c_contiguous != strided and np.array_equal(pos, joint_pos)
        ctrl._task_rows(0.0, -1, pos, joint_vel, *fts)
        qp_tasks = ctrl._tasks
        targets = np.r_[qp_tasks.momentum_target, qp_tasks.stack.target[: qp_tasks.stack.rows[0]]]
        outputs.append((targets, ctrl._signal_record.view(np.float64).copy()))
    for contiguous, strided_out in zip(*outputs, strict=True):
        np.testing.assert_array_equal(strided_out, contiguous)


def _fixed_swing_tick(cls: type, robot) -> object:  # noqa: ANN001
    """A controller after one task_rows call on the fixed random state of
    tests/data/jo_oh_task_rows.npz (state 7, swing phase, seeds 8)."""
    ctrl = cls()
    ctrl.reset(robot, cls.Params(), 0.001)
    swing_index = next(i for i, ph in enumerate(ctrl._plan.phases) if ph.swing >= 0)
    phase = ctrl._plan.phases[swing_index]
    _, _, _, _, v = _random_state(7, ctrl._data)
    ctrl._v[:] = v
    ctrl._enter_phase(swing_index)
    rng = np.random.default_rng(8)
    state = ctrl._state
    for name in ("position", "velocity", "acceleration"):
        state.impedance[name] = rng.normal(0, 0.1, (2, 3))
    state.impedance["armed"] = state.impedance["active"] = True
    state.foot_acc_cmd[:] = rng.normal(0, 1, (2, 3))
    state.stance_z[:] = rng.normal(0, 0.05, 2)
    state.prev_foot_vel[:] = rng.normal(0, 1, (2, 6))
    joint_pos, joint_vel = rng.normal(0, 0.3, (2, robot.n_joints))
    fts = rng.normal(0, 50, (2, 6))
    t = phase.t0 + 0.3 * (phase.t1 - phase.t0)
    ctrl._task_rows(t, phase.swing, joint_pos, joint_vel, *fts)
    return ctrl


def test_stacked_rows_equal_the_hand_written_rows_of_before() -> None:
    """The declared tasks, stacked, give the rows, b_1, signals and QP matrices that the
    hand-written task_rows gave on the same state (tests/data/jo_oh_task_rows.npz, written by
    the code before the task list), to 1e-12."""
    old = np.load(Path(__file__).parent / "data" / "jo_oh_task_rows.npz")
    robot = load_robot("kist_humanoid")
    ctrl = _fixed_swing_tick(controller_class("qpimpedance"), robot)
    stack = ctrl._tasks.stack
    rows = stack.rows[0]
    assert rows == old["target"].size  # pelvis 3, torso 3, posture 10, swing 6
    np.testing.assert_allclose(stack.jacobian[:rows], old["jacobian"], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(stack.target[:rows], old["target"], rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(stack.weight[:rows], old["weight"])
    np.testing.assert_allclose(ctrl._tasks.momentum_target, old["momentum_target"], rtol=1e-12)
    signals = ctrl._signal_record.view(np.float64)
    np.testing.assert_allclose(signals, old["signals"], rtol=1e-12, atol=1e-12)
    problem = ctrl._qps[(1 - int(old["swing"]),)].build()
    for name in ("P", "q", "A", "b"):
        np.testing.assert_allclose(getattr(problem, name), old[name], rtol=1e-12, atol=1e-12)


def test_a_task_added_to_the_list_is_stacked_and_the_controller_walks(
    kist_home_snapshot,  # noqa: ANN001
) -> None:
    """One more task (the head held upright) is one entry in the task list: its rows appear
    after the others', the paper's rows are unchanged, and the controller runs ticks."""
    base = controller_class("qpimpedance")

    class WithHead(base):
        def tasks(self, params, robot):  # noqa: ANN001, ANN202
            head = tasks.TaskSpec(
                "head", tasks.TaskKind.ORIENTATION, "head", ("rx", "ry"), 50.0, 14.0, 5.0,
                "not the paper's: a test of the task list",
            )  # fmt: skip
            return (*super().tasks(params, robot), head)

    robot = load_robot("kist_humanoid")
    plain, extended = _fixed_swing_tick(base, robot), _fixed_swing_tick(WithHead, robot)
    before, after = plain._tasks.stack, extended._tasks.stack
    n = before.rows[0]
    assert after.rows[0] == n + 2 and after.first_row[-1] == n
    np.testing.assert_array_equal(after.jacobian[:n], before.jacobian[:n])
    np.testing.assert_array_equal(after.target[:n], before.target[:n])
    head = extended._model.getFrameId("head")
    jac = pin.getFrameJacobian(extended._model, extended._data, head, LWA)
    np.testing.assert_allclose(after.jacobian[n : n + 2], jac[3:5], atol=1e-14)
    np.testing.assert_array_equal(after.weight[n : n + 2], 5.0)
    ctrl = WithHead()
    ctrl.reset(robot, WithHead.Params(), 0.001)
    for k in range(5):
        command = ctrl.step(0.001 * k, kist_home_snapshot())
        assert np.all(np.isfinite(command.ctrl))
    assert ctrl._tasks.stack.rows[0] == n - 6 + 2  # double support: no swing rows


def test_a_task_on_an_unknown_frame_or_axis_names_the_valid_ones() -> None:
    """task_table rejects an unknown frame, a linear axis on an orientation and an unknown
    joint, naming what is valid."""
    joints = ("a", "b")
    bad_frame = tasks.TaskSpec("t", tasks.TaskKind.ORIENTATION, "nose", ("rx",), 1, 1, 1, "")
    with pytest.raises(ValueError, match="unknown frame 'nose'"):
        tasks.task_table((bad_frame,), ("pelvis",), joints)
    linear = tasks.TaskSpec("t", tasks.TaskKind.ORIENTATION, "pelvis", ("x",), 1, 1, 1, "")
    with pytest.raises(ValueError, match="not among"):
        tasks.task_table((linear,), ("pelvis",), joints)
    posture = tasks.TaskSpec("t", tasks.TaskKind.POSTURE, ("c",), (), 1, 1, 1, "")
    with pytest.raises(ValueError, match="unknown joints"):
        tasks.task_table((posture,), ("pelvis",), joints)
