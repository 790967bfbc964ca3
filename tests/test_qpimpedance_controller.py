"""Tests of the qpimpedance controller's tick (Jo & Oh §III-D) on the kist_humanoid model."""

from __future__ import annotations

import numpy as np

from walkrepro.controllers import controller_class
from walkrepro.robot import load_robot


def test_standing_tick_puts_the_weight_on_both_feet(kist_home_snapshot) -> None:
    """At home in double support the QP's contact forces carry the robot's weight and the torques are finite."""
    robot = load_robot("kist_humanoid")
    cls = controller_class("qpimpedance")
    ctrl = cls()
    ctrl.reset(robot, cls.Params(), 0.001)
    cmd = ctrl.step(0.0, kist_home_snapshot())
    assert cmd.ctrl.shape == (robot.n_joints,)
    assert np.all(np.isfinite(cmd.ctrl))
    total = cmd.signals["left_fz_qp"] + cmd.signals["right_fz_qp"]
    assert abs(total - robot.total_mass * 9.81) < 0.05 * robot.total_mass * 9.81
    assert cmd.signals["swing_foot"] == -1.0


def test_unknown_solver_is_rejected_with_the_valid_names() -> None:
    """A spec naming an unsupported QP solver fails at reset and lists proxqp and osqp."""
    robot = load_robot("kist_humanoid")
    cls = controller_class("qpimpedance")
    try:
        cls().reset(robot, cls.Params(solver="cvxopt"), 0.001)
    except ValueError as exc:
        assert "proxqp" in str(exc) and "osqp" in str(exc)
    else:  # pragma: no cover
        raise AssertionError("expected a ValueError")


def test_ticks_are_deterministic_and_signals_plain(kist_home_snapshot) -> None:
    """Two controllers fed the same snapshots agree (to SIMD rounding); signals are plain floats."""
    robot = load_robot("kist_humanoid")
    cls = controller_class("qpimpedance")
    commands = []
    for _ in range(2):
        ctrl = cls()
        ctrl.reset(robot, cls.Params(), 0.001)
        commands.append([ctrl.step(0.001 * k, kist_home_snapshot()) for k in range(5)])
    for a, b in zip(*commands, strict=True):
        # Within one process the arrays sit at different addresses, and Eigen's and BLAS's
        # SIMD sums round by alignment (≈ 1e-14); a fresh process repeats a run bit for bit.
        np.testing.assert_allclose(a.ctrl, b.ctrl, rtol=1e-9, atol=1e-9)
        assert a.signals.keys() == b.signals.keys()
        np.testing.assert_allclose(list(a.signals.values()), list(b.signals.values()), atol=1e-9)
        assert all(type(v) is float for v in a.signals.values())


def test_osqp_runs_through_qpsolvers(kist_home_snapshot) -> None:
    """With solver osqp the tick goes through qpsolvers and still carries the robot's weight."""
    robot = load_robot("kist_humanoid")
    cls = controller_class("qpimpedance")
    ctrl = cls()
    ctrl.reset(robot, cls.Params(solver="osqp"), 0.001)
    cmd = ctrl.step(0.0, kist_home_snapshot())
    total = cmd.signals["left_fz_qp"] + cmd.signals["right_fz_qp"]
    assert abs(total - robot.total_mass * 9.81) < 0.05 * robot.total_mass * 9.81
