"""The whole-body QP of §III: centroidal momentum, friction pyramids, task accelerations.

Decision variables x = (ξ̈, β): the generalised acceleration (n + 6) and the pyramid
coefficients β_k of each support foot (N_c corner point contacts × m edges, Eq. 8).

    min  ‖M_B ξ̈ − b_1‖²_{W_1} + Σ_t ‖Φ_t ξ̈ − b_t‖²_{W_t} + ‖ξ̈‖²_{W_3} + Σ_k ‖β_k‖²_{W_4}
    s.t. M_B ξ̈ + C_B ξ̇ + g_B = Σ_k X_{C_k B}ᵀ R̃_{C_k} U_k β_k   (floating-base rows of Eq. 5)
         Φ_k ξ̈ + Φ̇_k ξ̇ = 0                                      (support feet)
         β_k ≥ 0

with b_1 = X_GBᵀ ḣ_{G,r} − C_B ξ̇ (Eq. 7) and b_t = ẍ_r − Φ̇_t ξ̇. The joint torques follow
from Eq. (9): τ = M_q ξ̈* + C_q ξ̇ + g_q − Σ_k J_{C_k}ᵀ λ*_k.

Here the contact Jacobians are Pinocchio's sole-frame Jacobians in LOCAL_WORLD_ALIGNED
axes, so Σ X_{C_k B}ᵀ R̃ U_k β_k is the base block of J_kᵀ (U_k β_k) with U_k β_k the
contact wrench at the sole centre in world axes. Build, then solve: :func:`build_qp`
returns an inspectable :class:`QPProblem`; :meth:`QPProblem.solve` calls ``qpsolvers``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import qpsolvers
from scipy import sparse

#: Solvers this module is tested with, fastest first on our problem (see README).
SOLVERS = ("proxqp", "osqp")


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
    n_c, m = corners.shape[0], basis.shape[1]
    edges_w = rotation @ basis  # (3, m)
    corners_w = corners @ rotation.T  # (N_c, 3)
    u = np.empty((6, m * n_c))
    u[:3] = np.tile(edges_w, n_c)
    # d̃_j × ū_i for every corner j and edge i, written out (np.cross is slow on small arrays).
    d = np.repeat(corners_w, m, axis=0).T  # (3, m N_c)
    e = u[:3]
    u[3] = d[1] * e[2] - d[2] * e[1]
    u[4] = d[2] * e[0] - d[0] * e[2]
    u[5] = d[0] * e[1] - d[1] * e[0]
    return u


@dataclass(frozen=True)
class Task:
    """A least-squares task ‖Φ ξ̈ − b‖²_W.

    Attributes:
        name: for logs and tests.
        jacobian: Φ, shape (r, n + 6).
        target: b = ẍ_r − Φ̇ ξ̇, shape (r,).
        weight: diagonal of W, shape (r,).
    """

    name: str
    jacobian: np.ndarray
    target: np.ndarray
    weight: np.ndarray


@dataclass(frozen=True)
class QPProblem:
    """min ½ xᵀPx + qᵀx  s.t.  A x = b,  lb ≤ x ≤ ub,  with x = (ξ̈, β).

    Attributes:
        P: Hessian, shape (nx, nx).
        q: linear term, shape (nx,).
        A: equality matrix, shape (ne, nx): 6 floating-base rows, then 6 per support foot.
        b: equality right-hand side, shape (ne,).
        lb: lower bounds (−inf for ξ̈, 0 for β), shape (nx,).
        ub: upper bounds (+inf), shape (nx,).
        nv: size of ξ̈ (n + 6).
        wrench_maps: U_k per support foot (world-axes wrench at the sole = U_k β_k).
        support: the support feet, in the order of their β blocks.
    """

    P: np.ndarray
    q: np.ndarray
    A: np.ndarray
    b: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    nv: int
    wrench_maps: tuple[np.ndarray, ...]
    support: tuple[int, ...]

    def solve(
        self, solver: str, initvals: np.ndarray | None = None, **options: object
    ) -> np.ndarray | None:
        """Solve with ``qpsolvers``; None when the solver finds no solution."""
        if solver not in qpsolvers.available_solvers:
            raise ValueError(
                f"QP solver {solver!r} is not installed; installed: "
                f"{', '.join(qpsolvers.available_solvers)} (pip install qpsolvers[{solver}])"
            )
        p, a = self.P, self.A
        if solver == "proxqp":
            options = {"backend": "dense", **options}  # our matrices are dense
        elif solver == "osqp":  # OSQP takes sparse matrices; converting here avoids a warning
            p, a = sparse.csc_matrix(p), sparse.csc_matrix(a)
        problem = qpsolvers.Problem(p, self.q, None, None, a, self.b, self.lb, self.ub)
        solution = qpsolvers.solve_problem(problem, solver=solver, initvals=initvals, **options)
        return solution.x if solution.found else None

    def split(self, x: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """ξ̈ and each support foot's contact wrench U_k β_k (world axes, at the sole)."""
        accel = x[: self.nv]
        wrenches, start = [], self.nv
        for u in self.wrench_maps:
            wrenches.append(u @ x[start : start + u.shape[1]])
            start += u.shape[1]
        return accel, wrenches


def build_qp(
    mass_matrix: np.ndarray,
    nonlinear: np.ndarray,
    momentum_target: np.ndarray,
    momentum_weight: np.ndarray,
    contact_jacobians: list[np.ndarray],
    contact_drifts: list[np.ndarray],
    wrench_maps: list[np.ndarray],
    support: tuple[int, ...],
    tasks: list[Task],
    accel_weight: float,
    force_weight: float,
) -> QPProblem:
    """Assemble the QP of §III-D.

    Args:
        mass_matrix: M, shape (nv, nv) (Pinocchio, base velocity in the base frame).
        nonlinear: C ξ̇ + g, shape (nv,).
        momentum_target: b_1 = X_GBᵀ ḣ_{G,r} − C_B ξ̇, shape (6,).
        momentum_weight: diagonal of W_1, shape (6,).
        contact_jacobians: J_k (sole frame, world axes) of each support foot, shape (6, nv).
        contact_drifts: J̇_k ξ̇ of each support foot, shape (6,).
        wrench_maps: R̃ U_k of each support foot, shape (6, m N_c).
        support: which feet these are (for bookkeeping).
        tasks: task-space acceleration tasks (swing foot Eq. 3, trunk, arms ...).
        accel_weight: W_3 (scalar times identity).
        force_weight: W_4 (scalar times identity).
    """
    nv = mass_matrix.shape[0]
    nb = sum(u.shape[1] for u in wrench_maps)
    nx = nv + nb
    # Cost rows: √W (Φ ξ̈ − b).
    rows = [np.sqrt(momentum_weight)[:, None] * mass_matrix[:6]]
    rhs = [np.sqrt(momentum_weight) * momentum_target]
    for task in tasks:
        sw = np.sqrt(task.weight)
        rows.append(sw[:, None] * task.jacobian)
        rhs.append(sw * task.target)
    a_cost = np.vstack(rows)
    b_cost = np.concatenate(rhs)
    p = np.zeros((nx, nx))
    p[:nv, :nv] = a_cost.T @ a_cost
    p[np.diag_indices(nv)] += accel_weight
    p[np.arange(nv, nx), np.arange(nv, nx)] += force_weight
    q = np.zeros(nx)
    q[:nv] = -a_cost.T @ b_cost

    ne = 6 + 6 * len(contact_jacobians)
    a_eq = np.zeros((ne, nx))
    b_eq = np.zeros(ne)
    a_eq[:6, :nv] = mass_matrix[:6]
    b_eq[:6] = -nonlinear[:6]
    col = nv
    for k, (jac, drift, u) in enumerate(
        zip(contact_jacobians, contact_drifts, wrench_maps, strict=True)
    ):
        a_eq[:6, col : col + u.shape[1]] = -jac[:, :6].T @ u
        a_eq[6 + 6 * k : 12 + 6 * k, :nv] = jac
        b_eq[6 + 6 * k : 12 + 6 * k] = -drift
        col += u.shape[1]
    lb = np.concatenate([np.full(nv, -np.inf), np.zeros(nb)])
    ub = np.full(nx, np.inf)
    return QPProblem(p, q, a_eq, b_eq, lb, ub, nv, tuple(wrench_maps), support)


def joint_torques(
    mass_matrix: np.ndarray,
    nonlinear: np.ndarray,
    accel: np.ndarray,
    contact_jacobians: list[np.ndarray],
    wrenches: list[np.ndarray],
) -> np.ndarray:
    """Eq. (9): τ = M_q ξ̈* + C_q ξ̇ + g_q − Σ_k J_{C_k}ᵀ λ*_k, shape (n,) [N m]."""
    tau = mass_matrix[6:] @ accel + nonlinear[6:]
    for jac, w in zip(contact_jacobians, wrenches, strict=True):
        tau -= jac[:, 6:].T @ w
    return tau
