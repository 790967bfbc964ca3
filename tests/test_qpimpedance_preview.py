"""Tests of the flat-ground footstep plan and the ZMP preview control (Kajita et al. 2003)."""

from __future__ import annotations

import numpy as np
import pytest

from walkrepro.papers.jo_oh.footsteps import RIGHT, WalkPattern, plan_walk
from walkrepro.papers.jo_oh.preview import generate_com, preview_gains
from walkrepro.papers.jo_oh.tasks import SWING_PLAN, pack_swing, swing_reference

DT = 0.005


def _plan():  # noqa: ANN202 - FootstepPlan
    return plan_walk(WalkPattern(0.09, 0.35, 6, RIGHT, 1.0, 0.56, 0.14, 0.5), DT)


def test_zmp_of_generated_com_tracks_reference() -> None:
    """The cart-table ZMP of the preview-control CoM follows the reference ZMP within millimetres."""
    plan = _plan()
    gains = preview_gains(DT, 0.85, 1.0, 1.0, 1e-6)
    for axis in range(2):
        states, zmp = generate_com(gains, plan.zmp_xy[:, axis])
        err = np.abs(zmp - plan.zmp_xy[:, axis])
        steady = plan.zmp_t > 0.3  # the preview sees the first step only 1 s ahead
        assert np.sqrt(np.mean(err**2)) < 0.01
        assert np.max(err[steady]) < 0.02
        # and the CoM ends at rest above the final ZMP
        assert abs(states[-1, 0] - plan.zmp_xy[-1, axis]) < 0.01


def test_plan_timing_and_strides() -> None:
    """Steps take 0.56 s swing + 0.14 s double support and the feet travel 0.35 m (half at the ends)."""
    plan = _plan()
    swings = [p for p in plan.phases if p.swing >= 0]
    assert len(swings) == 6
    for p in swings:
        assert abs((p.t1 - p.t0) - 0.56) < 1e-9
    xs = [p.target[0] for p in swings]
    np.testing.assert_allclose(np.diff([0.0, *xs[::2]]), [0.175, 0.35, 0.35])
    assert xs[-1] == pytest.approx(xs[-2])  # feet side by side at the end


def test_swing_trajectory_ends_at_target_with_zero_velocity() -> None:
    """The swing (the tick's swing_reference) starts at lift-off, peaks at the apex and lands on
    the target at rest."""
    start = np.array([0.0, -0.09, 0.04, 0.1, 0.0])
    target = np.array([0.35, -0.09, 0.0, 0.0, 0.0])
    packed = np.zeros(1, dtype=SWING_PLAN)
    pack_swing(1.0, 0.56, start, target, 0.1, 0.4, packed)

    def at(t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        pos, vel, acc = np.empty(5), np.empty(5), np.empty(5)
        swing_reference(packed, t, pos, vel, acc)
        return pos, vel, acc

    p0, _, _ = at(1.0)
    p1, v1, _ = at(1.56)
    np.testing.assert_allclose(p0, start)
    np.testing.assert_allclose(p1, target, atol=1e-12)
    np.testing.assert_allclose(v1, 0.0, atol=1e-12)
    assert abs(at(1.0 + 0.4 * 0.56)[0][2] - 0.14) < 1e-12
