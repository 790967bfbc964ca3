"""Tests of the centroidal-momentum QP (Jo & Oh §III): friction pyramid, equality rows, Eq. (9)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from oracles.centroidal_qp import LIBRARY_SOLVERS, solve_with_library

from walkrepro.papers.jo_oh.centroidal_qp import (
    CentroidalQP,
    Task,
    build_qp,
    contact_wrench_basis,
    friction_basis,
    joint_torques,
    rotate_wrench_basis,
)
from walkrepro.papers.jo_oh.condensed import CostRows, Dynamics, QPWeights, SupportContacts
from walkrepro.robot import load_robot

MU = 0.6


def test_pyramid_forces_lie_in_friction_cone() -> None:
    """Any U_k β with β ≥ 0 has every point force inside the Coulomb cone |f_t| ≤ μ f_n."""
    rng = np.random.default_rng(0)
    basis = friction_basis(MU, 4)
    rot = pin.rpy.rpyToMatrix(0.3, -0.2, 0.5)
    corners = np.array([[0.12, 0.065, 0], [0.12, -0.065, 0], [-0.12, 0.065, 0], [-0.12, -0.065, 0]])
    u = contact_wrench_basis(rot, corners, basis)
    assert u.shape == (6, 16)
    for _ in range(200):
        beta = rng.exponential(size=16)
        for j in range(4):
            f = rot.T @ (u[:3, 4 * j : 4 * j + 4] @ beta[4 * j : 4 * j + 4])  # contact frame
            assert np.hypot(f[0], f[1]) <= MU * f[2] + 1e-12
    # the torque rows are the moments of those forces about the sole centre
    beta = rng.exponential(size=16)
    w = u @ beta
    moment = sum(
        np.cross(rot @ corners[j], u[:3, 4 * j : 4 * j + 4] @ beta[4 * j : 4 * j + 4])
        for j in range(4)
    )
    np.testing.assert_allclose(w[3:], moment, atol=1e-12)


def _inputs(support: tuple[int, ...]) -> dict:
    """The QP inputs of a random state of kist_humanoid with the given support feet."""
    robot = load_robot("kist_humanoid")
    model = robot.pin_model
    data = model.createData()
    rng = np.random.default_rng(1)
    q, v = robot.pin_state_from_mujoco(robot.home_qpos, np.zeros(robot.mj_model.nv))
    v = 0.1 * rng.standard_normal(model.nv)
    pin.computeAllTerms(model, data, q, v)
    pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
    pin.updateFramePlacements(model, data)
    corners = np.array([[sx * 0.12, sy * 0.065, 0.0] for sx in (1, -1) for sy in (1, -1)])
    jacs, drifts, maps, rots = [], [], [], []
    for side in support:
        fid = model.getFrameId(("left_sole", "right_sole")[side])
        jacs.append(pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED))
        a = pin.getFrameClassicalAcceleration(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        drifts.append(np.concatenate([a.linear, a.angular]))
        rots.append(data.oMf[fid].rotation.copy())
        maps.append(contact_wrench_basis(rots[-1], corners, friction_basis(MU, 4)))
    return {
        "mass": data.M.copy(),
        "nle": data.nle.copy(),
        "b1": np.zeros(6) - (data.nle[:6] - data.g[:6]),
        "posture": Task("posture", np.eye(model.nv)[6:], -v[6:], np.ones(model.nv - 6)),
        "jacs": jacs,
        "drifts": drifts,
        "maps": maps,
        "rots": rots,
        "local": contact_wrench_basis(np.eye(3), corners, friction_basis(MU, 4)),
    }


def _problem(support: tuple[int, ...]):  # noqa: ANN202
    i = _inputs(support)
    problem = build_qp(
        Dynamics(i["mass"], i["nle"]),
        i["b1"],
        np.ones(6),
        SupportContacts(i["jacs"], i["drifts"], i["maps"]),
        support,
        [i["posture"]],
        QPWeights(1e-4, 1e-6),
    )
    return problem, i["mass"], i["nle"], i["jacs"], i["drifts"]


def test_problem_is_inspectable() -> None:
    """build_qp returns matrices of the documented shapes: 28 accelerations, 16 β per support foot."""
    problem, *_ = _problem((0, 1))
    assert problem.P.shape == (28 + 32, 28 + 32)
    assert problem.A.shape == (6 + 12, 60)
    assert np.all(problem.lb[28:] == 0) and np.all(np.isneginf(problem.lb[:28]))
    np.testing.assert_allclose(problem.P, problem.P.T)


@pytest.mark.parametrize("solver", ("active_set", *LIBRARY_SOLVERS))
def test_solution_satisfies_floating_base_dynamics(solver: str) -> None:
    """The QP solution satisfies the floating-base rows of Eq. (5) and the contact constraints,
    solved by the package's active set and by the library solvers (the oracles)."""
    problem, mass, nle, jacs, drifts = _problem((0, 1))
    if solver == "active_set":
        x = problem.solve()
    else:
        opts = {
            "proxqp": {"eps_abs": 1e-10, "eps_rel": 0.0},
            "osqp": {"eps_abs": 1e-10, "eps_rel": 1e-10, "polishing": True, "max_iter": 100000},
        }[solver]
        x = solve_with_library(problem, solver, **opts)
    assert x is not None
    accel, wrenches = problem.split(x)
    base = (
        mass[:6] @ accel
        + nle[:6]
        - sum(j[:, :6].T @ w for j, w in zip(jacs, wrenches, strict=True))
    )
    tol = 1e-6 if solver == "osqp" else 1e-8
    assert np.max(np.abs(base)) < tol * max(1.0, np.max(np.abs(nle[:6])))
    for jac, drift in zip(jacs, drifts, strict=True):
        assert np.max(np.abs(jac @ accel + drift)) < tol * 10
    assert np.all(x[problem.nv :] >= -1e-9)
    # the feet carry the weight (≈ 559 N)
    assert abs(sum(w[2] for w in wrenches) - 57.0 * 9.81) < 50.0


def test_eq9_torques_reproduce_the_joint_rows() -> None:
    """Eq. (9) torques with the QP's ξ̈ and λ make the whole Eq. (5) hold."""
    problem, mass, nle, jacs, _ = _problem((1,))
    x = solve_with_library(problem, "proxqp", eps_abs=1e-10, eps_rel=0.0)
    accel, wrenches = problem.split(x)
    tau = joint_torques(mass, nle, accel, jacs, wrenches)
    gen = np.concatenate([np.zeros(6), tau]) + sum(
        j.T @ w for j, w in zip(jacs, wrenches, strict=True)
    )
    np.testing.assert_allclose(mass @ accel + nle, gen, atol=1e-6)


@pytest.mark.parametrize("support", [(0, 1), (1,)])
def test_preallocated_qp_matches_build_qp(support: tuple[int, ...]) -> None:
    """CentroidalQP builds build_qp's matrices and, cold then warm, finds its solution (ProxQP
    through qpsolvers, the oracle) and Eq. (9) torques."""
    i = _inputs(support)
    problem, mass, nle, jacs, _ = _problem(support)
    nv = i["mass"].shape[0]
    qp = CentroidalQP(nv, support, [i["local"]] * len(support), 1e-4, 1e-6)
    qp.update(
        Dynamics(i["mass"], i["nle"]),
        CostRows(
            np.vstack([i["mass"][:6], i["posture"].jacobian]),
            np.concatenate([i["b1"], i["posture"].target]),
        ),
        i["jacs"],
        i["drifts"],
        i["rots"],
    )
    built = qp.build()
    for name in ("P", "q", "A", "b", "lb", "ub"):
        np.testing.assert_allclose(getattr(built, name), getattr(problem, name), atol=1e-9)
    ref = solve_with_library(problem, "proxqp", eps_abs=1e-10, eps_rel=0.0)
    ref_accel, ref_wrenches = problem.split(ref)
    ref_tau = joint_torques(mass, nle, ref_accel, jacs, ref_wrenches)
    for warm in (False, True):
        assert qp.solve(warm=warm)
        np.testing.assert_allclose(qp.accel, ref_accel, atol=1e-6)
        np.testing.assert_allclose(qp.wrenches, np.array(ref_wrenches), atol=1e-5)
        np.testing.assert_allclose(qp.tau, ref_tau, atol=1e-5)


def test_rotated_wrench_basis_equals_contact_wrench_basis() -> None:
    """Rotating the contact-frame basis gives the world-axes basis of Eq. (8)."""
    rot = pin.rpy.rpyToMatrix(0.3, -0.2, 0.5)
    corners = np.array([[0.12, 0.065, 0], [0.12, -0.065, 0], [-0.12, 0.065, 0], [-0.12, -0.065, 0]])
    basis = friction_basis(MU, 4)
    local = contact_wrench_basis(np.eye(3), corners, basis)
    out = np.empty_like(local)
    rotate_wrench_basis(rot, local, out)
    np.testing.assert_allclose(out, contact_wrench_basis(rot, corners, basis), atol=1e-14)
