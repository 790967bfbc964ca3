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
import warnings
from typing import NamedTuple

import numba
import numpy as np

from walkrepro.sim.robot import frame_jacobian, log3

#: Relative singular-value cut-off of the pseudo-inverses (W is rank-deficient in DS).
PINV_RCOND = 1e-9
#: Rows of the two stacked foot wrenches other than the normal forces (Appendix C).
TANGENTIAL_ROWS = np.array([0, 1, 3, 4, 5, 6, 7, 9, 10, 11])
#: numpy's cut-off of ``lstsq(rcond=None)`` for the 10 × 6 problem of Appendix C.
LSTSQ_RCOND = float(np.finfo(np.float64).eps) * 10
#: How F_s meets its bound (:func:`task2_force`; ``EfsmParams.fs_saturation``).
CLIP, DECOUPLED_CLIP, UNIFORM = 0, 1, 2
#: E-FSM phases (fsm.Phase) as plain ints for the compiled code.
_SSA, _DS = 1, 2

#: Compiled, cached on disk; float division by zero gives inf/NaN as in numpy (the tests of
#: singular matrices rely on it) rather than raising.
_jit = numba.njit(cache=True, error_model="numpy")

# Blocks of the matrices below are strided views; numba copies them for BLAS and says so.
# At these sizes (≤ 18 × 18) the copy costs less than writing the blocks out by hand.
warnings.filterwarnings(
    "ignore", message=".*is faster on contiguous arrays", category=numba.NumbaPerformanceWarning
)


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
    W = np.ascontiguousarray(P[6:, 6:])  # S P Sᵀ
    well = False
    W_pinv = np.zeros_like(W)
    w_eigvec = np.zeros((0, 0))
    if jc.shape[0] <= 6:
        well, W_pinv = inv_if_well_conditioned(W)
    if not well:
        W_pinv, w_eigvec = pinv_symmetric(W)
    # Eq. (8): f_c = J̄_cᵀ (SᵀΓ − b − g) + Λ_c J̇_c q̇, the wrench the feet exert on the ground.
    psi = np.ascontiguousarray(jbar_t[:, 6:])  # J̄_cᵀ Sᵀ
    f_bias = lam_c @ jc_dot_v - jbar_t @ nle
    # Appendix B: S q̈ = W Γ − S P (b + g) − S A⁻¹ J_cᵀ Λ_c J̇_c q̇; Γ_gc = W⁺ (S P (b + g)
    # + S J̄_c J̇_c q̇) holds the joints still.
    bias_acc = P[6:, :] @ nle + psi.T @ jc_dot_v
    gamma_gc = W_pinv @ bias_acc
    return ContactDynamics(P, W, W_pinv, psi, f_bias, gamma_gc, w_eigvec)


# ---- Appendix A and Eq. (11): the task hierarchy -----------------------------------------


@_jit
def task_phi(cd: ContactDynamics, jacobian: np.ndarray) -> np.ndarray:
    """Φ = J P Sᵀ, the task acceleration per joint torque, shape (m, k) (Appendix A)."""
    return jacobian @ np.ascontiguousarray(cd.P[:, 6:])


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
    """Three prioritized tasks of Eq. (11), their rows stacked (task 1, task 2, task 3).

    Attributes:
        torque_map: [J̃_1ᵀ, Ñ_1ᵀ J̃_2ᵀ, Ñ_12ᵀ J̃_3ᵀ], the torque per task force, shape (k, m);
            Γ_t = torque_map [F_1; F_2; F_3] (Eq. 11).
        lam1, lam2, lam3: Λ of each prioritized task, shapes (m_i, m_i).
    """

    torque_map: np.ndarray
    lam1: np.ndarray
    lam2: np.ndarray
    lam3: np.ndarray


@_jit
def task_hierarchy(cd: ContactDynamics, phi: np.ndarray, m1: int, m2: int) -> Hierarchy:
    """Three prioritized tasks of Eq. (11), stacked in ``phi`` (m1 rows, m2 rows, the rest).

    The same tasks as ``prioritized_task(cd, Φ_1, I)``, ``prioritized_task(cd, Φ_2, Ñ_1ᵀ)``
    and ``prioritized_task(cd, Φ_3, Ñ_12ᵀ)``, without forming the k × k projectors: with
    J̃ᵀ = W⁺Φᵀ, G = Φ W⁺ Φᵀ and W⁺ W W⁺ = W⁺,

        Ñ_1ᵀ J̃_2ᵀ  = J̃_2ᵀ − J̃_1ᵀ Λ_1 G_12,
        Ñ_12ᵀ J̃_3ᵀ = J̃_3ᵀ − J̃_12ᵀ Λ_12 G_12,3,   Λ_12 = (G_12,12)⁺,

    and Φ_2 Ñ_1ᵀ J̃_2ᵀ = G_22 − G_21 Λ_1 G_12, the Schur complement of G_11 in G_12,12,
    whose inverse Λ_2 is the lower-right block of Λ_12 (by eigenvalue interlacing no
    worse conditioned than G_12,12, so that block is also its pseudo-inverse).

    The inverses are plain inverses when that provably equals the pseudo-inverse
    (:func:`inv_if_well_conditioned`); otherwise this takes the projector form.
    """
    m12 = m1 + m2
    jt = cd.W_pinv @ phi.T  # J̃ᵀ of every row, shape (k, m)
    gram = phi @ jt  # G = Φ W⁺ Φᵀ
    ok1, lam1 = inv_if_well_conditioned(gram[:m1, :m1])
    ok12, lam12 = inv_if_well_conditioned(gram[:m12, :m12])
    if ok1 and ok12:
        torque_map = jt.copy()
        torque_map[:, m1:m12] -= jt[:, :m1] @ (lam1 @ gram[:m1, m1:m12])  # Ñ_1ᵀ J̃_2ᵀ
        torque_map[:, m12:] -= jt[:, :m12] @ (lam12 @ gram[:m12, m12:])  # Ñ_12ᵀ J̃_3ᵀ
        ok3, lam3 = inv_if_well_conditioned(phi[m12:] @ torque_map[:, m12:])
        if ok3:
            return Hierarchy(torque_map, lam1, np.ascontiguousarray(lam12[m1:, m1:]), lam3)
    # Ill-conditioned: the pseudo-inverses of the projector form (Appendix A).
    task1 = prioritized_task(cd, phi[:m1], np.eye(cd.W.shape[0]))
    task2 = prioritized_task(cd, phi[m1:m12], null_space_t(cd, phi[:m1]))
    task3 = prioritized_task(cd, phi[m12:], null_space_t(cd, phi[:m12]))
    torque_map = np.hstack((task1.torque_map, task2.torque_map, task3.torque_map))
    return Hierarchy(torque_map, task1.lam, task2.lam, task3.lam)


# ---- Appendices C and D: wrenches, CoP, redistribution ------------------------------------


@_jit
def skew(d: np.ndarray) -> np.ndarray:
    """[d]×, the matrix of d × (·)."""
    return np.array([[0.0, -d[2], d[1]], [d[2], 0.0, -d[0]], [-d[1], d[0], 0.0]])


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
    kmap = np.zeros((6, 6 * contact_points.shape[0]))
    for foot in range(contact_points.shape[0]):
        d = rt @ (contact_points[foot] - origin)  # [m], O axes
        c = 6 * foot
        kmap[:3, c : c + 3] = rt
        kmap[3:, c : c + 3] = skew(d) @ rt
        kmap[3:, c + 3 : c + 6] = rt
    return kmap


@_jit
def cop_of(wrench_o: np.ndarray) -> tuple[float, float]:
    """CoP (x, y) in O of a resultant wrench (f, m) in O, Eqs. (18) and (22) [m]:
    (−m_y / f_z, m_x / f_z); NaN when unloaded."""
    fz = wrench_o[2]
    if abs(fz) < 1e-9:
        return math.nan, math.nan
    return -wrench_o[4] / fz, wrench_o[3] / fz


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
    v2 = np.ascontiguousarray(cd.w_eigvec[:, :6])  # the six smallest: W's null space (Eq. 14)
    g = cd.psi @ v2  # wrench change per α, shape (12, 6)
    alpha_opt = least_squares(g[TANGENTIAL_ROWS], -f_now[TANGENTIAL_ROWS])
    target = f_now[:6] + g[:6] @ alpha_opt  # the leaving foot's rows of the optimum
    if eps_onset < 1.0:
        # The whole resultant about the leaving sole centre: the landing foot's moment
        # moves by (p_land − p_leave) × f_land.
        f_land = f_now[6:].copy()
        f_land[3:] += np.cross(-lever, f_land[:3])
        target = eps_onset * target + (1.0 - eps_onset) * (f_now[:6] + f_land)
    f_ref = eps * target
    alpha = np.linalg.solve(g[:6], f_ref - f_now[:6])  # Y_c f_c^cor (Eq. 16)
    return v2 @ alpha, f_ref


@_jit
def task2_force(
    lam: np.ndarray,
    acc: np.ndarray,
    double: bool,
    scale_swing: float,
    f_max: float,
    m_max: float,
    saturation: int,
) -> np.ndarray:
    """F_2 = Λ ẍ* (Eq. 6) with the swing-foot wrench F_s saturated and scaled by ε.

    Out of DS the last six rows are the swing foot (force, then moment). F_s is bounded
    component-wise (§V-B) and multiplied by ``scale_swing`` (ε in SSA, §IV-C). With
    :data:`UNIFORM` the bound is met by scaling the commanded linear swing acceleration
    (so every force component stays within it and the foot keeps heading for its target);
    with :data:`DECOUPLED_CLIP` the force rows are clipped one by one, with the orientation
    acceleration kept: clipping the force rows of Λ ẍ* alone (:data:`CLIP`) leaves in the
    moment rows the coupling term of an acceleration that is no longer produced, which
    pitched the swing foot 14° toe-up in free swing and 35° against the obstacle. The
    CoM/yaw forces are then computed with the swing-foot acceleration that this bounded
    F_s actually produces, so that they do not carry the coupling of an unbounded one.

    Args:
        lam: Λ_2, shape (m2, m2); acc: ẍ*, shape (m2,).
        double: DS (no swing foot: F_2 = Λ ẍ*).
        scale_swing: factor on F_s (ε in SSA, else 1).
        f_max, m_max: the bounds of each force [N] and moment [Nm] component of F_s.
        saturation: :data:`CLIP`, :data:`DECOUPLED_CLIP` or :data:`UNIFORM`.
    """
    f_free = lam @ acc  # Λ ẍ*, unbounded
    if double:
        return f_free
    if saturation == UNIFORM:
        # The largest s ≤ 1 for which every force row F_i = s a_i + b_i stays within the
        # bound (a: the part of Λ ẍ* due to ẍ_s*, b: the rest).
        a = lam[3:6, 3:6] @ acc[3:6]
        b = f_free[3:6] - a
        s = 1.0
        for i in range(3):
            if a[i] > 0.0:
                s = min(s, (f_max - b[i]) / a[i])
            elif a[i] < 0.0:
                s = min(s, (-f_max - b[i]) / a[i])
        s = max(s, 0.0)
        if s < 1.0:
            acc_bounded = acc.copy()
            acc_bounded[3:6] *= s
            f_free = lam @ acc_bounded
    fs = f_free[3:9].copy()  # F_s: force, moment
    if saturation == DECOUPLED_CLIP:
        fs[:3] = np.clip(fs[:3], -f_max, f_max)
        cut = fs[:3] - f_free[3:6]
        if np.any(cut != 0.0):  # keep the orientation acceleration: Λ_s couples the rows
            fs[3:] += lam[6:9, 3:6] @ np.linalg.solve(lam[3:6, 3:6], cut)
    fs[:3] = np.clip(fs[:3], -f_max, f_max)
    fs[3:] = np.clip(fs[3:], -m_max, m_max)
    fs *= scale_swing
    cut = fs - f_free[3:9]
    f2 = f_free
    if np.any(cut != 0.0):  # the CoM/yaw forces of the swing acceleration F_s produces
        f2[:3] += lam[0:3, 3:9] @ np.linalg.solve(lam[3:9, 3:9], cut)
    f2[3:] = fs
    return f2


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
    rot_w_sole = (rot_w.T @ sole_rot)[:2, :2]  # O_w-from-sole, xy
    half = np.abs(rot_w_sole) @ half_sole - margin  # the polygon's half extents in O_w [m]
    hi_x = half[0] + x_s if math.isfinite(x_s) else half[0]
    cx, cy = min(max(cop_x, -half[0]), hi_x), min(max(cop_y, -half[1]), half[1])
    if abs(cx - cop_x) <= 1e-8 + 1e-5 * abs(cop_x) and abs(cy - cop_y) <= 1e-8 + 1e-5 * abs(cop_y):
        return False, out  # inside (as np.isclose)
    fsig = fc - kpsi3 @ f3  # the wrench without task 3
    m_des = np.array([cy * fsig[2] - fsig[3], -cx * fsig[2] - fsig[4]])  # Eqs. (26)-(27)
    q3 = np.ascontiguousarray(kpsi3[3:5])  # Eq. (28)
    if abs(np.linalg.det(q3)) < 1e-12:
        return False, out
    return True, np.linalg.solve(q3, m_des)  # F_3 + F_3^bal, Eq. (29)


# ---- Γ of one tick -------------------------------------------------------------------------
# Records of whole_body_torques' inputs: kernels.tick builds them in compiled code, where a
# named tuple is a struct of pointers and numbers (built in Python, as the tests do, numba
# types each field at every call: a few µs).


class WbcParams(NamedTuple):
    """The OS-WBC's parameters (``EfsmParams``; §V-B).

    Attributes:
        kp: task stiffness k_p [1/s²]; kv: task damping k_v [1/s] (Eq. 6).
        fs_max_force, fs_max_moment: the bound of each F_s force [N] and moment [Nm]
            component.
        fs_saturation: :data:`CLIP`, :data:`DECOUPLED_CLIP` or :data:`UNIFORM`.
        balance: F_3^bal when the expected CoP leaves the polygon (Appendix D-3).
        cop_margin: safety margin of the support polygon [m].
        torque_limit: actuator saturation [Nm].
        half_sole: half the sole's length and width [m], shape (2,).
    """

    kp: float
    kv: float
    fs_max_force: float
    fs_max_moment: float
    fs_saturation: int
    balance: bool
    cop_margin: float
    torque_limit: float
    half_sole: np.ndarray


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
        v: generalized velocity, shape (n,).
    """

    a_inv: np.ndarray
    nle: np.ndarray
    jc_dot_v: np.ndarray
    j_world: np.ndarray
    j_com: np.ndarray
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
        com_yz_err_w: CoM y and z errors (target − CoM) in O_w [m], shape (2,).
        com_yz_vel_w: CoM y and z velocities in O_w [m/s], shape (2,).
        swing_ref: swing-sole position reference in the world [m] (unused in DS), (3,).
        phase: E-FSM phase (fsm.Phase as int).
        eps: ε; eps_onset: ε's onset ramp in DS (:func:`redistribution_torque`).
        xp_des: desired CoP along x of O_w [m].
        x_s: swing-foot centre along x of O_w [m].
    """

    rot_des_pelvis: np.ndarray
    rot_des_swing: np.ndarray
    com_yz_err_w: np.ndarray
    com_yz_vel_w: np.ndarray
    swing_ref: np.ndarray
    phase: int
    eps: float
    eps_onset: float
    xp_des: float
    x_s: float


class WbcOutput(NamedTuple):
    """What a tick's OS-WBC reports besides Γ.

    Attributes:
        com_force_x: F_1, the CoM x-force of task 1 [N] (Appendix D-1).
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


@_jit
def whole_body_torques(
    dynamics: WbcDynamics,
    frames: WbcFrames,
    targets: WbcTargets,
    params: WbcParams,
    actuator_rows: np.ndarray,
    tau: np.ndarray,
) -> WbcOutput:
    """Γ = Γ_t + Γ_c + Γ_gc (Eq. 7) of one tick, saturated, into ``tau`` (actuator order).

    The three tasks of Eq. (11): task 1 the CoM x-force for x_p^des (Appendix D-1); task 2
    CoM y/z, pelvis yaw and, out of DS, the 6-D swing foot; task 3 pelvis roll/pitch, plus
    F_3^bal (Appendix D-3). Γ_c redistributes the DS wrenches (Appendix C). Contacts: the
    support sole, plus the swing sole in DS (its rows second).

    Args:
        dynamics, frames, targets, params: :class:`WbcDynamics`, :class:`WbcFrames`,
            :class:`WbcTargets`, :class:`WbcParams`.
        actuator_rows: joint-torque row of each actuator, shape (k,).
        tau: out: actuator torques [Nm], shape (k,).
    """
    a_inv, nle, jc_dot_v, j_world, j_com, v = dynamics
    rot_w, p_sup, p_sw = frames.rot_w, frames.p_sup, frames.p_sw
    kp, kv = params.kp, params.kv
    n = a_inv.shape[0]
    double = targets.phase == _DS

    # Contact Jacobians at the sole centres, world axes: the support sole, then the swing
    # sole (a contact in DS, task 2 otherwise).
    j_feet = np.empty((12, n))
    frame_jacobian(j_world, frames.chain_sup, p_sup, j_feet[0:6])
    frame_jacobian(j_world, frames.chain_sw, p_sw, j_feet[6:12])
    j_swing = j_feet[6:12]
    cd = contact_dynamics(a_inv, nle, j_feet[: 12 if double else 6], jc_dot_v)

    # Task Jacobians (Eq. 11), stacked [CoM x | CoM y, z, pelvis yaw, (swing foot) | pelvis
    # roll, pitch]; the CoM and roll/pitch rows in O_w axes. The pelvis is the floating
    # base: its Jacobian is the base columns of data.J.
    rot_w_t = np.ascontiguousarray(rot_w.T)
    j_com_w = rot_w_t @ j_com
    j_pelvis = np.zeros((6, n))
    j_pelvis[:, :6] = j_world[:, :6]
    m2 = 3 if double else 9
    j_tasks = np.empty((m2 + 3, n))
    j_tasks[0] = j_com_w[0]  # task 1
    j_tasks[1:3] = j_com_w[1:3]  # task 2
    j_tasks[3] = j_pelvis[5]
    if not double:
        j_tasks[4:10] = j_swing
    j_tasks[m2 + 1 :] = (rot_w_t @ j_pelvis[3:6])[:2]  # task 3

    # Reference accelerations ẍ* = k_p e − k_v ẋ, Eq. (6) (Table II targets).
    w_pelvis = j_pelvis[3:6] @ v  # [rad/s], world axes
    e_pelvis = orientation_error(targets.rot_des_pelvis, frames.pelvis_rot)
    acc2 = np.empty(m2)
    acc2[0:2] = kp * targets.com_yz_err_w - kv * targets.com_yz_vel_w
    acc2[2] = kp * e_pelvis[2] - kv * w_pelvis[2]
    if not double:
        v_swing = j_swing @ v
        e_swing = orientation_error(targets.rot_des_swing, frames.sole_rot_sw)
        acc2[3:6] = kp * (targets.swing_ref - p_sw) - kv * v_swing[:3]
        acc2[6:9] = kp * e_swing - kv * v_swing[3:]
    acc3 = (rot_w_t @ (kp * e_pelvis - kv * w_pelvis))[:2]

    # The hierarchy (Eq. 11, Appendix A) and the forces of tasks 2 and 3.
    phi = task_phi(cd, j_tasks)
    hierarchy = task_hierarchy(cd, phi, 1, m2)
    forces = np.empty(m2 + 3)  # [F_1; F_2; F_3]
    scale_swing = targets.eps if targets.phase == _SSA else 1.0
    forces[1 : m2 + 1] = task2_force(
        hierarchy.lam2, acc2, double, scale_swing, params.fs_max_force, params.fs_max_moment,
        params.fs_saturation,
    )  # fmt: skip
    forces[m2 + 1 :] = hierarchy.lam3 @ acc3

    # The CoM x-force for x_p^des (Appendix D-1, Eqs. 17–21): the wrenches in O_w about the
    # support centre, K Ψ Γ (Eqs. 8, 10).
    points = np.empty((2 if double else 1, 3))
    points[0] = p_sup
    if double:
        points[1] = p_sw
    kmap = grasp_map(rot_w, p_sup, points)
    k_psi = kmap @ cd.psi
    k_tasks = k_psi @ hierarchy.torque_map  # resultant wrench per task force, (6, m)
    fc_23 = k_tasks[:, 1:] @ forces[1:]  # of tasks 2 and 3
    fc_b = kmap @ (cd.psi @ cd.gamma_gc + cd.f_bias)  # of Γ_gc and the bias
    f1 = com_force_for_cop(targets.xp_des, k_tasks[4, 0], fc_23[2] + fc_b[2], fc_b[4])
    forces[0] = f1
    fc = k_tasks[:, 0] * f1 + fc_23 + fc_b  # the expected resultant wrench in O_w

    # Balancing (Appendix D-3): the expected CoP out of the shrunk polygon -> F_3^bal.
    balancing = False
    if params.balance:
        k_task3 = np.ascontiguousarray(k_tasks[:, m2 + 1 :])
        f3 = forces[m2 + 1 :].copy()
        balancing, f3_bal = balance_force(
            fc, k_task3, f3, rot_w, frames.sole_rot_sup, params.half_sole, params.cop_margin,
            targets.x_s if double else math.nan,
        )  # fmt: skip
        if balancing:
            fc += k_task3 @ (f3_bal - f3)  # F_3 replaced
            forces[m2 + 1 :] = f3_bal
    gamma = hierarchy.torque_map @ forces + cd.gamma_gc  # Γ_t + Γ_gc

    # The contact wrench redistribution in DS (Appendix C) with ε (§IV-B).
    if double:
        f_now = cd.psi @ gamma + cd.f_bias  # Eq. (8)
        gamma_c, _ = redistribution_torque(cd, f_now, targets.eps, targets.eps_onset, p_sup - p_sw)
        gamma += gamma_c  # Γ = Γ_t + Γ_c + Γ_gc, Eq. (7)
        fc += k_psi @ gamma_c
    tau[:] = np.clip(gamma[actuator_rows], -params.torque_limit, params.torque_limit)
    cop_x, cop_y = cop_of(fc)
    return WbcOutput(f1, balancing, cop_x, cop_y)
