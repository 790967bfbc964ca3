"""Metrics specific to the jo_oh reproduction (computed from the log alone).

Paper III (Jo & Oh, §IV): the right foot meets an obstacle the controller does not know
about, steps on it, and the next step returns to the floor. These metrics read which world
geom carries a foot (``/sim/contacts``) and the foot's motion (``/sim/state``).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from walkrepro.evaluation.metrics import (
    GRAVITY,
    TOUCHDOWN_WEIGHT_FRACTION,
    LogData,
    NotMeasurable,
    choice_check,
    metric,
    qualified_check,
)
from walkrepro.sim.world import FLOOR_NAME

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
#: The landing peak of Fig. 4 is looked for within this time after the first contact [s].
LANDING_WINDOW = 0.3


def _foot_arg(arg: str) -> str:
    return arg or "right_foot"


def _obstacle_force(d: LogData, foot: str) -> np.ndarray:
    """Norm of the obstacles' contact force on a foot at each contact message [N]."""
    return np.linalg.norm(d.contact_wrench(f"{foot}/{OBSTACLE_GLOB}")[:, :3], axis=1)


def _floor_force(d: LogData, foot: str) -> np.ndarray:
    """Vertical force of the floor on a foot at each contact message [N]."""
    return d.contact_wrench(f"{foot}/{FLOOR_NAME}")[:, 2]


#: A touchdown is judged by what carries the foot this long after it [s] (the landing
#: transient of Fig. 4 is over by then).
JUDGE_DELAY = 0.05


@metric(
    "stepped_on_off",
    "1 if the foot (arg, default right_foot) stepped onto an obstacle* and a later step of "
    "it landed on the floor alone, without a fall; else 0",
    arg=choice_check("left_foot", "right_foot"),
)
def _stepped_on_off(d: LogData, arg: str) -> float:
    """Whole run, with falls measured: the claim of the no-impedance specs is "does not
    overcome", so a fall (before or after stepping off) is a measured 0, not a missing value.
    A run interrupted (or broken) before stepping off is not measurable; one that stepped
    off before it stopped is a measured 1.

    Steps are :attr:`LogData.footsteps` (the sole cleared both the floor it left and the
    block it lands on by 1 cm), each judged by the contact forces JUDGE_DELAY after it.
    """
    foot = _foot_arg(arg)
    if d.outcome == "fell":
        return 0.0
    d.require_states()
    d.require_contacts()
    if stepped_on_off(d, foot):
        return 1.0
    if d.outcome != "complete":
        raise NotMeasurable(f"{d.stop_reason()}, before the foot stepped onto and off the obstacle")
    return 0.0


def stepped_on_off(d: LogData, foot: str) -> bool:
    """Whether a step of ``foot`` landed on an obstacle and a later one on the floor alone."""
    on_obstacle = _obstacle_force(d, foot)
    on_floor = _floor_force(d, foot)
    load = TOUCHDOWN_WEIGHT_FRACTION * d.robot_mass * GRAVITY
    stepped_on = False
    for step in d.footsteps:
        if step.foot != foot:
            continue
        i = min(int(np.searchsorted(d.contact_t, step.t + JUDGE_DELAY)), d.contact_t.size - 1)
        if not stepped_on and on_obstacle[i] > load:
            stepped_on = True
        elif stepped_on and on_floor[i] > load and on_obstacle[i] < CONTACT_FORCE:
            return True
    return False


@metric(
    "time_after_last_step",
    "simulated time after the last step's touchdown [s] (the issue asks for >= 2 s without a fall)",
)
def _time_after_last_step(d: LogData, arg: str) -> float:
    """Completed: "stands ≥ 2 s after the last step without a fall" needs a completed run;
    a fall or an early stop makes it not measurable."""
    d.require_states()
    d.require_contacts()
    d.require_completed("the standing time after the last step was judged")
    if not d.footsteps:
        raise NotMeasurable("no step found")
    return d.data_end - d.footsteps[-1].t


def _first_obstacle_contact(d: LogData, foot: str) -> int | None:
    """Index of the first contact message where an obstacle pushes the foot (> 10 N)."""
    d.require_contacts()
    idx = np.flatnonzero(_obstacle_force(d, foot) > CONTACT_FORCE)
    return int(idx[0]) if idx.size else None


def sole_site_motion(
    d: LogData, foot: str, i0: int, i1: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times [s], rotation matrices R (i1 − i0, 3, 3) in O_w and spatial velocities
    (i1 − i0, 6) [rad/s, m/s] (angular, then linear, in O_w) of a foot's sole site for states
    i0..i1, from the logged state (MuJoCo's forward kinematics)."""
    model = d.model
    data = mujoco.MjData(model)
    site = model.site(f"{foot.split('_')[0]}_sole").id
    vel = np.zeros(6)
    rot = np.zeros((i1 - i0, 3, 3))
    out = np.zeros((i1 - i0, 6))
    for k, i in enumerate(range(i0, i1)):
        data.qpos[:] = d.qpos[i]
        data.qvel[:] = d.qvel[i]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_comVel(model, data)
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_SITE, site, vel, 0)
        rot[k] = data.site_xmat[site].reshape(3, 3)
        out[k] = vel
    return d.t[i0:i1], rot, out


def sole_velocity_z(d: LogData, foot: str, i0: int, i1: int) -> tuple[np.ndarray, np.ndarray]:
    """Times [s] and world z velocity [m/s] of a foot's sole centre for states i0..i1."""
    t, _, vel = sole_site_motion(d, foot, i0, i1)
    return t, vel[:, 5]


@metric(
    "swing_z_settling_time",
    "time from the foot's (arg, default right_foot) first obstacle contact until its sole "
    f"z velocity stays below {SETTLED_SPEED} m/s, within {SETTLE_WINDOW} s [s] (Fig. 5b)",
    arg=choice_check("left_foot", "right_foot"),
)
def _swing_z_settling_time(d: LogData, arg: str) -> float:
    """Window: the data must cover SETTLE_WINDOW after the first obstacle contact (a fall
    within it makes the metric not measurable). Sole velocity from the logged state."""
    foot = _foot_arg(arg)
    t_contact = _contact_time(d, foot)
    t_end = t_contact + SETTLE_WINDOW
    d.require_until(t_end, "the settling window after the obstacle contact ended")
    i0, i1 = np.searchsorted(d.t, [t_contact, t_end])
    if i1 <= i0:
        raise NotMeasurable("no state logged in the settling window")
    t, vz = sole_velocity_z(d, foot, int(i0), int(i1))
    return settling_time(t, vz, t_contact)


def settling_time(
    t: np.ndarray, value: np.ndarray, t_contact: float, bound: float = SETTLED_SPEED
) -> float:
    """Time from ``t_contact`` until |value| stays below ``bound`` (default SETTLED_SPEED
    [m/s]; 0 if it always is) [s]."""
    moving = np.flatnonzero(np.abs(value) >= bound)
    if not moving.size:
        return 0.0
    return float(t[moving[-1]] - t_contact)


#: The sole's tilt has settled once it stays within this of its value at the end of the
#: settling window [rad]: 1°, the smallest tilt §IV-B names ("a small tilting angle (< 1°)").
SETTLED_TILT = math.radians(1.0)
#: Axes of the sole's tilt (world frame): x, the roll of Fig. 6; y, the pitch of Fig. 7.
TILT_AXES = ("x", "y")

_foot_axis_arg = qualified_check(
    choice_check("left_foot", "right_foot"), choice_check(*TILT_AXES, required=True)
)


def _foot_axis(arg: str) -> tuple[str, int]:
    """``<foot>@<axis>`` (default right_foot@x) as the foot and the axis index (0 x, 1 y)."""
    foot, _, axis = (arg or "right_foot@x").partition("@")
    return foot or "right_foot", TILT_AXES.index(axis or "x")


def sole_half_extent(model: mujoco.MjModel, foot: str, axis: int) -> float:
    """Half the sole's extent across the tilt axis [m]: the distance from the sole's centre
    to its edge that a rotation about ``axis`` (0 x, 1 y) moves, from the foot body's largest
    box geom (its half-width for a roll about x, its half-length for a pitch about y)."""
    body = model.body(foot).id
    boxes = [
        model.geom_size[g]
        for g in range(model.ngeom)
        if model.geom_bodyid[g] == body and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX
    ]
    if not boxes:
        raise NotMeasurable(f"{foot} has no box geom to take the sole's size from")
    return float(max(size[1 - axis] for size in boxes))


def sole_tilt(d: LogData, foot: str, i0: int, i1: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times [s], the sole's tilt angles [rad] and angular velocities [rad/s] about the world
    x and y axes for states i0..i1, each (i1 − i0, 2).

    The tilt about x is the roll atan2(R_zy, R_zz), about y the pitch atan2(−R_zx,
    √(R_zy² + R_zz²)) of the sole site's rotation R in O_w (Fig. 6(a), 7(a)); the angular
    velocity is the site's, in O_w (Fig. 6(b), 7(b)).
    """
    t, rot, vel = sole_site_motion(d, foot, i0, i1)
    angle = np.stack(
        (
            np.arctan2(rot[:, 2, 1], rot[:, 2, 2]),
            np.arctan2(-rot[:, 2, 0], np.hypot(rot[:, 2, 1], rot[:, 2, 2])),
        ),
        axis=1,
    )
    return t, angle, vel[:, :2].copy()


def _tilt_window(d: LogData, foot: str) -> tuple[float, int, int]:
    """The first obstacle contact [s] and the state indices of the settling window after it."""
    t_contact = _contact_time(d, foot)
    d.require_until(
        t_contact + SETTLE_WINDOW, "the settling window after the obstacle contact ended"
    )
    i0, i1 = np.searchsorted(d.t, [t_contact, t_contact + SETTLE_WINDOW])
    if i1 <= i0:
        raise NotMeasurable("no state logged in the settling window")
    return t_contact, int(i0), int(i1)


@metric(
    "sole_rate_settling_time",
    "time from the foot's first obstacle contact until the sole's angular velocity about the "
    "world axis (arg <foot>@<axis>, default right_foot@x) stays below the rate that moves the "
    f"sole's edge at {SETTLED_SPEED} m/s, within {SETTLE_WINDOW} s [s] (Fig. 6(b), 7(b))",
    arg=_foot_axis_arg,
)
def _sole_rate_settling_time(d: LogData, arg: str) -> float:
    """Window: SETTLE_WINDOW after the first obstacle contact (> 10 N), which the data must
    cover (a fall within it makes the metric not measurable). The rate bound is SETTLED_SPEED
    (the z velocity's, Fig. 5(b)) at the sole's edge: SETTLED_SPEED / the sole's half extent
    across the axis (:func:`sole_half_extent`), e.g. 0.05 / 0.065 = 0.77 rad/s for a roll."""
    foot, axis = _foot_axis(arg)
    t_contact, i0, i1 = _tilt_window(d, foot)
    t, _, rate = sole_tilt(d, foot, i0, i1)
    bound = SETTLED_SPEED / sole_half_extent(d.model, foot, axis)
    return settling_time(t, rate[:, axis], t_contact, bound)


@metric(
    "sole_tilt_settling_time",
    "time from the foot's first obstacle contact until the sole's tilt about the world axis "
    "(arg <foot>@<axis>, default right_foot@x) stays within 1° of its value at the end of the "
    f"{SETTLE_WINDOW} s window [s] (Fig. 6(a), 7(a))",
    arg=_foot_axis_arg,
)
def _sole_tilt_settling_time(d: LogData, arg: str) -> float:
    """Window: SETTLE_WINDOW after the first obstacle contact (> 10 N), which the data must
    cover; it ends before the foot's next lift-off (a 0.7 s step), so the tilt it settles to
    is the one the foot stands at on the obstacle."""
    foot, axis = _foot_axis(arg)
    t_contact, i0, i1 = _tilt_window(d, foot)
    t, angle, _ = sole_tilt(d, foot, i0, i1)
    return settling_time(t, angle[:, axis] - angle[-1, axis], t_contact, SETTLED_TILT)


def _contact_time(d: LogData, foot: str) -> float:
    c = _first_obstacle_contact(d, foot)
    if c is None:
        raise NotMeasurable(f"no obstacle pushed {foot} with > {CONTACT_FORCE} N{d.stopped_note()}")
    return float(d.contact_t[c])


@metric(
    "peak_landing_force",
    "largest contact force norm on the foot (arg, default right_foot) within 0.3 s of its "
    "first obstacle contact [N] (Fig. 4)",
    arg=choice_check("left_foot", "right_foot"),
)
def _peak_landing_force(d: LogData, arg: str) -> float:
    """Window: the data must cover LANDING_WINDOW after the first obstacle contact (a fall
    within it makes the metric not measurable)."""
    foot = _foot_arg(arg)
    t0 = _contact_time(d, foot)
    d.require_until(t0 + LANDING_WINDOW, "the landing window after the obstacle contact ended")
    window = (d.contact_t >= t0) & (d.contact_t <= t0 + LANDING_WINDOW)
    force = np.linalg.norm(d.contact_wrench(f"{foot}/*")[window, :3], axis=1)
    return float(force.max())


#: The swing signals' side index (``swing_foot`` signal: 0 left, 1 right, −1 double support).
_SIDE_INDEX = {"left_foot": 0.0, "right_foot": 1.0}


@metric(
    "swing_height_error",
    "largest |z_d − z| of the foot's (arg, default right_foot) sole while it swings, the "
    "planned height z_d against the measured one [m] (flat-ground tracking, §II)",
    arg=choice_check("left_foot", "right_foot"),
)
def _swing_height_error(d: LogData, arg: str) -> float:
    """Whole logged time before any fall, from the controller's signals: the plan's
    ``<side>_z_d`` and the sole's ``<side>_z`` while ``swing_foot`` names the foot. On flat
    ground this is the tracking the swing gains buy (§II: "proper control gains to keep
    tracking"); on an obstacle it includes the block's push."""
    foot = _foot_arg(arg)
    side = foot.split("_")[0]
    t, swing = d.require_signal("swing_foot")
    _, z = d.require_signal(f"{side}_z")
    _, z_d = d.require_signal(f"{side}_z_d")
    swinging = swing == _SIDE_INDEX[foot]
    if not swinging.any():
        raise NotMeasurable(f"{foot} never swung{d.stopped_note()}")
    return float(np.max(np.abs(z_d[swinging] - z[swinging])))


@metric(
    "obstacle_rehits",
    "times the obstacle's push on the foot (arg, default right_foot) rises through 10 N again "
    'within 0.3 s of its first contact (Fig. 5c: the foot "continuously hits the obstacle")',
    arg=choice_check("left_foot", "right_foot"),
)
def _obstacle_rehits(d: LogData, arg: str) -> float:
    """Window: the data must cover LANDING_WINDOW after the first obstacle contact. Counts
    the contact messages (every control tick) where the force crosses CONTACT_FORCE upwards,
    the first contact excluded."""
    foot = _foot_arg(arg)
    t0 = _contact_time(d, foot)
    d.require_until(t0 + LANDING_WINDOW, "the landing window after the obstacle contact ended")
    window = (d.contact_t >= t0) & (d.contact_t <= t0 + LANDING_WINDOW)
    on = _obstacle_force(d, foot)[window] > CONTACT_FORCE
    return float(np.sum(on[1:] & ~on[:-1]))


@metric(
    "obstacles_crossed",
    "obstacles* that a foot stepped onto and off again (its next step landed on the floor "
    "alone), before any fall (the video's course of several unknown obstacles, §IV)",
)
def _obstacles_crossed(d: LogData, arg: str) -> float:
    """Whole logged time before any fall (a fall ends the count: what was crossed before it
    is measured). Steps are :attr:`LogData.footsteps`, each judged JUDGE_DELAY after its
    touchdown, as for ``stepped_on_off``."""
    d.require_states()
    d.require_contacts()
    load = TOUCHDOWN_WEIGHT_FRACTION * d.robot_mass * GRAVITY
    names = [o.name for o in d.spec.world.obstacles]
    crossed: set[str] = set()
    for foot in ("left_foot", "right_foot"):
        on = {n: np.linalg.norm(d.contact_wrench(f"{foot}/{n}")[:, :3], axis=1) for n in names}
        any_obstacle = _obstacle_force(d, foot)
        floor = _floor_force(d, foot)
        standing_on: str | None = None
        for step in d.footsteps:
            if step.foot != foot:
                continue
            i = min(int(np.searchsorted(d.contact_t, step.t + JUDGE_DELAY)), d.contact_t.size - 1)
            carrying = [n for n in names if on[n][i] > load]
            if standing_on and floor[i] > load and any_obstacle[i] < CONTACT_FORCE:
                crossed.add(standing_on)
            standing_on = carrying[0] if carrying else None
    return float(len(crossed))


def _other_foot(foot: str) -> str:
    return "right_foot" if foot == "left_foot" else "left_foot"


@metric(
    "support_peak_force",
    "largest contact force norm on the foot (arg, default left_foot) within 0.3 s of the "
    'other foot\'s first obstacle contact [N] (Fig. 4: "interference from the left leg")',
    arg=choice_check("left_foot", "right_foot"),
)
def _support_peak_force(d: LogData, arg: str) -> float:
    """Window: LANDING_WINDOW after the other (landing) foot's first obstacle contact, as for
    ``peak_landing_force``; the force is the support foot's whole contact force, whatever
    carries it (a fall within the window makes the metric not measurable)."""
    foot = arg or "left_foot"
    t0 = _contact_time(d, _other_foot(foot))
    d.require_until(t0 + LANDING_WINDOW, "the landing window after the obstacle contact ended")
    window = (d.contact_t >= t0) & (d.contact_t <= t0 + LANDING_WINDOW)
    force = np.linalg.norm(d.contact_wrench(f"{foot}/*")[window, :3], axis=1)
    return float(force.max()) if force.size else 0.0


def _swing_after_contact(d: LogData, foot: str) -> tuple[np.ndarray, np.ndarray, float]:
    """The ``swing_foot`` signal's times and values, and the foot's first obstacle contact
    time [s]; the data must cover the end of the swing in which that contact happened."""
    t0 = _contact_time(d, foot)
    t, swing = d.require_signal("swing_foot")
    after = (t >= t0) & (swing != _SIDE_INDEX[foot])
    if not after.any():
        d.require_until(math.inf, f"{foot}'s swing onto the obstacle ended")
        raise NotMeasurable(f"{foot}'s swing onto the obstacle did not end{d.stopped_note()}")
    return t, swing, t0


@metric(
    "swing_z_error_after_contact",
    "largest |z_m − z| of the foot's (arg, default right_foot) sole from its first obstacle "
    "contact to the end of that swing: the reference it tracks (modified by the impedance, or "
    "the plan without it) against the measured height [m] (Fig. 5a)",
    arg=choice_check("left_foot", "right_foot"),
)
def _swing_z_error_after_contact(d: LogData, arg: str) -> float:
    """Window: from the first obstacle contact (> 10 N) until ``swing_foot`` stops naming the
    foot (its support begins); the data must cover it. From the controller's signals: the
    tracked reference ``<side>_z_m`` (Eq. 3's x_m, equal to the plan's z_d without impedance)
    and the sole's ``<side>_z``."""
    foot = _foot_arg(arg)
    side = foot.split("_")[0]
    t, swing, t0 = _swing_after_contact(d, foot)
    _, z = d.require_signal(f"{side}_z")
    _, z_m = d.require_signal(f"{side}_z_m")
    t_end = float(t[(t >= t0) & (swing != _SIDE_INDEX[foot])][0])
    window = (t >= t0) & (t < t_end)
    if not window.any():
        raise NotMeasurable(f"no signal logged between the obstacle contact and {foot}'s support")
    return float(np.max(np.abs(z_m[window] - z[window])))


@metric(
    "positive_work_obstacle_step",
    "the actuators' positive mechanical work Σ_i Σ_t max(0, τ_i q̇_i) Δt over the step onto "
    "the obstacle: from the start of the foot's (arg, default right_foot) swing that first "
    "touches an obstacle* to the start of the next swing [J] (§IV-A: energy consumption)",
    arg=choice_check("left_foot", "right_foot"),
)
def _positive_work_obstacle_step(d: LogData, arg: str) -> float:
    """Window: the swing of the foot in which it first touches an obstacle (> 10 N), from its
    start (``swing_foot`` turns to the foot) to the next swing's start (``swing_foot`` turns to
    the other foot), so the double support after the landing is in it; the data must cover it.
    τ is each actuator's logged ``ctrl`` times its gear (torque-controlled motors) and q̇ its
    joint's logged velocity, at every logged state; each actuator's power counts only where it
    is positive (work done by the motor; none is recovered)."""
    foot = _foot_arg(arg)
    t_sig, swing, t0 = _swing_after_contact(d, foot)
    mine, other = _SIDE_INDEX[foot], _SIDE_INDEX[_other_foot(foot)]
    before = np.flatnonzero((t_sig <= t0) & (swing != mine))
    t_start = float(t_sig[before[-1] + 1]) if before.size else float(t_sig[0])
    nxt = np.flatnonzero((t_sig > t0) & (swing == other))
    if not nxt.size:
        raise NotMeasurable(
            f"the next swing after {foot}'s obstacle step did not start{d.stopped_note()}"
        )
    t_end = float(t_sig[nxt[0]])
    model = d.model
    if model.nu == 0 or np.any(model.actuator_trntype != mujoco.mjtTrn.mjTRN_JOINT):
        raise NotMeasurable("the actuators are not all joint actuators")
    if np.any(model.actuator_gaintype != mujoco.mjtGain.mjGAIN_FIXED) or np.any(
        model.actuator_biastype != mujoco.mjtBias.mjBIAS_NONE
    ):
        raise NotMeasurable("ctrl is not a torque for these actuators (position servos)")
    dofs = model.jnt_dofadr[model.actuator_trnid[:, 0]]
    gain = model.actuator_gainprm[:, 0] * model.actuator_gear[:, 0]
    t_ctrl, ctrl = d.inputs_ctrl
    i0, i1 = np.searchsorted(d.t, [t_start, t_end])
    if i1 - i0 < 2 or t_ctrl.size == 0:
        raise NotMeasurable("no state logged over the obstacle step")
    t = d.t[i0:i1]
    # The ctrl in force at each logged state (zero-order hold of the physics steps' inputs).
    k = np.clip(np.searchsorted(t_ctrl, t, side="right") - 1, 0, t_ctrl.size - 1)
    power = gain * ctrl[k] * d.qvel[i0:i1][:, dofs]  # [W] per actuator
    dt = np.diff(t, append=t_end)
    return float(np.sum(np.maximum(power, 0.0) * dt[:, None]))
