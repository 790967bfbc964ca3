"""The contact-consistent OS-WBC of Lee et al. 2021 (Appendix A) against Pinocchio dynamics."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from oracles import efsm_wbc as wbc

from walkrepro.robot import load_robot

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def _setup(feet: tuple[str, ...]):
    """Home posture at rest: contact dynamics plus a KKT forward-dynamics solver."""
    robot = load_robot("dyros_red")
    model, data = robot.pin_model, robot.pin_model.createData()
    q, v = robot.pin_state_from_mujoco(robot.home_qpos, np.zeros(robot.mj_model.nv))
    pin.computeAllTerms(model, data, q, v)
    pin.updateFramePlacements(model, data)
    jc = np.vstack([pin.getFrameJacobian(model, data, robot.pin_frame_id(f), LWA) for f in feet])
    a = np.triu(data.M) + np.triu(data.M, 1).T
    cd = wbc.contact_dynamics(np.linalg.inv(a), data.nle.copy(), jc, np.zeros(jc.shape[0]))

    def qdd(tau: np.ndarray) -> np.ndarray:
        """Forward dynamics with rigid contacts: A q̈ + b + g = SᵀΓ + J_cᵀλ, J_c q̈ = 0."""
        n, c = a.shape[0], jc.shape[0]
        kkt = np.block([[a, jc.T], [jc, np.zeros((c, c))]])
        rhs = np.concatenate([np.r_[np.zeros(6), tau] - data.nle, np.zeros(c)])
        return np.linalg.lstsq(kkt, rhs, rcond=None)[0][:n]

    jcom = data.Jcom.copy()
    return cd, qdd, jcom


@pytest.mark.parametrize("feet", [("left_sole",), ("left_sole", "right_sole")])
def test_gravity_compensation_holds_still(feet: tuple[str, ...]) -> None:
    """Γ_gc alone leaves the contact-constrained robot at rest (Appendix B)."""
    cd, qdd, _ = _setup(feet)
    assert np.linalg.norm(qdd(cd.gamma_gc)) < 1e-6


@pytest.mark.parametrize("feet", [("left_sole",), ("left_sole", "right_sole")])
def test_task_force_gives_task_acceleration(feet: tuple[str, ...]) -> None:
    """Γ = J̃ᵀF accelerates the task by Λ⁻¹F (Appendix A)."""
    cd, qdd, jcom = _setup(feet)
    j1 = jcom[0:1]
    task = wbc.prioritized_task(cd, wbc.task_phi(cd, j1), None)
    force = np.array([30.0])
    acc = j1 @ (qdd(cd.gamma_gc + task.torque_map @ force) - qdd(cd.gamma_gc))
    assert acc == pytest.approx(np.linalg.solve(task.lam, force), rel=1e-6)


@pytest.mark.parametrize("feet", [("left_sole",), ("left_sole", "right_sole")])
def test_lower_priority_torque_leaves_higher_task_alone(feet: tuple[str, ...]) -> None:
    """A torque projected by Ñ_1ᵀ changes no acceleration of task 1 (Eq. 11)."""
    cd, qdd, jcom = _setup(feet)
    j1 = jcom[0:1]
    n1 = wbc.null_space_t(cd, wbc.task_phi(cd, j1))
    rng = np.random.default_rng(0)
    gamma0 = rng.normal(scale=50.0, size=cd.k)
    moved = qdd(cd.gamma_gc + n1 @ gamma0) - qdd(cd.gamma_gc)
    assert np.linalg.norm(moved) > 1e-3  # the torque does move the robot ...
    assert abs((j1 @ moved)[0]) < 1e-8  # ... but not the CoM along x


def test_redistribution_changes_wrenches_not_motion() -> None:
    """Γ_c moves the DS contact wrenches without accelerating the robot (Appendix C)."""
    cd, qdd, _ = _setup(("left_sole", "right_sole"))
    f_now = cd.psi @ cd.gamma_gc + cd.f_bias
    gamma_c, f_ref = wbc.redistribution_torque(cd, f_now, slice(0, 6), 0.5)
    assert np.linalg.norm(qdd(cd.gamma_gc + gamma_c)) < 1e-6
    f_new = cd.psi @ (cd.gamma_gc + gamma_c) + cd.f_bias
    assert f_new[:6] == pytest.approx(f_ref, abs=1e-6)
    assert f_new[2] + f_new[8] == pytest.approx(f_now[2] + f_now[8], rel=1e-6)


def _random_tasks(cd: wbc.ContactDynamics, m2: int, seed: int) -> np.ndarray:
    """Φ of three stacked random tasks: 1, ``m2`` and 2 rows."""
    rng = np.random.default_rng(seed)
    return wbc.task_phi(cd, rng.normal(size=(3 + m2, cd.P.shape[0])))


@pytest.mark.parametrize("feet", [("left_sole",), ("left_sole", "right_sole")])
def test_w_pinv_is_the_pseudo_inverse(feet: tuple[str, ...]) -> None:
    """W⁺ (plain inverse with one foot, eigen-decomposition with two) is pinv(W)."""
    cd, _, _ = _setup(feet)
    ref = np.linalg.pinv(cd.W, rcond=wbc.PINV_RCOND, hermitian=True)
    scale = np.abs(ref).max()
    np.testing.assert_allclose(cd.W_pinv, ref, rtol=0, atol=1e-9 * scale)
    assert (cd.w_eigvec is None) == (len(feet) == 1)


@pytest.mark.parametrize(("feet", "m2"), [(("left_sole",), 9), (("left_sole", "right_sole"), 3)])
def test_task_hierarchy_matches_projector_form(feet: tuple[str, ...], m2: int) -> None:
    """The stacked hierarchy equals the tasks built from the projectors Ñ_1ᵀ, Ñ_12ᵀ (Eq. 11)."""
    cd, _, _ = _setup(feet)
    phi = _random_tasks(cd, m2, seed=len(feet))
    hier = wbc.task_hierarchy(cd, phi, 1, m2)
    s1, s2, s3 = slice(0, 1), slice(1, 1 + m2), slice(1 + m2, None)
    refs = (
        wbc.prioritized_task(cd, phi[s1], None),
        wbc.prioritized_task(cd, phi[s2], wbc.null_space_t(cd, phi[s1])),
        wbc.prioritized_task(cd, phi[s3], wbc.null_space_t(cd, phi[0 : 1 + m2])),
    )
    for rows, ref, lam in zip((s1, s2, s3), refs, hier.lams, strict=True):
        tm = hier.torque_map[:, rows]
        np.testing.assert_allclose(tm, ref.torque_map, rtol=0, atol=1e-8 * np.abs(tm).max())
        np.testing.assert_allclose(lam, ref.lam, rtol=1e-6, atol=1e-9 * np.abs(lam).max())


def test_well_conditioned_inverse_is_the_pseudo_inverse() -> None:
    """A well-conditioned SPD matrix gets its inverse; closed forms agree with LAPACK."""
    rng = np.random.default_rng(3)
    for n in (1, 2, 5):
        a = rng.normal(size=(n, n))
        m = a @ a.T + n * np.eye(n)
        m_inv = wbc.inv_if_well_conditioned(m)
        assert m_inv is not None
        np.testing.assert_allclose(m_inv, np.linalg.inv(m), rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("n", [1, 2, 5])
def test_ill_conditioned_inverse_is_refused(n: int) -> None:
    """Near-singular (cond ≥ 1/PINV_RCOND) or indefinite matrices fall back to the pinv."""
    m = np.eye(n)
    m[-1, -1] = 1e-10 if n > 1 else -1.0
    assert wbc.inv_if_well_conditioned(m) is None


def test_hierarchy_falls_back_when_a_task_is_singular() -> None:
    """Task 3 repeating a task-2 row (Λ_3 singular) gives the pseudo-inverse result."""
    cd, _, _ = _setup(("left_sole",))
    phi = _random_tasks(cd, 9, seed=4)
    phi[-1] = phi[3]  # fully inside task 2's space: Φ_3 Ñ_12ᵀ J̃_3ᵀ is rank one
    hier = wbc.task_hierarchy(cd, phi, 1, 9)
    ref = wbc.prioritized_task(cd, phi[10:], wbc.null_space_t(cd, phi[:10]))
    np.testing.assert_allclose(hier.lams[2], ref.lam)
    np.testing.assert_allclose(hier.torque_map[:, 10:], ref.torque_map)


def test_grasp_map_moves_moments_to_the_origin() -> None:
    """K (Eq. 10) sums forces and adds d × f to the moments, in the axes of O."""
    yaw = 0.3
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    origin = np.array([0.1, -0.2, 0.0])
    points = [np.array([0.3, 0.1, 0.05]), np.array([-0.1, 0.2, 0.0])]
    rng = np.random.default_rng(5)
    wrenches = rng.normal(size=12)
    force, moment = np.zeros(3), np.zeros(3)
    for p, w in zip(points, wrenches.reshape(2, 6), strict=True):
        force += w[:3]
        moment += w[3:] + np.cross(p - origin, w[:3])
    expected = np.r_[rot.T @ force, rot.T @ moment]
    np.testing.assert_allclose(wbc.grasp_map(rot, origin, points) @ wrenches, expected)


def test_redistribution_onset_blends_toward_the_leaving_foot() -> None:
    """With ε_onset = 0 the leaving foot's reference is the whole resultant about its centre."""
    cd, _, _ = _setup(("left_sole", "right_sole"))
    f_now = cd.psi @ cd.gamma_gc + cd.f_bias
    lever = np.array([0.02, 0.2, 0.001])  # leaving minus landing sole centre [m]
    _, f_ref = wbc.redistribution_torque(cd, f_now, slice(0, 6), 1.0, 0.0, lever)
    f_land = f_now[6:]
    whole = f_now[:6] + np.r_[f_land[:3], f_land[3:] + np.cross(-lever, f_land[:3])]
    np.testing.assert_allclose(f_ref, whole, rtol=1e-12, atol=1e-9)
