"""The periodic 3LP gait for a commanded speed (Paper II, Eqs. 9-10; note ``3lp.md`` §5).

A step starts with the stance foot at rest at the origin and the swing foot at rest at
(−v T, W). The pelvis position and velocity and the four swing-hip torque parameters are
solved so that, after one step and the touchdown relabelling, the relative state repeats in
the sagittal plane, mirrors in the lateral plane, and the swing foot lands at rest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from walkrepro.papers.faraji.threelp import (
    ANKLE,
    HIP_C,
    HIP_R,
    N_Q,
    N_XI,
    PELVIS,
    PELVIS_VEL,
    SWING,
    D,
    Q,
    ThreeLP,
    U,
    mirror,
    relabel,
    relative_coordinates,
)

# Unknowns of the periodic gait, as indices in ξ: pelvis position and velocity (x, y) and the
# swing-hip constant and ramp torques (x, y). Eight unknowns for eight equations (note §5).
_UNKNOWNS = np.r_[np.arange(N_Q)[PELVIS], np.arange(N_Q)[PELVIS_VEL], N_Q + np.arange(4)]
_M = relative_coordinates()
# Rows of q = [f, p, s, ḟ, ṗ, ṡ] (x, y interleaved) for f_x, p_x, s_x, ḟ_x, ṗ_x.
_SAGITTAL_ROWS = (0, 2, 4, 6, 8)


def landing_mirror() -> np.ndarray:
    """O₀: the mirror O with its two swing-velocity entries set to 0, shape (8, 8).

    In R ξ̄ = (M S Φ(0, T) − O₀ M) ξ̄ = 0 the swing-velocity rows then say that the swing foot
    lands at rest, the paper's separate condition N Q̄ = 0 (Eq. 9).
    """
    o0 = mirror(8)
    o0[4:6, 4:6] = 0.0
    return o0


@dataclass(frozen=True)
class PeriodicGait:
    """A periodic 3LP gait (Eq. 9) and its nominal trajectory over a step (Eq. 10).

    Everything is stored for a left swing (side d = +1); the right swing is its mirror image
    y → −y. Phase time t runs from 0 at touchdown to the step time T.
    """

    model: ThreeLP
    """The 3LP model the gait belongs to."""
    speed: float
    """Commanded average forward speed v [m/s]."""
    step_time: float
    """Step time T [s] (single support only, as in Paper II)."""
    step_width: float
    """Lateral distance W between the feet at touchdown [m]."""
    start: np.ndarray
    """ξ̄ at the step start for d = +1, shape (24,): state, inputs, disturbances."""
    residual: float
    """Max-abs periodicity residual ‖R ξ̄‖∞ of Eq. (9) [m, m/s]."""
    coefficients: np.ndarray
    """Modal coefficients W of q̄(t) = W φ(t) for d = +1, shape (12, 6)."""

    _sagittal_rows: tuple[tuple[float, ...], ...] = field(init=False, repr=False, compare=False)
    """Rows of W for f_x, p_x, s_x, ḟ_x, ṗ_x as floats (:meth:`sagittal_relative_state`)."""

    def __post_init__(self) -> None:
        # Shared by every caller of `initial` and `inputs`: make in-place edits fail loudly.
        self.start.flags.writeable = False
        self.coefficients.flags.writeable = False
        rows = tuple(tuple(self.coefficients[i].tolist()) for i in _SAGITTAL_ROWS)
        object.__setattr__(self, "_sagittal_rows", rows)

    @classmethod
    def solve(
        cls,
        model: ThreeLP,
        speed: float,
        step_time: float,
        step_width: float,
        ankle_torque: ArrayLike | None = None,
    ) -> PeriodicGait:
        """Solve the periodic gait of Eq. (9) with one 8×8 linear solve.

        Args:
            model: the 3LP model.
            speed: commanded average forward speed v [m/s].
            step_time: step time T [s].
            step_width: lateral foot spacing W at touchdown [m].
            ankle_torque: nominal stance-ankle parameters [τa_c (x, y), τa_r (x, y)] for
                d = +1, in [Nm] and [Nm/s]; None for the paper's free ankles (compass gait).

        Returns:
            The gait.
        """
        if step_time <= 0:
            raise ValueError(f"step_time must be positive, got {step_time}")
        fixed = np.zeros(N_XI)
        fixed[Q][SWING] = (-speed * step_time, step_width)
        if ankle_torque is not None:
            fixed[U][ANKLE] = np.asarray(ankle_torque, dtype=float)
        fixed[D] = model.disturbance(side=+1)

        m = _M
        s_q = relabel()[Q, Q]
        phi_q = model.propagator(0.0, step_time)[Q]
        r = m @ s_q @ phi_q
        r[:, Q] -= landing_mirror() @ m
        xi = fixed.copy()
        xi[_UNKNOWNS] = np.linalg.solve(r[:, _UNKNOWNS], -r @ fixed)
        return cls(
            model=model,
            speed=float(speed),
            step_time=float(step_time),
            step_width=float(step_width),
            start=xi,
            residual=float(np.abs(r @ xi).max()),
            coefficients=model.modal_coefficients(xi),
        )

    def initial(self, side: int = 1) -> np.ndarray:
        """ξ̄ at the step start for swing side d = ±1, shape (24,), read-only for d = +1."""
        return self.start if side > 0 else mirror(N_XI) @ self.start

    def inputs(self, side: int = 1) -> np.ndarray:
        """Nominal input parameters u = [τh_c, τh_r, τa_c, τa_r], shape (8,)."""
        return self.initial(side)[U]

    def disturbance(self, side: int = 1) -> np.ndarray:
        """Nominal disturbance vector d = [δ, σ], shape (4,)."""
        return self.initial(side)[D]

    def state(self, t: float, side: int = 1) -> np.ndarray:
        """Nominal state q̄(t) = A(t) Q̄ + B(t) Ū + C(t) D̄ of Eq. (10), shape (12,).

        Evaluated in modal form (a 12×6 product), cheap enough for every control tick.

        Args:
            t: phase time since touchdown [s].
            side: swing side d = ±1; −1 gives the mirror image.
        """
        q = self.coefficients @ self.model.modal_basis(t)
        if side < 0:
            q[1::2] *= -1.0
        return q

    def relative_state(self, t: float, side: int = 1) -> np.ndarray:
        """Nominal symmetric coordinates M q̄(t) = [p − f, p − s, ḟ, ṗ], shape (8,).

        The error of Eq. (15) is then e(t) = M q(t) − M q̄(t), whatever the stance position.
        """
        return _M @ self.state(t, side)

    def sagittal_relative_state(self, t: float) -> tuple[float, float, float, float]:
        """The sagittal entries of :meth:`relative_state`, ((p − f)_x, (p − s)_x, ḟ_x, ṗ_x).

        The same for both swing sides (the mirror flips only y). Plain floats: the
        controller calls it every tick.

        Args:
            t: phase time since touchdown [s].
        """
        a, b = self.model.omega_fall * t, self.model.omega_swing * t
        ch, sh, co, si = math.cosh(a), math.sinh(a), math.cos(b), math.sin(b)
        f, p, s, fd, pd = (
            w0 + w1 * t + w2 * ch + w3 * sh + w4 * co + w5 * si
            for w0, w1, w2, w3, w4, w5 in self._sagittal_rows
        )
        return p - f, p - s, fd, pd

    def hip_torque(self, t: float, side: int = 1) -> np.ndarray:
        """Nominal swing-hip torque τ̄(t) = τ_c + t τ_r (Eq. 4), signed per axis [Nm], (2,)."""
        u = self.inputs(side)
        return u[HIP_C] + t * u[HIP_R]
