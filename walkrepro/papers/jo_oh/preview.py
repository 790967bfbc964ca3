"""LIPM CoM–ZMP preview control (Kajita et al. 2003; the paper's walking pattern, ref. [23]).

The cart-table model with the CoM jerk as input, sampled at ``dt``:

    x_{k+1} = A x_k + B u_k,  x = (c, ċ, c̈),  p_k = C x_k = c_k − (z_c / g) c̈_k,

with the servo (integral) form of Katayama et al.: the optimal input is

    u_k = −G_i Σ_{j≤k} (p_j − p^ref_j) − G_x x_k − Σ_{l=1}^{N} G_p(l) p^ref_{k+l},

which minimises Σ Q_e e² + R u² over an infinite horizon with N samples of preview.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_discrete_are

GRAVITY = 9.81  # [m/s^2]


@dataclass(frozen=True)
class PreviewGains:
    """Gains of the preview servo.

    Attributes:
        a: state matrix A, shape (3, 3).
        b: input matrix B, shape (3,).
        c: output row C, shape (3,).
        gi: integral gain G_i [-].
        gx: state gain G_x, shape (3,).
        gp: preview gains G_p(1..N), shape (N,).
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    gi: float
    gx: np.ndarray
    gp: np.ndarray


def preview_gains(
    dt: float, com_height: float, preview_time: float, q_e: float, r_u: float
) -> PreviewGains:
    """Solve the preview servo's Riccati equation and its preview gains.

    Args:
        dt: sample time [s].
        com_height: constant CoM height z_c of the LIPM [m].
        preview_time: preview horizon [s].
        q_e: weight on the ZMP error [1/m²].
        r_u: weight on the CoM jerk [s⁶/m²].
    """
    a = np.array([[1.0, dt, dt**2 / 2], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    b = np.array([dt**3 / 6, dt**2 / 2, dt])
    c = np.array([1.0, 0.0, -com_height / GRAVITY])
    # Augmented system on (Σe, x): the integral of the ZMP error leads.
    at = np.zeros((4, 4))
    at[0, 0] = 1.0
    at[0, 1:] = c @ a
    at[1:, 1:] = a
    bt = np.concatenate([[c @ b], b])[:, None]
    qt = np.zeros((4, 4))
    qt[0, 0] = q_e
    p = solve_discrete_are(at, bt, qt, np.array([[r_u]]))
    s = r_u + (bt.T @ p @ bt).item()
    k = (bt.T @ p @ at).ravel() / s
    ac = at - bt @ k[None, :]
    n = int(round(preview_time / dt))
    gp = np.zeros(n)
    i_t = np.array([1.0, 0.0, 0.0, 0.0])
    x = -ac.T @ p @ i_t
    gp[0] = -k[0]
    for j in range(1, n):
        gp[j] = (bt.T @ x).item() / s
        x = ac.T @ x
    return PreviewGains(a=a, b=b, c=c, gi=float(k[0]), gx=k[1:], gp=gp)


def generate_com(
    gains: PreviewGains, zmp_ref: np.ndarray, x0: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Run the preview servo along a whole ZMP reference (one axis).

    Args:
        gains: from :func:`preview_gains`.
        zmp_ref: reference ZMP samples, shape (K,) [m]; the last value is held beyond.
        x0: initial (c, ċ, c̈), default at rest above the first reference ZMP.

    Returns:
        CoM states (c [m], ċ [m/s], c̈ [m/s²]), shape (K, 3), and the resulting ZMP, shape (K,).
    """
    n = gains.gp.size
    k_total = zmp_ref.size
    padded = np.concatenate([zmp_ref, np.full(n + 1, zmp_ref[-1])])
    x = np.array([zmp_ref[0], 0.0, 0.0]) if x0 is None else np.asarray(x0, dtype=float).copy()
    states = np.zeros((k_total, 3))
    zmp = np.zeros(k_total)
    err_sum = 0.0
    for k in range(k_total):
        states[k] = x
        zmp[k] = gains.c @ x
        err_sum += zmp[k] - zmp_ref[k]
        u = -gains.gi * err_sum - gains.gx @ x - gains.gp @ padded[k + 1 : k + 1 + n]
        x = gains.a @ x + gains.b * u
    return states, zmp
