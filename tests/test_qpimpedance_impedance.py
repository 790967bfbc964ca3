"""Tests of the impedance modification of the swing-foot reference (Jo & Oh Eqs. 1–3)."""

from __future__ import annotations

import numpy as np
from oracles.jo_oh_impedance import ImpedanceFilter, reference_acceleration

M, B, K = np.array([30.0, 0.3, 0.3]), np.array([120.0, 0.6, 0.6]), np.array([1500.0, 10.0, 10.0])


def _filter() -> ImpedanceFilter:
    return ImpedanceFilter(M, B, K, force_threshold=10.0, torque_threshold=3.0)


def _msd_step_response(m: float, b: float, k: float, f: float, t: np.ndarray) -> np.ndarray:
    """Closed-form x(t) of m ẍ + b ẋ + k x = f from rest (underdamped)."""
    wn = np.sqrt(k / m)
    zeta = b / (2 * np.sqrt(k * m))
    wd = wn * np.sqrt(1 - zeta**2)
    return f / k * (1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t)))


def test_modified_reference_is_a_mass_spring_damper() -> None:
    """Under a constant contact wrench and a resting desired pose, x_m follows the closed-form MSD response."""
    f = _filter()
    dt, n = 1e-4, 5000
    wrench = np.array([60.0, 4.0, -5.0])
    zero = np.zeros(3)
    f.update(zero, zero, zero, zero, dt)  # unloaded first: the foot has left the ground
    xs = np.zeros((n, 3))
    for i in range(n):
        xs[i] = f.update(zero, zero, zero, wrench, dt)[0]
    t = dt * np.arange(1, n + 1)
    for axis in range(3):
        expected = _msd_step_response(M[axis], B[axis], K[axis], wrench[axis], t)
        scale = abs(wrench[axis]) / K[axis]
        assert np.max(np.abs(xs[:, axis] - expected)) < 2e-3 * scale


def test_below_threshold_the_reference_is_unmodified() -> None:
    """Wrenches under 10 N and 3 N m leave the desired reference untouched."""
    f = _filter()
    x_d, v_d, a_d = (
        np.array([0.05, 0.0, 0.0]),
        np.array([-0.3, 0.0, 0.0]),
        np.array([2.0, 0.0, 0.0]),
    )
    x_m, v_m, a_m = f.update(x_d, v_d, a_d, np.array([9.0, 2.9, -2.9]), 1e-3)
    assert not f.active
    np.testing.assert_array_equal(x_m, x_d)
    np.testing.assert_array_equal(v_m, v_d)
    np.testing.assert_array_equal(a_m, a_d)


def test_load_at_lift_off_does_not_switch_impedance_on() -> None:
    """The residual load of a foot just lifting off is not an unexpected contact; a later one is."""
    f = _filter()
    zero = np.zeros(3)
    f.update(zero, zero, zero, np.array([80.0, 0.0, 0.0]), 1e-3)
    assert not f.active
    f.update(zero, zero, zero, zero, 1e-3)
    f.update(zero, zero, zero, np.array([80.0, 0.0, 0.0]), 1e-3)
    assert f.active


def test_reset_in_support_re_initialises() -> None:
    """reset() switches the modification off and sets the modified values to the desired ones."""
    f = _filter()
    zero = np.zeros(3)
    f.update(zero, zero, zero, zero, 1e-3)
    for _ in range(10):
        f.update(zero, zero, zero, np.array([100.0, 0.0, 0.0]), 1e-3)
    assert f.active and f.x_m[0] != 0.0
    f.reset(np.array([0.04, 0.0, 0.0]), zero, zero)
    assert not f.active
    np.testing.assert_array_equal(f.x_m, [0.04, 0.0, 0.0])


def test_reference_acceleration_is_eq3() -> None:
    """Eq. (3): ẍ_r = ẍ_m + K_v (ẋ_m − ẋ) + K_p (x_m − x)."""
    a = reference_acceleration(
        np.array([1.0, 0, 0]),
        np.array([2.0, 0, 0]),
        np.array([3.0, 0, 0]),
        np.zeros(3),
        np.zeros(3),
        np.full(3, 10.0),
        np.full(3, 5.0),
    )
    np.testing.assert_allclose(a, [3.0 + 5.0 * 2.0 + 10.0 * 1.0, 0, 0])
