"""Tests of the qpimpedance controller's tick (Jo & Oh §III-D) on the kist_humanoid model."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from walkrepro.controllers import controller_class
from walkrepro.papers.jo_oh.controller import SIGNAL_LAYOUT, SIGNALS, SUPPORTS
from walkrepro.papers.jo_oh.tasks import FOOT_SIGNALS, TICK_SIGNALS
from walkrepro.sim.robot import load_robot


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


def test_the_removed_solver_params_are_rejected() -> None:
    """The solver is ``qp_solver`` (and its tolerance ``qp_tolerance``): the earlier names
    ``solver`` and ``solver_eps`` are rejected, not silently ignored."""
    cls = controller_class("qpimpedance")
    for name, value in (("solver", "proxqp"), ("solver_eps", 1e-6)):
        with pytest.raises(ValidationError, match=name):
            cls.Params(**{name: value})


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


def _perturbed(snapshot, rng: np.random.Generator):  # noqa: ANN001, ANN202
    """The home snapshot with noisy joints, base and F/T readings (exercises every row)."""
    snapshot.joint_pos[:] += rng.normal(0, 0.02, snapshot.joint_pos.size)
    snapshot.joint_vel[:] = rng.normal(0, 0.2, snapshot.joint_vel.size)
    snapshot.base_linvel[:] = rng.normal(0, 0.05, 3)
    snapshot.base_angvel[:] = rng.normal(0, 0.05, 3)
    snapshot.left_ft[:] += rng.normal(0, 20, 6)
    snapshot.right_ft[:] += rng.normal(0, 20, 6)
    return snapshot


def test_data_views_follow_and_equal_fresh_reads(kist_home_snapshot) -> None:
    """The views of Data follow it; refreshing them every tick (the fallback) changes no output."""
    robot = load_robot("kist_humanoid")
    cls = controller_class("qpimpedance")
    controllers = [cls(), cls()]
    for ctrl in controllers:
        ctrl.reset(robot, cls.Params(), 0.001)
    assert not controllers[0]._refresh_views  # this Pinocchio returns views of Data
    assert controllers[0]._views.follows()
    controllers[1]._refresh_views = True
    rng = np.random.default_rng(0)
    for t in np.arange(0.0, 2.0, 0.05):  # double support, then the first swing
        snapshot = _perturbed(kist_home_snapshot(), rng)
        a, b = (ctrl.step(float(t), snapshot) for ctrl in controllers)
        np.testing.assert_allclose(a.ctrl, b.ctrl, rtol=0, atol=1e-9)
        assert a.signals.keys() == b.signals.keys() and a.events == b.events
        np.testing.assert_allclose(list(a.signals.values()), list(b.signals.values()), atol=1e-9)
        assert controllers[0]._views.follows()


def test_the_signal_record_holds_every_field_the_kernel_writes() -> None:
    """The controller's one signal declaration holds task_rows' fields and each foot's block,
    and its float64 view is the logged vector, field for field."""
    assert set(TICK_SIGNALS) <= set(SIGNALS.names)
    assert SIGNALS["left"] == SIGNALS["right"] == FOOT_SIGNALS
    names = [name for name, _, _ in SIGNAL_LAYOUT.fields]
    assert [n for n in names if n.startswith("left_")][: len(FOOT_SIGNALS.names)] == [
        f"left_{n}" for n in FOOT_SIGNALS.names
    ]
    assert SIGNAL_LAYOUT.width * 8 == SIGNALS.itemsize


def test_signals_follow_the_documented_order(kist_home_snapshot) -> None:
    """A tick logs the kernel's head, each support foot's QP f_z, then CoM, ZMP and failures."""
    robot = load_robot("kist_humanoid")
    cls = controller_class("qpimpedance")
    ctrl = cls()
    ctrl.reset(robot, cls.Params(), 0.001)
    names = [name for name, _, _ in SIGNAL_LAYOUT.fields]
    head, tail = names[: names.index("left_fz_qp")], names[names.index("right_fz_qp") + 1 :]
    seen = set()
    for phase in ctrl._plan.phases[:4]:  # stand, swing, double support, other swing
        cmd = ctrl.step(0.5 * (phase.t0 + phase.t1), kist_home_snapshot())
        support = SUPPORTS[phase.swing + 1]
        fz = [f"{('left', 'right')[side]}_fz_qp" for side in support]
        assert list(cmd.signals) == [*head, *fz, *tail]
        assert cmd.signals["swing_foot"] == phase.swing
        seen.add(support)
    assert len(seen) == 3  # both feet, then each foot alone


def test_failed_qp_holds_the_last_torques_and_logs_it(kist_home_snapshot) -> None:
    """When the QP finds no solution the tick repeats the last torques, logs qp_failed and no QP forces."""
    robot = load_robot("kist_humanoid")
    cls = controller_class("qpimpedance")
    ctrl = cls()
    ctrl.reset(robot, cls.Params(), 0.001)
    first = ctrl.step(0.0, kist_home_snapshot())
    for qp in ctrl._qps.values():
        qp.solve = lambda warm: False
    failed = ctrl.step(0.001, kist_home_snapshot())
    np.testing.assert_array_equal(failed.ctrl, first.ctrl)
    assert failed.ctrl is not first.ctrl
    assert [e["kind"] for e in failed.events] == ["qp_failed"]
    assert not any(key.endswith("_fz_qp") for key in failed.signals)
    assert failed.signals["qp_failures"] == 1.0
