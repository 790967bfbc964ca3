"""Step-to-step error map and the landing-constrained DLQR (Paper II, Eqs. 11-14, 17).

The error E[k] = M (Q[k] − Q̄[k]) at a touchdown evolves over one step as

    E[k+1] = Â E[k] + B̂ ΔU[k],   Ĉ E[k+1] = 0   (Eq. 13),

where ΔU = [δτh_c; δτh_r] (x, y each) corrects the swing-hip torque parameters and Ĉ picks the
swing-foot velocity at touchdown, which must be zero. The errors are expressed in the frame
of the next step's left swing (the mirror O of Eq. 8), so one gain serves both sides.

The constraint is eliminated by choosing the ramp torques w to null the landing velocity;
the constant torques v are the free inputs of an ordinary DLQR on the other six
coordinates (note ``3lp.md`` §6).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_discrete_are

from walkrepro.papers.faraji.threelp import (
    HIP,
    Q,
    ThreeLP,
    U,
    mirror,
    reconstruction,
    relabel,
    relative_coordinates,
)

#: Order of the coordinates y = S_y E: the six free ones (y_v), then the landing swing
#: velocity (y_w), which Ĉ of Eq. (14) constrains. The rows of S_y pick these from E.
_FREE = np.array([0, 1, 2, 3, 6, 7])
_LANDING = np.array([4, 5])
#: Number of free coordinates y_v and of free (constant-torque) inputs v.
N_FREE, N_V = 6, 2


def constraint_selector() -> np.ndarray:
    """S_y = [C_p; C_h]: E → y = [y_v (6); y_w (2)], a permutation, shape (8, 8).

    C_h = Ĉ of Eq. (14) picks the swing-foot velocity; the rows of C_p, an orthonormal basis
    of ker C_h, pick everything else.
    """
    return np.eye(8)[np.r_[_FREE, _LANDING]]


def error_map(model: ThreeLP, t0: float, step_time: float) -> tuple[np.ndarray, np.ndarray]:
    """Â and B̂ of Eq. (14), from phase t0 to the end of the step.

    Â = O M S A M̂ and B̂ = O M S B[:, hip], with A, B the closed form of the remaining
    step Φ(t0, T − t0). For t0 = 0 this is the step-to-step map; for t0 > 0 it is the
    remaining-step map A_H(t), B_H(t) of the time projection (note §7).

    Args:
        model: the 3LP model.
        t0: current phase time [s].
        step_time: step time T [s].

    Returns:
        Â, shape (8, 8), and B̂, shape (8, 4), on ΔU = [δτh_c (x, y), δτh_r (x, y)] [Nm, Nm/s].
    """
    phi = model.propagator(t0, step_time - t0)
    to_next = mirror(8) @ relative_coordinates() @ relabel()[Q, Q]  # O M S
    a_hat = to_next @ phi[Q, Q] @ reconstruction()
    b_hat = to_next @ phi[Q, U][:, HIP]
    return a_hat, b_hat


def default_weights(model: ThreeLP) -> tuple[np.ndarray, np.ndarray]:
    """The note's weights (§6), which make the costs dimensionless.

    Returns:
        Q = diag(1/h1² on positions, 1/(g h1) on velocities), shape (8, 8), and
        R = diag(1, 1, 0, 0)/(m g)², shape (4, 4): only the constant torques cost, the
        ramps are fixed by the landing constraint.
    """
    p = model.params
    q = np.diag(np.r_[np.full(4, 1 / p.h1**2), np.full(4, 1 / (p.g * p.h1))])
    r = np.diag([1.0, 1.0, 0.0, 0.0]) / (p.total_mass * p.g) ** 2
    return q, r


def split_blocks(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, ...]:
    """Split A (8×8, in y coordinates) and B (8×4) into their v/w blocks.

    Returns:
        A_vv, A_vw, A_wv, A_ww, B_vv, B_vw, B_wv, B_ww, with v the six free coordinates (or
        the two constant torques) and w the two landing velocities (or the two ramps).
    """
    v, w = slice(0, N_FREE), slice(N_FREE, 8)
    bv, bw = slice(0, N_V), slice(N_V, 4)
    return a[v, v], a[v, w], a[w, v], a[w, w], b[v, bv], b[v, bw], b[w, bv], b[w, bw]


@dataclass(frozen=True)
class Dlqr:
    """The discrete LQR of Eq. (17) with the landing-velocity constraint eliminated.

    In y = S_y E and ΔU = [v; w], the constraint y_w[k+1] = 0 (with y_w[k] = 0) fixes
    w = G y_v + H v, leaving y_v[k+1] = Ā y_v[k] + B̄ v[k] and v = −K y_v.
    """

    step_time: float
    """Step time T [s]."""
    A_hat: np.ndarray
    """Â of Eq. (14), shape (8, 8)."""
    B_hat: np.ndarray
    """B̂ of Eq. (14), shape (8, 4)."""
    Q: np.ndarray
    """State weight on E, shape (8, 8)."""
    R: np.ndarray
    """Input weight on ΔU, shape (4, 4)."""
    G: np.ndarray
    """Ramp torques that null the landing velocity, w = G y_v + H v, shape (2, 6)."""
    H: np.ndarray
    """See G, shape (2, 2)."""
    A_bar: np.ndarray
    """Reduced state matrix Ā = A_vv + B_vw G, shape (6, 6)."""
    B_bar: np.ndarray
    """Reduced input matrix B̄ = B_vv + B_vw H, shape (6, 2)."""
    P: np.ndarray
    """Solution of the discrete Riccati equation, shape (6, 6)."""
    K: np.ndarray
    """Reduced gain, v = −K y_v, shape (2, 6)."""
    gain: np.ndarray
    """Full gain of Eq. (17), ΔU = −gain · E, shape (4, 8)."""

    @classmethod
    def solve(
        cls,
        model: ThreeLP,
        step_time: float,
        Q: np.ndarray | None = None,
        R: np.ndarray | None = None,
    ) -> Dlqr:
        """Build the error map and solve the constrained DLQR (note §6).

        Â and B̂ depend on the model and the step time only, never on the speed, so neither
        do the gains.

        Args:
            model: the 3LP model.
            step_time: step time T [s].
            Q: weight on E, shape (8, 8); None for :func:`default_weights`.
            R: weight on ΔU, shape (4, 4); None for :func:`default_weights`.

        Returns:
            The controller.
        """
        q_def, r_def = default_weights(model)
        q = q_def if Q is None else np.asarray(Q, dtype=float)
        r = r_def if R is None else np.asarray(R, dtype=float)
        a_hat, b_hat = error_map(model, 0.0, step_time)
        s_y = constraint_selector()
        a_vv, _, a_wv, _, b_vv, b_vw, b_wv, b_ww = split_blocks(s_y @ a_hat @ s_y.T, s_y @ b_hat)
        b_ww_inv = np.linalg.inv(b_ww)
        g = -b_ww_inv @ a_wv
        h = -b_ww_inv @ b_wv
        a_bar = a_vv + b_vw @ g
        b_bar = b_vv + b_vw @ h
        # Carry the cost through ΔU = [v; G y + H v] (y_w = 0, so only Q_vv remains).
        q_vv = (s_y @ q @ s_y.T)[:N_FREE, :N_FREE]
        r_vv, r_vw, r_ww = r[:N_V, :N_V], r[:N_V, N_V:], r[N_V:, N_V:]
        q_bar = q_vv + g.T @ r_ww @ g
        r_bar = r_vv + r_vw @ h + h.T @ r_vw.T + h.T @ r_ww @ h
        n_bar = g.T @ (r_vw.T + r_ww @ h)
        p = solve_discrete_are(a_bar, b_bar, q_bar, r_bar, s=n_bar)
        k = np.linalg.solve(r_bar + b_bar.T @ p @ b_bar, b_bar.T @ p @ a_bar + n_bar.T)
        # ΔU = [v; w] = [−K; G − H K] y_v, and y_v = C_p E.
        full = np.vstack([k, -(g - h @ k)]) @ s_y[:N_FREE]
        return cls(
            step_time=float(step_time),
            A_hat=a_hat,
            B_hat=b_hat,
            Q=q,
            R=r,
            G=g,
            H=h,
            A_bar=a_bar,
            B_bar=b_bar,
            P=p,
            K=k,
            gain=full,
        )

    @property
    def closed_loop_eigenvalues(self) -> np.ndarray:
        """Eigenvalues of the reduced closed loop Ā − B̄ K, shape (6,)."""
        return np.linalg.eigvals(self.A_bar - self.B_bar @ self.K)

    def correction(self, error: np.ndarray) -> np.ndarray:
        """ΔU = −K E of Eq. (17) for a touchdown error E, shape (4,) [Nm, Nm/s].

        Args:
            error: E = M (Q − Q̄) at the step start, shape (8,); its swing-velocity entries
                are ignored (the swing foot starts at rest).
        """
        return -self.gain @ np.asarray(error, dtype=float)
