"""Metrics specific to the lee2021 reproduction (computed from the log alone).

Paper I (Lee et al. 2021): the E-FSM controller logs ``efsm_phase`` (0 SSD, 1 SSA, 2 DS),
``fsm_state`` (−1/0/1 of Fig. 8), the CoM and x_p^des in O_w, the expected and measured
CoP and the reference torques. Steps are read from the feet's motion: a *lifted step* is a
touchdown after the sole centre rose above :data:`LIFT_HEIGHT`, so a foot that is only
unloaded (weight shift) or scraped along the floor does not count.
"""

from __future__ import annotations

import math
from functools import lru_cache

import mujoco
import numpy as np

from walkrepro.metrics import LogData, metric

FEET = ("left", "right")
#: A step lifts the sole centre at least this high [m] (the paper's swing height is 0.05 m).
LIFT_HEIGHT = 0.01
#: ... and ends when it is back below this height [m] (the landing height is 0.005 m).
LAND_HEIGHT = 0.006
#: A step advances when the foot lands this far ahead of the other foot [m].
ADVANCE = 0.05
#: A foot placement is new when it is this far from the foot's previous one [m].
MOVED = 0.02
#: E-FSM phases as logged in ``efsm_phase`` (Table I).
PHASES = {"SSD": 0.0, "SSA": 1.0, "DS": 2.0}
#: A foot touches an obstacle above this contact force [N].
OBSTACLE_CONTACT_FORCE = 1.0


@lru_cache(maxsize=8)
def _sole_tracks(d: LogData) -> dict[str, np.ndarray]:
    """World position of each sole centre at every logged state, shape (N, 3) per foot."""
    model = d.model
    data = mujoco.MjData(model)
    sites = {f: model.site(f"{f}_sole").id for f in FEET}
    out = {f: np.zeros((d.t.size, 3)) for f in FEET}
    for i, qpos in enumerate(d.qpos):
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        for f in FEET:
            out[f][i] = data.site_xpos[sites[f]]
    return out


def lifted_steps(d: LogData) -> list[tuple[str, float, np.ndarray]]:
    """Touchdowns after a lift above LIFT_HEIGHT: (foot, time [s], sole position [m])."""
    steps = []
    for foot, track in _sole_tracks(d).items():
        lifted = False
        for i in range(d.t.size):
            z = track[i, 2]
            if not lifted and z > LIFT_HEIGHT:
                lifted = True
            elif lifted and z < LAND_HEIGHT:
                lifted = False
                steps.append((foot, float(d.t[i]), track[i].copy()))
    return sorted(steps, key=lambda s: s[1])


def _window(arg: str, default: tuple[float, float]) -> tuple[float, float]:
    if not arg:
        return default
    lo, _, hi = arg.partition("-")
    return float(lo), float(hi)


def _advancing(d: LogData) -> list[tuple[str, float, np.ndarray]]:
    """Touchdowns (from contact forces) ≥ ADVANCE ahead of the other foot, one per placement.

    A touchdown counts when the foot lands at least ADVANCE ahead of the other foot and
    at least MOVED from its previously counted placement (so load chatter is not a step).
    """
    tracks = _sole_tracks(d)
    last: dict[str, np.ndarray] = {}
    out = []
    for step in d.footsteps:
        foot = step.foot.split("_")[0]
        pos = np.asarray(step.position)
        other = tracks["right" if foot == "left" else "left"]
        i = min(int(np.searchsorted(d.t, step.t)), d.t.size - 1)
        moved = foot not in last or np.linalg.norm(pos[:2] - last[foot][:2]) >= MOVED
        if moved and pos[0] - other[i, 0] >= ADVANCE:
            out.append((foot, step.t, pos))
            last[foot] = pos
    return out


@metric("lifted_steps", "touchdowns after the sole rose > 1 cm (arg 't0-t1': window [s])")
def _lifted_steps(d: LogData, arg: str) -> float:
    t0, t1 = _window(arg, (-math.inf, math.inf))
    return float(sum(1 for _, t, _ in lifted_steps(d) if t0 <= t <= t1))


@metric("advancing_steps", "touchdowns landing ≥ 5 cm ahead of the other foot (new placements)")
def _advancing_steps(d: LogData, arg: str) -> float:
    return float(len(_advancing(d)))


@metric(
    "walk_speed",
    "pelvis x speed from the first lift-off to the last advancing touchdown [m/s]",
)
def _walk_speed(d: LogData, arg: str) -> float:
    adv = _advancing(d)
    if not adv:
        return math.nan
    tracks = _sole_tracks(d)
    lift = min(
        float(d.t[np.argmax(tracks[f][:, 2] > LIFT_HEIGHT)])
        for f in FEET
        if np.any(tracks[f][:, 2] > LIFT_HEIGHT)
    )
    t_end = adv[-1][1]
    i0, i1 = np.searchsorted(d.t, [lift, t_end])
    return float((d.qpos[i1, 0] - d.qpos[i0, 0]) / (d.t[i1] - d.t[i0]))


def _visits(d: LogData, phase: float) -> list[tuple[float, float]]:
    """(start, end) of every complete visit of an E-FSM phase [s]."""
    t, v = d.signal("efsm_phase")
    out, start = [], None
    for ti, vi in zip(t, v, strict=True):
        if vi == phase and start is None:
            start = ti
        elif vi != phase and start is not None:
            out.append((start, ti))
            start = None
    return out


@metric(
    "phase_duration_spread",
    "std/mean of the durations of complete visits of an E-FSM phase (arg SSD|SSA|DS) [-]",
)
def _phase_duration_spread(d: LogData, arg: str) -> float:
    visits = _visits(d, PHASES[arg or "SSA"])[1:]  # the first footstep starts from rest
    durations = np.array([b - a for a, b in visits])
    if durations.size < 2:
        return math.nan
    return float(np.std(durations) / np.mean(durations))


@metric("first_ssd_duration", "duration of the first SSD (after the first DS) [s]")
def _first_ssd_duration(d: LogData, arg: str) -> float:
    visits = _visits(d, PHASES["SSD"])
    return visits[0][1] - visits[0][0] if visits else math.nan


def _single_support(d: LogData) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t, phase = d.signal("efsm_phase")
    _, com_w = d.signal("com_w")
    _, xp = d.signal("xp_des_w")
    ss = phase < PHASES["DS"]
    return com_w[ss, 0], xp[ss], t[ss]


@metric("min_com_x_ss", "smallest CoM x in O_w in SSD/SSA (< 0: past the support centre) [m]")
def _min_com_x_ss(d: LogData, arg: str) -> float:
    x_m, _, _ = _single_support(d)
    return float(np.min(x_m)) if x_m.size else math.nan


@metric(
    "eq3_margin",
    "smallest x_m − x_p^des in SSD/SSA (Eq. 3 keeps x_p^des ≥ ζ behind the CoM) [m]",
)
def _eq3_margin(d: LogData, arg: str) -> float:
    x_m, xp, _ = _single_support(d)
    return float(np.min(x_m - xp)) if x_m.size else math.nan


@metric("max_torque_jump", "largest tick-to-tick change of a reference torque (arg 't0-t1') [Nm]")
def _max_torque_jump(d: LogData, arg: str) -> float:
    t, tau = d.signal("tau_ref")
    if t.size < 2:
        return math.nan
    t0, t1 = _window(arg, (-math.inf, math.inf))
    keep = (t[1:] >= t0) & (t[1:] <= t1)
    jumps = np.max(np.abs(np.diff(tau, axis=0)), axis=1)[keep]
    return float(np.max(jumps)) if jumps.size else math.nan


@metric(
    "cop_error_p90",
    "90th percentile of |expected − measured CoP| while walking (Fig. 15) [m]",
)
def _cop_error_p90(d: LogData, arg: str) -> float:
    _, exp = d.signal("cop_exp_world")
    _, meas = d.signal("cop_meas_world")
    _, valid = d.signal("cop_meas_valid")
    if not valid.size:
        return math.nan
    err = np.linalg.norm(exp - meas, axis=1)[valid > 0]
    return float(np.percentile(err, 90)) if err.size else math.nan


def _first_obstacle_contact(d: LogData, pattern: str) -> float:
    force = np.linalg.norm(d.contact_wrench(pattern)[:, :3], axis=1)
    hit = np.nonzero(force > OBSTACLE_CONTACT_FORCE)[0]
    return float(d.contact_t[hit[0]]) if hit.size else math.nan


@metric(
    "steps_after_contact",
    "lifted steps after the first contact on pairs 'body/geom' = arg (e.g. right_foot/obstacle*)",
)
def _steps_after_contact(d: LogData, arg: str) -> float:
    t_hit = _first_obstacle_contact(d, arg or "right_foot/obstacle*")
    if math.isnan(t_hit):
        return math.nan
    return float(sum(1 for _, t, _ in lifted_steps(d) if t > t_hit))


@metric("max_sole_x", "largest x of a sole centre (arg left|right) over the run [m]")
def _max_sole_x(d: LogData, arg: str) -> float:
    return float(np.max(_sole_tracks(d)[arg or "right"][:, 0]))


def _push_window(d: LogData) -> tuple[float, float]:
    on = [e["t"] for e in d.events if e.get("kind") == "disturbance_on"]
    off = [e["t"] for e in d.events if e.get("kind") == "disturbance_off"]
    if not on:
        return math.nan, math.nan
    return float(on[0]), float(off[0]) if off else float(d.t[-1])


def _ds_entries(d: LogData) -> list[float]:
    return [e["t"] for e in d.events if e.get("kind") == "fsm" and e.get("to") == "DS"]


@metric("ds_entries_during_push", "E-FSM transitions into DS while the push acts")
def _ds_entries_during_push(d: LogData, arg: str) -> float:
    t0, t1 = _push_window(d)
    if math.isnan(t0):
        return math.nan
    return float(sum(1 for t in _ds_entries(d) if t0 < t <= t1))


@metric("ds_delay_after_push", "time from the push's release to the next DS [s]")
def _ds_delay_after_push(d: LogData, arg: str) -> float:
    _, t1 = _push_window(d)
    later = [t for t in _ds_entries(d) if t > t1]
    return float(later[0] - t1) if later else math.inf


@metric("steps_after_push", "lifted steps after the push's release")
def _steps_after_push(d: LogData, arg: str) -> float:
    _, t1 = _push_window(d)
    if math.isnan(t1):
        return math.nan
    return float(sum(1 for _, t, _ in lifted_steps(d) if t > t1))


@metric(
    "push_com_speed",
    "mean |CoM x-velocity in O_w| over the last second of the push (Fig. 12d) [m/s]",
)
def _push_com_speed(d: LogData, arg: str) -> float:
    t0, t1 = _push_window(d)
    t, vel = d.signal("com_vel_w")
    keep = (t >= max(t0, t1 - 1.0)) & (t <= t1)
    return float(np.mean(np.abs(vel[keep, 0]))) if np.any(keep) else math.nan


@metric(
    "peak_swing_obstacle_force",
    "largest obstacle contact force on a foot while it is the E-FSM swing foot (arg left|right) [N]",
)
def _peak_swing_obstacle_force(d: LogData, arg: str) -> float:
    foot = arg or "right"
    force = np.linalg.norm(d.contact_wrench(f"{foot}_foot/obstacle*")[:, :3], axis=1)
    t, swing = d.signal("swing_foot")
    if not t.size or not force.size:
        return math.nan
    # swing_foot is 1 while the right foot swings, −1 for the left, 0 in DS.
    code = 1.0 if foot == "right" else -1.0
    i = np.clip(np.searchsorted(t, d.contact_t), 0, t.size - 1)
    swinging = swing[i] == code
    return float(np.max(force[swinging])) if np.any(swinging) else 0.0


#: A swing foot counts as blocked once its sole centre has moved less than this [m/s]...
BLOCKED_SPEED = 0.02
#: ... for this long [s] while touching the obstacle (the impact transient is over).
BLOCKED_TIME = 0.05


@metric(
    "blocked_swing_obstacle_force",
    "largest obstacle contact force on the E-FSM swing foot (arg left|right) once it is "
    "completely blocked: touching the obstacle and its sole slower than BLOCKED_SPEED for "
    "BLOCKED_TIME (§VI-B; the impact transient before that is left out) [N]",
)
def _blocked_swing_obstacle_force(d: LogData, arg: str) -> float:
    foot = arg or "right"
    force = np.linalg.norm(d.contact_wrench(f"{foot}_foot/obstacle*")[:, :3], axis=1)
    t_sig, swing = d.signal("swing_foot")
    if not t_sig.size or not force.size:
        return math.nan
    track = _sole_tracks(d)[foot]
    speed = np.r_[0.0, np.linalg.norm(np.diff(track[:, :2], axis=0), axis=1) / np.diff(d.t)]
    code = 1.0 if foot == "right" else -1.0
    i_sig = np.clip(np.searchsorted(t_sig, d.contact_t), 0, t_sig.size - 1)
    i_st = np.clip(np.searchsorted(d.t, d.contact_t), 0, d.t.size - 1)
    # Contact gaps of a few ticks (the foot chattering on the face) do not end a blockage.
    touching = force > OBSTACLE_CONTACT_FORCE
    still = (speed[i_st] < BLOCKED_SPEED) & (swing[i_sig] == code)
    best, since = 0.0, math.nan
    for k in range(force.size):
        if still[k] and (touching[k] or not math.isnan(since)):
            since = d.contact_t[k] if math.isnan(since) else since
            if d.contact_t[k] - since >= BLOCKED_TIME:
                best = max(best, float(force[k]))
        else:
            since = math.nan
    return best
