"""Metrics computed from a log alone: footsteps, speed, falls, peak forces, FSM timing.

Nothing here touches a live simulation. The scene stored in the log is recompiled only for
forward kinematics of logged states (e.g. where a foot touched down) and the robot's mass.

A metric name may take an argument after a colon, e.g. ``peak_contact_force:right_foot/obstacle*``
or ``state_time:1``. Each metric returns a float, or raises :class:`NotMeasurable` with the
reason when the log cannot answer it (no steps, an empty log, a fall or an interruption
before the claim could be judged, no push in the spec, ...). :func:`evaluate` turns that
into NaN plus the reason.

Falls: :class:`LogData` cuts every per-time series (states, contacts, signals, events,
inputs) at the fall, so a metric only ever sees the time before it. Each metric's docstring
says which rule it follows: *pre-fall* (computed over the time before the fall),
*completed* (not measurable when the run fell or stopped early, because its claim is about a
behaviour the run had to complete), or *window* (not measurable unless the data cover the
metric's time window).

Steps (:func:`detect_steps`): a step is a touchdown after the foot has left the surface:
its sole's lowest corner was at least :data:`LIFT_CLEARANCE` above both the surface it left
and the surface it lands on, for at least :data:`LIFT_TIME`. A foot moving along the floor
without lifting is *sliding*, reported by ``slid_steps`` and ``sliding_distance``, never
counted as a step.
"""

from __future__ import annotations

import fnmatch
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import NamedTuple

import mujoco
import numpy as np

from walkrepro.log import record
from walkrepro.specs.models import ExperimentSpec, spec_from_yaml_text

FOOT_BODIES = ("left_foot", "right_foot")
GRAVITY = 9.81  # [m/s^2]
#: A foot is in contact when it carries more than this fraction of the robot's weight.
TOUCHDOWN_WEIGHT_FRACTION = 0.1
#: ... and has been unloaded below half of that before (hysteresis against chatter).
LIFTOFF_WEIGHT_FRACTION = 0.05
#: A sole lower than this at the first logged state starts on the ground [m].
START_CONTACT_HEIGHT = 0.005
#: A step's sole clears the surfaces it leaves and lands on by at least this [m]: twice the
#: largest sole penetration and tilt rise of a loaded foot in these scenes (MuJoCo's soft
#: contacts sink a few mm), and a fifth of the smallest swing height of the three papers
#: (Lee et al. 0.05 m); the issue asks for at least 1 cm.
LIFT_CLEARANCE = 0.01
#: ... for at least this long [s]: a tenth of the shortest swing of the three gaits (Paper II
#: T = 0.4 s with 0.1 s DS), longer than a landing bounce (a few ms to ~20 ms).
LIFT_TIME = 0.05
#: A foot that moved this far along the floor without lifting has slid (a new placement
#: without a step) [m]: four times the sole centre's shift when a flat foot rolls 10°.
SLIDE_DISTANCE = 0.02
#: Outcomes of :attr:`LogData.outcome`.
OUTCOMES = ("complete", "fell", "interrupted", "error", "unknown", "partial")


class NotMeasurable(Exception):  # noqa: N818 (the interface's name)
    """A metric cannot be computed from this log; ``reason`` says why, for a person."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


class MetricResults(NamedTuple):
    """Metric values of one log, with the reason for each one that is not measurable."""

    #: metric name (with argument) -> value; NaN where not measurable.
    values: dict[str, float]
    #: metric name -> why it is not measurable (only for those).
    reasons: dict[str, str]


@dataclass(frozen=True)
class Footstep:
    """A step: a touchdown after the foot left the surface (see :func:`detect_steps`).

    Attributes:
        foot: body name (``left_foot`` or ``right_foot``).
        t: touchdown time [s] (the foot carries :data:`TOUCHDOWN_WEIGHT_FRACTION` again).
        position: sole-centre position in the world at touchdown [m].
        liftoff_t: when the foot was unloaded before this step [s].
        clearance: the sole's largest clearance above the surfaces it left and landed on [m].
    """

    foot: str
    t: float
    position: tuple[float, float, float]
    liftoff_t: float = math.nan
    clearance: float = math.nan


class SoleTrack(NamedTuple):
    """A foot's sole over the logged states (N states)."""

    #: sole-centre (site ``<side>_sole``) position in the world, shape (N, 3) [m].
    centre: np.ndarray
    #: height of the sole box's lowest corner in the world, shape (N,) [m].
    lowest: np.ndarray


class StepDetection(NamedTuple):
    """What :func:`detect_steps` finds for one foot (indices into the given samples)."""

    #: (lift-off index, touchdown index, largest clearance [m]) of each step.
    steps: list[tuple[int, int, float]]
    #: (start index, end index, net horizontal sole displacement [m]) of each interval in
    #: which the foot stayed on the surface (between steps, and before the first / after the
    #: last); a displacement there is sliding.
    ground_phases: list[tuple[int, int, float]]


def detect_steps(
    t: np.ndarray,
    fz: np.ndarray,
    lowest: np.ndarray,
    centre_xy: np.ndarray,
    weight: float,
    clearance: float = LIFT_CLEARANCE,
    min_time: float = LIFT_TIME,
) -> StepDetection:
    """Steps and ground phases of one foot from samples on one time base.

    A foot is *loaded* above ``TOUCHDOWN_WEIGHT_FRACTION · weight`` and *unloaded* below
    ``LIFTOFF_WEIGHT_FRACTION · weight`` (hysteresis). An unloaded interval is a *step* when
    the sole's lowest corner stays at least ``clearance`` above both its height at lift-off
    (the surface it left) and its height at touchdown (the surface it lands on: the floor,
    or the top of a block it steps onto) for at least ``min_time``. Any other unloading
    (weight shift, toe-off, scraping) leaves the foot on the ground.

    Args:
        t: sample times, shape (N,) [s].
        fz: vertical contact force on the foot, shape (N,) [N].
        lowest: height of the sole's lowest corner, shape (N,) [m].
        centre_xy: horizontal sole-centre position, shape (N, 2) [m].
        weight: robot weight [N].
        clearance: least clearance of a step [m].
        min_time: least time at that clearance [s].
    """
    on, off = TOUCHDOWN_WEIGHT_FRACTION * weight, LIFTOFF_WEIGHT_FRACTION * weight
    n = t.size
    steps: list[tuple[int, int, float]] = []
    if not n:
        return StepDetection(steps, [])
    # At the start a foot resting on the ground counts as loaded even before its contact
    # force builds up, so standing still is not a touchdown.
    loaded = bool(fz[0] > on) or lowest[0] < START_CONTACT_HEIGHT
    i_off = 0
    for i in range(1, n):
        if loaded and fz[i] < off:
            loaded, i_off = False, i
        elif not loaded and fz[i] > on:
            loaded = True
            base = max(lowest[i_off], lowest[i])
            high = lowest[i_off:i] - base >= clearance
            if _longest_run(t[i_off : i + 1], high) >= min_time:
                steps.append((i_off, i, float(np.max(lowest[i_off:i]) - base)))
    phases = []
    start = 0
    for i_off, i_on, _ in [*steps, (n - 1, n - 1, 0.0)]:
        shift = float(np.linalg.norm(centre_xy[i_off] - centre_xy[start]))
        phases.append((start, i_off, shift))
        start = i_on
    return StepDetection(steps, phases)


def _longest_run(t: np.ndarray, mask: np.ndarray) -> float:
    """Longest time [s] a boolean mask over samples ``t[:-1]`` stays true (a run lasts until
    the next false sample, or ``t[-1]``)."""
    best, since = 0.0, None
    for k in range(mask.size + 1):
        if k < mask.size and mask[k]:
            since = t[k] if since is None else since
        elif since is not None:
            best, since = max(best, float(t[k] - since)), None
    return best


class LogData:
    """A log's contents as arrays, with lazily derived quantities shared by metrics.

    Every per-time series is cut at the fall (kept: ``t < fall_time``; the fall event is
    kept), so metrics see only the time before it. A log with no messages on a topic gives
    empty arrays of the right shape: ``t`` (0,), ``qpos`` (0, nq), ``qvel`` (0, nv).

    Attributes:
        outcome: ``complete``, ``fell``, ``interrupted``, ``error``, ``partial`` (a cut or
            damaged log read with ``--partial``: :mod:`walkrepro.log.integrity`) or
            ``unknown`` (an outcome this version does not know).
        fall_time: time of the ``fall`` event [s], or None.
        end_time: time of the last logged state before any cut [s] (NaN if none).
        integrity: how whole the log is (:class:`walkrepro.log.integrity.LogIntegrity`).
    """

    def __init__(self, log: record.Log, partial: bool = False) -> None:
        from walkrepro.log.integrity import PARTIAL, check

        self.log = log
        self.integrity = check(log, partial)  # a damaged log only with partial
        outcome = log.metadata.get("outcome", "unknown")
        self.outcome = outcome if outcome in OUTCOMES else "unknown"
        if not self.integrity.whole:
            self.outcome = PARTIAL
        self.spec: ExperimentSpec = spec_from_yaml_text(log.spec_yaml, f"{log.path}:spec.yaml")
        events = log.messages(record.TOPIC_EVENTS)
        falls = [float(e["t"]) for e in events if e.get("kind") == "fall"]
        self.fall_time: float | None = falls[0] if falls else None
        cut = self.fall_time if self.fall_time is not None else math.inf
        states = log.arrays(record.TOPIC_STATE)  # numpy-speed read of the binary topic
        model = self.model
        t = states.get("t", np.zeros(0))
        self.end_time = float(t[-1]) if t.size else math.nan
        keep = t < cut
        self.t = np.asarray(t[keep], dtype=float)
        self.qpos = np.asarray(states.get("qpos", np.zeros((0, model.nq)))[keep], dtype=float)
        self.qvel = np.asarray(states.get("qvel", np.zeros((0, model.nv)))[keep], dtype=float)
        self.contacts = [m for m in log.messages(record.TOPIC_CONTACTS) if m["t"] < cut]
        self.signals = [m for m in log.messages(record.TOPIC_SIGNALS) if m["t"] < cut]
        self.events = [e for e in events if e["t"] < cut or e.get("kind") == "fall"]
        self._cut = cut

    @classmethod
    def from_path(cls, path: Path, partial: bool = False) -> LogData:
        """Read a log file; a cut or damaged one only with ``partial``
        (:class:`walkrepro.log.integrity.DamagedLogError` otherwise)."""
        return cls(record.read_log(path), partial)

    @cached_property
    def model(self) -> mujoco.MjModel:
        """The scene recompiled from the log's ``scene.xml``."""
        return mujoco.MjModel.from_xml_string(self.log.scene_xml)

    @cached_property
    def robot_mass(self) -> float:
        """Mass of the robot's tree (bodies under ``pelvis``) [kg]."""
        m = self.model
        root = m.body("pelvis").id
        return float(sum(m.body_mass[b] for b in range(m.nbody) if m.body_rootid[b] == root))

    @property
    def data_end(self) -> float:
        """Last time the (cut) states cover [s]; NaN for a log without states."""
        return float(self.t[-1]) if self.t.size else math.nan

    @cached_property
    def contact_t(self) -> np.ndarray:
        """Times of the ``/sim/contacts`` messages [s]."""
        return np.array([m["t"] for m in self.contacts], dtype=float)

    def contact_wrench(self, pattern: str) -> np.ndarray:
        """Summed contact wrench (N x 6, world frame, torque about the origin) of pairs
        matching ``body/geom`` glob."""
        out = np.zeros((len(self.contacts), 6))
        for i, msg in enumerate(self.contacts):
            for key, wrench in msg["pairs"].items():
                if fnmatch.fnmatchcase(key, pattern):
                    out[i] += wrench
        return out

    def foot_normal_force(self, foot: str) -> np.ndarray:
        """Vertical contact force on a foot from every world geom [N]."""
        return self.contact_wrench(f"{foot}/*")[:, 2]

    def state_index(self, times: np.ndarray) -> np.ndarray:
        """Index of the logged state at (or just after, else the last) each time."""
        if not self.t.size:
            return np.zeros(np.size(times), dtype=int)
        return np.minimum(np.searchsorted(self.t, times), self.t.size - 1)

    @cached_property
    def sole_tracks(self) -> dict[str, SoleTrack]:
        """Each foot's sole (``left_foot``, ``right_foot``) at every logged state."""
        model = self.model
        data = mujoco.MjData(model)
        n = self.t.size
        sites, geoms = {}, {}
        for foot in FOOT_BODIES:
            side = foot.split("_")[0]
            sites[foot] = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{side}_sole")
            geoms[foot] = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{foot}_sole")
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        out = {f: SoleTrack(np.zeros((n, 3)), np.zeros(n)) for f in FOOT_BODIES}
        for i, qpos in enumerate(self.qpos):
            data.qpos[:] = qpos
            mujoco.mj_kinematics(model, data)
            for foot in FOOT_BODIES:
                track, site, geom = out[foot], sites[foot], geoms[foot]
                track.centre[i] = (
                    data.site_xpos[site] if site >= 0 else data.xpos[model.body(foot).id]
                )
                if geom >= 0:
                    z_axis = data.geom_xmat[geom].reshape(3, 3)[2]  # world z of the geom axes
                    half = corners * model.geom_size[geom]
                    track.lowest[i] = data.geom_xpos[geom, 2] + float(np.min(half @ z_axis))
                else:
                    track.lowest[i] = track.centre[i, 2]
        return out

    @cached_property
    def step_detection(self) -> dict[str, StepDetection]:
        """:func:`detect_steps` of each foot, on the contact messages' time base."""
        weight = self.robot_mass * GRAVITY
        idx = self.state_index(self.contact_t)
        out = {}
        for foot in FOOT_BODIES:
            track = self.sole_tracks[foot]
            if not self.t.size:
                lowest, centre = np.zeros(0), np.zeros((0, 2))
                fz = np.zeros(0)
            else:
                lowest, centre = track.lowest[idx], track.centre[idx, :2]
                fz = self.foot_normal_force(foot)
            out[foot] = detect_steps(self.contact_t, fz, lowest, centre, weight)
        return out

    @cached_property
    def footsteps(self) -> list[Footstep]:
        """Steps of both feet (touchdowns after a lift, :func:`detect_steps`), in time order."""
        steps = []
        idx = self.state_index(self.contact_t)
        for foot, found in self.step_detection.items():
            centre = self.sole_tracks[foot].centre
            for i_off, i_on, clear in found.steps:
                pos = centre[idx[i_on]]
                steps.append(
                    Footstep(
                        foot,
                        float(self.contact_t[i_on]),
                        (float(pos[0]), float(pos[1]), float(pos[2])),
                        float(self.contact_t[i_off]),
                        clear,
                    )
                )
        return sorted(steps, key=lambda s: s.t)

    def signal(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Times [s] and values of a controller signal (empty arrays if never logged)."""
        pairs = [(m["t"], m[name]) for m in self.signals if name in m]
        if not pairs:
            return np.zeros(0), np.zeros(0)
        t, v = zip(*pairs, strict=True)
        return np.array(t), np.array(v, dtype=float)

    def require_signal(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`signal`, raising :class:`NotMeasurable` if it was never logged."""
        t, v = self.signal(name)
        if not t.size:
            raise NotMeasurable(f"the log has no controller signal {name!r}{self.stopped_note()}")
        return t, v

    @cached_property
    def inputs_ctrl(self) -> tuple[np.ndarray, np.ndarray]:
        """Times [s], shape (N,), and the actuator inputs ``ctrl`` of every physics step,
        shape (N, nu), before the fall (a position servo's ``ctrl`` is its target [rad])."""
        inputs = self.log.arrays(record.TOPIC_INPUTS, ("step", "ctrl"))
        nu = self.model.nu
        if "step" not in inputs:
            return np.zeros(0), np.zeros((0, nu))
        t = np.asarray(inputs["step"], dtype=float) * self.spec.sim.timestep
        keep = t < self._cut
        return t[keep], np.asarray(inputs["ctrl"], dtype=float).reshape(len(t), nu)[keep]

    @cached_property
    def inputs_xfrc(self) -> list[dict[str, list[float]]]:
        """Per-physics-step applied external wrenches (only non-zero bodies), before the fall."""
        dt = self.spec.sim.timestep
        return [
            m["xfrc"] for m in self.log.messages(record.TOPIC_INPUTS) if m["step"] * dt < self._cut
        ]

    # ---- the rules metrics share -----------------------------------------------------

    def stopped_note(self) -> str:
        """`` (the run stopped at ...)`` when a short log may explain a missing datum."""
        if self.outcome == "complete":
            return ""
        return f" ({self.stop_reason()})"

    def stop_reason(self) -> str:
        """Why the run did not complete, e.g. ``the robot fell at t = 1.234 s``."""
        if self.outcome == "fell" and self.fall_time is not None:
            return f"the robot fell at t = {self.fall_time:.3f} s"
        at = self.log.metadata.get("sim_time")
        end = float(at) if at is not None else self.end_time
        when = f" at t = {end:.3f} s" if not math.isnan(end) else ""
        if self.outcome == "partial":
            return self.integrity.describe()
        return {
            "fell": f"the robot fell{when}",
            "interrupted": f"run interrupted{when}",
            "error": f"run ended in an error{when}",
        }.get(self.outcome, f"the log was not closed (outcome unknown; data end{when})")

    def require_states(self, n: int = 1) -> None:
        """Raise :class:`NotMeasurable` unless at least ``n`` states were logged."""
        if self.t.size < n:
            what = "no" if not self.t.size else f"only {self.t.size}"
            raise NotMeasurable(
                f"the log has {what} /sim/state messages (need {n}){self.stopped_note()}"
            )

    def require_contacts(self) -> None:
        """Raise :class:`NotMeasurable` unless contact messages were logged."""
        if not self.contacts:
            raise NotMeasurable(f"the log has no /sim/contacts messages{self.stopped_note()}")

    def require_completed(self, what: str) -> None:
        """Raise :class:`NotMeasurable` unless the run completed: ``what`` is the behaviour
        the metric's claim needs the whole run for (e.g. ``"the push was recovered"``)."""
        if self.outcome != "complete":
            raise NotMeasurable(f"{self.stop_reason()}, before {what}")

    def require_until(self, t_end: float, what: str) -> None:
        """Raise :class:`NotMeasurable` unless the (cut) data reach ``t_end`` [s]."""
        self.require_states()
        if self.data_end < t_end - 1e-9:
            if self.outcome == "complete":
                raise NotMeasurable(f"the run ends at t = {self.data_end:.3f} s, before {what}")
            raise NotMeasurable(f"{self.stop_reason()}, before {what} (t = {t_end:.3f} s)")


MetricFn = Callable[[LogData, str], float]
#: Checks a metric's argument before any run: raises :class:`MetricArgError` if the metric
#: could not read it.
ArgCheck = Callable[[str], None]
_METRICS: dict[str, tuple[MetricFn, str, ArgCheck]] = {}


class MetricArgError(ValueError):
    """A metric's argument that the metric cannot read: a spec error, not a bug."""


def no_argument(arg: str) -> None:
    """Argument check of a metric that reads no argument."""
    if arg:
        raise MetricArgError(f"takes no argument, got {arg!r}")


def any_argument(arg: str) -> None:
    """Argument check of a metric that reads any argument (e.g. a contact-pair pattern)."""


def metric(name: str, doc: str, arg: ArgCheck = no_argument) -> Callable[[MetricFn], MetricFn]:
    """Register a metric function under ``name`` with a one-line description (with units)
    and the check of its argument (``arg``; by default it takes none), which specs run when
    they load (:func:`check_metric_arg`)."""

    def register(fn: MetricFn) -> MetricFn:
        _METRICS[name] = (fn, doc, arg)
        return fn

    return register


def _registry() -> dict[str, tuple[MetricFn, str, ArgCheck]]:
    """Every registered metric: the core ones above and, imported on the first lookup, every
    plugin's metric modules (:mod:`walkrepro.plugins`)."""
    from walkrepro import plugins

    plugins.load_metric_modules()
    return _METRICS


def check_metric_arg(full: str) -> None:
    """Raise :class:`MetricArgError` if the metric ``full`` (``name:arg``) cannot read its
    argument (an unknown metric is not checked here)."""
    base, arg = split_metric(full)
    if base in _registry():
        try:
            _METRICS[base][2](arg)
        except MetricArgError as exc:
            raise MetricArgError(f"metric {base!r}: {exc}") from None


def parse_window(arg: str) -> tuple[float, float]:
    """``"t0-t1"`` -> (t0, t1) [s], t0 < t1; :class:`MetricArgError` otherwise."""
    lo, sep, hi = arg.partition("-")
    try:
        t0, t1 = float(lo), float(hi)
    except ValueError:
        t0 = t1 = math.nan
    if not sep or not t0 < t1:
        raise MetricArgError(f"window {arg!r} is not 't0-t1' in seconds with t0 < t1")
    return t0, t1


def window_check(arg: str) -> None:
    """Argument check: none, or a window ``t0-t1`` [s]."""
    if arg:
        parse_window(arg)


def number_check(required: bool = False) -> ArgCheck:
    """Argument check: a number (or, unless ``required``, none)."""

    def check(arg: str) -> None:
        if not arg:
            if required:
                raise MetricArgError("needs a number as its argument, e.g. name:1")
            return
        try:
            float(arg)
        except ValueError:
            raise MetricArgError(f"argument {arg!r} is not a number") from None

    return check


def choice_check(*choices: str, required: bool = False) -> ArgCheck:
    """Argument check: one of ``choices`` (or, unless ``required``, none)."""

    def check(arg: str) -> None:
        if (arg or required) and arg not in choices:
            raise MetricArgError(f"argument {arg!r} is none of {', '.join(choices)}")

    return check


def qualified_check(head: ArgCheck, qualifier: ArgCheck) -> ArgCheck:
    """Argument check of ``head`` or ``head@qualifier``, e.g. a joint and a window
    (``knee@2-10``) or a leg and a kind of switch (``left@SSA-DS``)."""

    def check(arg: str) -> None:
        first, at, rest = arg.partition("@")
        head(first)
        if at:
            qualifier(rest)

    return check


def metric_names() -> list[str]:
    """Every registered metric base name."""
    return sorted(_registry())


def metric_doc(name: str) -> str:
    """One-line description of a metric."""
    return _registry()[name][1]


def split_metric(full: str) -> tuple[str, str]:
    """``"peak_contact_force:right_foot/obstacle*"`` -> ``("peak_contact_force", "right_foot/obstacle*")``."""
    base, _, arg = full.partition(":")
    return base, arg


def evaluate(data: LogData, names: list[str]) -> MetricResults:
    """Evaluate the named metrics (with arguments) on a log.

    A metric that raises :class:`NotMeasurable` gets NaN and its reason, as does one whose
    argument it cannot read (:class:`MetricArgError`: specs check arguments when they load,
    but an old log's spec may not have been); any other exception is a bug and propagates.
    """
    values, reasons = {}, {}
    registry = _registry()
    for full in names:
        base, arg = split_metric(full)
        if base not in registry:  # an old log's spec may name a metric since renamed
            values[full], reasons[full] = math.nan, f"this walkrepro has no metric {base!r}"
            continue
        try:
            values[full] = float(registry[base][0](data, arg))
        except NotMeasurable as exc:
            values[full], reasons[full] = math.nan, exc.reason
        except MetricArgError as exc:
            values[full], reasons[full] = math.nan, f"metric {base!r}: {exc}"
    return MetricResults(values, reasons)


def compute(data: LogData, names: list[str]) -> dict[str, float]:
    """Metric values of :func:`evaluate` (NaN where not measurable), for existing callers."""
    return evaluate(data, names).values


def default_metric_names(spec: ExperimentSpec) -> list[str]:
    """The metrics every run reports, plus those its ``expect`` list names."""
    names = [
        "fell",
        "fall_time",
        "sim_time",
        "pelvis_drift",
        "footsteps",
        "mean_step_length",
        "mean_step_duration",
        "step_duration_spread",
        "mean_forward_speed",
        "peak_external_force",
    ]
    names += [
        f"peak_contact_force:{foot}/{o.name}" for o in spec.world.obstacles for foot in FOOT_BODIES
    ]
    names += [e.metric for e in spec.expect]
    return list(dict.fromkeys(names))


# --------------------------------------------------------------------------------------
# The metrics


def window_arg(arg: str, default: tuple[float, float]) -> tuple[float, float]:
    """``"t0-t1"`` -> (t0, t1) [s]; ``default`` for an empty argument."""
    return parse_window(arg) if arg else default


@metric("fell", "1 if the run ended in a fall, else 0 (not measurable if it stopped early)")
def _fell(d: LogData, arg: str) -> float:
    """Whole run: 1 for a fall; 0 only for a run that completed without one."""
    if d.outcome == "fell":
        return 1.0
    if d.outcome != "complete":
        raise NotMeasurable(f"{d.stop_reason()}: whether it would have fallen is unknown")
    return 0.0


@metric("fall_time", "time of the fall [s]; not measurable if the robot did not fall")
def _fall_time(d: LogData, arg: str) -> float:
    """The ``fall`` event's time."""
    if d.fall_time is None:
        if d.outcome == "complete":
            raise NotMeasurable("the robot did not fall")
        raise NotMeasurable(f"{d.stop_reason()}, without a fall")
    return d.fall_time


@metric("sim_time", "simulated time reached [s]")
def _sim_time(d: LogData, arg: str) -> float:
    """The last logged state's time (before the cut at a fall, which is the fall time)."""
    if math.isnan(d.end_time):
        d.require_states()
    return d.end_time


@metric("pelvis_drift", "largest horizontal distance of the pelvis from its start [m]")
def _pelvis_drift(d: LogData, arg: str) -> float:
    """Pre-fall."""
    d.require_states()
    xy = d.qpos[:, 0:2]
    return float(np.max(np.linalg.norm(xy - xy[0], axis=1)))


@metric(
    "footsteps",
    "number of steps: touchdowns after the sole cleared the surface by 1 cm for 50 ms "
    "(arg: left_foot or right_foot for one foot)",
    arg=choice_check(*FOOT_BODIES),
)
def _footsteps(d: LogData, arg: str) -> float:
    """Pre-fall count of :attr:`LogData.footsteps`."""
    d.require_states()
    d.require_contacts()
    return float(sum(1 for s in d.footsteps if not arg or s.foot == arg))


@metric(
    "slid_steps",
    f"times a foot moved ≥ {SLIDE_DISTANCE} m along the surface without lifting (not steps) "
    "(arg: left_foot or right_foot)",
    arg=choice_check(*FOOT_BODIES),
)
def _slid_steps(d: LogData, arg: str) -> float:
    """Pre-fall: ground phases (:func:`detect_steps`) whose net sole shift is ≥ SLIDE_DISTANCE."""
    d.require_states()
    d.require_contacts()
    return float(
        sum(
            1
            for foot, found in d.step_detection.items()
            if not arg or foot == arg
            for _, _, shift in found.ground_phases
            if shift >= SLIDE_DISTANCE
        )
    )


@metric(
    "sliding_distance",
    "total horizontal distance the soles moved while on the surface (between steps) [m] "
    "(arg: left_foot or right_foot)",
    arg=choice_check(*FOOT_BODIES),
)
def _sliding_distance(d: LogData, arg: str) -> float:
    """Pre-fall: sum of the net sole shifts of every ground phase (:func:`detect_steps`)."""
    d.require_states()
    d.require_contacts()
    return float(
        sum(
            shift
            for foot, found in d.step_detection.items()
            if not arg or foot == arg
            for _, _, shift in found.ground_phases
        )
    )


def _need_steps(d: LogData, n: int) -> list[Footstep]:
    d.require_states()
    d.require_contacts()
    if len(d.footsteps) < n:
        raise NotMeasurable(f"{len(d.footsteps)} step(s) found, {n} needed{d.stopped_note()}")
    return d.footsteps


@metric("mean_step_length", "mean forward (x) distance between successive steps' touchdowns [m]")
def _mean_step_length(d: LogData, arg: str) -> float:
    """Pre-fall."""
    xs = [s.position[0] for s in _need_steps(d, 2)]
    return float(np.mean(np.diff(xs)))


@metric("mean_step_duration", "mean time between successive steps' touchdowns [s]")
def _mean_step_duration(d: LogData, arg: str) -> float:
    """Pre-fall."""
    return float(np.mean(np.diff([s.t for s in _need_steps(d, 2)])))


@metric(
    "step_duration_spread",
    "std/mean of the times between successive steps' touchdowns (0 = clock-like stepping) [-]",
)
def _step_duration_spread(d: LogData, arg: str) -> float:
    """Pre-fall."""
    intervals = np.diff([s.t for s in _need_steps(d, 3)])
    return float(np.std(intervals) / np.mean(intervals))


@metric(
    "mean_forward_speed",
    "pelvis x displacement / time [m/s] (arg 't0-t1' restricts the window [s])",
    arg=window_check,
)
def mean_forward_speed(d: LogData, arg: str) -> float:
    """Window: with an argument the data must cover it; without, pre-fall over the log."""
    d.require_states(2)
    t0, t1 = float(d.t[0]), float(d.t[-1])
    if arg:
        lo, hi = window_arg(arg, (t0, t1))
        d.require_until(hi, f"the end of the speed window {arg}")
        t0, t1 = max(t0, lo), min(t1, hi)
    i0, i1 = np.searchsorted(d.t, [t0, t1])
    i1 = min(i1, d.t.size - 1)
    if d.t[i1] <= d.t[i0]:
        raise NotMeasurable(f"the window {arg or 'of the run'} holds fewer than two states")
    return float((d.qpos[i1, 0] - d.qpos[i0, 0]) / (d.t[i1] - d.t[i0]))


@metric(
    "peak_contact_force",
    "largest contact force norm [N] on pairs matching 'body/geom' or 'geom'",
    arg=any_argument,
)
def _peak_contact_force(d: LogData, arg: str) -> float:
    """Pre-fall; 0 when no pair matches."""
    d.require_contacts()
    pattern = arg if "/" in arg else f"*/{arg or '*'}"
    forces = d.contact_wrench(pattern)[:, :3]
    return float(np.max(np.linalg.norm(forces, axis=1)))


@metric("peak_external_force", "largest applied disturbance force norm [N]")
def _peak_external_force(d: LogData, arg: str) -> float:
    """Pre-fall; 0 when nothing was applied."""
    if not d.inputs_xfrc:
        raise NotMeasurable(f"the log has no /sim/inputs messages{d.stopped_note()}")
    peak = 0.0
    for xfrc in d.inputs_xfrc:
        for wrench in xfrc.values():
            peak = max(peak, float(np.linalg.norm(wrench[:3])))
    return peak


def _need_state_arg(name: str, arg: str) -> None:
    if not arg:
        raise NotMeasurable(f"{name} needs the fsm_state value as its argument, e.g. {name}:1")


@metric(
    "state_time",
    "total time the controller's 'fsm_state' signal equals arg [s]",
    arg=number_check(required=True),
)
def _state_time(d: LogData, arg: str) -> float:
    """Pre-fall."""
    t, v = d.require_signal("fsm_state")
    _need_state_arg("state_time", arg)
    dt = np.diff(t, append=t[-1] + (t[-1] - t[-2] if t.size > 1 else 0.0))
    return float(np.sum(dt[v == float(arg)]))


@metric(
    "state_duration_spread",
    "std/mean of the durations of the visits of fsm_state == arg (0 = clock-like) [-]",
    arg=number_check(required=True),
)
def _state_duration_spread(d: LogData, arg: str) -> float:
    """Pre-fall, over complete visits."""
    t, v = d.require_signal("fsm_state")
    _need_state_arg("state_duration_spread", arg)
    target = float(arg)
    durations, start = [], None
    for ti, vi in zip(t, v, strict=True):
        if vi == target and start is None:
            start = ti
        elif vi != target and start is not None:
            durations.append(ti - start)
            start = None
    if len(durations) < 2:
        raise NotMeasurable(f"{len(durations)} complete visit(s) of fsm_state {arg}, 2 needed")
    return float(np.std(durations) / np.mean(durations))
