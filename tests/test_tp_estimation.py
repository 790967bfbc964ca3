"""Tests of Paper II's estimation filters and foot-lift laws (Eqs. 21-30)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from walkrepro.papers.faraji import lift
from walkrepro.papers.faraji.estimation import (
    IirFilter,
    KinematicState,
    MovingAverageDerivative,
    dead_zone,
    smooth_dead_zone,
)
from walkrepro.sim.robot import load_robot


def test_dead_zone_attenuates_64_percent_at_threshold() -> None:
    """The smooth dead-zone (Eq. 27) keeps 36 % of the signal at x = a (Fig. 10)."""
    a = 0.02
    y = float(smooth_dead_zone(a, a))
    assert 1.0 - y / a == pytest.approx(0.64, abs=0.005)


def test_dead_zone_is_odd_and_shifts_large_signals() -> None:
    """The dead-zone is odd, and far from the threshold it is a shift by a."""
    a = np.array([0.01, 0.1])
    x = np.array([0.005, 10.0])
    np.testing.assert_allclose(smooth_dead_zone(-x, a), -smooth_dead_zone(x, a))
    assert float(smooth_dead_zone(10.0, 0.1)) == pytest.approx(10.0 - 0.1, abs=1e-3)
    assert float(smooth_dead_zone(0.3, 0.0)) == 0.3  # a = 0 disables it


def test_scalar_dead_zone_matches_the_array_one() -> None:
    """dead_zone (one float, per tick) equals smooth_dead_zone, threshold 0 included."""
    for x in (-0.3, -0.02, 0.0, 0.001, 0.05, 2.0):
        for a in (0.0, 0.022, 0.23):
            assert dead_zone(x, a) == pytest.approx(float(smooth_dead_zone(x, a)), abs=1e-15)


def test_iir_filter_converges_with_rate_zeta() -> None:
    """The IIR of Eq. (26) moves a fraction ζ toward a step input each sample."""
    f = IirFilter(0.1, 1)
    f.reset(np.zeros(1))
    assert f.update(np.ones(1))[0] == pytest.approx(0.1)
    for _ in range(200):
        f.update(np.ones(1))
    assert f.value[0] == pytest.approx(1.0, abs=1e-6)


def test_moving_average_derivative_of_a_ramp_is_its_slope() -> None:
    """Differentiation plus a 30-sample average returns the slope of a ramp."""
    dt = 0.002
    d = MovingAverageDerivative(30, 1, dt)
    out = np.zeros(1)
    for i in range(100):
        out = d.update(np.array([0.5 * i * dt]))
    assert out[0] == pytest.approx(0.5)


def test_kinematics_put_the_home_feet_under_the_hips() -> None:
    """At home with a level IMU, the soles are 0.52 m below the pelvis and 14 cm apart."""
    robot = load_robot("coman")
    left, right, roll, pitch = KinematicState(robot).feet(
        np.array([1.0, 0, 0, 0]), robot.home_joint_pos
    )
    assert left[2] == pytest.approx(-robot.nominal_pelvis_height, abs=1e-6)
    assert left[1] - right[1] == pytest.approx(0.14, abs=1e-6)
    assert roll == pytest.approx(0.0) and pitch == pytest.approx(0.0)


def test_lift_laws_vanish_at_phase_changes() -> None:
    """Roll (Eq. 22), fixed lift (Eq. 23) and adaptive lift (Eq. 29) are zero at t = 0 and T."""
    T = 0.4
    for t in (0.0, T):
        assert lift.pelvis_roll(t, T, 0.1) == pytest.approx(0.0, abs=1e-12)
        assert lift.fixed_lift(t, T, 0.01) == pytest.approx(0.0, abs=1e-12)
        assert lift.adaptive_lift(t, T, 0.3, 0.52) == pytest.approx(0.0, abs=1e-12)
    assert lift.fixed_lift(T / 2, T, 0.01) == pytest.approx(0.01)


def test_hip_switch_hands_over_between_tracking_and_torso() -> None:
    """γ of Eq. (24) starts at 0 in swing and 1 in stance and swaps by t ≈ 2 t1."""
    t1 = 0.08
    assert lift.hip_switch_gamma(0.0, t1, swing=True) == 0.0
    assert lift.hip_switch_gamma(0.0, t1, swing=False) == 1.0
    assert lift.hip_switch_gamma(2 * t1, t1, swing=True) == pytest.approx(1 - math.exp(-4))


def test_knee_compensation_scales_with_load() -> None:
    """Eq. (21): the knee offset is μ at full body weight and 0 when unloaded."""
    assert lift.knee_target_offset(300.0, 300.0, 0.03) == pytest.approx(-0.03)
    assert lift.knee_target_offset(0.0, 300.0, 0.03) == 0.0


def test_kinematics_match_a_floating_base_with_the_heading_removed() -> None:
    """feet() equals Pinocchio's floating-base kinematics at the IMU tilt without its yaw."""
    import pinocchio as pin

    robot = load_robot("coman")
    rng = np.random.default_rng(3)
    q_joints = robot.home_joint_pos + rng.uniform(-0.2, 0.2, robot.n_joints)
    roll, pitch, yaw = 0.1, -0.15, 0.8
    rot = pin.rpy.rpyToMatrix(roll, pitch, yaw)
    quat = pin.Quaternion(rot)
    left, right, roll_est, pitch_est = KinematicState(robot).feet(
        np.array([quat.w, quat.x, quat.y, quat.z]), q_joints
    )
    model = robot.pin_model
    data = model.createData()
    q = pin.neutral(model)
    q[3:7] = pin.Quaternion(pin.rpy.rpyToMatrix(roll, pitch, 0.0)).coeffs()
    q[robot.pin_q_idx] = q_joints
    pin.framesForwardKinematics(model, data, q)
    for name, got in (("left_sole", left), ("right_sole", right)):
        want = data.oMf[model.getFrameId(name)].translation
        np.testing.assert_allclose(got, want, atol=1e-12)
    assert roll_est == pytest.approx(roll) and pitch_est == pytest.approx(pitch)


def test_moving_average_derivative_swap_carries_the_history_by_role() -> None:
    """After a swap, channel 0 averages channel 1's past rates plus its own new ones."""
    f = MovingAverageDerivative(window=4, size=2, dt=1.0)
    for k in range(5):
        f.update([1.0 * k, 3.0 * k])  # rates 1 and 3
    f.swap(0, 1)
    out = f.update([5.0, 15.0])  # the next rates are 1 and 3 again
    assert out[0] == pytest.approx((3.0 * 3 + 1.0) / 4)
    assert out[1] == pytest.approx((1.0 * 3 + 3.0) / 4)
