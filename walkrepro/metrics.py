"""Metrics computed from a log alone: footsteps, speed, falls, peak forces, FSM timing.

Nothing here touches a live simulation. The scene stored in the log is recompiled only for
forward kinematics of logged states (e.g. where a foot touched down) and the robot's mass.

A metric name may take an argument after a colon, e.g. ``peak_contact_force:right_foot/obstacle*``
or ``state_time:1``. Each metric returns a float, or NaN when the log has no data for it.
"""

from __future__ import annotations

import fnmatch
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import mujoco
import numpy as np

from walkrepro import record
from walkrepro.spec import ExperimentSpec, spec_from_yaml_text

FOOT_BODIES = ("left_foot", "right_foot")
GRAVITY = 9.81  # [m/s^2]
#: A foot is in contact when it carries more than this fraction of the robot's weight.
TOUCHDOWN_WEIGHT_FRACTION = 0.1
#: ... and has been unloaded below half of that before (hysteresis against chatter).
LIFTOFF_WEIGHT_FRACTION = 0.05
#: A sole centre lower than this at the first logged state starts on the ground [m].
START_CONTACT_HEIGHT = 0.005


@dataclass(frozen=True)
class Footstep:
    """A touchdown. ``foot`` body name, time [s], sole-centre position in the world [m]."""

    foot: str
    t: float
    position: tuple[float, float, float]


class LogData:
    """A log's contents as arrays, with lazily derived quantities shared by metrics."""

    def __init__(self, log: record.Log) -> None:
        self.log = log
        self.outcome = log.metadata.get("outcome", "unknown")
        self.spec: ExperimentSpec = spec_from_yaml_text(log.spec_yaml, f"{log.path}:spec.yaml")
        states = log.messages(record.TOPIC_STATE)
        self.t = np.array([m["t"] for m in states])
        self.qpos = np.array([m["qpos"] for m in states])
        self.qvel = np.array([m["qvel"] for m in states])
        self.contacts = log.messages(record.TOPIC_CONTACTS)
        self.signals = log.messages(record.TOPIC_SIGNALS)
        self.events = log.messages(record.TOPIC_EVENTS)

    @classmethod
    def from_path(cls, path: Path) -> LogData:
        """Read a log file."""
        return cls(record.read_log(path))

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

    @cached_property
    def contact_t(self) -> np.ndarray:
        """Times of the ``/sim/contacts`` messages [s]."""
        return np.array([m["t"] for m in self.contacts])

    def contact_wrench(self, pattern: str) -> np.ndarray:
        """Summed contact wrench (N x 6, world frame) of pairs matching ``body/geom`` glob."""
        out = np.zeros((len(self.contacts), 6))
        for i, msg in enumerate(self.contacts):
            for key, wrench in msg["pairs"].items():
                if fnmatch.fnmatchcase(key, pattern):
                    out[i] += wrench
        return out

    def foot_normal_force(self, foot: str) -> np.ndarray:
        """Vertical contact force on a foot from every world geom [N]."""
        return self.contact_wrench(f"{foot}/*")[:, 2]

    @cached_property
    def footsteps(self) -> list[Footstep]:
        """Touchdowns of both feet, in time order, detected from foot contact forces."""
        weight = self.robot_mass * GRAVITY
        on, off = TOUCHDOWN_WEIGHT_FRACTION * weight, LIFTOFF_WEIGHT_FRACTION * weight
        steps: list[Footstep] = []
        for foot in FOOT_BODIES:
            fz = self.foot_normal_force(foot)
            if not fz.size:
                continue
            # At the start a foot resting on the ground counts as loaded even before its
            # contact force builds up, so standing still is not a touchdown.
            loaded = bool(fz[0] > on) or self._sole(foot, 0)[2] < START_CONTACT_HEIGHT
            for i in range(1, fz.size):
                if loaded and fz[i] < off:
                    loaded = False
                elif not loaded and fz[i] > on:
                    loaded = True
                    steps.append(Footstep(foot, float(self.contact_t[i]), self._sole(foot, i)))
        return sorted(steps, key=lambda s: s.t)

    def _sole(self, foot: str, contact_index: int) -> tuple[float, float, float]:
        """World position of a foot's sole centre at a contact message's time."""
        i = int(np.searchsorted(self.t, self.contact_t[contact_index]))
        i = min(i, len(self.t) - 1)
        data = mujoco.MjData(self.model)
        data.qpos[:] = self.qpos[i]
        mujoco.mj_kinematics(self.model, data)
        side = foot.split("_")[0]
        site = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, f"{side}_sole")
        pos = data.site_xpos[site] if site >= 0 else data.xpos[self.model.body(foot).id]
        return (float(pos[0]), float(pos[1]), float(pos[2]))

    def signal(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Times [s] and values of a controller signal (empty arrays if never logged)."""
        pairs = [(m["t"], m[name]) for m in self.signals if name in m]
        if not pairs:
            return np.zeros(0), np.zeros(0)
        t, v = zip(*pairs, strict=True)
        return np.array(t), np.array(v, dtype=float)

    @cached_property
    def inputs_xfrc(self) -> list[dict[str, list[float]]]:
        """Per-physics-step applied external wrenches (only non-zero bodies)."""
        return [m["xfrc"] for m in self.log.messages(record.TOPIC_INPUTS)]


MetricFn = Callable[[LogData, str], float]
_METRICS: dict[str, tuple[MetricFn, str]] = {}


def metric(name: str, doc: str) -> Callable[[MetricFn], MetricFn]:
    """Register a metric function under ``name`` with a one-line description (with units)."""

    def register(fn: MetricFn) -> MetricFn:
        _METRICS[name] = (fn, doc)
        return fn

    return register


def metric_names() -> list[str]:
    """Every registered metric base name."""
    return sorted(_METRICS)


def metric_doc(name: str) -> str:
    """One-line description of a metric."""
    return _METRICS[name][1]


def split_metric(full: str) -> tuple[str, str]:
    """``"peak_contact_force:right_foot/obstacle*"`` -> ``("peak_contact_force", "right_foot/obstacle*")``."""
    base, _, arg = full.partition(":")
    return base, arg


def compute(data: LogData, names: list[str]) -> dict[str, float]:
    """Evaluate the named metrics (with arguments) on a log."""
    out = {}
    for full in names:
        base, arg = split_metric(full)
        out[full] = float(_METRICS[base][0](data, arg))
    return out


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


@metric("fell", "1 if the run ended in a fall, else 0")
def _fell(d: LogData, arg: str) -> float:
    return 1.0 if d.outcome == "fell" else 0.0


@metric("fall_time", "time of the fall [s]; NaN if the robot did not fall")
def _fall_time(d: LogData, arg: str) -> float:
    falls = [e["t"] for e in d.events if e.get("kind") == "fall"]
    return float(falls[0]) if falls else math.nan


@metric("sim_time", "simulated time reached [s]")
def _sim_time(d: LogData, arg: str) -> float:
    return float(d.t[-1]) if d.t.size else math.nan


@metric("pelvis_drift", "largest horizontal distance of the pelvis from its start [m]")
def _pelvis_drift(d: LogData, arg: str) -> float:
    if not d.t.size:
        return math.nan
    xy = d.qpos[:, 0:2]
    return float(np.max(np.linalg.norm(xy - xy[0], axis=1)))


@metric("footsteps", "number of touchdowns (arg: left_foot or right_foot for one foot)")
def _footsteps(d: LogData, arg: str) -> float:
    return float(sum(1 for s in d.footsteps if not arg or s.foot == arg))


@metric("mean_step_length", "mean forward (x) distance between successive touchdowns [m]")
def _mean_step_length(d: LogData, arg: str) -> float:
    xs = [s.position[0] for s in d.footsteps]
    if len(xs) < 2:
        return math.nan
    return float(np.mean(np.diff(xs)))


def _touchdown_intervals(d: LogData) -> np.ndarray:
    return np.diff([s.t for s in d.footsteps])


@metric("mean_step_duration", "mean time between successive touchdowns [s]")
def _mean_step_duration(d: LogData, arg: str) -> float:
    intervals = _touchdown_intervals(d)
    return float(np.mean(intervals)) if intervals.size else math.nan


@metric(
    "step_duration_spread",
    "std/mean of the times between successive touchdowns (0 = clock-like stepping) [-]",
)
def _step_duration_spread(d: LogData, arg: str) -> float:
    intervals = _touchdown_intervals(d)
    if intervals.size < 2:
        return math.nan
    return float(np.std(intervals) / np.mean(intervals))


@metric(
    "mean_forward_speed",
    "pelvis x displacement / time [m/s] (arg 't0-t1' restricts the window [s])",
)
def _mean_forward_speed(d: LogData, arg: str) -> float:
    if d.t.size < 2:
        return math.nan
    t0, t1 = float(d.t[0]), float(d.t[-1])
    if arg:
        lo, _, hi = arg.partition("-")
        t0, t1 = max(t0, float(lo)), min(t1, float(hi))
    i0, i1 = np.searchsorted(d.t, [t0, t1])
    i1 = min(i1, d.t.size - 1)
    if d.t[i1] <= d.t[i0]:
        return math.nan
    return float((d.qpos[i1, 0] - d.qpos[i0, 0]) / (d.t[i1] - d.t[i0]))


@metric(
    "peak_contact_force", "largest contact force norm [N] on pairs matching 'body/geom' or 'geom'"
)
def _peak_contact_force(d: LogData, arg: str) -> float:
    pattern = arg if "/" in arg else f"*/{arg or '*'}"
    forces = d.contact_wrench(pattern)[:, :3]
    return float(np.max(np.linalg.norm(forces, axis=1))) if forces.size else 0.0


@metric("peak_external_force", "largest applied disturbance force norm [N]")
def _peak_external_force(d: LogData, arg: str) -> float:
    peak = 0.0
    for xfrc in d.inputs_xfrc:
        for wrench in xfrc.values():
            peak = max(peak, float(np.linalg.norm(wrench[:3])))
    return peak


@metric("state_time", "total time the controller's 'fsm_state' signal equals arg [s]")
def _state_time(d: LogData, arg: str) -> float:
    t, v = d.signal("fsm_state")
    if not t.size:
        return math.nan
    dt = np.diff(t, append=t[-1] + (t[-1] - t[-2] if t.size > 1 else 0.0))
    return float(np.sum(dt[v == float(arg)]))


@metric(
    "state_duration_spread",
    "std/mean of the durations of the visits of fsm_state == arg (0 = clock-like) [-]",
)
def _state_duration_spread(d: LogData, arg: str) -> float:
    t, v = d.signal("fsm_state")
    target = float(arg)
    durations, start = [], None
    for ti, vi in zip(t, v, strict=True):
        if vi == target and start is None:
            start = ti
        elif vi != target and start is not None:
            durations.append(ti - start)
            start = None
    if len(durations) < 2:
        return math.nan
    return float(np.std(durations) / np.mean(durations))


# Paper-specific metrics register themselves on import (after `metric` exists).
from walkrepro.paper_metrics import faraji, jo_oh, lee2021  # noqa: E402, F401
