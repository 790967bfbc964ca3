"""Tests of the centroidal-momentum QP (Jo & Oh §III-D): friction pyramid, the built problem,
its solvers against the QP libraries (through qpsolvers), KKT residuals and Eq. (9)."""

from __future__ import annotations

import typing

import numpy as np
import pinocchio as pin
import pytest
from pydantic import ValidationError

from walkrepro.controllers import controller_class
from walkrepro.papers.jo_oh.centroidal_qp import (
    QP_SOLVERS,
    CentroidalQP,
    CentroidalTasks,
    Dynamics,
    QPWeights,
    SupportContacts,
    contact_wrench_basis,
    friction_basis,
    solve_with_qpsolvers,
    solver_options,
    stack_of,
)
from walkrepro.sim.robot import load_robot

MU = 0.6
CORNERS = np.array([[sx * 0.12, sy * 0.065, 0.0] for sx in (1, -1) for sy in (1, -1)])
WEIGHTS = QPWeights(1e-4, 1e-6)
#: The library solvers the runtime's answer is checked against (exact active sets, and an
#: iterative one at a tight tolerance).
LIBRARIES = ("daqp", "quadprog", "proxqp")


def test_pyramid_forces_lie_in_friction_cone() -> None:
    """Any U_k β with β ≥ 0 has every point force inside the Coulomb cone |f_t| ≤ μ f_n."""
    rng = np.random.default_rng(0)
    basis = friction_basis(MU, 4)
    rot = pin.rpy.rpyToMatrix(0.3, -0.2, 0.5)
    u = contact_wrench_basis(rot, CORNERS, basis)
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
        np.cross(rot @ CORNERS[j], u[:3, 4 * j : 4 * j + 4] @ beta[4 * j : 4 * j + 4])
        for j in range(4)
    )
    np.testing.assert_allclose(w[3:], moment, atol=1e-12)


def _qp(support: tuple[int, ...], solver: str = "active_set", seed: int = 1):  # noqa: ANN202
    """A CentroidalQP with the inputs of a random moving state of kist_humanoid, the given
    support feet, every task of the paper (random targets) and the momentum task."""
    robot = load_robot("kist_humanoid")
    model = robot.pin_model
    data = model.createData()
    rng = np.random.default_rng(seed)
    q, _ = robot.pin_state_from_mujoco(robot.home_qpos, np.zeros(robot.mj_model.nv))
    v = 0.1 * rng.standard_normal(model.nv)
    pin.computeAllTerms(model, data, q, v)
    pin.updateFramePlacements(model, data)
    nv = model.nv
    jacs, drifts, maps = [], [], []
    for side in (0, 1):
        fid = model.getFrameId(("left_sole", "right_sole")[side])
        jacs.append(pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED))
        a = pin.getFrameClassicalAcceleration(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        drifts.append(a.vector.copy())
        maps.append(contact_wrench_basis(data.oMf[fid].rotation, CORNERS, friction_basis(MU, 4)))

    def task(jacobian: np.ndarray, weight: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        rows = jacobian.shape[0]
        return jacobian.copy(), rng.normal(0, 1, rows), np.full(rows, weight)

    pelvis = pin.getFrameJacobian(model, data, model.getFrameId("pelvis"), pin.LOCAL_WORLD_ALIGNED)
    torso = pin.getFrameJacobian(model, data, model.getFrameId("torso"), pin.LOCAL_WORLD_ALIGNED)
    swing = jacs[1 - support[0]] if len(support) == 1 else jacs[0]
    blocks = [task(pelvis[3:], 100.0), task(torso[3:], 10.0), task(np.eye(nv)[6:], 1.0)]
    swing_task = task(swing, 100.0)  # in the QP in single support only
    if len(support) == 1:
        blocks.append(swing_task)
    tasks = CentroidalTasks(
        rng.normal(0, 5, 6) - (data.nle[:6] - data.g[:6]), np.ones(6), stack_of(*blocks)
    )
    dynamics = Dynamics(data.M.copy(), data.nle.copy())
    contacts = SupportContacts(
        np.array([jacs[k] for k in support]),
        np.array([drifts[k] for k in support]),
        np.array([maps[k] for k in support]),
    )
    qp = CentroidalQP(nv, len(support), 16, WEIGHTS, solver, tolerance=1e-11)
    qp.set_inputs(dynamics, tasks, contacts)
    return qp, dynamics, contacts


def test_problem_is_inspectable() -> None:
    """build_qp writes matrices of the documented shapes: 28 accelerations, 16 β per support foot,
    β ≥ 0 the only finite bounds, P symmetric with W_4 on the β block."""
    qp, *_ = _qp((0, 1))
    problem = qp.build()
    assert problem.P.shape == (28 + 32, 28 + 32)
    assert problem.A.shape == (6 + 12, 60)
    assert np.all(problem.lb[28:] == 0) and np.all(np.isneginf(problem.lb[:28]))
    assert np.all(np.isposinf(problem.ub))
    np.testing.assert_allclose(problem.P, problem.P.T)
    np.testing.assert_array_equal(problem.P[28:, 28:], WEIGHTS.force * np.eye(32))
    np.testing.assert_array_equal(problem.q[28:], 0.0)


def test_build_qp_is_the_papers_cost_and_constraints() -> None:
    """P and q are Σ ΦᵀWΦ + W_3 I and −Σ ΦᵀWb over the momentum term and the stacked tasks; A, b are Eq. (5)'s base rows and the support feet."""
    for support in ((0, 1), (1,)):
        qp, dynamics, contacts = _qp(support)
        problem = qp.build()
        _, tasks, *_ = qp._inputs
        terms = [(dynamics.mass_matrix[:6], tasks.momentum_target, tasks.momentum_weight)]
        stack = tasks.stack
        terms += [
            (stack.jacobian[first:last], stack.target[first:last], stack.weight[first:last])
            for first, last in zip(
                stack.first_row, [*stack.first_row[1:], stack.rows[0]], strict=True
            )
        ]
        assert len(terms) == (5 if len(support) == 1 else 4)  # the swing task: single support
        hess = WEIGHTS.accel * np.eye(28) + sum(j.T @ np.diag(w) @ j for j, _, w in terms)
        grad = -sum(j.T @ (w * b) for j, b, w in terms)
        np.testing.assert_allclose(problem.P[:28, :28], hess, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(problem.q[:28], grad, rtol=1e-12, atol=1e-9)
        np.testing.assert_array_equal(problem.A[:6, :28], dynamics.mass_matrix[:6])
        for k in range(len(support)):
            base = contacts.jacobians[k][:, :6].T @ contacts.wrench_maps[k]
            np.testing.assert_allclose(problem.A[:6, 28 + 16 * k : 44 + 16 * k], -base, atol=1e-12)
            np.testing.assert_array_equal(
                problem.A[6 + 6 * k : 12 + 6 * k, :28], contacts.jacobians[k]
            )
            np.testing.assert_array_equal(problem.b[6 + 6 * k : 12 + 6 * k], -contacts.drifts[k])
        np.testing.assert_array_equal(problem.b[:6], -dynamics.nonlinear[:6])


def _kkt_residuals(problem, x: np.ndarray, nv: int) -> tuple[float, float, float, float]:  # noqa: ANN001
    """(equality, bound, stationarity, complementarity) residuals of x, relative to the
    problem's scale, with ν fitted on the free ξ̈ rows and μ = (Px + q − Aᵀν) on β."""
    p, q, a, b = problem.P, problem.q, problem.A, problem.b
    scale = max(1.0, np.abs(b).max(), np.abs(q).max())
    grad = p @ x + q
    nu = np.linalg.lstsq(a[:, :nv].T, grad[:nv], rcond=None)[0]
    dual = grad - a.T @ nu  # 0 on ξ̈; the bound multipliers μ ≥ 0 on β
    beta, mu = x[nv:], dual[nv:]
    return (
        np.abs(a @ x - b).max() / scale,
        max(0.0, -beta.min()),
        max(np.abs(dual[:nv]).max(), max(0.0, -mu.min())) / scale,
        np.abs(mu * beta).max() / scale,
    )


@pytest.mark.parametrize("support", [(0, 1), (1,)])
@pytest.mark.parametrize("solver", QP_SOLVERS)
def test_every_solver_meets_the_kkt_conditions(support: tuple[int, ...], solver: str) -> None:
    """Each solver's answer satisfies the QP's KKT conditions: the equalities (Eq. 5 base rows,
    support feet), β ≥ 0, stationarity with μ ≥ 0, and complementarity μ β = 0."""
    qp, *_ = _qp(support, solver)
    assert qp.solve(warm=False)
    residuals = _kkt_residuals(qp.problem, qp.solution.x, qp.nv)
    tol = 1e-5 if solver == "osqp" else 1e-8  # OSQP: ADMM, then its polish
    assert max(residuals) < tol, residuals


@pytest.mark.parametrize("support", [(0, 1), (1,)])
@pytest.mark.parametrize("library", LIBRARIES)
def test_active_set_equals_the_libraries(support: tuple[int, ...], library: str) -> None:
    """The runtime's active set (cold, then warm-started) finds the libraries' minimiser, and
    the same Eq. (9) torques, on the same built problem."""
    qp, *_ = _qp(support)
    problem = qp.build()
    x = solve_with_qpsolvers(problem, library, **solver_options(library, 1e-11))
    assert x is not None
    reference, _, _ = _qp(support, library)
    assert reference.solve(warm=False)
    # The controller's library path solves the QP with ξ̈ eliminated (β ≥ 0 only): the same
    # minimiser as the library's on the full problem (ProxQP: to its tolerance).
    np.testing.assert_allclose(reference.solution.x, x, atol=1e-6 * max(1.0, np.abs(x).max()))
    for warm in (False, True):
        assert qp.solve(warm=warm)
        # β is weakly determined (W_4 = 1e-6): compare in units of the forces' scale.
        np.testing.assert_allclose(qp.accel, x[:28], atol=1e-6)
        np.testing.assert_allclose(qp.solution.x[28:], x[28:], atol=1e-6 * np.abs(x[28:]).max())
        force_scale = np.abs(reference.wrenches).max()  # ≈ 300 N
        np.testing.assert_allclose(qp.wrenches, reference.wrenches, atol=1e-7 * force_scale)
        np.testing.assert_allclose(qp.tau, reference.tau, atol=1e-7 * force_scale)


@pytest.mark.parametrize("solver", ("active_set", "daqp"))
def test_eq9_torques_make_the_whole_eq5_hold(solver: str) -> None:
    """Eq. (9) torques with the QP's ξ̈ and λ make the whole Eq. (5) hold, and the feet carry
    the weight (≈ 559 N) in double support."""
    for support in ((0, 1), (1,)):
        qp, dynamics, contacts = _qp(support, solver)
        assert qp.solve(warm=False)
        mass, nle = dynamics.mass_matrix, dynamics.nonlinear
        generalised = np.concatenate([np.zeros(6), qp.tau]) + sum(
            j.T @ w for j, w in zip(contacts.jacobians, qp.wrenches, strict=True)
        )
        np.testing.assert_allclose(mass @ qp.accel + nle, generalised, atol=1e-6)
        if len(support) == 2:
            assert abs(qp.wrenches[:, 2].sum() - 57.0 * 9.81) < 60.0


def test_the_solver_parameter_names_the_valid_solvers() -> None:
    """qp_solver accepts exactly QP_SOLVERS, and an unknown name lists them."""
    cls = controller_class("qpimpedance")
    field = cls.Params.model_fields["qp_solver"]
    assert typing.get_args(field.annotation) == QP_SOLVERS
    with pytest.raises(ValidationError, match="active_set"):
        cls.Params(qp_solver="cvxopt")
    with pytest.raises(ValueError, match="valid: active_set, daqp"):
        CentroidalQP(28, 1, 16, WEIGHTS, "cvxopt")


def test_a_library_solver_runs_the_controllers_tick(kist_home_snapshot) -> None:  # noqa: ANN001
    """A tick with qp_solver daqp (through qpsolvers) gives the active set's torques."""
    robot = load_robot("kist_humanoid")
    cls = controller_class("qpimpedance")
    torques = []
    for solver in ("active_set", "daqp"):
        ctrl = cls()
        ctrl.reset(robot, cls.Params(qp_solver=solver), 0.001)
        torques.append([ctrl.step(0.001 * k, kist_home_snapshot()).ctrl for k in range(3)])
    np.testing.assert_allclose(torques[1], torques[0], rtol=1e-7, atol=1e-6)


def test_the_default_tick_solves_through_qpsolvers(kist_home_snapshot, monkeypatch) -> None:  # noqa: ANN001
    """By default (qp_solver daqp) every tick's QP goes through qpsolvers.solve_problem, with
    the DAQP backend; the active set is opt-in."""
    import qpsolvers

    calls: list[str] = []
    solve_problem = qpsolvers.solve_problem

    def counted(problem, solver, **kwargs):  # noqa: ANN001, ANN202
        calls.append(solver)
        return solve_problem(problem, solver=solver, **kwargs)

    monkeypatch.setattr(qpsolvers, "solve_problem", counted)
    cls = controller_class("qpimpedance")
    assert cls.Params().qp_solver == "daqp"
    ctrl = cls()
    ctrl.reset(load_robot("kist_humanoid"), cls.Params(), 0.001)
    calls.clear()  # reset's warm-up solves each support set once
    for k in range(3):
        ctrl.step(0.001 * k, kist_home_snapshot())
    assert calls == ["daqp"] * 3
