"""The 3LP walking model and its closed-form propagation (Paper II, Eqs. 1-8 and 11).

3LP (Faraji & Ijspeert, IJRR 2017) is three linear pendulums, a torso and two legs, hung from a
massless pelvis that moves in a constant-height plane. It is linear, decoupled between the
sagittal (x) and lateral (y) axes, and both axes obey the same equations once torques are
signed per axis (note ``3lp.md`` §1): the sagittal torque is τ_y, the lateral one −τ_x. In this
convention an ankle torque is −m g (1 − r_g) times the CoP offset, and a positive swing-hip
torque accelerates the swing foot toward −x (or −y).

Vectors interleave the two axes, ``(x, y)`` per entry:

- state ``q`` (12,) = ``[f, p, s, ḟ, ṗ, ṡ]``: swing foot, pelvis, stance foot [m], [m/s]
  (Eqs. 1 and 6);
- inputs ``u`` (8,) = ``[τh_c, τh_r, τa_c, τa_r]``: swing-hip and stance-ankle torques
  τ(t) = τ_c + τ_r·t in [Nm] and [Nm/s], t the time since the step start (Eq. 4);
- disturbances ``d`` (4,) = ``[δ, σ]``: generalised torque δ on the whole body [Nm] and the
  swing-hip offset σ [m] (see :meth:`ThreeLP.disturbance`);
- ``ξ`` (24,) = ``[q, u, d]``, everything the closed form needs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

#: Sizes of the state q, the inputs u, the disturbances d and their stack ξ.
N_Q, N_U, N_D = 12, 8, 4
N_XI = N_Q + N_U + N_D

#: Slices of ξ.
Q, U, D = slice(0, N_Q), slice(N_Q, N_Q + N_U), slice(N_Q + N_U, N_XI)

#: Slices of q: positions of the swing foot, pelvis, stance foot, then their velocities.
SWING, PELVIS, STANCE = slice(0, 2), slice(2, 4), slice(4, 6)
SWING_VEL, PELVIS_VEL, STANCE_VEL = slice(6, 8), slice(8, 10), slice(10, 12)

#: Slices of u: swing-hip constant and ramp terms (the paper's u_c, u_r), stance-ankle ones.
HIP_C, HIP_R, ANKLE_C, ANKLE_R = slice(0, 2), slice(2, 4), slice(4, 6), slice(6, 8)
#: The four swing-hip parameters [τh_c; τh_r], the feedback inputs of Paper II; the ankle ones.
HIP, ANKLE = slice(0, 4), slice(4, 8)

#: Slices of d.
DELTA, SIGMA = slice(0, 2), slice(2, 4)

# Indices in ξ of the ramp parameters τ_r, the only entries that F1 multiplies (note §3).
_RAMP = np.r_[N_Q + 2 : N_Q + 4, N_Q + 6 : N_Q + 8]
_CONST = np.r_[N_Q + 0 : N_Q + 2, N_Q + 4 : N_Q + 6]


@dataclass(frozen=True)
class ThreeLPParams:
    """Physical parameters of the 3LP model (note ``3lp.md`` §1, §8).

    Derive them from the simulated robot; nothing robot-specific is hard-coded here.
    """

    m1: float
    """Torso mass m1 (trunk, arms and head) [kg]."""
    m2: float
    """Mass of one leg m2 [kg]."""
    h1: float
    """Pelvis height h1, the leg length [m]."""
    h2: float
    """Depth h2 of a leg's centre of mass below its hip [m], 0 < h2 < h1."""
    h3: float
    """Height h3 of the torso centre of mass above the pelvis [m]."""
    pw: float
    """Half the hip spacing pw [m]: the hips sit at p ± pw·ŷ."""
    g: float = 9.81
    """Gravity g [m/s²]."""
    I2: float = 0.0
    """Inertia I2 of the swing leg about its centre of mass [kg m²]; 0 for a point mass."""
    I3: float = 0.0
    """Inertia I3 of the stance leg about its centre of mass [kg m²]; 0 for a point mass."""
    h4: float = 0.0
    """Height h4 above the pelvis at which a horizontal torso push acts [m]."""
    r_g: float = 0.0
    """Fraction r_g of the body weight carried by an external support, in [0, 1)."""
    theta: float = 0.0
    """Constant torso pitch θ [rad]; 0 is upright."""

    def __post_init__(self) -> None:
        if self.m1 <= 0 or self.m2 <= 0:
            raise ValueError(f"masses must be positive, got m1={self.m1}, m2={self.m2}")
        if not 0 < self.h2 < self.h1:
            raise ValueError(f"need 0 < h2 < h1, got h2={self.h2}, h1={self.h1}")
        if self.g <= 0 or self.I2 < 0 or self.I3 < 0:
            raise ValueError("need g > 0 and I2, I3 >= 0")
        if not 0 <= self.r_g < 1:
            raise ValueError(f"need 0 <= r_g < 1, got r_g={self.r_g}")

    @property
    def total_mass(self) -> float:
        """Total mass m = m1 + 2 m2 [kg]."""
        return self.m1 + 2 * self.m2


@dataclass(frozen=True)
class AxisMatrices:
    """Single-support equations of one axis (note §2, paper Eq. 2).

    Accelerations of ``x = [f, p, s]`` are ``ẍ = Cx x + Cu [τ_h, τ_a] + Cd [δ, σ]``.
    """

    mass: np.ndarray
    """Mass matrix [[D1, c], [c, D2]] acting on [p̈, f̈], shape (2, 2), in [kg m]."""
    stiffness: np.ndarray
    """Stiffness on [p − s, f − s], shape (2, 2), in [N]: [[gμ, m2gκ], [m2gκ, −m2gκ]]."""
    Cx: np.ndarray
    """State matrix, shape (3, 3), in [1/s²]; rows and columns ordered [f, p, s]."""
    Cu: np.ndarray
    """Input matrix on [τ_h, τ_a], shape (3, 2), in [1/(kg m)]."""
    Cd: np.ndarray
    """Disturbance matrix on [δ, σ], shape (3, 2), in [1/(kg m)] and [1/s²]."""


@dataclass(frozen=True)
class ClosedForm:
    """q(t0 + t) = A q(t0) + B u + C d, the closed form of Eq. (5)."""

    A: np.ndarray
    """State transition, shape (12, 12)."""
    B: np.ndarray
    """Input map on u = [τh_c, τh_r, τa_c, τa_r], shape (12, 8)."""
    C: np.ndarray
    """Disturbance map on d = [δ, σ], shape (12, 4)."""


class ThreeLP:
    """The 3LP model: single-support dynamics and their exact closed-form propagation.

    Args:
        params: physical parameters.
    """

    def __init__(self, params: ThreeLPParams) -> None:
        self.params = params
        self.axis = _axis_matrices(params)
        #: ξ̇ = (F0 + t·F1) ξ, shape (24, 24) each (note §3).
        self.F0, self.F1 = _time_varying_system(self.axis)
        # The exact LTI augmentation: v = t·τ_r appended to ξ, v̇ = τ_r (note §3).
        self._F_aug = _augmented_system(self.F0, self.F1)
        lam, vec = np.linalg.eig(np.linalg.solve(self.axis.mass, self.axis.stiffness))
        order = np.argsort(-lam.real)
        self._modes = vec.real[:, order]  # columns: falling mode, swinging mode
        lam = lam.real[order]
        if not (lam[0] > 0 > lam[1]):
            raise ValueError(f"expected one falling and one swinging mode, got λ = {lam}")
        self.omega_fall = float(np.sqrt(lam[0]))
        """Falling-mode frequency ω₁ [rad/s]: the inverted pendulum."""
        self.omega_swing = float(np.sqrt(-lam[1]))
        """Swinging-mode frequency ω₂ [rad/s]: the swing pendulum."""

    def disturbance(
        self,
        side: int,
        force: tuple[float, float] = (0.0, 0.0),
        torque: tuple[float, float] = (0.0, 0.0),
    ) -> np.ndarray:
        """The disturbance vector d = [δ, σ] of a step (note §2).

        Args:
            side: d = +1 when the left leg swings (its hip at p + pw·ŷ), −1 for the right.
            force: horizontal force (F_x, F_y) on the torso, h4 above the pelvis [N].
            torque: external torque (T_x, T_y) on the torso [Nm].

        Returns:
            d, shape (4,): δ = (δ_x, δ_y) [Nm], σ = (0, side·pw) [m].
        """
        p = self.params
        lever = p.h1 + p.h4 * np.cos(p.theta)  # [m]
        delta_x = p.m1 * p.g * p.h3 * np.sin(p.theta) + lever * force[0] + torque[1]
        delta_y = lever * force[1] - torque[0]
        return np.array([delta_x, delta_y, 0.0, side * p.pw])

    def propagator(self, t0: float, dt: float) -> np.ndarray:
        """Φ(t0, dt), the exact map ξ(t0) → ξ(t0 + dt) of a single-support phase (note §3).

        Φ = P·expm(F dt)·E(t0): E(t0) initialises the augmented states v = t0·τ_r and P drops
        them. The inputs and disturbances in ξ are constant, so their rows are the identity.

        Args:
            t0: phase time at the start [s], measured from the step start.
            dt: duration [s].

        Returns:
            Φ, shape (24, 24).
        """
        X = expm(self._F_aug * dt)
        phi = X[:N_XI, :N_XI].copy()
        phi[:, _RAMP] += t0 * X[:N_XI, N_XI:]
        return phi

    def closed_form(self, t: float, t0: float = 0.0) -> ClosedForm:
        """A(t), B(t), C(t) of Eq. (5), from phase t0 to t0 + t [s]."""
        phi = self.propagator(t0, t)
        return ClosedForm(A=phi[Q, Q], B=phi[Q, U], C=phi[Q, D])

    def modal_basis(self, t: float) -> np.ndarray:
        """φ(t) = [1, t, cosh ω₁t, sinh ω₁t, cos ω₂t, sin ω₂t], shape (6,)."""
        a, b = self.omega_fall * t, self.omega_swing * t
        return np.array([1.0, t, np.cosh(a), np.sinh(a), np.cos(b), np.sin(b)])

    def modal_coefficients(self, xi: np.ndarray) -> np.ndarray:
        """Coefficients W with q(t) = W φ(t), for a step that starts (t = 0) at ξ.

        The modal closed form (note §3): per axis, the relative coordinates r = [p − s, f − s]
        obey Mm r̈ = K r + g0 + g1 t. Their solution is the particular part −K⁻¹(g0 + g1 t)
        plus a cosh/sinh falling mode and a cos/sin swinging mode. The stance foot drifts at
        its initial velocity (0 in practice).

        Args:
            xi: ξ at the step start, shape (24,).

        Returns:
            W, shape (12, 6), velocity rows included.
        """
        ax = self.axis
        w1, w2 = self.omega_fall, self.omega_swing
        bu = np.array([[0.0, 1.0], [-1.0, 0.0]])  # [τ_h, τ_a] -> row forces on [p, f]
        bd = np.diag([1.0, -ax.stiffness[1, 1]])  # [δ, σ] -> row forces on [p, f]
        coef = np.zeros((N_Q, 6))
        vinv = np.linalg.inv(self._modes)
        q, u, d = xi[Q], xi[U], xi[D]
        for a in range(2):  # axes x, y
            s0, sd0 = q[4 + a], q[10 + a]
            r0 = np.array([q[2 + a], q[a]]) - s0
            rd0 = np.array([q[8 + a], q[6 + a]]) - sd0
            g0 = bu @ u[[0 + a, 4 + a]] + bd @ d[[a, 2 + a]]  # [Nm]
            g1 = bu @ u[[2 + a, 6 + a]]  # [Nm/s]
            c0 = -np.linalg.solve(ax.stiffness, g0)
            c1 = -np.linalg.solve(ax.stiffness, g1)
            z0, zd0 = vinv @ (r0 - c0), vinv @ (rd0 - c1)
            # r(t) coefficients on φ = [1, t, ch, sh, c, s]
            r = np.zeros((2, 6))
            r[:, 0], r[:, 1] = c0, c1
            r[:, 2], r[:, 3] = self._modes[:, 0] * z0[0], self._modes[:, 0] * zd0[0] / w1
            r[:, 4], r[:, 5] = self._modes[:, 1] * z0[1], self._modes[:, 1] * zd0[1] / w2
            stance = np.array([s0, sd0, 0, 0, 0, 0])
            coef[4 + a] = stance
            coef[2 + a] = stance + r[0]
            coef[0 + a] = stance + r[1]
        # φ̇ = Dφ, so velocity coefficients are W_pos D.
        dphi = np.zeros((6, 6))
        dphi[1, 0] = 1.0
        dphi[2, 3] = dphi[3, 2] = w1
        dphi[4, 5], dphi[5, 4] = -w2, w2
        coef[6:] = coef[:6] @ dphi
        return coef


def _axis_matrices(p: ThreeLPParams) -> AxisMatrices:
    """Single-support mass, stiffness and matrices of one axis (note §2)."""
    kappa = p.h2 / p.h1
    m = p.total_mass
    z_t = p.h1 + p.h3 * np.cos(p.theta)  # torso CoM height [m]
    mu = p.m1 + 2 * p.m2 * (1 - kappa) - p.r_g * m  # [kg]
    d1 = p.m1 * z_t + 2 * p.m2 * (p.h1 - p.h2) ** 2 / p.h1 + (p.I2 + p.I3) / p.h1
    c = p.m2 * p.h2 * (p.h1 - p.h2) / p.h1 - p.I2 / p.h1
    d2 = p.m2 * p.h2**2 / p.h1 + p.I2 / p.h1
    mass = np.array([[d1, c], [c, d2]])  # on [p̈, f̈], [kg m]
    k_leg = p.m2 * p.g * kappa  # swing-leg gravity stiffness [N]
    gmu = p.g * mu  # [N]
    stiffness = np.array([[gmu, k_leg], [k_leg, -k_leg]])
    # Rows [p, f] of the right-hand side, on x = [f, p, s], [τ_h, τ_a] and [δ, σ].
    rhs_x = np.array([[k_leg, gmu, -(gmu + k_leg)], [-k_leg, k_leg, 0.0]])
    rhs_u = np.array([[0.0, 1.0], [-1.0, 0.0]])
    rhs_d = np.array([[1.0, 0.0], [0.0, k_leg]])
    minv = np.linalg.inv(mass)
    to_fps = np.array([[0.0, 1.0], [1.0, 0.0], [0.0, 0.0]])  # [p̈, f̈] -> [f̈, p̈, s̈ = 0]
    return AxisMatrices(
        mass=mass,
        stiffness=stiffness,
        Cx=to_fps @ minv @ rhs_x,
        Cu=to_fps @ minv @ rhs_u,
        Cd=to_fps @ minv @ rhs_d,
    )


def _time_varying_system(ax: AxisMatrices) -> tuple[np.ndarray, np.ndarray]:
    """F0, F1 of ξ̇ = (F0 + t F1) ξ, the 3D model block-diagonal over the axes (note §3)."""
    eye2 = np.eye(2)
    cx, cu, cd = np.kron(ax.Cx, eye2), np.kron(ax.Cu, eye2), np.kron(ax.Cd, eye2)
    f0 = np.zeros((N_XI, N_XI))
    f1 = np.zeros((N_XI, N_XI))
    f0[0:6, 6:12] = np.eye(6)
    f0[6:12, 0:6] = cx
    f0[6:12, _CONST] = cu  # columns [hip x, hip y, ankle x, ankle y]
    f0[6:12, D] = cd
    f1[6:12, _RAMP] = cu
    return f0, f1


def _augmented_system(f0: np.ndarray, f1: np.ndarray) -> np.ndarray:
    """Constant F of the augmented state [ξ, v], v = t·ξ_ramp, v̇ = ξ_ramp (note §3)."""
    n_v = len(_RAMP)
    f = np.zeros((N_XI + n_v, N_XI + n_v))
    f[:N_XI, :N_XI] = f0
    f[:N_XI, N_XI:] = f1[:, _RAMP]  # t·F1 ξ = F1[:, ramp] v
    f[N_XI + np.arange(n_v), _RAMP] = 1.0
    return f


def mirror(n: int = 8) -> np.ndarray:
    """The mirror y → −y of an interleaved (x, y) vector of length n, shape (n, n).

    For n = 8 this is O of Eq. (8): sagittal components keep their sign from one step to the
    next, lateral ones flip, because left and right steps are mirror images.
    """
    return np.diag(np.tile([1.0, -1.0], n // 2))


def relabel() -> np.ndarray:
    """The touchdown relabelling S of Eq. (3), acting on ξ, shape (24, 24).

    Swaps the swing- and stance-foot positions and keeps the world-frame velocities, so
    after it the swing-velocity slot still holds the landing velocity that the gait and the
    DLQR constrain to zero (note §4). It also mirrors the step: the lateral torque
    parameters and the side sign in σ flip; the external torque δ does not.
    """
    s = np.eye(N_XI)
    s[SWING, SWING] = s[STANCE, STANCE] = 0.0
    s[SWING, STANCE] = s[STANCE, SWING] = np.eye(2)
    s[U, U] = mirror(N_U)
    s[N_Q + N_U + 3, N_Q + N_U + 3] = -1.0  # σ_y = side·pw
    return s


def relative_coordinates() -> np.ndarray:
    """M: state q → symmetric error coordinates e = [p − f, p − s, ḟ, ṗ], shape (8, 12).

    Note §4. Invariant to translations of the whole state.
    """
    m = np.zeros((8, N_Q))
    eye = np.eye(2)
    m[0:2, PELVIS], m[0:2, SWING] = eye, -eye
    m[2:4, PELVIS], m[2:4, STANCE] = eye, -eye
    m[4:6, SWING_VEL] = eye
    m[6:8, PELVIS_VEL] = eye
    return m


def reconstruction() -> np.ndarray:
    """M̂ of Eq. (11): e → q with the stance foot at rest at the origin, shape (12, 8).

    M M̂ = I.
    """
    r = np.zeros((N_Q, 8))
    eye = np.eye(2)
    r[PELVIS, 2:4] = eye
    r[SWING, 2:4], r[SWING, 0:2] = eye, -eye  # f = p − (p − f)
    r[SWING_VEL, 4:6] = eye
    r[PELVIS_VEL, 6:8] = eye
    return r
