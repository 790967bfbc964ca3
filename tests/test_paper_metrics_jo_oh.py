"""Paper III (Jo & Oh) metrics on small synthetic logs: one where the claim holds, one where
it does not."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from test_metrics import (
    DT,
    FEET,
    Poser,
    Tick,
    _robot,
    home_sole,
    make_spec,
    measured,
    standing_pairs,
    unmeasurable_reason,
    write_log,
)

from walkrepro.metrics import LogData

ROBOT = "kist_humanoid"
TOP = 0.04  # [m] block height
BLOCK = {"name": "obstacle_block", "size": [0.16, 0.3, TOP], "position": [0.2, -0.1, TOP / 2]}


def _spec(duration: float):  # noqa: ANN202
    return make_spec(
        ROBOT,
        duration,
        controller={"type": "qpimpedance", "params": {}},
        world={"obstacles": [BLOCK]},
    )


@pytest.fixture(scope="module")
def poser() -> Poser:
    """The kist_humanoid poser."""
    return Poser(ROBOT)


#: The right sole's path: (start time [s], end time [s], x [m], z [m] at the end, arc
#: height above the higher end [m] (None: slides without lifting), surface it ends on).
ON_AND_OFF = [(0.2, 0.6, 0.2, TOP, 0.05, "obstacle_block"), (1.0, 1.4, 0.45, 0.0, 0.05, "floor")]
SLIDE_OFF = [(0.2, 0.6, 0.2, TOP, 0.05, "obstacle_block"), (1.0, 1.4, 0.45, 0.0, None, "floor")]


def _right_foot(
    poser: Poser, tmp_path: Path, path, duration: float, outcome: str = "complete"
) -> LogData:  # noqa: ANN001
    """The right foot follows ``path``; unloaded while it moves, loaded on its surface after."""
    x0, y, _ = home_sole(ROBOT, "right_foot")
    ticks = []
    for k in range(int(round(duration / DT)) + 1):
        t = k * DT
        xa, za, surface, moving = 0.0, 0.0, "floor", False
        for t0, t1, xb, zb, arc, on in path:
            if t >= t1:
                xa, za, surface = xb, zb, on
                continue
            if t >= t0:
                s = (t - t0) / (t1 - t0)
                x = xa + (xb - xa) * s
                if arc is None:  # slides along the block, then drops off its edge
                    z = za if s < 0.8 else zb
                else:
                    z = za + (zb - za) * s + arc * math.sin(math.pi * s)
                moving = True
            break
        if not moving:
            x, z = xa, za
        pairs = standing_pairs(ROBOT, ["left_foot"] if moving else ["left_foot", "right_foot"])
        if not moving:
            pairs[f"right_foot/{surface}"] = pairs.pop("right_foot/floor")
        # The pelvis follows the foot half-way, a little lower, so both legs reach.
        qpos = poser((0.5 * x, 0.0, -0.1 * x), right_foot=(x0 + x, y, z))
        ticks.append(Tick(t, qpos=qpos, pairs=pairs))
    if outcome == "fell":
        ticks[-1].events = [{"kind": "fall", "reason": "pelvis low"}]
    return write_log(tmp_path / "r.mcap", ticks, _spec(duration), outcome)


def test_steps_on_and_off_the_block(poser: Poser, tmp_path: Path) -> None:
    """A foot that lifts onto the block and later lifts off it to the floor stepped on and off."""
    d = _right_foot(poser, tmp_path, ON_AND_OFF, 2.0)
    assert measured(d, "footsteps:right_foot") == 2
    assert measured(d, "stepped_on_off:right_foot") == 1


def test_sliding_off_the_block_is_not_stepping_off(poser: Poser, tmp_path: Path) -> None:
    """A foot that slides off the block's edge to the floor did not step off it."""
    d = _right_foot(poser, tmp_path, SLIDE_OFF, 2.0)
    assert measured(d, "footsteps:right_foot") == 1
    assert measured(d, "stepped_on_off:right_foot") == 0


def test_fall_is_a_measured_failure(poser: Poser, tmp_path: Path) -> None:
    """A robot that falls has not overcome the block: 0, not a missing value."""
    d = _right_foot(poser, tmp_path, ON_AND_OFF, 2.0, outcome="fell")
    assert measured(d, "stepped_on_off:right_foot") == 0


def test_interrupted_on_the_block_not_measurable(poser: Poser, tmp_path: Path) -> None:
    """A run interrupted while the foot is still on the block does not answer the claim."""
    d = _right_foot(poser, tmp_path, ON_AND_OFF[:1], 0.9, outcome="interrupted")
    assert "before the foot stepped onto and off" in unmeasurable_reason(
        d, "stepped_on_off:right_foot"
    )


def test_stands_two_seconds_after_the_last_step(poser: Poser, tmp_path: Path) -> None:
    """The last step lands at 1.4 s of a 3.5 s run: 2.1 s after it (≥ 2 s)."""
    d = _right_foot(poser, tmp_path, ON_AND_OFF, 3.5)
    assert measured(d, "time_after_last_step") == pytest.approx(2.1, abs=DT)


def test_too_little_time_after_the_last_step(poser: Poser, tmp_path: Path) -> None:
    """A run that ends 1.1 s after the last step fails the 2 s claim."""
    assert measured(_right_foot(poser, tmp_path, ON_AND_OFF, 2.5), "time_after_last_step") < 2


def test_time_after_last_step_not_measurable_after_a_fall(poser: Poser, tmp_path: Path) -> None:
    """After a fall the standing time is not measurable."""
    d = _right_foot(poser, tmp_path, ON_AND_OFF, 3.5, outcome="fell")
    assert unmeasurable_reason(d, "time_after_last_step").startswith(
        "the robot fell at t = 3.500 s"
    )


# ---- landing on the block (Figs. 4, 5) -----------------------------------------------------


T_CONTACT = 0.5  # [s]


def _landing(tmp_path: Path, vz_until: float, peak: float, late_peak: float = 0.0) -> LogData:
    """The right foot meets the block at 0.5 s with a force ``peak`` [N]; the robot's z
    velocity is 0.2 m/s until ``vz_until`` [s] after that, then 0; a ``late_peak`` at 0.9 s."""
    nv = _robot(ROBOT).home_qpos.size - 1
    ticks = []
    for k in range(int(round(1.5 / DT))):
        t = round(k * DT, 6)
        qvel = np.zeros(nv)
        if T_CONTACT - 0.1 <= t < T_CONTACT + vz_until:
            qvel[2] = -0.2 if (k % 2) else 0.2
        pairs = standing_pairs(ROBOT, ["left_foot"] if t >= T_CONTACT else FEET)
        if t >= T_CONTACT:
            force = peak if abs(t - T_CONTACT - 0.05) < 1e-9 else 300.0
            force = late_peak if late_peak and abs(t - 0.9) < 1e-9 else force
            pairs["right_foot/obstacle_block"] = [0.0, 0.0, force, 0.0, 0.0, 0.0]
        ticks.append(Tick(t, qvel=qvel, pairs=pairs))
    return write_log(tmp_path / "l.mcap", ticks, _spec(1.5))


def test_impedance_settles_faster(tmp_path: Path) -> None:
    """A foot still after 60 ms settles faster than one shaking for 300 ms (Fig. 5b)."""
    fast = measured(_landing(tmp_path, 0.06, 500.0), "swing_z_settling_time:right_foot")
    slow = measured(_landing(tmp_path, 0.30, 500.0), "swing_z_settling_time:right_foot")
    assert fast == pytest.approx(0.05, abs=DT) and slow == pytest.approx(0.29, abs=DT)
    assert fast < slow


def test_equal_settling_is_no_improvement(tmp_path: Path) -> None:
    """Two feet settling equally fast do not show the impedance's effect."""
    a = measured(_landing(tmp_path, 0.06, 500.0), "swing_z_settling_time:right_foot")
    b = measured(_landing(tmp_path, 0.06, 650.0), "swing_z_settling_time:right_foot")
    assert not a < b


def test_lower_landing_peak_with_impedance(tmp_path: Path) -> None:
    """The landing peak is the largest force within 0.3 s of the contact: 500 N < 650 N."""
    with_imp = measured(_landing(tmp_path, 0.06, 500.0), "peak_landing_force:right_foot")
    without = measured(_landing(tmp_path, 0.06, 650.0), "peak_landing_force:right_foot")
    assert with_imp == pytest.approx(500.0) and with_imp < without


def test_landing_peak_ignores_later_forces(tmp_path: Path) -> None:
    """A larger force 0.4 s after the contact is not the landing peak (no false lower/higher)."""
    d = _landing(tmp_path, 0.06, 500.0, late_peak=2000.0)
    assert measured(d, "peak_landing_force:right_foot") == pytest.approx(500.0)
    assert not measured(d, "peak_landing_force:right_foot") > 650.0


def test_no_obstacle_contact_not_measurable(poser: Poser, tmp_path: Path) -> None:
    """Without a contact on the block the landing metrics are not measurable."""
    d = write_log(tmp_path / "n.mcap", [Tick(k * DT) for k in range(10)], _spec(0.1))
    for name in ("swing_z_settling_time:right_foot", "peak_landing_force:right_foot"):
        assert "no obstacle pushed right_foot" in unmeasurable_reason(d, name)


def _rehits(tmp_path: Path, bounces: int) -> LogData:
    """The right foot meets the block at 0.5 s and leaves it ``bounces`` times (20 ms apart)."""
    ticks = []
    for k in range(int(round(1.0 / DT))):
        t = round(k * DT, 6)
        pairs = standing_pairs(ROBOT, ["left_foot"])
        since = t - T_CONTACT
        off = any(0.01 + 0.02 * b <= since < 0.02 + 0.02 * b for b in range(bounces))
        if since >= 0 and not off:
            pairs["right_foot/obstacle_block"] = [0.0, 0.0, 200.0, 0.0, 0.0, 0.0]
        ticks.append(Tick(t, pairs=pairs))
    return write_log(tmp_path / f"b{bounces}.mcap", ticks, _spec(1.0))


def test_a_foot_that_keeps_hitting_the_block_counts_its_rehits(tmp_path: Path) -> None:
    """Each loss and return of the block's push within 0.3 s is one re-hit (Fig. 5c); a foot that stays has none."""
    assert measured(_rehits(tmp_path, 0), "obstacle_rehits:right_foot") == 0
    assert measured(_rehits(tmp_path, 5), "obstacle_rehits:right_foot") == 5


def test_swing_height_error_is_the_largest_gap_while_swinging(tmp_path: Path) -> None:
    """Only ticks where the foot swings count: a 9 mm lag in swing, not the 5 cm in support."""
    ticks = []
    for k in range(100):
        t = k * DT
        swing = 1.0 if 20 <= k < 80 else -1.0
        z_d = 0.05 if swing == 1.0 else 0.0
        z = z_d - (0.009 if k == 50 else 0.002) if swing == 1.0 else 0.05
        signals = {
            "swing_foot": swing,
            "right_z": z,
            "right_z_d": z_d,
            "left_z": 0.0,
            "left_z_d": 0.0,
        }
        ticks.append(Tick(t, signals=signals))
    d = write_log(tmp_path / "s.mcap", ticks, _spec(0.1))
    assert measured(d, "swing_height_error:right_foot") == pytest.approx(0.009)
    assert "left_foot never swung" in unmeasurable_reason(d, "swing_height_error:left_foot")


def _course_spec(duration: float):  # noqa: ANN202
    second = {**BLOCK, "name": "obstacle_second", "position": [0.45, -0.1, TOP / 2]}
    return make_spec(
        ROBOT,
        duration,
        controller={"type": "qpimpedance", "params": {}},
        world={"obstacles": [BLOCK, second]},
    )


def test_obstacles_crossed_counts_obstacles_stepped_onto_and_off(
    poser: Poser, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """On the block and off to the floor crosses it; sliding off, stepping on to another obstacle or falling does not."""
    import test_paper_metrics_jo_oh as this

    monkeypatch.setattr(this, "_spec", _course_spec)
    assert measured(_right_foot(poser, tmp_path, ON_AND_OFF, 2.0), "obstacles_crossed") == 1
    assert measured(_right_foot(poser, tmp_path, SLIDE_OFF, 2.0), "obstacles_crossed") == 0
    onto_second = [ON_AND_OFF[0], (*ON_AND_OFF[1][:3], TOP, 0.05, "obstacle_second")]
    assert measured(_right_foot(poser, tmp_path, onto_second, 2.0), "obstacles_crossed") == 0
    fell = _right_foot(poser, tmp_path, ON_AND_OFF[:1], 0.9, outcome="fell")
    assert measured(fell, "obstacles_crossed") == 0
