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

from walkrepro.evaluation.metrics import LogData, MetricArgError, check_metric_arg

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


# ---- the 4 cm task's comparisons: interference, tracking error, energy (Figs. 4, 5a) --------


#: swing_foot of the synthetic step: the right foot swings 0.2-0.8 s, double support to
#: 0.9 s, then the left foot swings.
def _swing_foot(t: float) -> float:
    if 0.2 <= t < 0.8:
        return 1.0
    return 0.0 if t >= 0.9 else -1.0


def _support_log(tmp_path: Path, peak: float, late_peak: float = 0.0) -> LogData:
    """The right foot meets the block at 0.5 s; the left foot carries 300 N, ``peak`` [N]
    50 ms after the contact, and ``late_peak`` at 0.9 s (outside the 0.3 s landing window)."""
    ticks = []
    for k in range(int(round(1.5 / DT))):
        t = round(k * DT, 6)
        pairs = standing_pairs(ROBOT, ["left_foot"] if t >= T_CONTACT else FEET)
        if t >= T_CONTACT:
            pairs["right_foot/obstacle_block"] = [0.0, 0.0, 300.0, 0.0, 0.0, 0.0]
            left = peak if abs(t - T_CONTACT - 0.05) < 1e-9 else 300.0
            left = late_peak if late_peak and abs(t - 0.9) < 1e-9 else left
            pairs["left_foot/floor"] = [0.0, 0.0, left, 0.0, 0.0, 0.0]
        ticks.append(Tick(t, pairs=pairs))
    return write_log(tmp_path / "sp.mcap", ticks, _spec(1.5))


def test_support_foot_force_is_lower_with_impedance(tmp_path: Path) -> None:
    """The left foot's peak during the right foot's landing: 520 N with < 600 N without (Fig. 4)."""
    with_imp = measured(_support_log(tmp_path, 520.0), "support_peak_force:left_foot")
    without = measured(_support_log(tmp_path, 600.0), "support_peak_force:left_foot")
    assert with_imp == pytest.approx(520.0) and without == pytest.approx(600.0)
    assert with_imp < without


def test_support_foot_force_no_lower_is_no_reduction(tmp_path: Path) -> None:
    """A larger left-foot peak with impedance fails the claim; a later peak is not in it."""
    with_imp = measured(_support_log(tmp_path, 650.0, late_peak=2000.0), "support_peak_force")
    without = measured(_support_log(tmp_path, 600.0), "support_peak_force:left_foot")
    assert with_imp == pytest.approx(650.0)
    assert not with_imp < without


def _tracking_log(tmp_path: Path, gap: float, gap_outside: float = 0.0) -> LogData:
    """The right foot swings 0.2-0.8 s and meets the block at 0.5 s; after the contact its
    height stays ``gap`` [m] above the tracked reference; ``gap_outside`` before the contact
    and in the support after the swing."""
    ticks = []
    for k in range(int(round(1.5 / DT))):
        t = round(k * DT, 6)
        swing = _swing_foot(t)
        pairs = standing_pairs(ROBOT, ["left_foot"] if 0.2 <= t < 0.8 else FEET)
        if t >= T_CONTACT:
            pairs["right_foot/obstacle_block"] = [0.0, 0.0, 300.0, 0.0, 0.0, 0.0]
        z_m = 0.02
        inside = T_CONTACT <= t and swing == 1.0
        signals = {
            "swing_foot": swing,
            "right_z": z_m + (gap if inside else gap_outside),
            "right_z_m": z_m,
            "left_z": 0.0,
            "left_z_m": 0.0,
        }
        ticks.append(Tick(t, pairs=pairs, signals=signals))
    return write_log(tmp_path / "tr.mcap", ticks, _spec(1.5))


def test_tracking_error_after_contact_is_smaller_with_impedance(tmp_path: Path) -> None:
    """A foot 5 mm off its reference after contact tracks better than one 40 mm off (Fig. 5a);
    the gap before the contact and in support does not count."""
    name = "swing_z_error_after_contact:right_foot"
    with_imp = measured(_tracking_log(tmp_path, 0.005, gap_outside=0.1), name)
    without = measured(_tracking_log(tmp_path, 0.04), name)
    assert with_imp == pytest.approx(0.005) and without == pytest.approx(0.04)
    assert with_imp < without


def test_equal_tracking_error_is_no_improvement(tmp_path: Path) -> None:
    """Two feet equally far from their references show no smaller error."""
    name = "swing_z_error_after_contact:right_foot"
    assert not measured(_tracking_log(tmp_path, 0.04), name) < measured(
        _tracking_log(tmp_path, 0.04), name
    )


def _work_log(tmp_path: Path, torque: float, speed: float, t_end: float = 1.5) -> LogData:
    """The right foot swings 0.2-0.8 s onto the block (contact at 0.5 s), the left swings from
    0.9 s; the first actuator commands ``torque`` [Nm] while its joint turns at ``speed``
    [rad/s] from 0.3 s to 0.6 s; 100 Nm at 1 rad/s outside the step (0.1 s and from 1.0 s)."""
    scene_model = _robot(ROBOT).mj_model
    dof = int(scene_model.jnt_dofadr[scene_model.actuator_trnid[0, 0]])
    nv, nu = scene_model.nv, scene_model.nu
    ticks = []
    for k in range(int(round(t_end / DT))):
        t = round(k * DT, 6)
        qvel, ctrl = np.zeros(nv), np.zeros(nu)
        if 0.3 <= t < 0.6:
            qvel[dof], ctrl[0] = speed, torque
        elif t < 0.15 or t >= 1.0:
            qvel[dof], ctrl[0] = 1.0, 100.0
        pairs = standing_pairs(ROBOT, ["left_foot"] if 0.2 <= t < 0.8 else FEET)
        if t >= T_CONTACT:
            pairs["right_foot/obstacle_block"] = [0.0, 0.0, 300.0, 0.0, 0.0, 0.0]
        signals = {"swing_foot": _swing_foot(t)}
        ticks.append(Tick(t, qvel=qvel, pairs=pairs, signals=signals, ctrl=ctrl))
    return write_log(tmp_path / "w.mcap", ticks, _spec(t_end))


def test_positive_work_of_the_obstacle_step(tmp_path: Path) -> None:
    """20 Nm at 0.5 rad/s for 0.3 s is 3 J; outside the step (0.2-0.9 s) nothing counts, and
    less work with impedance (1.5 J) is lower energy."""
    name = "positive_work_obstacle_step:right_foot"
    without = measured(_work_log(tmp_path, 20.0, 0.5), name)
    with_imp = measured(_work_log(tmp_path, 10.0, 0.5), name)
    assert without == pytest.approx(3.0, rel=1e-6) and with_imp == pytest.approx(1.5, rel=1e-6)
    assert with_imp < without


def test_negative_power_is_not_work_done(tmp_path: Path) -> None:
    """A motor braking its joint (τ q̇ < 0) does no positive work: 0 J, so no claim of lower
    energy can rest on it; a step that never ends is not measurable."""
    name = "positive_work_obstacle_step:right_foot"
    assert measured(_work_log(tmp_path, -20.0, 0.5), name) == 0.0
    assert not measured(_work_log(tmp_path, 20.0, 0.5), name) < 3.0
    reason = unmeasurable_reason(_work_log(tmp_path, 20.0, 0.5, t_end=0.85), name)
    assert "the next swing after right_foot's obstacle step did not start" in reason


# ---- the sole's tilt on the tilted step (Figs. 6, 7) ---------------------------------------

#: The paper's swing time left after its contact (Fig. 4: 5.33 s to 5.592 s) [s], the rows'
#: bound for "regulated fast".
FAST = 0.262


def _tilt_log(
    tmp_path: Path, until: float, rate: float = 0.0, wobble: float = 0.0, axis: int = 0
) -> LogData:
    """The right foot meets the block at 0.5 s; the robot turns as one body about the world
    ``axis`` (0 x, 1 y): its angular velocity alternates ±``rate`` [rad/s] and its tilt is 20°
    ± ``wobble`` [rad] for ``until`` [s] after the contact, then 0 rad/s and 20° flat."""
    home = _robot(ROBOT).home_qpos
    ticks = []
    for k in range(int(round(1.5 / DT))):
        t = round(k * DT, 6)
        qpos, qvel = home.copy(), np.zeros(home.size - 1)
        pairs = standing_pairs(ROBOT, ["left_foot"] if t >= T_CONTACT else FEET)
        if t >= T_CONTACT:
            pairs["right_foot/obstacle_block"] = [0.0, 0.0, 300.0, 0.0, 0.0, 0.0]
            shaking = t < T_CONTACT + until
            sign = -1.0 if k % 2 else 1.0
            angle = math.radians(20.0) + (sign * wobble if shaking else 0.0)
            qpos[3:7] = [math.cos(angle / 2), 0.0, 0.0, 0.0]
            qpos[4 + axis] = math.sin(angle / 2)
            if shaking:
                qvel[3 + axis] = sign * rate  # the free joint's angular velocity, body frame
        ticks.append(Tick(t, qpos=qpos, qvel=qvel, pairs=pairs))
    return write_log(tmp_path / "tilt.mcap", ticks, _spec(1.5))


def test_a_roll_rate_damped_fast_settles_within_the_bound(tmp_path: Path) -> None:
    """A sole rolling at ±1 rad/s for 0.1 s after the contact settles in 0.1 s (< 0.262 s,
    Fig. 6(b)); one rolling for 0.4 s does not."""
    name = "sole_rate_settling_time:right_foot@x"
    fast = measured(_tilt_log(tmp_path, 0.1, rate=1.0), name)
    slow = measured(_tilt_log(tmp_path, 0.4, rate=1.0), name)
    assert fast == pytest.approx(0.1 - DT, abs=DT) and fast < FAST
    assert slow == pytest.approx(0.4 - DT, abs=DT) and not slow < FAST


def test_the_rate_bound_is_the_sole_edge_speed_across_the_axis(tmp_path: Path) -> None:
    """0.5 rad/s moves the sole's edge at 0.033 m/s for a roll (half-width 0.065 m, settled)
    and at 0.06 m/s for a pitch (half-length 0.12 m, still moving): the bound is 0.05 m/s at
    the edge."""
    roll = measured(_tilt_log(tmp_path, 0.4, rate=0.5), "sole_rate_settling_time:right_foot@x")
    pitch = _tilt_log(tmp_path, 0.4, rate=0.5, axis=1)
    assert roll == 0.0
    assert measured(pitch, "sole_rate_settling_time:right_foot@y") == pytest.approx(
        0.4 - DT, abs=DT
    )


def test_a_tilt_that_stops_wobbling_settles(tmp_path: Path) -> None:
    """A sole wobbling ±3° about its 20° for 0.1 s settles its tilt in 0.1 s (Fig. 6(a)); one
    wobbling 0.4 s does not settle fast; a ±0.5° wobble is within the 1° band (0 s)."""
    name = "sole_tilt_settling_time:right_foot@x"
    fast = measured(_tilt_log(tmp_path, 0.1, wobble=math.radians(3.0)), name)
    slow = measured(_tilt_log(tmp_path, 0.4, wobble=math.radians(3.0)), name)
    small = measured(_tilt_log(tmp_path, 0.4, wobble=math.radians(0.5)), name)
    assert fast == pytest.approx(0.1 - DT, abs=DT) and fast < FAST
    assert slow == pytest.approx(0.4 - DT, abs=DT) and not slow < FAST
    assert small == 0.0


def test_tilt_settling_needs_the_whole_window(tmp_path: Path) -> None:
    """A run that ends before 0.6 s after the contact does not answer the claim; a wrong axis
    is a clean argument error."""
    ticks = [Tick(round(k * DT, 6)) for k in range(int(round(0.8 / DT)))]
    for tick in ticks:
        if tick.t >= T_CONTACT:
            tick.pairs = {"right_foot/obstacle_block": [0.0, 0.0, 300.0, 0.0, 0.0, 0.0]}
    d = write_log(tmp_path / "short.mcap", ticks, _spec(0.8))
    assert "before the settling window" in unmeasurable_reason(
        d, "sole_tilt_settling_time:right_foot@y"
    )
    with pytest.raises(MetricArgError, match="none of x, y"):
        check_metric_arg("sole_rate_settling_time:right_foot@z")
