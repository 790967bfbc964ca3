"""The contact-consistent OS-WBC of Lee et al. 2021 (Appendices A–D, ``lee2021/wbc.py``)
against Pinocchio's constrained dynamics and numpy's linear algebra."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from walkrepro.papers.lee2021 import wbc
from walkrepro.papers.lee2021.fsm import Phase
from walkrepro.papers.lee2021.tasks import HIERARCHY, TaskSpec, task_rows, task_set
from walkrepro.sim.robot import load_robot

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
ONE_FOOT, TWO_FEET = ("left_sole",), ("left_sole", "right_sole")


class Setup:
    """dyros_red at its home posture (moving if ``seed`` is given) with ``feet`` in contact:
    the package's contact dynamics and Pinocchio's constrained forward dynamics."""

    def __init__(self, feet: tuple[str, ...], seed: int | None = None) -> None:
        self.robot = robot = load_robot("dyros_red")
        self.model, self.data = model, data = robot.pin_model, robot.pin_model.createData()
        qpos, qvel = robot.home_qpos.copy(), np.zeros(robot.mj_model.nv)
        if seed is not None:
            rng = np.random.default_rng(seed)
            qpos[7:] += rng.normal(scale=0.03, size=qpos.size - 7)
            qvel = rng.normal(scale=0.3, size=qvel.size)
        self.q, self.v = q, v = robot.pin_state_from_mujoco(qpos, qvel)
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        ids = [robot.pin_frame_id(f) for f in feet]
        self.jc = np.vstack([pin.getFrameJacobian(model, data, i, LWA) for i in ids])
        self.jc_dot_v = np.concatenate(
            [pin.getFrameClassicalAcceleration(model, data, i, LWA).vector for i in ids]
        )
        self.sole_pos = np.array([data.oMf[i].translation for i in ids])
        self.sole_rot = np.array([data.oMf[i].rotation for i in ids])
        self.a = np.triu(data.M) + np.triu(data.M, 1).T
        self.nle, self.j_world, self.j_com = data.nle.copy(), data.J.copy(), data.Jcom.copy()
        self.pelvis_rot = data.oMi[1].rotation.copy()
        self.cd = wbc.contact_dynamics(np.linalg.inv(self.a), self.nle, self.jc, self.jc_dot_v)
        self.k = self.cd.W.shape[0]

    def qdd(self, tau: np.ndarray) -> np.ndarray:
        """q̈ of joint torques ``tau`` with rigid contacts (J_c q̈ + J̇_c q̇ = 0), Pinocchio's
        ``forwardDynamics``."""
        tau_full = np.r_[np.zeros(6), tau]
        return pin.forwardDynamics(
            self.model, self.model.createData(), self.q, self.v, tau_full, self.jc, self.jc_dot_v
        ).copy()

    def contact_wrench(self, tau: np.ndarray) -> np.ndarray:
        """The wrenches the feet apply to the ground (Pinocchio's −λ), stacked per foot."""
        data = self.model.createData()
        tau_full = np.r_[np.zeros(6), tau]
        pin.forwardDynamics(self.model, data, self.q, self.v, tau_full, self.jc, self.jc_dot_v)
        return -data.lambda_c.copy()


@pytest.mark.parametrize("feet", [ONE_FOOT, TWO_FEET])
def test_p_is_pinocchios_constrained_inverse_inertia(feet: tuple[str, ...]) -> None:
    """P = A⁻¹(I − J_cᵀ J̄_cᵀ) is the upper-left block of Pinocchio's inverse KKT matrix."""
    s = Setup(feet, seed=1)
    kkt_inv = pin.computeKKTContactDynamicMatrixInverse(s.model, s.model.createData(), s.q, s.jc)
    n = s.a.shape[0]
    p = s.cd.P
    np.testing.assert_allclose(p, kkt_inv[:n, :n], rtol=0, atol=1e-9 * np.abs(p).max())
    np.testing.assert_allclose(s.cd.W, p[6:, 6:])


@pytest.mark.parametrize("feet", [ONE_FOOT, TWO_FEET])
def test_contact_wrench_map_is_pinocchios(feet: tuple[str, ...]) -> None:
    """f_c = Ψ Γ + f_bias (Eq. 8) is the contact wrench of Pinocchio's forward dynamics."""
    s = Setup(feet, seed=2)
    tau = np.random.default_rng(2).normal(scale=20.0, size=s.k)
    want = s.contact_wrench(tau)
    got = s.cd.psi @ tau + s.cd.f_bias
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-8 * np.abs(want).max())


@pytest.mark.parametrize("feet", [ONE_FOOT, TWO_FEET])
def test_gravity_compensation_holds_still(feet: tuple[str, ...]) -> None:
    """Γ_gc alone leaves the joints unaccelerated (Appendix B): at rest, and moving on one
    foot (moving on two feet, the closed chain's drift J̇_c q̇ needs joint accelerations)."""
    for seed in (None, 3) if len(feet) == 1 else (None,):
        s = Setup(feet, seed)
        assert np.linalg.norm(s.qdd(s.cd.gamma_gc)[6:]) < 1e-6


@pytest.mark.parametrize("feet", [ONE_FOOT, TWO_FEET])
def test_task_force_gives_task_acceleration(feet: tuple[str, ...]) -> None:
    """Γ = J̃ᵀF accelerates the task by Λ⁻¹F (Appendix A)."""
    s = Setup(feet)
    j1 = s.j_com[0:1]
    task = wbc.prioritized_task(s.cd, wbc.task_phi(s.cd, j1), np.eye(s.k))
    force = np.array([30.0])
    acc = j1 @ (s.qdd(s.cd.gamma_gc + task.torque_map @ force) - s.qdd(s.cd.gamma_gc))
    assert acc == pytest.approx(np.linalg.solve(task.lam, force), rel=1e-6)


@pytest.mark.parametrize("feet", [ONE_FOOT, TWO_FEET])
def test_lower_priority_torque_leaves_higher_task_alone(feet: tuple[str, ...]) -> None:
    """A torque projected by Ñ_1ᵀ changes no acceleration of task 1 (Eq. 11)."""
    s = Setup(feet)
    j1 = s.j_com[0:1]
    n1 = wbc.null_space_t(s.cd, wbc.task_phi(s.cd, j1))
    gamma0 = np.random.default_rng(0).normal(scale=50.0, size=s.k)
    moved = s.qdd(s.cd.gamma_gc + n1 @ gamma0) - s.qdd(s.cd.gamma_gc)
    assert np.linalg.norm(moved) > 1e-3  # the torque does move the robot ...
    assert abs((j1 @ moved)[0]) < 1e-8  # ... but not the CoM along x


@pytest.mark.parametrize("feet", [ONE_FOOT, TWO_FEET])
def test_null_space_projector_properties(feet: tuple[str, ...]) -> None:
    """Ñᵀ is idempotent, Φ Ñᵀ = 0 and Ñᵀ J̃ᵀ = 0 (Appendix A), for a 3-row task."""
    s = Setup(feet, seed=4)
    phi = wbc.task_phi(s.cd, s.j_com)
    n_t = wbc.null_space_t(s.cd, phi)
    jt = s.cd.W_pinv @ phi.T
    scale = np.abs(phi).max()
    np.testing.assert_allclose(n_t @ n_t, n_t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(phi @ n_t, 0.0, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(n_t @ jt, 0.0, rtol=0, atol=1e-9 * np.abs(jt).max())


def test_redistribution_changes_wrenches_not_motion() -> None:
    """Γ_c moves the DS contact wrenches without accelerating the robot (Appendix C)."""
    s = Setup(TWO_FEET)
    cd = s.cd
    f_now = cd.psi @ cd.gamma_gc + cd.f_bias
    lever = s.sole_pos[0] - s.sole_pos[1]
    gamma_c, f_ref = wbc.redistribution_torque(cd, f_now, 0.5, 1.0, lever)
    assert np.linalg.norm(s.qdd(cd.gamma_gc + gamma_c)) < 1e-6
    f_new = s.contact_wrench(cd.gamma_gc + gamma_c)
    assert f_new[:6] == pytest.approx(f_ref, abs=1e-6)
    assert f_new[2] + f_new[8] == pytest.approx(f_now[2] + f_now[8], rel=1e-6)


def test_redistribution_minimizes_the_tangential_wrenches() -> None:
    """With ε = 1 the leaving foot's reference is that of the distribution of least
    tangential forces and moments over both feet, numpy's lstsq over W's null space."""
    s = Setup(TWO_FEET, seed=5)
    cd = s.cd
    f_now = cd.psi @ (cd.gamma_gc + np.random.default_rng(5).normal(scale=20.0, size=s.k))
    f_now += cd.f_bias
    _, f_ref = wbc.redistribution_torque(cd, f_now, 1.0, 1.0, s.sole_pos[0] - s.sole_pos[1])
    null_w = np.linalg.svd(cd.W)[2][-6:].T  # W's null space, another basis
    g = cd.psi @ null_w
    rows = wbc.TANGENTIAL_ROWS
    alpha = np.linalg.lstsq(g[rows], -f_now[rows], rcond=None)[0]
    np.testing.assert_allclose(f_ref, (f_now + g @ alpha)[:6], rtol=0, atol=1e-6)


@pytest.mark.parametrize("feet", [ONE_FOOT, TWO_FEET])
def test_w_pinv_is_the_pseudo_inverse(feet: tuple[str, ...]) -> None:
    """W⁺ (plain inverse with one foot, eigen-decomposition with two) is pinv(W)."""
    s = Setup(feet)
    ref = np.linalg.pinv(s.cd.W, rcond=wbc.PINV_RCOND, hermitian=True)
    np.testing.assert_allclose(s.cd.W_pinv, ref, rtol=0, atol=1e-9 * np.abs(ref).max())
    assert (s.cd.w_eigvec.size == 0) == (len(feet) == 1)


def _random_tasks(cd: wbc.ContactDynamics, m2: int, seed: int) -> np.ndarray:
    """Φ of three stacked random tasks: 1, ``m2`` and 2 rows."""
    rng = np.random.default_rng(seed)
    return wbc.task_phi(cd, rng.normal(size=(3 + m2, cd.P.shape[0])))


def _three_levels(cd: wbc.ContactDynamics, phi: np.ndarray, m2: int) -> wbc.Hierarchy:
    """The hierarchy of ``phi`` stacked as three levels: 1, ``m2`` and the rest."""
    m = phi.shape[0]
    return wbc.task_hierarchy(cd, phi, np.array([0, 1, 1 + m2]), np.array([1, 1 + m2, m]))


@pytest.mark.parametrize(("feet", "m2"), [(ONE_FOOT, 9), (TWO_FEET, 3)])
def test_task_hierarchy_matches_projector_form(feet: tuple[str, ...], m2: int) -> None:
    """The stacked hierarchy equals the tasks built from the projectors Ñ_1ᵀ, Ñ_12ᵀ (Eq. 11)."""
    s = Setup(feet)
    cd = s.cd
    phi = _random_tasks(cd, m2, seed=len(feet))
    hier = _three_levels(cd, phi, m2)
    s1, s2, s3 = slice(0, 1), slice(1, 1 + m2), slice(1 + m2, None)
    refs = (
        wbc.prioritized_task(cd, phi[s1], np.eye(s.k)),
        wbc.prioritized_task(cd, phi[s2], wbc.null_space_t(cd, phi[s1])),
        wbc.prioritized_task(cd, phi[s3], wbc.null_space_t(cd, phi[0 : 1 + m2])),
    )
    lams = (hier.lam[s1, s1], hier.lam[s2, s2], hier.lam[s3, s3])
    for rows, ref, lam in zip((s1, s2, s3), refs, lams, strict=True):
        tm = hier.torque_map[:, rows]
        np.testing.assert_allclose(tm, ref.torque_map, rtol=0, atol=1e-8 * np.abs(tm).max())
        np.testing.assert_allclose(lam, ref.lam, rtol=1e-6, atol=1e-9 * np.abs(lam).max())


@pytest.mark.parametrize(("feet", "m2"), [(ONE_FOOT, 9), (TWO_FEET, 3)])
def test_each_task_is_achieved_in_the_null_space_of_the_higher(
    feet: tuple[str, ...], m2: int
) -> None:
    """Task i's torque J̃_iᵀ F_i gives Λ_i⁻¹ F_i on task i and nothing on the tasks above."""
    s = Setup(feet)
    phi = _random_tasks(s.cd, m2, seed=7)
    hier = _three_levels(s.cd, phi, m2)
    rows = (slice(0, 1), slice(1, 1 + m2), slice(1 + m2, None))
    rng = np.random.default_rng(7)
    for rows_i in rows:
        lam = hier.lam[rows_i, rows_i]
        force = rng.normal(size=lam.shape[0])
        acc = phi @ (hier.torque_map[:, rows_i] @ force)  # Φ J̃ᵀ F: every task's acceleration
        np.testing.assert_allclose(acc[rows_i], np.linalg.solve(lam, force), rtol=1e-6, atol=1e-9)
        above = acc[: rows_i.start]
        assert np.abs(above).max(initial=0.0) < 1e-8 * np.abs(acc).max()


@pytest.mark.parametrize("n", [1, 2, 5])
def test_well_conditioned_inverse_is_the_pseudo_inverse(n: int) -> None:
    """A well-conditioned SPD matrix gets its inverse."""
    a = np.random.default_rng(3).normal(size=(n, n))
    m = a @ a.T + n * np.eye(n)
    ok, m_inv = wbc.inv_if_well_conditioned(m)
    assert ok
    np.testing.assert_allclose(m_inv, np.linalg.pinv(m), rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("n", [1, 2, 5])
def test_ill_conditioned_inverse_is_refused(n: int) -> None:
    """Near-singular (cond ≥ 1/PINV_RCOND), indefinite or singular matrices are refused."""
    m = np.eye(n)
    m[-1, -1] = 1e-10 if n > 1 else -1.0
    assert not wbc.inv_if_well_conditioned(m)[0]
    assert not wbc.inv_if_well_conditioned(np.zeros((n, n)))[0]


def test_hierarchy_falls_back_when_a_task_is_singular() -> None:
    """Task 3 repeating a task-2 row (Λ_3 singular) gives the pseudo-inverse result."""
    s = Setup(ONE_FOOT)
    phi = _random_tasks(s.cd, 9, seed=4)
    phi[-1] = phi[3]  # fully inside task 2's space: Φ_3 Ñ_12ᵀ J̃_3ᵀ is rank one
    hier = _three_levels(s.cd, phi, 9)
    ref = wbc.prioritized_task(s.cd, phi[10:], wbc.null_space_t(s.cd, phi[:10]))
    np.testing.assert_allclose(hier.lam[10:, 10:], ref.lam)
    np.testing.assert_allclose(hier.torque_map[:, 10:], ref.torque_map)
    assert np.linalg.matrix_rank(hier.lam[10:, 10:]) == 1


def _yaw(angle: float) -> np.ndarray:
    """Rotation about z [rad]."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_grasp_map_moves_moments_to_the_origin() -> None:
    """K (Eq. 10) sums forces and adds d × f to the moments, in the axes of O."""
    rot = _yaw(0.3)
    origin = np.array([0.1, -0.2, 0.0])
    points = np.array([[0.3, 0.1, 0.05], [-0.1, 0.2, 0.0]])
    wrenches = np.random.default_rng(5).normal(size=12)
    force, moment = np.zeros(3), np.zeros(3)
    for p, w in zip(points, wrenches.reshape(2, 6), strict=True):
        force += w[:3]
        moment += w[3:] + np.cross(p - origin, w[:3])
    expected = np.r_[rot.T @ force, rot.T @ moment]
    np.testing.assert_allclose(wbc.grasp_map(rot, origin, points) @ wrenches, expected)
    np.testing.assert_allclose(
        wbc.grasp_map(rot, origin, points[:1]) @ wrenches[:6],
        np.r_[
            rot.T @ wrenches[:3],
            rot.T @ (wrenches[3:6] + np.cross(points[0] - origin, wrenches[:3])),
        ],
    )


def test_cop_of_a_wrench() -> None:
    """The CoP (Eqs. 18, 22) is where the wrench has no x/y moment; NaN when unloaded."""
    wrench = np.array([3.0, -2.0, 400.0, 8.0, -12.0, 1.0])
    x, y = wbc.cop_of(wrench)
    # The moment about (x, y, 0): m − (x, y, 0) × f has no x/y part.
    moment = wrench[3:] - np.cross([x, y, 0.0], wrench[:3])
    np.testing.assert_allclose(moment[:2], 0.0, atol=1e-12)
    wrench[2] = 0.0
    assert all(math.isnan(c) for c in wbc.cop_of(wrench))


def test_redistribution_onset_blends_toward_the_leaving_foot() -> None:
    """With ε_onset = 0 the leaving foot's reference is the whole resultant about its centre."""
    s = Setup(TWO_FEET)
    f_now = s.cd.psi @ s.cd.gamma_gc + s.cd.f_bias
    lever = np.array([0.02, 0.2, 0.001])  # leaving minus landing sole centre [m]
    _, f_ref = wbc.redistribution_torque(s.cd, f_now, 1.0, 0.0, lever)
    f_land = f_now[6:]
    whole = f_now[:6] + np.r_[f_land[:3], f_land[3:] + np.cross(-lever, f_land[:3])]
    np.testing.assert_allclose(f_ref, whole, rtol=1e-12, atol=1e-9)


def test_balance_force_restores_cop_to_the_polygon() -> None:
    """An expected CoP outside the shrunk sole gets F_3 that puts it on the edge (Eq. 29)."""
    rng = np.random.default_rng(6)
    kpsi3 = rng.normal(size=(6, 2))
    kpsi3[2] = 0.0  # task 3 (upper-body roll/pitch) changes no vertical force here
    f3 = rng.normal(size=2)
    half_sole, margin = np.array([0.1, 0.05]), 0.01
    inside = np.array([0.0, 0.0, 500.0, 0.0, 0.0, 0.0])  # CoP at the centre
    args = (np.eye(3), np.eye(3), half_sole, margin, math.nan)
    assert not wbc.balance_force(inside, kpsi3, f3, *args)[0]
    outside = inside.copy()
    outside[4] = -0.2 * 500.0  # CoP x = 0.2 m, beyond 0.1 − 0.01
    acting, f3_new = wbc.balance_force(outside, kpsi3, f3, *args)
    assert acting
    cop = wbc.cop_of(outside + kpsi3 @ (f3_new - f3))
    assert cop[0] == pytest.approx(0.09, abs=1e-9)
    assert cop[1] == pytest.approx(0.0, abs=1e-9)


def _whole_body(
    s: Setup,
    phase: Phase,
    balance: bool = False,
    tasks: tuple[TaskSpec, ...] = HIERARCHY,
) -> tuple[np.ndarray, wbc.WbcOutput]:
    """Γ (joint order, unsaturated) and the report of whole_body_torques at the state of
    ``s`` (left foot the support, O_w yawed 0.2 rad, x_p^des 2 cm; random CoM y/z errors and
    velocities in O_w and swing-foot target)."""
    rng = np.random.default_rng(int(phase))
    n = s.a.shape[0]
    chains = [
        np.any(pin.getFrameJacobian(s.model, s.data, s.robot.pin_frame_id(f), LWA) != 0.0, axis=0)
        for f in TWO_FEET
    ]
    tau = np.empty(s.k)
    p_sw = s.data.oMf[s.robot.pin_frame_id("right_sole")]
    rot_w = _yaw(0.2)
    com = s.data.com[0].copy()
    com_err_w, vcom_w = rng.normal(scale=0.02, size=2), rng.normal(scale=0.02, size=2)
    out = wbc.whole_body_torques(
        wbc.WbcDynamics(
            np.linalg.inv(s.a), s.nle, s.jc_dot_v, s.j_world, s.j_com, com,
            rot_w @ np.r_[0.0, vcom_w], s.v,
        ),
        wbc.WbcFrames(
            rot_w, s.sole_pos[0], p_sw.translation.copy(), s.sole_rot[0],
            p_sw.rotation.copy(), s.pelvis_rot, chains[0].astype(np.int64),
            chains[1].astype(np.int64),
        ),
        wbc.WbcTargets(
            _yaw(0.05), _yaw(-0.03), com + rot_w @ np.r_[0.0, com_err_w],
            p_sw.translation + rng.normal(scale=0.02, size=3), int(phase), 0.6, 0.5, 0.02, 0.3,
        ),
        wbc.WbcParams(
            task_set(tasks, 100.0, 20.0), 30.0, 10.0, wbc.UNIFORM, balance, 0.03, 1e9,
            np.array([0.15, 0.075]), np.arange(s.k),
        ),
        tau,
    )  # fmt: skip
    assert n == s.k + 6
    return tau, out


#: Γ and the report of the hand-stacked whole_body_torques (task rows by slices) before the
#: hierarchy was declared by name, at the states of _whole_body (written by that code).
BEFORE = Path(__file__).parent / "data" / "lee2021_wbc_before.json"


@pytest.mark.parametrize("phase", list(Phase))
@pytest.mark.parametrize("balance", [False, True])
def test_declared_hierarchy_gives_the_hand_stacked_torques(phase: Phase, balance: bool) -> None:
    """HIERARCHY stacked by stack_tasks gives the torques, F_1, balancing and expected CoP
    of the former hand-stacked rows (j_tasks[4:10], acc2[6:9], …) up to rounding."""
    want = json.loads(BEFORE.read_text())[f"{phase.name}_{'balance' if balance else 'plain'}"]
    s = Setup(TWO_FEET if phase is Phase.DS else ONE_FOOT, seed=8 + int(phase))
    tau, out = _whole_body(s, phase, balance)
    scale = np.abs(want["tau"]).max()
    np.testing.assert_allclose(tau, want["tau"], rtol=0, atol=1e-9 * scale)
    assert out.com_force_x == pytest.approx(want["com_force_x"], rel=1e-9)
    assert out.balancing == want["balancing"]
    assert [out.cop_exp_x, out.cop_exp_y] == pytest.approx(want["cop_exp"], rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("phase", list(Phase))
def test_a_hierarchy_without_the_upper_body_task_still_stacks(phase: Phase) -> None:
    """Removing task 3 (the upper body's roll and pitch) is one edit: the hierarchy stacks
    two levels, the balancing force (task 3's) no longer acts, and Γ changes."""
    tasks = tuple(t for t in HIERARCHY if t.name != "upper_body_roll_pitch")
    s = Setup(TWO_FEET if phase is Phase.DS else ONE_FOOT, seed=8 + int(phase))
    tau, out = _whole_body(s, phase, balance=True, tasks=tasks)
    full, _ = _whole_body(s, phase, balance=True)
    assert np.all(np.isfinite(tau)) and not out.balancing
    assert np.abs(tau - full).max() > 1e-3 * np.abs(full).max()


def test_a_task_moved_to_its_own_priority_is_one_more_level() -> None:
    """Moving the CoM height below the swing foot (priority 2.5) adds a level; the rows keep
    their names' quantities and axes, and the gains default to k_p, k_v."""
    tasks = tuple(t._replace(priority=2.5) if t.name == "com_yz" else t for t in HIERARCHY)
    rows = task_rows(tasks, 100.0, 20.0)
    assert list(rows.level) == [0, 1, 1, 1, 1, 1, 1, 1, 2, 2, 3, 3]
    assert np.all(rows.kp == 100.0) and np.all(rows.kv == 20.0)
    own = task_rows((HIERARCHY[0]._replace(kp=50.0),), 100.0, 20.0)
    assert own.kp.tolist() == [50.0]


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda t: t._replace(axes=(6,)) if t.name == "com_yz" else t, "axis 6"),
        (lambda t: t._replace(axes=(3,)) if t.name == "com_yz" else t, "no angular"),
        (lambda t: t._replace(axes=(2,)) if t.name == "com_x" else t, "CoP law"),
        (lambda t: t._replace(axes=(5,)) if t.name == "upper_body_roll_pitch" else t, "balance"),
        (lambda t: t._replace(name="com_x"), "repeat"),
    ],
)
def test_a_hierarchy_the_laws_cannot_take_is_refused(edit, message: str) -> None:
    """A task the force laws cannot take is refused with its name, at reset."""
    with pytest.raises(ValueError, match=message):
        task_rows(tuple(edit(t) for t in HIERARCHY), 100.0, 20.0)


@pytest.mark.parametrize("phase", list(Phase))
def test_expected_cop_is_that_of_pinocchios_contact_wrenches(phase: Phase) -> None:
    """The expected CoP the WBC reports (Eqs. 8, 10, 18, 22) is the CoP, in O_w, of the
    contact wrenches Pinocchio's constrained dynamics gives for its Γ."""
    s = Setup(TWO_FEET if phase is Phase.DS else ONE_FOOT, seed=8 + int(phase))
    tau, out = _whole_body(s, phase)
    wrenches = s.contact_wrench(tau)
    kmap = wbc.grasp_map(_yaw(0.2), s.sole_pos[0], s.sole_pos)
    cop = wbc.cop_of(kmap @ wrenches)
    assert (out.cop_exp_x, out.cop_exp_y) == pytest.approx(cop, abs=1e-9)


def test_double_support_torque_lands_the_leaving_foot_wrench_on_its_reference() -> None:
    """In DS, Pinocchio's contact wrench of the leaving (support) foot under Γ has the
    resultant of the redistribution's reference: ε scales the optimum (Appendix C, §IV-B)."""
    s = Setup(TWO_FEET, seed=12)
    tau, _ = _whole_body(s, Phase.DS)
    wrenches = s.contact_wrench(tau)
    f_now = s.cd.psi @ tau + s.cd.f_bias
    np.testing.assert_allclose(f_now, wrenches, rtol=0, atol=1e-7 * np.abs(wrenches).max())
    # Γ_c adds nothing more: the redistribution of Γ's own wrenches is the identity.
    lever = s.sole_pos[0] - s.sole_pos[1]
    gamma_c, f_ref = wbc.redistribution_torque(s.cd, f_now, 0.6, 0.5, lever)
    np.testing.assert_allclose(wrenches[:6], f_ref, rtol=0, atol=1e-6 * np.abs(wrenches).max())
    assert np.abs(gamma_c).max() < 1e-6 * np.abs(tau).max()
