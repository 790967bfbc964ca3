"""Paper I (Lee et al.) metrics on small synthetic logs: one where the claim holds, one where
it does not."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from test_metrics import (
    DT,
    Poser,
    Tick,
    floor_wrench,
    home_sole,
    make_spec,
    measured,
    standing_pairs,
    unmeasurable_reason,
    write_log,
)

from walkrepro.evaluation.metrics import LogData, MetricArgError, check_metric_arg
from walkrepro.papers.lee2021.metrics import eq3_cop_lead, ow_x, switch_torque_jumps

ROBOT = "dyros_red"
BOX = {"name": "obstacle_box", "size": [0.2, 0.2, 0.15], "position": [0.4, -0.1, 0.075]}
PUSH = {
    "name": "push",
    "body": "pelvis",
    "frame": "world",
    "force": [-50, 0, 0],
    "start": 0.5,
    "duration": 0.5,
}


def _spec(**fields):  # noqa: ANN202
    fields.setdefault("controller", {"type": "efsm", "params": {}})
    return make_spec(ROBOT, **fields)


@pytest.fixture(scope="module")
def poser() -> Poser:
    """The dyros_red poser (its IK warm start is shared by the tests)."""
    return Poser(ROBOT)


def _swing(
    poser: Poser,
    foot: str,
    t0: float,
    t1: float,
    dx: float,
    height: float,
    n: int,
    pelvis_speed: float = 0.0,
    start_dx: float = 0.0,
) -> list[Tick]:
    """Ticks 0..n-1: ``foot`` is unloaded in [t0, t1) and its sole moves ``dx`` forward on
    a sine arc of ``height`` (0: slides along the floor); the other foot carries the robot."""
    other = "right_foot" if foot == "left_foot" else "left_foot"
    x0, y0, _ = home_sole(ROBOT, foot)
    ticks = []
    for k in range(n):
        t = k * DT
        s = min(max((t - t0) / (t1 - t0), 0.0), 1.0)
        sole = (x0 + start_dx + dx * s, y0, height * math.sin(math.pi * s))
        swinging = t0 <= t < t1
        ticks.append(
            Tick(
                t,
                qpos=poser((pelvis_speed * t, 0, 0), **{foot: sole}),
                pairs=standing_pairs(ROBOT, [other] if swinging else [foot, other]),
            )
        )
    return ticks


# ---- steps --------------------------------------------------------------------------------


def test_lifted_step_counts(poser: Poser, tmp_path: Path) -> None:
    """A foot that lifts 4 cm and lands is one lifted step."""
    d = write_log(tmp_path / "a.mcap", _swing(poser, "left_foot", 0.2, 0.6, 0.1, 0.04, 80), _spec())
    assert measured(d, "lifted_steps") == 1
    assert measured(d, "lifted_steps:0.0-0.5") == 0  # the window holds no touchdown


def test_sliding_foot_is_not_a_lifted_step(poser: Poser, tmp_path: Path) -> None:
    """A foot unloaded and slid 10 cm along the floor is no step; it is reported as sliding."""
    d = write_log(tmp_path / "a.mcap", _swing(poser, "left_foot", 0.2, 0.6, 0.1, 0.0, 80), _spec())
    assert measured(d, "lifted_steps") == 0 and measured(d, "advancing_steps") == 0
    assert measured(d, "slid_steps") == 1
    assert measured(d, "sliding_distance") == pytest.approx(0.1, abs=1e-3)


def test_advancing_step_lands_ahead(poser: Poser, tmp_path: Path) -> None:
    """A lifted step landing 10 cm ahead of the other foot advances."""
    d = write_log(tmp_path / "a.mcap", _swing(poser, "left_foot", 0.2, 0.6, 0.1, 0.04, 80), _spec())
    assert measured(d, "advancing_steps") == 1


def test_step_in_place_does_not_advance(poser: Poser, tmp_path: Path) -> None:
    """A lifted step landing beside the other foot (2 cm ahead) does not advance."""
    d = write_log(
        tmp_path / "a.mcap", _swing(poser, "left_foot", 0.2, 0.6, 0.02, 0.04, 80), _spec()
    )
    assert measured(d, "lifted_steps") == 1 and measured(d, "advancing_steps") == 0


def test_swing_apex_reaches_the_raise_height(poser: Poser, tmp_path: Path) -> None:
    """A swing whose sole rises 5 cm (Table II's raise height) has a 5 cm apex."""
    d = write_log(tmp_path / "a.mcap", _swing(poser, "left_foot", 0.2, 0.6, 0.1, 0.05, 80), _spec())
    assert measured(d, "swing_apex") == pytest.approx(0.05, abs=2e-3)
    assert measured(d, "swing_apex:min") == pytest.approx(0.05, abs=2e-3)


def test_swing_apex_of_a_low_swing(poser: Poser, tmp_path: Path) -> None:
    """A swing that rises only 2 cm has a 2 cm apex, 3 cm short of the raise height."""
    d = write_log(tmp_path / "a.mcap", _swing(poser, "left_foot", 0.2, 0.6, 0.1, 0.02, 80), _spec())
    assert measured(d, "swing_apex") == pytest.approx(0.02, abs=2e-3)


def test_swing_apex_of_a_slide_is_not_measurable(poser: Poser, tmp_path: Path) -> None:
    """A foot slid along the floor takes no step, so there is no apex to measure."""
    d = write_log(tmp_path / "a.mcap", _swing(poser, "left_foot", 0.2, 0.6, 0.1, 0.0, 80), _spec())
    assert unmeasurable_reason(d, "swing_apex").startswith("no advancing step")


def test_walk_speed_over_the_steps(poser: Poser, tmp_path: Path) -> None:
    """With the pelvis at 0.1 m/s the walk speed is 0.1 m/s, in §VI-A's band."""
    ticks = _swing(poser, "left_foot", 0.2, 0.6, 0.15, 0.04, 80, pelvis_speed=0.1)
    d = write_log(tmp_path / "a.mcap", ticks, _spec())
    assert measured(d, "walk_speed") == pytest.approx(0.1, abs=1e-6)


def test_walk_speed_of_a_robot_that_stays_put(poser: Poser, tmp_path: Path) -> None:
    """A pelvis that does not move while the foot steps gives 0 m/s, outside the band."""
    d = write_log(tmp_path / "a.mcap", _swing(poser, "left_foot", 0.2, 0.6, 0.1, 0.04, 80), _spec())
    assert measured(d, "walk_speed") == pytest.approx(0.0, abs=1e-9)


def test_walk_speed_not_measurable_after_a_fall(poser: Poser, tmp_path: Path) -> None:
    """A walk that ends in a fall has no walk speed, and says why."""
    ticks = _swing(poser, "left_foot", 0.2, 0.6, 0.15, 0.04, 80, pelvis_speed=0.1)
    ticks[70].events = [{"kind": "fall", "reason": "pelvis low"}]
    d = write_log(tmp_path / "a.mcap", ticks, _spec(), "fell")
    assert unmeasurable_reason(d, "walk_speed").startswith("the robot fell at t = 0.700 s")
    assert measured(d, "advancing_steps") == 1  # pre-fall count


# ---- E-FSM phases -------------------------------------------------------------------------


def _phases(tmp_path: Path, durations: list[float]) -> LogData:
    """A log whose efsm_phase cycles DS → SSD (given durations) → SSA (0.2 s) → DS ..."""
    schedule = []
    for ssd in durations:
        schedule += [(2.0, 0.1), (0.0, ssd), (1.0, 0.2)]
    schedule.append((2.0, 0.1))
    ticks, t = [], 0.0
    for phase, length in schedule:
        for _ in range(max(1, round(length / DT))):
            ticks.append(Tick(round(t, 6), signals={"efsm_phase": phase}))
            t += DT
    return write_log(
        tmp_path / "p.mcap", ticks, _spec(sim={"duration": t, "timestep": DT, "control_period": DT})
    )


def test_phase_durations_that_vary(tmp_path: Path) -> None:
    """SSD visits of 0.2, 0.3 and 0.45 s spread by more than 2 % (a time-independent FSM)."""
    assert measured(_phases(tmp_path, [0.3, 0.2, 0.3, 0.45]), "phase_duration_spread:SSD") > 0.02


def test_clock_like_phase_durations(tmp_path: Path) -> None:
    """Equal SSD visits have no spread (a clock-driven FSM fails the claim)."""
    spread = measured(_phases(tmp_path, [0.3, 0.3, 0.3, 0.3]), "phase_duration_spread:SSD")
    assert spread == pytest.approx(0.0, abs=1e-9)


def test_first_ssd_skipped(tmp_path: Path) -> None:
    """A first SSD of one tick is (nearly) skipped: ≤ 0.05 s."""
    assert measured(_phases(tmp_path, [DT, 0.3]), "first_ssd_duration") <= 0.05


def test_first_ssd_not_skipped(tmp_path: Path) -> None:
    """A first SSD of 0.3 s is not skipped."""
    assert measured(_phases(tmp_path, [0.3, 0.3]), "first_ssd_duration") == pytest.approx(0.3)


# ---- CoM and CoP in O_w -------------------------------------------------------------------


def _single_support(tmp_path: Path, cop_along: float, zeta: float = 0.03) -> LogData:
    """Standing at home, the E-FSM in SSD with the right foot swinging (support: left), the
    floor's CoP ``cop_along`` [m] from the left sole centre toward the right one."""
    lx, ly, _ = home_sole(ROBOT, "left_foot")
    rx, ry, _ = home_sole(ROBOT, "right_foot")
    u = np.array([rx - lx, ry - ly]) / math.hypot(rx - lx, ry - ly)
    cop = np.array([lx, ly]) + cop_along * u
    weight = sum(w[2] for w in standing_pairs(ROBOT).values())
    ticks = [
        Tick(
            k * DT,
            pairs={"left_foot/floor": floor_wrench(cop[0], cop[1], weight)},
            signals={"efsm_phase": 0.0, "swing_foot": 1.0},
        )
        for k in range(20)
    ]
    spec = _spec(controller={"type": "efsm", "params": {"zeta": zeta}})
    return write_log(tmp_path / "ss.mcap", ticks, spec)


def test_com_between_the_feet(tmp_path: Path) -> None:
    """At home the CoM lies half the feet's spacing toward the swing foot: it has not passed
    the support foot (> −0.075 m)."""
    d = _single_support(tmp_path, 0.0)
    half = abs(home_sole(ROBOT, "left_foot")[1] - home_sole(ROBOT, "right_foot")[1]) / 2
    assert measured(d, "min_com_x_ss") == pytest.approx(half, abs=0.01)
    assert measured(d, "min_com_x_ss") > -0.075


def test_com_past_the_support_foot() -> None:
    """A CoM 0.1 m beyond the support centre, away from the swing foot, fails the claim."""
    p_sup, p_sw = np.array([[0.0, 0.1]]), np.array([[0.0, -0.1]])
    assert ow_x(np.array([[0.0, 0.2]]), p_sup, p_sw)[0] == pytest.approx(-0.1)
    assert ow_x(np.array([[0.0, 0.2]]), p_sup, p_sw)[0] < -0.075


def test_measured_cop_behind_the_com(tmp_path: Path) -> None:
    """A measured CoP 5 cm from the support centre lies behind a CoM at ~10 cm (Eq. 3, L1)."""
    d = _single_support(tmp_path, 0.05, zeta=0.2)
    assert measured(d, "eq3_cop_lead") > 0
    com_x = measured(d, "min_com_x_ss")
    assert measured(d, "eq3_cop_lead") == pytest.approx(com_x - 0.05, abs=1e-6)


def test_measured_cop_ahead_of_the_com(tmp_path: Path) -> None:
    """A measured CoP beyond the CoM (toward the swing foot) fails Eq. (3)'s purpose."""
    assert measured(_single_support(tmp_path, 0.15, zeta=0.2), "eq3_cop_lead") < 0


def test_eq3_only_judges_a_com_within_zeta() -> None:
    """Samples with the CoM farther than ζ from the support centre are not Eq. (3)'s case."""
    com = np.array([0.10, 0.02])
    cop = np.array([0.12, 0.00])
    assert eq3_cop_lead(com, cop, 0.03) == pytest.approx(0.02)


def test_eq3_not_measurable_when_com_never_near(tmp_path: Path) -> None:
    """With the CoM never within ζ of the support centre, Eq. (3)'s lead is not measurable."""
    assert "never came within ζ" in unmeasurable_reason(
        _single_support(tmp_path, 0.05), "eq3_cop_lead"
    )


# ---- torques and CoP error ----------------------------------------------------------------


def _torques(tmp_path: Path, steps: dict[tuple[int, int], float], switches: bool = True) -> LogData:
    """Reference torques rising 0.01 Nm per tick, plus a step of ``steps[(tick, joint)]``
    [Nm] from that tick on; the E-FSM goes DS → SSD at tick 30 and SSD → SSA at tick 60
    (``switches``), else stays in DS. dyros_red's left leg is actuators 0–5."""
    tau = np.array([np.full(12, 0.01 * k) for k in range(100)])
    for (k, j), step in steps.items():
        tau[k:, j] += step
    phase = [2 if k < 30 or not switches else 0 if k < 60 else 1 for k in range(100)]
    ticks = [
        Tick(k * DT, signals={"tau_ref": tau[k].tolist(), "efsm_phase": phase[k]})
        for k in range(100)
    ]
    return write_log(tmp_path / "tau.mcap", ticks, _spec())


def test_switch_torque_jump_found(tmp_path: Path) -> None:
    """A 50 Nm step of a left-leg torque at a state switch is the measured jump."""
    d = _torques(tmp_path, {(30, 3): 50.0})
    assert measured(d, "switch_torque_jump") == pytest.approx(50.01)
    assert measured(d, "switch_torque_jump:left") == pytest.approx(50.01)


def test_switch_torque_jump_ignores_other_ticks_and_the_other_leg(tmp_path: Path) -> None:
    """Bigger steps away from the switches, or on the right leg, do not count for the left."""
    d = _torques(tmp_path, {(45, 0): 80.0, (30, 6): 90.0, (60, 5): 5.0})
    assert measured(d, "switch_torque_jump") == pytest.approx(5.01)
    assert measured(d, "switch_torque_jump:right") == pytest.approx(90.01)


def test_smooth_torques_jump_by_their_slope_only(tmp_path: Path) -> None:
    """Smooth reference torques change at the switches by their slope only."""
    assert measured(_torques(tmp_path, {}), "switch_torque_jump") == pytest.approx(0.01)


def test_switch_torque_jump_needs_a_switch(tmp_path: Path) -> None:
    """Without an E-FSM state switch there is no switch jump to measure."""
    d = _torques(tmp_path, {(30, 3): 50.0}, switches=False)
    assert "never switched state" in unmeasurable_reason(d, "switch_torque_jump")


def test_switch_torque_jump_unknown_leg_lists_the_legs(tmp_path: Path) -> None:
    """A leg other than left or right is refused, naming the valid legs: by the spec check,
    and as not measurable on a log whose spec was never checked."""
    with pytest.raises(MetricArgError, match="left, right"):
        check_metric_arg("switch_torque_jump:middle")
    assert "left, right" in unmeasurable_reason(_torques(tmp_path, {}), "switch_torque_jump:middle")


def test_switch_torque_jump_of_one_kind_of_switch(tmp_path: Path) -> None:
    """@FROM-TO keeps one kind of switch: the DS → SSD jump is not the SSD → SSA one."""
    d = _torques(tmp_path, {(30, 3): 50.0, (60, 2): 7.0})
    assert measured(d, "switch_torque_jump:left@DS-SSD") == pytest.approx(50.01)
    assert measured(d, "switch_torque_jump:left@SSD-SSA") == pytest.approx(7.01)
    assert "never switched SSA → DS" in unmeasurable_reason(d, "switch_torque_jump:left@SSA-DS")


def test_switch_torque_jump_unknown_switch_lists_the_kinds(tmp_path: Path) -> None:
    """A switch kind outside Table I's cycle is refused, naming the valid kinds; a missing
    leg before @ means the left one."""
    with pytest.raises(MetricArgError, match="SSD-SSA, SSA-DS, DS-SSD"):
        check_metric_arg("switch_torque_jump:left@DS-SSA")
    d = _torques(tmp_path, {(30, 3): 50.0})
    assert measured(d, "switch_torque_jump:@DS-SSD") == pytest.approx(50.01)


def test_switch_torque_jumps_per_switch() -> None:
    """Each switch gets the jump into its first tick, over the given joints only."""
    phase = np.array([2, 2, 0, 0, 1])
    tau = np.array([[0.0, 0.0], [0.0, 9.0], [1.0, 9.0], [1.0, 0.0], [3.0, 0.0]])
    ticks, jumps = switch_torque_jumps(phase, tau, np.array([0]))
    np.testing.assert_array_equal(ticks, [2, 4])
    np.testing.assert_allclose(jumps, [1.0, 2.0])


def _cop_error(tmp_path: Path, err: float) -> LogData:
    ticks = [
        Tick(
            k * DT,
            signals={
                "cop_exp_world": [0.0, 0.0],
                "cop_meas_world": [err, 0.0] if k % 2 else [1.0, 1.0],
                "cop_meas_valid": k % 2,
            },
        )
        for k in range(50)
    ]
    return write_log(tmp_path / "cop.mcap", ticks, _spec())


def test_cop_error_small(tmp_path: Path) -> None:
    """Valid CoP samples 1 cm off give a p90 error ≤ 2 cm; invalid samples are ignored."""
    assert measured(_cop_error(tmp_path, 0.01), "cop_error_p90") == pytest.approx(0.01)


def test_cop_error_large(tmp_path: Path) -> None:
    """CoP samples 5 cm off fail Fig. 15's 0–2 cm."""
    assert measured(_cop_error(tmp_path, 0.05), "cop_error_p90") > 0.02


# ---- the obstacle (§VI-B) -----------------------------------------------------------------


def _collision(
    poser: Poser, tmp_path: Path, left_height: float, outcome: str = "complete"
) -> LogData:
    """The right foot touches the box at 0.1 s; then the left foot swings twice (lifting
    ``left_height``: 0 slides)."""
    ticks = _swing(poser, "left_foot", 0.2, 0.5, 0.05, left_height, 60)
    ticks += [
        Tick(tk.t + 0.6, qpos=tk.qpos, pairs=tk.pairs)
        for tk in _swing(poser, "left_foot", 0.1, 0.4, 0.05, left_height, 60, start_dx=0.05)
    ]
    for tk in ticks[10:15]:
        tk.pairs = {**tk.pairs, "right_foot/obstacle_box": [-20.0, 0.0, 0.0, 0.0, 0.0, 0.0]}
    if outcome == "fell":
        ticks[-1].events = [{"kind": "fall", "reason": "pelvis low"}]
    return write_log(tmp_path / "c.mcap", ticks, _spec(world={"obstacles": [BOX]}), outcome)


def test_keeps_stepping_after_the_collision(poser: Poser, tmp_path: Path) -> None:
    """Two lifted steps after the first obstacle contact count two."""
    assert (
        measured(_collision(poser, tmp_path, 0.04), "steps_after_contact:right_foot/obstacle*") == 2
    )


def test_shuffling_after_the_collision_is_no_stepping(poser: Poser, tmp_path: Path) -> None:
    """A foot slid along the floor after the contact gives no steps."""
    assert (
        measured(_collision(poser, tmp_path, 0.0), "steps_after_contact:right_foot/obstacle*") == 0
    )


def test_steps_after_contact_not_measurable_after_a_fall(poser: Poser, tmp_path: Path) -> None:
    """A run that falls after the collision does not answer "keeps walking"."""
    d = _collision(poser, tmp_path, 0.04, "fell")
    assert "fell" in unmeasurable_reason(d, "steps_after_contact:right_foot/obstacle*")


def test_right_foot_stays_behind_the_box(tmp_path: Path) -> None:
    """A right sole at home (x ≈ 0) stays behind the box face limit (< 0.14 m)."""
    d = write_log(tmp_path / "a.mcap", [Tick(k * DT) for k in range(5)], _spec())
    assert measured(d, "max_sole_x:right") < 0.14


def test_right_foot_passing_the_box(poser: Poser, tmp_path: Path) -> None:
    """A right sole carried to x = 0.2 m passes the limit."""
    _, y, _ = home_sole(ROBOT, "right_foot")
    ticks = [Tick(k * DT, qpos=poser(right_foot=(0.05 * k, y, 0.05))) for k in range(5)]
    d = write_log(tmp_path / "a.mcap", ticks, _spec())
    assert measured(d, "max_sole_x:right") == pytest.approx(0.2, abs=1e-4)


def _swing_force(tmp_path: Path, force: float, swinging: bool = True) -> LogData:
    ticks = []
    for k in range(50):
        pairs = standing_pairs(ROBOT)
        if 10 <= k < 40:
            pairs["right_foot/obstacle_box"] = [-force, 0.0, 0.0, 0.0, 0.0, 0.0]
        ticks.append(Tick(k * DT, pairs=pairs, signals={"swing_foot": 1.0 if swinging else -1.0}))
    return write_log(tmp_path / "f.mcap", ticks, _spec(world={"obstacles": [BOX]}))


def test_swing_obstacle_force_in_band(tmp_path: Path) -> None:
    """A 40 N push of the box on the swing foot is in §VI-B's 15–80 N band, blocked or not."""
    d = _swing_force(tmp_path, 40.0)
    assert measured(d, "peak_swing_obstacle_force:right") == pytest.approx(40.0)
    # The foot stands still against the box for 0.3 s: completely blocked.
    assert measured(d, "blocked_swing_obstacle_force:right") == pytest.approx(40.0)


def test_swing_obstacle_force_out_of_band(tmp_path: Path) -> None:
    """A 350 N push on the swing foot is out of the band; on the stance foot it is not counted."""
    assert measured(_swing_force(tmp_path, 350.0), "peak_swing_obstacle_force:right") > 80
    assert (
        measured(_swing_force(tmp_path, 350.0, swinging=False), "peak_swing_obstacle_force:right")
        == 0
    )


def test_moving_foot_is_not_blocked(poser: Poser, tmp_path: Path) -> None:
    """A swing foot still moving (0.5 m/s) while it touches the box is not blocked: 0 N."""
    _, y, _ = home_sole(ROBOT, "right_foot")
    ticks = []
    for k in range(50):
        pairs = standing_pairs(ROBOT, ["left_foot"])
        pairs["right_foot/obstacle_box"] = [-40.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        ticks.append(
            Tick(
                k * DT,
                qpos=poser(right_foot=(0.005 * k, y, 0.05)),
                pairs=pairs,
                signals={"swing_foot": 1.0},
            )
        )
    d = write_log(tmp_path / "m.mcap", ticks, _spec(world={"obstacles": [BOX]}))
    assert measured(d, "blocked_swing_obstacle_force:right") == 0


# ---- the human push (§VI-C) ---------------------------------------------------------------


def _push(
    tmp_path: Path,
    ds_at: list[float],
    outcome: str = "complete",
    com_speed: object = 0.0,
    force: object = 0.0,
    end: float = 1.0,
) -> LogData:
    """A 3 s log with a push window from 0.5 s to ``end`` [s]: E-FSM entries into DS at
    ``ds_at``, the CoM moving at ``com_speed`` [m/s] along x and the push's force ``force``
    [N] along −x (numbers or functions of time)."""
    ticks = []
    for k in range(300):
        t = round(k * DT, 6)
        events = []
        if t == 0.5:
            events.append({"kind": "disturbance_on", "name": "push"})
        if t == end:
            events.append({"kind": "disturbance_off", "name": "push"})
        if any(abs(t - x) < 1e-9 for x in ds_at):
            events.append({"kind": "fsm", "from": "SSA", "to": "DS"})
        f = force(t) if callable(force) else force
        qvel = np.zeros(_nv())
        qvel[0] = com_speed(t) if callable(com_speed) else com_speed
        xfrc = {"pelvis": [-f, 0.0, 0.0, 0.0, 0.0, 0.0]} if 0.5 <= t < end and f else {}
        ticks.append(Tick(t, qvel=qvel, signals={"ow_yaw": 0.0}, events=events, xfrc=xfrc))
    spec = _spec(disturbances=[{**PUSH, "duration": end - 0.5}])
    return write_log(tmp_path / "push.mcap", ticks, spec, outcome)


def _nv() -> int:
    from test_metrics import _robot

    return int(_robot(ROBOT).home_qpos.size - 1)


def test_no_ds_while_held(tmp_path: Path) -> None:
    """A DS entry only after the release: none during the push."""
    assert measured(_push(tmp_path, [1.3]), "ds_entries_during_push") == 0


def test_ds_while_held(tmp_path: Path) -> None:
    """A DS entry in the middle of the push fails Fig. 12(a)'s claim."""
    assert measured(_push(tmp_path, [0.7, 1.3]), "ds_entries_during_push") == 1


def test_ds_soon_after_release(tmp_path: Path) -> None:
    """DS 0.3 s after the release is within 1.5 s."""
    assert measured(_push(tmp_path, [1.3]), "ds_delay_after_push") == pytest.approx(0.3)


def test_ds_late_or_never(tmp_path: Path) -> None:
    """DS 1.8 s after the release fails; a completed run with no DS after it gives inf."""
    assert measured(_push(tmp_path, [2.8]), "ds_delay_after_push") == pytest.approx(1.8)
    assert measured(_push(tmp_path, []), "ds_delay_after_push") == math.inf


def test_ds_delay_after_onset_counts_a_ds_during_the_push(tmp_path: Path) -> None:
    """A DS the push brings on (0.2 s after the onset, while it acts) counts from the onset;
    counted from the release, the delay would be the next DS's (2.0 s)."""
    d = _push(tmp_path, [0.7, 3.0 - DT])
    assert measured(d, "ds_delay_after_onset") == pytest.approx(0.2)
    assert measured(d, "ds_delay_after_push") == pytest.approx(2.0 - DT)


def test_ds_delay_after_onset_late_never_or_unknown(tmp_path: Path) -> None:
    """DS 1.5 s after the onset is what it is; a completed run without DS gives inf; a run
    stopped before any DS does not answer."""
    assert measured(_push(tmp_path, [2.0]), "ds_delay_after_onset") == pytest.approx(1.5)
    assert measured(_push(tmp_path, []), "ds_delay_after_onset") == math.inf
    d = _push(tmp_path, [], outcome="interrupted")
    assert "before the E-FSM entered DS" in unmeasurable_reason(d, "ds_delay_after_onset")


def test_ds_delay_not_measurable_when_stopped_early(tmp_path: Path) -> None:
    """A run stopped after the release, before any DS, does not answer the delay."""
    d = _push(tmp_path, [], outcome="interrupted")
    assert "before the E-FSM entered DS" in unmeasurable_reason(d, "ds_delay_after_push")


def test_com_still_while_held(tmp_path: Path) -> None:
    """A CoM moving at 1 cm/s while held is ≈ 0 (≤ 0.03 m/s)."""
    assert measured(_push(tmp_path, [], com_speed=0.01), "push_com_speed") == pytest.approx(0.01)


def test_com_moving_while_held(tmp_path: Path) -> None:
    """A CoM still moving at 0.1 m/s while held fails Fig. 12(d)'s claim."""
    assert measured(_push(tmp_path, [], com_speed=0.1), "push_com_speed") > 0.03


def test_steps_after_release(poser: Poser, tmp_path: Path) -> None:
    """A lifted step after the release counts; a foot slid after it does not."""
    spec = _spec(disturbances=[PUSH])
    lifted = _swing(poser, "left_foot", 1.1, 1.5, 0.05, 0.04, 160)
    assert measured(write_log(tmp_path / "a.mcap", lifted, spec), "steps_after_push") == 1
    slid = _swing(poser, "left_foot", 1.1, 1.5, 0.05, 0.0, 160)
    assert measured(write_log(tmp_path / "b.mcap", slid, spec), "steps_after_push") == 0


def test_no_push_in_the_spec(tmp_path: Path) -> None:
    """Push metrics on a run without a push are not measurable, and say so."""
    d = write_log(tmp_path / "a.mcap", [Tick(k * DT) for k in range(5)], _spec())
    for name in (
        "ds_entries_during_push",
        "ds_delay_after_push",
        "ds_delay_after_onset",
        "steps_after_push",
        "push_com_speed",
    ):
        assert "no push" in unmeasurable_reason(d, name)


# ---- the hand's hold (§VI-C: the force at equilibrium and the still CoM) -----------------


def _hold_log(tmp_path: Path, force: object, com_speed: object = 0.0) -> LogData:
    """A 3 s log with a 0.5–2.5 s hold (:func:`_push`)."""
    return _push(tmp_path, [], com_speed=com_speed, force=force, end=2.5)


def test_hold_force_is_the_equilibrium_not_the_peak(tmp_path: Path) -> None:
    """A hand that overshoots to 120 N while engaging and settles at 75 N measures 75 N over
    the middle second (1.0–2.0 s): within §VI-C's 60–90 N, where the peak is not."""
    d = _hold_log(tmp_path, lambda t: 120.0 if t < 0.9 else 75.0)
    assert measured(d, "hold_force") == pytest.approx(75.0)
    assert measured(d, "peak_external_force") == pytest.approx(120.0)


def test_hold_force_too_weak(tmp_path: Path) -> None:
    """A hand that settles at 40 N fails the 60 N bound, whatever it did while engaging."""
    d = _hold_log(tmp_path, lambda t: 120.0 if t < 0.9 else 40.0)
    assert measured(d, "hold_force") == pytest.approx(40.0)


def test_hold_com_speed_over_the_middle_second(tmp_path: Path) -> None:
    """A CoM that moves fast while the hand engages and releases but is still in the middle
    second passes; one still swinging at 0.1 m/s in the middle second fails."""
    still = _hold_log(tmp_path, 75.0, lambda t: 0.3 if t < 0.9 or t > 2.1 else 0.01)
    assert measured(still, "hold_com_speed") == pytest.approx(0.01)
    swinging = _hold_log(tmp_path, 75.0, lambda t: 0.1 if int(t * 10) % 2 else -0.1)
    assert measured(swinging, "hold_com_speed") == pytest.approx(0.1)


def test_hold_metrics_need_a_second(tmp_path: Path) -> None:
    """A 0.5 s push has no middle second: not measurable, and it says why."""
    d = _push(tmp_path, [1.3])
    assert "less than the 1 s" in unmeasurable_reason(d, "hold_force")
    assert "less than the 1 s" in unmeasurable_reason(d, "hold_com_speed")


# ---- footsteps as the E-FSM walks them (§VI-A, Table II, Fig. 8) ---------------------------


def _two_swings(poser: Poser, first_height: float, second_height: float) -> list[Tick]:
    """The left foot swings 10 cm forward in 0.2–0.6 s (raised ``first_height``; 0: slid),
    then the right foot 20 cm in 0.8–1.2 s (raised ``second_height``), 1.5 s in all."""
    (lx, ly, _), (rx, ry, _) = home_sole(ROBOT, "left_foot"), home_sole(ROBOT, "right_foot")
    ticks = []
    for k in range(150):
        t = k * DT
        s1 = min(max((t - 0.2) / 0.4, 0.0), 1.0)
        s2 = min(max((t - 0.8) / 0.4, 0.0), 1.0)
        left = (lx + 0.1 * s1, ly, first_height * math.sin(math.pi * s1))
        right = (rx + 0.2 * s2, ry, second_height * math.sin(math.pi * s2))
        loaded = [f for f, (a, b) in {"left_foot": (0.2, 0.6), "right_foot": (0.8, 1.2)}.items()
                  if not a <= t < b]  # fmt: skip
        ticks.append(
            Tick(
                t,
                qpos=poser((0.05 * s1 + 0.1 * s2, 0, 0), left_foot=left, right_foot=right),
                pairs=standing_pairs(ROBOT, loaded),
            )
        )
    return ticks


def test_first_swing_slid_counts_as_the_efsm_footstep(poser: Poser, tmp_path: Path) -> None:
    """A first swing that slides 10 cm forward (no raise target: its SSD omitted) is counted
    by efsm_footsteps with the later lifted step, and is still reported by slid_steps."""
    d = write_log(tmp_path / "a.mcap", _two_swings(poser, 0.0, 0.04), _spec())
    assert measured(d, "advancing_steps") == 1
    assert measured(d, "efsm_footsteps") == 2
    assert measured(d, "slid_steps") == 1 and measured(d, "later_slides") == 0


def test_a_later_slide_is_no_footstep(poser: Poser, tmp_path: Path) -> None:
    """A first swing that lifts, then a later swing that slides: the slide is no footstep and
    later_slides reports it (every swing after the first must lift)."""
    d = write_log(tmp_path / "a.mcap", _two_swings(poser, 0.04, 0.0), _spec())
    assert measured(d, "efsm_footsteps") == 1
    assert measured(d, "later_slides") == 1


def test_all_swings_lifted(poser: Poser, tmp_path: Path) -> None:
    """Two lifted swings are two footsteps, none slid."""
    d = write_log(tmp_path / "a.mcap", _two_swings(poser, 0.04, 0.04), _spec())
    assert measured(d, "efsm_footsteps") == 2 and measured(d, "later_slides") == 0
