"""Readable numpy reference of Paper III's impedance modification of the swing-foot
reference (§II, Eqs. 1–3), a test oracle: the controller runs it compiled,
``walkrepro.papers.jo_oh.tasks.advance_impedance``, which tests/test_qpimpedance_tasks.py
checks against this one.

The model (Eqs. 1–3, and why e uses the modified state) is described at
``advance_impedance``.
"""

from __future__ import annotations

import numpy as np


class ImpedanceFilter:
    """Eqs. (1)–(3) for one foot over (z [m], φ_x [rad], φ_y [rad]).

    The controller's tick runs the compiled copy :func:`.tasks.advance_impedance`; this class
    is its readable reference, and the tests hold the two equal.

    Args:
        m_d: desired mass / inertia M_d, shape (3,) [kg, kg m², kg m²].
        b_d: desired damping B_d, shape (3,) [N s/m, N m s/rad, N m s/rad].
        k_d: desired stiffness K_d, shape (3,) [N/m, N m/rad, N m/rad].
        force_threshold: |λ_z| that switches the modification on [N].
        torque_threshold: |λ_φx| or |λ_φy| that switches it on [N m].
    """

    def __init__(
        self,
        m_d: np.ndarray,
        b_d: np.ndarray,
        k_d: np.ndarray,
        force_threshold: float,
        torque_threshold: float,
    ) -> None:
        self.m_d = np.asarray(m_d, dtype=float)
        self.b_d = np.asarray(b_d, dtype=float)
        self.k_d = np.asarray(k_d, dtype=float)
        self.thresholds = np.array([force_threshold, torque_threshold, torque_threshold])
        self.active = False
        self.armed = False
        self.x_m = np.zeros(3)
        self.v_m = np.zeros(3)
        self.a_m = np.zeros(3)

    def reset(self, x_d: np.ndarray, v_d: np.ndarray, a_d: np.ndarray) -> None:
        """Re-initialise in support: the modified reference is the desired one, switched off."""
        self.active = False
        self.armed = False
        self.x_m[:] = x_d
        self.v_m[:] = v_d
        self.a_m[:] = a_d

    def update(
        self,
        x_d: np.ndarray,
        v_d: np.ndarray,
        a_d: np.ndarray,
        wrench: np.ndarray,
        dt: float,
        enabled: bool = True,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Advance one control period and return the modified (x_m, ẋ_m, ẍ_m).

        Args:
            x_d, v_d, a_d: desired (z, φ_x, φ_y), rates and accelerations.
            wrench: contact wrench on the foot λ = (f_z [N], μ_x [N m], μ_y [N m]).
            dt: control period [s].
            enabled: False runs without impedance (the modified reference is the desired one).
        """
        over = bool(np.any(np.abs(wrench) > self.thresholds))
        if not self.armed and not over:
            self.armed = True  # the foot has left the ground: a new contact is unexpected
        if enabled and self.armed and not self.active and over:
            self.active = True  # start from the desired state: the reference stays continuous
            self.x_m[:] = x_d
            self.v_m[:] = v_d
        if not self.active:
            self.x_m[:] = x_d
            self.v_m[:] = v_d
            self.a_m[:] = a_d
            return self.x_m, self.v_m, self.a_m
        e = x_d - self.x_m
        e_dot = v_d - self.v_m
        self.a_m[:] = a_d + (wrench + self.b_d * e_dot + self.k_d * e) / self.m_d  # Eq. (2)
        self.v_m += self.a_m * dt
        self.x_m += self.v_m * dt
        return self.x_m, self.v_m, self.a_m


def reference_acceleration(
    x_m: np.ndarray,
    v_m: np.ndarray,
    a_m: np.ndarray,
    x: np.ndarray,
    v: np.ndarray,
    k_p: np.ndarray,
    k_v: np.ndarray,
) -> np.ndarray:
    """Eq. (3): ẍ_r = ẍ_m + K_v (ẋ_m − ẋ) + K_p (x_m − x)."""
    return a_m + k_v * (v_m - v) + k_p * (x_m - x)
