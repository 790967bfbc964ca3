"""Metrics specific to the faraji reproduction (computed from the log alone).

Paper II (Faraji et al., time-projection push recovery) reports footstep scatter at phase
changes (Fig. 14), corrective steps after pushes (Figs. 16-17), pelvis speed under drag
(Fig. 18), walking speed (Fig. 19) and an apparent ankle stiffness (Fig. 20).
"""

from __future__ import annotations

import math
from functools import cache
from typing import NamedTuple

import mujoco
import numpy as np

from walkrepro.evaluation.metrics import (
    FOOT_BODIES,
    GRAVITY,
    LIFT_TIME,
    LIFTOFF_WEIGHT_FRACTION,
    TOUCHDOWN_WEIGHT_FRACTION,
    LogData,
    MetricArgError,
    NotMeasurable,
    choice_check,
    mean_forward_speed,
    metric,
    number_check,
    parse_window,
    qualified_check,
    window_check,
)

#: A step is corrective when its realised footstep adjustment lies further than this many
#: standard deviations from the undisturbed steps' mean adjustment (a 3σ outlier of the
#: undisturbed gait, either way: issue 14's "exceeds the undisturbed gait's spread").
CORRECTIVE_SIGMAS = 3.0
#: Undisturbed steps needed before the push to estimate that spread (mean and σ of fewer
#: are too uncertain: with 6 samples σ is known to about ±30 %).
MIN_UNDISTURBED_STEPS = 6
#: Step time of the paper's gait [s] (T = 0.4 s), used when the log has no phase events.
STEP_TIME = 0.4


def _phase_times(d: LogData) -> np.ndarray:
    """Times of the controller's phase changes (touchdowns of the fixed-timing gait) [s]."""
    return np.array([e["t"] for e in d.events if e.get("kind") == "phase"])


def _stride_speed(d: LogData) -> tuple[np.ndarray, np.ndarray]:
    """Pelvis forward speed averaged over one stride (2 T) [m/s], and its times [s].

    The average removes the within-step oscillation, leaving the walking speed of Fig. 18.
    """
    if d.t.size < 3:
        return np.zeros(0), np.zeros(0)
    dt = float(np.median(np.diff(d.t)))
    n = max(1, int(round(2 * STEP_TIME / dt)))
    x = d.qpos[:, 0]
    if x.size <= n:
        return np.zeros(0), np.zeros(0)
    v = (x[n:] - x[:-n]) / (d.t[n:] - d.t[:-n])
    return 0.5 * (d.t[n:] + d.t[:-n]), v


def _window(t: np.ndarray, arg: str) -> np.ndarray:
    if not arg:
        return np.ones(t.size, dtype=bool)
    lo, hi = parse_window(arg)
    return (t >= lo) & (t <= hi)


def _speed_in_window(d: LogData, arg: str) -> np.ndarray:
    """Stride-averaged speeds with centre times in the window ``arg`` [m/s].

    Window rule: the data must reach the window's end (a fall or an early stop before it
    makes the metric not measurable, so speeds of a fall are never reported).
    """
    if arg:
        d.require_until(parse_window(arg)[1], f"the end of the window {arg}")
    t, v = _stride_speed(d)
    m = _window(t, arg)
    if not m.any():
        raise NotMeasurable(f"no stride-averaged speed in the window {arg or 'of the run'}")
    return v[m]


@metric(
    "peak_pelvis_speed",
    "largest |stride-averaged pelvis x speed| [m/s] (arg 't0-t1')",
    arg=window_check,
)
def _peak_pelvis_speed(d: LogData, arg: str) -> float:
    """Window (see :func:`_speed_in_window`); pre-fall without an argument."""
    v = _speed_in_window(d, arg)
    return float(np.max(np.abs(v)))


@metric(
    "peak_forward_pelvis_speed",
    "largest stride-averaged pelvis x speed [m/s] (arg 't0-t1')",
    arg=window_check,
)
def _peak_forward(d: LogData, arg: str) -> float:
    """Window (see :func:`_speed_in_window`); pre-fall without an argument."""
    v = _speed_in_window(d, arg)
    return float(np.max(v))


@metric(
    "peak_backward_pelvis_speed",
    "largest backward stride-averaged pelvis speed, as a positive number [m/s] (arg 't0-t1')",
    arg=window_check,
)
def _peak_backward(d: LogData, arg: str) -> float:
    """Window (see :func:`_speed_in_window`); pre-fall without an argument."""
    v = _speed_in_window(d, arg)
    return float(-np.min(v))


@metric(
    "mean_abs_pelvis_speed",
    "mean |stride-averaged pelvis x speed| [m/s] (arg 't0-t1')",
    arg=window_check,
)
def _mean_abs_speed(d: LogData, arg: str) -> float:
    """Window (see :func:`_speed_in_window`); pre-fall without an argument."""
    v = _speed_in_window(d, arg)
    return float(np.mean(np.abs(v)))


def corrective_band(
    adjustments: np.ndarray, phases: np.ndarray, t_push: float
) -> tuple[float, float]:
    """Band of the undisturbed gait: μ ∓ 3σ of the undisturbed steps' adjustments [m].

    ``adjustments`` holds one signed adjustment per step (the realised one, :func:`landings`);
    ``phases`` the steps' start times. The undisturbed steps are those that end before the
    push, without the first (it starts from standing). μ and σ (ddof 1) are taken over the
    signed values, so a gait whose steps are biased one way (the in-place gait lands its
    feet ≈ 1 cm ahead of the pelvis) gives a band centred on that bias, and a step the other
    way is measured against the spread, not the bias. Raises :class:`NotMeasurable` with
    fewer than MIN_UNDISTURBED_STEPS.

    Returns:
        (low, high): μ − 3σ and μ + 3σ [m].
    """
    ends = np.append(phases[1:], np.inf)
    undisturbed = adjustments[1:][ends[1:] <= t_push]
    if undisturbed.size < MIN_UNDISTURBED_STEPS:
        raise NotMeasurable(
            f"{undisturbed.size} undisturbed step(s) before the push at t = {t_push:.3f} s; "
            f"{MIN_UNDISTURBED_STEPS} are needed for the corrective-step band"
        )
    mu = float(np.mean(undisturbed))  # [m]
    half = CORRECTIVE_SIGMAS * float(np.std(undisturbed, ddof=1))  # 3σ [m]
    return mu - half, mu + half


def corrective_steps(
    adjustments: np.ndarray, phases: np.ndarray, t_push: float, band: tuple[float, float]
) -> list[int]:
    """Indices of the corrective steps, from the step the push falls in: steps whose signed
    adjustment lies outside ``band`` (|a − μ| > 3σ), until the first step back inside it
    after one outside (the recovery's end).

    Raises :class:`NotMeasurable` when the log ends while the steps are still corrective.
    """
    low, high = band
    first = max(0, int(np.searchsorted(phases, t_push, side="right")) - 1)
    steps: list[int] = []
    for k in range(first, adjustments.size - 1):  # the last step may be cut short by the log's end
        if adjustments[k] < low or adjustments[k] > high:
            steps.append(k)
        elif steps:
            return steps
    if steps:
        raise NotMeasurable("the log ends before the footstep adjustments settled")
    return steps


def count_corrective(
    adjustments: np.ndarray, phases: np.ndarray, t_push: float, band: tuple[float, float]
) -> int:
    """Number of :func:`corrective_steps`."""
    return len(corrective_steps(adjustments, phases, t_push, band))


def unsettled_steps(
    adjustments: np.ndarray, phases: np.ndarray, t_push: float, band: tuple[float, float]
) -> int:
    """Steps after the recovery whose adjustment still lies outside ``band``.

    The recovery ends at the first step back inside the band after the corrective ones
    (:func:`corrective_steps`; with none, at the step the push falls in); every later step
    to the end of the log is read, so a gait that keeps swaying beyond its undisturbed
    spread after the count has stopped shows it here.
    """
    chosen = corrective_steps(adjustments, phases, t_push, band)
    first = max(0, int(np.searchsorted(phases, t_push, side="right")) - 1)
    end = chosen[-1] + 1 if chosen else first
    rest = adjustments[end:]
    return int(np.sum((rest < band[0]) | (rest > band[1])))


def _push_time(d: LogData, arg: str) -> float:
    if arg:
        return float(arg)
    if not d.spec.disturbances:
        raise NotMeasurable("the spec has no push (disturbances is empty)")
    return float(d.spec.disturbances[0].start)


def _landing_steps(d: LogData) -> tuple[np.ndarray, np.ndarray]:
    """Step start times [s] and realised adjustments [m] (:func:`landings`)."""
    steps = landings(d)
    if steps.end.size < 2:
        raise NotMeasurable(f"{steps.end.size} step(s) ended while the gait ran, 2 needed")
    return steps.start, steps.adjustment


def _recovery(d: LogData, arg: str) -> tuple[np.ndarray, np.ndarray, float, tuple[float, float]]:
    """A completed pushed run's realised steps, their start times, the push time and the
    undisturbed band: the arguments of :func:`count_corrective` and :func:`unsettled_steps`."""
    d.require_completed("the push was recovered")
    starts, adjustments = _landing_steps(d)
    t_push = _push_time(d, arg)
    return adjustments, starts, t_push, corrective_band(adjustments, starts, t_push)


@metric(
    "corrective_band_low",
    "lower edge of the undisturbed gait's band, μ − 3σ of the realised footstep "
    "adjustments of the undisturbed steps before the push (arg: push time [s]) [m]",
    arg=number_check(),
)
def _corrective_band_low(d: LogData, arg: str) -> float:
    """Pre-fall (only steps before the push are read); see :func:`corrective_band`."""
    starts, adjustments = _landing_steps(d)
    return corrective_band(adjustments, starts, _push_time(d, arg))[0]


@metric(
    "corrective_band_high",
    "upper edge of the undisturbed gait's band, μ + 3σ of the realised footstep "
    "adjustments of the undisturbed steps before the push (arg: push time [s]) [m]",
    arg=number_check(),
)
def _corrective_band_high(d: LogData, arg: str) -> float:
    """Pre-fall (only steps before the push are read); see :func:`corrective_band`."""
    starts, adjustments = _landing_steps(d)
    return corrective_band(adjustments, starts, _push_time(d, arg))[1]


@metric(
    "recovery_steps",
    "corrective steps after the push (arg: push time [s], default the spec's first "
    "disturbance): steps from the one the push falls in whose realised footstep adjustment "
    "a (the swing foot relative to the pelvis at the phase change, minus the 3LP nominal) "
    "lies outside the undisturbed steps' band, |a − μ| > 3σ, until the first step back "
    "inside it (Fig. 16)",
    arg=number_check(),
)
def _recovery_steps(d: LogData, arg: str) -> float:
    """Completed: "the push is recovered in N corrective steps" needs a run that completed,
    so a fall or an early stop makes it not measurable.

    Issue 14's definition: a corrective step is one whose adjustment exceeds the undisturbed
    gait's spread by a margin derived from that spread (3σ). A step's adjustment is where
    the step put the foot (:func:`landings`, from the logged state), as Fig. 16 counts
    steps on snapshots "taken at phase change moments". The commanded adjustment is not
    it: it is recomputed every tick from the filtered errors and reaches the floor through
    the hip servo's lag, so its peak within a step can be a transient the foot never
    follows (the strong backward push's second step commands +15 cm at its peak and lands
    12 cm behind the nominal). Each step's adjustment is compared with the band μ ± 3σ of
    the same run's undisturbed steps before the push (:func:`corrective_band`), so the
    metric holds under ``--set`` overrides.
    """
    return float(count_corrective(*_recovery(d, arg)))


@metric(
    "unsettled_steps",
    "steps after the recovery (from the first step back inside the undisturbed band, to the "
    "end of the run) whose realised footstep adjustment lies outside that band again "
    "(arg: push time [s]); 0 when the gait has returned to its undisturbed spread (Figs. "
    "16-17)",
    arg=number_check(),
)
def _unsettled_steps(d: LogData, arg: str) -> float:
    """Completed, as ``recovery_steps``: the count stops at the first step back inside the
    band; this reads the steps after it, so a recovery that ends on one lucky step inside
    a continuing sway is not taken for a settled gait."""
    return float(unsettled_steps(*_recovery(d, arg)))


@metric("max_footstep_adjustment", "largest |commanded footstep adjustment| after truncation [m]")
def _max_adjustment(d: LogData, arg: str) -> float:
    """Pre-fall. Reads ``footstep``: the claim (truncation at 15 cm, Fig. 13) is about it."""
    _, v = d.require_signal("footstep")
    return float(np.max(np.abs(v)))


@metric(
    "max_footstep_adjustment_raw",
    "largest |footstep adjustment| before truncation [m] (arg 't0-t1': over that window, "
    "which the run must reach without a fall)",
    arg=window_check,
)
def _max_adjustment_raw(d: LogData, arg: str) -> float:
    """Pre-fall. Reads ``footstep_raw`` (the adjustment before truncation, Fig. 17).

    With a window ``t0-t1`` the data must reach its end: a robot falling inside it asks
    for any footstep while it falls, so a raw adjustment read there says nothing about a
    recovery (Fig. 17's strong push is recovered "despite a safety threshold").
    """
    lo, hi = _window_or_run(d, arg)
    t, v = d.require_signal("footstep_raw")
    inside = (t >= lo) & (t <= hi)
    if not inside.any():
        raise NotMeasurable(f"no footstep adjustment logged in the window {arg}")
    return float(np.max(np.abs(v[inside])))


class Landings(NamedTuple):
    """Where each step of the fixed-timing gait put its swing foot (:func:`landings`)."""

    #: start time of each step [s] (the phase change before it).
    start: np.ndarray
    #: the phase change that ends it (the gait's touchdown) [s].
    end: np.ndarray
    #: realised footstep adjustment [m], forward +.
    adjustment: np.ndarray


def landings(d: LogData) -> Landings:
    """Realised footstep adjustment of each step, from the logged state (Figs. 13, 16-17).

    At each phase change (the fixed-timing gait's touchdown) the foot that swung in the
    ending step sits where the step placed it: its sole centre's x relative to the pelvis
    (world axes, from ``qpos``), minus the 3LP gait's nominal swing-foot position relative to
    the pelvis at that instant (−s₁ of ``e_nominal``, the controller's reference, not its
    measurement). What the controller commands (``footstep``, truncated at 15 cm) reaches
    the floor through the servos, the springs and the pelvis's own motion; this is what did.
    Fig. 16 shows the same: snapshots "taken at phase change moments".

    Steps that end before the gait's reference exists (standing) are skipped; pre-fall.
    """
    d.require_states()
    sig = [
        m
        for m in d.signals
        if "e_nominal" in m and "swing_side" in m and np.isfinite(m["e_nominal"][0])
    ]
    if not sig:
        raise NotMeasurable(f"the log has no 3LP reference (e_nominal){d.stopped_note()}")
    t = np.array([m["t"] for m in sig])
    phases = _phase_times(d)
    ran = (phases > t[0]) & (phases <= min(t[-1], d.t[-1]))
    if not ran.any():
        raise NotMeasurable(f"no phase change while the gait ran{d.stopped_note()}")
    end = phases[ran]
    before = np.append(phases[0] - STEP_TIME, phases[:-1])  # each phase change's predecessor
    last = np.searchsorted(t, end, side="left") - 1  # the ending step's last tick
    rel = _feet_relative(d, end)  # (n, foot: left, right, xy)
    swing = np.array([0 if sig[i]["swing_side"] > 0 else 1 for i in last])  # +1: left swings
    nominal = np.array([-sig[i]["e_nominal"][0] for i in last])  # f − p of the 3LP gait [m]
    return Landings(before[ran], end, rel[np.arange(end.size), swing, 0] - nominal)


@metric(
    "max_landing_adjustment",
    "largest |realised footstep adjustment| [m]: at each phase change the swing foot's sole "
    "centre x relative to the pelvis (logged state) minus the 3LP gait's nominal (Fig. 13's "
    "15 cm truncation, measured where the foot lands)",
)
def _max_landing_adjustment(d: LogData, arg: str) -> float:
    """Completed (see :func:`landings`): the claim bounds every landing of the walk, and a
    run that fell or stopped early has landings it never made, while its last ones are part
    of the fall (the pelvis already pitched over); a maximum over the landings before the
    fall would confirm the bound on part of the run only. Not measurable then."""
    d.require_completed("every landing of the run could be measured")
    return float(np.max(np.abs(landings(d).adjustment)))


@cache
def _site_ids(xml: str) -> tuple[mujoco.MjModel, int, int, int]:
    model = mujoco.MjModel.from_xml_string(xml)
    ids = [
        mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, s) for s in ("left_sole", "right_sole")
    ]
    return model, ids[0], ids[1], model.body("pelvis").id


def _feet_relative(d: LogData, times: np.ndarray) -> np.ndarray:
    """Sole centres minus pelvis origin (world axes, horizontal) at given times, (n, 2, 2) [m]."""
    model, left, right, pelvis = _site_ids(d.log.scene_xml)
    data = mujoco.MjData(model)
    out = np.zeros((times.size, 2, 2))
    for k, ti in enumerate(times):
        i = min(int(np.searchsorted(d.t, ti)), d.t.size - 1)
        data.qpos[:] = d.qpos[i]
        mujoco.mj_kinematics(model, data)
        for j, site in enumerate((left, right)):
            out[k, j] = data.site_xpos[site, :2] - data.xpos[pelvis, :2]
    return out


@metric(
    "footstep_scatter",
    "spread of the feet relative to the pelvis at phase changes (Fig. 14): RMS distance of "
    "each foot's sample from that foot's mean, both feet pooled [m] (arg 't0-t1')",
    arg=window_check,
)
def _footstep_scatter(d: LogData, arg: str) -> float:
    """Pre-fall: the feet at the phase changes before any fall."""
    d.require_states()
    phases = _phase_times(d)
    phases = phases[_window(phases, arg or "2.0-1e9")]
    if phases.size < 4:
        raise NotMeasurable(f"{phases.size} phase change(s) in the window, 4 needed")
    return footstep_scatter(_feet_relative(d, phases))


def footstep_scatter(rel: np.ndarray) -> float:
    """RMS distance of each foot's samples from that foot's mean, both feet pooled [m].

    Args:
        rel: feet relative to the pelvis, shape (n, 2, 2) [m] (sample, foot, xy).
    """
    dev = rel - rel.mean(axis=0, keepdims=True)
    return float(np.sqrt(np.mean(np.sum(dev**2, axis=2))))


@metric(
    "speed_to_command",
    "mean pelvis x speed over the window (arg 't0-t1' [s], as mean_forward_speed) divided "
    "by the commanded 3LP speed, the spec's controller.params.speed (Fig. 19) [-]",
    arg=window_check,
)
def _speed_to_command(d: LogData, arg: str) -> float:
    """Window as :func:`walkrepro.evaluation.metrics.mean_forward_speed`. Fig. 19's claim is about the
    speed realised against the one commanded, so the ratio follows a ``--set`` of the
    command where a band in m/s would not. Signed: a backward command (speed < 0) walked
    backward gives a positive ratio, walked forward a negative one. Not measurable without
    a commanded speed (in place)."""
    command = float(d.spec.controller.params.get("speed", 0.0))  # [m/s]
    if command == 0.0:
        raise NotMeasurable(f"the spec commands no walking speed (speed = {command} m/s)")
    return mean_forward_speed(d, arg) / command


def _pull(d: LogData) -> tuple[float, float, float, float]:
    """(force x [N], start [s], hold start [s], hold end [s]) of the spec's first disturbance.

    The hold is where the full force acts: the pull's window less a ``ramp`` profile's rise
    and fall (``ramp_time`` each), the whole window for a constant pull. Window rule: the
    log must reach the pull's end, so a fall under the pull is never read as a displacement.
    """
    if not d.spec.disturbances:
        raise NotMeasurable("the spec has no pull (disturbances is empty)")
    dist = d.spec.disturbances[0]
    t0 = float(dist.start)
    t1 = float(dist.start + dist.duration)
    d.require_until(t1, "the pull ended")
    ramp = float(dist.ramp_time) if dist.profile == "ramp" else 0.0
    return float(dist.force[0]), t0, t0 + ramp, t1 - ramp


def _mean_in(t: np.ndarray, x: np.ndarray, lo: float, hi: float) -> float:
    m = (t >= lo) & (t <= hi)
    if not m.any():
        raise NotMeasurable(f"no state logged in [{lo:.3f}, {hi:.3f}] s")
    return float(np.mean(x[m]))


def displacement(
    t: np.ndarray, x: np.ndarray, t0: float, h0: float, h1: float | None = None
) -> float:
    """Mean of ``x`` over the last half of the hold [h0, h1] minus its mean over the second
    before the pull's start ``t0`` (``h1`` None: the hold is [t0, h0])."""
    if h1 is None:
        h0, h1 = t0, h0
    before = _mean_in(t, x, max(0.0, t0 - 1.0), t0)
    during = _mean_in(t, x, 0.5 * (h0 + h1), h1)
    return during - before


@metric(
    "pelvis_displacement",
    "pelvis x over the last half of the pull's hold (its ramps excluded) minus before it [m]",
)
def _pelvis_displacement(d: LogData, arg: str) -> float:
    """Window (the whole pull must be logged); pelvis from the logged state."""
    _, t0, h0, h1 = _pull(d)
    return displacement(d.t, d.qpos[:, 0], t0, h0, h1)


@metric("torso_displacement", "neck-height (torso top) x displacement under the pull [m]")
def _torso_displacement(d: LogData, arg: str) -> float:
    """Window (the whole pull must be logged); the neck from the logged state."""
    _, t0, h0, h1 = _pull(d)
    model = d.model
    data = mujoco.MjData(model)
    torso = _torso_id(model)
    xs = np.zeros(d.t.size)
    for i in range(d.t.size):
        data.qpos[:] = d.qpos[i]
        mujoco.mj_kinematics(model, data)
        xs[i] = data.xpos[torso, 0] + data.xmat[torso].reshape(3, 3)[0, 2] * _neck_offset(model)
    return displacement(d.t, xs, t0, h0, h1)


def _torso_id(model: mujoco.MjModel) -> int:
    """The ``torso`` body (COMAN's neck is its top), or NotMeasurable on another robot."""
    torso = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "torso")
    if torso < 0:
        raise NotMeasurable("the robot has no 'torso' body (the neck of Paper II Fig. 20)")
    return torso


def _neck_offset(model: mujoco.MjModel) -> float:
    """Height of the neck above the torso body origin [m]: the top of its box geom
    (robots/coman), else the highest anchor of its child bodies, the shoulder axes
    (robots/coman_lab, whose torso is drawn with capsules), else 0."""
    torso = model.body("torso").id
    tops = [
        model.geom_pos[g, 2] + model.geom_size[g, 2]
        for g in range(model.ngeom)
        if model.geom_bodyid[g] == torso and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX
    ]
    if not tops:
        tops = [model.body_pos[b, 2] for b in range(model.nbody) if model.body_parentid[b] == torso]
    return float(max(tops)) if tops else 0.0


def paper_ankle_stiffness(
    force: float, neck_height: float, pelvis_height: float, pelvis_shift: float
) -> float:
    """Paper II Fig. 20's effective stiffness per ankle, K = F h_n h_p / (2 d_p) [Nm/rad].

    The paper states only its inputs and result ("a minimal pulling force of ≈ 7 N can
    easily move the pelvis by ≈ 5 cm [...] which implies an effective stiffness of only
    ≈ 31 Nm/rad per ankle"): the pull F [N] at the neck, at height h_n above the ground
    [m], loads the two ankles with the moment F h_n [Nm], shared equally; the lean is the
    pelvis displacement d_p [m] over the pelvis height h_p above the ground [m] (small
    angles, the robot a rigid stick pivoting at the ground). The heights are from the
    ground, not from the ankles: only they give the paper's number, 7 N × 0.84 m × 0.52 m
    / (2 × 0.05 m) ≈ 30 on COMAN (heights above the ankles, 0.74 m × 0.42 m, give ≈ 22).
    Gravity's moment on the lean is not subtracted: the paper's figure is the apparent one.

    Raises:
        NotMeasurable: the pelvis did not move (d_p = 0).
    """
    if not pelvis_shift:
        raise NotMeasurable("the pelvis did not move under the pull (zero lean)")
    return abs(force) * neck_height * pelvis_height / (2.0 * abs(pelvis_shift))


@metric(
    "ankle_stiffness",
    "apparent stiffness per ankle F·h_neck·h_pelvis / (2·d_pelvis) [Nm/rad] (Paper II "
    "Fig. 20, the formula its ≈ 7 N, ≈ 5 cm and ≈ 31 Nm/rad imply): F the pull, d_pelvis "
    "the pelvis displacement, the heights above the ground (the floor, z = 0)",
)
def _ankle_stiffness(d: LogData, arg: str) -> float:
    """Window (the whole pull must be logged). Heights from the first logged state, above
    the floor (z = 0 in walkrepro's scenes); see :func:`paper_ankle_stiffness`."""
    force, t0, h0, h1 = _pull(d)
    model = d.model
    _torso_id(model)
    data = mujoco.MjData(model)
    data.qpos[:] = d.qpos[0]
    mujoco.mj_kinematics(model, data)
    neck = data.xpos[model.body("torso").id, 2] + _neck_offset(model)
    pelvis = data.xpos[model.body("pelvis").id, 2]
    shift = displacement(d.t, d.qpos[:, 0], t0, h0, h1)
    return paper_ankle_stiffness(force, neck, pelvis, shift)


# ---- position tracking delay (Hardware Limitations, Sensor Quality; Fig. 4) ----------------

#: Longest lag searched between a joint's position command and its link angle [s].
MAX_TRACKING_LAG = 0.1
#: Grid on which the command and the link angle are compared [s] (the lag is then refined
#: between grid points by a parabola through the correlation peak).
TRACKING_GRID = 0.0005
#: Below this correlation the link does not follow its command (e.g. a stance ankle whose
#: spring carries the body) and a lag would mean nothing.
MIN_TRACKING_CORRELATION = 0.9


def tracking_lag(
    command: np.ndarray, link: np.ndarray, dt: float, max_lag: float
) -> tuple[float, float]:
    """Lag of ``link`` behind ``command`` and their correlation there.

    The lag s ∈ [0, max_lag] maximises the normalised correlation of the mean-free signals
    c(t) and θ(t + s), both sampled every ``dt`` [s]; a parabola through the peak and its
    neighbours refines s between samples. Returns (s [s], correlation at the best sample).
    """
    c = command - command.mean()
    y = link - link.mean()
    n_lags = min(int(round(max_lag / dt)), c.size - 2)
    if n_lags < 2:
        raise NotMeasurable("too few samples to measure a tracking lag")
    r = np.empty(n_lags + 1)
    for k in range(n_lags + 1):
        a, b = c[: c.size - k], y[k:]
        den = float(np.linalg.norm(a) * np.linalg.norm(b))
        r[k] = float(a @ b) / den if den > 0 else 0.0
    k = int(np.argmax(r))
    shift = 0.0
    if 0 < k < n_lags:
        curv = r[k - 1] - 2 * r[k] + r[k + 1]
        if curv < 0:
            shift = 0.5 * (r[k - 1] - r[k + 1]) / curv
    return (k + shift) * dt, float(r[k])


def _position_servos(model: mujoco.MjModel, joint: str) -> list[tuple[str, int, list[int]]]:
    """(link joint name, actuator, qpos addresses summing to the link angle) of each position
    servo driving a joint named ``*_<joint>`` (both legs' knees for ``"knee"``)."""
    out = []
    for a in range(model.nu):
        affine = model.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE
        if not affine or model.actuator_biasprm[a, 1] >= 0:
            continue  # not a position servo (a torque motor has no position feedback)
        jid = int(model.actuator_trnid[a, 0])
        name = model.joint(jid).name.removesuffix("_motor")
        if not name.endswith(f"_{joint}"):
            continue
        parts = [jid]
        link = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if link >= 0 and link != jid:
            parts.append(link)  # series-elastic: link angle = motor + spring deflection
        out.append((name, a, [int(model.jnt_qposadr[j]) for j in parts]))
    return out


def _joint_name(arg: str) -> None:
    if not arg:
        raise MetricArgError("name a joint, e.g. tracking_delay:knee or tracking_delay:knee@2-10")


#: Argument check of ``tracking_delay``: a joint name, then optionally ``@t0-t1``.
_tracking_delay_arg = qualified_check(_joint_name, parse_window)


@metric(
    "tracking_delay",
    "lag of the link angle behind its position command, the smallest over the joints "
    "'*_<arg>' (arg 'knee' or 'knee@t0-t1') [s]",
    arg=_tracking_delay_arg,
)
def _tracking_delay(d: LogData, arg: str) -> float:
    """Paper II, Hardware Limitations: "a delayed position tracking of at least 20 ms in the
    stiffest and aggressive conditions" (Fig. 4: commands against link encoders in place).

    The paper's delay is what its controller saw: a command sent against the link encoder
    read back. Here that is the lag of the link angle of the logged state (motor plus
    spring for a series-elastic joint) behind the servo's target (``ctrl``, logged every
    physics step), which is everything between the controller's output and the link's
    motion (servo, motor, spring, load). A sensing delay the spec adds (``sensors.delay``)
    is not counted: it is an input of the run, and a row on it could not fail. Window ``@t0-t1`` (default: the
    whole pre-fall run); the smallest lag over the matching joints, each of which must
    follow its command (correlation ≥ :data:`MIN_TRACKING_CORRELATION`).
    """
    _tracking_delay_arg(arg)
    joint, _, window = arg.partition("@")
    servos = _position_servos(d.model, joint)
    if not servos:
        raise NotMeasurable(f"no position servo drives a joint '*_{joint}' in this robot")
    d.require_states(2)
    t_u, ctrl = d.inputs_ctrl
    lo, hi = (float(d.t[0]), float(d.t[-1])) if not window else parse_window(window)
    if window:
        d.require_until(hi, f"the end of the window {window}")
    lo, hi = max(lo, float(d.t[0]), float(t_u[0])), min(hi, float(d.t[-1]), float(t_u[-1]))
    grid = np.arange(lo, hi, TRACKING_GRID)
    lags = []
    for name, a, adr in servos:
        command = np.interp(grid, t_u, ctrl[:, a])
        link = np.interp(grid, d.t, d.qpos[:, adr].sum(axis=1))
        lag, corr = tracking_lag(command, link, TRACKING_GRID, MAX_TRACKING_LAG)
        if corr < MIN_TRACKING_CORRELATION:
            raise NotMeasurable(
                f"{name} does not follow its command (correlation {corr:.2f} < "
                f"{MIN_TRACKING_CORRELATION})"
            )
        lags.append(lag)
    return float(min(lags))


# ---- dead-zone thresholds against the open-loop error spread (Fig. 9, Eq. 27) -------------

#: The sagittal state errors the dead-zones act on, in ``e_raw`` order (Eq. 15).
ERROR_NAMES = ("e1x", "e2x", "de1x", "de2x")


#: Argument check of ``dead_zone_spread``: an error name, then optionally ``@t0-t1``.
_dead_zone_spread_arg = qualified_check(choice_check(*ERROR_NAMES, required=True), parse_window)


@metric(
    "dead_zone_spread",
    "standard deviation of a filtered sagittal state error (arg e1x, e2x, de1x or de2x, "
    "optionally '@t0-t1') over the run, divided by the dead-zone threshold a the run's "
    "controller used for it (Fig. 9: a is set to that deviation) [-]",
    arg=_dead_zone_spread_arg,
)
def _dead_zone_spread(d: LogData, arg: str) -> float:
    """Paper II, Fig. 9 and Eq. 27: "We simply fit a Gaussian model on these measurements and
    estimate the typical standard deviation which is later used to determine the threshold
    for a dead-zone function" (the filtered state errors of open-loop in-place walking).
    :func:`_error_spread` divided by the run's threshold (its spec's controller parameters,
    defaults included)."""
    from walkrepro.controllers import controller_params

    spread = _error_spread(d, arg)
    params = controller_params(d.spec.controller)
    thresholds = getattr(params, "dead_zone_thresholds", None)
    if thresholds is None:
        raise NotMeasurable(f"controller {d.spec.controller.type!r} has no dead-zones")
    return spread / thresholds[ERROR_NAMES.index(arg.partition("@")[0])]


@metric(
    "error_spread",
    "standard deviation of a filtered sagittal state error (arg e1x, e2x [m], de1x or de2x "
    "[m/s], optionally '@t0-t1') over the run: Fig. 9's statistic, which sets the dead-zone "
    "threshold a",
    arg=_dead_zone_spread_arg,
)
def _error_spread(d: LogData, arg: str) -> float:
    """Paper II, Fig. 9: the standard deviation of the controller's filtered error before the
    dead-zone (``e_raw``), the claim being about them. Window ``@t0-t1`` (default: the whole
    pre-fall run)."""
    _dead_zone_spread_arg(arg)
    name, _, window = arg.partition("@")
    t, e = d.require_signal("e_raw")
    if window:
        d.require_until(parse_window(window)[1], f"the end of the window {window}")
        keep = _window(t, window)
        t, e = t[keep], e[keep]
    if t.size < 2:
        raise NotMeasurable(
            f"fewer than two filtered errors in the window {window or 'of the run'}"
        )
    return float(np.std(e[:, ERROR_NAMES.index(name)]))


# ---- the gait's shape from the log: lift, double support, bounce, springs, timing ----------
#
# Paper II describes its in-place gait with a few numbers besides its figures' results: the
# foot lift (Fig. 8: "about 2.4 cm"), the double support the springs produce (3LP Model:
# "approximately 20 % in each phase"), the knee springs' stance compressions (Fig. 7) and
# when the feet touch down against the fixed timing (Fig. 19). Each is read here from the
# logged contact forces and states alone.

#: A swing is an unloaded interval of a foot at least this long [s] (the core's LIFT_TIME: a
#: tenth of the shortest swing of the three gaits, longer than a landing bounce).
MIN_SWING_TIME = LIFT_TIME
#: A foot carries its share of single support above this fraction of the robot's weight: Eq.
#: 21 scales μ by |F|/(m g), so μ is the compression at F = m g; samples above 0.9 m g keep
#: the stance at (nearly) full load and drop the weight transfers of double support.
FULL_LOAD_FRACTION = 0.9


class Swing(NamedTuple):
    """An unloaded interval of one foot (:func:`foot_swings`), indices on the contact time base."""

    #: ``left_foot`` or ``right_foot``.
    foot: str
    #: first unloaded sample (lift-off).
    off: int
    #: first loaded sample after it (touchdown).
    on: int


def loaded_mask(fz: np.ndarray, weight: float) -> np.ndarray:
    """Whether a foot carries load at each sample, with the core's hysteresis.

    Loaded above ``TOUCHDOWN_WEIGHT_FRACTION · weight`` (10 %), unloaded below
    ``LIFTOFF_WEIGHT_FRACTION · weight`` (5 %), unchanged between (as
    :func:`walkrepro.evaluation.metrics.detect_steps`, whose step detection also asks for a clearance;
    a load claim asks only for the load). The first sample is loaded above the 5 % mark.

    Args:
        fz: vertical contact force on the foot, shape (N,) [N].
        weight: robot weight m g [N].
    """
    on, off = TOUCHDOWN_WEIGHT_FRACTION * weight, LIFTOFF_WEIGHT_FRACTION * weight
    out = np.zeros(fz.size, dtype=bool)
    state = bool(fz.size) and bool(fz[0] > off)
    for i, f in enumerate(fz):
        if state and f < off:
            state = False
        elif not state and f > on:
            state = True
        out[i] = state
    return out


def foot_swings(t: np.ndarray, loaded: np.ndarray, foot: str) -> list[Swing]:
    """The unloaded intervals of one foot that end in a touchdown and last at least
    :data:`MIN_SWING_TIME` (shorter ones are chatter of a landing or a weight shift)."""
    swings, off = [], None
    for i in range(1, loaded.size):
        if loaded[i - 1] and not loaded[i]:
            off = i
        elif off is not None and loaded[i] and not loaded[i - 1]:
            if t[i] - t[off] >= MIN_SWING_TIME:
                swings.append(Swing(foot, off, i))
            off = None
    return swings


class Loading(NamedTuple):
    """Both feet's load over the contact messages (:func:`loading`)."""

    #: contact message times, shape (N,) [s].
    t: np.ndarray
    #: each foot's loaded mask, ``left_foot`` and ``right_foot`` -> shape (N,).
    loaded: dict[str, np.ndarray]
    #: each foot's vertical contact force, shape (N,) [N].
    fz: dict[str, np.ndarray]
    #: the swings of both feet, in touchdown order.
    swings: list[Swing]


def loading(d: LogData) -> Loading:
    """Load masks (:func:`loaded_mask`) and swings (:func:`foot_swings`) of both feet, from
    the logged contact forces (pre-fall)."""
    d.require_states()
    d.require_contacts()
    weight = d.robot_mass * GRAVITY
    t = d.contact_t
    fz = {foot: d.foot_normal_force(foot) for foot in FOOT_BODIES}
    loaded = {foot: loaded_mask(fz[foot], weight) for foot in FOOT_BODIES}
    swings = [s for foot in FOOT_BODIES for s in foot_swings(t, loaded[foot], foot)]
    return Loading(t, loaded, fz, sorted(swings, key=lambda s: s.on))


def _window_or_run(d: LogData, arg: str) -> tuple[float, float]:
    """The window ``t0-t1`` the data must reach, or the whole pre-fall run."""
    if not arg:
        return -math.inf, math.inf
    lo, hi = parse_window(arg)
    d.require_until(hi, f"the end of the window {arg}")
    return lo, hi


def double_support_fractions(
    t: np.ndarray, loaded: dict[str, np.ndarray], touchdowns: np.ndarray
) -> np.ndarray:
    """Fraction of each step in which both feet carry load [-].

    A step runs from one touchdown to the next (``touchdowns``, any foot, sorted) [s]; its
    double support is the time both masks are loaded, over the step's duration. Each sample
    stands for the time to the next one.

    Args:
        t: sample times, shape (N,) [s].
        loaded: each foot's loaded mask, shape (N,).
        touchdowns: touchdown times [s].
    """
    both = np.logical_and(*loaded.values())
    dt = np.diff(t, append=t[-1])
    out = []
    for a, b in zip(touchdowns[:-1], touchdowns[1:], strict=True):
        inside = (t >= a) & (t < b)
        out.append(float(np.sum(dt[inside & both]) / (b - a)))
    return np.array(out)


@metric(
    "double_support_fraction",
    "median over the steps (touchdown to next touchdown, from the contact forces) of the "
    "fraction of the step in which both feet carry more than 10 % of the weight (5 % to "
    "unload) [-] (arg 't0-t1': steps inside the window)",
    arg=window_check,
)
def _double_support_fraction(d: LogData, arg: str) -> float:
    """Paper II, 3LP Model: "the intrinsic physical compliance of COMAN naturally produces a
    double support phase of approximately 20% in each phase" (and Eq. 24's t₁ = 0.2 T, "the
    force transfer rate during contact switch time (double support ≈ 20%)").

    A touchdown is a foot's loading after a swing of at least :data:`MIN_SWING_TIME`
    (:func:`foot_swings`); a step runs from one touchdown to the next, whichever foot;
    its double support is the time both feet are loaded (:func:`loaded_mask`). Window
    (steps that start and end in it; the data must reach its end), else pre-fall; the
    median over at least two steps.
    """
    lo, hi = _window_or_run(d, arg)
    ld = loading(d)
    touchdowns = np.array([ld.t[s.on] for s in ld.swings])
    touchdowns = touchdowns[(touchdowns >= lo) & (touchdowns <= hi)]
    if touchdowns.size < 3:
        raise NotMeasurable(
            f"{max(touchdowns.size - 1, 0)} step(s) between touchdowns in the window "
            f"{arg or 'of the run'}, 2 needed{d.stopped_note()}"
        )
    return float(np.median(double_support_fractions(ld.t, ld.loaded, touchdowns)))


def swing_lifts(centre_z: np.ndarray, loaded: np.ndarray, swings: list[Swing]) -> np.ndarray:
    """Peak rise of the sole centre in each swing above where the foot stood before it [m].

    The floor level of a swing is the median sole-centre height over the foot's loaded
    samples of the ground phase before it (from the previous swing's touchdown, or the log's
    start); the lift is the highest sole-centre height in the swing minus that level, NaN
    for a swing with no loaded sample before it.

    Args:
        centre_z: sole-centre height on the contact time base, shape (N,) [m].
        loaded: the foot's loaded mask, shape (N,).
        swings: that foot's swings, in time order.
    """
    out, start = np.full(len(swings), math.nan), 0
    for k, s in enumerate(swings):
        ground = np.flatnonzero(loaded[start : s.off]) + start
        if ground.size:
            out[k] = float(np.max(centre_z[s.off : s.on]) - np.median(centre_z[ground]))
        start = s.on
    return out


@metric(
    "swing_lift",
    "median over the swings (unloaded intervals of ≥ 50 ms, from the contact forces) of the "
    "swing sole centre's peak height above where that foot stood before the swing [m] (arg "
    "'t0-t1': swings that touch down in the window)",
    arg=window_check,
)
def _swing_lift(d: LogData, arg: str) -> float:
    """Paper II, Lateral Plane, Eqs. 22-23 and Fig. 8: the pelvis roll and the half-sine
    swing-foot trajectory "lift it about 2.4 cm in total"; Fig. 8 caption: "In practice, an
    open-loop foot lift of about 2.4cm is achieved through a combination of both strategies".
    Fig. 6: a lift of 2-3 cm "cannot be completely realized due to saturated knee velocities".

    The foot is the paper's foot point, the middle of the sole (site ``<side>_sole``), its
    height in the world frame; a swing is a foot's unloaded interval (:func:`foot_swings`),
    so a foot that is unloaded but scrapes the floor counts with its small lift, where the
    step count (``footsteps``, 1 cm of clearance) would drop it. Window (swings that touch
    down in it; the data must reach its end), else pre-fall.
    """
    lo, hi = _window_or_run(d, arg)
    ld = loading(d)
    idx = d.state_index(ld.t)
    lifts = []
    for foot in FOOT_BODIES:
        mine = [s for s in ld.swings if s.foot == foot]
        z = d.sole_tracks[foot].centre[idx, 2]
        for s, lift in zip(mine, swing_lifts(z, ld.loaded[foot], mine), strict=True):
            if lo <= ld.t[s.on] <= hi and not math.isnan(lift):
                lifts.append(lift)
    if not lifts:
        raise NotMeasurable(f"no swing in the window {arg or 'of the run'}{d.stopped_note()}")
    return float(np.median(lifts))


def lateral_excursions(
    t: np.ndarray, pelvis_xy: np.ndarray, yaw: np.ndarray, touchdowns: np.ndarray
) -> np.ndarray:
    """Peak-to-peak lateral pelvis displacement in each stride [m].

    A stride runs from one touchdown of a foot to its next (``touchdowns``: one foot's,
    sorted) [s]. Lateral is the horizontal axis normal to the pelvis's mean heading over the
    stride (its mean yaw), so a gait that turns slowly keeps its bounce apart from its
    progression.

    Args:
        t: state times, shape (N,) [s].
        pelvis_xy: pelvis position in the world, shape (N, 2) [m].
        yaw: pelvis yaw in the world, shape (N,) [rad].
        touchdowns: one foot's touchdown times [s].
    """
    out = []
    for a, b in zip(touchdowns[:-1], touchdowns[1:], strict=True):
        inside = (t >= a) & (t <= b)
        if not inside.any():
            continue
        heading = math.atan2(np.mean(np.sin(yaw[inside])), np.mean(np.cos(yaw[inside])))
        lateral = pelvis_xy[inside] @ np.array([-math.sin(heading), math.cos(heading)])
        out.append(float(np.max(lateral) - np.min(lateral)))
    return np.array(out)


@metric(
    "lateral_bounce",
    "median over the strides (a foot's touchdown to its next, from the contact forces) of "
    "the pelvis's peak-to-peak displacement normal to its heading [m] (arg 't0-t1': strides "
    "inside the window)",
    arg=window_check,
)
def _lateral_bounce(d: LogData, arg: str) -> float:
    """Paper II, Lateral Plane: "Lateral bounces in 3LP are as small as 2.2 cm total
    displacement of the pelvis, given the desired step width of 25 cm and step time of
    T = 0.4 s"; the robot's pelvis roll (Eq. 22) makes it "converge to a natural lateral
    bouncing". Total displacement is read as peak to peak, left extreme to right extreme,
    over a stride (two steps).

    The pelvis is the free joint's body origin (``qpos``), in the world frame projected on
    the axis normal to the stride's mean pelvis heading (:func:`lateral_excursions`);
    touchdowns as :func:`foot_swings`, strides of both feet pooled. Window (strides that
    start and end in it; the data must reach its end), else pre-fall.
    """
    lo, hi = _window_or_run(d, arg)
    ld = loading(d)
    w, x, y, z = d.qpos[:, 3], d.qpos[:, 4], d.qpos[:, 5], d.qpos[:, 6]
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    bounces = []
    for foot in FOOT_BODIES:
        tds = np.array([ld.t[s.on] for s in ld.swings if s.foot == foot])
        tds = tds[(tds >= lo) & (tds <= hi)]
        bounces.extend(lateral_excursions(d.t, d.qpos[:, :2], yaw, tds))
    if not bounces:
        raise NotMeasurable(
            f"no stride (two touchdowns of one foot) in the window {arg or 'of the run'}"
            f"{d.stopped_note()}"
        )
    return float(np.median(bounces))


def _knee_side(arg: str) -> None:
    if arg not in ("left", "right"):
        raise MetricArgError(f"argument {arg!r} is neither left nor right (the knee's side)")


#: Argument check of ``knee_spring_compression``: a side, then optionally ``@t0-t1``.
_knee_compression_arg = qualified_check(_knee_side, parse_window)


def spring_compression(deflection: np.ndarray, link_angle: np.ndarray) -> np.ndarray:
    """Series-spring deflection counted positive where the load bends the joint further than
    its motor: deflection (link − motor) signed by the joint's bend (the sign of the
    median link angle) [rad].

    Args:
        deflection: link minus motor angle, shape (N,) [rad].
        link_angle: the link angle (motor plus spring), shape (N,) [rad].
    """
    bend = float(np.median(link_angle))
    if bend == 0.0:
        raise NotMeasurable("the joint is straight: no direction of bending to sign it")
    return math.copysign(1.0, bend) * deflection


@metric(
    "knee_spring_compression",
    "median series-spring deflection of the knee (arg 'left' or 'right', optionally "
    "'@t0-t1'), link minus motor angle signed so that bending further under the load is "
    "positive, over the samples where that foot carries at least 90 % of the weight [rad]",
    arg=_knee_compression_arg,
)
def _knee_spring_compression(d: LogData, arg: str) -> float:
    """The median of :func:`full_load_knee_compressions` (see there)."""
    return float(np.median(full_load_knee_compressions(d, arg)))


@metric(
    "knee_spring_compression_mean",
    "mean series-spring deflection of the knee (arg 'left' or 'right', optionally '@t0-t1') "
    "over the samples where that foot carries at least 90 % of the weight: Fig. 7's "
    "'statistical average of these histograms', μ of Eq. 21 [rad]",
    arg=_knee_compression_arg,
)
def _knee_spring_compression_mean(d: LogData, arg: str) -> float:
    """Paper II, SEA Compensation: "the statistical average of these histograms is used as a
    constant" (μ_left, μ_right of Eq. 21): the mean of :func:`full_load_knee_compressions`."""
    return float(np.mean(full_load_knee_compressions(d, arg)))


@metric(
    "knee_deflection_ratio",
    "mean knee spring compression at full load (knee_spring_compression_mean, arg 'left' or "
    "'right', optionally '@t0-t1') divided by the μ of that knee the run's controller used "
    "(Eq. 21's constant, controller parameter knee_deflection) [-]",
    arg=_knee_compression_arg,
)
def _knee_deflection_ratio(d: LogData, arg: str) -> float:
    """Paper II, SEA Compensation, Eq. 21: μ is the average compression of the open-loop
    in-place gait; 1 when the run's μ is what the run measures. Not measurable when the
    controller derives μ itself (``knee_deflection`` None) or has no μ."""
    from walkrepro.controllers import controller_params

    params = controller_params(d.spec.controller)
    if not hasattr(params, "knee_deflection"):
        raise NotMeasurable(f"controller {d.spec.controller.type!r} has no knee compensation μ")
    mu = params.knee_deflection
    if mu is None:
        raise NotMeasurable("the run's μ is derived from the home posture, not set")
    side = arg.partition("@")[0]
    mu_side = (mu[0] if side == "left" else mu[1]) if isinstance(mu, tuple) else mu
    if mu_side == 0.0:
        raise NotMeasurable(f"the run's {side} μ is 0: no compensation to compare with")
    return _knee_spring_compression_mean(d, arg) / mu_side


def full_load_knee_compressions(d: LogData, arg: str) -> np.ndarray:
    """Paper II, SEA Compensation and Fig. 7: "we perform an open-loop in-place walking gait
    before experiments to identify steady-state knee spring compressions which are plotted
    as histograms in Figure 7"; their average μ enters Eq. 21 scaled by |F|/(m g), so μ is
    the compression at full load. "Given a shank length of ≈ 25 cm, δθ_left(t) and
    δθ_right(t) each compensate about 3.2 cm and 1.4 cm": μ_left ≈ 0.128 rad, μ_right ≈
    0.056 rad, on springs that "permanently deflect over time and lose their original
    stiffness" (Fig. 7 caption).

    The deflection is the logged state of the knee's spring joint (``<l|r>_knee``, in series
    with its motor joint ``<l|r>_knee_motor``: link = motor + spring), signed by
    :func:`spring_compression`; the samples are those on the contact time base where the
    foot's vertical contact force is at least :data:`FULL_LOAD_FRACTION` of the weight
    (single support at full load). Window ``@t0-t1`` (the data must reach its end), else
    pre-fall.
    """
    _knee_compression_arg(arg)
    side, _, window = arg.partition("@")
    lo, hi = _window_or_run(d, window)
    model = d.model
    prefix = side[0]
    motor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{prefix}_knee_motor")
    spring = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{prefix}_knee")
    if motor < 0 or spring < 0:
        raise NotMeasurable(
            f"the robot has no series-elastic {side} knee ({prefix}_knee_motor and {prefix}_knee)"
        )
    d.require_states()
    d.require_contacts()
    t = d.contact_t
    fz = d.foot_normal_force(f"{side}_foot")
    full = (fz >= FULL_LOAD_FRACTION * d.robot_mass * GRAVITY) & (t >= lo) & (t <= hi)
    if not full.any():
        raise NotMeasurable(
            f"the {side} foot never carries {FULL_LOAD_FRACTION:.0%} of the weight in the "
            f"window {window or 'of the run'}{d.stopped_note()}"
        )
    idx = d.state_index(t[full])
    deflection = d.qpos[idx, model.jnt_qposadr[spring]]
    link = d.qpos[idx, model.jnt_qposadr[motor]] + deflection
    return spring_compression(deflection, link)


def touchdown_leads(phases: np.ndarray, swings: list[tuple[float, float]]) -> np.ndarray:
    """How early each swing touched down against the fixed-timing gait's phase change [s].

    A swing (lift-off, touchdown) [s] belongs to the first phase change after its midpoint,
    the touchdown the gait expects; the lead is that phase change's time minus the
    touchdown's (positive: earlier than expected). Swings after the last phase change are
    dropped.

    Args:
        phases: phase-change times of the gait, sorted [s].
        swings: (lift-off, touchdown) times of each swing [s].
    """
    out = []
    for off, on in swings:
        k = int(np.searchsorted(phases, 0.5 * (off + on), side="right"))
        if k < phases.size:
            out.append(float(phases[k] - on))
    return np.array(out)


def _leads(d: LogData, arg: str) -> np.ndarray:
    """:func:`touchdown_leads` of the run's swings whose expected touchdown lies in the
    window ``arg`` (the data must reach its end), else every one before any fall."""
    lo, hi = _window_or_run(d, arg)
    phases = _phase_times(d)
    if phases.size < 2:
        raise NotMeasurable(
            f"{phases.size} phase change(s) logged: no fixed-timing gait{d.stopped_note()}"
        )
    ld = loading(d)
    swings = [(float(ld.t[s.off]), float(ld.t[s.on])) for s in ld.swings]
    # The phase change each swing belongs to, to select by the window.
    mids = np.array([0.5 * (a + b) for a, b in swings])
    k = np.searchsorted(phases, mids, side="right")
    expected = np.where(k < phases.size, phases[np.minimum(k, phases.size - 1)], np.inf)
    chosen = [s for s, e in zip(swings, expected, strict=True) if lo <= e <= hi]
    leads = touchdown_leads(phases, chosen)
    if not leads.size:
        raise NotMeasurable(
            f"no touchdown expected in the window {arg or 'of the run'}{d.stopped_note()}"
        )
    return leads


@metric(
    "touchdown_lead",
    "mean over the swings (from the contact forces) of the gait's phase change the swing "
    "belongs to minus the swing's touchdown [s]: positive when the feet land earlier than "
    "the fixed timing expects (arg 't0-t1': expected touchdowns in the window)",
    arg=window_check,
)
def _touchdown_lead(d: LogData, arg: str) -> float:
    """Paper II, Walking Gait Generation, Fig. 19: "the actual phase transition takes place
    slightly earlier than expected in faster walking speeds. This can be due to a tracking
    delay in the hip joints or extra spring compressions in the stance leg which limit the
    ground clearance and influence the swing phase timing."

    The expected touchdowns are the phase changes of the fixed-timing gait (``phase``
    events, every T from the gait's start: its clock, not a command); the actual ones are
    where the swing foot carries 10 % of the weight again (:func:`foot_swings`); see
    :func:`touchdown_leads`. The mean, not the median: the claim is a systematic shift of
    the phase transitions, and an early landing every few steps is part of it. Window
    (expected touchdowns in it; the data must reach its end), else pre-fall.
    """
    return float(np.mean(_leads(d, arg)))


@metric(
    "max_touchdown_lead",
    "largest lead of a touchdown on the gait's phase change it belongs to [s] (as "
    "touchdown_lead; arg 't0-t1'): the earliest landing against the fixed timing",
    arg=window_check,
)
def _max_touchdown_lead(d: LogData, arg: str) -> float:
    """Paper II, Adaptive Foot Lift and Fig. 15: after a push "the toes might touch the
    ground much earlier than expected", and "unexpected touchdown events which prevent a
    complete swing when happening earlier than expected". The largest of
    :func:`touchdown_leads` in the window (see ``touchdown_lead``)."""
    return float(np.max(_leads(d, arg)))


@metric(
    "touchdown_lead_spread",
    "standard deviation over the swings of the touchdown's lead on the gait's phase change "
    "it belongs to [s] (as touchdown_lead; arg 't0-t1'): how irregular the touchdowns are "
    "against the fixed timing",
    arg=window_check,
)
def _touchdown_lead_spread(d: LogData, arg: str) -> float:
    """Paper II, In-Place Walking without dead-zones and Fig. 15: "actual phase change
    moments might happen earlier or later", "unexpected touchdown events". The standard
    deviation of :func:`touchdown_leads` in the window (at least two swings)."""
    leads = _leads(d, arg)
    if leads.size < 2:
        raise NotMeasurable(f"{leads.size} touchdown in the window {arg}: no spread")
    return float(np.std(leads))


@metric(
    "pelvis_yaw_change",
    "largest |pelvis yaw − its yaw at t0| over the window 't0-t1' [rad] (arg required; the "
    "run must reach t1)",
    arg=window_check,
)
def _pelvis_yaw_change(d: LogData, arg: str) -> float:
    """Paper II, Strong Pushes and Fig. 17: "a transverse slippage happens in the right foot
    which rotates the robot slightly". The rotation about the vertical of the floating base
    (the pelvis, ``qpos[3:7]``, w-x-y-z) from the window's start, unwrapped; a fall inside
    the window makes it not measurable."""
    if not arg:
        raise MetricArgError("needs a window, e.g. pelvis_yaw_change:4-8")
    lo, hi = _window_or_run(d, arg)
    inside = (d.t >= lo) & (d.t <= hi)
    if inside.sum() < 2:
        raise NotMeasurable(f"fewer than two states in the window {arg}")
    w, x, y, z = d.qpos[inside, 3:7].T
    yaw = np.unwrap(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))
    return float(np.max(np.abs(yaw - yaw[0])))


@metric(
    "peak_knee_motor_speed",
    "largest |velocity| of the knees' motor shafts (joints '*_knee_motor') [rad/s] (arg "
    "'t0-t1': over that window, which the run must reach)",
    arg=window_check,
)
def _peak_knee_motor_speed(d: LogData, arg: str) -> float:
    """Paper II, Actuator Limitations and Fig. 6: "a leg lift of 2 – 3 cm cannot be
    completely realized due to saturated knee velocities" (θ̇_max = ± 2.43 rad/s at 15 V).
    The logged motor-side joint velocities (``qvel``) of the series-elastic knees, the
    shaft the 15 V bound acts on."""
    lo, hi = _window_or_run(d, arg)
    model = d.model
    dofs = [
        int(model.jnt_dofadr[j])
        for j in range(model.njnt)
        if (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or "").endswith("_knee_motor")
    ]
    if not dofs:
        raise NotMeasurable("the robot has no knee motor joints ('*_knee_motor')")
    d.require_states(2)
    inside = (d.t >= lo) & (d.t <= hi)
    return float(np.max(np.abs(d.qvel[np.ix_(inside, dofs)])))


# ---- early swing: the toes' release and the clearance (Figs. 11-12) -------------------------


def _phase_fraction(arg: str) -> None:
    try:
        frac = float(arg)
    except ValueError:
        raise MetricArgError(
            f"argument {arg!r} is not a fraction of the step time, e.g. 0.1 (t = 0.1 T)"
        ) from None
    if not 0.0 <= frac <= 1.0:
        raise MetricArgError(f"the fraction of the step time {frac:g} is not in [0, 1]")


#: Argument check of ``swing_foot_load`` and ``swing_toe_load``: a fraction of the step time,
#: then optionally ``@t0-t1``.
_swing_load_arg = qualified_check(_phase_fraction, parse_window)


def _sole_frames(d: LogData, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sole centres (n, foot: left, right, xyz) [m] and the soles' horizontal forward unit
    axes (n, foot, xy) in the world, at given times, from the logged state."""
    model, left, right, _ = _site_ids(d.log.scene_xml)
    data = mujoco.MjData(model)
    centres, axes = np.zeros((times.size, 2, 3)), np.zeros((times.size, 2, 2))
    for k, i in enumerate(d.state_index(times)):
        data.qpos[:] = d.qpos[i]
        mujoco.mj_kinematics(model, data)
        for j, site in enumerate((left, right)):
            centres[k, j] = data.site_xpos[site]
            forward = data.site_xmat[site].reshape(3, 3)[:2, 0]  # the sole's x axis, horizontal
            axes[k, j] = forward / max(float(np.linalg.norm(forward)), 1e-12)
    return centres, axes


def early_swing_loads(fz: np.ndarray, cop_ahead: np.ndarray | None, weight: float) -> np.ndarray:
    """Vertical load of each starting swing foot as a fraction of the weight [-], counting
    only contact on the toe half of the sole when ``cop_ahead`` is given.

    Args:
        fz: vertical contact force on the foot that begins its swing, one per phase change,
            shape (n,) [N].
        cop_ahead: that foot's centre of pressure ahead of its sole centre along the sole's
            forward axis, shape (n,) [m], or None to count any contact.
        weight: robot weight m g [N].
    """
    load = np.maximum(fz, 0.0) / weight
    if cop_ahead is not None:
        load = np.where(cop_ahead > 0.0, load, 0.0)
    return load


def _early_swing_load(d: LogData, arg: str, toes: bool) -> float:
    """The largest :func:`early_swing_loads` over the window's phase changes (see
    ``swing_foot_load``)."""
    _swing_load_arg(arg)
    head, _, window = arg.partition("@")
    frac = float(head)
    lo, hi = _window_or_run(d, window)
    d.require_states()
    d.require_contacts()
    events = [
        e
        for e in d.events
        if e.get("kind") == "phase" and e.get("swing") in ("left", "right") and lo <= e["t"] <= hi
    ]
    phases = _phase_times(d)
    if phases.size < 2 or not events:
        raise NotMeasurable(
            f"no phase change of the fixed-timing gait in the window {window or 'of the run'}"
            f"{d.stopped_note()}"
        )
    step_time = float(np.median(np.diff(phases)))  # T [s]
    times = np.array([e["t"] + frac * step_time for e in events])
    if window:
        d.require_until(float(times[-1]), f"phase + {frac:g} T of the window's last phase change")
    else:  # pre-fall: the phase changes whose instant the data reach
        keep = times <= d.data_end
        events, times = [e for e, k in zip(events, keep, strict=True) if k], times[keep]
        if not events:
            raise NotMeasurable(f"no phase change read at phase + {frac:g} T{d.stopped_note()}")
    k = np.minimum(np.searchsorted(d.contact_t, times), d.contact_t.size - 1)
    feet = [0 if e["swing"] == "left" else 1 for e in events]
    fz = np.array([d.foot_normal_force(FOOT_BODIES[f])[i] for f, i in zip(feet, k, strict=True)])
    cop_ahead = None
    if toes:
        centres, axes = _sole_frames(d, d.contact_t[k])
        cop_ahead = np.zeros(len(events))
        for n, (f, i) in enumerate(zip(feet, k, strict=True)):
            w = d.contact_wrench(f"{FOOT_BODIES[f]}/*")[i]
            if w[2] <= 0.0:
                continue
            cop = np.array([-w[4] / w[2], w[3] / w[2]])  # the floor's CoP (z = 0) [m]
            cop_ahead[n] = float((cop - centres[n, f, :2]) @ axes[n, f])
    return float(np.max(early_swing_loads(fz, cop_ahead, d.robot_mass * GRAVITY)))


@metric(
    "swing_foot_load",
    "largest vertical contact force, as a fraction of the weight, on the foot that begins "
    "its swing at a phase change, read at phase + f·T (arg 'f', optionally '@t0-t1': phase "
    "changes in the window; T the gait's median phase interval) [-]",
    arg=_swing_load_arg,
)
def _swing_foot_load(d: LogData, arg: str) -> float:
    """Paper II, Fig. 11 caption: "The adaptive lift, depending on the current posture,
    provides an extra lift on the commanded posture which leads to enough ground clearance
    shown at t = 0.2T." A foot clear of the ground carries no load: below the core's lift-off
    mark (5 % of the weight) it is unloaded.

    The phase changes are the fixed-timing gait's ``phase`` events, each naming the foot
    that swings in the step it starts (``swing``); the load is that foot's logged vertical
    contact force (every floor geom) at the first contact message at or after phase + f·T.
    Window (phase changes in it; the data must reach its end), else pre-fall."""
    return _early_swing_load(d, arg, toes=False)


@metric(
    "swing_toe_load",
    "as swing_foot_load, counting the foot's load only when its centre of pressure lies "
    "ahead of its sole centre (the toe half) [-] (arg 'f', optionally '@t0-t1')",
    arg=_swing_load_arg,
)
def _swing_toe_load(d: LogData, arg: str) -> float:
    """Paper II, Adaptive Foot Lift and Figs. 11-12: after a push that moves the pelvis
    forward, "in the early next swing phase, although the robot attempts to lift the foot
    through fixed and adaptive strategies, the ankle spring is still releasing, causing the
    toes to keep touching the ground at time t = 0.1T".

    As ``swing_foot_load``; the centre of pressure is the foot's logged floor wrench
    (torque about the world origin) on the floor plane z = 0, x = −τ_y/F_z, y = τ_x/F_z, and
    "ahead" is along the sole's forward axis (site ``<side>_sole``, horizontal), so a heel
    contact counts 0."""
    return _early_swing_load(d, arg, toes=True)


# ---- the resting posture against its ghost (Fig. 5) -----------------------------------------


def spring_joints(model: mujoco.MjModel) -> list[int]:
    """Qpos addresses of the series springs: each joint ``<name>`` with a motor joint
    ``<name>_motor`` in series (link angle = motor + spring)."""
    out = []
    for j in range(model.njnt):
        name = model.joint(j).name
        if name and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{name}_motor") >= 0:
            out.append(int(model.jnt_qposadr[j]))
    return out


def com_over_feet(model: mujoco.MjModel, data: mujoco.MjData, qpos: np.ndarray) -> np.ndarray:
    """The robot's CoM in the feet frame [m]: origin midway between the sole centres, axes
    of the left sole (site ``left_sole``), so a posture whose feet are tilted is read as if
    they stood flat."""
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    left, right = model.site("left_sole").id, model.site("right_sole").id
    origin = 0.5 * (data.site_xpos[left] + data.site_xpos[right])
    rot = data.site_xmat[left].reshape(3, 3)
    return rot.T @ (data.subtree_com[model.body("pelvis").id] - origin)


@metric(
    "ghost_com_offset",
    "mean over the window (arg 't0-t1', default the run) of the forward CoM position over "
    "the feet of the actual posture (link angles) minus that of the ghost posture (motor "
    "angles, every series spring at rest) [m]: negative when the springs move the CoM back",
    arg=window_check,
)
def _ghost_com_offset(d: LogData, arg: str) -> float:
    """Paper II, Fig. 5 caption: "When commanding a resting posture with the CoP in the middle
    of support polygon, spring compressions lead to a different posture. Ankle spring
    compressions make the robot lean forward while knee spring compressions make it lean
    backward. [...] The actual CoM might also move backward for 1 – 2 cm." The ghost robot
    is "referring to pre-spring motor positions" (Fig. 3).

    Each logged state gives two postures: the actual one (``qpos``) and its ghost, the same
    state with every series spring (:func:`spring_joints`) at zero deflection. Each CoM is
    read in its own feet frame (:func:`com_over_feet`: the ghost stands on its own soles);
    the metric is the mean forward (sole x) difference, actual minus ghost. Window (the
    data must reach its end), else pre-fall."""
    lo, hi = _window_or_run(d, arg)
    d.require_states()
    model = d.model
    springs = spring_joints(model)
    if not springs:
        raise NotMeasurable("the robot has no series-elastic joints: its ghost is itself")
    inside = np.flatnonzero((d.t >= lo) & (d.t <= hi))
    if not inside.size:
        raise NotMeasurable(f"no state logged in the window {arg}")
    data = mujoco.MjData(model)
    offsets = []
    for i in inside:
        ghost = d.qpos[i].copy()
        ghost[springs] = 0.0
        offsets.append(
            com_over_feet(model, data, d.qpos[i])[0] - com_over_feet(model, data, ghost)[0]
        )
    return float(np.mean(offsets))
