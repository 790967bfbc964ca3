"""Paper I (Lee et al.) metrics for the claims the register added (Fig. 7b's state durations,
Fig. 15's CoP error while a support foot moves, §VI-B's collision time and walking in place,
§VI-C's hold and release) on small synthetic logs: one where the claim holds, one where it
does not."""

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
    floor_wrench,
    home_sole,
    make_spec,
    measured,
    standing_pairs,
    unmeasurable_reason,
    write_log,
)

from walkrepro.evaluation.metrics import LogData, NotMeasurable
from walkrepro.papers.lee2021.metrics import (
    capture_points,
    duration_distance_correlation,
    landing_heights,
    swing_travel,
)

ROBOT = "dyros_red"
FEET = ("left_foot", "right_foot")
BOX = {"name": "obstacle_box", "size": [0.2, 0.2, 0.15], "position": [0.4, -0.1, 0.075]}


def _spec(**fields):  # noqa: ANN202
    fields.setdefault("controller", {"type": "efsm", "params": {}})
    return make_spec(ROBOT, **fields)


@pytest.fixture(scope="module")
def poser() -> Poser:
    """The dyros_red poser (its IK warm start is shared by the tests)."""
    return Poser(ROBOT)


# ---- Fig. 7(b): state duration against the CoM–CoP distance -------------------------------


def test_correlation_negative_when_near_cop_states_last_longer() -> None:
    """Visits of 0.4, 0.3, 0.2 s with CoM–CoP distances 1, 3, 6 cm rank perfectly inversely."""
    t = np.arange(0.0, 1.0, DT)
    cop = np.where(t < 0.4, 0.09, np.where(t < 0.7, 0.07, 0.04))
    visits = [(0.0, 0.4), (0.4, 0.7), (0.7, 0.9)]
    assert duration_distance_correlation(visits, t, np.full_like(t, 0.1), cop) == -1.0


def test_correlation_positive_when_near_cop_states_are_short() -> None:
    """The reverse ordering (near CoP, short state) fails Fig. 7(b)'s claim: +1."""
    t = np.arange(0.0, 1.0, DT)
    cop = np.where(t < 0.4, 0.04, np.where(t < 0.7, 0.07, 0.09))
    visits = [(0.0, 0.4), (0.4, 0.7), (0.7, 0.9)]
    assert duration_distance_correlation(visits, t, np.full_like(t, 0.1), cop) == 1.0


def test_correlation_needs_three_visits_with_a_cop() -> None:
    """Two visits, or visits without a measured CoP, give no ranking."""
    t = np.arange(0.0, 1.0, DT)
    cop = np.where(t < 0.5, 0.05, np.nan)
    with pytest.raises(NotMeasurable, match="fewer than 3"):
        duration_distance_correlation([(0.0, 0.2), (0.2, 0.5), (0.5, 0.9)], t, t * 0, cop)


def _ssd_visits(tmp_path: Path, visits: list[tuple[float, float]]) -> LogData:
    """Standing at home, the right foot the E-FSM's swing foot; the E-FSM alternates DS (0.1
    s) and SSD visits of the given (duration [s], floor CoP from the left sole centre toward
    the right one [m])."""
    lx, ly, _ = home_sole(ROBOT, "left_foot")
    rx, ry, _ = home_sole(ROBOT, "right_foot")
    u = np.array([rx - lx, ry - ly]) / math.hypot(rx - lx, ry - ly)
    weight = sum(w[2] for w in standing_pairs(ROBOT).values())
    ticks, k = [], 0
    for duration, cop_along in [*visits, (0.1, 0.0)]:
        cop = np.array([lx, ly]) + cop_along * u
        for phase, n in ((2.0, 10), (0.0, round(duration / DT))):
            for _ in range(n):
                pairs = {"left_foot/floor": floor_wrench(cop[0], cop[1], weight)}
                ticks.append(Tick(round(k * DT, 6), pairs=pairs,
                                  signals={"efsm_phase": phase, "swing_foot": 1.0}))  # fmt: skip
                k += 1
    spec = _spec(sim={"duration": k * DT, "timestep": DT, "control_period": DT})
    return write_log(tmp_path / "ssd.mcap", ticks, spec)


def test_ssd_durations_longer_with_the_cop_near_the_com(tmp_path: Path) -> None:
    """A log whose longer SSD visits have the CoP nearer the CoM gives a negative correlation;
    the first visit (from rest) is left out."""
    half = abs(home_sole(ROBOT, "left_foot")[1] - home_sole(ROBOT, "right_foot")[1]) / 2
    visits = [(0.1, half), (0.4, half - 0.01), (0.3, half - 0.03), (0.2, half - 0.06)]
    assert measured(_ssd_visits(tmp_path, visits), "duration_cop_distance_corr:SSD") < 0


def test_ssd_durations_shorter_with_the_cop_near_the_com(tmp_path: Path) -> None:
    """The reverse (longer SSD with the CoP farther from the CoM) is positive: the row fails."""
    half = abs(home_sole(ROBOT, "left_foot")[1] - home_sole(ROBOT, "right_foot")[1]) / 2
    visits = [(0.1, half), (0.2, half - 0.01), (0.3, half - 0.03), (0.4, half - 0.06)]
    assert measured(_ssd_visits(tmp_path, visits), "duration_cop_distance_corr:SSD") > 0


# ---- Fig. 15: the CoP error while a supporting foot moves ---------------------------------


def _moving_support(poser: Poser, tmp_path: Path, swing: float, err: float) -> LogData:
    """The left foot slides 5 cm forward in 0.2–0.4 s (1 s log) while the E-FSM's swing
    foot is ``swing`` (1: the right swings, the left supports); the CoP error is ``err`` [m]
    while it moves, 1 mm otherwise."""
    lx, ly, _ = home_sole(ROBOT, "left_foot")
    ticks = []
    for k in range(100):
        t = k * DT
        s = min(max((t - 0.2) / 0.2, 0.0), 1.0)
        moving = 0.2 < t <= 0.4
        ticks.append(
            Tick(
                t,
                qpos=poser(left_foot=(lx + 0.05 * s, ly, 0.0)),
                signals={
                    "swing_foot": swing,
                    "cop_exp_world": [0.0, 0.0],
                    "cop_meas_world": [err if moving else 0.001, 0.0],
                    "cop_meas_valid": 1,
                },
            )
        )
    return write_log(tmp_path / "ms.mcap", ticks, _spec())


def test_cop_error_small_while_the_support_foot_moves(poser: Poser, tmp_path: Path) -> None:
    """A 1 cm error while the supporting left foot moves stays in Fig. 15's 0–2 cm."""
    d = _moving_support(poser, tmp_path, 1.0, 0.01)
    assert measured(d, "cop_error_p90:support_moving") == pytest.approx(0.01)


def test_cop_error_grows_while_the_support_foot_moves(poser: Poser, tmp_path: Path) -> None:
    """A 5 cm error only while the supporting foot moves fails the claim, though the whole
    walk's p90 (the moving ticks are 20 %) hides it."""
    d = _moving_support(poser, tmp_path, 1.0, 0.05)
    assert measured(d, "cop_error_p90:support_moving") == pytest.approx(0.05)
    assert measured(d, "cop_error_p90") <= 0.05


def test_a_moving_swing_foot_is_no_moving_support(poser: Poser, tmp_path: Path) -> None:
    """The same motion of the left foot while it is the swing foot selects no tick."""
    d = _moving_support(poser, tmp_path, -1.0, 0.05)
    assert "while a supporting foot moved" in unmeasurable_reason(d, "cop_error_p90:support_moving")


# ---- §VI-B: the collision's time and walking in place -------------------------------------


def _collision(
    poser: Poser,
    tmp_path: Path,
    pelvis_speed: float,
    contact: bool = True,
    outcome: str = "complete",
    sideways: bool = False,
) -> LogData:
    """The right foot touches the box at 0.1–0.15 s (unless not ``contact``); the left foot
    swings 5 cm in 0.2–0.5 s while the pelvis, and the feet with it, move at ``pelvis_speed``
    [m/s] (0.6 s), forward or ``sideways`` (+y)."""
    ticks = []
    lx, ly, _ = home_sole(ROBOT, "left_foot")
    rx, ry, _ = home_sole(ROBOT, "right_foot")
    for k in range(60):
        t = k * DT
        s = min(max((t - 0.2) / 0.3, 0.0), 1.0)
        px, py = (0.0, pelvis_speed * t) if sideways else (pelvis_speed * t, 0.0)
        left = (lx + px + 0.05 * s, ly + py, 0.04 * math.sin(math.pi * s))
        pairs = standing_pairs(ROBOT, ["right_foot"] if 0.2 <= t < 0.5 else FEET)
        if contact and 10 <= k < 15:
            pairs["right_foot/obstacle_box"] = [-20.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        qpos = poser((px, py, 0), left_foot=left, right_foot=(rx + px, ry + py, 0.0))
        ticks.append(Tick(t, qpos=qpos, pairs=pairs))
    if outcome == "fell":
        ticks[-1].events = [{"kind": "fall", "reason": "pelvis low"}]
    return write_log(tmp_path / "c.mcap", ticks, _spec(world={"obstacles": [BOX]}), outcome)


def test_first_contact_time(poser: Poser, tmp_path: Path) -> None:
    """The first contact of the right foot with the box is at 0.1 s."""
    d = _collision(poser, tmp_path, 0.0)
    assert measured(d, "first_contact_time:right_foot/obstacle*") == pytest.approx(0.1)


def test_no_contact_no_collision_time(poser: Poser, tmp_path: Path) -> None:
    """A run in which the foot never touches the box has no collision time."""
    d = _collision(poser, tmp_path, 0.0, contact=False)
    assert "no contact" in unmeasurable_reason(d, "first_contact_time:right_foot/obstacle*")


def test_stepping_in_place_after_the_collision(poser: Poser, tmp_path: Path) -> None:
    """A pelvis that stays put while the left foot steps has moved < 0.1 m: in place."""
    d = _collision(poser, tmp_path, 0.0)
    assert measured(d, "pelvis_advance_after_contact:right_foot/obstacle*") < 0.01


def test_walking_on_after_the_collision(poser: Poser, tmp_path: Path) -> None:
    """A pelvis that walks on at 0.4 m/s (0.2 m after the contact) fails "in the same place"."""
    d = _collision(poser, tmp_path, 0.4)
    shift = measured(d, "pelvis_advance_after_contact:right_foot/obstacle*")
    assert shift == pytest.approx(0.4 * (0.59 - 0.1), abs=0.01)
    assert shift > 0.1


def test_sideways_sway_stays_in_place(poser: Poser, tmp_path: Path) -> None:
    """A pelvis swaying 0.2 m sideways (stepping in place shifts the weight) is still in place."""
    d = _collision(poser, tmp_path, 0.4, sideways=True)
    assert measured(d, "pelvis_advance_after_contact:right_foot/obstacle*") < 0.01


def test_pelvis_shift_not_measurable_after_a_fall(poser: Poser, tmp_path: Path) -> None:
    """A run that falls after the collision does not answer "in the same place"."""
    d = _collision(poser, tmp_path, 0.0, outcome="fell")
    assert "fell" in unmeasurable_reason(d, "pelvis_advance_after_contact:right_foot/obstacle*")


# ---- §VI-C: the hold until the release starts, and DS after the release -------------------


def _ramp_push(tmp_path: Path, ds_at: list[float], profile: str = "ramp") -> LogData:
    """A 2 s log with a hand on the pelvis from 0.5 to 1.0 s, letting go over its last 0.2 s
    (``profile`` ramp) or at once (constant); E-FSM entries into DS at ``ds_at`` [s]."""
    ticks = []
    for k in range(200):
        t = round(k * DT, 6)
        events = []
        if t == 0.5:
            events.append({"kind": "disturbance_on", "name": "push"})
        if t == 1.0:
            events.append({"kind": "disturbance_off", "name": "push"})
        if any(abs(t - x) < 1e-9 for x in ds_at):
            events.append({"kind": "fsm", "from": "SSA", "to": "DS"})
        ticks.append(Tick(t, events=events))
    push = {"name": "push", "body": "pelvis", "frame": "world", "force": [-50, 0, 0],
            "start": 0.5, "duration": 0.5, "profile": profile}  # fmt: skip
    if profile == "ramp":
        push["ramp_time"] = 0.2
    return write_log(tmp_path / "push.mcap", ticks, _spec(disturbances=[push]))


def test_ds_during_the_release_is_not_during_the_hold(tmp_path: Path) -> None:
    """A DS entry at 0.9 s, while the hand lets go (from 0.8 s), counts in the push window but
    not in the held window."""
    d = _ramp_push(tmp_path, [0.9])
    assert measured(d, "ds_entries_during_push") == 1
    assert measured(d, "ds_entries_during_push:held") == 0


def test_ds_while_fully_held(tmp_path: Path) -> None:
    """A DS entry at 0.7 s, before the hand lets go, fails Fig. 13's claim."""
    assert measured(_ramp_push(tmp_path, [0.7]), "ds_entries_during_push:held") == 1


def test_ds_delay_counted_from_the_release_start(tmp_path: Path) -> None:
    """DS at 1.4 s is 0.6 s after the ramp starts letting go (0.8 s), 0.4 s after the window
    ends; a DS during the release counts too."""
    d = _ramp_push(tmp_path, [1.4])
    assert measured(d, "ds_delay_after_release") == pytest.approx(0.6)
    assert measured(d, "ds_delay_after_push") == pytest.approx(0.4)
    assert measured(_ramp_push(tmp_path, [0.9]), "ds_delay_after_release") == pytest.approx(0.1)


def test_ds_delay_from_a_sudden_release(tmp_path: Path) -> None:
    """A push that stops at once (constant profile) is released at the window's end."""
    d = _ramp_push(tmp_path, [1.4], profile="constant")
    assert measured(d, "ds_delay_after_release") == pytest.approx(0.4)
    assert measured(d, "ds_entries_during_push:held") == 0


def test_ds_delay_after_release_never(tmp_path: Path) -> None:
    """A completed run with no DS after the release gives inf (the row fails)."""
    assert measured(_ramp_push(tmp_path, [0.6]), "ds_delay_after_release") == math.inf


# ---- §VI-A, Fig. 7(c): the foot does not land completely at the end of SSA ---------------


def test_landing_heights_at_the_switches() -> None:
    """The landing foot's height is read at the first DS tick of each SSA → DS switch, for
    the foot that swung in that SSA."""
    phase = np.array([0, 1, 1, 2, 2, 0, 1, 2], dtype=float)
    swing = np.array([1, 1, 1, 0, 0, -1, -1, 0], dtype=float)
    left = np.array([0, 0, 0, 0, 0, 0.03, 0.02, 0.004])
    right = np.array([0.02, 0.01, 0.006, 0.008, 0.0, 0, 0, 0])
    assert np.allclose(landing_heights(phase, swing, left, right), [0.008, 0.004])


def _landing(poser: Poser, tmp_path: Path, height: float) -> LogData:
    """Two steps of the right foot: SSA (0.2 s) with the sole centre coming down to
    ``height`` [m] above the floor, then DS (0.1 s) with it there, then SSD again."""
    rx, ry, _ = home_sole(ROBOT, "right_foot")
    ticks, k = [], 0
    for _ in range(2):
        for phase, swing, n in ((1.0, 1.0, 20), (2.0, 0.0, 10), (0.0, 1.0, 10)):
            for j in range(n):
                z = height + (0.02 * (1 - j / n) if phase == 1.0 else 0.0)
                z = 0.03 if phase == 0.0 else z
                ticks.append(Tick(round(k * DT, 6), qpos=poser(right_foot=(rx, ry, z)),
                                  signals={"efsm_phase": phase, "swing_foot": swing}))  # fmt: skip
                k += 1
    return write_log(tmp_path / "land.mcap", ticks, _spec())


def test_a_foot_still_above_the_floor_at_the_switch(poser: Poser, tmp_path: Path) -> None:
    """A sole centre 8 mm up when DS begins has not landed completely: > 1 mm."""
    assert measured(_landing(poser, tmp_path, 0.008), "landing_height") == pytest.approx(0.008)


def test_a_foot_landed_flat_at_the_switch(poser: Poser, tmp_path: Path) -> None:
    """A sole flat on the floor when DS begins fails the claim (≤ 1 mm)."""
    assert measured(_landing(poser, tmp_path, 0.0), "landing_height") == pytest.approx(
        0.0, abs=1e-6
    )


def test_no_landing_height_without_a_switch(tmp_path: Path) -> None:
    """A log whose E-FSM never leaves SSA has no SSA → DS switch to judge."""
    ticks = [Tick(k * DT, signals={"efsm_phase": 1.0, "swing_foot": 1.0}) for k in range(20)]
    d = write_log(tmp_path / "ssa.mcap", ticks, _spec())
    assert "never switched SSA → DS" in unmeasurable_reason(d, "landing_height")


# ---- Fig. 13(d): the swing foot moves while the upper body is held ------------------------


def _held_swing(poser: Poser, tmp_path: Path, travel: float) -> LogData:
    """A hand on the pelvis from 0.5 to 1.0 s, letting go over its last 0.2 s; the right foot
    swings throughout and moves ``travel`` [m] forward (x) while held (0.5–0.8 s), and 10 cm
    more while the hand lets go."""
    rx, ry, _ = home_sole(ROBOT, "right_foot")
    ticks = []
    for k in range(120):
        t = round(k * DT, 6)
        s = min(max((t - 0.5) / 0.3, 0.0), 1.0)
        x = rx + travel * s + (0.1 * (t - 0.8) / 0.2 if t > 0.8 else 0.0)
        events = []
        if t == 0.5:
            events.append({"kind": "disturbance_on", "name": "push"})
        if t == 1.0:
            events.append({"kind": "disturbance_off", "name": "push"})
        ticks.append(Tick(t, qpos=poser(right_foot=(x, ry, 0.03)), events=events,
                          signals={"efsm_phase": 1.0, "swing_foot": 1.0}))  # fmt: skip
    hold = {"name": "push", "body": "pelvis", "frame": "world", "force": [-50, 0, 0],
            "start": 0.5, "duration": 0.5, "profile": "ramp", "ramp_time": 0.2}  # fmt: skip
    return write_log(tmp_path / "held.mcap", ticks, _spec(disturbances=[hold]))


def test_the_swing_foot_moves_while_held(poser: Poser, tmp_path: Path) -> None:
    """A swing foot that moves 5 cm while the hand holds moves (> 2 cm)."""
    d = _held_swing(poser, tmp_path, 0.05)
    assert measured(d, "swing_travel_during_push:held") == pytest.approx(0.05, abs=1e-3)


def test_the_swing_foot_still_while_held(poser: Poser, tmp_path: Path) -> None:
    """A swing foot that stays put while held fails Fig. 13(d); its motion during the
    release (from 0.8 s) does not count with ``held``, and does without it."""
    d = _held_swing(poser, tmp_path, 0.0)
    assert measured(d, "swing_travel_during_push:held") < 1e-3
    assert measured(d, "swing_travel_during_push") > 0.05


def test_swing_travel_of_each_swing_foot() -> None:
    """Each foot's travel is counted from where it was when it first swung; DS samples none."""
    swing = np.array([1, 1, 0, -1, -1], dtype=float)
    right = np.array([[0, 0, 0], [0.01, 0, 0], [0.5, 0, 0], [0.5, 0, 0], [0.5, 0, 0]])
    left = np.array([[0, 0, 0], [0, 0, 0], [0, 0, 0], [0.1, 0, 0], [0.1, 0.03, 0.04]])
    assert swing_travel(swing, left, right) == pytest.approx(0.05)


# ---- §III-B3: the CP in SSD, and the CoP against x_p^des in DS ----------------------------


def test_capture_point_of_eq2() -> None:
    """x_CP = x_m + ẋ_m sqrt(z_m0 / g): a CoM at 0.05 m moving at −0.2 m/s, 0.8 m high."""
    cp = capture_points(np.array([0.05]), np.array([-0.2]), 0.8)
    assert cp[0] == pytest.approx(0.05 - 0.2 * math.sqrt(0.8 / 9.81))


def _ssd_drift(poser: Poser, tmp_path: Path, speed: float) -> LogData:
    """SSD with the right foot swinging (the left supports) for 0.3 s, the whole robot
    moving toward the support foot (+y, −x of O_w) at ``speed`` [m/s]."""
    rx, ry, _ = home_sole(ROBOT, "right_foot")
    lx, ly, _ = home_sole(ROBOT, "left_foot")
    ticks = []
    for k in range(30):
        t = round(k * DT, 6)
        dy = speed * t
        qvel = np.zeros(poser.model.nv)
        qvel[1] = speed
        qpos = poser((0.0, dy, 0.0), left_foot=(lx, ly + dy, 0.0), right_foot=(rx, ry + dy, 0.03))
        ticks.append(Tick(t, qpos=qpos, qvel=qvel, pairs=standing_pairs(ROBOT, ["left_foot"]),
                          signals={"efsm_phase": 0.0, "swing_foot": 1.0}))  # fmt: skip
    return write_log(tmp_path / "ssd_drift.mcap", ticks, _spec())


def test_min_cp_of_a_still_com_is_the_com(poser: Poser, tmp_path: Path) -> None:
    """A still robot's CP is its CoM: the smallest CP equals the smallest CoM x in O_w."""
    d = _ssd_drift(poser, tmp_path, 0.0)
    assert measured(d, "min_cp_x_ssd") == pytest.approx(measured(d, "min_com_x_ss"), abs=1e-9)


def test_min_cp_leads_a_moving_com(poser: Poser, tmp_path: Path) -> None:
    """A CoM moving at 0.5 m/s toward the support foot puts the CP ≈ 0.14 m further on (its
    O_w x-axis points from the support to the swing foot, −y here): beyond the support centre."""
    still = measured(_ssd_drift(poser, tmp_path, 0.0), "min_cp_x_ssd")
    d = _ssd_drift(poser, tmp_path, 0.5)
    lead = still - measured(d, "min_cp_x_ssd")
    assert lead == pytest.approx(0.5 * math.sqrt(_com_height(d) / 9.81), abs=2e-3)
    assert measured(d, "min_cp_x_ssd") < 0


def _com_height(d: LogData) -> float:
    """The CoM height at the log's first state [m]."""
    data = mujoco.MjData(d.model)
    data.qpos[:] = d.qpos[0]
    mujoco.mj_kinematics(d.model, data)
    mujoco.mj_comPos(d.model, data)
    return float(data.subtree_com[d.model.body("pelvis").id][2])


def _ds_tracking(tmp_path: Path, lag: float) -> LogData:
    """DS for 0.3 s with x_p^des moving from the left sole centre toward the right one, and
    the floor's CoP ``lag`` [m] behind it along that line (SSA ticks before it, ignored)."""
    lx, ly, _ = home_sole(ROBOT, "left_foot")
    rx, ry, _ = home_sole(ROBOT, "right_foot")
    u = np.array([rx - lx, ry - ly]) / math.hypot(rx - lx, ry - ly)
    weight = sum(w[2] for w in standing_pairs(ROBOT).values())
    ticks = []
    for k in range(40):
        t = round(k * DT, 6)
        ds = k >= 10
        s = (k - 10) / 30 if ds else 0.0
        des = np.array([lx, ly]) + s * math.hypot(rx - lx, ry - ly) * u
        cop = des - (lag if ds else 0.05) * u
        pairs = {"left_foot/floor": floor_wrench(cop[0], cop[1], weight)}
        ticks.append(Tick(t, pairs=pairs, signals={"efsm_phase": 2.0 if ds else 1.0,
                                                    "swing_foot": 0.0 if ds else 1.0,
                                                    "xp_des_world": list(des)}))  # fmt: skip
    return write_log(tmp_path / "ds.mcap", ticks, _spec())


def test_ds_cop_follows_the_desired_cop(tmp_path: Path) -> None:
    """A floor CoP 2 mm behind x_p^des in DS tracks it within 2 mm; the SSA ticks' 5 cm
    offset does not count."""
    assert measured(_ds_tracking(tmp_path, 0.002), "ds_cop_tracking_p90") == pytest.approx(0.002)


def test_ds_cop_lags_the_desired_cop(tmp_path: Path) -> None:
    """A floor CoP 3 cm behind x_p^des is a CoP not generated as desired: 3 cm."""
    assert measured(_ds_tracking(tmp_path, 0.03), "ds_cop_tracking_p90") == pytest.approx(0.03)
