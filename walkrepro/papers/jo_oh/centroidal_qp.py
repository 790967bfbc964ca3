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
returns an inspectable :class:`QPProblem` (its matrices are what any QP library takes; the
tests hand them to ``qpsolvers`` as the oracle); :meth:`QPProblem.solve` solves it exactly
by the active set of :mod:`.condensed`.

At 1 kHz the controller uses :class:`CentroidalQP` instead: the same problem, solved exactly
in one compiled call with ξ̈ and the equality rows eliminated (:mod:`.condensed`: 16 or 32
bounded variables instead of 60), warm-started from the support set's last β.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from walkrepro.papers.jo_oh.condensed import (
    CostRows,
    Dynamics,
    QPSolution,
    QPWeights,
    SupportContacts,
    compiled_entry,
    solve_centroidal,
    solve_eliminated,
)


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


def rotate_wrench_basis(rotation: np.ndarray, local: np.ndarray, out: np.ndarray) -> np.ndarray:
    """R̃_{C_k} U_k from U_k in the contact frame, written into ``out``.

    Rotations preserve cross products, R (d̃ × ū) = (R d̃) × (R ū), so the world-axes basis of
    :func:`contact_wrench_basis` is the contact-frame one with both halves rotated: one
    (3, 3) @ (2, 3, m N_c) product instead of rebuilding it.

    Args:
        rotation: world-from-contact-frame rotation R̃_{C_k}, shape (3, 3).
        local: ``contact_wrench_basis(np.eye(3), corners, basis)``, shape (6, m N_c).
        out: C-contiguous result, shape (6, m N_c).
    """
    np.matmul(rotation, local.reshape(2, 3, -1), out=out.reshape(2, 3, -1))
    return out


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

    def solve(self) -> np.ndarray | None:
        """Solve exactly by the active set with ξ̈ eliminated; None when it finds no solution.

        :func:`.condensed.solve_eliminated` needs the shape :func:`empty_qp` gives: q and P
        zero on β but for P's W_4 I, and β ≥ 0 its only bounds.
        """
        nv = self.nv
        x = np.zeros(self.q.size)
        force_weight = self.P[nv, nv] if self.q.size > nv else 1.0
        accel = x[:nv]  # a view: the kernel writes ξ̈ into x
        ok = solve_eliminated(
            self.P[:nv, :nv].copy(),
            self.q[:nv].copy(),
            np.ascontiguousarray(self.A[:, :nv]),
            np.ascontiguousarray(self.A[:, nv:]),
            self.b.copy(),
            force_weight,
            x[nv:],
            accel,
        )
        return x if ok >= 0 else None

    def split(self, x: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """ξ̈ and each support foot's contact wrench U_k β_k (world axes, at the sole)."""
        accel = x[: self.nv]
        wrenches, start = [], self.nv
        for u in self.wrench_maps:
            wrenches.append(u @ x[start : start + u.shape[1]])
            start += u.shape[1]
        return accel, wrenches


def build_qp(
    dynamics: Dynamics,
    momentum_target: np.ndarray,
    momentum_weight: np.ndarray,
    contacts: SupportContacts,
    support: tuple[int, ...],
    tasks: list[Task],
    weights: QPWeights,
) -> QPProblem:
    """Assemble the QP of §III-D.

    Args:
        dynamics: M (Pinocchio, base velocity in the base frame) and C ξ̇ + g.
        momentum_target: b_1 = X_GBᵀ ḣ_{G,r} − C_B ξ̇, shape (6,).
        momentum_weight: diagonal of W_1, shape (6,).
        contacts: J_k (sole frame, world axes), J̇_k ξ̇ and R̃ U_k of each support foot, per
            foot shapes (6, nv), (6,) and (6, m N_c) (stacked arrays or sequences).
        support: which feet these are (for bookkeeping).
        tasks: task-space acceleration tasks (swing foot Eq. 3, trunk, arms ...).
        weights: W_3 and W_4.
    """
    nv = dynamics.mass_matrix.shape[0]
    n_beta = tuple(u.shape[1] for u in contacts.wrench_maps)
    problem = empty_qp(nv, n_beta, support, weights.force)
    # Cost rows: √W (Φ ξ̈ − b).
    rows = [np.sqrt(momentum_weight)[:, None] * dynamics.mass_matrix[:6]]
    rhs = [np.sqrt(momentum_weight) * momentum_target]
    for task in tasks:
        sw = np.sqrt(task.weight)
        rows.append(sw[:, None] * task.jacobian)
        rhs.append(sw * task.target)
    assemble_qp(
        problem, dynamics, CostRows(np.vstack(rows), np.concatenate(rhs)), contacts, weights.accel
    )
    return problem


def empty_qp(
    nv: int, n_beta: tuple[int, ...], support: tuple[int, ...], force_weight: float
) -> QPProblem:
    """A :class:`QPProblem` of the given shape with its constant parts filled in.

    Constant: the β block of P (W_4 I), the bounds (ξ̈ free, β ≥ 0) and the zeros of q and A
    outside the blocks :func:`assemble_qp` writes.

    Args:
        nv: size of ξ̈.
        n_beta: number of pyramid coefficients m N_c of each support foot.
        support: the support feet, in the order of their β blocks.
        force_weight: W_4 (scalar times identity).
    """
    nb = sum(n_beta)
    nx = nv + nb
    p = np.zeros((nx, nx))
    p[np.arange(nv, nx), np.arange(nv, nx)] = force_weight
    ne = 6 + 6 * len(n_beta)
    lb = np.concatenate([np.full(nv, -np.inf), np.zeros(nb)])
    ub = np.full(nx, np.inf)
    maps = tuple(np.zeros((6, m)) for m in n_beta)
    return QPProblem(p, np.zeros(nx), np.zeros((ne, nx)), np.zeros(ne), lb, ub, nv, maps, support)


def assemble_qp(
    problem: QPProblem,
    dynamics: Dynamics,
    cost: CostRows,
    contacts: SupportContacts,
    accel_weight: float,
) -> None:
    """Write the tick-dependent blocks of the §III-D QP into ``problem`` (from :func:`empty_qp`).

    P_ξξ = AᵀA + W_3 I and q_ξ = −Aᵀb for the stacked weighted cost rows A ξ̈ ≈ b (momentum
    rows √W_1 M_B, b = √W_1 b_1, then the tasks √W_t Φ_t, √W_t b_t; zero rows add nothing);
    the equality rows of Eq. (5) and of the support feet; ``problem.wrench_maps`` the R̃ U_k.

    Args:
        problem: the problem to fill in place.
        dynamics: M and C ξ̇ + g.
        cost: stacked √W Φ rows, shape (r, nv), and √W b, shape (r,).
        contacts: J_k, J̇_k ξ̇ and R̃ U_k of each support foot (as :func:`build_qp`).
        accel_weight: W_3 (scalar times identity).
    """
    nv = problem.nv
    for out, u in zip(problem.wrench_maps, contacts.wrench_maps, strict=True):
        out[:] = u
    hess = cost.rows.T @ cost.rows
    hess.reshape(-1)[:: nv + 1] += accel_weight  # a view: hess is contiguous
    problem.P[:nv, :nv] = hess
    np.negative(cost.rhs @ cost.rows, out=problem.q[:nv])
    a_eq, b_eq = problem.A, problem.b
    a_eq[:6, :nv] = dynamics.mass_matrix[:6]
    np.negative(dynamics.nonlinear[:6], out=b_eq[:6])
    col, row = nv, 6
    for jac, drift, u in zip(contacts.jacobians, contacts.drifts, problem.wrench_maps, strict=True):
        m = u.shape[1]
        np.negative(jac[:, :6].T @ u, out=a_eq[:6, col : col + m])
        a_eq[row : row + 6, :nv] = jac
        np.negative(drift, out=b_eq[row : row + 6])
        col += m
        row += 6


class CentroidalQP:
    """The QP of §III-D for one support set, in preallocated arrays, solved tick after tick.

    The QP is solved exactly with ξ̈ and the equality rows eliminated (:mod:`.condensed`, one
    compiled call that also applies Eq. 9), warm-started from the set's last β.

    Args:
        nv: size of ξ̈.
        support: the support feet, in the order of their β blocks.
        local_maps: U_k of each support foot in its contact frame, shape (6, m N_c)
            (``contact_wrench_basis(np.eye(3), ...)``).
        accel_weight: W_3 (scalar times identity).
        force_weight: W_4 (scalar times identity).

    Attributes:
        problem: the full problem, filled in by :meth:`build` (for inspection).
        accel: ξ̈* of the last successful :meth:`solve`, shape (nv,).
        wrenches: U_k β*_k of each support foot (world axes, at the sole), shape (k, 6).
        tau: Eq. (9) joint torques of the last successful :meth:`solve`, shape (nv − 6,).
    """

    def __init__(
        self,
        nv: int,
        support: tuple[int, ...],
        local_maps: list[np.ndarray],
        accel_weight: float,
        force_weight: float,
    ) -> None:
        n_feet, m = len(local_maps), local_maps[0].shape[1]
        self.problem = empty_qp(nv, tuple(u.shape[1] for u in local_maps), support, force_weight)
        self._local_maps = [np.ascontiguousarray(u) for u in local_maps]
        self._weights = QPWeights(accel_weight, force_weight)
        # Stacks per support foot that :meth:`update` fills for the compiled kernel.
        self._stacks = SupportContacts(
            np.zeros((n_feet, 6, nv)), np.zeros((n_feet, 6)), np.zeros((n_feet, 6, m))
        )
        self.accel = np.zeros(nv)
        self.wrenches = np.zeros((n_feet, 6))
        self.tau = np.zeros(nv - 6)
        self._solution = QPSolution(np.zeros(n_feet * m), self.accel, self.wrenches, self.tau)
        # This tick's inputs (:meth:`set_inputs`) and the kernel to call on them: until then
        # empty inputs and the dispatcher, which compiles nothing before it is called.
        empty = Dynamics(np.zeros((nv, nv)), np.zeros(nv)), CostRows(np.zeros((0, nv)), np.zeros(0))
        self._kernel_args = (empty[1], empty[0], self._stacks, self._weights, self._solution)
        self._kernel = solve_centroidal

    def update(
        self,
        dynamics: Dynamics,
        cost: CostRows,
        contact_jacobians: list[np.ndarray],
        contact_drifts: list[np.ndarray],
        contact_rotations: list[np.ndarray],
    ) -> None:
        """Take this tick's inputs (as :func:`assemble_qp`; J_k, J̇_k ξ̇ and R̃_{C_k} per foot).

        The arrays are referenced, not copied, except the per-foot ones, which are stacked.
        """
        jacobians, drifts, maps = self._stacks
        for k, (jac, drift, rot) in enumerate(
            zip(contact_jacobians, contact_drifts, contact_rotations, strict=True)
        ):
            jacobians[k] = jac
            drifts[k] = drift
            rotate_wrench_basis(rot, self._local_maps[k], maps[k])
        self.set_inputs(dynamics, CostRows(np.ascontiguousarray(cost.rows), cost.rhs), self._stacks)

    def set_inputs(self, dynamics: Dynamics, cost: CostRows, contacts: SupportContacts) -> None:
        """Take this tick's inputs already stacked per support foot, by reference (no copies).

        Args:
            dynamics: M and C ξ̇ + g.
            cost: the stacked weighted cost rows (``rows`` C-contiguous).
            contacts: J_k (C-contiguous), J̇_k ξ̇ and R̃_{C_k} U_k of each support foot.
        """
        # One tuple for the compiled call, and the kernel's entry for its types: a caller
        # whose inputs stay the same arrays (filled in place each tick) sets them once, and
        # :meth:`solve` neither looks up attributes nor has numba check the records' types.
        self._kernel_args = (cost, dynamics, contacts, self._weights, self._solution)
        self._kernel = compiled_entry(solve_centroidal, *self._kernel_args)

    def build(self) -> QPProblem:
        """The full problem of this tick's inputs (as :func:`build_qp`), for inspection."""
        cost, dynamics, contacts, weights, _ = self._kernel_args
        assemble_qp(self.problem, dynamics, cost, contacts, weights.accel)
        return self.problem

    def solve(self, warm: bool) -> bool:
        """Solve this tick's problem; ``warm`` starts from this set's last solution.

        Returns:
            Whether a solution was found (then in :attr:`accel`, :attr:`wrenches`, :attr:`tau`).
        """
        if not warm:
            self._solution.beta[:] = 0.0  # cold: every β at its bound
        return self._kernel(*self._kernel_args) >= 0


def joint_torques(
    mass_matrix: np.ndarray,
    nonlinear: np.ndarray,
    accel: np.ndarray,
    contact_jacobians: Sequence[np.ndarray],
    wrenches: Sequence[np.ndarray],
) -> np.ndarray:
    """Eq. (9): τ = M_q ξ̈* + C_q ξ̇ + g_q − Σ_k J_{C_k}ᵀ λ*_k, shape (n,) [N m]."""
    tau = mass_matrix[6:] @ accel + nonlinear[6:]
    for jac, w in zip(contact_jacobians, wrenches, strict=True):
        tau -= jac[:, 6:].T @ w
    return tau
