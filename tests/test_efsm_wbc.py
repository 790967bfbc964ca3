"""The contact-consistent OS-WBC of Lee et al. 2021 (Appendix A) against Pinocchio dynamics."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from walkrepro.controllers.efsm import wbc
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
