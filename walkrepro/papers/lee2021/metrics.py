"""Metrics specific to the lee2021 reproduction (computed from the log alone).

Paper I (Lee et al. 2021): the E-FSM controller logs ``efsm_phase`` (0 SSD, 1 SSA, 2 DS),
``swing_foot`` (1 right, −1 left, 0 DS), the expected and measured CoP and the reference
torques. Steps are :attr:`walkrepro.evaluation.metrics.LogData.footsteps`: touchdowns after the sole
left the floor (:func:`walkrepro.evaluation.metrics.detect_steps`), so a foot that is only unloaded
(weight shift) or slid along the floor does not count.

The CoM, the feet and the CoP these metrics judge are the simulated ones (logged state and
contact wrenches). A controller signal is read only where the paper's claim is about it
(the E-FSM's phases, which say *when* a claim applies; the reference torques of Fig. 14; the
expected CoP of Fig. 15), and each docstring says so.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import scipy.stats

from walkrepro.errors import UnknownNameError
from walkrepro.evaluation.metrics import (
    SLIDE_DISTANCE,
    Footstep,
    LogData,
    NotMeasurable,
    any_argument,
    choice_check,
    metric,
    qualified_check,
    window_arg,
    window_check,
)
from walkrepro.log import record
from walkrepro.sim.robot import leg_actuators
from walkrepro.sim.world import FLOOR_NAME

FEET = ("left", "right")
#: A step advances when the foot lands this far ahead (x) of the other foot [m]: half the
#: paper's 0.1 m step length (§VI-A), so a step in place or a closing step does not count.
ADVANCE = 0.05
#: E-FSM phases as logged in ``efsm_phase`` (Table I).
PHASES = {"SSD": 0.0, "SSA": 1.0, "DS": 2.0}
#: A foot touches an obstacle above this contact force [N].
OBSTACLE_CONTACT_FORCE = 1.0
#: Margin parameter ζ of Eq. (3) [m] when the spec does not set ``zeta`` (§VI: ζ = 0.03 m).
ZETA = 0.03
#: g of the LIPM, Eqs. (1)-(2) [m/s²] (the controller's, walkrepro/papers/lee2021/fsm.py).
GRAVITY = 9.81


def _sole_tracks(d: LogData) -> dict[str, np.ndarray]:
    """World position of each sole centre at every logged state, shape (N, 3) per side."""
    return {f: d.sole_tracks[f"{f}_foot"].centre for f in FEET}


def lifted_steps(d: LogData) -> list[tuple[str, float, np.ndarray]]:
    """Steps (``LogData.footsteps``) as (side, touchdown time [s], sole position [m])."""
    return [(s.foot.split("_")[0], s.t, np.array(s.position)) for s in d.footsteps]


def advancing_steps(d: LogData) -> list[Footstep]:
    """Steps whose foot lands ≥ ADVANCE ahead (world x) of the other foot's sole centre."""
    tracks = _sole_tracks(d)
    out = []
    for step in d.footsteps:
        other = tracks["right" if step.foot == "left_foot" else "left"]
        i = int(d.state_index(np.array([step.t]))[0])
        if step.position[0] - other[i, 0] >= ADVANCE:
            out.append(step)
    return out


def _need_walk(d: LogData) -> None:
    d.require_states(2)
    d.require_contacts()


@metric(
    "lifted_steps",
    "steps: touchdowns after the sole cleared the floor by 1 cm for 50 ms (arg 't0-t1': window [s])",
    arg=window_check,
)
def _lifted_steps(d: LogData, arg: str) -> float:
    """Pre-fall count of steps with touchdowns in the window."""
    _need_walk(d)
    t0, t1 = window_arg(arg, (-math.inf, math.inf))
    return float(sum(1 for s in d.footsteps if t0 <= s.t <= t1))


@metric(
    "advancing_steps",
    f"steps (the sole left the floor) landing ≥ {ADVANCE} m ahead of the other foot",
)
def _advancing_steps(d: LogData, arg: str) -> float:
    """Pre-fall count of :func:`advancing_steps` (§VI-A: "11 steps of 0.1 m")."""
    _need_walk(d)
    return float(len(advancing_steps(d)))


def first_swing_slide(d: LogData) -> tuple[str, float] | None:
    """The walk's first swing, when it slid instead of lifting: (foot body, advance [m]).

    Table II raises the swing foot only in SSD, and Fig. 8 shows the paper's own first SSD
    omitted (the CoM is still after the first DS, so ẋ_m ≈ 0 ends SSD at once): the first
    swing gets no raise target and may move along the floor. It is that swing when a foot's
    sole centre moved ≥ ``ADVANCE`` forward (world x, along the floor) before any foot lifted
    (the first touchdown's lift-off), ending ≥ ``ADVANCE`` ahead of the other foot. None
    when no foot did (the first swing lifted, or nothing moved).
    """
    if not d.footsteps:
        return None
    t_lift = min(s.liftoff_t for s in d.footsteps)
    i0, i1 = (int(i) for i in d.state_index(np.array([d.t[0], t_lift])))
    tracks = _sole_tracks(d)
    for side in FEET:
        other = tracks["right" if side == "left" else "left"]
        moved = tracks[side][i1, 0] - tracks[side][i0, 0]
        ahead = tracks[side][i1, 0] - other[i1, 0]
        if moved >= ADVANCE and ahead >= ADVANCE:
            return f"{side}_foot", float(moved)
    return None


@metric(
    "efsm_footsteps",
    "footsteps as the paper's E-FSM walks them: the lifted advancing steps, and the first "
    "swing if it advanced along the floor (its SSD omitted, Fig. 8)",
)
def _efsm_footsteps(d: LogData, arg: str) -> float:
    """Pre-fall: ``advancing_steps`` plus :func:`first_swing_slide` (§VI-A, Fig. 6: "11
    steps"; Table II and Fig. 8: the first swing has no raise target). Any later swing must
    lift (≥ 1 cm for ≥ 50 ms) to count; ``later_slides`` reports the ones that did not."""
    _need_walk(d)
    return float(len(advancing_steps(d)) + (first_swing_slide(d) is not None))


@metric(
    "later_slides",
    "slides (as slid_steps) other than the walk's first swing (see efsm_footsteps)",
)
def _later_slides(d: LogData, arg: str) -> float:
    """Pre-fall: ``slid_steps`` less the first swing's slide, which the E-FSM's omitted first
    SSD explains (:func:`first_swing_slide`); every later swing must lift."""
    _need_walk(d)
    slides = sum(
        1
        for found in d.step_detection.values()
        for _, _, shift in found.ground_phases
        if shift >= SLIDE_DISTANCE
    )
    return float(slides - (first_swing_slide(d) is not None))


def swing_apex(d: LogData, step: Footstep) -> float:
    """Largest height [m] of a step's sole centre above the surfaces it left and landed on.

    The sole centre (site ``<side>_sole``, logged state) is the point whose height Table II
    sets (0.05 m raising, 0.005 m landing). The surfaces are the heights of the sole's
    lowest corner at lift-off and at touchdown (the larger of the two), as in
    :func:`walkrepro.evaluation.metrics.detect_steps`: a foot touches down on a corner, its centre
    still ≈ 8 mm up in ``forward_walk``, so the centre then is not the surface.
    """
    track = d.sole_tracks[step.foot]
    i_off, i_on = (int(i) for i in d.state_index(np.array([step.liftoff_t, step.t])))
    surface = max(track.lowest[i_off], track.lowest[i_on])
    return float(np.max(track.centre[i_off : i_on + 1, 2]) - surface)


@metric(
    "swing_apex",
    "apex height of the advancing steps' sole centres, median (arg median|min) [m]",
    arg=choice_check("median", "min"),
)
def _swing_apex(d: LogData, arg: str) -> float:
    """:func:`swing_apex` of each advancing step, reduced over the steps by ``arg``:
    ``median`` (default) or ``min``.

    Table II raises the swing foot to 0.05 m in SSD; Fig. 7(c) plots the reached height.
    Measured from the logged state, never from the controller's reference. A foot that slid
    is no step and has no apex here (``slid_steps`` reports it).
    """
    _need_walk(d)
    reduce = {"": np.median, "median": np.median, "min": np.min}.get(arg)
    if reduce is None:
        raise UnknownNameError("swing_apex reduction", arg, ["median", "min"])
    adv = advancing_steps(d)
    if not adv:
        raise NotMeasurable(f"no advancing step{d.stopped_note()}")
    return float(reduce([swing_apex(d, s) for s in adv]))


#: A sole lands completely when its centre is at most this high above the floor at the
#: SSA → DS switch [m]: a sole flat on the floor has its centre at z ≤ 0 (the contact only
#: penetrates); 1 mm, a fifth of Table II's 5 mm landing offset, tells a foot still above the
#: floor or tilted on it from one landed flat.
LANDED_HEIGHT = 0.001


def landing_heights(
    phase: np.ndarray, swing: np.ndarray, left_z: np.ndarray, right_z: np.ndarray
) -> np.ndarray:
    """Height of the landing sole centre at each SSA → DS switch of the E-FSM [m].

    Args:
        phase: ``efsm_phase`` per control tick (N,) (0 SSD, 1 SSA, 2 DS).
        swing: ``swing_foot`` at the same ticks (N,) (1: the right swings, −1: the left).
        left_z, right_z: each sole centre's height above the floor at the same ticks (N,) [m].

    Returns:
        shape (n_switches,): at the first DS tick of each switch, the height of the foot that
        swung in the SSA just ended (§VI-A, Fig. 7(c): the swing foot "does not land
        completely on the ground at the end of the SSA-state").
    """
    k = np.nonzero((phase[1:] == PHASES["DS"]) & (phase[:-1] == PHASES["SSA"]))[0] + 1
    right = swing[k - 1] == 1.0
    return np.where(right, right_z[k], left_z[k])


@metric(
    "landing_height",
    "median over the E-FSM's SSA → DS switches of the landing (swing) sole centre's height "
    f"above the floor (Fig. 7c; > {LANDED_HEIGHT} m: not landed completely) [m]",
)
def _landing_height(d: LogData, arg: str) -> float:
    """Pre-fall. §VI-A, Fig. 7(c): "the robot foot does not land completely on the ground at
    the end of the SSA-state". The switch is the E-FSM's (``efsm_phase``, ``swing_foot``:
    the claim is about the end of its SSA state); the height is the sole centre's (site
    ``<side>_sole``, the point Table II's 0.005 m landing target sets) above the floor
    plane z = 0 of O_g, from the logged state (Paper I's walks are on that floor)."""
    d.require_states()
    t, phase = d.require_signal("efsm_phase")
    _, swing = d.require_signal("swing_foot")
    i = d.state_index(t)
    tracks = _sole_tracks(d)
    heights = landing_heights(phase, swing, tracks["left"][i, 2], tracks["right"][i, 2])
    if not heights.size:
        raise NotMeasurable(f"the E-FSM never switched SSA → DS{d.stopped_note()}")
    return float(np.median(heights))


@metric(
    "walk_speed",
    "pelvis x speed from the first step's lift-off to the last advancing step's touchdown [m/s]",
)
def _walk_speed(d: LogData, arg: str) -> float:
    """Completed: §VI-A's speed is that of the whole walk, so a fall or an early stop makes
    it not measurable. Steps as in ``advancing_steps``."""
    _need_walk(d)
    d.require_completed("the walk was completed")
    adv = advancing_steps(d)
    if not adv:
        raise NotMeasurable("no advancing step")
    lift = min(s.liftoff_t for s in d.footsteps)
    i0, i1 = d.state_index(np.array([lift, adv[-1].t]))
    if d.t[i1] <= d.t[i0]:
        raise NotMeasurable("the first lift-off is not before the last advancing touchdown")
    return float((d.qpos[i1, 0] - d.qpos[i0, 0]) / (d.t[i1] - d.t[i0]))


def phase_visits(
    t: np.ndarray, phase_signal: np.ndarray, phase: float
) -> list[tuple[float, float]]:
    """(start, end) [s] of every complete visit of an E-FSM phase in a phase signal."""
    out, start = [], None
    for ti, vi in zip(t, phase_signal, strict=True):
        if vi == phase and start is None:
            start = ti
        elif vi != phase and start is not None:
            out.append((start, ti))
            start = None
    return out


def _visits(d: LogData, phase: float) -> list[tuple[float, float]]:
    t, v = d.require_signal("efsm_phase")
    return phase_visits(t, v, phase)


@metric(
    "phase_duration_spread",
    "std/mean of the durations of complete visits of an E-FSM phase (arg SSD|SSA|DS) [-]",
    arg=choice_check(*PHASES),
)
def _phase_duration_spread(d: LogData, arg: str) -> float:
    """Pre-fall. Reads ``efsm_phase``: §VI-A's claim is about the E-FSM's state durations
    (Fig. 8), which are the controller's states, not contact states."""
    visits = _visits(d, PHASES[arg or "SSA"])[1:]  # the first footstep starts from rest
    durations = np.array([b - a for a, b in visits])
    if durations.size < 2:
        raise NotMeasurable(f"{durations.size} complete {arg or 'SSA'} visit(s) after the first")
    return float(np.std(durations) / np.mean(durations))


@metric("first_ssd_duration", "duration of the first SSD (after the first DS) [s]")
def _first_ssd_duration(d: LogData, arg: str) -> float:
    """Pre-fall. Reads ``efsm_phase`` (Fig. 8's claim is about the E-FSM's first SSD)."""
    visits = _visits(d, PHASES["SSD"])
    if not visits:
        raise NotMeasurable(f"the E-FSM never completed an SSD{d.stopped_note()}")
    return visits[0][1] - visits[0][0]


def duration_distance_correlation(
    visits: list[tuple[float, float]], t: np.ndarray, com_x: np.ndarray, cop_x: np.ndarray
) -> float:
    """Spearman rank correlation of visit durations with their mean CoM–CoP distance [-].

    Args:
        visits: (start, end) [s] of the E-FSM state's complete visits.
        t: single-support sample times (N,) [s]; com_x, cop_x: CoM and measured CoP along
            x of O_w at those times (N,) [m], cop_x NaN where the floor carries nothing.

    Returns:
        in [−1, 1]: < 0 when the visits with the CoM nearer its CoP last longer (Eq. 1: the
        CoM's acceleration is proportional to x_m − x_p). Visits without a measured CoP are
        left out.

    Raises:
        NotMeasurable: fewer than three visits with a CoP, or all durations or all distances
            equal (no ranking).
    """
    durations, distances = [], []
    for a, b in visits:
        keep = (t >= a) & (t < b) & np.isfinite(cop_x)
        if np.any(keep):
            durations.append(b - a)
            distances.append(float(np.mean(np.abs(com_x[keep] - cop_x[keep]))))
    if len(durations) < 3:
        raise NotMeasurable(f"{len(durations)} visit(s) with a measured CoP, fewer than 3")
    if np.ptp(durations) == 0 or np.ptp(distances) == 0:
        raise NotMeasurable("the visits' durations or distances are all equal")
    return float(scipy.stats.spearmanr(durations, distances).statistic)


@metric(
    "duration_cop_distance_corr",
    "Spearman correlation of an E-FSM state's visit durations (arg SSD|SSA) with the mean "
    "|x_m − x_p| along x of O_w over each visit (Fig. 7b: < 0, nearer CoM and CoP, longer "
    "state) [-]",
    arg=choice_check("SSD", "SSA"),
)
def _duration_cop_distance_corr(d: LogData, arg: str) -> float:
    """Pre-fall. §VI-A, Fig. 7(b): where the CoM–CoP distance is marginal the CoM
    decelerates slowly and SSD lasts longer; where it is greater SSD and SSA are shorter.
    Durations from the E-FSM's phases (``efsm_phase``: the claim is about its states), the
    first visit left out as in ``phase_duration_spread``; CoM and CoP are the simulated
    ones (logged state, floor contact wrench, :class:`SingleSupport`)."""
    phase = PHASES[arg or "SSD"]
    ss = SingleSupport(d)
    on = ss.phase == phase
    visits = _visits(d, phase)[1:]
    return duration_distance_correlation(visits, ss.t[on], ss.com_x[on], ss.cop_x[on])


def _com_world(d: LogData) -> np.ndarray:
    """The robot's CoM in the world at every logged state, (N, 3) [m] (cached on ``d``)."""
    cached = d.__dict__.get("_lee_com_world")
    if cached is not None:
        return cached
    model = d.model
    data = mujoco.MjData(model)
    root = model.body("pelvis").id
    out = np.zeros((d.t.size, 3))
    for i, qpos in enumerate(d.qpos):
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        out[i] = data.subtree_com[root]
    d.__dict__["_lee_com_world"] = out
    return out


class SingleSupport:
    """The single-support samples of a run along x of O_w (§III-A1), from the logged state.

    O_w: origin at the support sole centre, x towards the swing sole's ground projection.
    Which foot supports is the E-FSM's (``swing_foot`` signal): Eq. (3) applies in its SSD
    and SSA states, so that signal says *when* the claims hold; every position is simulated.

    Attributes:
        t: times [s]; phase: E-FSM phase (0 SSD, 1 SSA).
        com_x: CoM along x of O_w [m]; cop_x: measured CoP (floor contact wrench) along x
            of O_w [m], NaN where the floor carries nothing.
    """

    def __init__(self, d: LogData) -> None:
        d.require_states()
        t_sig, phase = d.require_signal("efsm_phase")
        _, swing = d.require_signal("swing_foot")
        i = d.state_index(t_sig)
        ss = (phase < PHASES["DS"]) & (swing != 0) & (np.abs(d.t[i] - t_sig) < 1e-9)
        if not np.any(ss):
            raise NotMeasurable(f"the E-FSM was never in single support{d.stopped_note()}")
        i, swing = i[ss], swing[ss]
        tracks = _sole_tracks(d)
        right_swings = (swing == 1.0)[:, None]
        p_sup = np.where(right_swings, tracks["left"][i], tracks["right"][i])[:, :2]
        p_sw = np.where(right_swings, tracks["right"][i], tracks["left"][i])[:, :2]
        self.t, self.phase = t_sig[ss], phase[ss]
        self.com_x = ow_x(_com_world(d)[i, :2], p_sup, p_sw)
        self.cop_x = ow_x(_measured_cop(d, self.t), p_sup, p_sw)
        self._d, self._p_sup, self._p_sw = d, p_sup, p_sw

    def cp_x(self, keep: np.ndarray) -> np.ndarray:
        """Capture point along x of O_w at the samples ``keep`` selects, Eq. (2) [m].

        x_CP = x_m + ẋ_m sqrt(z_m0 / g): the CoM and its velocity from the logged state
        (``qpos``, ``qvel``), ẋ_m along the sample's own O_w x-axis (O_w moves with the swing
        foot, but x_CP is the point where the CoM would stop, so its velocity is the CoM's in
        the world); z_m0 the CoM's height at the first logged state (Table II: the CoM's
        z-position task holds its initial value).
        """
        vel = _com_velocity_world(self._d, self.t[keep])[:, :2]
        p_sup, p_sw = self._p_sup[keep], self._p_sw[keep]
        axis = (p_sw - p_sup) / np.linalg.norm(p_sw - p_sup, axis=1, keepdims=True)
        z_m0 = float(_com_world(self._d)[0, 2])
        return capture_points(self.com_x[keep], np.sum(vel * axis, axis=1), z_m0)


def capture_points(com_x: np.ndarray, com_vx: np.ndarray, z_m0: float) -> np.ndarray:
    """x_CP = x_m + ẋ_m sqrt(z_m0 / g), Eq. (2) [m].

    Args:
        com_x: CoM along x of O_w (n,) [m]; com_vx: its velocity along that axis (n,) [m/s];
        z_m0: the LIPM's CoM height [m].
    """
    return com_x + com_vx * math.sqrt(z_m0 / GRAVITY)


def ow_x(points: np.ndarray, p_sup: np.ndarray, p_sw: np.ndarray) -> np.ndarray:
    """Coordinate along x of O_w (§III-A1) of horizontal points, each sample its own O_w.

    Args:
        points, p_sup, p_sw: world xy of the points, the support and the swing sole centres,
            shape (n, 2) [m].

    Returns:
        shape (n,) [m]: 0 at the support centre, positive toward the swing foot.
    """
    axis = p_sw - p_sup
    axis = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    return np.sum((points - p_sup) * axis, axis=1)


def eq3_cop_lead(com_x: np.ndarray, cop_x: np.ndarray, zeta: float) -> float:
    """Smallest x_m − x_p over the samples with x_m ≤ ζ and a CoP [m] (``eq3_cop_lead``)."""
    near = (com_x <= zeta) & np.isfinite(cop_x)
    if not np.any(near):
        raise NotMeasurable("the CoM never came within ζ of the support centre in single support")
    return float(np.min(com_x[near] - cop_x[near]))


def _measured_cop(d: LogData, times: np.ndarray) -> np.ndarray:
    """CoP of the floor's contact wrench on the robot at given times, (n, 2) world [m].

    The logged torque is about the world origin and the floor is z = 0, so the CoP is
    x = −M_y / F_z, y = M_x / F_z. NaN where the floor carries less than 1 N.
    """
    d.require_contacts()
    wrench = d.contact_wrench(f"*/{FLOOR_NAME}")
    k = np.clip(np.searchsorted(d.contact_t, times), 0, d.contact_t.size - 1)
    w = wrench[k]
    fz = np.where(w[:, 2] > 1.0, w[:, 2], np.nan)
    return np.stack([-w[:, 4] / fz, w[:, 3] / fz], axis=1)


def _zeta(d: LogData) -> float:
    return float(d.spec.controller.params.get("zeta", ZETA))


@metric("min_com_x_ss", "smallest CoM x in O_w in SSD/SSA (< 0: past the support centre) [m]")
def _min_com_x_ss(d: LogData, arg: str) -> float:
    """Pre-fall. §VI-A, Fig. 7(b): "the CoM stops its motion successfully before it advances
    beyond the supporting foot". CoM and O_w from the logged state (:class:`SingleSupport`)."""
    return float(np.min(SingleSupport(d).com_x))


@metric(
    "eq3_cop_lead",
    "smallest x_m − x_p along x of O_w in SSD/SSA while the CoM is within ζ of the support "
    "centre (Eq. 3's x_m ≤ ζ case), x_p the measured CoP (> 0: the CoP stays behind the "
    "CoM, so by law L1 the CoM accelerates away from the support centre) [m]",
)
def _eq3_cop_lead(d: LogData, arg: str) -> float:
    """Pre-fall. Eq. (3) puts x_p^des ζ behind the CoM once x_m ≤ ζ so that, by law L1, the
    CoM accelerates away from the CoP: it does not pass the support centre in SSD and moves
    on toward the swing foot in SSA (§III-B1/2). The observable consequence is that the
    *measured* CoP (floor contact wrench) lies behind the simulated CoM in those samples;
    the controller's x_p^des is not read (it is Eq. (3)'s clamp itself). ζ is the spec's
    ``zeta`` (default 0.03 m).
    """
    ss = SingleSupport(d)
    return eq3_cop_lead(ss.com_x, ss.cop_x, _zeta(d))


@metric(
    "min_cp_x_ssd",
    "smallest capture point x_CP (Eq. 2, from the logged CoM state) along x of O_w in the "
    "E-FSM's SSD (< 0: past the support centre; below the sole's back edge: beyond the "
    "support polygon) [m]",
)
def _min_cp_x_ssd(d: LogData, arg: str) -> float:
    """Pre-fall. §III-B3: with too small a Δx_p^des "the CP in the SSD-state after the
    DS-state can move beyond the support polygon"; §III-B1: SSD decelerates the CoM so that
    it stops in the support polygon (B1). The SSD samples are the E-FSM's (``efsm_phase``:
    the claim is about its SSD state); the CoM, its velocity and O_w are from the logged
    state (:meth:`SingleSupport.cp_x`), not the controller's ``cp_w``. The first SSD (from
    rest, Fig. 8) is included: it is as much an SSD after a DS as the others."""
    ss = SingleSupport(d)
    keep = ss.phase == PHASES["SSD"]
    if not np.any(keep):
        raise NotMeasurable(f"the E-FSM was never in SSD{d.stopped_note()}")
    return float(np.min(ss.cp_x(keep)))


def switch_torque_jumps(
    phase: np.ndarray, tau: np.ndarray, joints: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Largest tick-to-tick reference-torque change of some joints at each E-FSM switch.

    Args:
        phase: ``efsm_phase`` per control tick, shape (N,).
        tau: ``tau_ref`` at the same ticks, shape (N, n_actuators) [Nm].
        joints: the actuator indices judged (e.g. :func:`walkrepro.sim.robot.leg_actuators`).

    Returns:
        (ticks, jumps): the ticks k whose phase differs from tick k − 1's (the first tick
        computed in the new state), and max_j |τ_j[k] − τ_j[k − 1]| over ``joints`` there [Nm].
    """
    ticks = np.nonzero(np.diff(phase) != 0)[0] + 1
    jumps = np.max(np.abs(tau[ticks][:, joints] - tau[ticks - 1][:, joints]), axis=1)
    return ticks, jumps


#: Switch kinds of ``switch_torque_jump``'s ``@FROM-TO`` argument (Table I's cycle).
SWITCHES = ("SSD-SSA", "SSA-DS", "DS-SSD")


#: Argument check of ``switch_torque_jump``: a leg, then optionally ``@FROM-TO``.
_switch_arg = qualified_check(choice_check(*FEET), choice_check(*SWITCHES, required=True))


@metric(
    "switch_torque_jump",
    "largest tick-to-tick change of a leg's reference torques at the E-FSM state switches "
    "(Fig. 14), arg 'left' or 'right' (default left), optionally '@FROM-TO' for one kind of "
    "switch, e.g. 'left@SSA-DS' [Nm]",
    arg=_switch_arg,
)
def _switch_torque_jump(d: LogData, arg: str) -> float:
    """Pre-fall. Reads ``tau_ref`` and ``efsm_phase``: §VI-D1's claim (Fig. 14) is about the
    left leg's reference torques, which jump where the E-FSM switches state without ε. The
    jump at a switch is the one into the first tick computed in the new state; the leg's
    joints come from the log's model (:func:`walkrepro.sim.robot.leg_actuators`). ``@FROM-TO``
    keeps the switches of one kind: ε acts on the contact switches (§IV-B: F_s fades before
    the landing of SSA → DS, the redistribution wrench before the lift-off of DS → SSD),
    not on SSD → SSA, where Table II steps the swing height target."""
    _switch_arg(arg)  # specs check it when they load; an old log's spec may not have
    side, _, kind = arg.partition("@")
    side = side or "left"
    t, tau = d.require_signal("tau_ref")
    t_phase, phase = d.require_signal("efsm_phase")
    if t_phase.size != t.size or not np.array_equal(t_phase, t):
        raise NotMeasurable("efsm_phase and tau_ref were not logged at the same ticks")
    ticks, jumps = switch_torque_jumps(phase, tau, leg_actuators(d.model, f"{side}_foot"))
    if kind:
        old, new = (PHASES[name] for name in kind.split("-"))
        keep = (phase[ticks - 1] == old) & (phase[ticks] == new)
        ticks, jumps = ticks[keep], jumps[keep]
    if not ticks.size:
        what = f"switched {kind.replace('-', ' → ')}" if kind else "switched state"
        raise NotMeasurable(f"the E-FSM never {what}{d.stopped_note()}")
    return float(np.max(jumps))


#: A supporting foot moves (violates the stationary contact, §VI-D2) above this sole
#: centre speed [m/s]: the speed below which a blocked swing foot counts as still.
SUPPORT_MOVING_SPEED = 0.02


@metric(
    "cop_error_p90",
    "90th percentile of |expected − measured CoP| while walking (Fig. 15); arg "
    "'support_moving': only the ticks at which a supporting foot moves [m]",
    arg=choice_check("support_moving"),
)
def _cop_error_p90(d: LogData, arg: str) -> float:
    """Pre-fall. Reads ``cop_exp_world`` (the expected CoP of Eqs. 18, 22 from the reference
    torques) and ``cop_meas_world`` (the F/T sensors' CoP): Fig. 15 compares exactly these.
    With ``support_moving``, only the ticks at which a foot the E-FSM counts as supporting
    (``swing_foot``: both in DS, the other foot in single support) moves, its sole centre
    faster than ``SUPPORT_MOVING_SPEED`` in the logged state (§VI-D2: the error "tends not
    to vary noticeably even when a supporting foot moves")."""
    t, exp = d.require_signal("cop_exp_world")
    _, meas = d.require_signal("cop_meas_world")
    _, valid = d.require_signal("cop_meas_valid")
    keep = valid > 0
    if arg == "support_moving":
        keep &= support_moving(d, t)
    err = np.linalg.norm(exp - meas, axis=1)[keep]
    if not err.size and arg:
        raise NotMeasurable(
            f"no tick with a measured CoP while a supporting foot moved{d.stopped_note()}"
        )
    if not err.size:
        raise NotMeasurable("the measured CoP was never valid (no foot loaded)")
    return float(np.percentile(err, 90))


@metric(
    "ds_cop_tracking_p90",
    "90th percentile over the E-FSM's DS ticks of |x_p^des − x_p|, the desired CoP of Eq. (4) "
    "against the measured CoP (floor contact wrench), in the world's xy-plane [m]",
)
def _ds_cop_tracking_p90(d: LogData, arg: str) -> float:
    """Pre-fall. §III-B3: "When the term Δx_p^des is too large, the CoP cannot be generated
    as desired": in DS, Eq. (4) moves x_p^des by Δx_p^des per control period, and this is how
    far the CoP the floor exerts (:func:`_measured_cop`, from the logged contact wrench)
    stays from it. Reads ``xp_des_world`` and ``efsm_phase``: the claim is about the E-FSM's
    desired CoP in its DS state. Ticks at which the floor carries nothing are left out."""
    t, phase = d.require_signal("efsm_phase")
    t_des, xp_des = d.require_signal("xp_des_world")
    if t_des.size != t.size or not np.array_equal(t_des, t):
        raise NotMeasurable("efsm_phase and xp_des_world were not logged at the same ticks")
    keep = phase == PHASES["DS"]
    err = np.linalg.norm(xp_des[keep] - _measured_cop(d, t[keep]), axis=1)
    err = err[np.isfinite(err)]
    if not err.size:
        raise NotMeasurable(f"no DS tick with a measured CoP{d.stopped_note()}")
    return float(np.percentile(err, 90))


def support_moving(d: LogData, times: np.ndarray) -> np.ndarray:
    """Whether a supporting foot's sole centre moves faster than ``SUPPORT_MOVING_SPEED``.

    Args:
        d: the log; ``swing_foot`` says which feet support (1: the right swings, so the left
            supports; −1: the reverse; 0: DS, both support).
        times: control ticks (n,) [s].

    Returns:
        shape (n,) bool.
    """
    d.require_states(2)
    t_sw, swing = d.require_signal("swing_foot")
    swing = swing[np.clip(np.searchsorted(t_sw, times), 0, t_sw.size - 1)]
    i = d.state_index(times)
    moving = {}
    for side, track in _sole_tracks(d).items():
        speed = np.r_[0.0, np.linalg.norm(np.diff(track, axis=0), axis=1) / np.diff(d.t)]
        moving[side] = speed[i] > SUPPORT_MOVING_SPEED
    left_supports = swing != -1.0
    right_supports = swing != 1.0
    return (left_supports & moving["left"]) | (right_supports & moving["right"])


def _first_obstacle_contact(d: LogData, pattern: str) -> float:
    force = np.linalg.norm(d.contact_wrench(pattern)[:, :3], axis=1)
    hit = np.nonzero(force > OBSTACLE_CONTACT_FORCE)[0]
    if not hit.size:
        raise NotMeasurable(f"no contact on {pattern}{d.stopped_note()}")
    return float(d.contact_t[hit[0]])


@metric(
    "steps_after_contact",
    "steps after the first contact on pairs 'body/geom' = arg (e.g. right_foot/obstacle*)",
    arg=any_argument,
)
def _steps_after_contact(d: LogData, arg: str) -> float:
    """Completed: §VI-B's "keeps walking in the same place" needs the whole run after the
    collision, so a fall or an early stop makes it not measurable."""
    _need_walk(d)
    t_hit = _first_obstacle_contact(d, arg or "right_foot/obstacle*")
    d.require_completed("the run after the collision was completed")
    return float(sum(1 for s in d.footsteps if s.t > t_hit))


@metric(
    "first_contact_time",
    "time of the first contact on pairs 'body/geom' = arg (default right_foot/obstacle*) [s]",
    arg=any_argument,
)
def _first_contact_time(d: LogData, arg: str) -> float:
    """Pre-fall (§VI-B: "the collision at t ≈ 4.5 s"): the first logged contact force above
    ``OBSTACLE_CONTACT_FORCE`` on the pairs; not measurable when there is none."""
    d.require_contacts()
    return _first_obstacle_contact(d, arg or "right_foot/obstacle*")


@metric(
    "pelvis_advance_after_contact",
    "distance the pelvis moves along the walking direction (world x) from the first contact "
    "on pairs 'body/geom' = arg (default right_foot/obstacle*) to the end of the run [m]",
    arg=any_argument,
)
def _pelvis_advance_after_contact(d: LogData, arg: str) -> float:
    """Completed (§VI-B: the robot "walks repetitively in the same place after the right foot
    is blocked", judged over the rest of the run): |Δx| of the pelvis, from the logged state,
    between the first contact and the run's last state. Along the walking direction (world
    x in every Paper I spec) only: stepping in place sways the pelvis sideways by up to the
    step width, which is no leaving of the place."""
    d.require_states()
    d.require_contacts()
    t_hit = _first_obstacle_contact(d, arg or "right_foot/obstacle*")
    d.require_completed("the run after the collision was completed")
    i0 = int(d.state_index(np.array([t_hit]))[0])
    return float(abs(d.qpos[-1, 0] - d.qpos[i0, 0]))


@metric(
    "max_sole_x",
    "largest x of a sole centre (arg left|right) over the run [m]",
    arg=choice_check(*FEET),
)
def _max_sole_x(d: LogData, arg: str) -> float:
    """Pre-fall (Fig. 10: the right foot cannot pass the obstacle)."""
    d.require_states()
    return float(np.max(_sole_tracks(d)[arg or "right"][:, 0]))


def _push_window(d: LogData) -> tuple[float, float]:
    """(start, end) [s] of the spec's first disturbance, from the log's events where present."""
    if not d.spec.disturbances:
        raise NotMeasurable("the spec has no push (disturbances is empty)")
    dist = d.spec.disturbances[0]
    on = [e["t"] for e in d.events if e.get("kind") == "disturbance_on"]
    off = [e["t"] for e in d.events if e.get("kind") == "disturbance_off"]
    t0 = float(on[0]) if on else float(dist.start)
    t1 = float(off[0]) if off else float(dist.start + dist.duration)
    d.require_until(t1, "the push ended")
    return t0, t1


def _ds_entries(d: LogData) -> list[float]:
    """E-FSM transitions into DS (events): §VI-C's claims are about the E-FSM's states."""
    return [e["t"] for e in d.events if e.get("kind") == "fsm" and e.get("to") == "DS"]


def _release_start(d: LogData, t1: float) -> float:
    """When the spec's first disturbance starts to let go [s]: a ramp's fall starts
    ``ramp_time`` before the window's end ``t1`` (a hand that "reduces the pushing force",
    §VI-C); any other profile lets go at ``t1``."""
    dist = d.spec.disturbances[0]
    return t1 - float(dist.ramp_time) if dist.profile == "ramp" else t1


@metric(
    "ds_entries_during_push",
    "E-FSM transitions into DS while the push acts; arg 'held': only until the release "
    "starts (a ramp's fall)",
    arg=choice_check("held"),
)
def _ds_entries_during_push(d: LogData, arg: str) -> float:
    """Window (the whole push must be logged). Reads the E-FSM's transition events: Fig.
    12(a)'s claim is that the E-FSM stays in SSA while the upper body is held. With ``held``
    the window ends where the hand starts to let go (Fig. 13: "the transit from the
    SSA-state to the DS-state does not occur" while the human holds; §VI-C: DS follows once
    the human "reduces the pushing force")."""
    t0, t1 = _push_window(d)
    if arg == "held":
        t1 = _release_start(d, t1)
    return float(sum(1 for t in _ds_entries(d) if t0 < t <= t1))


@metric("ds_delay_after_push", "time from the push's release to the next DS [s] (inf: never)")
def _ds_delay_after_push(d: LogData, arg: str) -> float:
    """Completed: a fall or an early stop before the next DS makes it not measurable; a
    completed run that never reaches DS again gives inf. Reads the E-FSM's events (Fig.
    12(a)(b): DS starts when the CP reaches x_s − r)."""
    _, t1 = _push_window(d)
    return _next_ds_delay(d, t1, "the E-FSM entered DS after the push")


@metric(
    "ds_delay_after_release",
    "time from the start of the push's release (a ramp's fall) to the next DS [s] (inf: never)",
)
def _ds_delay_after_release(d: LogData, arg: str) -> float:
    """Completed: as ``ds_delay_after_push``, counted from where the hand starts to let go
    (§VI-C: the human "reduces the pushing force on the robot from t ≈ 27.4 s" and DS
    commences at t ≈ 28.2 s). A DS entered before the release started does not count."""
    _, t1 = _push_window(d)
    return _next_ds_delay(d, _release_start(d, t1), "the E-FSM entered DS after the release")


@metric("ds_delay_after_onset", "time from the push's onset to the next DS [s] (inf: never)")
def _ds_delay_after_onset(d: LogData, arg: str) -> float:
    """Completed: as ``ds_delay_after_push``, counted from the onset, so a DS that the push
    itself brings on (the E-FSM's reaction to a short push toward the swing foot, §III-B:
    SSA ends when x_CP ≥ x_s − r) counts. A fall or an early stop before the next DS makes
    it not measurable; a completed run that never reaches DS again gives inf."""
    t0, _ = _push_window(d)
    return _next_ds_delay(d, t0, "the E-FSM entered DS after the push's onset")


def _next_ds_delay(d: LogData, since: float, what: str) -> float:
    """Time from ``since`` [s] to the E-FSM's next transition into DS; inf if a completed run
    has none; not measurable (``what`` did not happen) if the run ended early or fell."""
    later = [t for t in _ds_entries(d) if t > since]
    if later:
        return float(later[0] - since)
    d.require_completed(what)
    return math.inf


@metric("steps_after_push", "steps after the push's release")
def _steps_after_push(d: LogData, arg: str) -> float:
    """Completed: "walking resumes" (Fig. 11(e)) is judged over the rest of a completed run."""
    _need_walk(d)
    _, t1 = _push_window(d)
    d.require_completed("walking after the push was judged")
    return float(sum(1 for s in d.footsteps if s.t > t1))


@metric(
    "push_com_speed",
    "mean |CoM x-velocity in O_w| over the last second of the push (Fig. 12d) [m/s]",
)
def _push_com_speed(d: LogData, arg: str) -> float:
    """Window (the push must be logged to its end). The CoM velocity is the simulated one,
    along the E-FSM's O_w x-axis (``ow_yaw``: the frame in which Fig. 12(d) is drawn)."""
    t0, t1 = _push_window(d)
    t, yaw = d.require_signal("ow_yaw")
    keep = (t >= max(t0, t1 - 1.0)) & (t <= t1)
    if not np.any(keep):
        raise NotMeasurable("no O_w logged in the last second of the push")
    vel = _com_velocity_world(d, t[keep])
    vx = np.cos(yaw[keep]) * vel[:, 0] + np.sin(yaw[keep]) * vel[:, 1]
    return float(np.mean(np.abs(vx)))


def _middle_second(d: LogData) -> tuple[float, float]:
    """(start, end) [s] of the middle second of the spec's first disturbance window: where a
    hand that engaged over its ramp holds at equilibrium (§VI-C: "the force from the human and
    the generated CoM force are in equilibrium")."""
    t0, t1 = _push_window(d)
    if t1 - t0 < 1.0:
        raise NotMeasurable(f"the push lasts {t1 - t0:.3f} s, less than the 1 s measured")
    mid = 0.5 * (t0 + t1)
    return mid - 0.5, mid + 0.5


@metric(
    "hold_force",
    "mean force norm of the first disturbance over the middle second of its window (§VI-C's "
    "≈ 75 N at equilibrium) [N]",
)
def _hold_force(d: LogData, arg: str) -> float:
    """Window. Reads the logged applied wrenches (every physics step): for a hold
    (``kind: hold``) the hand's force is an outcome of its impedance and the robot's motion,
    so this measures the equilibrium the paper reports, not a set value."""
    a, b = _middle_second(d)
    body = d.spec.disturbances[0].body
    dt = d.spec.sim.timestep
    forces = [
        float(np.linalg.norm(m["xfrc"].get(body, (0.0, 0.0, 0.0))[:3]))
        for m in d.log.messages(record.TOPIC_INPUTS)
        if a <= m["step"] * dt < b
    ]
    if not forces:
        raise NotMeasurable("no applied wrench logged in the middle second of the push")
    return float(np.mean(forces))


@metric(
    "hold_com_speed",
    "mean |CoM x-velocity in O_w| over the middle second of the push or hold (Fig. 12d) [m/s]",
)
def _hold_com_speed(d: LogData, arg: str) -> float:
    """Window. As ``push_com_speed``, over the middle second of the window: a hand that
    engages and lets go over ramps holds the CoM between them."""
    a, b = _middle_second(d)
    t, yaw = d.require_signal("ow_yaw")
    keep = (t >= a) & (t <= b)
    if not np.any(keep):
        raise NotMeasurable("no O_w logged in the middle second of the push")
    vel = _com_velocity_world(d, t[keep])
    vx = np.cos(yaw[keep]) * vel[:, 0] + np.sin(yaw[keep]) * vel[:, 1]
    return float(np.mean(np.abs(vx)))


def swing_travel(swing: np.ndarray, left: np.ndarray, right: np.ndarray) -> float:
    """Largest distance a swing foot's sole centre moves from where it was when it first
    swung in the samples [m].

    Args:
        swing: ``swing_foot`` per sample (n,) (1: the right swings, −1: the left, 0: DS).
        left, right: each sole centre in the world at the same samples (n, 3) [m].

    Returns:
        the largest |p(t) − p(t_first)| over the samples in which the foot is the swing foot,
        over both feet; 0 when no foot swings.
    """
    best = 0.0
    for code, track in ((1.0, right), (-1.0, left)):
        on = np.nonzero(swing == code)[0]
        if on.size:
            best = max(best, float(np.max(np.linalg.norm(track[on] - track[on[0]], axis=1))))
    return best


@metric(
    "swing_travel_during_push",
    "largest distance the E-FSM's swing foot's sole centre moves from where it was at the "
    "push's onset, while the push acts; arg 'held': only until the release starts [m]",
    arg=choice_check("held"),
)
def _swing_travel_during_push(d: LogData, arg: str) -> float:
    """Window (the whole push must be logged). Fig. 13(d): the "swing foot moves when the
    upper body is disturbed". The swing foot is the E-FSM's (``swing_foot``: the caption
    names the swing foot); its sole centre (site ``<side>_sole``) is the logged state's.
    With ``held`` the window ends where the hand starts to let go, as in
    ``ds_entries_during_push:held``. Not measurable when no foot swings in the window."""
    t0, t1 = _push_window(d)
    if arg == "held":
        t1 = _release_start(d, t1)
    d.require_states()
    t, swing = d.require_signal("swing_foot")
    keep = (t >= t0) & (t <= t1)
    if not np.any(swing[keep] != 0.0):
        raise NotMeasurable("no foot was the E-FSM's swing foot while the push acted")
    i = d.state_index(t[keep])
    tracks = _sole_tracks(d)
    return swing_travel(swing[keep], tracks["left"][i], tracks["right"][i])


def _com_velocity_world(d: LogData, times: np.ndarray) -> np.ndarray:
    """The robot's CoM velocity in the world at given times, (n, 3) [m/s]."""
    model = d.model
    data = mujoco.MjData(model)
    root = model.body("pelvis").id
    out = np.zeros((times.size, 3))
    jac = np.zeros((3, model.nv))
    for k, i in enumerate(d.state_index(times)):
        data.qpos[:] = d.qpos[i]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_jacSubtreeCom(model, data, jac, root)
        out[k] = jac @ d.qvel[i]
    return out


def _swing_force(d: LogData, foot: str) -> tuple[np.ndarray, np.ndarray]:
    """Obstacle force norm on a foot per contact message [N], and whether the E-FSM swings
    it then (``swing_foot``: the paper's claim is about the force on the *swing* foot)."""
    d.require_contacts()
    force = np.linalg.norm(d.contact_wrench(f"{foot}_foot/obstacle*")[:, :3], axis=1)
    t, swing = d.require_signal("swing_foot")
    # swing_foot is 1 while the right foot swings, −1 for the left, 0 in DS.
    code = 1.0 if foot == "right" else -1.0
    i = np.clip(np.searchsorted(t, d.contact_t), 0, t.size - 1)
    return force, swing[i] == code


@metric(
    "peak_swing_obstacle_force",
    "largest obstacle contact force on a foot while it is the E-FSM swing foot (arg left|right) [N]",
    arg=choice_check(*FEET),
)
def _peak_swing_obstacle_force(d: LogData, arg: str) -> float:
    """Pre-fall; 0 when the swing foot never touches an obstacle."""
    force, swinging = _swing_force(d, arg or "right")
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
    arg=choice_check(*FEET),
)
def _blocked_swing_obstacle_force(d: LogData, arg: str) -> float:
    """Pre-fall; 0 when the swing foot is never blocked. Sole speed from the logged state."""
    foot = arg or "right"
    d.require_states(2)
    force, swinging = _swing_force(d, foot)
    return blocked_force(d.t, _sole_tracks(d)[foot], d.contact_t, force, swinging)


def blocked_force(
    t: np.ndarray, sole: np.ndarray, contact_t: np.ndarray, force: np.ndarray, swinging: np.ndarray
) -> float:
    """Largest ``force`` once the foot is blocked (see ``blocked_swing_obstacle_force``).

    Args:
        t: state times (N,) [s]; sole: sole centre at those times (N, 3) [m].
        contact_t: contact message times (M,) [s]; force: obstacle force norm (M,) [N];
        swinging: whether the foot is the swing foot at each contact message (M,).
    """
    speed = np.r_[0.0, np.linalg.norm(np.diff(sole[:, :2], axis=0), axis=1) / np.diff(t)]
    i_st = np.clip(np.searchsorted(t, contact_t), 0, t.size - 1)
    # Contact gaps of a few ticks (the foot chattering on the face) do not end a blockage.
    touching = force > OBSTACLE_CONTACT_FORCE
    still = (speed[i_st] < BLOCKED_SPEED) & swinging
    best, since = 0.0, math.nan
    for k in range(force.size):
        if still[k] and (touching[k] or not math.isnan(since)):
            since = contact_t[k] if math.isnan(since) else since
            if contact_t[k] - since >= BLOCKED_TIME:
                best = max(best, float(force[k]))
        else:
            since = math.nan
    return best
