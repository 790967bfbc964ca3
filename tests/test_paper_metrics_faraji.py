"""Paper II (Faraji et al.) metrics on small synthetic logs: one where the claim holds, one
where it does not."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from test_metrics import (
    DT,
    Poser,
    Tick,
    home_sole,
    make_spec,
    measured,
    unmeasurable_reason,
    write_log,
)

from walkrepro.evaluation.metrics import LogData, NotMeasurable
from walkrepro.papers.faraji.controller import TimeProjectionParams
from walkrepro.papers.faraji.metrics import (
    CORRECTIVE_SIGMAS,
    _neck_offset,
    corrective_band,
    corrective_steps,
    count_corrective,
    footstep_scatter,
    paper_ankle_stiffness,
    tracking_lag,
    unsettled_steps,
)
from walkrepro.sim.robot import load_robot

ROBOT = "coman"
STEP = 0.4  # [s] (Paper II's T)
PUSH_AT = 4.0  # [s]


def _spec(duration: float, **fields):  # noqa: ANN202
    return make_spec(ROBOT, duration, controller={"type": "timeprojection", "params": {}}, **fields)


# ---- pelvis speed under the drag (Fig. 18) -------------------------------------------------


def _pelvis(  # noqa: ANN001
    tmp_path: Path, speed, duration: float = 4.0, outcome: str = "complete", params=None
) -> LogData:
    """The pelvis moves at ``speed(t)`` [m/s] (the legs at home move with it); ``params``:
    the spec's controller parameters."""
    q0 = Poser(ROBOT).home
    ticks, x = [], 0.0
    for k in range(int(round(duration / DT)) + 1):
        qpos = q0.copy()
        qpos[0] += x
        ticks.append(Tick(k * DT, qpos=qpos))
        x += speed(k * DT) * DT
    if outcome == "fell":
        ticks[-1].events = [{"kind": "fall", "reason": "pelvis low"}]
    spec = make_spec(ROBOT, duration, controller={"type": "timeprojection", "params": params or {}})
    return write_log(tmp_path / "p.mcap", ticks, spec, outcome)


def test_drag_makes_the_robot_walk(tmp_path: Path) -> None:
    """A pelvis pulled to 0.2 m/s forward, then 0.2 m/s backward, peaks in the 0.08–0.3 band."""
    d = _pelvis(tmp_path, lambda t: 0.2 if t < 2.0 else -0.2)
    assert measured(d, "peak_forward_pelvis_speed:0.5-1.5") == pytest.approx(0.2, abs=1e-6)
    assert measured(d, "peak_backward_pelvis_speed:2.5-3.5") == pytest.approx(0.2, abs=1e-6)
    assert measured(d, "peak_pelvis_speed") == pytest.approx(0.2, abs=1e-6)
    assert measured(d, "mean_abs_pelvis_speed:0.5-3.5") == pytest.approx(0.2, abs=0.03)


def test_robot_that_stands_under_the_drag(tmp_path: Path) -> None:
    """A pelvis that does not move has no emergent walking (0 m/s, below the band)."""
    d = _pelvis(tmp_path, lambda t: 0.0)
    assert measured(d, "peak_forward_pelvis_speed:0.5-1.5") == 0
    assert measured(d, "peak_backward_pelvis_speed:2.5-3.5") == 0


def test_stepping_lowers_the_mean_speed(tmp_path: Path) -> None:
    """A pelvis at 0.1 m/s has a lower mean |speed| than one at 0.14 m/s (Fig. 18's comparison)."""
    slow = measured(_pelvis(tmp_path, lambda t: 0.1), "mean_abs_pelvis_speed:0.5-3.5")
    fast = measured(_pelvis(tmp_path, lambda t: 0.14), "mean_abs_pelvis_speed:0.5-3.5")
    assert slow < fast


def test_speed_window_after_a_fall_not_measurable(tmp_path: Path) -> None:
    """Speeds of a window the robot fell in are not measurable (a fall is not a walk)."""
    d = _pelvis(tmp_path, lambda t: 0.2, duration=2.0, outcome="fell")
    assert unmeasurable_reason(d, "peak_forward_pelvis_speed:0.5-3.0").startswith(
        "the robot fell at t = 2.000 s"
    )


# ---- walking speed against the command (Fig. 19) -------------------------------------------


def _walk(tmp_path: Path, speed: float, command: float | None) -> LogData:
    """The pelvis moves at ``speed`` [m/s] for 4 s under a spec commanding ``command``."""
    params = None if command is None else {"speed": command}
    return _pelvis(tmp_path, lambda t: speed, params=params)


def test_speed_within_a_quarter_of_the_command(tmp_path: Path) -> None:
    """0.11 m/s under a 0.1 m/s command is 1.1× the command, inside Fig. 19's ±25 %."""
    ratio = measured(_walk(tmp_path, 0.11, 0.1), "speed_to_command:0.5-3.5")
    assert ratio == pytest.approx(1.1, abs=1e-6)
    assert 0.75 <= ratio <= 1.25


def test_speed_far_below_the_command(tmp_path: Path) -> None:
    """A walk at half the commanded speed is outside the ±25 % band."""
    ratio = measured(_walk(tmp_path, 0.1, 0.2), "speed_to_command:0.5-3.5")
    assert ratio == pytest.approx(0.5, abs=1e-6)
    assert not 0.75 <= ratio <= 1.25


def test_speed_ratio_follows_the_spec_command(tmp_path: Path) -> None:
    """The same 0.2 m/s walk is on target for a 0.2 m/s command, 2× a 0.1 m/s one."""
    assert measured(_walk(tmp_path, 0.2, 0.2), "speed_to_command:0.5-3.5") == pytest.approx(1.0)
    assert measured(_walk(tmp_path, 0.2, 0.1), "speed_to_command:0.5-3.5") == pytest.approx(2.0)


def test_speed_ratio_needs_a_commanded_speed(tmp_path: Path) -> None:
    """In-place walking (no speed commanded) has no realised-to-commanded ratio."""
    reason = unmeasurable_reason(_walk(tmp_path, 0.0, None), "speed_to_command:0.5-3.5")
    assert "commands no walking speed" in reason


def test_speed_ratio_of_a_backward_command_is_signed(tmp_path: Path) -> None:
    """Backward at 0.09 m/s under a −0.1 m/s command is 0.9× it; drifting forward at
    0.05 m/s under the same command is −0.5×, outside any band around 1."""
    assert measured(_walk(tmp_path, -0.09, -0.1), "speed_to_command:0.5-3.5") == pytest.approx(
        0.9, abs=1e-6
    )
    assert measured(_walk(tmp_path, 0.05, -0.1), "speed_to_command:0.5-3.5") == pytest.approx(
        -0.5, abs=1e-6
    )


# ---- corrective steps after a push (Fig. 16) -----------------------------------------------


def _footsteps(tmp_path: Path, peaks: list[float], outcome: str = "complete") -> LogData:
    """Phase changes every 0.4 s from 0.5 s; in step k the commanded footstep adjustment
    rises to ``peaks[k]`` [m]; a push at 4.0 s. No state moves: only the command is logged."""
    n = len(peaks)
    duration = 0.5 + STEP * n
    ticks = []
    per_step, start = int(round(STEP / DT)), int(round(0.5 / DT))
    for k in range(int(round(duration / DT))):
        t = round(k * DT, 6)
        i, j = divmod(k - start, per_step)
        adj = peaks[i] * math.sin(math.pi * j / per_step) if k >= start else 0.0
        events = [{"kind": "phase", "step": i}] if k >= start and j == 0 else []
        ticks.append(Tick(t, signals={"footstep": adj, "footstep_raw": 1.5 * adj}, events=events))
    return write_log(tmp_path / "f.mcap", ticks, _spec(duration, disturbances=[PUSH]), outcome)


PUSH = {
    "name": "push",
    "body": "torso",
    "frame": "world",
    "force": [60, 0, 0],
    "start": PUSH_AT,
    "duration": 0.1,
}


def _landing_log(
    tmp_path: Path,
    offsets: list[float],
    commanded: list[float] | None = None,
    nominal: float = 0.0,
    outcome: str = "complete",
) -> LogData:
    """Phase changes every 0.4 s from 0.5 s, the left foot swinging first, a push at 4.0 s
    (in step 8); at the end of step k the foot that swung sits ``offsets[k]`` [m] ahead of
    the 3LP nominal ``nominal`` [m] (f − p, relative to the pelvis), while the controller's
    ``footstep`` signal says ``commanded[k]`` (default: the offsets). The pelvis stays at
    home's x; between phase changes the robot stands. Before 0.5 s the gait's signals are
    NaN."""
    commanded = offsets if commanded is None else commanded
    poser = Poser(ROBOT)
    data = mujoco.MjData(poser.model)
    data.qpos[:] = poser.home
    mujoco.mj_kinematics(poser.model, data)
    pelvis_x = float(data.xpos[poser.model.body("pelvis").id, 0])
    per_step, start = int(round(STEP / DT)), int(round(0.5 / DT))
    ticks = []
    for k in range(start + per_step * len(offsets) + 1):
        t = round(k * DT, 6)
        i, j = divmod(k - start, per_step)
        nan = math.nan
        signals = {"phase": -1.0, "swing_side": nan, "e_nominal": [nan] * 4, "footstep": nan}
        events, qpos = [], None
        if k >= start:
            ending = i - 1 if j == 0 else i  # the step this tick belongs to (its last tick)
            signals = {
                "phase": j * DT,
                "swing_side": 1.0 if i % 2 == 0 else -1.0,
                "e_nominal": [-nominal, 0.0, 0.0, 0.0],
                "footstep": commanded[min(i, len(offsets) - 1)],
            }
            if j == 0:
                events = [{"kind": "phase", "step": i}]
            if j == 0 and ending >= 0:
                foot = "left_foot" if ending % 2 == 0 else "right_foot"
                _, y, z = home_sole(ROBOT, foot)
                # The pelvis 6 cm lower than home, so that a long step stays in reach.
                x = pelvis_x + nominal + offsets[ending]
                qpos = poser((0.0, 0.0, -0.06), **{foot: (x, y, z)})
        ticks.append(Tick(t, qpos=qpos, signals=signals, events=events))
    spec = _spec(0.5 + STEP * len(offsets) + DT, disturbances=[PUSH])
    path = tmp_path / f"landing{len(list(tmp_path.glob('landing*.mcap')))}.mcap"  # a new file
    return write_log(path, ticks, spec, outcome)


UNDISTURBED = [0.0, 0.01, 0.02, 0.015, 0.025, 0.01, 0.02, 0.015, 0.02]  # steps from 0.5 s
#: The steps the band is estimated from: they end before the push (by 3.7 s), without the
#: first (it starts from standing).
BAND_STEPS = slice(1, 8)


def test_push_recovered_in_two_corrective_steps(tmp_path: Path) -> None:
    """Two steps land 10 and 9 cm ahead after the push, then calm steps: 2 corrective."""
    d = _landing_log(tmp_path, UNDISTURBED + [0.10, 0.09, 0.02, 0.015, 0.02])
    assert measured(d, "recovery_steps:4.0") == 2
    assert measured(d, "recovery_steps") == 2  # the push time from the spec


def test_undisturbed_run_has_no_corrective_step(tmp_path: Path) -> None:
    """Steps no larger than the undisturbed ones are not corrective: 0 (outside 1–5)."""
    d = _landing_log(tmp_path, UNDISTURBED + [0.02, 0.025, 0.02, 0.015])
    assert measured(d, "recovery_steps") == 0


def test_corrective_band_follows_the_undisturbed_spread(tmp_path: Path) -> None:
    """The band is the undisturbed steps' μ ± 3σ: wide undisturbed steps make a 6 cm
    landing ordinary, narrow ones make it corrective."""
    narrow = _landing_log(tmp_path, UNDISTURBED + [0.06, 0.02, 0.02, 0.02])
    assert measured(narrow, "recovery_steps") == 1
    wide = [0.0, 0.01, 0.05, 0.02, 0.06, 0.01, 0.05, 0.02, 0.06]
    assert measured(_landing_log(tmp_path, wide + [0.06, 0.02, 0.02, 0.02]), "recovery_steps") == 0
    peaks = np.array(UNDISTURBED[BAND_STEPS])
    half = CORRECTIVE_SIGMAS * peaks.std(ddof=1)
    low, high = peaks.mean() - half, peaks.mean() + half
    assert measured(narrow, "corrective_band_low") == pytest.approx(low, abs=1e-5)
    assert measured(narrow, "corrective_band_high") == pytest.approx(high, abs=1e-5)


def test_step_against_a_biased_gait_is_corrective(tmp_path: Path) -> None:
    """Undisturbed steps all landing forward (1–2.5 cm): a step landing 2.5 cm behind lies
    outside μ ± 3σ of their signed values (−0.03 to 3.3 cm) and counts, though its
    magnitude is below a |value| rule's threshold (mean + 3σ of the magnitudes, 3.3 cm)."""
    d = _landing_log(tmp_path, UNDISTURBED + [-0.025, 0.02, 0.015, 0.02])
    assert measured(d, "recovery_steps") == 1
    peaks = np.abs(UNDISTURBED[BAND_STEPS])
    assert 0.025 < peaks.mean() + CORRECTIVE_SIGMAS * peaks.std(ddof=1)  # the |value| rule's miss


def test_steps_inside_the_band_are_not_corrective(tmp_path: Path) -> None:
    """Undisturbed steps spread both ways around a forward bias (μ 1.1 cm, σ 1.6 cm): +5 cm
    and −3 cm stay inside μ ± 3σ (−3.7 to 5.9 cm) and do not count."""
    mixed = [0.0, 0.02, -0.01, 0.03, 0.0, 0.025, -0.005, 0.02, 0.01]
    d = _landing_log(tmp_path, mixed + [0.05, -0.03, 0.02, 0.01])
    assert measured(d, "recovery_steps") == 0
    assert measured(d, "corrective_band_low") < -0.03
    assert measured(d, "corrective_band_high") > 0.05


def test_corrective_steps_are_where_the_feet_land_not_the_command(tmp_path: Path) -> None:
    """A command that peaks at 15 cm while the foot lands on the undisturbed band is not a
    corrective step; a foot landing 10 cm ahead is one, whatever the command said."""
    calm = UNDISTURBED + [0.02, 0.02, 0.015, 0.02]
    transient = _landing_log(tmp_path, calm, commanded=UNDISTURBED + [0.15, -0.15, 0.015, 0.02])
    assert measured(transient, "max_footstep_adjustment") == pytest.approx(0.15)
    assert measured(transient, "recovery_steps") == 0
    landed = _landing_log(tmp_path, UNDISTURBED + [0.10, 0.02, 0.015, 0.02], commanded=calm)
    assert measured(landed, "recovery_steps") == 1


def test_gait_back_in_its_band_after_the_recovery(tmp_path: Path) -> None:
    """Two corrective steps, then every step inside the band: nothing unsettled."""
    d = _landing_log(tmp_path, UNDISTURBED + [0.10, 0.09, 0.02, 0.015, 0.02, 0.01])
    assert measured(d, "unsettled_steps") == 0


def test_sway_after_the_recovery_is_unsettled(tmp_path: Path) -> None:
    """One step back inside ends the count at 1, but the gait keeps landing outside the band
    (+6 and −4 cm) afterwards: 2 unsettled steps."""
    d = _landing_log(tmp_path, UNDISTURBED + [0.10, 0.02, 0.06, 0.02, -0.04, 0.02, 0.01])
    assert measured(d, "recovery_steps") == 1
    assert measured(d, "unsettled_steps") == 2


def test_unsettled_steps_without_corrective_steps() -> None:
    """A push that moves no step out of the band leaves nothing unsettled; a later step
    outside is a (late) corrective step, not an unsettled one."""
    phases = 0.5 + STEP * np.arange(14)
    calm = np.r_[UNDISTURBED, 0.02, 0.015, 0.02, 0.02, 0.01]
    band = corrective_band(calm, phases, PUSH_AT)
    assert corrective_steps(calm, phases, PUSH_AT, band) == []
    assert unsettled_steps(calm, phases, PUSH_AT, band) == 0
    late = np.r_[UNDISTURBED, 0.02, 0.015, 0.08, 0.02, 0.01]
    assert corrective_steps(late, phases, PUSH_AT, band) == [11]
    assert unsettled_steps(late, phases, PUSH_AT, band) == 0


def test_recovery_not_measurable_after_a_fall(tmp_path: Path) -> None:
    """A pushed robot that falls has not recovered: not measurable, with the fall time."""
    d = _landing_log(tmp_path, UNDISTURBED + [0.1, 0.1], outcome="fell")
    assert "before the push was recovered" in unmeasurable_reason(d, "recovery_steps")


def test_recovery_needs_enough_undisturbed_steps() -> None:
    """With fewer than six undisturbed steps before the push there is no threshold."""
    phases = 0.5 + STEP * np.arange(6)
    with pytest.raises(Exception, match="undisturbed step"):
        corrective_band(np.full(6, 0.01), phases, 2.0)


def test_recovery_still_going_at_the_end_is_not_measurable() -> None:
    """Corrective steps up to the end of the log: the recovery is not over."""
    phases = 0.5 + STEP * np.arange(12)
    peaks = np.r_[np.full(9, 0.01), 0.1, 0.1, 0.1]
    with pytest.raises(Exception, match="settled"):
        count_corrective(peaks, phases, PUSH_AT, (-0.05, 0.05))


def test_adjustment_within_truncation(tmp_path: Path) -> None:
    """Adjustments of at most 10 cm stay within the 15 cm truncation; raw ones are 1.5× larger."""
    d = _footsteps(tmp_path, UNDISTURBED + [0.10])
    assert measured(d, "max_footstep_adjustment") == pytest.approx(0.10, abs=1e-3)
    assert measured(d, "max_footstep_adjustment_raw") == pytest.approx(0.15, abs=1.5e-3)


def test_raw_adjustment_in_a_window_the_run_reaches(tmp_path: Path) -> None:
    """A 20 cm push step inside a window the run completes reads 30 cm raw, beyond 15 cm."""
    d = _footsteps(tmp_path, UNDISTURBED + [0.20, 0.01, 0.01])
    assert measured(d, "max_footstep_adjustment_raw:4-5") == pytest.approx(0.30, abs=3e-3)


def test_raw_adjustment_before_the_push_stays_small(tmp_path: Path) -> None:
    """Undisturbed steps before the push keep the raw adjustment under the 15 cm truncation."""
    d = _footsteps(tmp_path, UNDISTURBED + [0.20, 0.01, 0.01])
    assert measured(d, "max_footstep_adjustment_raw:0.5-3.9") < 0.15


def test_raw_adjustment_of_a_fall_is_not_measurable(tmp_path: Path) -> None:
    """A run that falls before the window ends has no raw adjustment there: not measured."""
    d = _footsteps(tmp_path, UNDISTURBED + [0.20], outcome="fell")
    assert "before the end of the window" in unmeasurable_reason(
        d, "max_footstep_adjustment_raw:4-8"
    )


def test_adjustment_beyond_truncation(tmp_path: Path) -> None:
    """A 20 cm adjustment fails the 15 cm truncation claim."""
    assert measured(_footsteps(tmp_path, UNDISTURBED + [0.20]), "max_footstep_adjustment") > 0.15


# ---- realised footstep adjustment (Fig. 13's truncation, where the foot lands) ---------------


def test_landing_adjustment_is_where_the_foot_lands(tmp_path: Path) -> None:
    """A foot placed 10 cm ahead of the nominal after a 10 cm command: 0.10, inside 15 cm."""
    d = _landing_log(tmp_path, [0.0, 0.01, 0.10, -0.02], [0.0, 0.01, 0.10, -0.02])
    assert measured(d, "max_landing_adjustment") == pytest.approx(0.10, abs=1e-4)


def test_landing_beyond_the_truncation_though_the_command_is_truncated(tmp_path: Path) -> None:
    """The command stops at the 15 cm truncation but the foot lands 18 cm ahead (servo lag,
    the pelvis's own motion): the metric reads the foot, so the truncation claim fails."""
    d = _landing_log(tmp_path, [0.0, 0.01, 0.18, 0.02], [0.0, 0.01, 0.15, 0.02])
    assert measured(d, "max_footstep_adjustment") == pytest.approx(0.15)
    assert measured(d, "max_landing_adjustment") == pytest.approx(0.18, abs=1e-4)


def test_landing_adjustment_is_measured_from_the_gait_nominal(tmp_path: Path) -> None:
    """A walking gait whose feet land on its 4 cm nominal has no realised adjustment; a foot
    5 cm behind it has −5 cm (the magnitude is reported)."""
    on_nominal = _landing_log(tmp_path, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], nominal=0.04)
    assert measured(on_nominal, "max_landing_adjustment") == pytest.approx(0.0, abs=1e-4)
    behind = _landing_log(tmp_path, [0.0, -0.05, 0.0], [0.0, 0.0, 0.0], nominal=0.04)
    assert measured(behind, "max_landing_adjustment") == pytest.approx(0.05, abs=1e-4)


def test_landing_adjustment_needs_the_gait_reference(tmp_path: Path) -> None:
    """A log without the 3LP reference (another controller) cannot place the nominal step."""
    d = _footsteps(tmp_path, UNDISTURBED)
    assert "e_nominal" in unmeasurable_reason(d, "max_landing_adjustment")


# ---- footstep scatter (Fig. 14) ------------------------------------------------------------


def _scatter_log(tmp_path: Path, jitter: float) -> LogData:
    """Phase changes every 0.4 s from 2.0 s; at each the left foot sits ``jitter`` [m]
    ahead or behind (alternately) of its home place, relative to the pelvis."""
    poser = Poser(ROBOT)
    x, y, z = home_sole(ROBOT, "left_foot")
    ticks = []
    for k in range(int(4.5 / DT)):
        t = round(k * DT, 6)
        i = int(round((t - 2.0) / STEP))
        at_phase = t >= 2.0 and abs(t - 2.0 - i * STEP) < 1e-9
        sign = 1 if i % 2 else -1
        qpos = poser(left_foot=(x + sign * jitter, y, z)) if at_phase else None
        ticks.append(Tick(t, qpos=qpos, events=[{"kind": "phase", "step": i}] if at_phase else []))
    return write_log(tmp_path / "s.mcap", ticks, _spec(4.5))


def test_scatter_grows_without_dead_zones(tmp_path: Path) -> None:
    """Feet jittering ±4 cm scatter ≥ 2× as much as feet jittering ±1 cm (Fig. 14C vs B)."""
    closed = measured(_scatter_log(tmp_path, 0.01), "footstep_scatter")
    no_deadzone = measured(_scatter_log(tmp_path, 0.04), "footstep_scatter")
    assert closed == pytest.approx(0.01 / math.sqrt(2), abs=1e-4)  # one of two feet moves
    assert no_deadzone >= 2 * closed


def test_scatter_equal_when_feet_repeat(tmp_path: Path) -> None:
    """Two runs with the same footstep jitter do not differ by 2×."""
    a = measured(_scatter_log(tmp_path, 0.02), "footstep_scatter")
    assert a < 2 * footstep_scatter(np.array([[[0.02, 0], [0, 0]], [[-0.02, 0], [0, 0]]]))


# ---- the standing pull (Fig. 20) -----------------------------------------------------------


def _pull_log(
    tmp_path: Path,
    shift: float,
    outcome: str = "complete",
    duration: float = 4.0,
    ramp_time: float = 0.0,
) -> LogData:
    """A 7 N pull at the neck from 1 to 3 s (ramped up and down over ``ramp_time`` [s] if
    given); the pelvis (and torso) sit ``shift`` [m] forward while the full force acts,
    the feet stay put."""
    poser = Poser(ROBOT)
    moved = poser((shift, 0.0, 0.0))
    lo, hi = 1.0 + ramp_time, 3.0 - ramp_time
    ticks = [
        Tick(k * DT, qpos=moved if lo < k * DT <= hi + 1e-9 else poser.home)
        for k in range(int(round(duration / DT)) + 1)
    ]
    if outcome == "fell":
        ticks[-1].events = [{"kind": "fall", "reason": "pelvis low"}]
    pull = {
        "name": "neck_pull",
        "body": "torso",
        "frame": "world",
        "force": [7, 0, 0],
        "start": 1.0,
        "duration": 2.0,
    }
    if ramp_time:
        pull.update(profile="ramp", ramp_time=ramp_time)
    return write_log(tmp_path / "a.mcap", ticks, _spec(duration, disturbances=[pull]), outcome)


def test_paper_formula_gives_the_papers_31() -> None:
    """Fig. 20's numbers: 7 N at COMAN's neck (0.84 m), pelvis (0.52 m) moved 5 cm → ≈ 31
    Nm/rad per ankle with heights from the ground; from the ankles (0.1 m up) it reads ≈ 22,
    outside the paper's rounding."""
    assert paper_ankle_stiffness(7.0, 0.8385, 0.5165, 0.05) == pytest.approx(30.3, abs=0.1)
    assert paper_ankle_stiffness(7.0, 0.7385, 0.4165, 0.05) == pytest.approx(21.5, abs=0.1)
    assert paper_ankle_stiffness(-7.0, 0.8385, 0.5165, -0.05) == pytest.approx(30.3, abs=0.1)
    with pytest.raises(NotMeasurable):
        paper_ankle_stiffness(7.0, 0.8385, 0.5165, 0.0)


def test_ankle_stiffness_in_band(tmp_path: Path) -> None:
    """A pelvis displaced 5 cm by the 7 N pull gives about 31 Nm/rad per ankle (20–45),
    F h_neck h_pelvis / (2 d) with the logged heights above the floor."""
    d = _pull_log(tmp_path, 0.05)
    assert measured(d, "pelvis_displacement") == pytest.approx(0.05, abs=1e-6)
    assert measured(d, "torso_displacement") == pytest.approx(0.05, abs=1e-3)
    model = d.model
    data = mujoco.MjData(model)
    data.qpos[:] = d.qpos[0]
    mujoco.mj_kinematics(model, data)
    neck = data.xpos[model.body("torso").id, 2] + _neck_offset(model)
    pelvis = data.xpos[model.body("pelvis").id, 2]
    expected = 7.0 * neck * pelvis / (2 * 0.05)
    assert measured(d, "ankle_stiffness") == pytest.approx(expected, rel=1e-6)
    assert 20 <= measured(d, "ankle_stiffness") <= 45


def test_ankle_stiffness_too_stiff(tmp_path: Path) -> None:
    """A pelvis displaced only 1 cm means ankles 5× stiffer, above the band."""
    stiff = measured(_pull_log(tmp_path, 0.01), "ankle_stiffness")
    assert stiff > 45
    assert stiff == pytest.approx(5 * measured(_pull_log(tmp_path, 0.05), "ankle_stiffness"))


def test_pull_read_over_the_hold_not_the_ramps(tmp_path: Path) -> None:
    """A ramped pull (0.5 s up, 0.5 s down) is read where the full force acts: a pelvis
    5 cm forward only during the hold reads 5 cm (the last half of the whole window, which
    takes in the ramp down, would read 2.5 cm)."""
    d = _pull_log(tmp_path, 0.05, ramp_time=0.5)
    assert measured(d, "pelvis_displacement") == pytest.approx(0.05, abs=1e-6)
    assert measured(d, "ankle_stiffness") == pytest.approx(
        measured(_pull_log(tmp_path, 0.05), "ankle_stiffness"), rel=1e-6
    )


def test_pull_cut_by_a_fall_not_measurable(tmp_path: Path) -> None:
    """A fall before the pull ends leaves displacement and stiffness not measurable."""
    d = _pull_log(tmp_path, 0.04, outcome="fell", duration=2.0)
    for name in ("pelvis_displacement", "torso_displacement", "ankle_stiffness"):
        assert unmeasurable_reason(d, name).startswith(
            "the robot fell at t = 2.000 s, before the pull ended"
        )


# ---- position tracking delay (Hardware Limitations: "at least 20 ms") -----------------------

TRACK_DT = 0.001  # [s] between the synthetic messages of the tracking logs


def _tracking_log(
    tmp_path: Path, lag: float, robot: str = ROBOT, follows: bool = True, sensing_delay: float = 0.0
) -> LogData:
    """The knees' servos are commanded a 1.25 Hz swing of 0.15 rad (the gait's); each knee
    reaches the command ``lag`` [s] late (``follows``: else it stays still)."""
    spec = make_spec(
        robot,
        3.0,
        sim={"duration": 3.0, "timestep": TRACK_DT, "control_period": TRACK_DT},
        sensors={"delay": sensing_delay},
    )
    model = mujoco.MjModel.from_xml_path(str(load_robot(robot).xml_path))
    knees = [a for a in range(model.nu) if model.actuator(a).name.endswith("_knee")]
    adr = [int(model.jnt_qposadr[model.actuator_trnid[a, 0]]) for a in knees]
    q0 = Poser(robot).home

    def command(t: float) -> float:
        return 0.15 * math.sin(2 * math.pi * 1.25 * t)

    ticks = []
    for k in range(int(round(3.0 / TRACK_DT)) + 1):
        t = k * TRACK_DT
        qpos, ctrl = q0.copy(), np.zeros(model.nu)
        for a, i in zip(knees, adr, strict=True):
            ctrl[a] = q0[i] + command(t)
            qpos[i] = q0[i] + (command(t - lag) if follows else 0.0)
        ticks.append(Tick(t, qpos=qpos, ctrl=ctrl))
    return write_log(tmp_path / "track.mcap", ticks, spec)


def test_knee_tracking_lag_above_20_ms(tmp_path: Path) -> None:
    """A knee that reaches its command 25 ms late shows a 25 ms tracking delay (≥ 20 ms)."""
    assert measured(_tracking_log(tmp_path, 0.025), "tracking_delay:knee") == pytest.approx(
        0.025, abs=5e-4
    )


def test_stiff_knee_tracking_lag_below_20_ms(tmp_path: Path) -> None:
    """A knee 5 ms behind its command misses the paper's ≥ 20 ms (the claim fails)."""
    d = _tracking_log(tmp_path, 0.005)
    assert measured(d, "tracking_delay:knee") == pytest.approx(0.005, abs=5e-4)
    assert measured(d, "tracking_delay:knee@1-3") == pytest.approx(0.005, abs=5e-4)


def test_sensing_delay_is_not_counted_in_the_tracking_lag(tmp_path: Path) -> None:
    """A 20 ms sensing delay the spec adds is an input, not counted: a 5 ms servo lag reads 5 ms."""
    d = _tracking_log(tmp_path, 0.005, sensing_delay=0.02)
    assert measured(d, "tracking_delay:knee") == pytest.approx(0.005, abs=5e-4)


def test_knee_that_does_not_follow_has_no_tracking_lag(tmp_path: Path) -> None:
    """A knee that stays still while commanded to swing has no lag to measure."""
    reason = unmeasurable_reason(_tracking_log(tmp_path, 0.0, follows=False), "tracking_delay:knee")
    assert "does not follow" in reason


def test_torque_controlled_robot_has_no_tracking_lag(tmp_path: Path) -> None:
    """dyros_red's joints are torque motors, not position servos: nothing to measure."""
    reason = unmeasurable_reason(
        _tracking_log(tmp_path, 0.02, robot="dyros_red"), "tracking_delay:knee"
    )
    assert "no position servo" in reason


def test_tracking_lag_refined_between_samples() -> None:
    """The parabola through the correlation peak resolves a lag between two grid samples."""
    t = np.arange(0.0, 4.0, 0.002)
    lag, corr = tracking_lag(np.sin(5 * t), np.sin(5 * (t - 0.0213)), 0.002, 0.1)
    assert lag == pytest.approx(0.0213, abs=2e-4)
    assert corr > 0.99


# ---- dead-zone thresholds against the open-loop error spread (Fig. 9) -----------------------


def _errors_log(tmp_path: Path, scale: float) -> LogData:
    """Filtered errors alternating ± ``scale`` × each default dead-zone threshold: their
    standard deviation is ``scale`` thresholds."""
    a = np.array(TimeProjectionParams().dead_zone_thresholds)
    ticks = [
        Tick(k * DT, signals={"e_raw": list((1 if k % 2 else -1) * scale * a)}) for k in range(200)
    ]
    return write_log(tmp_path / "e.mcap", ticks, _spec(2.0))


def test_dead_zone_thresholds_set_to_the_spread(tmp_path: Path) -> None:
    """Errors spreading by exactly the thresholds give a ratio of 1 (Fig. 9's procedure)."""
    d = _errors_log(tmp_path, 1.0)
    for name in ("e1x", "e2x", "de1x", "de2x"):
        assert measured(d, f"dead_zone_spread:{name}") == pytest.approx(1.0)
    assert measured(d, "dead_zone_spread:e1x@0.5-1.5") == pytest.approx(1.0, rel=1e-3)


def test_dead_zone_thresholds_stale_against_the_spread(tmp_path: Path) -> None:
    """Errors spreading 1.25× the thresholds show thresholds that no longer follow Fig. 9."""
    assert measured(_errors_log(tmp_path, 1.25), "dead_zone_spread:e1x") == pytest.approx(1.25)


# ---- the corrective steps drawn (Figs. 16-17) -----------------------------------------------


def test_corrective_steps_are_the_counted_steps() -> None:
    """The steps named corrective are the ones the count counts, from the pushed step on."""
    phases = 0.5 + STEP * np.arange(14)
    peaks = np.r_[UNDISTURBED, 0.1, -0.06, 0.02, 0.08, 0.015]
    band = corrective_band(peaks, phases, PUSH_AT)
    assert corrective_steps(peaks, phases, PUSH_AT, band) == [9, 10]
    assert count_corrective(peaks, phases, PUSH_AT, band) == 2  # the later 8 cm is another story


def test_push_figure_marks_the_corrective_steps(tmp_path: Path) -> None:
    """Fig. 16 draws the band and marks the counted steps, with their count in the legend."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    from walkrepro.papers.faraji import figures as figs

    d = _landing_log(tmp_path, UNDISTURBED + [0.1, -0.06, 0.02, 0.015])
    _, ax = plt.subplots()
    figs._mark_corrective(ax, d)
    labels = [line.get_label() for line in ax.get_lines()]
    assert "corrective steps (2)" in labels
    red = ax.get_lines()[labels.index("corrective steps (2)")]
    assert list(red.get_ydata()) == pytest.approx([0.1, -0.06], abs=1e-4)
    assert list(red.get_xdata()) == pytest.approx([0.5 + 10 * STEP, 0.5 + 11 * STEP])
    (tmp_path / "fell").mkdir()
    fell = _landing_log(tmp_path / "fell", UNDISTURBED + [0.1, -0.06], outcome="fell")
    _, ax2 = plt.subplots()
    figs._mark_corrective(ax2, fell)
    assert any("not counted (fell)" in line.get_label() for line in ax2.get_lines())
    plt.close("all")


def test_the_neck_is_the_torso_top_or_the_shoulder_axes() -> None:
    """Fig. 20's neck: the top of coman's torso box, the shoulder axes on coman_lab (capsules)."""
    from walkrepro.papers.faraji.metrics import _neck_offset
    from walkrepro.sim.robot import load_robot

    assert _neck_offset(load_robot("coman").mj_model) == pytest.approx(0.2)
    lab = load_robot("coman_lab").mj_model
    shoulder = lab.body("l_shoulder_pitch_link").id
    assert _neck_offset(lab) == pytest.approx(float(lab.body_pos[shoulder, 2]))


# ---- rotation after a strong push (Fig. 17) and knee speed saturation (Fig. 6) -------------


def _turning(
    tmp_path: Path, yaw_rate: float, knee_speed: float, outcome: str = "complete"
) -> LogData:
    """4 s at home: the pelvis turns about the vertical at ``yaw_rate`` [rad/s] from 2 s and
    the knees' motor shafts swing at up to ``knee_speed`` [rad/s] (a 1.25 Hz sine)."""
    robot = load_robot(ROBOT)
    model = mujoco.MjModel.from_xml_path(str(robot.xml_path))
    dofs = [int(model.jnt_dofadr[model.joint(f"{s}_knee_motor").id]) for s in "lr"]
    q0 = Poser(ROBOT).home
    ticks = []
    for k in range(int(round(4.0 / DT)) + 1):
        t = k * DT
        yaw = yaw_rate * max(0.0, t - 2.0)
        qpos, qvel = q0.copy(), np.zeros(model.nv)
        qpos[3:7] = [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]
        qvel[dofs] = knee_speed * math.sin(2 * math.pi * 1.25 * t)
        ticks.append(Tick(t, qpos=qpos, qvel=qvel))
    if outcome == "fell":
        ticks[-1].events = [{"kind": "fall", "reason": "pelvis low"}]
    spec = make_spec(ROBOT, 4.0, controller={"type": "timeprojection", "params": {}})
    return write_log(tmp_path / "turn.mcap", ticks, spec, outcome)


def test_pelvis_that_turns_after_the_push(tmp_path: Path) -> None:
    """A pelvis turning at 0.1 rad/s from 2 s has turned 0.2 rad by 4 s (Fig. 17 holds)."""
    d = _turning(tmp_path, 0.1, 0.0)
    assert measured(d, "pelvis_yaw_change:1-4") == pytest.approx(0.2, abs=2e-3)


def test_pelvis_that_keeps_its_heading(tmp_path: Path) -> None:
    """A pelvis that never turns has no rotation (Fig. 17's claim fails)."""
    assert measured(_turning(tmp_path, 0.0, 0.0), "pelvis_yaw_change:1-4") == pytest.approx(0.0)


def test_pelvis_rotation_of_a_fall_is_not_measured(tmp_path: Path) -> None:
    """A run that falls inside the window has no rotation to report."""
    d = _turning(tmp_path, 0.1, 0.0, outcome="fell")
    assert "before the end of the window" in unmeasurable_reason(d, "pelvis_yaw_change:1-8")


def test_knee_motor_at_the_voltage_bound(tmp_path: Path) -> None:
    """Knee shafts swinging at up to 2.43 rad/s peak at the paper's bound (Fig. 6 holds)."""
    d = _turning(tmp_path, 0.0, 2.43)
    assert measured(d, "peak_knee_motor_speed:0.5-3.5") == pytest.approx(2.43, abs=1e-3)


def test_slow_knee_motor_is_not_saturated(tmp_path: Path) -> None:
    """Knee shafts swinging at 1 rad/s stay far below the 2.43 rad/s bound (Fig. 6 fails)."""
    d = _turning(tmp_path, 0.0, 1.0)
    assert measured(d, "peak_knee_motor_speed") == pytest.approx(1.0, abs=1e-3)


def test_landing_adjustment_of_a_fallen_run_is_not_measurable(tmp_path: Path) -> None:
    """A bound on every landing is not confirmed by the landings before a fall: on a run
    that fell, max_landing_adjustment is not measurable (a complete run measures it)."""
    offsets = UNDISTURBED + [0.1, 0.1]
    assert measured(_landing_log(tmp_path, offsets), "max_landing_adjustment") == pytest.approx(
        0.1, abs=1e-4
    )
    fell = _landing_log(tmp_path, offsets, outcome="fell")
    assert "before every landing of the run could be measured" in unmeasurable_reason(
        fell, "max_landing_adjustment"
    )
