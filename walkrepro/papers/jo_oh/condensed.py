"""The §III-D QP solved exactly in its condensed form: ξ̈ and the equalities eliminated.

The QP of :mod:`.centroidal_qp` is

    min ½ ξ̈ᵀ P ξ̈ + qᵀ ξ̈ + ½ W_4 ‖β‖²   s.t.   E ξ̈ = f + G β,   β ≥ 0,

with P = AᵀA + W_3 I (A: the stacked weighted cost rows, q = −Aᵀb), E = [M_B; J_1; J_2]
(floating-base rows of Eq. 5, then the support feet), f = [−(C ξ̇ + g)_B; −J̇_k ξ̇] and
G = [J_{k,B}ᵀ U_k; 0]. P is positive definite (W_3 > 0), so for a fixed β the best ξ̈ is
ξ̈ = P⁻¹(Eᵀν − q) with ν = S⁻¹(r + Gβ), S = E P⁻¹ Eᵀ, r = f + E P⁻¹ q, and the QP
becomes, exactly, one in β alone with only the bounds:

    min ½ βᵀ (Gᵀ S⁻¹ G + W_4 I) β + (Gᵀ S⁻¹ r)ᵀ β   s.t.   β ≥ 0.

That is 16 or 32 variables instead of 60, and no equality rows. A primal active-set method
solves it to machine precision (not to a tolerance), warm-started from the previous tick's
β, whose active set rarely changes; two Cholesky factors (P, S) and a few small products
do the rest. Same problem, same unique minimiser: only the solver's error differs from a
library solver's, rounding instead of a tolerance (ProxQP's ``eps_abs``; the tests check the
two agree).

Why numba: at 1 kHz a tick has ≈ 200 µs for everything. Written with numpy this is a few
hundred calls on matrices of 6 to 60 rows, each paying about 1 µs of call overhead; one
compiled call does the same arithmetic in a few µs. The kernels are plain loops and small
products, compiled once and cached on disk (``cache=True``); :func:`warm_up` compiles them
when the controller resets, so the first tick is not slow.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numba
import numpy as np

#: Iterations of the active-set method per variable before it gives up (it never has).
MAX_ITER_PER_VARIABLE = 4
#: A bound leaves the active set only if its multiplier is below −this [same units as the
#: gradient]. Rounding sits orders below; ProxQP's tolerance (1e-6) orders above.
MULTIPLIER_TOL = 1e-10


# Records the compiled kernels take (named tuples: numba passes them without copies and
# reads their fields as cheaply as separate arguments).
class CostRows(NamedTuple):
    """The stacked weighted cost rows A ξ̈ ≈ b of the §III-D QP: A = √W Φ, b = √W (ẍ_r − Φ̇ ξ̇).

    Attributes:
        rows: A, shape (r, nv), C-contiguous.
        rhs: b, shape (r,).
    """

    rows: np.ndarray
    rhs: np.ndarray


class Dynamics(NamedTuple):
    """Pinocchio's joint-space dynamics terms of Eq. (5) (base velocity in the base frame).

    Attributes:
        mass_matrix: M, shape (nv, nv) [kg, kg m, kg m²].
        nonlinear: C ξ̇ + g, shape (nv,) [N, N m].
    """

    mass_matrix: np.ndarray
    nonlinear: np.ndarray


class SupportContacts(NamedTuple):
    """The support feet's contact terms, stacked per foot in the order of their β blocks.

    Attributes:
        jacobians: J_k (sole frame, world axes), shape (k, 6, nv).
        drifts: J̇_k ξ̇, shape (k, 6) [m/s², rad/s²].
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


class QPSolution(NamedTuple):
    """The §III-D QP's solution and its Eq. (9) torques, written in place.

    Attributes:
        beta: β, the pyramid coefficients, shape (k m N_c,); read as the start (≥ 0; zeros
            for a cold start), overwritten with β*.
        accel: ξ̈*, shape (nv,).
        wrenches: U_k β*_k of each support foot (world axes, at the sole), shape (k, 6).
        tau: Eq. (9) joint torques, shape (nv − 6,) [N m].
    """

    beta: np.ndarray
    accel: np.ndarray
    wrenches: np.ndarray
    tau: np.ndarray


def compiled_entry(kernel: Any, *args: Any) -> Callable[..., Any]:
    """``kernel``'s compiled entry for the types of ``args`` (compiled or loaded from the cache).

    A numba dispatcher finds the types of every argument on every call: cheap for arrays
    and numbers, ≈ 0.2 µs per field for a named tuple (in Python). A tick whose records are
    the same objects every tick looks that up once, here, and calls the entry directly. The
    entry checks no types: call it only with arguments of the types of ``args`` (the same
    records, and arrays of the same dtype, dimension and layout).
    """
    return kernel.compile(tuple(kernel.typeof_pyval(a) for a in args))


@numba.njit(cache=True)
def cholesky_in_place(a: np.ndarray) -> bool:
    """Overwrite the lower triangle of symmetric ``a`` with L, a = L Lᵀ; False if not PD."""
    n = a.shape[0]
    for j in range(n):
        s = a[j, j]
        for k in range(j):
            s -= a[j, k] * a[j, k]
        if not s > 0.0:
            return False
        d = np.sqrt(s)
        a[j, j] = d
        for i in range(j + 1, n):
            s = a[i, j]
            for k in range(j):
                s -= a[i, k] * a[j, k]
            a[i, j] = s / d
    return True


@numba.njit(cache=True)
def solve_lower(low: np.ndarray, b: np.ndarray) -> None:
    """b ← L⁻¹ b for lower-triangular L (the lower triangle of ``low``), b of shape (n, m)."""
    n, m = b.shape
    for i in range(n):
        for k in range(i):
            c = low[i, k]
            for j in range(m):
                b[i, j] -= c * b[k, j]
        d = low[i, i]
        for j in range(m):
            b[i, j] /= d


@numba.njit(cache=True)
def solve_lower_transposed(low: np.ndarray, b: np.ndarray) -> None:
    """b ← L⁻ᵀ b for lower-triangular L (the lower triangle of ``low``), b of shape (n, m)."""
    n, m = b.shape
    for i in range(n - 1, -1, -1):
        for k in range(i + 1, n):
            c = low[k, i]
            for j in range(m):
                b[i, j] -= c * b[k, j]
        d = low[i, i]
        for j in range(m):
            b[i, j] /= d


@numba.njit(cache=True)
def solve_lower_vector(low: np.ndarray, b: np.ndarray) -> None:
    """b ← L⁻¹ b for one right-hand side, b of shape (n,).

    The same operations, in the same order, as :func:`solve_lower` on one column (so the same
    result to the bit), written for a vector: on an (n, 1) matrix the column loop of
    :func:`solve_lower` costs ≈ 3× the arithmetic.
    """
    for i in range(b.shape[0]):
        s = b[i]
        for k in range(i):
            s -= low[i, k] * b[k]
        b[i] = s / low[i, i]


@numba.njit(cache=True)
def solve_lower_transposed_vector(low: np.ndarray, b: np.ndarray) -> None:
    """b ← L⁻ᵀ b for one right-hand side, b of shape (n,) (as :func:`solve_lower_vector`)."""
    n = b.shape[0]
    for i in range(n - 1, -1, -1):
        s = b[i]
        for k in range(i + 1, n):
            s -= low[k, i] * b[k]
        b[i] = s / low[i, i]


@numba.njit(cache=True)
def nonnegative_qp(hess: np.ndarray, grad: np.ndarray, x: np.ndarray, max_iter: int) -> int:
    """min ½ xᵀHx + gᵀx s.t. x ≥ 0 for positive definite H, by a primal active-set method.

    Nocedal & Wright, Algorithm 16.3, for bounds: minimise over the free variables with the
    others at 0; step back to the first bound crossed, or, at a feasible subspace minimum,
    free the bound with the most negative multiplier (H x + g)_i until none is negative.

    Args:
        hess: H, shape (n, n).
        grad: g, shape (n,).
        x: start (x ≥ 0; its positive entries are the first free set), overwritten with the
            minimiser.
        max_iter: iterations before giving up.

    Returns:
        The iterations taken, or −1 if it did not converge (x is then feasible, not optimal).
    """
    n = grad.size
    free = x > 0.0
    sub = np.empty((n, n))
    rhs = np.empty(n)
    idx = np.empty(n, dtype=np.int64)
    y = np.empty(n)
    for it in range(max_iter):
        nf = 0
        for i in range(n):
            if free[i]:
                idx[nf] = i
                nf += 1
        for a in range(nf):
            for b in range(a + 1):
                sub[a, b] = hess[idx[a], idx[b]]
            rhs[a] = -grad[idx[a]]
        low, r = sub[:nf, :nf], rhs[:nf]
        if not cholesky_in_place(low):
            return -1
        solve_lower_vector(low, r)
        solve_lower_transposed_vector(low, r)
        y[:] = 0.0
        for a in range(nf):
            y[idx[a]] = r[a]
        alpha, blocking = 1.0, -1
        for a in range(nf):
            i = idx[a]
            if y[i] < 0.0:
                step = x[i] / (x[i] - y[i])
                if step < alpha:
                    alpha, blocking = step, i
        if blocking >= 0:  # the subspace minimum is infeasible: go as far as feasible
            for i in range(n):
                x[i] = max(x[i] + alpha * (y[i] - x[i]), 0.0)
            x[blocking] = 0.0
            free[blocking] = False
            continue
        x[:] = y
        entering, most_negative = -1, -MULTIPLIER_TOL
        for i in range(n):
            if not free[i]:
                lam = grad[i]
                for j in range(n):
                    lam += hess[i, j] * x[j]
                if lam < most_negative:
                    entering, most_negative = i, lam
        if entering < 0:
            return it + 1
        free[entering] = True
    return -1


@numba.njit(cache=True)
def solve_eliminated(
    hess_accel: np.ndarray,
    grad_accel: np.ndarray,
    eq_accel: np.ndarray,
    eq_beta: np.ndarray,
    eq_rhs: np.ndarray,
    force_weight: float,
    beta: np.ndarray,
    accel: np.ndarray,
) -> int:
    """min ½ ξ̈ᵀPξ̈ + qᵀξ̈ + ½ W_4 ‖β‖²  s.t.  E ξ̈ + F β = f,  β ≥ 0, with ξ̈ eliminated.

    For a fixed β the minimiser is ξ̈ = P⁻¹(Eᵀν − q), ν = S⁻¹(r − Fβ), with S = E P⁻¹ Eᵀ and
    r = f + E P⁻¹ q, which leaves min ½ βᵀ(FᵀS⁻¹F + W_4 I)β − (FᵀS⁻¹r)ᵀβ, β ≥ 0.

    Args:
        hess_accel: P, positive definite, shape (nv, nv); overwritten with its Cholesky factor.
        grad_accel: q, shape (nv,).
        eq_accel: E, full row rank, shape (ne, nv).
        eq_beta: F, shape (ne, nb).
        eq_rhs: f, shape (ne,).
        force_weight: W_4 > 0.
        beta: start (≥ 0; zeros for a cold start), shape (nb,); overwritten with β*.
        accel: out, ξ̈*, shape (nv,).

    Returns:
        The active-set iterations, or −1 if a factorisation failed or the method did not
        converge (the outputs are then not to be used).
    """
    return _solve_condensed(
        hess_accel,
        grad_accel,
        np.ascontiguousarray(eq_accel.T),
        eq_beta.copy(),
        eq_rhs,
        force_weight,
        beta,
        accel,
    )


@numba.njit(cache=True)
def _solve_condensed(
    hess_accel: np.ndarray,
    grad_accel: np.ndarray,
    eq_accel_t: np.ndarray,
    eq_beta: np.ndarray,
    eq_rhs: np.ndarray,
    force_weight: float,
    beta: np.ndarray,
    accel: np.ndarray,
) -> int:
    """:func:`solve_eliminated` on Eᵀ (C-contiguous, shape (nv, ne)) and F, both overwritten
    (Eᵀ with Y = L⁻¹Eᵀ, F with L_S⁻¹F): :func:`solve_centroidal` builds them in place."""
    nv, ne, nb = hess_accel.shape[0], eq_accel_t.shape[1], eq_beta.shape[1]
    if not cholesky_in_place(hess_accel):  # P = L Lᵀ
        return -1
    # z, r, ν stay (n, 1) matrices where BLAS multiplies them (the same gemm calls, so the
    # same floats); the triangular solves take their column as a vector.
    z = np.empty((nv, 1))
    z[:, 0] = grad_accel
    solve_lower_vector(hess_accel, z[:, 0])  # z = L⁻¹ q
    y = eq_accel_t
    solve_lower(hess_accel, y)  # Y = L⁻¹ Eᵀ
    chol_s = y.T @ y  # S = YᵀY
    r = y.T @ z  # r = f + Yᵀz
    for i in range(ne):
        r[i, 0] += eq_rhs[i]
    if not cholesky_in_place(chol_s):
        return -1
    zf = eq_beta
    solve_lower(chol_s, zf)  # Z = L_S⁻¹ F
    solve_lower_vector(chol_s, r[:, 0])  # L_S⁻¹ r
    hess = zf.T @ zf
    for i in range(nb):
        hess[i, i] += force_weight
    grad = -(zf.T @ r)[:, 0]
    iterations = nonnegative_qp(hess, grad, beta, MAX_ITER_PER_VARIABLE * max(nb, 1))
    if iterations < 0:
        return -1
    nu = r - zf @ beta.reshape(-1, 1)
    solve_lower_transposed_vector(chol_s, nu[:, 0])  # ν = L_S⁻ᵀ (L_S⁻¹ r − Z β)
    a = y @ nu - z
    solve_lower_transposed_vector(hess_accel, a[:, 0])  # ξ̈ = L⁻ᵀ (Y ν − z)
    accel[:] = a[:, 0]
    return iterations


@numba.njit(cache=True)
def solve_centroidal(
    cost: CostRows,
    dynamics: Dynamics,
    contacts: SupportContacts,
    weights: QPWeights,
    solution: QPSolution,
) -> int:
    """The §III-D QP of :func:`.centroidal_qp.build_qp`, solved eliminated, and Eq. (9).

    Args:
        cost: the stacked weighted cost rows A = √W Φ (C-contiguous) and √W b.
        dynamics: M and C ξ̇ + g.
        contacts: J_k, J̇_k ξ̇ and R̃ U_k of each support foot.
        weights: W_3 and W_4.
        solution: β start (≥ 0; zeros for a cold start), overwritten with β*; out, ξ̈*, the
            wrenches U_k β*_k (world axes, at the sole) and the Eq. (9) torques τ [N m].

    Returns:
        As :func:`solve_eliminated`.
    """
    cost_rows, cost_rhs = cost.rows, cost.rhs
    mass_matrix, nonlinear = dynamics.mass_matrix, dynamics.nonlinear
    jacobians, drifts, wrench_maps = contacts.jacobians, contacts.drifts, contacts.wrench_maps
    accel_weight, force_weight = weights.accel, weights.force
    beta, accel, wrenches, tau = solution.beta, solution.accel, solution.wrenches, solution.tau
    nv = mass_matrix.shape[0]
    n_feet, m = wrench_maps.shape[0], wrench_maps.shape[2]
    ne = 6 + 6 * n_feet
    # P = AᵀA + W_3 I and q = −Aᵀb (assemble_qp).
    hess_accel = cost_rows.T @ cost_rows
    for i in range(nv):
        hess_accel[i, i] += accel_weight
    grad_accel = -(cost_rhs @ cost_rows)
    # Floating-base rows of Eq. (5), M_B ξ̈ − Σ J_{k,B}ᵀ U_k β_k = −(C ξ̇ + g)_B, then the
    # support feet, J_k ξ̈ = −J̇_k ξ̇; E is built transposed, as the elimination uses it.
    eq_accel_t = np.empty((nv, ne))
    eq_beta = np.zeros((ne, n_feet * m))
    eq_rhs = np.empty(ne)
    for j in range(nv):
        for i in range(6):
            eq_accel_t[j, i] = mass_matrix[i, j]
        for k in range(n_feet):
            for i in range(6):
                eq_accel_t[j, 6 + 6 * k + i] = jacobians[k, i, j]
    eq_rhs[:6] = -nonlinear[:6]
    for k in range(n_feet):
        eq_rhs[6 + 6 * k : 12 + 6 * k] = -drifts[k]
        for i in range(6):
            for c in range(m):
                s = 0.0
                for j in range(6):
                    s += jacobians[k, j, i] * wrench_maps[k, j, c]
                eq_beta[i, k * m + c] = -s
    iterations = _solve_condensed(
        hess_accel, grad_accel, eq_accel_t, eq_beta, eq_rhs, force_weight, beta, accel
    )
    if iterations < 0:
        return -1
    # Eq. (9): τ = M_q ξ̈* + C_q ξ̇ + g_q − Σ_k J_{C_k,q}ᵀ λ*_k.
    # (Written as loops: Pinocchio's M is column-major, which numba's `@` takes slowly.)
    for k in range(n_feet):
        wrenches[k] = wrench_maps[k] @ beta[k * m : (k + 1) * m]
    for i in range(nv - 6):
        s = nonlinear[6 + i]
        for j in range(nv):
            s += mass_matrix[6 + i, j] * accel[j]
        for k in range(n_feet):
            for j in range(6):
                s -= jacobians[k, j, 6 + i] * wrenches[k, j]
        tau[i] = s
    return iterations


def warm_up() -> None:
    """Compile (or load from the cache) the kernels with the argument types a tick uses."""
    nv, m = 20, 2
    rng = np.random.default_rng(0)
    # Pinocchio's M is column-major (as in the controller); the tests' copies are row-major.
    for n_feet, mass in ((1, np.asfortranarray(np.eye(nv))), (2, np.asfortranarray(np.eye(nv)))):
        solve_centroidal(
            CostRows(np.ascontiguousarray(rng.standard_normal((30, nv))), rng.standard_normal(30)),
            Dynamics(mass, rng.standard_normal(nv)),
            SupportContacts(
                rng.standard_normal((n_feet, 6, nv)),
                np.zeros((n_feet, 6)),
                rng.standard_normal((n_feet, 6, m)),
            ),
            QPWeights(1e-4, 1e-6),
            QPSolution(np.zeros(n_feet * m), np.empty(nv), np.empty((n_feet, 6)), np.empty(nv - 6)),
        )
