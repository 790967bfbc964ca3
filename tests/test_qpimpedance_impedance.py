"""Tests of the impedance modification of the swing-foot reference (Jo & Oh Eqs. 1–3), the
package's ``tasks.advance_impedance``."""

from __future__ import annotations

import numpy as np

from walkrepro.papers.jo_oh.tasks import (
    IMPEDANCE_STATE,
    DesiredMotion,
    ImpedanceGains,
    advance_impedance,
)

M, B, K = np.array([30.0, 0.3, 0.3]), np.array([120.0, 0.6, 0.6]), np.array([1500.0, 10.0, 10.0])
GAINS = ImpedanceGains(M, B, K, np.array([10.0, 3.0, 3.0]))  # 10 N, 3 N m thresholds (§IV)
ZERO = np.zeros(3)


class Foot:
    """One foot's impedance state, (x_m, ẋ_m, ẍ_m) and (armed, active), as the tick keeps it."""

    def __init__(self) -> None:
        self.record = np.zeros(1, dtype=IMPEDANCE_STATE)

    def update(
        self,
        desired: tuple[np.ndarray, np.ndarray, np.ndarray],
        wrench: np.ndarray,
        dt: float,
        enabled: bool = True,
    ) -> bool:
        """One control period of :func:`advance_impedance`; whether it switched on."""
        motion = DesiredMotion(*(np.asarray(d, dtype=float) for d in desired))
        return advance_impedance(
            self.record[0], motion, np.asarray(wrench, float), GAINS, dt, enabled
        )

    @property
    def state(self) -> np.ndarray:
        """(x_m, ẋ_m, ẍ_m), shape (3, 3)."""
        r = self.record[0]
        return np.array([r["position"], r["velocity"], r["acceleration"]])

    @property
    def active(self) -> bool:
        return bool(self.record[0]["active"])


def _msd_step_response(m: float, b: float, k: float, f: float, t: np.ndarray) -> np.ndarray:
    """Closed-form x(t) of m ẍ + b ẋ + k x = f from rest (underdamped)."""
    wn = np.sqrt(k / m)
    zeta = b / (2 * np.sqrt(k * m))
    wd = wn * np.sqrt(1 - zeta**2)
    return f / k * (1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t)))


def test_modified_reference_is_a_mass_spring_damper() -> None:
    """Under a constant contact wrench and a resting desired pose, x_m follows the closed-form
    response of Eq. (1), M_d ẍ + B_d ẋ + K_d x = λ."""
    foot = Foot()
    dt, n = 1e-4, 5000
    wrench = np.array([60.0, 4.0, -5.0])
    rest = (ZERO, ZERO, ZERO)
    foot.update(rest, ZERO, dt)  # unloaded first: the foot has left the ground
    xs = np.zeros((n, 3))
    for i in range(n):
        foot.update(rest, wrench, dt)
        xs[i] = foot.state[0]
    t = dt * np.arange(1, n + 1)
    for axis in range(3):
        expected = _msd_step_response(M[axis], B[axis], K[axis], wrench[axis], t)
        scale = abs(wrench[axis]) / K[axis]
        assert np.max(np.abs(xs[:, axis] - expected)) < 2e-3 * scale


def test_below_threshold_the_reference_is_unmodified() -> None:
    """Wrenches under 10 N and 3 N m leave the desired reference untouched."""
    foot = Foot()
    desired = (np.array([0.05, 0.0, 0.0]), np.array([-0.3, 0.0, 0.0]), np.array([2.0, 0.0, 0.0]))
    assert not foot.update(desired, np.array([9.0, 2.9, -2.9]), 1e-3)
    assert not foot.active
    np.testing.assert_array_equal(foot.state, np.array(desired))


def test_load_at_lift_off_does_not_switch_impedance_on() -> None:
    """The residual load of a foot just lifting off is not an unexpected contact; a later one is."""
    foot = Foot()
    rest, load = (ZERO, ZERO, ZERO), np.array([80.0, 0.0, 0.0])
    assert not foot.update(rest, load, 1e-3)
    foot.update(rest, ZERO, 1e-3)
    assert foot.update(rest, load, 1e-3)
    assert foot.active


def test_switched_off_without_impedance() -> None:
    """With the modification disabled (the paper's comparison) a landing never switches it on,
    and the reference stays the desired one."""
    foot = Foot()
    desired = (np.array([0.02, 0.01, 0.0]), np.array([-0.2, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]))
    foot.update(desired, ZERO, 1e-3, enabled=False)
    for _ in range(20):
        assert not foot.update(desired, np.array([200.0, 5.0, 0.0]), 1e-3, enabled=False)
    assert not foot.active
    np.testing.assert_array_equal(foot.state, np.array(desired))


def test_eq2_integrates_from_the_desired_state_at_switch_on() -> None:
    """At switch-on x_m, ẋ_m start at the desired state (a continuous reference), and Eq. (2)
    ẍ_m = ẍ_d + M_d⁻¹ (λ + B_d ė + K_d e) is integrated semi-implicitly."""
    foot = Foot()
    x_d, v_d, a_d = np.array([0.03, 0.01, -0.02]), np.array([-0.2, 0.1, 0.0]), np.array([1.0, 0, 0])
    wrench = np.array([50.0, 4.0, 0.0])
    foot.update((x_d, v_d, a_d), ZERO, 1e-3)
    assert foot.update((x_d, v_d, a_d), wrench, 1e-3)
    a_m = a_d + wrench / M  # e = ė = 0 at switch-on
    v_m = v_d + a_m * 1e-3
    np.testing.assert_allclose(foot.state, [x_d + v_m * 1e-3, v_m, a_m], rtol=1e-15)
