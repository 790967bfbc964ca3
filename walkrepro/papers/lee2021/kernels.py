"""Compiled per-tick kernels of the E-FSM controller: the OS-WBC of Lee et al. 2021.

One control tick of the OS-WBC (Appendices A–D) is about fifty products, inverses and
projections of matrices with 1 to 18 rows. Written with numpy, each call costs 1–5 µs of
overhead, far more than its arithmetic: the tick took ≈ 150 µs, which held the 2 kHz
experiments near real time. Why numba: fused into one compiled call the same algebra takes
a few µs, with no C extension to build. The kernels are the implementation; they follow the
readable numpy reference kept as a test oracle, ``tests/oracles/efsm_wbc.py`` (checked against
Pinocchio's constrained dynamics), step by step, and ``tests/test_efsm_kernels.py`` checks that
they agree with it. ``cache=True`` keeps the
machine code on disk, so only the first process compiles; the controller's reset compiles
or loads them with two throwaway ticks.

The whole tick after Pinocchio's ``computeAllTerms`` is one call, :func:`tick`: the frames,
O_w, the E-FSM (its reference is the oracle ``tests/oracles/efsm_fsm.py``), the footstep
planner, A⁻¹ and J̇_c q̇ (in Pinocchio's operations, tested against it to 1e-12), Γ and the
CoPs. Python around it cost more than the
algebra: each numba call pays ≈ 50 ns per array argument (hence :func:`tick_state`, one
record for the controller's own arrays, and :class:`PinocchioViews`, one for the views of
Pinocchio's ``Data``, made once), a Pinocchio call ≈ 1 µs, a line of Python ≈ 0.1 µs.
Records the kernels pass each other (:class:`WbcDynamics`, :class:`FsmParams`, …) are
named tuples built in compiled code, where they cost nothing. Inside, temporary arrays are kept few: each is an allocation, and at 2 kHz
between MuJoCo steps little of the tick's memory is still in cache.

Matrices here are small, so products are plain loops: they take any memory layout
(Pinocchio's arrays are column-major views) without copies, and cost less than a BLAS call.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
from numba.core import types
from numba.experimental import structref

from walkrepro.robot import (
    eigen_rotate,
    frame_classical_acceleration,
    frame_jacobian,
    log3_entries,
)

#: Rows of the two stacked foot wrenches other than the normal forces (Appendix C).
TANGENTIAL_ROWS = np.array([0, 1, 3, 4, 5, 6, 7, 9, 10, 11])
#: Relative singular-value cut-off of the pseudo-inverses (W is rank-deficient in DS).
PINV_RCOND = 1e-9
#: numpy's default cut-off of ``lstsq`` (rcond=None) for the 10 × 6 problem of Appendix C.
_LSTSQ_RCOND = float(np.finfo(np.float64).eps) * 10

#: Compiled, cached on disk; float division by zero gives inf/NaN as in numpy (which the
#: tests of singular matrices rely on) rather than raising.
_jit = numba.njit(cache=True, error_model="numpy")

# Phases of fsm.Phase, as plain ints for the compiled code.
_SSD, _SSA, _DS = 0, 1, 2


# ---- small dense algebra ------------------------------------------------------------------


@_jit
def matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a @ b, for a finite b.

    Zero entries of ``a`` are skipped: the tick's Jacobians are a third zeros (joints off a
    foot's chain), and with every sum starting at +0.0 a ±0 term changes no bit of it (it
    would only turn an inf or NaN of ``b`` into NaN).
    """
    n, m, p = a.shape[0], a.shape[1], b.shape[1]
    out = np.zeros((n, p))
    for i in range(n):
        for k in range(m):
            a_ik = a[i, k]
            if a_ik == 0.0:
                continue
            for j in range(p):
                out[i, j] += a_ik * b[k, j]
    return out


@_jit
def matmul_bt(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a @ bᵀ."""
    n, m, p = a.shape[0], a.shape[1], b.shape[0]
    out = np.empty((n, p))
    for i in range(n):
        for j in range(p):
            acc = 0.0
            for k in range(m):
                acc += a[i, k] * b[j, k]
            out[i, j] = acc
    return out


@_jit
def matvec(a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """a @ x."""
    n, m = a.shape
    out = np.empty(n)
    for i in range(n):
        acc = 0.0
        for k in range(m):
            acc += a[i, k] * x[k]
        out[i] = acc
    return out


@_jit
def _lu_solve_in_place(lu: np.ndarray, x: np.ndarray) -> None:
    """x ← lu⁻¹ x for x of shape (n, p), LU with partial pivoting (as LAPACK's gesv).

    ``lu`` is overwritten by the factors: callers pass copies they own (a tick solves about
    ten systems, and each copy is an allocation). An exactly singular matrix gives
    infs/NaNs rather than an error, like the numpy kernels the reference uses, so callers
    can test the result.
    """
    n, p = lu.shape[0], x.shape[1]
    for col in range(n):
        piv = col
        for r in range(col + 1, n):
            if abs(lu[r, col]) > abs(lu[piv, col]):
                piv = r
        if piv != col:
            for j in range(n):
                lu[col, j], lu[piv, j] = lu[piv, j], lu[col, j]
            for j in range(p):
                x[col, j], x[piv, j] = x[piv, j], x[col, j]
        pivot = lu[col, col]
        for r in range(col + 1, n):
            f = lu[r, col] / pivot
            lu[r, col] = f
            for j in range(col + 1, n):
                lu[r, j] -= f * lu[col, j]
            for j in range(p):
                x[r, j] -= f * x[col, j]
    for col in range(n - 1, -1, -1):  # back substitution, row operations (vectorize)
        pivot = lu[col, col]
        for j in range(p):
            x[col, j] /= pivot
        for r in range(col):
            f = lu[r, col]
            for j in range(p):
                x[r, j] -= f * x[col, j]


@_jit
def inverse(a: np.ndarray) -> np.ndarray:
    """a⁻¹ (infs/NaNs if a is singular)."""
    return _invert(a.copy())


@_jit
def _invert(a: np.ndarray) -> np.ndarray:
    """a⁻¹ of a temporary ``a``, which is overwritten (one copy fewer than :func:`inverse`)."""
    x = np.eye(a.shape[0])
    _lu_solve_in_place(a, x)
    return x


@_jit
def solve_vec(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a⁻¹ b for a vector b (infs/NaNs if a is singular)."""
    x = b.copy().reshape((b.shape[0], 1))
    _lu_solve_in_place(a.copy(), x)
    return x[:, 0]


@_jit
def _any_nonzero(x: np.ndarray) -> bool:
    """np.any(x != 0.0) without the temporary array."""
    for i in range(x.shape[0]):
        if x[i] != 0.0:
            return True
    return False


@_jit
def lstsq(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """argmin ‖a x − b‖ for a tall a (m ≥ n), as ``np.linalg.lstsq(a, b, rcond=None)[0]``.

    Householder QR: for a of full column rank the minimizer is unique, so it equals
    LAPACK's SVD-based one up to rounding, at a fraction of the cost. A nearly
    rank-deficient a (a diagonal entry of R below 1e-8 of the largest) goes to
    ``np.linalg.lstsq`` itself, whose cut-off then decides.
    """
    m, n = a.shape
    r = a.copy()
    y = b.copy()
    v = np.empty(m)
    for k in range(n):
        norm = 0.0
        for i in range(k, m):
            norm += r[i, k] * r[i, k]
        norm = math.sqrt(norm)
        if norm == 0.0:
            return np.linalg.lstsq(a, b, _LSTSQ_RCOND)[0]
        alpha = -norm if r[k, k] >= 0.0 else norm  # reflect away from r[k, k]: no cancellation
        for i in range(k, m):
            v[i] = r[i, k]
        v[k] -= alpha
        v_sq = 0.0
        for i in range(k, m):
            v_sq += v[i] * v[i]
        for j in range(k, n):  # H = I − 2 v vᵀ / (vᵀ v) on the remaining columns and on b
            dot = 0.0
            for i in range(k, m):
                dot += v[i] * r[i, j]
            f = 2.0 * dot / v_sq
            for i in range(k, m):
                r[i, j] -= f * v[i]
        dot = 0.0
        for i in range(k, m):
            dot += v[i] * y[i]
        f = 2.0 * dot / v_sq
        for i in range(k, m):
            y[i] -= f * v[i]
    diag = np.abs(np.diag(r[:n, :n]))
    if diag.min() <= 1e-8 * diag.max():
        return np.linalg.lstsq(a, b, _LSTSQ_RCOND)[0]
    x = np.empty(n)
    for k in range(n - 1, -1, -1):  # R x = Qᵀ b
        acc = y[k]
        for j in range(k + 1, n):
            acc -= r[k, j] * x[j]
        x[k] = acc / r[k, k]
    return x


@_jit
def inv_if_well_conditioned(m: np.ndarray) -> tuple[bool, np.ndarray]:
    """m⁻¹ when it provably equals m⁺, as the oracle's ``efsm_wbc.inv_if_well_conditioned``.

    Returns:
        (True, m⁻¹), or (False, anything) when the trace test cannot prove it.
    """
    n = m.shape[0]
    if n == 1:
        a = m[0, 0]
        m_inv = np.empty((1, 1))
        m_inv[0, 0] = 1.0 / a if a > 0.0 else 0.0
        return a > 0.0, m_inv
    if n == 2:  # closed form
        a, b, c, d = m[0, 0], m[0, 1], m[1, 0], m[1, 1]
        det = a * d - b * c
        m_inv = np.empty((2, 2))
        if det == 0.0:
            return False, m_inv
        m_inv[0, 0], m_inv[0, 1] = d / det, -b / det
        m_inv[1, 0], m_inv[1, 1] = -c / det, a / det
        tr, tr_inv = a + d, (a + d) / det
    else:
        m_inv = inverse(m)
        tr, tr_inv = np.trace(m), np.trace(m_inv)
    return (tr > 0.0 and tr_inv > 0.0 and tr * tr_inv * PINV_RCOND < 1.0), m_inv


@_jit
def pinv_eigh(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """m⁺ of a symmetric m, and its eigenvectors by ascending eigenvalue (k, k)."""
    eigval, eigvec_f = np.linalg.eigh(m)
    eigvec = np.ascontiguousarray(eigvec_f)
    cutoff = PINV_RCOND * np.abs(eigval).max()
    scaled = eigvec.copy()  # eigvec · diag(1/λ), the dropped directions zeroed
    for j in range(eigval.shape[0]):
        inv_val = 1.0 / eigval[j] if abs(eigval[j]) > cutoff else 0.0
        for i in range(eigvec.shape[0]):
            scaled[i, j] *= inv_val
    return matmul_bt(scaled, eigvec), eigvec


# ---- kinematics read from Pinocchio's results ----------------------------------------------


@_jit
def _row_row(a: np.ndarray, i: int, b: np.ndarray, j: int) -> float:
    """(a bᵀ)[i, j] of 3 × 3 matrices, summed from 0.0 as :func:`matmul_bt`."""
    acc = 0.0
    for k in range(3):
        acc += a[i, k] * b[j, k]
    return acc


@_jit
def orientation_error(rot_des: np.ndarray, rot: np.ndarray) -> tuple[float, float, float]:
    """log3(R_des Rᵀ), the orientation error in world axes [rad] (a tuple: no allocation)."""
    return log3_entries(
        (
            _row_row(rot_des, 0, rot, 0), _row_row(rot_des, 0, rot, 1), _row_row(rot_des, 0, rot, 2),
            _row_row(rot_des, 1, rot, 0), _row_row(rot_des, 1, rot, 1), _row_row(rot_des, 1, rot, 2),
            _row_row(rot_des, 2, rot, 0), _row_row(rot_des, 2, rot, 1), _row_row(rot_des, 2, rot, 2),
        )
    )  # fmt: skip


# ---- Pinocchio's last steps, in the tick ----------------------------------------------------
# After computeAllTerms a tick also called Pinocchio's cholesky.decompose, computeMinv and
# getFrameClassicalAcceleration: about 1 µs of Python binding each, and a fresh 18 × 18 array.
# These kernels (and robot.frame_classical_acceleration, shared with Paper III's controller)
# compute what those calls return inside the tick, in Pinocchio's operations;
# tests/test_efsm_kernels.py checks them against Pinocchio to 1e-12, and
# benchmarks/pinocchio_ports.py measures what calling Pinocchio instead would cost.


@_jit
def mass_matrix_inverse(mass: np.ndarray, tree: np.ndarray, out: np.ndarray) -> None:
    """A⁻¹ from A's upper triangle, as Pinocchio's ``cholesky.decompose`` + ``computeMinv``.

    A = U D Uᵀ along the kinematic tree (U unit upper triangular, non-zero only between a
    velocity coordinate and its ancestors); then column c of A⁻¹ is U⁻ᵀ D⁻¹ U⁻¹ e_c, of which
    the upper triangle is kept and mirrored. Every entry gets the terms of Pinocchio's sums
    in Pinocchio's order (left to right: its dot products run along strided rows, which
    Eigen does not vectorize). Only the loops are turned, so that independent sums
    (ancestors; columns) run side by side rather than one after the other: a direct port
    of Pinocchio's column-by-column loops cost as much as the two Python calls it replaces.

    Args:
        mass: A (``data.M`` after computeAllTerms; only its upper triangle is read), (n, n).
        tree: ``data.parents_fromRow`` (row 0) and ``data.nvSubtree_fromRow`` (row 1), (2, n).
        out: A⁻¹, both triangles, (n, n).
    """
    n = mass.shape[0]
    parent, subtree = tree[0], tree[1]
    u = np.zeros((n, n))  # U's strict upper triangle
    d, d_inv, du, acc = np.empty((4, n))  # D, D⁻¹ and two work vectors: one allocation
    rows = np.empty(n, dtype=np.int64)
    # cholesky.decompose, last coordinate first: D_j = A_jj − Σ_k U_jk D_k U_jk and
    # U_ij = (A_ij − Σ_k U_ik D_k U_jk) / D_j for each ancestor i, k over j's subtree.
    for j in range(n - 1, -1, -1):
        below = subtree[j] - 1  # the coordinates j + 1 … j + below move with j
        for k in range(below):
            du[k] = u[j, j + 1 + k] * d[j + 1 + k]
        n_rows, i = 0, j  # j, then its ancestors
        while i >= 0:
            rows[n_rows] = i
            n_rows += 1
            i = parent[i]
        for r in range(n_rows):  # Eigen's sums: the first term, then + each next one
            acc[r] = u[rows[r], j + 1] * du[0] if below else 0.0
        for k in range(1, below):
            for r in range(n_rows):
                acc[r] = acc[r] + u[rows[r], j + 1 + k] * du[k]
        d[j] = mass[j, j] - acc[0]
        d_inv[j] = 1.0 / d[j]
        for r in range(1, n_rows):
            u[rows[r], j] = (mass[rows[r], j] - acc[r]) * d_inv[j]
    # computeMinv: column c is e_c, then U⁻¹ (back substitution), D⁻¹ on rows ≤ c, and U⁻ᵀ
    # (forward substitution); all columns at once, the rows > c left out (Pinocchio
    # computes them, then overwrites them with the mirror image).
    # In U⁻¹ e_c only the ancestors of c (and c) are non-zero: the other terms of
    # Pinocchio's sums are ±0, which change no non-zero sum, so they are skipped; the
    # non-zero ones are added in its order, from +0.0 (its first term may be ±0: the same).
    for i in range(n):
        for c in range(n):
            out[i, c] = 1.0 if i == c else 0.0
    for k in range(n - 2, -1, -1):
        end = k + subtree[k]  # the columns below k: k + 1 … end − 1
        acc[k + 1 : end] = 0.0
        for i in range(k + 1, end):
            u_ki = u[k, i]
            for c in range(i, i + subtree[i]):  # the columns with row i non-zero
                acc[c] = acc[c] + u_ki * out[i, c]
        for c in range(k + 1, end):
            out[k, c] = -acc[c]
    for k in range(n):
        for c in range(k, n):
            out[k, c] *= d_inv[k]
    for k in range(n):
        for i in range(k + 1, k + subtree[k]):
            u_ki = u[k, i]
            for c in range(i, n):
                out[i, c] -= u_ki * out[k, c]
    for i in range(n):
        for c in range(i):
            out[i, c] = out[c, i]


@_jit
def frame_placement(
    joint_rot: np.ndarray,
    joint_pos: np.ndarray,
    local_rot: np.ndarray,
    local_pos: np.ndarray,
    rot: np.ndarray,
    pos: np.ndarray,
) -> None:
    """A frame's world placement, as Pinocchio's ``updateFramePlacements`` (oMf = oMi · iMf).

    Args:
        joint_rot, joint_pos: ``data.oMi[j]`` of the frame's joint.
        local_rot, local_pos: the frame's placement in the joint (``model.frames[f]``).
        rot, pos: out: the frame's world rotation (3, 3) and position (3,) [m].
    """
    for col in range(3):
        rot[0, col], rot[1, col], rot[2, col] = eigen_rotate(
            joint_rot, local_rot[0, col], local_rot[1, col], local_rot[2, col]
        )
    x0, x1, x2 = eigen_rotate(joint_rot, local_pos[0], local_pos[1], local_pos[2])
    pos[0], pos[1], pos[2] = joint_pos[0] + x0, joint_pos[1] + x1, joint_pos[2] + x2


# ---- Appendix A: contact dynamics and the task hierarchy ---------------------------------


@_jit
def contact_dynamics(
    a_inv: np.ndarray, nle: np.ndarray, jc: np.ndarray, jc_dot_v: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]:
    """The contact-consistent quantities of Appendices A and B (oracle: ``contact_dynamics``).

    Uses the symmetry of A⁻¹ and Λ_c to form the products row by row (J_c A⁻¹ rather than
    A⁻¹ J_cᵀ), which the compiler vectorizes.

    Returns:
        P (n, n), W⁺ (k, k), Ψ = J̄_cᵀSᵀ (c, k), f_bias (c,), Γ_gc (k,), W's eigenvectors
        (k, k), and whether W⁺ was built from them (else they are not computed).
    """
    c, n = jc.shape
    jc_a_inv = matmul(jc, a_inv)  # J_c A⁻¹ = (A⁻¹ J_cᵀ)ᵀ, shape (c, n)
    lam_c = _invert(matmul_bt(jc_a_inv, jc))  # Λ_c = (J_c A⁻¹ J_cᵀ)⁻¹
    if not math.isfinite(np.trace(lam_c)):
        raise np.linalg.LinAlgError("singular contact inertia J_c A⁻¹ J_cᵀ")
    jbar_t = matmul(lam_c, jc_a_inv)  # J̄_cᵀ = Λ_c J_c A⁻¹, shape (c, n)
    P = a_inv.copy()  # A⁻¹(I − J_cᵀ J̄_cᵀ) = A⁻¹ − J̄_c (J_c A⁻¹)
    for r in range(c):
        for i in range(n):
            f = jbar_t[r, i]
            for j in range(n):
                P[i, j] -= f * jc_a_inv[r, j]
    W = P[6:, 6:]  # a view: what inverts it copies it
    well, W_pinv = False, np.empty((0, 0))
    w_eigvec = W_pinv  # only built with W⁺ from the eigen-decomposition
    if c <= 6:
        well, W_pinv = inv_if_well_conditioned(W)
    if not well:
        W_pinv, w_eigvec = pinv_eigh(W)
    # Eq. (8): f_c = J̄_cᵀ (SᵀΓ − b − g) + Λ_c J̇_c q̇.
    psi = jbar_t[:, 6:].copy()  # J̄_cᵀ Sᵀ, shape (c, k)
    f_bias = matvec(lam_c, jc_dot_v)
    f_bias -= matvec(jbar_t, nle)
    # Appendix B: S q̈ = W Γ − S P (b+g) − S A⁻¹ J_cᵀ Λ_c J̇_c q̇.
    bias_acc = matvec(P[6:, :], nle)
    for r in range(c):
        for i in range(n - 6):
            bias_acc[i] += psi[r, i] * jc_dot_v[r]
    gamma_gc = matvec(W_pinv, bias_acc)
    return P, W_pinv, psi, f_bias, gamma_gc, w_eigvec, not well


@_jit
def _prioritized_torque_map(
    W: np.ndarray, W_pinv: np.ndarray, phi: np.ndarray, prec_phi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Ñ_precᵀ J̃ᵀ and Λ of a task below the tasks stacked in ``prec_phi`` (pinv form, Eq. 11).

    As ``efsm_wbc.prioritized_task(cd, phi, efsm_wbc.null_space_t(cd, prec_phi))``, or with no
    preceding task when ``prec_phi`` has no rows.
    """
    jt = matmul_bt(W_pinv, phi)  # J̃ᵀ
    torque_map = jt
    if prec_phi.shape[0] > 0:
        jt_prec = matmul_bt(W_pinv, prec_phi)
        lam_prec = np.linalg.pinv(matmul(prec_phi, jt_prec), PINV_RCOND)
        # Ñᵀ = I − J̃_precᵀ Λ_prec Φ_prec W⁺ W
        n_t = np.eye(W.shape[0]) - matmul(
            matmul(matmul(matmul(jt_prec, lam_prec), prec_phi), W_pinv), W
        )
        torque_map = matmul(n_t, jt)
    lam = np.linalg.pinv(matmul(phi, torque_map), PINV_RCOND)
    return torque_map, lam


@_jit
def task_hierarchy(
    W: np.ndarray, W_pinv: np.ndarray, phi: np.ndarray, m1: int, m2: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Three prioritized tasks of Eq. (11), as the oracle's ``efsm_wbc.task_hierarchy``.

    Returns:
        torque map [J̃_1ᵀ, Ñ_1ᵀ J̃_2ᵀ, Ñ_12ᵀ J̃_3ᵀ] (k, m), and Λ_1, Λ_2, Λ_3.
    """
    k, m = W.shape[0], phi.shape[0]
    m12 = m1 + m2
    jt = matmul_bt(W_pinv, phi)  # J̃ᵀ of every row, shape (k, m)
    gram = matmul(phi, jt)  # Φ W⁺ Φᵀ
    ok1, lam1 = inv_if_well_conditioned(gram[:m1, :m1])
    ok12, lam12 = inv_if_well_conditioned(gram[:m12, :m12])
    if ok1 and ok12:
        # torque_map = J̃ᵀ (I − U), U strictly block-upper:
        # Ñ_1ᵀ J̃_2ᵀ = J̃_2ᵀ − J̃_1ᵀ Λ_1 G_12, Ñ_12ᵀ J̃_3ᵀ = J̃_3ᵀ − J̃_12ᵀ Λ_12 G_12,3.
        # U's non-zero blocks only: its zeros would add ±0 terms, which change no sum.
        u_2 = matmul(lam1, gram[:m1, m1:m12])  # U[:m1, m1:m12]
        u_3 = matmul(lam12, gram[:m12, m12:])  # U[:m12, m12:]
        torque_map = jt.copy()
        for i in range(k):
            for j in range(m1, m):
                acc = 0.0  # (J̃ᵀ U)[i, j], summed as matmul does
                if j < m12:
                    for r in range(m1):
                        acc += jt[i, r] * u_2[r, j - m1]
                else:
                    for r in range(m12):
                        acc += jt[i, r] * u_3[r, j - m12]
                torque_map[i, j] = jt[i, j] - acc
        ok3, lam3 = inv_if_well_conditioned(matmul(phi[m12:], torque_map[:, m12:]))
        if ok3:
            return torque_map, lam1, lam12[m1:, m1:].copy(), lam3
    # Ill-conditioned: the pseudo-inverses of the projector form (Appendix A).
    tmap = np.empty((k, m))
    tm1, pinv_lam1 = _prioritized_torque_map(W, W_pinv, phi[:m1], phi[:0])
    tm2, pinv_lam2 = _prioritized_torque_map(W, W_pinv, phi[m1:m12], phi[:m1])
    tm3, pinv_lam3 = _prioritized_torque_map(W, W_pinv, phi[m12:], phi[:m12])
    tmap[:, :m1], tmap[:, m1:m12], tmap[:, m12:] = tm1, tm2, tm3
    return tmap, pinv_lam1, pinv_lam2, pinv_lam3


# ---- Appendices C and D: wrenches, CoP, redistribution ------------------------------------


@_jit
def grasp_map(rot_o: np.ndarray, origin: np.ndarray, contact_points: np.ndarray) -> np.ndarray:
    """K of Eq. (10), as the oracle's ``efsm_wbc.grasp_map``; ``contact_points``: (feet, 3)."""
    n_feet = contact_points.shape[0]
    kmap = np.zeros((6, 6 * n_feet))
    for foot in range(n_feet):
        dx = contact_points[foot, 0] - origin[0]
        dy = contact_points[foot, 1] - origin[1]
        dz = contact_points[foot, 2] - origin[2]
        # The distance from O's origin in O axes (Rᵀ (p − o)), as scalars.
        d = (
            rot_o[0, 0] * dx + rot_o[1, 0] * dy + rot_o[2, 0] * dz,
            rot_o[0, 1] * dx + rot_o[1, 1] * dy + rot_o[2, 1] * dz,
            rot_o[0, 2] * dx + rot_o[1, 2] * dy + rot_o[2, 2] * dz,
        )
        c = 6 * foot
        for i in range(3):
            for j in range(3):
                kmap[i, c + j] = rot_o[j, i]  # Rᵀ
                kmap[3 + i, c + 3 + j] = rot_o[j, i]
        for j in range(3):  # [d]× Rᵀ
            kmap[3, c + j] = -d[2] * rot_o[j, 1] + d[1] * rot_o[j, 2]
            kmap[4, c + j] = d[2] * rot_o[j, 0] - d[0] * rot_o[j, 2]
            kmap[5, c + j] = -d[1] * rot_o[j, 0] + d[0] * rot_o[j, 1]
    return kmap


@_jit
def cop_of(wrench_o: np.ndarray) -> tuple[float, float]:
    """CoP (x, y) in O of a resultant wrench in O, Eqs. (18) and (22) [m]; NaN if unloaded."""
    fz = wrench_o[2]
    if abs(fz) < 1e-9:
        return math.nan, math.nan
    return -wrench_o[4] / fz, wrench_o[3] / fz


@_jit
def redistribution_torque(
    psi: np.ndarray,
    w_eigvec: np.ndarray,
    f_now: np.ndarray,
    eps: float,
    eps_onset: float,
    lever: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Γ_c of Appendix C (Eqs. 14–16) and the leaving foot's reference wrench.

    As the oracle's ``efsm_wbc.redistribution_torque`` with the leaving foot's rows first
    (``leave=slice(0, 6)``) and ``lever`` given.
    """
    v2 = w_eigvec[:, :6].copy()  # W's null space (Eq. 14)
    g = matmul(psi, v2)  # wrench change per α, shape (12, 6)
    n_tan = TANGENTIAL_ROWS.shape[0]
    g_tan, rhs = np.empty((n_tan, 6)), np.empty(n_tan)
    for i in range(n_tan):
        g_tan[i] = g[TANGENTIAL_ROWS[i]]
        rhs[i] = -f_now[TANGENTIAL_ROWS[i]]
    alpha_opt = lstsq(g_tan, rhs)
    target = f_now[:6] + matvec(g[:6], alpha_opt)  # the leaving foot's rows of f_opt
    if eps_onset < 1.0:
        # The whole resultant about the leaving sole centre: m_a moves by (p_a − p_l) × f_a.
        fx, fy, fz = f_now[6], f_now[7], f_now[8]
        lx, ly, lz = -lever[0], -lever[1], -lever[2]
        shifted = f_now[6:].copy()  # the landing foot's wrench about the leaving sole centre
        shifted[3] += ly * fz - lz * fy
        shifted[4] += lz * fx - lx * fz
        shifted[5] += lx * fy - ly * fx
        f_all = f_now[:6] + shifted
        target = eps_onset * target + (1.0 - eps_onset) * f_all
    f_ref = eps * target
    alpha = solve_vec(g[:6], f_ref - f_now[:6])  # Y_c f_c^cor (Eq. 16)
    return matvec(v2, alpha), f_ref


@_jit
def _clip(x: float, bound: float) -> float:
    """x clipped to [−bound, bound] (as np.clip)."""
    return min(max(x, -bound), bound)


@_jit
def task2_force(
    lam: np.ndarray,
    acc: np.ndarray,
    double: bool,
    scale_swing: float,
    f_max: float,
    m_max: float,
    decoupled: float,
) -> np.ndarray:
    """F_2 = Λ ẍ* (Eq. 6) with the swing-foot wrench F_s saturated and scaled.

    As ``EfsmController._task2_force`` (see it for why); ``scale_swing`` is ε in SSA, else 1.
    """
    f_free = matvec(lam, acc)  # Λ ẍ*, unbounded
    if double:
        return f_free
    if decoupled == 2:
        # Uniform: scale the commanded linear swing acceleration ẍ_s* by the largest s ≤ 1
        # for which every force row F_i = s A_i + B_i stays within the bound (A: the part of
        # Λ ẍ* due to ẍ_s*, B: the rest), so the foot keeps heading for its target.
        s_max = 1.0
        for i in range(3):
            a_i = 0.0
            for j in range(3):
                a_i += lam[3 + i, 3 + j] * acc[3 + j]
            b_i = f_free[3 + i] - a_i
            if a_i > 0.0:
                s_max = min(s_max, (f_max - b_i) / a_i)
            elif a_i < 0.0:
                s_max = min(s_max, (-f_max - b_i) / a_i)
        s_max = max(s_max, 0.0)
        if s_max < 1.0:
            acc_b = acc.copy()
            for i in range(3, 6):
                acc_b[i] *= s_max
            f_free = matvec(lam, acc_b)
    fs = f_free[3:9].copy()
    if decoupled == 1:
        cut = np.empty(3)
        for i in range(3):
            fs[i] = _clip(fs[i], f_max)
            cut[i] = fs[i] - f_free[3 + i]
        if _any_nonzero(cut):
            fs[3:] += matvec(lam[6:9, 3:6], solve_vec(lam[3:6, 3:6], cut))
    for i in range(3):
        fs[i] = _clip(fs[i], f_max)
        fs[3 + i] = _clip(fs[3 + i], m_max)
    if scale_swing != 1.0:
        fs *= scale_swing
    cut = fs - f_free[3:9]
    f2 = f_free
    if _any_nonzero(cut):
        f2[:3] += matvec(lam[0:3, 3:9], solve_vec(lam[3:9, 3:9], cut))
    f2[3:] = fs
    return f2


@_jit
def balance_force(
    fc: np.ndarray,
    kpsi3: np.ndarray,
    f3: np.ndarray,
    rot: np.ndarray,
    sole_rot: np.ndarray,
    half_sole: np.ndarray,
    margin: float,
    x_s: float,
) -> tuple[bool, np.ndarray]:
    """F_3 + F_3^bal (Eqs. 23–29), as ``EfsmController._balance_force``.

    Args:
        x_s: swing-foot centre along x of O_w in DS [m], NaN out of DS.

    Returns:
        (False, anything) when the expected CoP is inside the polygon (Eq. 23), else
        (True, F_3 + F_3^bal).
    """
    out = np.empty(2)
    cop_x, cop_y = cop_of(fc)
    if not (math.isfinite(cop_x) and math.isfinite(cop_y)):
        return False, out
    # O_w-from-foot (xy): rot[:2, :2]ᵀ @ sole_rot[:2, :2] with rot a yaw.
    c, s = rot[0, 0], rot[1, 0]
    a00, a01, a10, a11 = sole_rot[0, 0], sole_rot[0, 1], sole_rot[1, 0], sole_rot[1, 1]
    r00, r01 = c * a00 + s * a10, c * a01 + s * a11
    r10, r11 = c * a10 - s * a00, c * a11 - s * a01
    half_x, half_y = half_sole[0], half_sole[1]
    hx = (abs(r00) * half_x + abs(r01) * half_y) - margin
    hy = (abs(r10) * half_x + abs(r11) * half_y) - margin
    hi_x = hx + x_s if math.isfinite(x_s) else hx
    cx, cy = min(max(cop_x, -hx), hi_x), min(max(cop_y, -hy), hy)
    tol_x, tol_y = 1e-8 + 1e-5 * abs(cop_x), 1e-8 + 1e-5 * abs(cop_y)
    if abs(cx - cop_x) <= tol_x and abs(cy - cop_y) <= tol_y:
        return False, out
    fsig = fc - matvec(kpsi3, f3)  # the wrench without task 3
    m_des = np.array([cy * fsig[2] - fsig[3], -cx * fsig[2] - fsig[4]])  # Eqs. (26)-(27)
    q3 = kpsi3[3:5].copy()  # Eq. (28)
    if abs(q3[0, 0] * q3[1, 1] - q3[0, 1] * q3[1, 0]) < 1e-12:
        return False, out
    return True, solve_vec(q3, m_des)  # F_3 + F_3^bal, Eq. (29)


# ---- the whole tick -------------------------------------------------------------------------
# Records of :func:`whole_body_torques`' inputs. :func:`tick` builds them in compiled code,
# where a named tuple is a struct of pointers and numbers (no allocation); built in Python
# (as the tests do) numba types each of their arrays at every call, a few µs.


class WbcDynamics(NamedTuple):
    """The dynamics of a tick, world axes (n velocity coordinates, the pelvis first).

    Attributes:
        a_inv: A⁻¹, shape (n, n).
        nle: b + g, shape (n,).
        jc_dot_v: J̇_c q̇ of the contacts (support sole, then the swing sole in DS), shape
            (6 or 12,).
        j_world: Pinocchio's joint Jacobians ``data.J`` (see
            :func:`walkrepro.robot.frame_jacobian`). The pelvis (the rigid upper body) is the
            floating base: its first six columns.
        j_com: CoM Jacobian, shape (3, n).
        v: generalized velocity, shape (n,).
    """

    a_inv: np.ndarray
    nle: np.ndarray
    jc_dot_v: np.ndarray
    j_world: np.ndarray
    j_com: np.ndarray
    v: np.ndarray


class WbcFrames(NamedTuple):
    """The frames of a :func:`whole_body_torques` call: O_w and the two soles, world axes.

    Attributes:
        ow_rot: world-from-O_w rotation (§III-A1).
        p_sup, p_sw: support and swing sole centres [m]; p_sup is the origin of O_w.
        sole_rot_sup, sole_rot_sw: world-from-sole rotations.
        pelvis_rot: world-from-pelvis rotation.
        support_sup, support_sw: the velocity coordinates moving each sole (1/0), shape (n,).
    """

    ow_rot: np.ndarray
    p_sup: np.ndarray
    p_sw: np.ndarray
    sole_rot_sup: np.ndarray
    sole_rot_sw: np.ndarray
    pelvis_rot: np.ndarray
    support_sup: np.ndarray
    support_sw: np.ndarray


class WbcTargets(NamedTuple):
    """What the E-FSM and the task references ask of a tick (Eq. 6, Table II, §IV-B).

    Attributes:
        rot_des: orientation targets (Table II), shape (2, 3, 3): pelvis, swing sole.
        task_ref: shape (7,): [0:2] CoM y, z error in O_w [m]; [2:4] CoM y, z velocity in
            O_w [m/s]; [4:7] swing-sole position reference [m] (unused in DS).
        phase: E-FSM phase (fsm.Phase as int).
        eps: ε; eps_onset: ε's onset ramp in DS (oracle: ``efsm_wbc.redistribution_torque``).
        xp_des: desired CoP along x of O_w [m].
        x_s: swing-foot centre along x of O_w [m].
    """

    rot_des: np.ndarray
    task_ref: np.ndarray
    phase: int
    eps: float
    eps_onset: float
    xp_des: float
    x_s: float


@_jit
def whole_body_torques(
    dynamics: WbcDynamics,
    frames: WbcFrames,
    targets: WbcTargets,
    params: np.ndarray,
    actuator_rows: np.ndarray,
    tau: np.ndarray,
) -> tuple[float, bool, float, float]:
    """Γ = Γ_t + Γ_c + Γ_gc (Eq. 7) of one tick (:func:`tick` calls it with its frames).

    The three tasks of Eq. (11): task 1 the CoM x-force for x_p^des (Appendix D-1); task 2
    CoM y/z, pelvis yaw and, out of DS, the 6-D swing foot; task 3 pelvis roll/pitch, plus
    F_3^bal (Appendix D-3). Γ_c redistributes the DS wrenches (Appendix C). Contacts: the
    support sole, plus the swing sole in DS (its rows second).

    Args:
        dynamics: A⁻¹, b + g, J̇_c q̇, the Jacobians and v (:class:`WbcDynamics`).
        frames: O_w, the soles and the pelvis (:class:`WbcFrames`).
        targets: phase, ε, x_p^des and the task references (:class:`WbcTargets`).
        params: k_p, k_v, F_s force bound [N], F_s moment bound [Nm], decoupled saturation
            (1/0), balancing (1/0), CoP safety margin [m], torque limit [Nm], half sole
            length and width [m].
        actuator_rows: joint-torque row of each actuator, shape (k,).
        tau: out: actuator torques, saturated, shape (k,) [Nm].

    Returns:
        F_1 (the CoM x-force [N]), whether F_3^bal acted, and the expected CoP (x, y) in
        O_w [m] (NaN if unloaded).
    """
    a_inv, nle, jc_dot_v, j_world, j_com, v = dynamics
    rot, p_sup, p_sw, sole_rot_sup, sole_rot_sw, pelvis_rot, support_sup, support_sw = frames
    rot_des, task_ref, phase, eps, eps_onset, xp_des, x_s = targets
    kp, kv, f_max, m_max = params[0], params[1], params[2], params[3]
    decoupled, balance, margin, tau_lim = params[4], params[5] != 0.0, params[6], params[7]
    n = a_inv.shape[0]
    double = phase == _DS

    # Contact and task Jacobians, world axes.
    jacobians = np.empty((12, n))  # the support sole's, then the swing sole's
    frame_jacobian(j_world, support_sup, p_sup, jacobians[0:6])
    frame_jacobian(j_world, support_sw, p_sw, jacobians[6:12])
    jc, j_swing = jacobians[0 : 12 if double else 6], jacobians[6:12]
    P, W_pinv, psi, f_bias, gamma_gc, w_eigvec, _ = contact_dynamics(a_inv, nle, jc, jc_dot_v)

    # Task Jacobians, stacked [CoM x | CoM y, z, pelvis yaw, (swing foot) | pelvis roll, pitch],
    # CoM and roll/pitch rows in O_w axes (Eq. 11).
    m2 = 3 if double else 9
    m = m2 + 3
    j_all = np.zeros((m, n))
    w_pelvis = np.zeros(3)  # world axes
    for i in range(3):
        for col in range(6):
            w_pelvis[i] += j_world[3 + i, col] * v[col]
    for col in range(n):
        for i in range(3):
            for j in range(3):
                j_all[i, col] += rot[j, i] * j_com[j, col]
        if col < 6:
            j_all[3, col] = j_world[5, col]
            for i in range(2):
                for j in range(3):
                    j_all[m - 2 + i, col] += rot[j, i] * j_world[3 + j, col]
        if not double:
            for i in range(6):
                j_all[4 + i, col] = j_swing[i, col]

    # Reference accelerations, Eq. (6) (Table II targets).
    e_pelvis = orientation_error(rot_des[0], pelvis_rot)  # world axes
    acc2 = np.empty(m2)
    acc2[0] = kp * task_ref[0] - kv * task_ref[2]
    acc2[1] = kp * task_ref[1] - kv * task_ref[3]
    acc2[2] = kp * e_pelvis[2] - kv * w_pelvis[2]
    if not double:
        v_swing = matvec(j_swing, v)
        e_swing = orientation_error(rot_des[1], sole_rot_sw)
        for i in range(3):
            acc2[3 + i] = (task_ref[4 + i] - p_sw[i]) * kp - kv * v_swing[i]
            acc2[6 + i] = e_swing[i] * kp - kv * v_swing[3 + i]
    acc3 = np.zeros(2)
    for i in range(2):  # rot[:, i] · (k_p e − k_v ω)
        for j in range(3):
            acc3[i] += rot[j, i] * (kp * e_pelvis[j] - kv * w_pelvis[j])

    # The hierarchy (Eq. 11, Appendix A): rows [task 1 (1), task 2 (m2), task 3 (2)].
    phi = matmul(j_all, P[:, 6:].copy())  # Φ = J P Sᵀ (a contiguous P Sᵀ vectorizes)
    tmap, _, lam2, lam3 = task_hierarchy(P[6:, 6:], W_pinv, phi, 1, m2)
    f_all = np.empty(m)  # [F_1; F_2; F_3]
    scale_swing = eps if phase == _SSA else 1.0
    f_all[1 : m2 + 1] = task2_force(lam2, acc2, double, scale_swing, f_max, m_max, decoupled)
    f_all[m2 + 1 :] = matvec(lam3, acc3)

    # CoM x-force for x_p^des (Appendix D-1, Eqs. 17–21) in O_w at the support centre.
    points = np.empty((2 if double else 1, 3))
    points[0] = p_sup
    if double:
        points[1] = p_sw
    kmap = grasp_map(rot, p_sup, points)
    kpsi = matmul(kmap, psi)
    kt = matmul(kpsi, tmap)  # resultant wrench per task force, shape (6, m)
    fc23 = matvec(kt[:, 1:], f_all[1:])  # of tasks 2 and 3
    f_gc = matvec(psi, gamma_gc)
    f_gc += f_bias
    fcb = matvec(kmap, f_gc)
    f1 = -((fc23[2] + fcb[2]) * xp_des + fcb[4]) / kt[4, 0]  # Eqs. (20)-(21)
    f_all[0] = f1

    # Balancing (Appendix D-3): expected CoP out of the shrunk polygon -> F_3^bal.
    fc = np.empty(6)
    for i in range(6):
        fc[i] = (kt[i, 0] * f1 + fc23[i]) + fcb[i]
    balancing = False
    if balance:
        kt3 = kt[:, m2 + 1 :]
        f3 = f_all[m2 + 1 :]
        balancing, f3_new = balance_force(
            fc, kt3, f3, rot, sole_rot_sup, params[8:10], margin, x_s if double else math.nan
        )
        if balancing:
            fc += matvec(kt3, f3_new - f3)  # F_3 replaced
            f_all[m2 + 1 :] = f3_new
    gamma = matvec(tmap, f_all)
    gamma += gamma_gc  # Γ_t + Γ_gc

    # Contact wrench redistribution in DS (Appendix C) with ε (§IV-B).
    if double:
        f_now = matvec(psi, gamma)
        f_now += f_bias
        gamma_c, _ = redistribution_torque(psi, w_eigvec, f_now, eps, eps_onset, p_sup - p_sw)
        gamma += gamma_c  # Γ = Γ_t + Γ_c + Γ_gc, Eq. (7)
        fc += matvec(kpsi, gamma_c)
    for i in range(tau.shape[0]):
        tau[i] = min(max(gamma[actuator_rows[i]], -tau_lim), tau_lim)
    cop_x, cop_y = cop_of(fc)
    return f1, balancing, cop_x, cop_y


@_jit
def _row_dot3(rot: np.ndarray, i: int, x: np.ndarray, start: int) -> float:
    """Row i of a 3 × 3 ``rot`` times x[start : start + 3], summed from 0.0 as matvec does."""
    acc = 0.0
    for j in range(3):
        acc += rot[i, j] * x[start + j]
    return acc


@_jit
def measured_cop(
    ft_rot_left: np.ndarray,
    ft_pos_left: np.ndarray,
    wrench_left: np.ndarray,
    ft_rot_right: np.ndarray,
    ft_pos_right: np.ndarray,
    wrench_right: np.ndarray,
    foot_com: np.ndarray,
    foot_weight: np.ndarray,
) -> tuple[float, float]:
    """CoP (x, y) in the world from the two F/T sensors, as ``EfsmController._measured_cop``.

    Args:
        ft_rot_left, ft_rot_right: world-from-sensor rotation of each F/T frame.
        ft_pos_left, ft_pos_right: position of each F/T frame in the world [m].
        wrench_left, wrench_right: each sensor's (f, τ) in its frame, the wrench the foot
            applies to the leg [N, Nm].
        foot_com: centre of mass of the part below each sensor (left, right), in the
            sensor frame, shape (2, 3) [m].
        foot_weight: weight of that part (left, right), shape (2,) [N].

    Returns:
        The ground-level CoP [m]; NaN when no foot carries vertical load.
    """
    force_z = mom_x = mom_y = 0.0
    for foot in range(2):
        rot = ft_rot_left if foot == 0 else ft_rot_right
        pos = ft_pos_left if foot == 0 else ft_pos_right
        wrench = wrench_left if foot == 0 else wrench_right
        # Force and torque in world axes (scalars: no temporary arrays).
        f = (
            _row_dot3(rot, 0, wrench, 0),
            _row_dot3(rot, 1, wrench, 0),
            _row_dot3(rot, 2, wrench, 0),
        )
        tq = (_row_dot3(rot, 0, wrench, 3), _row_dot3(rot, 1, wrench, 3))
        weight = foot_weight[foot]  # [N], along +z
        if f[2] + weight <= 0.0:
            continue
        cx = pos[0] + rot[0, 0] * foot_com[foot, 0] + rot[0, 1] * foot_com[foot, 1]
        cx += rot[0, 2] * foot_com[foot, 2]
        cy = pos[1] + rot[1, 0] * foot_com[foot, 0] + rot[1, 1] * foot_com[foot, 1]
        cy += rot[1, 2] * foot_com[foot, 2]
        force_z += f[2] + weight
        # τ + p_ft × f + c_foot × (0, 0, weight), x and y rows.
        mom_x += tq[0] + (pos[1] * f[2] - pos[2] * f[1]) + cy * weight
        mom_y += tq[1] + (pos[2] * f[0] - pos[0] * f[2]) - cx * weight
    if force_z <= 1e-6:
        return math.nan, math.nan
    # Ground-level CoP: the point on z = 0 about which the moment has no x/y part.
    return -mom_y / force_z, mom_x / force_z


# ---- the control tick: O_w, E-FSM, footsteps, OS-WBC ----------------------------------------
# The tick after computeAllTerms is one compiled call (why: a numba call costs ≈ 50 ns per
# array argument, a Pinocchio call ≈ 1 µs, and a line of Python 50–100 ns, at 2 kHz).
# tests/test_efsm_kernels.py compares it with the same tick composed of the readable
# references (the oracle's EventFsm in tests/oracles/efsm_fsm.py, Pinocchio's frames and A⁻¹,
# numpy), phase by phase.

#: Bits of :func:`tick`'s result: the E-FSM transitions of the tick (they happen in this order).
SSD_TO_SSA, SSA_TO_DS, DS_TO_SSD = 1, 2, 4
#: ``g`` of the capture point, Eq. (2), as the oracle's efsm_fsm.capture_point [m/s²].
_GRAVITY = 9.81

#: The signals :func:`tick` writes into ``state["signals"]``, in order: (name, length).
SIGNALS = (
    ("fsm_state", 1),
    ("efsm_phase", 1),
    ("epsilon", 1),
    ("epsilon_onset", 1),
    ("d", 1),
    ("com_w", 3),
    ("com_vel_w", 3),
    ("com_world", 3),
    ("com_vel_world", 3),
    ("cp_w", 1),
    ("cp_ref_w", 1),
    ("x_s_w", 1),
    ("xp_des_w", 1),
    ("xp_des_world", 2),
    ("cop_exp_w", 2),
    ("cop_exp_world", 2),
    ("cop_meas_world", 2),
    ("cop_meas_valid", 1),
    ("swing_pos_world", 3),
    ("swing_ref_world", 3),
    ("swing_foot", 1),
    ("support_pos_world", 3),
    ("ow_yaw", 1),
    ("com_force_x", 1),
    ("balancing", 1),
    ("steps_done", 1),
)


def tick_state(nq: int, nv: int, n_actuators: int) -> np.ndarray:
    """A zeroed state of :func:`tick`: one numpy record (a structured array of length 1).

    The controller's own arrays and numbers, as one argument: numba unboxes a record in one
    step, where two dozen separate arrays and numbers cost ≈ 50 ns each. The controller
    keeps views of the fields it writes or reads (``state["tau"][0]`` is a view).

    Fields (per foot: left, right):
        params: k_p, k_v, F_s bounds, ..., as :func:`whole_body_torques`' ``params``.
        zeta, r, dxp, d_thr, v_stop, use_epsilon, ds_onset_ramp: efsm_fsm.FsmParams and the onset
            ramp switch (1/0) of EfsmParams.
        step_length, n_steps (−1: no limit), width, heading, lateral: the footstep planner.
        z_m0, raise_height, land_height: CoM height (Eq. 2) and swing heights (Table II) [m].
        rot_des: orientation targets (Table II): pelvis, swing sole.
        actuator_rows, cholesky_tree, sole_support: as :func:`whole_body_torques` and
            :func:`mass_matrix_inverse`; sole_support per foot, 1/0.
        sole_local_rot/pos, ft_local_rot/pos: each sole and F/T frame in its joint.
        foot_com, foot_weight: as :func:`measured_cop`.
        support (0 left, 1 right), phase (fsm.Phase), xp_des [m], ds_start_xp (x_p^des when
            DS started; NaN out of DS) [m], steps_done, swing_target [m]: the E-FSM's state.
        rot: world-from-O_w, rewritten every tick.
        pin_state: Pinocchio's q (row 0, first nq entries) and v (row 1, first nv entries)
            of the tick, written by the controller (:func:`walkrepro.robot.pin_state_into`).
        tau: out: actuator torques [Nm]. signals: out: :data:`SIGNALS`, flattened.
    """
    f8, i8 = np.float64, np.int64
    n_signals = sum(n for _, n in SIGNALS)
    fields = [
        ("params", f8, (10,)),
        ("zeta", f8),
        ("r", f8),
        ("dxp", f8),
        ("d_thr", f8),
        ("v_stop", f8),
        ("use_epsilon", i8),
        ("ds_onset_ramp", i8),
        ("step_length", f8),
        ("n_steps", i8),
        ("width", f8),
        ("heading", f8, (3,)),
        ("lateral", f8, (3,)),
        ("z_m0", f8),
        ("raise_height", f8),
        ("land_height", f8),
        ("rot_des", f8, (2, 3, 3)),
        ("actuator_rows", i8, (n_actuators,)),
        ("cholesky_tree", i8, (2, nv)),
        ("sole_support", i8, (2, nv)),
        ("sole_local_rot", f8, (2, 3, 3)),
        ("sole_local_pos", f8, (2, 3)),
        ("ft_local_rot", f8, (2, 3, 3)),
        ("ft_local_pos", f8, (2, 3)),
        ("foot_com", f8, (2, 3)),
        ("foot_weight", f8, (2,)),
        ("support", i8),
        ("phase", i8),
        ("xp_des", f8),
        ("ds_start_xp", f8),
        ("steps_done", i8),
        ("swing_target", f8, (3,)),
        ("rot", f8, (3, 3)),
        ("pin_state", f8, (2, max(nq, nv))),
        ("tau", f8, (n_actuators,)),
        ("signals", f8, (n_signals,)),
    ]
    return np.zeros(1, dtype=np.dtype(fields, align=True))


@_jit
def ow_frame(
    p_sup: np.ndarray, p_sw: np.ndarray, com: np.ndarray, vcom: np.ndarray, rot: np.ndarray
) -> tuple[float, float, tuple[float, float, float], tuple[float, float, float], float]:
    """O_w (§III-A1) and the CoM and swing foot in it.

    Args:
        p_sup: support sole centre, the origin of O_w [m].
        p_sw: swing sole centre [m]; O_w's x points to its ground projection.
        com, vcom: CoM position [m] and velocity [m/s] in the world.
        rot: out: the world-from-O_w rotation (3, 3); only its top-left 2 × 2 is written
            (the rest stays that of a rotation about z).

    Returns:
        cos and sin of O_w's yaw; com_w [m] and vcom_w [m/s]; x_s, the swing sole centre
        along x of O_w [m].
    """
    ox, oy, oz = p_sup[0], p_sup[1], p_sup[2]
    sx, sy = p_sw[0], p_sw[1]
    yaw = math.atan2(sy - oy, sx - ox)
    c, s = math.cos(yaw), math.sin(yaw)
    rot[0, 0], rot[0, 1], rot[1, 0], rot[1, 1] = c, -s, s, c
    dx, dy = com[0] - ox, com[1] - oy
    com_w = (c * dx + s * dy, c * dy - s * dx, com[2] - oz)
    vcom_w = (c * vcom[0] + s * vcom[1], c * vcom[1] - s * vcom[0], vcom[2])
    return c, s, com_w, vcom_w, c * (sx - ox) + s * (sy - oy)


@_jit
def _epsilon(d: float, d_thr: float) -> float:
    """ε(d) (§IV-B), as the oracle's efsm_fsm.epsilon."""
    if d <= 0.0:
        return 0.0
    if d < d_thr:
        return d / d_thr
    return 1.0


class FsmInput(NamedTuple):
    """What the E-FSM reads each tick, along the x-axis of O_w (the oracle's
    ``efsm_fsm.FsmInput``).

    Attributes:
        x_m: CoM position [m]; xd_m: CoM velocity [m/s].
        x_cp: capture point, Eq. (2) [m].
        x_s: swing-foot centre [m].
    """

    x_m: float
    xd_m: float
    x_cp: float
    x_s: float


class FsmParams(NamedTuple):
    """Parameters of the E-FSM (§V-B; the oracle's ``efsm_fsm.FsmParams``).

    Attributes:
        zeta: margin ζ of law L1 [m].
        r: margin r of law L2 [m].
        dxp: Δx_p^des per control period [m] (Eq. 4).
        d_thr: ε threshold d^thr [m] (§IV-B).
        v_stop: |ẋ_m| counted as ≈ 0 ending SSD [m/s] (Table I).
        use_epsilon: False: ε ≡ 1 (the ablation of §VI-D1).
    """

    zeta: float
    r: float
    dxp: float
    d_thr: float
    v_stop: float
    use_epsilon: bool


@_jit
def fsm_step(
    phase: int, xp_des: float, fsm_input: FsmInput, params: FsmParams
) -> tuple[int, float, float, float, int]:
    """One control period of the E-FSM (Table I), as the oracle's ``efsm_fsm.EventFsm.step``.

    Args:
        phase: the phase before the tick (fsm.Phase as int); xp_des: x_p^des before it [m].
        fsm_input: CoM, capture point and swing foot along x of O_w (:class:`FsmInput`).
        params: ζ, r, Δx_p^des, d^thr, v_stop and the ε switch (:class:`FsmParams`).

    Returns:
        The phase after the tick's transitions, x_p^des (Eqs. 3–4), ε, d, and the
        transitions as bits (:data:`SSD_TO_SSA`, :data:`SSA_TO_DS`, :data:`DS_TO_SSD`).
    """
    x_m, xd_m, x_cp, x_s = fsm_input
    zeta, r, dxp, d_thr, v_stop, use_epsilon = params
    transitions = 0
    if phase == _SSD and xd_m >= -v_stop:
        transitions |= SSD_TO_SSA
        phase = _SSA
    if phase == _SSA and x_cp >= x_s - r:
        transitions |= SSA_TO_DS
        phase = _DS
    if phase == _DS:  # Eq. (4): steps of Δx_p^des toward x_s
        delta = x_s - xp_des
        xp_des = xp_des + math.copysign(dxp, delta) if abs(delta) > dxp else x_s
    else:  # Eq. (3)
        xp_des = 0.0 if x_m > zeta else x_m - zeta
    if phase == _DS:  # d (§IV-B; the oracle's efsm_fsm.transition_distance)
        d = x_s - xp_des
    elif phase == _SSA:
        d = (x_s - r) - x_cp
    else:
        d = math.inf
    eps = _epsilon(d, d_thr) if use_epsilon else 1.0
    if phase == _DS and abs(x_s - xp_des) <= 0.0:
        transitions |= DS_TO_SSD
        phase = _SSD
    return phase, xp_des, eps, d, transitions


@_jit
def next_swing_target(
    p_sup: np.ndarray,
    swing: int,
    steps_done: int,
    step_length: float,
    n_steps: int,
    width: float,
    heading: np.ndarray,
    lateral: np.ndarray,
) -> tuple[float, float, float]:
    """Footstep planner: the next swing-foot target, step_length ahead of the support [m].

    After ``n_steps`` footsteps (``n_steps`` ≥ 0) the targets are beside the support foot
    (stepping in place), so the E-FSM keeps its cycle without a separate stopping state.

    Args:
        p_sup: the new support sole centre [m]; swing: the new swing foot (0 left, 1 right).
        steps_done: footsteps so far, this one included.
        heading, lateral: the walking direction and the left-pointing lateral axis.
    """
    side = 1.0 if swing == 0 else -1.0
    length = step_length if n_steps < 0 or steps_done <= n_steps else 0.0
    offset = side * width
    return (
        p_sup[0] + heading[0] * length + offset * lateral[0],
        p_sup[1] + heading[1] * length + offset * lateral[1],
        p_sup[2] + heading[2] * length + offset * lateral[2],
    )


class PinocchioTerms(NamedTuple):
    """What a tick reads of Pinocchio's ``computeAllTerms`` (views of ``Data``), world axes.

    Attributes:
        mass: A, ``data.M`` (only its upper triangle is read), shape (n, n).
        nle: b + g, ``data.nle``, shape (n,).
        j_world: the joint Jacobians ``data.J``, shape (6, n).
        j_com: the CoM Jacobian ``data.Jcom``, shape (3, n).
        com: the CoM ``data.com[0]`` [m]; vcom: its velocity ``data.vcom[0]`` [m/s].
        pelvis_rot: world-from-pelvis rotation, ``data.oMi[1].rotation``.
    """

    mass: np.ndarray
    nle: np.ndarray
    j_world: np.ndarray
    j_com: np.ndarray
    com: np.ndarray
    vcom: np.ndarray
    pelvis_rot: np.ndarray


class FootJoint(NamedTuple):
    """The joint j carrying one foot's sole and F/T frame, after ``computeAllTerms`` (views).

    Attributes:
        rot, pos: its placement ``data.oMi[j]``: world-from-joint rotation, position [m].
        vel: its spatial velocity ``data.v[j].vector`` (v [m/s], ω [rad/s]), joint axes.
        acc: its bias acceleration ``data.a[j].vector`` (q̈ = 0), joint axes.
    """

    rot: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray


@structref.register
class PinocchioViewsType(types.StructRef):
    """numba's type of :class:`PinocchioViews` (its fields typed as given, not literal)."""

    def preprocess_fields(self, fields: tuple) -> tuple:
        """The fields' types without literal values."""
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class PinocchioViews(structref.StructRefProxy):
    """Everything :func:`tick` reads of Pinocchio's ``Data``, as one argument; make it with
    :func:`pinocchio_views`, once per ``Data`` (its arrays are views, so it stays current).

    Fields: ``terms`` (:class:`PinocchioTerms`) and ``feet`` (:class:`FootJoint` of the
    left, then the right foot). Why not a named tuple: numba finds the type of a named tuple
    argument in Python at every call, ≈ 2 µs for these fifteen arrays (more than the
    separate arrays cost); a StructRef carries its type, and its arrays were unboxed once,
    when it was made.
    """


structref.define_proxy(PinocchioViews, PinocchioViewsType, ["terms", "feet"])


@_jit
def pinocchio_views(terms: PinocchioTerms, feet: tuple[FootJoint, FootJoint]) -> PinocchioViews:
    """The :class:`PinocchioViews` of ``terms`` and ``feet`` (left, right); compiled and
    cached, unlike the proxy's own constructor."""
    return PinocchioViews(terms, feet)


@_jit
def tick(
    views: PinocchioViews,
    wrench_left: np.ndarray,
    wrench_right: np.ndarray,
    state: np.ndarray,
) -> int:
    """``EfsmController.step`` after computeAllTerms: O_w, the E-FSM, the footstep planner,
    Γ (Eq. 7) and the expected and measured CoP.

    Args:
        views: :class:`PinocchioViews` of ``Data`` after computeAllTerms: the dynamics, CoM
            and pelvis (:class:`PinocchioTerms`) and the joint carrying each foot's sole and
            F/T frame (:class:`FootJoint`, left and right).
        wrench_left, wrench_right: the F/T readings (see :func:`measured_cop`).
        state: :func:`tick_state`, read and updated; ``tau`` and ``signals`` are written.

    Returns:
        The E-FSM transitions of the tick as bits (:data:`DS_TO_SSD`: the feet swapped roles).
    """
    mass, nle, j_world, j_com, com, vcom, pelvis_rot = views.terms
    feet = views.feet
    st = state[0]
    n = mass.shape[0]
    # The soles and the F/T frames (left, right), as updateFramePlacements.
    frames = np.empty((4, 4, 3))  # [sole left, sole right, F/T left, F/T right]: R; p
    sole_rot, sole_pos = frames[0:2, 0:3], frames[0:2, 3]
    ft_rot, ft_pos = frames[2:4, 0:3], frames[2:4, 3]
    for f in range(2):
        joint_rot, joint_pos = feet[f].rot, feet[f].pos
        frame_placement(
            joint_rot,
            joint_pos,
            st.sole_local_rot[f],
            st.sole_local_pos[f],
            sole_rot[f],
            sole_pos[f],
        )
        frame_placement(
            joint_rot, joint_pos, st.ft_local_rot[f], st.ft_local_pos[f], ft_rot[f], ft_pos[f]
        )

    # O_w and the E-FSM inputs (§III-A1, Eq. 2); the E-FSM (Table I).
    sup = st.support
    sw = 1 - sup
    rot = st.rot
    cos_w, sin_w, com_w, vcom_w, x_s = ow_frame(sole_pos[sup], sole_pos[sw], com, vcom, rot)
    x_cp = math.sqrt(st.z_m0 / _GRAVITY) * vcom_w[0] + com_w[0]
    fsm_params = FsmParams(st.zeta, st.r, st.dxp, st.d_thr, st.v_stop, st.use_epsilon != 0)
    phase, xp_des, eps, d, transitions = fsm_step(
        st.phase, st.xp_des, FsmInput(com_w[0], vcom_w[0], x_cp, x_s), fsm_params
    )
    if transitions & DS_TO_SSD:
        # DS ends: the swing foot becomes the support foot; next footstep target; O_w moves
        # (x_p^des, the new support centre, is 0 in it).
        sup, sw = sw, sup
        st.support = sup
        st.steps_done += 1
        st.swing_target[0], st.swing_target[1], st.swing_target[2] = next_swing_target(
            sole_pos[sup], sw, st.steps_done, st.step_length, st.n_steps, st.width,
            st.heading, st.lateral,
        )  # fmt: skip
        cos_w, sin_w, com_w, vcom_w, x_s = ow_frame(sole_pos[sup], sole_pos[sw], com, vcom, rot)
        x_cp = math.sqrt(st.z_m0 / _GRAVITY) * vcom_w[0] + com_w[0]
        xp_des = 0.0
    st.phase, st.xp_des = phase, xp_des
    double = phase == _DS

    # Task-space errors of Eq. (6) (Table II targets): CoM y, z and their velocities in O_w;
    # the swing-foot reference: the planned xy, raised in SSD, lowered otherwise.
    sup_x, sup_y, sup_z = sole_pos[sup, 0], sole_pos[sup, 1], sole_pos[sup, 2]
    task_ref = np.empty(7)
    task_ref[0] = 0.0 - com_w[1]
    task_ref[1] = st.z_m0 - com_w[2]
    task_ref[2], task_ref[3] = vcom_w[1], vcom_w[2]
    task_ref[4], task_ref[5] = st.swing_target[0], st.swing_target[1]
    task_ref[6] = sup_z + (st.raise_height if phase == _SSD else st.land_height)

    # ε's ramp at DS onset (EfsmParams.ds_onset_ramp): the landing foot's wrench grows
    # from 0 over the first d^thr of the x_p^des ramp.
    eps_on = 1.0
    if double:
        if math.isnan(st.ds_start_xp):
            st.ds_start_xp = xp_des
        if st.use_epsilon != 0 and st.ds_onset_ramp != 0:
            eps_on = _epsilon(abs(xp_des - st.ds_start_xp), st.d_thr)
    else:
        st.ds_start_xp = math.nan  # Γ_c = 0

    # A⁻¹ and J̇_c q̇ (support foot first, the swing foot's rows in DS), as Pinocchio.
    a_inv = np.empty((n, n))
    mass_matrix_inverse(mass, st.cholesky_tree, a_inv)
    jc_dot_v = np.empty(12 if double else 6)
    for i in range(2 if double else 1):
        f = sup if i == 0 else sw
        frame_classical_acceleration(
            feet[f].rot, feet[f].vel, feet[f].acc, st.sole_local_pos[f], jc_dot_v[6 * i : 6 * i + 6]
        )

    # Γ = Γ_t + Γ_c + Γ_gc (Eqs. 7 and 11, Appendices A–D), saturated, actuator order.
    f1, balancing, cop_exp_x, cop_exp_y = whole_body_torques(
        WbcDynamics(a_inv, nle, jc_dot_v, j_world, j_com, st.pin_state[1, :n]),
        WbcFrames(
            rot, sole_pos[sup], sole_pos[sw], sole_rot[sup], sole_rot[sw], pelvis_rot,
            st.sole_support[sup], st.sole_support[sw],
        ),
        WbcTargets(st.rot_des, task_ref, phase, eps, eps_on, xp_des, x_s),
        st.params,
        st.actuator_rows,
        st.tau,
    )  # fmt: skip
    meas_x, meas_y = measured_cop(
        ft_rot[0], ft_pos[0], wrench_left, ft_rot[1], ft_pos[1], wrench_right,
        st.foot_com, st.foot_weight,
    )  # fmt: skip
    meas_valid = math.isfinite(meas_x) and math.isfinite(meas_y)
    if not meas_valid:  # no foot loaded: logs hold finite numbers only
        meas_x, meas_y = 0.0, 0.0

    # The signals, in the order of SIGNALS; O_w's rot[:2, :2] is (c, −s; s, c).
    r00, r01, r10, r11 = cos_w, -sin_w, sin_w, cos_w
    out = st.signals
    out[0] = 0.0 if double else (1.0 if sup == 0 else -1.0)  # fsm_state
    out[1] = phase
    out[2], out[3] = eps, eps_on
    out[4] = d if math.isfinite(d) else 1.0
    out[5], out[6], out[7] = com_w
    out[8], out[9], out[10] = vcom_w
    out[11], out[12], out[13] = com[0], com[1], com[2]
    out[14], out[15], out[16] = vcom[0], vcom[1], vcom[2]
    out[17], out[18], out[19], out[20] = x_cp, x_s - st.r, x_s, xp_des
    out[21], out[22] = sup_x + r00 * xp_des, sup_y + r10 * xp_des  # xp_des_world
    out[23], out[24] = cop_exp_x, cop_exp_y
    out[25] = sup_x + (r00 * cop_exp_x + r01 * cop_exp_y)  # cop_exp_world
    out[26] = sup_y + (r10 * cop_exp_x + r11 * cop_exp_y)
    out[27], out[28], out[29] = meas_x, meas_y, meas_valid
    out[30], out[31], out[32] = sole_pos[sw, 0], sole_pos[sw, 1], sole_pos[sw, 2]
    out[33], out[34], out[35] = task_ref[4], task_ref[5], task_ref[6]  # swing_ref_world
    out[36] = 0.0 if double else (1.0 if sw == 1 else -1.0)  # swing_foot
    out[37], out[38], out[39] = sup_x, sup_y, sup_z
    out[40] = math.atan2(r10, r00)  # ow_yaw
    out[41], out[42], out[43] = f1, balancing, st.steps_done
    return transitions
