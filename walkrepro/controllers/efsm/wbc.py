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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Relative singular-value cut-off of the pseudo-inverses (W is rank-deficient in DS).
PINV_RCOND = 1e-9


@dataclass(frozen=True)
class ContactDynamics:
    """Contact-constrained dynamics at one instant (Appendix A).

    Attributes:
        P: A⁻¹(I − J_cᵀ J̄_cᵀ), shape (n, n).
        W: S P Sᵀ, shape (k, k).
        W_pinv: W⁺, shape (k, k).
        psi: J̄_cᵀ Sᵀ, contact wrench per joint torque, shape (c, k) (Eq. 8).
        f_bias: −μ_c − p_c, contact wrench at Γ = 0, shape (c,) (Eq. 8).
        gamma_gc: Γ_gc, gravity/Coriolis compensation torque, shape (k,) (Appendix B).
    """

    P: np.ndarray
    W: np.ndarray
    W_pinv: np.ndarray
    psi: np.ndarray
    f_bias: np.ndarray
    gamma_gc: np.ndarray

    @property
    def k(self) -> int:
        """Number of actuated joints."""
        return self.W.shape[0]


def contact_dynamics(
    a_inv: np.ndarray, nle: np.ndarray, jc: np.ndarray, jc_dot_v: np.ndarray
) -> ContactDynamics:
    """Build the contact-consistent quantities of Appendices A and B.

    Args:
        a_inv: A⁻¹, inverse joint-space inertia, shape (n, n).
        nle: b + g, Coriolis/centrifugal and gravity forces, shape (n,).
        jc: contact Jacobian J_c, shape (c, n) (its wrench dual: forces/moments the feet
            apply to the ground).
        jc_dot_v: J̇_c q̇, shape (c,).
    """
    lam_c = np.linalg.inv(jc @ a_inv @ jc.T)  # Λ_c
    a_inv_jct_lam = a_inv @ jc.T @ lam_c  # J̄_c = A⁻¹ J_cᵀ Λ_c
    P = a_inv - a_inv_jct_lam @ jc @ a_inv  # A⁻¹(I − J_cᵀ J̄_cᵀ), symmetric
    W = P[6:, 6:]
    W_pinv = np.linalg.pinv(W, rcond=PINV_RCOND, hermitian=True)
    # Eq. (8): f_c = J̄_cᵀ (SᵀΓ − b − g) + Λ_c J̇_c q̇  (the wrench the feet exert on the ground).
    jbar_t = a_inv_jct_lam.T  # J̄_cᵀ, shape (c, n)
    psi = jbar_t[:, 6:]
    f_bias = -jbar_t @ nle + lam_c @ jc_dot_v
    # Appendix B: joint accelerations S q̈ = W Γ − S P (b+g) − S A⁻¹ J_cᵀ Λ_c J̇_c q̇.
    bias_acc = P[6:, :] @ nle + a_inv_jct_lam[6:, :] @ jc_dot_v
    gamma_gc = W_pinv @ bias_acc
    return ContactDynamics(P, W, W_pinv, psi, f_bias, gamma_gc)


@dataclass(frozen=True)
class Task:
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


def grasp_map(
    rot_o: np.ndarray, origin: np.ndarray, contact_points: list[np.ndarray]
) -> np.ndarray:
    """K of Eq. (10): resultant wrench in frame O from stacked world-aligned foot wrenches.

    Args:
        rot_o: world-from-O rotation, shape (3, 3).
        origin: origin of O in the world [m].
        contact_points: world position of each contact's wrench reference point [m].
    """
    blocks = []
    rt = rot_o.T
    for p in contact_points:
        d = rt @ (np.asarray(p) - origin)  # distance from O's origin, O axes
        skew = np.array([[0.0, -d[2], d[1]], [d[2], 0.0, -d[0]], [-d[1], d[0], 0.0]])
        blk = np.zeros((6, 6))
        blk[:3, :3] = rt
        blk[3:, :3] = skew @ rt
        blk[3:, 3:] = rt
        blocks.append(blk)
    return np.hstack(blocks)


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
    eigval, eigvec = np.linalg.eigh(cd.W)
    v2 = eigvec[:, :6]  # the six smallest: W's null space (Eq. 14)
    g = cd.psi @ v2  # wrench change per α, shape (12, 6)
    tangential = np.r_[0, 1, 3, 4, 5, 6, 7, 9, 10, 11]
    alpha_opt = np.linalg.lstsq(g[tangential], -f_now[tangential], rcond=None)[0]
    f_opt = f_now + g @ alpha_opt
    target = f_opt[leave]
    if eps_onset < 1.0 and lever is not None:
        land = slice(6, 12) if leave.start == 0 else slice(0, 6)
        f_land = f_now[land]
        # The whole resultant about the leaving sole centre: m_a moves by (p_a − p_l) × f_a.
        f_all = f_now[leave] + np.r_[f_land[:3], f_land[3:] + np.cross(-lever, f_land[:3])]
        target = eps_onset * target + (1.0 - eps_onset) * f_all
    f_ref = eps * target
    alpha = np.linalg.solve(g[leave], f_ref - f_now[leave])  # Y_c f_c^cor (Eq. 16)
    return v2 @ alpha, f_ref
