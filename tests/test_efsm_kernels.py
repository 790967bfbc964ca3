"""The compiled OS-WBC kernels of the E-FSM controller against the numpy reference
(tests/oracles/efsm_wbc.py)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest
from oracles import efsm_wbc as wbc
from oracles.efsm_fsm import (
    EventFsm,
    FsmInput,
    FsmParams,
    Phase,
    capture_point,
    epsilon,
)

from walkrepro.papers.lee2021 import kernels
from walkrepro.papers.lee2021.controller import EfsmController, EfsmParams
from walkrepro.robot import load_robot

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
FEET = ("left_sole", "right_sole")


def _close(actual: np.ndarray, expected: np.ndarray, rel: float = 1e-9) -> None:
    """Equal up to rounding, relative to the largest entry."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    assert actual.shape == expected.shape
    scale = max(float(np.abs(expected).max(initial=0.0)), 1e-300)
    np.testing.assert_allclose(actual, expected, rtol=0, atol=rel * scale)


def _robot_state(seed: int) -> dict[str, np.ndarray]:
    """Dynamics of dyros_red near its home posture, moving (random joint offsets, velocities)."""
    robot, model, data, v = _moving_dyros(seed, joint_scale=0.03, velocity_scale=0.3)
    ids = [robot.pin_frame_id(f) for f in FEET]
    a = np.triu(data.M) + np.triu(data.M, 1).T
    support = [np.any(pin.getFrameJacobian(model, data, i, LWA) != 0.0, axis=0) for i in ids]
    return {
        "j_world": data.J.copy(),
        "support": support,
        "pelvis_rot": data.oMi[1].rotation.copy(),
        "a_inv": np.linalg.inv(a),
        "nle": data.nle.copy(),
        "jc": np.vstack([pin.getFrameJacobian(model, data, i, LWA) for i in ids]),
        "jc_dot_v": np.concatenate(
            [pin.getFrameClassicalAcceleration(model, data, i, LWA).vector for i in ids]
        ),
        "j_com": data.Jcom.copy(),
        "j_pelvis": pin.getJointJacobian(model, data, 1, LWA),
        "v": v,
        "sole_pos": np.array([data.oMf[i].translation for i in ids]),
        "sole_rot": np.array([data.oMf[i].rotation for i in ids]),
    }


@pytest.mark.parametrize("n_feet", [1, 2])
def test_contact_dynamics_matches_reference(n_feet: int) -> None:
    """P, W⁺, Ψ, f_bias and Γ_gc of the kernel equal wbc.contact_dynamics (Appendix A)."""
    s = _robot_state(n_feet)
    rows = slice(0, 6 * n_feet)
    ref = wbc.contact_dynamics(s["a_inv"], s["nle"], s["jc"][rows], s["jc_dot_v"][rows])
    P, W_pinv, psi, f_bias, gamma_gc, eigvec, from_eigh = kernels.contact_dynamics(
        s["a_inv"], s["nle"], s["jc"][rows], s["jc_dot_v"][rows]
    )
    for got, want in ((P, ref.P), (W_pinv, ref.W_pinv), (psi, ref.psi)):
        _close(got, want)
    _close(f_bias, ref.f_bias)
    _close(gamma_gc, ref.gamma_gc)
    assert from_eigh == (ref.w_eigvec is not None)
    if from_eigh:  # the same null space (eigenvectors are unique up to a basis change)
        v2, v2_ref = eigvec[:, :6], ref.w_eigvec[:, :6]
        _close(v2 @ v2.T, v2_ref @ v2_ref.T)


@pytest.mark.parametrize("seed", range(5))
def test_small_algebra_matches_numpy(seed: int) -> None:
    """The loop products, LU solve and inverse equal numpy's on random matrices."""
    rng = np.random.default_rng(seed)
    n, m, p = rng.integers(1, 13, size=3)
    a, b, c = rng.normal(size=(n, m)), rng.normal(size=(m, p)), rng.normal(size=(p, m))
    x = rng.normal(size=m)
    _close(kernels.matmul(a, b), a @ b)
    _close(kernels.matmul(np.asfortranarray(a), b), a @ b)  # Pinocchio's layout
    _close(kernels.matmul_bt(a, c), a @ c.T)
    _close(kernels.matvec(a, x), a @ x)
    sq = rng.normal(size=(m, m)) + m * np.eye(m)
    _close(kernels.inverse(sq), np.linalg.inv(sq), rel=1e-12)
    _close(kernels.solve_vec(sq, x), np.linalg.solve(sq, x), rel=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_lstsq_matches_numpy(seed: int) -> None:
    """The QR least squares equals np.linalg.lstsq, also when a is rank-deficient (fallback)."""
    rng = np.random.default_rng(seed)
    a, b = rng.normal(size=(10, 6)), rng.normal(size=10)
    a[:, 0] *= 1e3  # badly scaled columns, as forces next to moments
    if seed == 3:
        a[:, 5] = a[:, 4]  # rank 5: the minimum-norm solution, as LAPACK's
    want = np.linalg.lstsq(a, b, rcond=None)[0]
    _close(kernels.lstsq(a, b), want, rel=1e-10)


@pytest.mark.parametrize("n", [1, 2, 3, 10])
def test_inv_if_well_conditioned_matches_reference(n: int) -> None:
    """The kernel accepts and refuses the same matrices as the reference, same inverse."""
    rng = np.random.default_rng(n)
    a = rng.normal(size=(n, n))
    spd = a @ a.T + n * np.eye(n)
    ill = np.eye(n)
    ill[-1, -1] = 1e-10 if n > 1 else -1.0
    for m in (spd, ill, np.zeros((n, n))):
        ref = wbc.inv_if_well_conditioned(m)
        ok, m_inv = kernels.inv_if_well_conditioned(m)
        assert ok == (ref is not None)
        if ok:
            _close(m_inv, ref, rel=1e-12)


@pytest.mark.parametrize(("n_feet", "m2"), [(1, 9), (2, 3)])
@pytest.mark.parametrize("singular_task3", [False, True])
def test_task_hierarchy_matches_reference(n_feet: int, m2: int, singular_task3: bool) -> None:
    """Torque map and Λs equal wbc.task_hierarchy, also on its pseudo-inverse fallback."""
    s = _robot_state(10 + n_feet)
    rows = slice(0, 6 * n_feet)
    cd = wbc.contact_dynamics(s["a_inv"], s["nle"], s["jc"][rows], s["jc_dot_v"][rows])
    rng = np.random.default_rng(n_feet)
    phi = wbc.task_phi(cd, rng.normal(size=(3 + m2, cd.P.shape[0])))
    if singular_task3:
        phi[-1] = phi[1]  # task 3 repeats a task-2 row: Λ_3 is singular
    ref = wbc.task_hierarchy(cd, phi, 1, m2)
    tmap, lam1, lam2, lam3 = kernels.task_hierarchy(cd.W, cd.W_pinv, phi, 1, m2)
    _close(tmap, ref.torque_map, rel=1e-8)
    for got, want in zip((lam1, lam2, lam3), ref.lams, strict=True):
        _close(got, want, rel=1e-6)


def test_grasp_map_and_cop_match_reference() -> None:
    """K (Eq. 10) and the CoP of a wrench equal the reference."""
    rng = np.random.default_rng(4)
    yaw = 0.7
    rot = np.array(
        [[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]]
    )
    origin, points = rng.normal(size=3), rng.normal(size=(2, 3))
    _close(kernels.grasp_map(rot, origin, points), wbc.grasp_map(rot, origin, list(points)))
    _close(kernels.grasp_map(rot, origin, points[:1]), wbc.grasp_map(rot, origin, [points[0]]))
    wrench = rng.normal(size=6)
    assert kernels.cop_of(wrench) == pytest.approx(wbc.cop_of(wrench), rel=1e-15)
    wrench[2] = 0.0
    assert all(math.isnan(c) for c in kernels.cop_of(wrench))


@pytest.mark.parametrize(("eps", "eps_onset"), [(1.0, 1.0), (0.4, 1.0), (0.7, 0.3)])
def test_redistribution_matches_reference(eps: float, eps_onset: float) -> None:
    """Γ_c and the leaving foot's reference wrench equal wbc.redistribution_torque (App. C)."""
    s = _robot_state(20)
    cd = wbc.contact_dynamics(s["a_inv"], s["nle"], s["jc"], s["jc_dot_v"])
    rng = np.random.default_rng(5)
    f_now = cd.psi @ (cd.gamma_gc + rng.normal(scale=20.0, size=cd.k)) + cd.f_bias
    lever = s["sole_pos"][0] - s["sole_pos"][1]
    ref = wbc.redistribution_torque(cd, f_now, slice(0, 6), eps, eps_onset, lever)
    got = kernels.redistribution_torque(cd.psi, cd.w_eigvec, f_now, eps, eps_onset, lever)
    _close(got[0], ref[0], rel=1e-8)
    _close(got[1], ref[1], rel=1e-9)


def _task2_force_reference(
    lam: np.ndarray, acc: np.ndarray, scale: float, f_max: float, m_max: float
) -> np.ndarray:
    """F_2 with F_s saturated (decoupled) and scaled: the numpy version the kernel replaced."""
    f_free = lam @ acc
    fs = f_free[3:9].copy()
    fs[:3] = np.clip(fs[:3], -f_max, f_max)
    cut = fs[:3] - f_free[3:6]
    if cut.any():
        fs[3:] += lam[6:9, 3:6] @ np.linalg.solve(lam[3:6, 3:6], cut)
    fs[:3] = np.clip(fs[:3], -f_max, f_max)
    fs[3:] = np.clip(fs[3:], -m_max, m_max)
    fs *= scale
    f2 = f_free.copy()
    cut = fs - f_free[3:9]
    if cut.any():
        f2[:3] += lam[0:3, 3:9] @ np.linalg.solve(lam[3:9, 3:9], cut)
    f2[3:] = fs
    return f2


@pytest.mark.parametrize("seed", range(4))
def test_task2_force_matches_reference(seed: int) -> None:
    """The saturated, ε-scaled task-2 force equals its numpy reference (Eq. 6, §IV-C)."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(9, 9))
    lam = a @ a.T + 9.0 * np.eye(9)
    acc = rng.normal(scale=10.0, size=9)  # large enough to saturate some rows
    scale = (1.0, 0.5, 0.0, 1.0)[seed]
    got = kernels.task2_force(lam, acc, False, scale, 30.0, 10.0, True)
    _close(got, _task2_force_reference(lam, acc, scale, 30.0, 10.0), rel=1e-12)
    _close(
        kernels.task2_force(lam[:3, :3].copy(), acc[:3], True, 1.0, 1.0, 1.0, True),
        lam[:3, :3] @ acc[:3],
    )


def test_balance_force_restores_cop_to_the_polygon() -> None:
    """An expected CoP outside the shrunk sole gets F_3 that puts it on the edge (Eq. 29)."""
    rng = np.random.default_rng(6)
    kpsi3 = rng.normal(size=(6, 2))
    kpsi3[2] = 0.0  # task 3 (upper-body roll/pitch) changes no vertical force here
    f3 = rng.normal(size=2)
    rot = sole_rot = np.eye(3)
    half_sole, margin = np.array([0.1, 0.05]), 0.01
    inside = np.array([0.0, 0.0, 500.0, 0.0, 0.0, 0.0])  # CoP at the centre
    args = (rot, sole_rot, half_sole, margin, math.nan)
    assert not kernels.balance_force(inside, kpsi3, f3, *args)[0]
    outside = inside.copy()
    outside[4] = -0.2 * 500.0  # CoP x = 0.2 m, beyond 0.1 − 0.01
    acting, f3_new = kernels.balance_force(outside, kpsi3, f3, *args)
    assert acting
    fc_new = outside + kpsi3 @ (f3_new - f3)
    cop = kernels.cop_of(fc_new)
    assert cop[0] == pytest.approx(0.09, abs=1e-9)
    assert cop[1] == pytest.approx(0.0, abs=1e-9)


def _tick_reference(
    s: dict, phase: Phase, rot: np.ndarray, task_ref: np.ndarray, rot_des: np.ndarray
) -> tuple[np.ndarray, float]:
    """Γ of one tick composed from the numpy reference (Eqs. 6, 7, 11, 20–21, App. C), as the
    controller computed it before the fused kernel; no balancing (the CoP is inside)."""
    kp, kv, f_max, m_max = 100.0, 20.0, 30.0, 10.0
    double = phase is Phase.DS
    rows = slice(0, 12 if double else 6)
    cd = wbc.contact_dynamics(s["a_inv"], s["nle"], s["jc"][rows], s["jc_dot_v"][rows])
    j_ub, j_sw, v = s["j_pelvis"][3:], s["jc"][6:12], s["v"]
    w_pelvis = j_ub @ v
    e_ub = pin.log3(rot_des[0] @ s["pelvis_rot"].T)
    blocks = [rot.T @ s["j_com"], j_ub[2:3]] + ([] if double else [j_sw]) + [rot.T[:2] @ j_ub]
    acc2 = [
        kp * task_ref[0] - kv * task_ref[2],
        kp * task_ref[1] - kv * task_ref[3],
        kp * e_ub[2] - kv * w_pelvis[2],
    ]
    if not double:
        e_sw = pin.log3(rot_des[1] @ s["sole_rot"][1].T)
        err_sw = np.r_[task_ref[4:7] - s["sole_pos"][1], e_sw]
        acc2 += list(kp * err_sw - kv * (j_sw @ v))
    acc3 = rot.T[:2] @ (kp * e_ub - kv * w_pelvis)
    m2 = len(acc2)
    hier = wbc.task_hierarchy(cd, wbc.task_phi(cd, np.vstack(blocks)), 1, m2)
    lam2, lam3 = hier.lams[1], hier.lams[2]
    scale = 0.6 if phase is Phase.SSA else 1.0  # ε = 0.6
    acc2 = np.array(acc2)
    f2 = lam2 @ acc2 if double else _task2_force_reference(lam2, acc2, scale, f_max, m_max)
    f_all = np.r_[0.0, f2, lam3 @ acc3]
    p_sup, p_sw = s["sole_pos"]
    kmap = wbc.grasp_map(rot, p_sup, [p_sup, p_sw] if double else [p_sup])
    kt = kmap @ cd.psi @ hier.torque_map
    fc23, fcb = kt[:, 1:] @ f_all[1:], kmap @ (cd.psi @ cd.gamma_gc + cd.f_bias)
    f_all[0] = wbc.com_force_for_cop(0.02, kt[4, 0], fc23[2] + fcb[2], fcb[4])  # x_p^des
    gamma = hier.torque_map @ f_all + cd.gamma_gc
    if double:
        f_now = cd.psi @ gamma + cd.f_bias
        gamma += wbc.redistribution_torque(cd, f_now, slice(0, 6), 0.6, 0.5, p_sup - p_sw)[0]
    return gamma, f_all[0]


def _yaw(angle: float) -> np.ndarray:
    """Rotation about z [rad]."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize("phase", list(Phase))
def test_whole_tick_matches_reference_composition(phase: Phase) -> None:
    """The fused kernel's Γ equals the tick composed from the numpy reference, each phase."""
    s = _robot_state(30 + int(phase))
    rng = np.random.default_rng(int(phase))
    rot = _yaw(0.2)
    task_ref = rng.normal(scale=0.02, size=7)
    task_ref[4:7] += s["sole_pos"][1]  # a swing target near the swing sole
    rot_des = np.array([_yaw(0.05), _yaw(-0.03)])
    want, f1_want = _tick_reference(s, phase, rot, task_ref, rot_des)
    k = want.size
    tau = np.empty(k)
    actuator_rows = np.arange(k)[::-1].copy()  # a reordering, to check it too
    params = np.array([100.0, 20.0, 30.0, 10.0, 1.0, 0.0, 0.03, 1e9, 0.1, 0.05])  # no clip
    c = 12 if phase is Phase.DS else 6
    f1, balancing, _, _ = kernels.whole_body_torques(
        kernels.WbcDynamics(
            s["a_inv"], s["nle"], s["jc_dot_v"][:c].copy(), s["j_world"], s["j_com"], s["v"]
        ),
        kernels.WbcFrames(
            rot, s["sole_pos"][0], s["sole_pos"][1], s["sole_rot"][0], s["sole_rot"][1],
            s["pelvis_rot"], s["support"][0], s["support"][1],
        ),
        kernels.WbcTargets(rot_des, task_ref, int(phase), 0.6, 0.5, 0.02, 0.3),
        params,
        actuator_rows,
        tau,
    )  # fmt: skip
    assert not balancing
    assert f1 == pytest.approx(f1_want, rel=1e-8)
    _close(tau, want[actuator_rows], rel=1e-8)


def test_frame_jacobian_matches_pinocchio() -> None:
    """The sole Jacobians built from data.J equal pinocchio.getFrameJacobian (LWA)."""
    s = _robot_state(40)
    for i in range(2):
        out = np.empty((6, s["v"].size))
        kernels.frame_jacobian(s["j_world"], s["support"][i], s["sole_pos"][i], out)
        _close(out, s["jc"][6 * i : 6 * i + 6], rel=1e-14)


def test_warm_up_compiles_what_a_tick_uses() -> None:
    """After reset, ticks in and out of DS compile nothing more (the first tick is not slow)."""
    robot = load_robot("dyros_red")
    ctrl = EfsmController()
    ctrl.reset(robot, EfsmParams(), 0.0005)
    compiled = len(kernels.tick.signatures)
    home = ctrl._home_snapshot()
    ctrl.step(0.0, home)
    ctrl._st["phase"] = int(Phase.SSD)
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
    ``joint_scale`` [rad], ``velocity_scale``); computeAllTerms and the frames updated.
    Returns robot, Pinocchio model and data, and the velocity v."""
    robot = load_robot("dyros_red")
    model, data = robot.pin_model, robot.pin_model.createData()
    rng = np.random.default_rng(seed)
    qpos = robot.home_qpos.copy()
    qpos[7:] += rng.normal(scale=joint_scale, size=qpos.size - 7)
    q, v = robot.pin_state_from_mujoco(
        qpos, rng.normal(scale=velocity_scale, size=robot.mj_model.nv)
    )
    pin.computeAllTerms(model, data, q, v)
    pin.updateFramePlacements(model, data)
    return robot, model, data, v


@pytest.mark.parametrize("seed", range(3))
def test_mass_matrix_inverse_is_pinocchios(seed: int) -> None:
    """A⁻¹ agrees with Pinocchio's cholesky.decompose + computeMinv to 1e-12."""
    _, model, data, _ = _moving_dyros(seed)
    tree = np.array([list(data.parents_fromRow), list(data.nvSubtree_fromRow)], dtype=np.int64)
    out = np.empty((model.nv, model.nv))
    kernels.mass_matrix_inverse(data.M, tree, out)
    pin.cholesky.decompose(model, data)
    np.testing.assert_allclose(out, pin.cholesky.computeMinv(model, data), rtol=1e-12, atol=1e-12)
    _close(out @ (np.triu(data.M) + np.triu(data.M, 1).T), np.eye(model.nv), rel=1e-9)


@pytest.mark.parametrize("seed", range(3))
def test_frames_match_pinocchio(seed: int) -> None:
    """The sole and F/T placements agree with Pinocchio's updateFramePlacements. Their J̇ q̇ comes from robot.frame_classical_acceleration,
    tested against Pinocchio in test_qpimpedance_tasks.py."""
    robot, model, data, _ = _moving_dyros(seed)
    for name in ("left_sole", "right_sole", "left_foot_ft", "right_foot_ft"):
        frame = model.frames[robot.pin_frame_id(name)]
        joint = frame.parentJoint
        rot, pos = np.empty((3, 3)), np.empty(3)
        kernels.frame_placement(
            data.oMi[joint].rotation,
            data.oMi[joint].translation,
            frame.placement.rotation,
            frame.placement.translation,
            rot,
            pos,
        )
        want = data.oMf[robot.pin_frame_id(name)]
        _close(rot, want.rotation, rel=1e-15)
        _close(pos, want.translation, rel=1e-15)


def test_matmul_skips_zeros_without_changing_a_bit() -> None:
    """a @ b with a's zero entries skipped equals the full left-to-right sums exactly."""
    rng = np.random.default_rng(9)
    a, b = rng.normal(size=(4, 7)), rng.normal(size=(7, 5))
    a[rng.random(a.shape) < 0.4] = 0.0
    a[0, 0] = -0.0
    want = [[0.0] * 5 for _ in range(4)]
    for i in range(4):
        for j in range(5):
            for k in range(7):
                want[i][j] += float(a[i, k]) * float(b[k, j])
    assert kernels.matmul(a, b).tolist() == want


def test_fsm_step_matches_event_fsm() -> None:
    """The compiled E-FSM step equals fsm.EventFsm.step tick by tick, through every state."""
    params = FsmParams(use_epsilon=True)
    kernel_params = kernels.FsmParams(
        params.zeta, params.r, params.dxp, params.d_thr, params.v_stop, params.use_epsilon
    )
    fsm = EventFsm(params, Phase.SSD, 0.0)
    phase, xp_des = int(Phase.SSD), 0.0
    rng = np.random.default_rng(11)
    x_m, xd_m = 0.05, -0.2
    seen = set()
    for _ in range(3000):  # a CoM that decelerates, turns, and runs to the swing foot
        xd_m += rng.normal(scale=0.01) + (0.002 if fsm.phase is not Phase.DS else 0.0)
        x_m += 0.0005 * xd_m
        x_s = 0.28 + rng.normal(scale=0.001)
        x_cp = capture_point(x_m, xd_m, 0.6)
        want = fsm.step(FsmInput(x_m, xd_m, x_cp, x_s))
        phase, xp_des, eps, d, bits = kernels.fsm_step(
            phase, xp_des, kernels.FsmInput(x_m, xd_m, x_cp, x_s), kernel_params
        )
        assert (phase, xp_des, eps, d) == (int(want.phase), want.xp_des, want.epsilon, want.d)
        codes = {
            (Phase.SSD, Phase.SSA): kernels.SSD_TO_SSA,
            (Phase.SSA, Phase.DS): kernels.SSA_TO_DS,
            (Phase.DS, Phase.SSD): kernels.DS_TO_SSD,
        }
        assert bits == sum(codes[tr] for tr in want.transitions)
        seen.update(want.transitions)
        if want.switched_support:
            x_m, xd_m = x_m - x_s, -0.1  # the new O_w, and a fresh step
            fsm.reframe(0.0)
            xp_des = 0.0
    assert len(seen) == 3


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


SIDES = ("left", "right")


def _reference_tick(ctrl: EfsmController, sensors, state: np.ndarray) -> tuple:
    """One tick composed of the references, as the controller computed it before its tick was
    one kernel: Pinocchio's frames, J̇ q̇ and A⁻¹, fsm.EventFsm, the footstep planner's numpy
    formula, whole_body_torques and measured_cop. Returns Γ, the signal values in the order
    of kernels.SIGNALS, and the transitions."""
    st, p, model, data = state[0], ctrl._p, ctrl._model, ctrl._data
    q, v = sensors.pinocchio_state(ctrl._robot)
    pin.computeAllTerms(model, data, q, v)
    pin.updateFramePlacements(model, data)
    soles = [data.oMf[ctrl._sole[f]] for f in SIDES]
    fsm = EventFsm(
        FsmParams(p.zeta, p.r, p.dxp, p.d_thr, p.v_stop, p.use_epsilon),
        Phase(int(st["phase"])),
        float(st["xp_des"]),
    )
    sup = int(st["support"])
    sw = 1 - sup
    com, vcom, rot, z_m0 = data.com[0], data.vcom[0], st["rot"].copy(), float(st["z_m0"])
    ow = kernels.ow_frame(soles[sup].translation, soles[sw].translation, com, vcom, rot)
    x_cp = capture_point(ow[2][0], ow[3][0], z_m0)
    out = fsm.step(FsmInput(ow[2][0], ow[3][0], x_cp, ow[4]))
    xp_des, target, steps = out.xp_des, st["swing_target"].copy(), int(st["steps_done"])
    if out.switched_support:
        sup, sw, steps = sw, sup, steps + 1
        length = p.step_length if p.n_steps is None or steps <= p.n_steps else 0.0
        side = 1.0 if sw == 0 else -1.0
        target = soles[sup].translation + st["heading"] * length
        target = target + side * float(st["width"]) * st["lateral"]
        ow = kernels.ow_frame(soles[sup].translation, soles[sw].translation, com, vcom, rot)
        x_cp = capture_point(ow[2][0], ow[3][0], z_m0)
        xp_des = 0.0
    (c, s, com_w, vcom_w, x_s), double = ow, out.phase is Phase.DS
    p_sup, p_sw = soles[sup].translation, soles[sw].translation
    h = p.raise_height if out.phase is Phase.SSD else p.land_height
    sw_ref = [target[0], target[1], p_sup[2] + h]
    task_ref = np.array([0.0 - com_w[1], z_m0 - com_w[2], vcom_w[1], vcom_w[2], *sw_ref])
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
    f1, balancing, cop_x, cop_y = kernels.whole_body_torques(
        kernels.WbcDynamics(
            pin.cholesky.computeMinv(model, data), data.nle, jc_dot_v, data.J, data.Jcom, v
        ),
        kernels.WbcFrames(
            rot, p_sup, p_sw, soles[sup].rotation, soles[sw].rotation, data.oMi[1].rotation,
            st["sole_support"][sup], st["sole_support"][sw],
        ),
        kernels.WbcTargets(
            st["rot_des"], task_ref, int(out.phase), out.epsilon, eps_on, xp_des, x_s
        ),
        st["params"],
        st["actuator_rows"],
        tau,
    )  # fmt: skip
    meas = ctrl._measured_cop(sensors)
    valid = all(math.isfinite(x) for x in meas)
    signals = [
        0.0 if double else (1.0 if sup == 0 else -1.0), int(out.phase), out.epsilon, eps_on,
        out.d if math.isfinite(out.d) else 1.0, *com_w, *vcom_w, *com, *vcom, x_cp, x_s - p.r,
        x_s, xp_des, p_sup[0] + c * xp_des, p_sup[1] + s * xp_des, cop_x, cop_y,
        p_sup[0] + (c * cop_x - s * cop_y), p_sup[1] + (s * cop_x + c * cop_y),
        *(meas if valid else (0.0, 0.0)), valid, *p_sw, *sw_ref,
        0.0 if double else (1.0 if sw == 1 else -1.0), *p_sup, math.atan2(s, c), f1, balancing,
        steps,
    ]  # fmt: skip
    return tau, np.array(signals, dtype=float), [tr for tr in out.transitions]


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
        x_s = kernels.ow_frame(p_sup, p_sw, ctrl._data.com[0], ctrl._data.vcom[0], np.eye(3))[4]
        st["xp_des"], st["ds_start_xp"] = x_s - 0.5 * ctrl._p.dxp, x_s - 0.05
    state = ctrl._state.copy()
    tau_want, signals_want, transitions = _reference_tick(ctrl, sensors, state)
    cmd = ctrl.step(0.0005, sensors)
    assert [(e["from"], e["to"]) for e in cmd.events if e["kind"] == "fsm"] == [
        (a.name, b.name) for a, b in transitions
    ]
    assert (case == "DS_ends") == any(e["kind"] == "support" for e in cmd.events)
    _close(cmd.ctrl, tau_want, rel=1e-9)
    _close(ctrl._signals, signals_want, rel=1e-9)
