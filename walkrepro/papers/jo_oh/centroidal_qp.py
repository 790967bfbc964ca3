"""The whole-body QP of §III-D: centroidal momentum, friction pyramids, task accelerations.

Decision variables x = (ξ̈, β): the generalised acceleration (n + 6) and the pyramid
coefficients β_k of each support foot (N_c corner point contacts × m edges, Eq. 8).

    min  ‖M_B ξ̈ − b_1‖²_{W_1} + Σ_t ‖Φ_t ξ̈ − b_t‖²_{W_t} + ‖ξ̈‖²_{W_3} + Σ_k ‖β_k‖²_{W_4}
    s.t. M_B ξ̈ + C_B ξ̇ + g_B = Σ_k X_{C_k B}ᵀ R̃_{C_k} U_k β_k   (floating-base rows of Eq. 5)
         Φ_k ξ̈ + Φ̇_k ξ̇ = 0                                      (support feet)
         Λ_k β_k ≥ 0                                             (Λ_k = I: β_k ≥ 0)

with b_1 = X_GBᵀ ḣ_{G,r} − C_B ξ̇ (Eq. 7) and b_t = ẍ_r − Φ̇_t ξ̇. The joint torques follow
from Eq. (9): τ = M_q ξ̈* + C_q ξ̇ + g_q − Σ_k J_{C_k}ᵀ λ*_k.

Here the contact Jacobians are Pinocchio's sole-frame Jacobians in LOCAL_WORLD_ALIGNED
axes, so Σ X_{C_k B}ᵀ R̃ U_k β_k is the base block of J_kᵀ (U_k β_k) with U_k β_k the
contact wrench at the sole centre in world axes.

Build, then solve. Each tick :func:`build_qp` writes the problem, from the tasks named as in
the paper (:class:`CentroidalTasks`: b_1 and the declared tasks' stacked rows), into a
:class:`QPProblem`: the matrices any QP library takes, min ½ xᵀPx + qᵀx s.t. A x = b,
lb ≤ x ≤ ub. :class:`CentroidalQP` then solves it with the solver the controller names
(:data:`QP_SOLVERS`): by default ``daqp`` through ``qpsolvers.solve_problem`` (chosen by
measurement on Paper III's runs, docs/performance.md), or any other ``qpsolvers`` backend, or
``active_set``, this package's exact active set on the same matrices with ξ̈ eliminated
(:mod:`.condensed`), an opt-in fast path. Why numba: the build is ≈ 30 small matrix products
and copies a tick, ≈ 1 µs each from Python; compiled, the build is one call, and Eq. (9)
another.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from walkrepro.papers.jo_oh.condensed import solve_eliminated
from walkrepro.runtime.records import define_record

#: Rows of the floating base in ξ̇, M and C ξ̇ + g (Eq. 5's first block), and their count.
N_BASE = 6
BASE = slice(0, N_BASE)
#: Rows of a contact wrench (force, moment) and of a support foot's constraint Φ_k ξ̈ = −Φ̇_k ξ̇.
N_WRENCH = 6

#: The QP solvers a controller may name: this package's exact active set, and the
#: ``qpsolvers`` backends (each a pip install away: ``pip install qpsolvers[NAME]``).
QP_SOLVERS = ("active_set", "daqp", "quadprog", "proxqp", "osqp")
#: The backends that take the QP with ξ̈ eliminated (:func:`eliminate_accelerations`): the
#: same minimiser, faster. OSQP (ADMM) solves the β-only QP worse (β off by ≈ 20 %, ξ̈ by
#: 1e-4 on Paper III's runs, docs/performance.md), so it gets the full problem.
ELIMINATING_SOLVERS = ("daqp", "quadprog", "proxqp")


# ---- records (named tuples: numba passes them without copies) ----------------------------
class Dynamics(NamedTuple):
    """Pinocchio's joint-space dynamics terms of Eq. (5) (base velocity in the base frame).

    Attributes:
        mass_matrix: M = [M_B; M_q], shape (nv, nv) [kg, kg m, kg m²].
        nonlinear: C ξ̇ + g, shape (nv,) [N, N m].
    """

    mass_matrix: np.ndarray
    nonlinear: np.ndarray


class TaskStack(NamedTuple):
    """The task terms Σ_t ‖Φ_t ξ̈ − b_t‖²_{W_t} of §III-D, stacked row by row
    (:func:`.tasks.stack_tasks` fills them from the declared tasks each tick).

    Attributes:
        jacobian: Φ_t of every task, stacked, shape (max rows, nv).
        target: b_t = ẍ_r − Φ̇_t ξ̇, shape (max rows,) [m/s², rad/s²].
        weight: the diagonal of W_t, shape (max rows,).
        first_row: each declared task's first row (−1: not in this tick's QP), shape (tasks,).
        rows: the rows in use this tick (the first ``rows[0]``), shape (1,) int.
    """

    jacobian: np.ndarray
    target: np.ndarray
    weight: np.ndarray
    first_row: np.ndarray
    rows: np.ndarray


class CentroidalTasks(NamedTuple):
    """The cost terms of the §III-D QP, as the paper names them.

    Attributes:
        momentum_target: b_1 = X_GBᵀ ḣ_{G,r} − C_B ξ̇ (Eq. 7), shape (6,) [N, N m]; the term
            is ‖M_B ξ̈ − b_1‖²_{W_1}, with M_B from :class:`Dynamics`.
        momentum_weight: the diagonal of W_1, shape (6,).
        stack: the declared tasks' rows (pelvis and torso orientation, arm and waist posture,
            swing foot in single support, as the controller declares them).
    """

    momentum_target: np.ndarray
    momentum_weight: np.ndarray
    stack: TaskStack


def empty_stack(n_rows: int, n_tasks: int, nv: int) -> TaskStack:
    """A :class:`TaskStack` for at most ``n_rows`` rows of ``n_tasks`` tasks over ξ̈ (nv)."""
    return TaskStack(
        np.zeros((n_rows, nv)),
        np.zeros(n_rows),
        np.zeros(n_rows),
        np.full(n_tasks, -1, dtype=np.int64),
        np.zeros(1, dtype=np.int64),
    )


class SupportContacts(NamedTuple):
    """The support feet's contact terms, stacked per foot in the order of their β blocks.

    Attributes:
        jacobians: J_k = Φ_k (sole frame, world axes), shape (k, 6, nv).
        drifts: J̇_k ξ̇ = Φ̇_k ξ̇, shape (k, 6) [m/s², rad/s²].
        wrench_maps: R̃_{C_k} U_k (Eq. 8, world axes, wrench at the sole), shape (k, 6, m N_c).
    """

    jacobians: np.ndarray
    drifts: np.ndarray
    wrench_maps: np.ndarray


class QPWeights(NamedTuple):
    """The regularisation weights of the §III-D QP (each a scalar times identity).

    Attributes:
        accel: W_3, on ξ̈.
        force: W_4, on β.
    """

    accel: float
    force: float


class QPProblem(NamedTuple):
    """min ½ xᵀPx + qᵀx  s.t.  A x = b,  lb ≤ x ≤ ub,  with x = (ξ̈, β) (nx = nv + Σ m N_c).

    Attributes:
        P: Hessian, shape (nx, nx): the ξ̈ block from the tasks and W_3, the β block W_4 I.
        q: linear term, shape (nx,) (zero on β).
        A: equality matrix, shape (6 + 6k, nx): the 6 floating-base rows of Eq. (5), then 6
            per support foot.
        b: equality right-hand side, shape (6 + 6k,).
        lb: lower bounds, −inf on ξ̈ and 0 on β (Λ_k β_k ≥ 0), shape (nx,).
        ub: upper bounds, +inf, shape (nx,).
    """

    P: np.ndarray
    q: np.ndarray
    A: np.ndarray
    b: np.ndarray
    lb: np.ndarray
    ub: np.ndarray


class EliminatedQP(NamedTuple):
    """The QP with ξ̈ eliminated (:func:`eliminate_accelerations`): min ½ βᵀHβ + gᵀβ, β ≥ 0,
    and ξ̈ = ξ̈₀ + S β.

    Attributes:
        hessian: H = SᵀP_ξξS + W_4 I, shape (nβ, nβ).
        gradient: g = Sᵀ(P_ξξ ξ̈₀ + q_ξ), shape (nβ,).
        offset: ξ̈₀, the minimiser of the equality-constrained cost at β = 0, shape (nv,).
        sensitivity: S = ∂ξ̈/∂β, shape (nv, nβ).
    """

    hessian: np.ndarray
    gradient: np.ndarray
    offset: np.ndarray
    sensitivity: np.ndarray


class QPSolution(NamedTuple):
    """The §III-D QP's solution and its Eq. (9) torques, written in place.

    Attributes:
        x: (ξ̈*, β*), shape (nx,); its β part is the active set's start (≥ 0; zeros for a
            cold start).
        wrenches: U_k β*_k of each support foot (world axes, at the sole), shape (k, 6).
        tau: Eq. (9) joint torques, shape (nv − 6,) [N m].
    """

    x: np.ndarray
    wrenches: np.ndarray
    tau: np.ndarray


def stack_of(*blocks: tuple[np.ndarray, np.ndarray, np.ndarray]) -> TaskStack:
    """A :class:`TaskStack` holding these tasks' (Φ_t, b_t, W_t diagonal) rows, in order (for
    tests and for a QP built outside the controller)."""
    jacobians, targets, weights = zip(*blocks, strict=True)
    jacobian = np.vstack(jacobians)
    first = np.cumsum([0, *(len(target) for target in targets)])[: len(blocks)]
    return TaskStack(
        jacobian,
        np.concatenate(targets),
        np.concatenate(weights),
        first.astype(np.int64),
        np.array([jacobian.shape[0]], dtype=np.int64),
    )


# ---- the friction pyramid (Eq. 8) ----------------------------------------------------------
def friction_basis(mu: float, n_edges: int) -> np.ndarray:
    """Edge directions Ū of an m-sided friction pyramid inscribed in the cone |f_t| ≤ μ f_n.

    Args:
        mu: Coulomb friction coefficient μ [-].
        n_edges: number of pyramid edges m (≥ 3).

    Returns:
        Unit edge vectors in the contact frame (z normal), shape (3, m). Any f = Ū α with
        α ≥ 0 lies inside the cone because every edge lies on it and the cone is convex.
    """
    if n_edges < 3:
        raise ValueError(f"a friction pyramid needs at least 3 edges, got {n_edges}")
    angles = 2.0 * np.pi * np.arange(n_edges) / n_edges
    edges = np.stack([mu * np.cos(angles), mu * np.sin(angles), np.ones(n_edges)])
    return edges / np.linalg.norm(edges, axis=0)


def contact_wrench_basis(
    rotation: np.ndarray, corners: np.ndarray, basis: np.ndarray
) -> np.ndarray:
    """U_k of Eq. (8), rotated to world axes (R̃_{C_k} U_k).

    Args:
        rotation: world-from-contact-frame rotation R̃_{C_k}, shape (3, 3).
        corners: contact points d̃_j in the contact frame [m], shape (N_c, 3).
        basis: pyramid edges Ū in the contact frame, shape (3, m).

    Returns:
        Shape (6, m N_c): column (j, i) is the wrench (force; torque about the contact frame
        origin), world axes, of a unit force along edge i at corner j.
    """
    edges_w = rotation @ basis  # Ū_j in world axes, (3, m)
    corners_w = corners @ rotation.T  # d̃_j in world axes, (N_c, 3)
    forces = np.tile(edges_w, corners.shape[0])  # E_3 Ū_j
    moments = np.cross(np.repeat(corners_w, basis.shape[1], axis=0), forces.T).T  # $(d̃_j) Ū_j
    return np.vstack([forces, moments])


# ---- build -------------------------------------------------------------------------------
def empty_qp(nv: int, n_beta: int, n_feet: int, force_weight: float) -> QPProblem:
    """A :class:`QPProblem` of the given shape with its constant parts filled in.

    Constant: the β block of P (W_4 I), the bounds (ξ̈ free, β ≥ 0) and the zeros of q and A
    outside the blocks :func:`build_qp` writes.

    Args:
        nv: size of ξ̈.
        n_beta: number of pyramid coefficients of all support feet, Σ m N_c.
        n_feet: number of support feet.
        force_weight: W_4.
    """
    nx = nv + n_beta
    p = np.zeros((nx, nx))
    p[np.arange(nv, nx), np.arange(nv, nx)] = force_weight
    lb = np.concatenate([np.full(nv, -np.inf), np.zeros(n_beta)])
    ne = N_BASE + N_WRENCH * n_feet
    return QPProblem(p, np.zeros(nx), np.zeros((ne, nx)), np.zeros(ne), lb, np.full(nx, np.inf))


@numba.njit(cache=True)
def _add_rows(
    jacobian: np.ndarray,
    target: np.ndarray,
    weight: np.ndarray,
    rows: np.ndarray,
    rhs: np.ndarray,
    start: int,
) -> int:
    """Rows √W Φ and √W b of ‖Φ ξ̈ − b‖²_W from ``start`` (loops: no temporaries)."""
    for r in range(weight.size):
        sqrt_w = np.sqrt(weight[r])
        for j in range(jacobian.shape[1]):
            rows[start + r, j] = sqrt_w * jacobian[r, j]
        rhs[start + r] = sqrt_w * target[r]
    return start + weight.size


@numba.njit(cache=True)
def build_qp(
    dynamics: Dynamics,
    tasks: CentroidalTasks,
    contacts: SupportContacts,
    weights: QPWeights,
    problem: QPProblem,
) -> None:
    """Write this tick's QP of §III-D into ``problem`` (from :func:`empty_qp`).

    The cost ‖M_B ξ̈ − b_1‖²_{W_1} + Σ_t ‖Φ_t ξ̈ − b_t‖²_{W_t} + ‖ξ̈‖²_{W_3} is ‖A_c ξ̈ − a_c‖²
    + W_3 ‖ξ̈‖² with the weighted rows A_c = [√W_1 M_B; √W_t Φ_t …], a_c = [√W_1 b_1; √W_t b_t
    …]: P_ξξ = A_cᵀA_c + W_3 I, q_ξ = −A_cᵀa_c (the β block, W_4 I, is constant). The swing
    foot's task is in the cost in single support only. The equalities: the floating-base
    rows of Eq. (5), M_B ξ̈ − Σ_k X_{C_k B}ᵀ R̃_{C_k} U_k β_k = −(C_B ξ̇ + g_B), then each
    support foot's Φ_k ξ̈ = −Φ̇_k ξ̇.

    Args:
        dynamics: M and C ξ̇ + g.
        tasks: b_1, W_1 and the tasks Φ_t, b_t, W_t.
        contacts: J_k, J̇_k ξ̇ and R̃_{C_k} U_k of each support foot.
        weights: W_3 (W_4 is in ``problem`` from :func:`empty_qp`).
        problem: written in place.
    """
    mass_matrix = dynamics.mass_matrix
    nv = mass_matrix.shape[0]
    n_feet, m = contacts.wrench_maps.shape[0], contacts.wrench_maps.shape[2]
    # The weighted cost rows: the momentum term, then the tasks as stacked.
    stack = tasks.stack
    n_tasks = stack.rows[0]
    rows, rhs = np.empty((N_BASE + n_tasks, nv)), np.empty(N_BASE + n_tasks)
    row = _add_rows(mass_matrix[BASE], tasks.momentum_target, tasks.momentum_weight, rows, rhs, 0)
    _add_rows(
        stack.jacobian[:n_tasks], stack.target[:n_tasks], stack.weight[:n_tasks], rows, rhs, row
    )
    hess = rows.T @ rows  # A_cᵀ A_c
    for i in range(nv):
        hess[i, i] += weights.accel  # + W_3 I
    problem.P[:nv, :nv] = hess
    problem.q[:nv] = -(rhs @ rows)
    # Floating-base rows of Eq. (5).
    problem.A[BASE, :nv] = mass_matrix[BASE]
    problem.b[BASE] = -dynamics.nonlinear[BASE]
    for k in range(n_feet):
        jacobian = contacts.jacobians[k]
        # −X_{C_k B}ᵀ R̃_{C_k} U_k: the base columns of J_kᵀ applied to the wrench basis.
        beta = nv + k * m  # this foot's first β
        problem.A[BASE, beta : beta + m] = -(
            np.ascontiguousarray(jacobian[:, BASE].T) @ contacts.wrench_maps[k]
        )
        # The support foot: Φ_k ξ̈ + Φ̇_k ξ̇ = 0.
        first = N_BASE + N_WRENCH * k
        problem.A[first : first + N_WRENCH, :nv] = jacobian
        problem.b[first : first + N_WRENCH] = -contacts.drifts[k]


# ---- solve -------------------------------------------------------------------------------
@numba.njit(cache=True)
def joint_torques(dynamics: Dynamics, contacts: SupportContacts, solution: QPSolution) -> None:
    """Eq. (9), τ = M_q ξ̈* + C_q ξ̇ + g_q − Σ_k J_{C_k,q}ᵀ λ*_k, with λ*_k = R̃ U_k β*_k.

    Writes ``solution.wrenches`` (λ*_k, world axes, at the sole) and ``solution.tau`` [N m].
    """
    mass_matrix, nonlinear = dynamics.mass_matrix, dynamics.nonlinear
    jacobians, wrench_maps = contacts.jacobians, contacts.wrench_maps
    x, wrenches, tau = solution.x, solution.wrenches, solution.tau
    nv = mass_matrix.shape[0]
    n_feet, m = wrench_maps.shape[0], wrench_maps.shape[2]
    for k in range(n_feet):
        beta = nv + k * m  # this foot's first β
        wrenches[k] = wrench_maps[k] @ x[beta : beta + m]
    # Written as loops: Pinocchio's M is column-major, which numba's `@` takes slowly.
    for i in range(nv - N_BASE):
        joint = N_BASE + i
        s = nonlinear[joint]
        for j in range(nv):
            s += mass_matrix[joint, j] * x[j]
        for k in range(n_feet):
            for j in range(N_WRENCH):
                s -= jacobians[k, j, joint] * wrenches[k, j]
        tau[i] = s


@numba.njit(cache=True)
def solve_active_set(problem: QPProblem, nv: int, force_weight: float, x: np.ndarray) -> int:
    """Solve ``problem`` exactly by :func:`.condensed.solve_eliminated` (ξ̈ eliminated, an
    active set on β ≥ 0), starting from x's β (≥ 0); x ← (ξ̈*, β*).

    It needs the shape :func:`empty_qp` gives: the β block of P W_4 I, q zero on β, and
    β ≥ 0 the only bounds.

    Returns:
        The active-set iterations, or −1 if it found no solution.
    """
    return solve_eliminated(
        problem.P[:nv, :nv].copy(),
        problem.q[:nv],
        problem.A[:, :nv],
        problem.A[:, nv:],
        problem.b,
        force_weight,
        x[nv:],
        x[:nv],
    )


#: One support set's QP as one argument of :func:`solve_centroidal`: its inputs and outputs,
#: made once by :func:`qp_records` (the arrays are filled in place every tick): ``dynamics``
#: (:class:`Dynamics`), ``tasks`` (:class:`CentroidalTasks`), ``contacts``
#: (:class:`SupportContacts`), ``weights`` (:class:`QPWeights`), ``problem``
#: (:class:`QPProblem`), ``eliminated`` (:class:`EliminatedQP`) and ``solution``
#: (:class:`QPSolution`). A StructRef: numba finds the
#: type of a named tuple argument in Python, field by field, at every call (≈ 25–30 µs a tick
#: here, measured); a StructRef carries its type.
QPRecordsType, QPRecords = define_record(
    "QPRecords",
    ("dynamics", "tasks", "contacts", "weights", "problem", "eliminated", "solution"),
    __name__,
)


@numba.njit(cache=True)
def qp_records(
    dynamics: Dynamics,
    tasks: CentroidalTasks,
    contacts: SupportContacts,
    weights: QPWeights,
    problem: QPProblem,
    eliminated: EliminatedQP,
    solution: QPSolution,
) -> QPRecords:
    """The :class:`QPRecords` of these records (compiled and cached, unlike the proxy's own
    constructor)."""
    return QPRecords(dynamics, tasks, contacts, weights, problem, eliminated, solution)


def empty_eliminated(nv: int, n_beta: int) -> EliminatedQP:
    """An :class:`EliminatedQP` for ξ̈ of size nv and nβ pyramid coefficients."""
    return EliminatedQP(
        np.zeros((n_beta, n_beta)), np.zeros(n_beta), np.zeros(nv), np.zeros((nv, n_beta))
    )


#: Columns of the right-hand sides :func:`eliminate_accelerations` solves for: ξ̈₀'s, then S's.
OFFSET_COLUMN, FIRST_SENSITIVITY_COLUMN = 0, 1


@numba.njit(cache=True)
def eliminate_accelerations(
    problem: QPProblem, nv: int, force_weight: float, out: EliminatedQP
) -> None:
    """The §III-D QP as a QP in β alone, exactly: for fixed β the cost's minimiser over ξ̈
    subject to A_ξ ξ̈ + A_β β = b solves the KKT system

        [P_ξξ  A_ξᵀ] [ξ̈]   [−q_ξ       ]
        [A_ξ   0   ] [ν ] = [b − A_β β ],

    so ξ̈ = ξ̈₀ + S β (one solve, 1 + nβ right-hand sides), and the cost along it is
    ½ βᵀ(SᵀP_ξξS + W_4 I)β + (Sᵀ(P_ξξ ξ̈₀ + q_ξ))ᵀβ + const. The equalities then hold for
    every β; only β ≥ 0 remains (the bounds of :func:`empty_qp`'s shape).
    """
    p_xx, q_x = problem.P[:nv, :nv], problem.q[:nv]
    a_x, a_b = problem.A[:, :nv], problem.A[:, nv:]
    n_eq, n_beta = a_x.shape[0], a_b.shape[1]
    kkt = np.zeros((nv + n_eq, nv + n_eq))
    kkt[:nv, :nv] = p_xx
    kkt[:nv, nv:] = a_x.T
    kkt[nv:, :nv] = a_x
    rhs = np.zeros((nv + n_eq, FIRST_SENSITIVITY_COLUMN + n_beta))
    rhs[:nv, OFFSET_COLUMN] = -q_x
    rhs[nv:, OFFSET_COLUMN] = problem.b
    rhs[nv:, FIRST_SENSITIVITY_COLUMN:] = -a_b
    solution = np.linalg.solve(kkt, rhs)
    offset, sensitivity = out.offset, out.sensitivity
    offset[:] = solution[:nv, OFFSET_COLUMN]
    sensitivity[:] = solution[:nv, FIRST_SENSITIVITY_COLUMN:]
    weighted = np.ascontiguousarray(p_xx) @ sensitivity  # P_ξξ S
    out.hessian[:] = sensitivity.T @ weighted
    for i in range(n_beta):
        out.hessian[i, i] += force_weight  # + W_4 I
    out.gradient[:] = sensitivity.T @ (np.ascontiguousarray(p_xx) @ offset + q_x)


@numba.njit(cache=True)
def build_eliminated(qp: QPRecords) -> None:
    """:func:`build_qp`, then :func:`eliminate_accelerations`, in one compiled call."""
    build_qp(qp.dynamics, qp.tasks, qp.contacts, qp.weights, qp.problem)
    nv = qp.dynamics.mass_matrix.shape[0]
    eliminate_accelerations(qp.problem, nv, qp.weights.force, qp.eliminated)


@numba.njit(cache=True)
def finish_eliminated(qp: QPRecords, eliminated_accelerations: bool) -> None:
    """With ``eliminated_accelerations``, x ← (ξ̈₀ + S β, β) from the solution's β; then
    Eq. (9) (:func:`joint_torques`)."""
    eliminated, x = qp.eliminated, qp.solution.x
    nv = eliminated.offset.shape[0]
    if eliminated_accelerations:
        x[:nv] = eliminated.offset + eliminated.sensitivity @ x[nv:]
    joint_torques(qp.dynamics, qp.contacts, qp.solution)


@numba.njit(cache=True)
def solve_centroidal(qp: QPRecords) -> int:
    """The tick's QP with the ``active_set`` solver: :func:`build_qp`, :func:`solve_active_set`,
    Eq. (9) (:func:`joint_torques`), in one compiled call.

    Returns:
        As :func:`solve_active_set`.
    """
    dynamics, tasks, contacts, weights = qp.dynamics, qp.tasks, qp.contacts, qp.weights
    problem, solution = qp.problem, qp.solution
    build_qp(dynamics, tasks, contacts, weights, problem)
    nv = dynamics.mass_matrix.shape[0]
    iterations = solve_active_set(problem, nv, weights.force, solution.x)
    if iterations >= 0:
        joint_torques(dynamics, contacts, solution)
    return iterations


@numba.njit(cache=True)
def build_centroidal(qp: QPRecords) -> None:
    """:func:`build_qp` on the records' inputs (one compiled call: the records carry their
    type, where the named tuples would be typed field by field at every call)."""
    build_qp(qp.dynamics, qp.tasks, qp.contacts, qp.weights, qp.problem)


def solve_with_qpsolvers(
    problem: QPProblem, solver: str, initvals: np.ndarray | None = None, **options: object
) -> np.ndarray | None:
    """min ½ xᵀPx + qᵀx s.t. A x = b, lb ≤ x ≤ ub through ``qpsolvers``; None when no solution.

    Args:
        problem: the assembled QP.
        solver: a ``qpsolvers`` backend (``proxqp`` runs its dense backend, ``osqp`` gets
            sparse matrices).
        initvals: a primal start, for the solvers that take one.
        options: the solver's settings (``eps_abs`` …).
    """
    import qpsolvers  # only the library solvers need it

    if solver not in qpsolvers.available_solvers:
        raise ValueError(
            f"QP solver {solver!r} is not installed; installed: "
            f"{', '.join(qpsolvers.available_solvers)} (pip install qpsolvers[{solver}])"
        )
    p, a = problem.P, problem.A
    if solver == "proxqp":
        options = {"backend": "dense", **options}  # the matrices are dense
    elif solver == "osqp":  # OSQP takes sparse matrices; converting here avoids a warning
        from scipy import sparse

        p, a = sparse.csc_matrix(p), sparse.csc_matrix(a)
    qp = qpsolvers.Problem(p, problem.q, None, None, a, problem.b, problem.lb, problem.ub)
    solution = qpsolvers.solve_problem(qp, solver=solver, initvals=initvals, **options)
    return solution.x if solution.found else None


def solve_bounded_with_qpsolvers(
    eliminated: EliminatedQP, solver: str, initvals: np.ndarray | None = None, **options: object
) -> np.ndarray | None:
    """min ½ βᵀHβ + gᵀβ s.t. β ≥ 0 (the QP with ξ̈ eliminated) through
    ``qpsolvers.solve_problem``; β*, or None when no solution."""
    import qpsolvers  # only the library solvers need it

    if solver not in qpsolvers.available_solvers:
        raise ValueError(
            f"QP solver {solver!r} is not installed; installed: "
            f"{', '.join(qpsolvers.available_solvers)} (pip install qpsolvers[{solver}])"
        )
    hessian = eliminated.hessian
    if solver == "proxqp":
        options = {"backend": "dense", **options}
    elif solver == "osqp":
        from scipy import sparse

        hessian = sparse.csc_matrix(hessian)
    lower = np.zeros(eliminated.gradient.size)
    qp = qpsolvers.Problem(hessian, eliminated.gradient, lb=lower)
    solution = qpsolvers.solve_problem(qp, solver=solver, initvals=initvals, **options)
    return solution.x if solution.found else None


def solver_options(solver: str, tolerance: float) -> dict[str, object]:
    """The settings :func:`solve_with_qpsolvers` passes to ``solver`` for an absolute
    tolerance [the QP's units]: the iterative solvers' stopping tolerance; the active-set
    solvers (daqp, quadprog) stop at the exact minimiser and take none."""
    if solver == "proxqp":
        return {"eps_abs": tolerance, "eps_rel": 0.0}
    if solver == "osqp":
        return {
            "eps_abs": tolerance,
            "eps_rel": 0.0,
            "polishing": True,
            "max_iter": 100_000,
            "raise_error": False,  # not converged: no solution, as the other solvers say it
        }
    return {}


class CentroidalQP:
    """The QP of §III-D for one support set, in preallocated arrays, built and solved each tick.

    Args:
        nv: size of ξ̈.
        n_feet: number of support feet.
        n_beta_per_foot: pyramid coefficients m N_c of each foot.
        weights: W_3 and W_4.
        solver: one of :data:`QP_SOLVERS`.
        tolerance: the iterative solvers' absolute tolerance (:func:`solver_options`).

    Attributes:
        problem: this tick's problem (after :meth:`build` or :meth:`solve`).
        solution: ξ̈*, β*, the wrenches and the Eq. (9) torques of the last successful
            :meth:`solve`.
    """

    def __init__(
        self,
        nv: int,
        n_feet: int,
        n_beta_per_foot: int,
        weights: QPWeights,
        solver: str = "daqp",
        tolerance: float = 1e-9,
    ) -> None:
        if solver not in QP_SOLVERS:
            raise ValueError(f"unknown QP solver {solver!r}; valid: {', '.join(QP_SOLVERS)}")
        self.nv, self.solver, self._weights = nv, solver, weights
        self._options = solver_options(solver, tolerance)
        self.problem = empty_qp(nv, n_feet * n_beta_per_foot, n_feet, weights.force)
        self.eliminated = empty_eliminated(nv, n_feet * n_beta_per_foot)
        nx = self.problem.q.size
        self.solution = QPSolution(np.zeros(nx), np.zeros((n_feet, 6)), np.zeros(nv - 6))
        self._inputs: tuple | None = None

    @property
    def accel(self) -> np.ndarray:
        """ξ̈* of the last successful :meth:`solve`, shape (nv,)."""
        return self.solution.x[: self.nv]

    @property
    def wrenches(self) -> np.ndarray:
        """U_k β*_k of each support foot (world axes, at the sole), shape (k, 6)."""
        return self.solution.wrenches

    @property
    def tau(self) -> np.ndarray:
        """Eq. (9) joint torques of the last successful :meth:`solve`, shape (nv − 6,) [N m]."""
        return self.solution.tau

    def set_inputs(
        self, dynamics: Dynamics, tasks: CentroidalTasks, contacts: SupportContacts
    ) -> None:
        """Take the tick's inputs by reference (no copies): a caller that fills the same
        arrays in place every tick sets them once."""
        self._inputs = (dynamics, tasks, contacts, self._weights, self.problem)
        self._records = qp_records(*self._inputs, self.eliminated, self.solution)

    def build(self) -> QPProblem:
        """This tick's problem (:func:`build_qp`), for inspection or a library solver."""
        assert self._inputs is not None, "set_inputs first"
        build_centroidal(self._records)
        return self.problem

    def solve(self, warm: bool) -> bool:
        """Build and solve this tick's problem; ``warm`` starts from this set's last solution.

        Returns:
            Whether a solution was found (then in :attr:`solution`).
        """
        assert self._inputs is not None, "set_inputs first"
        x = self.solution.x
        if self.solver == "active_set":
            if not warm:
                x[self.nv :] = 0.0  # cold: every β at its bound
            return solve_centroidal(self._records) >= 0
        if self.solver not in ELIMINATING_SOLVERS:
            found = solve_with_qpsolvers(
                self.build(), self.solver, x.copy() if warm else None, **self._options
            )
            if found is None:
                return False
            x[:] = found
            finish_eliminated(self._records, False)
            return True
        build_eliminated(self._records)
        start = x[self.nv :].copy() if warm else None
        beta = solve_bounded_with_qpsolvers(self.eliminated, self.solver, start, **self._options)
        if beta is None:
            return False
        x[self.nv :] = beta
        finish_eliminated(self._records, True)
        return True
