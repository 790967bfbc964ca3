"""The contact-consistent operational-space whole-body controller (OS-WBC), §IV and
Appendices A–D of Lee et al. 2021 (after Park & Khatib [25] and Lee et al. [35]).

Notation (Appendix A), with n = 6 + k generalized velocities (the pelvis, the rigid upper
body, is the floating base: the first six), k actuated joints, S = [0 I] the joint
selection and c contact rows:

    P   = A⁻¹ (I − J_cᵀ J̄_cᵀ)               (n × n, the contact-consistent inverse inertia)
    W   = S P Sᵀ                           (k × k)
    Φ   = J P Sᵀ                           (m × k, task acceleration per joint torque)
    J̃ᵀ  = W⁺ Φᵀ                            (k × m, torque of a task force)
    Λ   = (Φ W⁺ Φᵀ)⁺                        (m × m, task inertia)
    Ñᵀ  = I − J̃ᵀ Λ Φ W⁺ W                   (k × k, null-space projector)

so that a torque Γ = J̃ᵀ F gives the task acceleration Λ⁻¹ F and Φ Ñᵀ = 0 (the task
acceleration is blind to any torque Ñᵀ Γ_0). The hierarchy of Eq. (11) uses the prioritized
projector Ñ_{12}ᵀ for the third task. Γ = Γ_t + Γ_c + Γ_gc (Eq. 7): the task torques, the
contact redistribution (Appendix C) and the gravity/Coriolis compensation (Appendix B).

Everything here is compiled with numba (``@``, ``np.linalg``) and is what the controller's
tick runs (:func:`.kernels.tick` calls :func:`whole_body_torques`). The matrices are world
axes unless a name says otherwise (``_w``: the walking frame O_w of §III-A1). The tests check
these functions against Pinocchio's constrained dynamics (``tests/test_efsm_wbc.py``).
"""

from __future__ import annotations

import math
from enum import IntEnum
from typing import NamedTuple

import numba
import numpy as np

from walkrepro.papers.lee2021.fsm import Phase
from walkrepro.papers.lee2021.tasks import (
    ANGULAR,
    LINEAR,
    N_QUANTITIES,
    SPATIAL,
    Quantity,
    TaskLayout,
    TaskSet,
    stack_tasks,
)
from walkrepro.sim.robot import frame_jacobian, log3

#: Relative singular-value cut-off of the pseudo-inverses (W is rank-deficient in DS).
PINV_RCOND = 1e-9
#: numpy's cut-off of ``lstsq(rcond=None)`` for the 10 × 6 problem of Appendix C.
LSTSQ_RCOND = float(np.finfo(np.float64).eps) * 10
#: The rows of a wrench (f, m), world or O axes, and of a point or vector (x, y, z).
FX, FY, FZ, MX, MY, MZ = range(6)
X, Y, Z = FX, FY, FZ
#: Its force and moment; the x and y moments (the CoP's, Eqs. 18, 22, 28); x and y.
FORCE, MOMENT, MOMENT_XY, XY = LINEAR, ANGULAR, slice(MX, MZ), slice(X, Z)
#: The floating base's velocity coordinates (the pelvis's, the first six).
BASE = slice(0, SPATIAL)
#: The actuated joints' velocity coordinates, S's rows (after the base).
JOINTS = slice(SPATIAL, None)
#: The DS contact rows: the leaving (support) foot's wrench, then the landing foot's.
LEAVING, LANDING = slice(0, SPATIAL), slice(SPATIAL, 2 * SPATIAL)
#: W's null space in DS: the second foot's six contact constraints (Eq. 14).
NULL_DIM = SPATIAL
#: Rows of the two stacked foot wrenches other than the normal forces (Appendix C).
TANGENTIAL_ROWS = np.flatnonzero(np.tile(np.arange(SPATIAL) != FZ, 2))


class Saturation(IntEnum):
    """How F_s meets its bound (:func:`task2_force`; ``EfsmParams.fs_saturation``)."""

    CLIP = 0  #: each row of Λ ẍ* clipped alone
    DECOUPLED_CLIP = 1  #: the force rows clipped, the orientation acceleration kept
    UNIFORM = 2  #: the linear swing acceleration scaled until every force row is in bounds


CLIP, DECOUPLED_CLIP, UNIFORM = Saturation

#: Compiled, cached on disk; float division by zero gives inf/NaN as in numpy (the tests of
#: singular matrices rely on it) rather than raising.
_jit = numba.njit(cache=True, error_model="numpy")

#: The same, inlined into its caller in numba's IR (the same operations, so the same
#: results): for the functions that take the tick's large records, which a compiled call
#: would otherwise pass by value, each array's reference count raised and dropped per call.
_inline = numba.njit(cache=True, error_model="numpy", inline="always")


# ---- pseudo-inverses ---------------------------------------------------------------------


@_jit
def inv_if_well_conditioned(m: np.ndarray) -> tuple[bool, np.ndarray]:
    """m⁻¹ of a symmetric positive-definite m when it equals m⁺ (cut-off PINV_RCOND).

    The pseudo-inverse drops no singular value when cond(m) < 1 / PINV_RCOND. For a
    positive-definite m, cond(m) = λ_max / λ_min < tr(m) tr(m⁻¹), so a product of traces
    below the bound proves that the plain inverse is the pseudo-inverse (up to rounding).

    Returns:
        (True, m⁻¹), or (False, anything) when this test cannot prove it (the caller then
        takes m⁺).
    """
    try:
        m_inv = np.ascontiguousarray(np.linalg.inv(m))
    except Exception:  # exactly singular
        return False, np.zeros((m.shape[0], m.shape[0]))
    tr, tr_inv = np.trace(m), np.trace(m_inv)
    return (tr > 0.0 and tr_inv > 0.0 and tr * tr_inv * PINV_RCOND < 1.0), m_inv


@_jit
def pinv_symmetric(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """m⁺ of a symmetric m from its eigen-decomposition m = V diag(λ) Vᵀ (as
    ``np.linalg.pinv(m, PINV_RCOND, hermitian=True)``).

    Returns:
        m⁺ = V diag(1/λ, 0 where |λ| ≤ PINV_RCOND max|λ|) Vᵀ, and V, the eigenvectors by
        ascending eigenvalue, shape (k, k).
    """
    eigval, eigvec = np.linalg.eigh(m)
    eigvec = np.ascontiguousarray(eigvec)
    keep = np.abs(eigval) > PINV_RCOND * np.abs(eigval).max()
    inv_val = np.where(keep, 1.0 / eigval, 0.0)
    return (eigvec * inv_val) @ eigvec.T, eigvec


@_jit
def least_squares(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """argmin_x ‖a x − b‖ of a tall a (as ``np.linalg.lstsq(a, b, rcond=None)[0]``).

    With a = Q R of full column rank, x = R⁻¹ Qᵀ b; a nearly rank-deficient a (a diagonal
    entry of R below 1e-8 of the largest) goes to ``np.linalg.lstsq``, whose cut-off then
    picks the minimum-norm solution. Why not lstsq always: numba's (LAPACK's SVD-based
    gelsd) takes ≈ 7–15 µs for the 10 × 6 problem of Appendix C, QR ≈ 2 µs.
    """
    q, r = np.linalg.qr(a)
    diag = np.abs(np.diag(r))
    if diag.min() <= 1e-8 * diag.max():
        return np.linalg.lstsq(a, b, LSTSQ_RCOND)[0]
    return np.linalg.solve(r, q.T @ b)


# ---- Appendices A and B: contact-consistent dynamics ------------------------------------


class ContactDynamics(NamedTuple):
    """Contact-constrained dynamics at one instant (Appendices A and B).

    Attributes:
        P: A⁻¹(I − J_cᵀ J̄_cᵀ), shape (n, n).
        W: S P Sᵀ, shape (k, k).
        W_pinv: W⁺, shape (k, k).
        psi: Ψ = J̄_cᵀ Sᵀ, contact wrench per joint torque, shape (c, k) (Eq. 8).
        f_bias: −J̄_cᵀ(b + g) + Λ_c J̇_c q̇, the contact wrench at Γ = 0, shape (c,) (Eq. 8).
        gamma_gc: Γ_gc, the gravity/Coriolis compensation torque, shape (k,) (Appendix B).
        w_eigvec: W's eigenvectors by ascending eigenvalue, shape (k, k), when W⁺ was built
            from them (rank-deficient W, as in DS); shape (0, 0) otherwise.
    """

    P: np.ndarray
    W: np.ndarray
    W_pinv: np.ndarray
    psi: np.ndarray
    f_bias: np.ndarray
    gamma_gc: np.ndarray
    w_eigvec: np.ndarray


@_jit
def contact_dynamics(
    a_inv: np.ndarray, nle: np.ndarray, jc: np.ndarray, jc_dot_v: np.ndarray
) -> ContactDynamics:
    """The contact-consistent quantities of Appendices A and B.

    W⁺ is the plain inverse when W is provably well conditioned (one foot: the six contact
    constraints only fix the floating base); otherwise, as with both feet where W has six
    zero eigenvalues, the pseudo-inverse from W's eigen-decomposition, whose null space
    :func:`redistribution_torque` uses.

    Args:
        a_inv: A⁻¹, inverse joint-space inertia, shape (n, n).
        nle: b + g, Coriolis/centrifugal and gravity forces, shape (n,).
        jc: contact Jacobian J_c (world axes at each sole centre), shape (c, n); its wrench
            dual: the forces and moments the feet apply to the ground.
        jc_dot_v: J̇_c q̇, shape (c,).

    Raises:
        LinAlgError: J_c A⁻¹ J_cᵀ is singular.
    """
    jc_a_inv = jc @ a_inv  # J_c A⁻¹ = (A⁻¹ J_cᵀ)ᵀ, A⁻¹ symmetric, shape (c, n)
    lam_c = np.linalg.inv(jc_a_inv @ jc.T)  # Λ_c = (J_c A⁻¹ J_cᵀ)⁻¹
    jbar_t = lam_c @ jc_a_inv  # J̄_cᵀ = Λ_c J_c A⁻¹, shape (c, n)
    P = a_inv - jbar_t.T @ jc_a_inv  # A⁻¹(I − J_cᵀ J̄_cᵀ) = A⁻¹ − J̄_c J_c A⁻¹
    W = np.ascontiguousarray(P[JOINTS, JOINTS])  # S P Sᵀ
    well = False
    W_pinv = np.zeros_like(W)
    w_eigvec = np.zeros((0, 0))
    if jc.shape[0] <= SPATIAL:  # one foot
        well, W_pinv = inv_if_well_conditioned(W)
    if not well:
        W_pinv, w_eigvec = pinv_symmetric(W)
    # Eq. (8): f_c = J̄_cᵀ (SᵀΓ − b − g) + Λ_c J̇_c q̇, the wrench the feet exert on the ground.
    psi = np.ascontiguousarray(jbar_t[:, JOINTS])  # J̄_cᵀ Sᵀ
    f_bias = lam_c @ jc_dot_v - jbar_t @ nle
    # Appendix B: S q̈ = W Γ − S P (b + g) − S A⁻¹ J_cᵀ Λ_c J̇_c q̇; Γ_gc = W⁺ (S P (b + g)
    # + S J̄_c J̇_c q̇) holds the joints still.
    bias_acc = P[JOINTS] @ nle + psi.T @ jc_dot_v
    gamma_gc = W_pinv @ bias_acc
    return ContactDynamics(P, W, W_pinv, psi, f_bias, gamma_gc, w_eigvec)


# ---- Appendix A and Eq. (11): the task hierarchy -----------------------------------------


@_inline
def task_phi(cd: ContactDynamics, jacobian: np.ndarray) -> np.ndarray:
    """Φ = J P Sᵀ, the task acceleration per joint torque, shape (m, k) (Appendix A)."""
    return jacobian @ np.ascontiguousarray(cd.P[:, JOINTS])


@_jit
def null_space_t(cd: ContactDynamics, phi: np.ndarray) -> np.ndarray:
    """Ñᵀ = I − J̃ᵀ Λ Φ W⁺ W of the tasks stacked in ``phi`` (Appendix A), shape (k, k)."""
    jt = cd.W_pinv @ phi.T  # J̃ᵀ = W⁺ Φᵀ
    lam = np.linalg.pinv(phi @ jt, PINV_RCOND)  # Λ = (Φ W⁺ Φᵀ)⁺
    return np.eye(cd.W.shape[0]) - jt @ lam @ phi @ cd.W_pinv @ cd.W


class Task(NamedTuple):
    """One prioritized operational-space task, projected into the null space of the tasks
    above it (Eq. 11).

    Attributes:
        torque_map: Ñ_precᵀ J̃ᵀ, the torque per task force, shape (k, m).
        lam: Λ of the prioritized task, (Φ Ñ_precᵀ W⁺ Φᵀ)⁺, shape (m, m).
    """

    torque_map: np.ndarray
    lam: np.ndarray


@_jit
def prioritized_task(cd: ContactDynamics, phi: np.ndarray, n_prec_t: np.ndarray) -> Task:
    """A task below the tasks whose null-space projector is ``n_prec_t`` (Eq. 11); the
    first task has Ñ_precᵀ = I."""
    torque_map = n_prec_t @ (cd.W_pinv @ phi.T)  # Ñ_precᵀ J̃ᵀ
    return Task(torque_map, np.ascontiguousarray(np.linalg.pinv(phi @ torque_map, PINV_RCOND)))


class Hierarchy(NamedTuple):
    """The prioritized tasks of Eq. (11), their rows stacked by priority level.

    Attributes:
        torque_map: [J̃_1ᵀ, Ñ_1ᵀ J̃_2ᵀ, Ñ_12ᵀ J̃_3ᵀ, …], the torque per task force, shape
            (k, m); Γ_t = torque_map [F_1; F_2; …] (Eq. 11).
        lam: Λ_i of each prioritized level on its rows' diagonal block, zero elsewhere,
            shape (m, m).
    """

    torque_map: np.ndarray
    lam: np.ndarray


@_jit
def task_hierarchy(
    cd: ContactDynamics, phi: np.ndarray, first: np.ndarray, end: np.ndarray
) -> Hierarchy:
    """The prioritized tasks of Eq. (11), level i the rows ``first[i]`` … ``end[i]`` − 1 of
    ``phi`` (highest priority first).

    The same tasks as ``prioritized_task(cd, Φ_i, Ñ_<iᵀ)`` (Ñ_<iᵀ the projector of all the
    rows above level i; I for the first), without forming the k × k projectors: with
    J̃ᵀ = W⁺Φᵀ, G = Φ W⁺ Φᵀ and W⁺ W W⁺ = W⁺,

        Ñ_<iᵀ J̃_iᵀ = J̃_iᵀ − J̃_<iᵀ Λ_<i G_<i,i,   Λ_<i = (G_<i,<i)⁺,

    and Φ_i Ñ_<iᵀ J̃_iᵀ is the Schur complement of G_<i,<i in G_≤i,≤i, whose inverse Λ_i is
    the lower-right block of Λ_≤i (by eigenvalue interlacing no worse conditioned than
    G_≤i,≤i, so that block is also its pseudo-inverse); the last level inverts its Schur
    complement itself.

    The inverses are plain inverses when that provably equals the pseudo-inverse
    (:func:`inv_if_well_conditioned`); otherwise this takes the projector form.
    """
    m = phi.shape[0]
    jt = cd.W_pinv @ phi.T  # J̃ᵀ of every row, shape (k, m)
    gram = phi @ jt  # G = Φ W⁺ Φᵀ
    torque_map, lam = jt.copy(), np.zeros((m, m))
    lam_above = np.zeros((0, 0))  # Λ_<i
    ok = True
    for level in range(first.size):
        s, e = first[level], end[level]
        if s > 0:  # Ñ_<iᵀ J̃_iᵀ
            torque_map[:, s:e] -= jt[:, :s] @ (lam_above @ gram[:s, s:e])
        if e < m:
            ok, lam_above = inv_if_well_conditioned(gram[:e, :e])  # Λ_≤i
            lam[s:e, s:e] = lam_above[s:, s:]
        else:
            ok, lam_i = inv_if_well_conditioned(phi[s:e] @ torque_map[:, s:e])
            lam[s:e, s:e] = lam_i
        if not ok:
            break
    if ok:
        return Hierarchy(torque_map, lam)
    # Ill-conditioned: the pseudo-inverses of the projector form (Appendix A).
    k = cd.W.shape[0]
    for level in range(first.size):
        s, e = first[level], end[level]
        n_above_t = null_space_t(cd, phi[:s]) if s > 0 else np.eye(k)
        task = prioritized_task(cd, phi[s:e], n_above_t)
        torque_map[:, s:e] = task.torque_map
        lam[s:e, s:e] = task.lam
    return Hierarchy(torque_map, lam)


# ---- Appendices C and D: wrenches, CoP, redistribution ------------------------------------


@_jit
def skew(d: np.ndarray) -> np.ndarray:
    """[d]×, the matrix of d × (·)."""
    x, y, z = d[X], d[Y], d[Z]
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


@_jit
def grasp_map(rot_o: np.ndarray, origin: np.ndarray, contact_points: np.ndarray) -> np.ndarray:
    """K of Eq. (10): the resultant wrench in frame O of stacked world-axes foot wrenches.

    Args:
        rot_o: world-from-O rotation, shape (3, 3).
        origin: O's origin in the world [m].
        contact_points: each contact's wrench reference point in the world [m], (feet, 3).

    Returns:
        K, shape (6, 6 · feet): per foot [[Rᵀ, 0], [[d]× Rᵀ, Rᵀ]], d = Rᵀ (p − o) in O axes.
    """
    rt = np.ascontiguousarray(rot_o.T)
    feet = contact_points.shape[0]
    kmap = np.zeros((SPATIAL, feet, SPATIAL))  # [resultant row, foot, foot's wrench row]
    for foot in range(feet):
        d = rt @ (contact_points[foot] - origin)  # [m], O axes
        kmap[FORCE, foot, FORCE] = rt
        kmap[MOMENT, foot, FORCE] = skew(d) @ rt
        kmap[MOMENT, foot, MOMENT] = rt
    return kmap.reshape((SPATIAL, feet * SPATIAL))


@_jit
def cop_of(wrench_o: np.ndarray) -> tuple[float, float]:
    """CoP (x, y) in O of a resultant wrench (f, m) in O, Eqs. (18) and (22) [m]:
    (−m_y / f_z, m_x / f_z); NaN when unloaded."""
    fz = wrench_o[FZ]
    if abs(fz) < 1e-9:
        return math.nan, math.nan
    return -wrench_o[MY] / fz, wrench_o[MX] / fz


@_jit
def com_force_for_cop(xp_des: float, q1: float, fz_rest: float, my_bias: float) -> float:
    """The CoM x-force realising x_p^des, Appendix D-1 (Eqs. 20–21) [N]:

        ˣF_m = −((ᶻF_c|2 + ᶻF_c|3 + ᶻF_c|b) x_p^des + ʸM_c|b) / Q_1.

    Args:
        xp_des: desired CoP along x of O_w [m].
        q1: Q_1, the y moment about O_w per unit task-1 force [m].
        fz_rest: ᶻF_c|2 + ᶻF_c|3 + ᶻF_c|b, the normal force of tasks 2, 3 and the bias [N].
        my_bias: ʸM_c|b, the y moment of the bias wrench [Nm].
    """
    return -(fz_rest * xp_des + my_bias) / q1


@_jit
def redistribution_torque(
    cd: ContactDynamics,
    f_now: np.ndarray,
    eps: float,
    eps_onset: float,
    lever: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Γ_c of Appendix C (Eqs. 14–16) and the leaving foot's reference wrench.

    The null space of W (its six near-zero eigen-directions V₂, Eq. 14) changes the contact
    wrenches without changing any task or the resultant. The correction f_c^cor is chosen
    as in [35]: first the distribution that minimizes both feet's tangential forces and
    moments, then the leaving foot's wrench is scaled by ε (§IV-B) so that it unloads
    smoothly before DS ends. With ``eps_onset`` < 1 the reference is blended toward the
    leaving foot carrying the whole resultant (the landing foot unloaded, as in the SSA
    just before), so that the wrenches also start continuously when DS begins.

    Args:
        cd: contact dynamics with both feet in contact (c = 12), W⁺ from its eigenvectors.
        f_now: the contact wrenches the other torques produce, shape (12,), the leaving
            foot's rows first (world axes, moments about each sole centre) [N, Nm].
        eps: the state-transition parameter ε.
        eps_onset: blend in [0, 1] from "all on the leaving foot" (0) to the optimum (1).
        lever: leaving minus landing sole centre [m].

    Returns:
        Γ_c, shape (k,) [Nm], and the leaving foot's reference wrench, shape (6,).
    """
    # The six smallest eigenvectors: W's null space (Eq. 14).
    v2 = np.ascontiguousarray(cd.w_eigvec[:, :NULL_DIM])
    g = cd.psi @ v2  # wrench change per α, shape (12, 6)
    alpha_opt = least_squares(g[TANGENTIAL_ROWS], -f_now[TANGENTIAL_ROWS])
    target = f_now[LEAVING] + g[LEAVING] @ alpha_opt  # the leaving foot's rows of the optimum
    if eps_onset < 1.0:
        # The whole resultant about the leaving sole centre: the landing foot's moment
        # moves by (p_land − p_leave) × f_land.
        f_land = f_now[LANDING].copy()
        f_land[MOMENT] += np.cross(-lever, f_land[FORCE])
        target = eps_onset * target + (1.0 - eps_onset) * (f_now[LEAVING] + f_land)
    f_ref = eps * target
    alpha = np.linalg.solve(g[LEAVING], f_ref - f_now[LEAVING])  # Y_c f_c^cor (Eq. 16)
    return v2 @ alpha, f_ref


@_jit
def uniform_scale(a: np.ndarray, b: np.ndarray, f_max: float) -> float:
    """The largest s ∈ [0, 1] for which every row s a_i + b_i stays within ±f_max."""
    s = 1.0
    for i in range(a.size):
        if a[i] > 0.0:
            s = min(s, (f_max - b[i]) / a[i])
        elif a[i] < 0.0:
            s = min(s, (-f_max - b[i]) / a[i])
    return max(s, 0.0)


@_jit
def task2_force(
    lam: np.ndarray,
    acc: np.ndarray,
    first: int,
    n_lin: int,
    n_ang: int,
    scale_swing: float,
    f_max: float,
    m_max: float,
    saturation: int,
) -> np.ndarray:
    """F = Λ ẍ* (Eq. 6) of one priority level, its swing-foot wrench F_s saturated and
    scaled by ε.

    F_s (the level's rows ``first`` …: ``n_lin`` force, then ``n_ang`` moment components) is
    bounded component-wise (§V-B) and multiplied by ``scale_swing`` (ε in SSA, §IV-C). With
    :data:`UNIFORM` the bound is met by scaling the commanded linear swing acceleration (so
    every force component stays within it and the foot keeps heading for its target); with
    :data:`DECOUPLED_CLIP` the force rows are clipped one by one, with the orientation
    acceleration kept: clipping the force rows of Λ ẍ* alone (:data:`CLIP`) leaves in the
    moment rows the coupling term of an acceleration that is no longer produced, which
    pitched the swing foot 14° toe-up in free swing and 35° against the obstacle. The
    level's other forces (CoM, yaw) are then computed with the swing-foot acceleration that
    this bounded F_s actually produces, so that they do not carry the coupling of an
    unbounded one.

    Args:
        lam: Λ of the level, shape (m, m); acc: ẍ*, shape (m,).
        first, n_lin, n_ang: F_s's rows (none in DS: F = Λ ẍ*).
        scale_swing: factor on F_s (ε in SSA, else 1).
        f_max, m_max: the bounds of each force [N] and moment [Nm] component of F_s.
        saturation: :class:`Saturation`.
    """
    f_free = lam @ acc  # Λ ẍ*, unbounded
    n_sw = n_lin + n_ang
    if n_sw == 0:
        return f_free
    swing, lin = slice(first, first + n_sw), slice(first, first + n_lin)
    ang = slice(first + n_lin, first + n_sw)
    lam_ll = np.ascontiguousarray(lam[lin, lin])
    if saturation == Saturation.UNIFORM:
        # F_i = s a_i + b_i (a: the part of Λ ẍ* due to ẍ_s*, b: the rest).
        a = lam_ll @ acc[lin]
        s = uniform_scale(a, f_free[lin] - a, f_max)
        if s < 1.0:
            acc_bounded = acc.copy()
            acc_bounded[lin] *= s
            f_free = lam @ acc_bounded
    fs = f_free[swing].copy()  # F_s: force, moment
    if saturation == Saturation.DECOUPLED_CLIP:
        fs[:n_lin] = np.clip(fs[:n_lin], -f_max, f_max)
        cut = fs[:n_lin] - f_free[lin]
        if np.any(cut != 0.0):  # keep the orientation acceleration: Λ_s couples the rows
            fs[n_lin:] += np.ascontiguousarray(lam[ang, lin]) @ np.linalg.solve(lam_ll, cut)
    fs[:n_lin] = np.clip(fs[:n_lin], -f_max, f_max)
    fs[n_lin:] = np.clip(fs[n_lin:], -m_max, m_max)
    fs *= scale_swing
    cut = fs - f_free[swing]
    f = f_free
    if np.any(cut != 0.0):  # the other forces of what F_s produces
        x = np.linalg.solve(np.ascontiguousarray(lam[swing, swing]), cut)
        end = first + n_sw  # the level's other rows: before and after F_s's
        if first > 0:
            f[:first] += np.ascontiguousarray(lam[:first, swing]) @ x
        if end < acc.size:
            f[end:] += np.ascontiguousarray(lam[end:, swing]) @ x
    f[swing] = fs
    return f


@_jit
def balance_force(
    fc: np.ndarray,
    kpsi3: np.ndarray,
    f3: np.ndarray,
    rot_w: np.ndarray,
    sole_rot: np.ndarray,
    half_sole: np.ndarray,
    margin: float,
    x_s: float,
) -> tuple[bool, np.ndarray]:
    """F_3 + F_3^bal (Appendix D-3, Eqs. 23–29): the task-3 force that puts the expected CoP
    back on the boundary of the support polygon shrunk by ``margin``.

    Args:
        fc: the expected resultant contact wrench in O_w, shape (6,).
        kpsi3: K Ψ J̃_3ᵀ (resultant wrench per task-3 force), shape (6, 2).
        f3: F_3 = Λ_3 ẍ_3*, shape (2,).
        rot_w: world-from-O_w rotation (a yaw).
        sole_rot: world-from-support-sole rotation.
        half_sole: half the sole's length and width [m].
        margin: safety margin inside the polygon [m].
        x_s: the swing-foot centre along x of O_w in DS [m] (the polygon reaches it), NaN
            out of DS.

    Returns:
        (False, anything) when the expected CoP is inside the polygon (Eq. 23), else
        (True, F_3 + F_3^bal).
    """
    out = np.empty(2)
    cop_x, cop_y = cop_of(fc)
    if not (math.isfinite(cop_x) and math.isfinite(cop_y)):
        return False, out
    rot_w_sole = (rot_w.T @ sole_rot)[XY, XY]  # O_w-from-sole, xy
    half = np.abs(rot_w_sole) @ half_sole - margin  # the polygon's half extents in O_w [m]
    half_x, half_y = half[X], half[Y]
    hi_x = half_x + x_s if math.isfinite(x_s) else half_x
    cx, cy = min(max(cop_x, -half_x), hi_x), min(max(cop_y, -half_y), half_y)
    if abs(cx - cop_x) <= 1e-8 + 1e-5 * abs(cop_x) and abs(cy - cop_y) <= 1e-8 + 1e-5 * abs(cop_y):
        return False, out  # inside (as np.isclose)
    fsig = fc - kpsi3 @ f3  # the wrench without task 3
    m_des = np.array([cy * fsig[FZ] - fsig[MX], -cx * fsig[FZ] - fsig[MY]])  # Eqs. (26)-(27)
    q3 = np.ascontiguousarray(kpsi3[MOMENT_XY])  # Eq. (28)
    if abs(np.linalg.det(q3)) < 1e-12:
        return False, out
    return True, np.linalg.solve(q3, m_des)  # F_3 + F_3^bal, Eq. (29)


# ---- Γ of one tick -------------------------------------------------------------------------
# Records of whole_body_torques' inputs: kernels.tick builds them in compiled code, where a
# named tuple is a struct of pointers and numbers (built in Python, as the tests do, numba
# types each field at every call: a few µs).


class WbcParams(NamedTuple):
    """The OS-WBC's parameters (``EfsmParams``; §V-B), made once at reset.

    Attributes:
        tasks: the task hierarchy of Eq. (11) with each row's gains k_p, k_v (Eq. 6) and
            its rows out of and in DS (:func:`.tasks.task_set` of :data:`.tasks.HIERARCHY`).
        fs_max_force, fs_max_moment: the bound of each F_s force [N] and moment [Nm]
            component.
        fs_saturation: :class:`Saturation`.
        balance: F_3^bal when the expected CoP leaves the polygon (Appendix D-3).
        cop_margin: safety margin of the support polygon [m].
        torque_limit: actuator saturation [Nm].
        half_sole: half the sole's length and width [m], shape (2,).
        actuator_rows: the joint-torque row of each actuator, shape (k,).
    """

    tasks: TaskSet
    fs_max_force: float
    fs_max_moment: float
    fs_saturation: int
    balance: bool
    cop_margin: float
    torque_limit: float
    half_sole: np.ndarray
    actuator_rows: np.ndarray


class WbcDynamics(NamedTuple):
    """The dynamics of a tick, world axes (n velocity coordinates, the pelvis first).

    Attributes:
        a_inv: A⁻¹, shape (n, n).
        nle: b + g, shape (n,).
        jc_dot_v: J̇_c q̇ of the contacts (support sole, then the swing sole in DS), shape
            (6 or 12,).
        j_world: Pinocchio's joint Jacobians ``data.J``, shape (6, n) (see
            :func:`walkrepro.sim.robot.frame_jacobian`); the pelvis's are its first six columns.
        j_com: CoM Jacobian, shape (3, n).
        com, vcom: the CoM [m] and its velocity [m/s], shape (3,).
        v: generalized velocity, shape (n,).
    """

    a_inv: np.ndarray
    nle: np.ndarray
    jc_dot_v: np.ndarray
    j_world: np.ndarray
    j_com: np.ndarray
    com: np.ndarray
    vcom: np.ndarray
    v: np.ndarray


class WbcFrames(NamedTuple):
    """The frames of a tick: O_w and the two soles, world axes.

    Attributes:
        rot_w: world-from-O_w rotation (§III-A1).
        p_sup, p_sw: support and swing sole centres [m]; p_sup is the origin of O_w.
        sole_rot_sup, sole_rot_sw: world-from-sole rotations.
        pelvis_rot: world-from-pelvis rotation.
        chain_sup, chain_sw: whether each velocity coordinate moves the sole (1/0), (n,).
    """

    rot_w: np.ndarray
    p_sup: np.ndarray
    p_sw: np.ndarray
    sole_rot_sup: np.ndarray
    sole_rot_sw: np.ndarray
    pelvis_rot: np.ndarray
    chain_sup: np.ndarray
    chain_sw: np.ndarray


class WbcTargets(NamedTuple):
    """What the E-FSM and the task references ask of a tick (Eq. 6, Table II, §IV-B).

    Attributes:
        rot_des_pelvis, rot_des_swing: orientation targets (Table II), world-from-target.
        com_ref: the CoM target in the world [m], (3,) (Table II: y 0 and z z_m0 in O_w;
            along x of O_w task 1 follows x_p^des instead).
        swing_ref: swing-sole position reference in the world [m] (unused in DS), (3,).
        phase: E-FSM phase (:class:`.fsm.Phase`).
        eps: ε; eps_onset: ε's onset ramp in DS (:func:`redistribution_torque`).
        xp_des: desired CoP along x of O_w [m].
        x_s: swing-foot centre along x of O_w [m].
    """

    rot_des_pelvis: np.ndarray
    rot_des_swing: np.ndarray
    com_ref: np.ndarray
    swing_ref: np.ndarray
    phase: int
    eps: float
    eps_onset: float
    xp_des: float
    x_s: float


class WbcOutput(NamedTuple):
    """What a tick's OS-WBC reports besides Γ.

    Attributes:
        com_force_x: F_1, the CoM x-force of task 1 [N] (Appendix D-1; 0 without that task).
        balancing: whether F_3^bal acted (Appendix D-3).
        cop_exp_x, cop_exp_y: the expected CoP in O_w [m] (NaN if unloaded).
    """

    com_force_x: float
    balancing: bool
    cop_exp_x: float
    cop_exp_y: float


@_jit
def orientation_error(rot_des: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """log₃(R_des Rᵀ), the orientation error in world axes [rad]."""
    e = np.empty(3)
    log3(rot_des @ rot.T, e)
    return e


@_inline
def task_quantities(
    dynamics: WbcDynamics, frames: WbcFrames, targets: WbcTargets, j_swing: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each :class:`.tasks.Quantity`'s Jacobian, error (target − actual; Table II) and
    velocity, world axes: shapes (quantities, 6, n), (quantities, 6), (quantities, 6).

    The pelvis is the floating base: its Jacobian is the base columns of ``data.J``; it has
    no position target (its linear error is 0). The CoM has no angular rows.
    """
    n = dynamics.v.size
    jac = np.zeros((N_QUANTITIES, SPATIAL, n))
    err, vel = np.zeros((N_QUANTITIES, SPATIAL)), np.zeros((N_QUANTITIES, SPATIAL))
    com, pelvis, swing = Quantity.COM.value, Quantity.UPPER_BODY.value, Quantity.SWING_FOOT.value
    jac[com, LINEAR] = dynamics.j_com
    err[com, LINEAR] = targets.com_ref - dynamics.com  # [m]
    vel[com, LINEAR] = dynamics.vcom  # [m/s]
    jac[pelvis, :, BASE] = dynamics.j_world[:, BASE]
    err[pelvis, ANGULAR] = orientation_error(targets.rot_des_pelvis, frames.pelvis_rot)  # [rad]
    vel[pelvis] = jac[pelvis] @ dynamics.v
    jac[swing] = j_swing
    err[swing, LINEAR] = targets.swing_ref - frames.p_sw  # [m]
    err[swing, ANGULAR] = orientation_error(targets.rot_des_swing, frames.sole_rot_sw)  # [rad]
    vel[swing] = j_swing @ dynamics.v
    return jac, err, vel


@_inline
def task_forces(
    hierarchy: Hierarchy,
    layout: TaskLayout,
    acc: np.ndarray,
    targets: WbcTargets,
    params: WbcParams,
) -> np.ndarray:
    """[F_1; F_2; …] = Λ_i ẍ_i* of each level (Eq. 6), the swing foot's F_s saturated and
    scaled by ε (:func:`task2_force`); the CoP row's force is set apart (Appendix D-1)."""
    forces = np.empty(acc.size)
    scale_swing = targets.eps if targets.phase == Phase.SSA else 1.0
    for level in range(layout.first.size):
        s, e = layout.first[level], layout.end[level]
        lam = np.ascontiguousarray(hierarchy.lam[s:e, s:e])
        if level == layout.swing_level:
            forces[s:e] = task2_force(
                lam, acc[s:e], layout.swing_first - s, layout.swing_lin.size,
                layout.swing_ang.size, scale_swing,
                params.fs_max_force, params.fs_max_moment, params.fs_saturation,
            )  # fmt: skip
        else:
            forces[s:e] = lam @ acc[s:e]
    return forces


@_inline
def expected_wrench(
    k_tasks: np.ndarray,
    forces: np.ndarray,
    fc_b: np.ndarray,
    layout: TaskLayout,
    frames: WbcFrames,
    targets: WbcTargets,
    params: WbcParams,
) -> tuple[np.ndarray, float, bool]:
    """The expected resultant wrench in O_w with the CoP row's force (Appendix D-1) and the
    balancing force (Appendix D-3) set in ``forces``; also F_1 and whether F_3^bal acted.

    Args:
        k_tasks: K Ψ J̃ᵀ, the resultant wrench in O_w per task force, shape (6, m).
        forces: the task forces (:func:`task_forces`), updated.
        fc_b: K (Ψ Γ_gc + f_bias), the resultant of Γ_gc and the bias (Eqs. 8, 10).
    """
    f1 = 0.0
    for i in layout.cop:  # Appendix D-1, Eqs. (17)–(21): the CoM x-force for x_p^des
        forces[i] = 0.0
        fc_rest = k_tasks @ forces  # of the other tasks
        f1 = com_force_for_cop(targets.xp_des, k_tasks[MY, i], fc_rest[FZ] + fc_b[FZ], fc_b[MY])
        forces[i] = f1
    fc = k_tasks @ forces + fc_b
    bal = layout.balance
    balancing = False
    if params.balance and bal.size:  # Appendix D-3: the CoP out of the shrunk polygon
        k_bal = np.ascontiguousarray(k_tasks[:, bal])
        f3 = forces[bal]
        double = targets.phase == Phase.DS
        balancing, f3_bal = balance_force(
            fc, k_bal, f3, frames.rot_w, frames.sole_rot_sup, params.half_sole,
            params.cop_margin, targets.x_s if double else math.nan,
        )  # fmt: skip
        if balancing:
            fc += k_bal @ (f3_bal - f3)  # F_3 replaced by F_3 + F_3^bal
            forces[bal] = f3_bal
    return fc, f1, balancing


@_inline
def whole_body_torques(
    dynamics: WbcDynamics,
    frames: WbcFrames,
    targets: WbcTargets,
    params: WbcParams,
    tau: np.ndarray,
) -> WbcOutput:
    """Γ = Γ_t + Γ_c + Γ_gc (Eq. 7) of one tick, saturated, into ``tau`` (actuator order).

    The tasks of Eq. (11) are ``params.tasks`` (:data:`.tasks.HIERARCHY`: task 1 the CoM
    x-force for x_p^des, Appendix D-1; task 2 CoM y/z, pelvis yaw and, out of DS, the 6-D
    swing foot; task 3 pelvis roll/pitch, plus F_3^bal, Appendix D-3). Γ_c redistributes the
    DS wrenches (Appendix C). Contacts: the support sole, plus the swing sole in DS (its rows
    second).

    Args:
        dynamics, frames, targets, params: :class:`WbcDynamics`, :class:`WbcFrames`,
            :class:`WbcTargets`, :class:`WbcParams`.
        tau: out: actuator torques [Nm], shape (k,).
    """
    n = dynamics.v.size
    double = targets.phase == Phase.DS
    # Contact Jacobians at the sole centres, world axes: the support sole, then the swing
    # sole (a contact in DS, a task otherwise).
    j_sup, j_swing = np.empty((SPATIAL, n)), np.empty((SPATIAL, n))
    frame_jacobian(dynamics.j_world, frames.chain_sup, frames.p_sup, j_sup)
    frame_jacobian(dynamics.j_world, frames.chain_sw, frames.p_sw, j_swing)
    j_contacts = np.vstack((j_sup, j_swing)) if double else j_sup
    cd = contact_dynamics(dynamics.a_inv, dynamics.nle, j_contacts, dynamics.jc_dot_v)

    # The task rows (Eqs. 6, 11), their hierarchy (Appendix A) and forces.
    layout = params.tasks.double if double else params.tasks.single
    jac, err, vel = task_quantities(dynamics, frames, targets, j_swing)
    jacobian, acc = stack_tasks(params.tasks.rows, layout, jac, err, vel, frames.rot_w)
    hierarchy = task_hierarchy(cd, task_phi(cd, jacobian), layout.first, layout.end)
    forces = task_forces(hierarchy, layout, acc, targets, params)

    # The wrenches in O_w about the support centre, K Ψ Γ (Eqs. 8, 10); task 1's force for
    # x_p^des (Appendix D-1) and the balancing force (Appendix D-3).
    contacts = 2 if double else 1
    points = np.vstack((frames.p_sup, frames.p_sw))  # the soles in contact: the first
    kmap = grasp_map(frames.rot_w, frames.p_sup, points[:contacts])
    k_psi = kmap @ cd.psi
    k_tasks = k_psi @ hierarchy.torque_map  # resultant wrench per task force, (6, m)
    fc_b = kmap @ (cd.psi @ cd.gamma_gc + cd.f_bias)  # of Γ_gc and the bias
    fc, f1, balancing = expected_wrench(k_tasks, forces, fc_b, layout, frames, targets, params)
    gamma = hierarchy.torque_map @ forces + cd.gamma_gc  # Γ_t + Γ_gc

    # The contact wrench redistribution in DS (Appendix C) with ε (§IV-B).
    if double:
        f_now = cd.psi @ gamma + cd.f_bias  # Eq. (8)
        lever = frames.p_sup - frames.p_sw
        gamma_c, _ = redistribution_torque(cd, f_now, targets.eps, targets.eps_onset, lever)
        gamma += gamma_c  # Γ = Γ_t + Γ_c + Γ_gc, Eq. (7)
        fc += k_psi @ gamma_c
    limit = params.torque_limit
    tau[:] = np.clip(gamma[params.actuator_rows], -limit, limit)
    cop_x, cop_y = cop_of(fc)
    return WbcOutput(f1, balancing, cop_x, cop_y)
