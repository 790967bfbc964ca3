"""The ``active_set`` solver of the §III-D QP: exact, with ξ̈ and the equalities eliminated.

The QP that :func:`.centroidal_qp.build_qp` builds is

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
library solver's, rounding instead of a tolerance (the tests check it against DAQP, quadprog
and ProxQP through ``qpsolvers``, and its KKT residuals). It stays beside the ``qpsolvers``
backends because it is faster on this problem by more than a tenth of a control tick
(``docs/performance.md``).

Why numba: at 1 kHz a tick has ≈ 200 µs for everything. Written with numpy this is a few
hundred calls on matrices of 6 to 60 rows, each paying about 1 µs of call overhead; one
compiled call does the same arithmetic in a few µs. The kernels are plain loops and small
products, compiled once and cached on disk (``cache=True``); the controller compiles them
when it resets, so the first tick is not slow.
"""

from __future__ import annotations

import numba
import numpy as np

#: Iterations of the active-set method per variable before it gives up (it never has).
MAX_ITER_PER_VARIABLE = 4
#: A bound leaves the active set only if its multiplier is below −this [same units as the
#: gradient]. Rounding sits orders below; ProxQP's tolerance (1e-6) orders above.
MULTIPLIER_TOL = 1e-10


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
    (Eᵀ with Y = L⁻¹Eᵀ, F with L_S⁻¹F): :func:`solve_eliminated` makes them."""
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
