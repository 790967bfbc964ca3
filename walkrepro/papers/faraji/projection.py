"""Time-projection control as look-up tables (Paper II, Eqs. 15-18 and Fig. 13).

At phase time t the error e(t) = M (q(t) − q̄(t)) (Eq. 15) is projected back to a virtual
step-start error y₀: the one whose DLQR correction, applied from now to the end of the step,
gives the same end-of-step error (Eq. 18, with the landing constraint eliminated; note
``3lp.md`` §7). Everything is linear in e(t), so the whole controller is two tables over the
phase, computed off-line:

- torque gains, δu(t) = −K_tp(t) e(t), the correction of the swing-hip parameters
  [δτh_c; δτh_r] (Fig. 13A, for torque-controlled robots);
- footstep gains, Δf(T) = F(t) e(t), the resulting change of the touchdown position of the
  swing foot (Fig. 13B, Paper II's position-controlled robot). Truncate it
  (:func:`truncate_footstep`) and divide by the pelvis height (:func:`attack_angle`).

On-line, either table is a linear interpolation and a small matrix-vector product.

The gains are the same for a left and a right swing (the mirror O commutes with them), so
errors and corrections can stay in world-aligned axes on both sides.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from walkrepro.papers.faraji.dlqr import (
    Dlqr,
    constraint_selector,
    error_map,
    split_blocks,
)
from walkrepro.papers.faraji.gait import PeriodicGait
from walkrepro.papers.faraji.threelp import (
    HIP,
    SWING,
    Q,
    ThreeLP,
    U,
    reconstruction,
)

#: Paper II, Fig. 13 caption: footstep adjustments are truncated at 15 cm ≈ 0.35 z [m].
FOOTSTEP_LIMIT = 0.15
#: Indices of the sagittal components of e = [p − f, p − s, ḟ, ṗ] (Paper II uses only these).
SAGITTAL = np.array([0, 2, 4, 6])


@dataclass(frozen=True)
class ProjectionGains:
    """Time-projection gains at one phase time t (note §7)."""

    torque: np.ndarray
    """K_tp(t): δu = −K_tp e, on δu = [δτh_c (x, y), δτh_r (x, y)], shape (4, 8)."""
    footstep: np.ndarray
    """F(t): change of the swing-foot touchdown position Δf = F e [m], shape (2, 8)."""


def projection_gains(model: ThreeLP, dlqr: Dlqr, t: float) -> ProjectionGains:
    """Exact time-projection gains at phase time t (Eqs. 16-18, note §7).

    With y = S_y e and the remaining-step map A_H(t), B_H(t) (:func:`~.dlqr.error_map`):

    - the ramp w nulls the landing velocity, including the current swing velocity y_w:
      w = G_t y + H_t v, G_t = −B_ww⁺ [A_wv A_ww], H_t = −B_ww⁺ B_wv;
    - the free end error is then y_end = Â_t y + B̂_t v, Â_t = [A_vv A_vw] + B_vw G_t,
      B̂_t = B_vv + B_vw H_t;
    - the virtual step-start error y₀ whose DLQR action v = −K y₀ gives the same end error
      solves (Ā − B̄ K) y₀ = Â_t y − B̂_t K y₀ (Eq. 18), so y₀ = L Â_t y with
      L = (Ā − (B̄ − B̂_t) K)⁻¹;
    - K_tp = [K L Â_t S_y; −G_t S_y + H_t K L Â_t S_y].

    The footstep gain follows the closed loop to the end of the step. Without further
    disturbance the correction stays constant along it (the property of note §7), so
    Δq(T) = A(t→T) M̂ e + B(t→T) δu exactly.

    Args:
        model: the 3LP model.
        dlqr: the DLQR for the same step time.
        t: phase time, 0 ≤ t < T [s].

    Returns:
        The gains.
    """
    step_time = dlqr.step_time
    if not 0 <= t < step_time:
        raise ValueError(f"phase time must be in [0, {step_time}), got {t}")
    s_y = constraint_selector()
    a_h, b_h = error_map(model, t, step_time)
    a_vv, a_vw, a_wv, a_ww, b_vv, b_vw, b_wv, b_ww = split_blocks(s_y @ a_h @ s_y.T, s_y @ b_h)
    # B_ww → 0 as t → T; the pseudo-inverse keeps the solve defined up to the end.
    b_ww_pinv = np.linalg.pinv(b_ww)
    g_t = -b_ww_pinv @ np.hstack([a_wv, a_ww])  # (2, 8)
    h_t = -b_ww_pinv @ b_wv  # (2, 2)
    a_t = np.hstack([a_vv, a_vw]) + b_vw @ g_t  # (6, 8)
    b_t = b_vv + b_vw @ h_t  # (6, 2)
    lmat = np.linalg.inv(dlqr.A_bar - (dlqr.B_bar - b_t) @ dlqr.K)
    k_v = dlqr.K @ lmat @ a_t @ s_y  # v = −k_v e
    torque = np.vstack([k_v, -g_t @ s_y + h_t @ k_v])

    phi = model.propagator(t, step_time - t)
    end = phi[Q, Q] @ reconstruction() - phi[Q, U][:, HIP] @ torque  # Δq(T) = end · e
    return ProjectionGains(torque=torque, footstep=end[SWING])


@dataclass(frozen=True)
class TimeProjection:
    """Look-up tables of the time-projection controller over the phase (Fig. 13).

    Samples sit at t_i = i T / n, i = 0 … n − 1: the gains are singular at t = T, where no
    control authority is left. Between samples the gains are interpolated linearly; past the
    last sample they are held.

    Warning:
        ‖K_tp(t)‖ grows sharply near the end of the step, because the remaining authority
        B_H(t) → 0; the footstep gains stay bounded. On a real robot use the footstep table,
        or saturate or freeze the torque correction in the last ~10 % of the step.
    """

    step_time: float
    """Step time T [s]."""
    phases: np.ndarray
    """Sample phase times t_i [s], shape (n,)."""
    torque_gains: np.ndarray
    """K_tp(t_i): δu = −K_tp e, shape (n, 4, 8), in [Nm/m, Nm s/m, ...]."""
    footstep_gains: np.ndarray
    """F(t_i): Δf(T) = F e [m], shape (n, 2, 8)."""
    _torque_slopes: np.ndarray = field(init=False, repr=False)
    _footstep_slopes: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        for table in (self.phases, self.torque_gains, self.footstep_gains):
            table.flags.writeable = False
        # Slopes per interval, so an on-line lookup is one multiply-add.
        object.__setattr__(self, "_torque_slopes", np.diff(self.torque_gains, axis=0))
        object.__setattr__(self, "_footstep_slopes", np.diff(self.footstep_gains, axis=0))

    @classmethod
    def build(
        cls, model: ThreeLP, gait: PeriodicGait, dlqr: Dlqr, n_samples: int = 100
    ) -> TimeProjection:
        """Tabulate the gains of :func:`projection_gains` over a step.

        The gains depend on the model and the step time, not on the gait's speed; the gait is
        taken for its step time.

        Args:
            model: the 3LP model.
            gait: the periodic gait (its step time must match the DLQR's).
            dlqr: the DLQR.
            n_samples: samples per step (≈ 100 in the note).

        Returns:
            The tables.
        """
        if not np.isclose(gait.step_time, dlqr.step_time):
            raise ValueError(
                f"gait step time {gait.step_time} s != DLQR step time {dlqr.step_time} s"
            )
        if n_samples < 2:
            raise ValueError(f"n_samples must be >= 2, got {n_samples}")
        phases = dlqr.step_time * np.arange(n_samples) / n_samples
        gains = [projection_gains(model, dlqr, t) for t in phases]
        return cls(
            step_time=dlqr.step_time,
            phases=phases,
            torque_gains=np.stack([g.torque for g in gains]),
            footstep_gains=np.stack([g.footstep for g in gains]),
        )

    def locate(self, t: float) -> tuple[int, float]:
        """Where phase time t falls on the tables' uniform grid: the interval index i and the
        fraction a in [0, 1] along it, so a gain at t is ``table[i] + a * slope[i]`` (the
        linear interpolation of Fig. 13's tables; held past the last sample).

        Args:
            t: phase time since touchdown [s].

        Returns:
            (i, a): 0 ≤ i ≤ n − 2 [-], 0 ≤ a ≤ 1 [-].
        """
        s = t * (len(self.phases) / self.step_time)
        if s <= 0.0:
            return 0, 0.0
        i = int(s)
        if i >= len(self.phases) - 1:
            return len(self.phases) - 2, 1.0
        return i, s - i

    def torque_gain(self, t: float) -> np.ndarray:
        """K_tp(t) interpolated, shape (4, 8)."""
        i, a = self.locate(t)
        return self.torque_gains[i] + a * self._torque_slopes[i]

    def footstep_gain(self, t: float) -> np.ndarray:
        """F(t) interpolated, shape (2, 8)."""
        i, a = self.locate(t)
        return self.footstep_gains[i] + a * self._footstep_slopes[i]

    def torque_correction(self, t: float, e: np.ndarray) -> np.ndarray:
        """δu = −K_tp(t) e(t), the hip-parameter correction of Eq. (18).

        Args:
            t: phase time since touchdown [s].
            e: error e(t) = M (q(t) − q̄(t)), shape (8,) [m, m/s].

        Returns:
            [δτh_c (x, y) [Nm], δτh_r (x, y) [Nm/s]], shape (4,), signed per axis; replaces
            (does not accumulate onto) the previous tick's correction.
        """
        return -(self.torque_gain(t) @ e)

    def hip_torque_correction(self, t: float, e: np.ndarray) -> np.ndarray:
        """The swing-hip torque correction δτ(t) = δτh_c + t δτh_r [Nm], shape (2,)."""
        du = self.torque_correction(t, e)
        return du[:2] + t * du[2:]

    def footstep_adjustment(self, t: float, e: np.ndarray) -> tuple[float, float]:
        """Change (Δx, Δy) of the touchdown position of the swing foot [m] (Fig. 13B).

        Args:
            t: phase time since touchdown [s].
            e: error e(t) = M (q(t) − q̄(t)), shape (8,) [m, m/s].

        Returns:
            (Δx, Δy) [m], untruncated; see :func:`truncate_footstep`.
        """
        dx, dy = self.footstep_gain(t) @ e
        return float(dx), float(dy)


def truncate_footstep(step: float, limit: float = FOOTSTEP_LIMIT) -> float:
    """Clip a footstep adjustment to ±limit [m] (Paper II, Fig. 13: 15 cm)."""
    return min(max(float(step), -limit), limit)


def attack_angle(step: float, pelvis_height: float) -> float:
    """Attack-angle adjustment [rad] ≈ footstep adjustment / pelvis height h1 (Fig. 13).

    Args:
        step: footstep adjustment [m], truncated first.
        pelvis_height: 3LP pelvis height h1 [m].
    """
    return step / pelvis_height
