"""Metrics specific to the jo_oh reproduction (computed from the log alone).

Paper III (Jo & Oh, §IV): the right foot meets an obstacle the controller does not know
about, steps on it, and the next step returns to the floor. These metrics read which world
geom carries a foot (``/sim/contacts``) and the foot's motion (``/sim/state``).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from walkrepro.metrics import GRAVITY, TOUCHDOWN_WEIGHT_FRACTION, LogData, metric
from walkrepro.world import FLOOR_NAME

#: World geoms that are obstacles (spec: names start with "obstacle").
OBSTACLE_GLOB = "obstacle*"
#: A foot touches an obstacle when the obstacle pushes on it with more than this [N]
#: (the paper's 10 N contact threshold, §IV).
CONTACT_FORCE = 10.0
#: The swing foot's z velocity has settled once it stays below this [m/s].
SETTLED_SPEED = 0.05
#: Settling is judged within this time after the first obstacle contact [s] (shorter
#: than the 0.7 s step, so the foot's next lift-off is outside it).
SETTLE_WINDOW = 0.6


def _foot_arg(arg: str) -> str:
    return arg or "right_foot"


def _obstacle_force(d: LogData, foot: str) -> np.ndarray:
    """Norm of the obstacles' contact force on a foot at each contact message [N]."""
    return np.linalg.norm(d.contact_wrench(f"{foot}/{OBSTACLE_GLOB}")[:, :3], axis=1)


def _floor_force(d: LogData, foot: str) -> np.ndarray:
    """Vertical force of the floor on a foot at each contact message [N]."""
    return d.contact_wrench(f"{foot}/{FLOOR_NAME}")[:, 2]


@metric(
    "stepped_on_off",
    "1 if the foot (arg, default right_foot) landed on an obstacle* and a later touchdown "
    "of it was on the floor alone, without a fall; else 0",
)
def _stepped_on_off(d: LogData, arg: str) -> float:
    foot = _foot_arg(arg)
    if d.outcome == "fell" or not d.contacts:
        return 0.0
    on_obstacle = _obstacle_force(d, foot)
    on_floor = _floor_force(d, foot)
    load = TOUCHDOWN_WEIGHT_FRACTION * d.robot_mass * GRAVITY
    touchdowns = [s.t for s in d.footsteps if s.foot == foot]
    stepped_on = None
    for t in touchdowns:
        # Judge each touchdown by what carries the foot a little after it (50 ms).
        i = min(int(np.searchsorted(d.contact_t, t + 0.05)), d.contact_t.size - 1)
        if stepped_on is None and on_obstacle[i] > load:
            stepped_on = t
        elif stepped_on is not None and on_floor[i] > load and on_obstacle[i] < CONTACT_FORCE:
            return 1.0
    return 0.0


@metric(
    "time_after_last_step",
    "simulated time after the last touchdown [s] (the issue asks for >= 2 s without a fall)",
)
def _time_after_last_step(d: LogData, arg: str) -> float:
    if not d.footsteps or not d.t.size:
        return math.nan
    falls = [e["t"] for e in d.events if e.get("kind") == "fall"]
    end = float(falls[0]) if falls else float(d.t[-1])
    return end - d.footsteps[-1].t


def _first_obstacle_contact(d: LogData, foot: str) -> int | None:
    """Index of the first contact message where an obstacle pushes the foot (> 10 N)."""
    idx = np.flatnonzero(_obstacle_force(d, foot) > CONTACT_FORCE)
    return int(idx[0]) if idx.size else None


def sole_velocity_z(d: LogData, foot: str, i0: int, i1: int) -> tuple[np.ndarray, np.ndarray]:
    """Times [s] and world z velocity [m/s] of a foot's sole centre for states i0..i1."""
    model = d.model
    data = mujoco.MjData(model)
    side = foot.split("_")[0]
    site = model.site(f"{side}_sole").id
    vel = np.zeros(6)
    out = np.zeros(i1 - i0)
    for k, i in enumerate(range(i0, i1)):
        data.qpos[:] = d.qpos[i]
        data.qvel[:] = d.qvel[i]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_comVel(model, data)
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_SITE, site, vel, 0)
        out[k] = vel[5]
    return d.t[i0:i1], out


@metric(
    "swing_z_settling_time",
    "time from the foot's (arg, default right_foot) first obstacle contact until its sole "
    f"z velocity stays below {SETTLED_SPEED} m/s, within {SETTLE_WINDOW} s [s] (Fig. 5b)",
)
def _swing_z_settling_time(d: LogData, arg: str) -> float:
    foot = _foot_arg(arg)
    c = _first_obstacle_contact(d, foot)
    if c is None:
        return math.nan
    t_contact = float(d.contact_t[c])
    t_end = min(t_contact + SETTLE_WINDOW, float(d.t[-1]))
    i0, i1 = np.searchsorted(d.t, [t_contact, t_end])
    if i1 <= i0:
        return math.nan
    t, vz = sole_velocity_z(d, foot, int(i0), int(i1))
    moving = np.flatnonzero(np.abs(vz) >= SETTLED_SPEED)
    if not moving.size:
        return 0.0
    return float(t[moving[-1]] - t_contact)


@metric(
    "peak_landing_force",
    "largest contact force norm on the foot (arg, default right_foot) within 0.3 s of its "
    "first obstacle contact [N] (Fig. 4)",
)
def _peak_landing_force(d: LogData, arg: str) -> float:
    foot = _foot_arg(arg)
    c = _first_obstacle_contact(d, foot)
    if c is None:
        return math.nan
    t0 = d.contact_t[c]
    window = (d.contact_t >= t0) & (d.contact_t <= t0 + 0.3)
    force = np.linalg.norm(d.contact_wrench(f"{foot}/*")[window, :3], axis=1)
    return float(force.max()) if force.size else math.nan
