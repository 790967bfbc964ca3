"""Compiled per-tick kernels of the E-FSM controller: the OS-WBC of Lee et al. 2021.

One control tick of the OS-WBC (Appendices A–D) is about fifty products, inverses and
projections of matrices with 1 to 18 rows. Written with numpy, each call costs 1–5 µs of
overhead, far more than its arithmetic: the tick took ≈ 150 µs, which held the 2 kHz
experiments near real time. Why numba: fused into one compiled call the same algebra takes
a few µs, with no C extension to build. The kernels follow :mod:`.wbc` (the readable numpy
reference, checked against Pinocchio's constrained dynamics) step by step, and
``tests/test_efsm_kernels.py`` checks that they agree with it. ``cache=True`` keeps the
machine code on disk, so only the first process compiles; :func:`warm_up`, called by the
controller's reset, compiles or loads them before the first tick.

Matrices here are small, so products are plain loops: they take any memory layout
(Pinocchio's arrays are column-major views) without copies, and cost less than a BLAS call.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from walkrepro.controllers.efsm.wbc import PINV_RCOND
from walkrepro.robot import frame_jacobian

#: Rows of the two stacked foot wrenches other than the normal forces (Appendix C).
TANGENTIAL_ROWS = np.array([0, 1, 3, 4, 5, 6, 7, 9, 10, 11])
#: numpy's default cut-off of ``lstsq`` (rcond=None) for the 10 × 6 problem of Appendix C.
_LSTSQ_RCOND = float(np.finfo(np.float64).eps) * 10

#: Compiled, cached on disk; float division by zero gives inf/NaN as in numpy (which the
#: tests of singular matrices rely on) rather than raising.
_jit = numba.njit(cache=True, error_model="numpy")

# Phases of fsm.Phase, as plain ints for the compiled code.
_SSA, _DS = 1, 2


# ---- small dense algebra ------------------------------------------------------------------


@_jit
def matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a @ b."""
    n, m, p = a.shape[0], a.shape[1], b.shape[1]
    out = np.zeros((n, p))
    for i in range(n):
        for k in range(m):
            a_ik = a[i, k]
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
def lu_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a⁻¹ b for b of shape (n, p), LU with partial pivoting (as LAPACK's gesv).

    An exactly singular ``a`` gives infs/NaNs rather than an error, like the numpy kernels
    the reference uses, so callers can test the result.
    """
    n, p = a.shape[0], b.shape[1]
    lu = a.copy()
    x = b.copy()
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
    return x


@_jit
def inverse(a: np.ndarray) -> np.ndarray:
    """a⁻¹ (infs/NaNs if a is singular)."""
    return lu_solve(a, np.eye(a.shape[0]))


@_jit
def solve_vec(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a⁻¹ b for a vector b (infs/NaNs if a is singular)."""
    return lu_solve(a, b.reshape((b.shape[0], 1)).copy())[:, 0]


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
    """m⁻¹ when it provably equals m⁺, as :func:`.wbc.inv_if_well_conditioned`.

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

#: Pinocchio's Taylor-expansion threshold of log3, TaylorSeriesExpansion<double>::precision<2>.
_LOG3_PREC = float(np.finfo(np.float64).eps) ** (1.0 / 3.0)
_EPS = float(np.finfo(np.float64).eps)


@_jit
def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b of 3-vectors."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


@_jit
def _log3_singular_axis(rot: np.ndarray, i0: int, val: float) -> tuple[float, np.ndarray]:
    """Angle and axis of a rotation by ≈ π from its i0-th diagonal (Pinocchio's
    ``internal::compute_theta_axis``)."""
    i1, i2 = (i0 + 1) % 3, (i0 + 2) % 3
    sign = 1.0 if rot[i2, i1] >= rot[i1, i2] else -1.0
    s = math.sqrt(val + _EPS + _EPS * _EPS) * sign
    axis = np.empty(3)
    axis[i0] = s / 2.0
    axis[i1] = 1.0 / (2.0 * s) * (rot[i1, i0] + rot[i0, i1])
    axis[i2] = 1.0 / (2.0 * s) * (rot[i2, i0] + rot[i0, i2])
    w = 1.0 / (2.0 * s) * (rot[i2, i1] - rot[i1, i2])
    norm = math.sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2])
    return 2.0 * math.atan2(norm, w), axis / norm


@_jit
def log3(rot: np.ndarray) -> np.ndarray:
    """The rotation vector of ``rot`` [rad], as ``pinocchio.log3`` (same branches).

    The rotation is renormalized first; below θ = ε^(1/3) a Taylor expansion replaces
    θ / sin θ, and near θ = π the axis comes from the largest diagonal entry.
    """
    c0 = rot[:, 0] / math.sqrt(rot[0, 0] ** 2 + rot[1, 0] ** 2 + rot[2, 0] ** 2)
    c1 = rot[:, 1] / math.sqrt(rot[0, 1] ** 2 + rot[1, 1] ** 2 + rot[2, 1] ** 2)
    c2 = _cross(c0, c1)
    c0 = _cross(c1, c2)
    r = np.empty((3, 3))
    r[:, 0], r[:, 1], r[:, 2] = c0, c1, c2
    tr = r[0, 0] + r[1, 1] + r[2, 2]
    cos_value = (tr - 1.0) / 2.0
    prec = _LOG3_PREC
    if cos_value < -1.0 + prec:  # θ ≈ π
        vals = np.array([2.0 * r[i, i] - tr + 1.0 for i in range(3)])
        if vals[0] >= vals[1]:
            i0 = 0 if vals[0] >= vals[2] else 2
        else:
            i0 = 1 if vals[1] >= vals[2] else 2
        theta, axis = _log3_singular_axis(r, i0, vals[i0])
        return theta * axis
    acos_expansion = math.sqrt(2.0 * (1.0 - cos_value) + _EPS * _EPS)
    if tr <= 3.0 - prec:
        theta = math.acos(cos_value) if tr >= -1.0 + prec else math.pi - acos_expansion
    else:
        theta = acos_expansion
    antisym = np.array(
        [0.5 * (r[2, 1] - r[1, 2]), 0.5 * (r[0, 2] - r[2, 0]), 0.5 * (r[1, 0] - r[0, 1])]
    )
    sq = antisym[0] ** 2 + antisym[1] ** 2 + antisym[2] ** 2
    if theta >= prec:
        t = theta / math.sin(theta)
    else:
        t = 1.0 + sq / 6.0 + sq * sq * 3.0 / 40.0
    return t * antisym


@_jit
def orientation_error(rot_des: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """log3(R_des Rᵀ), the orientation error in world axes [rad]."""
    return log3(matmul_bt(rot_des, rot))


# ---- Appendix A: contact dynamics and the task hierarchy ---------------------------------


@_jit
def contact_dynamics(
    a_inv: np.ndarray, nle: np.ndarray, jc: np.ndarray, jc_dot_v: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]:
    """The contact-consistent quantities of Appendices A and B, as :func:`.wbc.contact_dynamics`.

    Uses the symmetry of A⁻¹ and Λ_c to form the products row by row (J_c A⁻¹ rather than
    A⁻¹ J_cᵀ), which the compiler vectorizes.

    Returns:
        P (n, n), W⁺ (k, k), Ψ = J̄_cᵀSᵀ (c, k), f_bias (c,), Γ_gc (k,), W's eigenvectors
        (k, k), and whether W⁺ was built from them (else they are not computed).
    """
    c, n = jc.shape
    jc_a_inv = matmul(jc, a_inv)  # J_c A⁻¹ = (A⁻¹ J_cᵀ)ᵀ, shape (c, n)
    lam_c = inverse(matmul_bt(jc_a_inv, jc))  # Λ_c = (J_c A⁻¹ J_cᵀ)⁻¹
    if not math.isfinite(np.trace(lam_c)):
        raise np.linalg.LinAlgError("singular contact inertia J_c A⁻¹ J_cᵀ")
    jbar_t = matmul(lam_c, jc_a_inv)  # J̄_cᵀ = Λ_c J_c A⁻¹, shape (c, n)
    P = a_inv.copy()  # A⁻¹(I − J_cᵀ J̄_cᵀ) = A⁻¹ − J̄_c (J_c A⁻¹)
    for r in range(c):
        for i in range(n):
            f = jbar_t[r, i]
            for j in range(n):
                P[i, j] -= f * jc_a_inv[r, j]
    W = P[6:, 6:].copy()
    well, W_pinv = inv_if_well_conditioned(W) if c <= 6 else (False, W)
    w_eigvec = np.empty((0, 0))  # only built with W⁺ from the eigen-decomposition
    if not well:
        W_pinv, w_eigvec = pinv_eigh(W)
    # Eq. (8): f_c = J̄_cᵀ (SᵀΓ − b − g) + Λ_c J̇_c q̇.
    psi = jbar_t[:, 6:].copy()  # J̄_cᵀ Sᵀ, shape (c, k)
    f_bias = matvec(lam_c, jc_dot_v) - matvec(jbar_t, nle)
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

    As ``wbc.prioritized_task(cd, phi, wbc.null_space_t(cd, prec_phi))``, or with no
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
    """Three prioritized tasks of Eq. (11), as :func:`.wbc.task_hierarchy`.

    Returns:
        torque map [J̃_1ᵀ, Ñ_1ᵀ J̃_2ᵀ, Ñ_12ᵀ J̃_3ᵀ] (k, m), and Λ_1, Λ_2, Λ_3.
    """
    k, m = W.shape[0], phi.shape[0]
    m12 = m1 + m2
    jt = matmul_bt(W_pinv, phi)  # J̃ᵀ of every row, shape (k, m)
    gram = matmul(phi, jt)  # Φ W⁺ Φᵀ
    ok1, lam1 = inv_if_well_conditioned(gram[:m1, :m1].copy())
    ok12, lam12 = inv_if_well_conditioned(gram[:m12, :m12].copy())
    if ok1 and ok12:
        # torque_map = J̃ᵀ (I − U), U strictly block-upper:
        # Ñ_1ᵀ J̃_2ᵀ = J̃_2ᵀ − J̃_1ᵀ Λ_1 G_12, Ñ_12ᵀ J̃_3ᵀ = J̃_3ᵀ − J̃_12ᵀ Λ_12 G_12,3.
        u = np.zeros((m, m))
        u[:m1, m1:m12] = matmul(lam1, gram[:m1, m1:m12])
        u[:m12, m12:] = matmul(lam12, gram[:m12, m12:])
        torque_map = jt - matmul(jt, u)
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
    """K of Eq. (10), as :func:`.wbc.grasp_map`; ``contact_points`` has shape (feet, 3)."""
    n_feet = contact_points.shape[0]
    kmap = np.zeros((6, 6 * n_feet))
    for foot in range(n_feet):
        d = np.empty(3)  # distance from O's origin, O axes
        for i in range(3):
            d[i] = (
                rot_o[0, i] * (contact_points[foot, 0] - origin[0])
                + rot_o[1, i] * (contact_points[foot, 1] - origin[1])
                + rot_o[2, i] * (contact_points[foot, 2] - origin[2])
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

    As :func:`.wbc.redistribution_torque` with the leaving foot's rows first
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
    alpha = solve_vec(g[:6].copy(), f_ref - f_now[:6])  # Y_c f_c^cor (Eq. 16)
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
    decoupled: bool,
) -> np.ndarray:
    """F_2 = Λ ẍ* (Eq. 6) with the swing-foot wrench F_s saturated and scaled.

    As ``EfsmController._task2_force`` (see it for why); ``scale_swing`` is ε in SSA, else 1.
    """
    f_free = matvec(lam, acc)  # Λ ẍ*, unbounded
    if double:
        return f_free
    fs = f_free[3:9].copy()
    if decoupled:
        cut = np.empty(3)
        for i in range(3):
            fs[i] = _clip(fs[i], f_max)
            cut[i] = fs[i] - f_free[3 + i]
        if np.any(cut != 0.0):
            fs[3:] += matvec(lam[6:9, 3:6], solve_vec(lam[3:6, 3:6].copy(), cut))
    for i in range(3):
        fs[i] = _clip(fs[i], f_max)
        fs[3 + i] = _clip(fs[3 + i], m_max)
    if scale_swing != 1.0:
        fs *= scale_swing
    cut = fs - f_free[3:9]
    f2 = f_free
    if np.any(cut != 0.0):
        f2[:3] += matvec(lam[0:3, 3:9], solve_vec(lam[3:9, 3:9].copy(), cut))
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


@_jit
def whole_body_torques(
    a_inv: np.ndarray,
    nle: np.ndarray,
    j_world: np.ndarray,
    jc_dot_v: np.ndarray,
    support_sup: np.ndarray,
    support_sw: np.ndarray,
    j_com: np.ndarray,
    v: np.ndarray,
    rot: np.ndarray,
    p_sup: np.ndarray,
    p_sw: np.ndarray,
    sole_rot_sup: np.ndarray,
    sole_rot_sw: np.ndarray,
    pelvis_rot: np.ndarray,
    rot_des: np.ndarray,
    task_ref: np.ndarray,
    phase: int,
    eps: float,
    eps_onset: float,
    xp_des: float,
    x_s: float,
    params: np.ndarray,
    actuator_rows: np.ndarray,
    tau: np.ndarray,
) -> tuple[float, bool, float, float]:
    """Γ = Γ_t + Γ_c + Γ_gc (Eq. 7) of one tick, as ``EfsmController.step`` computes it.

    The three tasks of Eq. (11): task 1 the CoM x-force for x_p^des (Appendix D-1); task 2
    CoM y/z, pelvis yaw and, out of DS, the 6-D swing foot; task 3 pelvis roll/pitch, plus
    F_3^bal (Appendix D-3). Γ_c redistributes the DS wrenches (Appendix C). Contacts: the
    support sole, plus the swing sole in DS (its rows second).

    Args:
        a_inv: A⁻¹, shape (n, n).
        nle: b + g, shape (n,).
        j_world: Pinocchio's joint Jacobians ``data.J`` (see :func:`walkrepro.robot.frame_jacobian`). The
            pelvis (the rigid upper body) is the floating base: its first six columns.
        jc_dot_v: J̇_c q̇ of the contacts, world axes, shape (6 or 12,).
        support_sup, support_sw: the velocity coordinates moving each sole, shape (n,).
        j_com: CoM Jacobian, world axes, shape (3, n).
        v: generalized velocity, shape (n,).
        rot: world-from-O_w rotation.
        p_sup, p_sw: support and swing sole centres [m]; p_sup is the origin of O_w.
        sole_rot_sup, sole_rot_sw: world-from-sole rotations.
        pelvis_rot: world-from-pelvis rotation.
        rot_des: orientation targets (Table II), shape (2, 3, 3): pelvis, swing sole.
        task_ref: shape (7,): [0:2] CoM y, z error in O_w [m]; [2:4] CoM y, z velocity in
            O_w [m/s]; [4:7] swing-sole position reference [m] (unused in DS).
        phase: E-FSM phase (fsm.Phase as int).
        eps: ε; eps_onset: ε's onset ramp in DS (see ``wbc.redistribution_torque``).
        xp_des: desired CoP along x of O_w [m]; x_s: swing-foot centre along x of O_w [m].
        params: k_p, k_v, F_s force bound [N], F_s moment bound [Nm], decoupled saturation
            (1/0), balancing (1/0), CoP safety margin [m], torque limit [Nm], half sole
            length and width [m].
        actuator_rows: joint-torque row of each actuator, shape (k,).
        tau: out: actuator torques, saturated, shape (k,) [Nm].

    Returns:
        F_1 (the CoM x-force [N]), whether F_3^bal acted, and the expected CoP (x, y) in
        O_w [m] (NaN if unloaded).
    """
    kp, kv, f_max, m_max = params[0], params[1], params[2], params[3]
    decoupled, balance, margin, tau_lim = params[4] != 0.0, params[5] != 0.0, params[6], params[7]
    n = a_inv.shape[0]
    double = phase == _DS

    # Contact and task Jacobians, world axes.
    jc = np.empty((12 if double else 6, n))
    frame_jacobian(j_world, support_sup, p_sup, jc[0:6])
    j_swing = np.empty((6, n))
    frame_jacobian(j_world, support_sw, p_sw, jc[6:12] if double else j_swing)
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
    phi = matmul(j_all, P[:, 6:])  # Φ = J P Sᵀ
    tmap, _, lam2, lam3 = task_hierarchy(P[6:, 6:].copy(), W_pinv, phi, 1, m2)
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
    fcb = matvec(kmap, matvec(psi, gamma_gc) + f_bias)
    f1 = -((fc23[2] + fcb[2]) * xp_des + fcb[4]) / kt[4, 0]  # Eqs. (20)-(21)
    f_all[0] = f1

    # Balancing (Appendix D-3): expected CoP out of the shrunk polygon -> F_3^bal.
    fc = kt[:, 0] * f1 + fc23 + fcb
    balancing = False
    if balance:
        kt3 = kt[:, m2 + 1 :].copy()
        f3 = f_all[m2 + 1 :].copy()
        balancing, f3_new = balance_force(
            fc, kt3, f3, rot, sole_rot_sup, params[8:10], margin, x_s if double else math.nan
        )
        if balancing:
            fc = fc + matvec(kt3, f3_new - f3)  # F_3 replaced
            f_all[m2 + 1 :] = f3_new
    gamma = matvec(tmap, f_all) + gamma_gc  # Γ_t + Γ_gc

    # Contact wrench redistribution in DS (Appendix C) with ε (§IV-B).
    if double:
        f_now = matvec(psi, gamma) + f_bias
        gamma_c, _ = redistribution_torque(psi, w_eigvec, f_now, eps, eps_onset, p_sup - p_sw)
        gamma += gamma_c  # Γ = Γ_t + Γ_c + Γ_gc, Eq. (7)
        fc = fc + matvec(kpsi, gamma_c)
    for i in range(tau.shape[0]):
        tau[i] = min(max(gamma[actuator_rows[i]], -tau_lim), tau_lim)
    cop_x, cop_y = cop_of(fc)
    return f1, balancing, cop_x, cop_y


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
        f = np.zeros(3)
        tq = np.zeros(3)
        for i in range(3):  # world axes
            for j in range(3):
                f[i] += rot[i, j] * wrench[j]
                tq[i] += rot[i, j] * wrench[3 + j]
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
