"""The contact-consistent operational-space whole-body controller (OS-WBC), §IV and
Appendices A–D of Lee et al. 2021 (after Park & Khatib [25] and Lee et al. [35]).

Notation (Appendix A), with n = 6 + k generalized velocities and k actuated joints:

    P   = A⁻¹ (I − J_cᵀ J̄_cᵀ)               (n × n, the contact-consistent inverse inertia)
    W   = S P Sᵀ                           (k × k)
    Φ   = J P Sᵀ                           (m × k, task acceleration per joint torque)
    J̃ᵀ  = W⁺ Φᵀ                            (k × m, torque of a task force)
    Λ   = (Φ W⁺ Φᵀ)⁺                        (m × m, task inertia)
    Ñᵀ  = I − J̃ᵀ Λ Φ W⁺ W                   (k × k, null-space projector)

so that a torque Γ = J̃ᵀ F gives the task acceleration Λ⁻¹ F and Φ Ñᵀ = 0 (the task
acceleration is blind to any torque Ñᵀ Γ_0). The hierarchy of Eq. (11) uses the
prioritized projector Ñ_{12}ᵀ = Ñ_1ᵀ Ñ_{2|1}ᵀ for the third task.

A test oracle, not part of the package: the readable numpy reference of that algebra,
tested against Pinocchio's constrained dynamics. The controller runs the same steps compiled
in ``walkrepro.papers.lee2021.kernels`` (a tick is too many small numpy calls to run
fast), which the tests check against this one.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from walkrepro.papers.lee2021.kernels import PINV_RCOND

#: Rows of the two stacked foot wrenches other than the normal forces (Appendix C).
_TANGENTIAL = np.array([0, 1, 3, 4, 5, 6, 7, 9, 10, 11])


class ContactDynamics(NamedTuple):
    """Contact-constrained dynamics at one instant (Appendix A).

    Attributes:
        P: A⁻¹(I − J_cᵀ J̄_cᵀ), shape (n, n).
        W: S P Sᵀ, shape (k, k).
        W_pinv: W⁺, shape (k, k).
        psi: J̄_cᵀ Sᵀ, contact wrench per joint torque, shape (c, k) (Eq. 8).
        f_bias: −μ_c − p_c, contact wrench at Γ = 0, shape (c,) (Eq. 8).
        gamma_gc: Γ_gc, gravity/Coriolis compensation torque, shape (k,) (Appendix B).
        w_eigvec: eigenvectors of W by ascending eigenvalue, shape (k, k), when W⁺ was
            built from them (rank-deficient W, as in DS); None otherwise.
    """

    P: np.ndarray
    W: np.ndarray
    W_pinv: np.ndarray
    psi: np.ndarray
    f_bias: np.ndarray
    gamma_gc: np.ndarray
    w_eigvec: np.ndarray | None = None

    @property
    def k(self) -> int:
        """Number of actuated joints."""
        return self.W.shape[0]


def inv_if_well_conditioned(m: np.ndarray) -> np.ndarray | None:
    """m⁻¹ of a symmetric positive-definite m when it equals m⁺ (cut-off PINV_RCOND).

    The pseudo-inverse drops no singular value when cond(m) < 1 / PINV_RCOND. For a
    positive-definite m, cond(m) = λ_max / λ_min < tr(m) tr(m⁻¹), so a product of traces
    below the bound proves that the plain inverse is the pseudo-inverse (up to rounding).

    Returns:
        m⁻¹, or None when this test cannot prove it (the caller falls back to m⁺).
    """
    if m.shape[0] == 1:
        a = float(m[0, 0])
        return np.array([[1.0 / a]]) if a > 0.0 else None
    if m.shape[0] == 2:  # closed form, traces in floats
        (a, b), (c, d) = m.tolist()
        det = a * d - b * c
        if det == 0.0:
            return None
        m_inv = np.array([[d / det, -b / det], [-c / det, a / det]])
        tr, tr_inv = a + d, (a + d) / det
    else:
        try:
            m_inv = np.linalg.inv(m)
        except np.linalg.LinAlgError:  # exactly singular
            return None
        tr, tr_inv = float(m.trace()), float(m_inv.trace())
    if tr > 0.0 and tr_inv > 0.0 and tr * tr_inv * PINV_RCOND < 1.0:  # False if NaN
        return m_inv
    return None


def _pinv_eigh(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """m⁺ of a symmetric m from its eigen-decomposition (as ``pinv(hermitian=True)``).

    Returns:
        m⁺, and the eigenvectors by ascending eigenvalue, shape (k, k).
    """
    eigval, eigvec = np.linalg.eigh(m)
    mag = np.abs(eigval)
    keep = mag > PINV_RCOND * mag.max()
    inv_val = np.divide(1.0, eigval, out=np.zeros_like(eigval), where=keep)
    return (eigvec * inv_val) @ eigvec.T, eigvec


def contact_dynamics(
    a_inv: np.ndarray, nle: np.ndarray, jc: np.ndarray, jc_dot_v: np.ndarray
) -> ContactDynamics:
    """Build the contact-consistent quantities of Appendices A and B.

    W⁺ is the plain inverse when W is provably well conditioned (one foot: the six
    contact constraints only fix the floating base); otherwise, as with both feet where
    W has six zero eigenvalues, it is the pseudo-inverse from W's eigen-decomposition,
    which :func:`redistribution_torque` reuses.

    Args:
        a_inv: A⁻¹, inverse joint-space inertia, shape (n, n).
        nle: b + g, Coriolis/centrifugal and gravity forces, shape (n,).
        jc: contact Jacobian J_c, shape (c, n) (its wrench dual: forces/moments the feet
            apply to the ground).
        jc_dot_v: J̇_c q̇, shape (c,).
    """
    a_inv_jct = a_inv @ jc.T  # A⁻¹ J_cᵀ, shape (n, c)
    lam_c = np.linalg.inv(jc @ a_inv_jct)  # Λ_c
    if not math.isfinite(lam_c.trace()):
        raise np.linalg.LinAlgError("singular contact inertia J_c A⁻¹ J_cᵀ")
    a_inv_jct_lam = a_inv_jct @ lam_c  # J̄_c = A⁻¹ J_cᵀ Λ_c
    P = a_inv - a_inv_jct_lam @ a_inv_jct.T  # A⁻¹(I − J_cᵀ J̄_cᵀ), symmetric (A⁻¹ is)
    W = P[6:, 6:]
    W_pinv = inv_if_well_conditioned(W) if jc.shape[0] <= 6 else None
    w_eigvec = None
    if W_pinv is None:
        W_pinv, w_eigvec = _pinv_eigh(W)
    # Eq. (8): f_c = J̄_cᵀ (SᵀΓ − b − g) + Λ_c J̇_c q̇  (the wrench the feet exert on the ground).
    jbar_t = a_inv_jct_lam.T  # J̄_cᵀ, shape (c, n)
    psi = jbar_t[:, 6:]
    f_bias = lam_c @ jc_dot_v - jbar_t @ nle
    # Appendix B: joint accelerations S q̈ = W Γ − S P (b+g) − S A⁻¹ J_cᵀ Λ_c J̇_c q̇.
    bias_acc = P[6:, :] @ nle + a_inv_jct_lam[6:, :] @ jc_dot_v
    gamma_gc = W_pinv @ bias_acc
    return ContactDynamics(P, W, W_pinv, psi, f_bias, gamma_gc, w_eigvec)


class Task(NamedTuple):
    """One prioritized operational-space task, projected into its null spaces.

    Attributes:
        phi: Φ = J P Sᵀ, shape (m, k).
        torque_map: Ñ_precᵀ J̃ᵀ, torque per task force, shape (k, m) (Eq. 11).
        lam: Λ of the prioritized task, (Φ Ñ_precᵀ W⁺ Φᵀ)⁺, shape (m, m).
    """

    phi: np.ndarray
    torque_map: np.ndarray
    lam: np.ndarray


def task_phi(cd: ContactDynamics, jacobian: np.ndarray) -> np.ndarray:
    """Φ = J P Sᵀ, the task acceleration per joint torque, shape (m, k)."""
    return jacobian @ cd.P[:, 6:]


def null_space_t(cd: ContactDynamics, phi: np.ndarray) -> np.ndarray:
    """Ñᵀ = I − W⁺Φᵀ Λ Φ W⁺ W of the tasks stacked in ``phi`` (Appendix A), shape (k, k)."""
    jt = cd.W_pinv @ phi.T
    lam = np.linalg.pinv(phi @ jt, rcond=PINV_RCOND)
    return np.eye(cd.k) - jt @ lam @ phi @ cd.W_pinv @ cd.W


def prioritized_task(cd: ContactDynamics, phi: np.ndarray, n_prec_t: np.ndarray | None) -> Task:
    """A task below the tasks whose null-space projector is ``n_prec_t`` (Eq. 11)."""
    jt = cd.W_pinv @ phi.T  # J̃ᵀ
    torque_map = jt if n_prec_t is None else n_prec_t @ jt
    lam = np.linalg.pinv(phi @ torque_map, rcond=PINV_RCOND)
    return Task(phi, torque_map, lam)


class Hierarchy(NamedTuple):
    """Three prioritized tasks of Eq. (11), their rows stacked (task 1, task 2, task 3).

    Attributes:
        torque_map: [J̃_1ᵀ, Ñ_1ᵀ J̃_2ᵀ, Ñ_12ᵀ J̃_3ᵀ], torque per task force, shape (k, m);
            Γ_t = torque_map @ [F_1; F_2; F_3] (Eq. 11).
        lams: Λ of each prioritized task, shapes (m_i, m_i).
    """

    torque_map: np.ndarray
    lams: tuple[np.ndarray, np.ndarray, np.ndarray]


def task_hierarchy(cd: ContactDynamics, phi: np.ndarray, m1: int, m2: int) -> Hierarchy:
    """Three prioritized tasks of Eq. (11), stacked in ``phi`` (m1, m2, then the rest rows).

    The same tasks as ``prioritized_task(cd, Φ_1, None)``, ``prioritized_task(cd, Φ_2, Ñ_1ᵀ)``
    and ``prioritized_task(cd, Φ_3, Ñ_12ᵀ)``, without forming the k × k projectors: with
    J̃ᵀ = W⁺Φᵀ, G = Φ W⁺ Φᵀ and W⁺ W W⁺ = W⁺,

        Ñ_1ᵀ J̃_2ᵀ  = J̃_2ᵀ − J̃_1ᵀ Λ_1 G_12,
        Ñ_12ᵀ J̃_3ᵀ = J̃_3ᵀ − J̃_12ᵀ Λ_12 G_12,3,   Λ_12 = (G_12,12)⁺,

    and Φ_2 Ñ_1ᵀ J̃_2ᵀ = G_22 − G_21 Λ_1 G_12, the Schur complement of G_11 in G_12,12,
    whose inverse Λ_2 is the lower-right block of Λ_12 (by eigenvalue interlacing no
    worse conditioned than G_12,12, so that block is also its pseudo-inverse).

    The inverses are plain inverses when that provably equals the pseudo-inverse
    (:func:`inv_if_well_conditioned`); otherwise this falls back to the projectors.

    Args:
        cd: contact dynamics.
        phi: Φ of the three tasks, stacked, shape (m, k).
        m1: rows of task 1.
        m2: rows of task 2.
    """
    s1, s2, s12, s3 = slice(0, m1), slice(m1, m1 + m2), slice(0, m1 + m2), slice(m1 + m2, None)
    jt = cd.W_pinv @ phi.T  # J̃ᵀ of every row, shape (k, m)
    gram = phi @ jt  # Φ W⁺ Φᵀ
    lam1 = inv_if_well_conditioned(gram[s1, s1])
    lam12 = inv_if_well_conditioned(gram[s12, s12])
    if lam1 is not None and lam12 is not None:
        # Both projections in one product: torque_map = J̃ᵀ (I − U), U strictly block-upper.
        u = np.zeros(gram.shape)
        u[s1, s2] = lam1 @ gram[s1, s2]  # Ñ_1ᵀ J̃_2ᵀ = J̃_2ᵀ − J̃_1ᵀ Λ_1 G_12
        u[s12, s3] = lam12 @ gram[s12, s3]  # Ñ_12ᵀ J̃_3ᵀ = J̃_3ᵀ − J̃_12ᵀ Λ_12 G_12,3
        torque_map = jt - jt @ u
        lam3 = inv_if_well_conditioned(phi[s3] @ torque_map[:, s3])
        if lam3 is not None:
            return Hierarchy(torque_map, (lam1, lam12[s2, s2], lam3))
    # Ill-conditioned: the pseudo-inverses of the projector form (Appendix A).
    tasks = (
        prioritized_task(cd, phi[s1], None),
        prioritized_task(cd, phi[s2], null_space_t(cd, phi[s1])),
        prioritized_task(cd, phi[s3], null_space_t(cd, phi[s12])),
    )
    return Hierarchy(np.hstack([t.torque_map for t in tasks]), tuple(t.lam for t in tasks))


def grasp_map(
    rot_o: np.ndarray, origin: np.ndarray, contact_points: list[np.ndarray]
) -> np.ndarray:
    """K of Eq. (10): resultant wrench in frame O from stacked world-aligned foot wrenches.

    Args:
        rot_o: world-from-O rotation, shape (3, 3).
        origin: origin of O in the world [m].
        contact_points: world position of each contact's wrench reference point [m].
    """
    rt = rot_o.T
    kmap = np.zeros((6, 6 * len(contact_points)))
    for i, p in enumerate(contact_points):
        dx, dy, dz = (rt @ (p - origin)).tolist()  # distance from O's origin, O axes
        skew = np.array([[0.0, -dz, dy], [dz, 0.0, -dx], [-dy, dx, 0.0]])
        c = 6 * i
        kmap[:3, c : c + 3] = rt
        kmap[3:, c : c + 3] = skew @ rt
        kmap[3:, c + 3 : c + 6] = rt
    return kmap


def cop_of(wrench_o: np.ndarray) -> tuple[float, float]:
    """CoP (x, y) in O of a resultant wrench in O, Eqs. (18) and (22) [m]."""
    fz = wrench_o[2]
    if abs(fz) < 1e-9:
        return float("nan"), float("nan")
    return float(-wrench_o[4] / fz), float(wrench_o[3] / fz)


def com_force_for_cop(xp_des: float, q1: float, fz_rest: float, my_bias: float) -> float:
    """CoM x-force realising x_p^des, Appendix D-1 (Eqs. 20–21) [N].

    ˣF_m = −((ᶻF_c|2 + ᶻF_c|3 + ᶻF_c|b) x_p^des + ʸM_c|b) / Q_1.
    """
    return -(fz_rest * xp_des + my_bias) / q1


def redistribution_torque(
    cd: ContactDynamics,
    f_now: np.ndarray,
    leave: slice,
    eps: float,
    eps_onset: float = 1.0,
    lever: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Γ_c of Appendix C (Eqs. 14–16) and the leaving foot's reference wrench.

    The null space of W (its six near-zero singular directions v₂) changes the contact
    wrenches without changing any task or the resultant. The correction f_c^cor is chosen
    as in [35]: first the distribution that minimizes both feet's tangential forces and
    moments, then the leaving foot's wrench is scaled by ε (§IV-B) so that it unloads
    smoothly before DS ends. With ``eps_onset`` < 1 the reference is blended toward the
    leaving foot carrying the whole resultant (the landing foot unloaded, as in the SSA
    just before), so that the wrenches also start continuously when DS begins.

    Args:
        cd: contact dynamics with both feet in contact (c = 12).
        f_now: contact wrenches produced by the other torques, shape (12,), the leaving
            foot's rows first (world axes, moments about each sole centre).
        leave: rows of the foot that becomes the swing foot when DS ends.
        eps: state-transition parameter ε.
        eps_onset: blend in [0, 1] from "all on the leaving foot" (0) to the optimum (1).
        lever: leaving minus landing sole centre [m], needed when ``eps_onset`` < 1.

    Returns:
        Γ_c, shape (k,), and the leaving foot's reference wrench, shape (6,).
    """
    eigvec = cd.w_eigvec if cd.w_eigvec is not None else np.linalg.eigh(cd.W)[1]
    v2 = eigvec[:, :6]  # the six smallest: W's null space (Eq. 14)
    g = cd.psi @ v2  # wrench change per α, shape (12, 6)
    alpha_opt = np.linalg.lstsq(g[_TANGENTIAL], -f_now[_TANGENTIAL], rcond=None)[0]
    f_opt = f_now + g @ alpha_opt
    target = f_opt[leave]
    if eps_onset < 1.0 and lever is not None:
        land = slice(6, 12) if leave.start == 0 else slice(0, 6)
        fx, fy, fz = f_now[land][:3].tolist()
        lx, ly, lz = (-lever).tolist()
        # The whole resultant about the leaving sole centre: m_a moves by (p_a − p_l) × f_a.
        shifted = f_now[land].copy()
        shifted[3:] += (ly * fz - lz * fy, lz * fx - lx * fz, lx * fy - ly * fx)
        f_all = f_now[leave] + shifted
        target = eps_onset * target + (1.0 - eps_onset) * f_all
    f_ref = eps * target
    alpha = np.linalg.solve(g[leave], f_ref - f_now[leave])  # Y_c f_c^cor (Eq. 16)
    return v2 @ alpha, f_ref
