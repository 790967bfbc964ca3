"""Metrics specific to the faraji reproduction (computed from the log alone).

Paper II (Faraji et al., time-projection push recovery) reports footstep scatter at phase
changes (Fig. 14), corrective steps after pushes (Figs. 16-17), pelvis speed under drag
(Fig. 18), walking speed (Fig. 19) and an apparent ankle stiffness (Fig. 20).
"""

from __future__ import annotations

import math
from functools import cache

import mujoco
import numpy as np

from walkrepro.metrics import LogData, metric

#: A step is corrective when its peak footstep adjustment exceeds this [m]: the undisturbed
#: closed-loop in-place run (results/in_place) stays below 0.03 m in every step.
CORRECTIVE_STEP = 0.04
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
    lo, _, hi = arg.partition("-")
    return (t >= float(lo)) & (t <= float(hi))


@metric("peak_pelvis_speed", "largest |stride-averaged pelvis x speed| [m/s] (arg 't0-t1')")
def _peak_pelvis_speed(d: LogData, arg: str) -> float:
    t, v = _stride_speed(d)
    m = _window(t, arg)
    return float(np.max(np.abs(v[m]))) if m.any() else math.nan


@metric("peak_forward_pelvis_speed", "largest stride-averaged pelvis x speed [m/s] (arg 't0-t1')")
def _peak_forward(d: LogData, arg: str) -> float:
    t, v = _stride_speed(d)
    m = _window(t, arg)
    return float(np.max(v[m])) if m.any() else math.nan


@metric(
    "peak_backward_pelvis_speed",
    "largest backward stride-averaged pelvis speed, as a positive number [m/s] (arg 't0-t1')",
)
def _peak_backward(d: LogData, arg: str) -> float:
    t, v = _stride_speed(d)
    m = _window(t, arg)
    return float(-np.min(v[m])) if m.any() else math.nan


@metric("mean_abs_pelvis_speed", "mean |stride-averaged pelvis x speed| [m/s] (arg 't0-t1')")
def _mean_abs_speed(d: LogData, arg: str) -> float:
    t, v = _stride_speed(d)
    m = _window(t, arg)
    return float(np.mean(np.abs(v[m]))) if m.any() else math.nan


def _step_adjustments(d: LogData) -> tuple[np.ndarray, np.ndarray]:
    """Largest |footstep adjustment| (truncated) commanded during each step.

    Returns:
        Step start times [s] and the per-step peak adjustments [m].
    """
    t, v = d.signal("footstep")
    phases = _phase_times(d)
    if not t.size or phases.size < 2:
        return np.zeros(0), np.zeros(0)
    bounds = np.append(phases, np.inf)
    peaks = np.array(
        [
            float(np.max(np.abs(v[(t >= lo) & (t < hi)]), initial=0.0))
            for lo, hi in zip(bounds[:-1], bounds[1:], strict=True)
        ]
    )
    return phases, peaks


@metric(
    "recovery_steps",
    f"corrective steps after the push time arg [s]: steps (from the one the push falls in) "
    f"whose peak |footstep adjustment| exceeds {CORRECTIVE_STEP} m, counted until the first "
    "step below it (Paper II Fig. 16)",
)
def _recovery_steps(d: LogData, arg: str) -> float:
    starts, peaks = _step_adjustments(d)
    if not starts.size:
        return math.nan
    t0 = float(arg) if arg else 0.0
    first = max(0, int(np.searchsorted(starts, t0, side="right")) - 1)
    count = 0
    for a in peaks[first:]:
        if a > CORRECTIVE_STEP:
            count += 1
        elif count:
            break
    return float(count)


@metric("max_footstep_adjustment", "largest |commanded footstep adjustment| after truncation [m]")
def _max_adjustment(d: LogData, arg: str) -> float:
    t, v = d.signal("footstep")
    return float(np.max(np.abs(v))) if t.size else math.nan


@metric("max_footstep_adjustment_raw", "largest |footstep adjustment| before truncation [m]")
def _max_adjustment_raw(d: LogData, arg: str) -> float:
    t, v = d.signal("footstep_raw")
    return float(np.max(np.abs(v))) if t.size else math.nan


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
)
def _footstep_scatter(d: LogData, arg: str) -> float:
    phases = _phase_times(d)
    phases = phases[_window(phases, arg or "2.0-1e9")]
    if phases.size < 4:
        return math.nan
    rel = _feet_relative(d, phases)
    dev = rel - rel.mean(axis=0, keepdims=True)
    return float(np.sqrt(np.mean(np.sum(dev**2, axis=2))))


def _pull(d: LogData) -> tuple[float, float, float]:
    """(force x [N], start [s], end [s]) of the spec's first disturbance."""
    dist = d.spec.disturbances[0]
    return float(dist.force[0]), float(dist.start), float(dist.start + dist.duration)


def _mean_in(t: np.ndarray, x: np.ndarray, lo: float, hi: float) -> float:
    m = (t >= lo) & (t <= hi)
    return float(np.mean(x[m])) if m.any() else math.nan


@metric("pelvis_displacement", "pelvis x during the last half of the pull minus before it [m]")
def _pelvis_displacement(d: LogData, arg: str) -> float:
    if not d.spec.disturbances:
        return math.nan
    _, t0, t1 = _pull(d)
    before = _mean_in(d.t, d.qpos[:, 0], max(0.0, t0 - 1.0), t0)
    during = _mean_in(d.t, d.qpos[:, 0], 0.5 * (t0 + t1), t1)
    return during - before


@metric("torso_displacement", "neck-height (torso top) x displacement under the pull [m]")
def _torso_displacement(d: LogData, arg: str) -> float:
    if not d.spec.disturbances:
        return math.nan
    _, t0, t1 = _pull(d)
    model = mujoco.MjModel.from_xml_string(d.log.scene_xml)
    data = mujoco.MjData(model)
    torso = model.body("torso").id
    xs = np.zeros(d.t.size)
    for i in range(d.t.size):
        data.qpos[:] = d.qpos[i]
        mujoco.mj_kinematics(model, data)
        xs[i] = data.xpos[torso, 0] + data.xmat[torso].reshape(3, 3)[0, 2] * _neck_offset(model)
    before = _mean_in(d.t, xs, max(0.0, t0 - 1.0), t0)
    during = _mean_in(d.t, xs, 0.5 * (t0 + t1), t1)
    return during - before


def _neck_offset(model: mujoco.MjModel) -> float:
    """Height of the neck above the torso body origin: the top of its box geom [m]."""
    torso = model.body("torso").id
    tops = [
        model.geom_pos[g, 2] + model.geom_size[g, 2]
        for g in range(model.ngeom)
        if model.geom_bodyid[g] == torso and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX
    ]
    return float(max(tops)) if tops else 0.0


@metric(
    "ankle_stiffness",
    "apparent stiffness per ankle F·h / (2·lean) [Nm/rad] (Paper II Fig. 20): F the pull, "
    "h its height above the ankles, lean = pelvis displacement / pelvis height above the ankles",
)
def _ankle_stiffness(d: LogData, arg: str) -> float:
    if not d.spec.disturbances:
        return math.nan
    force, _, _ = _pull(d)
    model = mujoco.MjModel.from_xml_string(d.log.scene_xml)
    data = mujoco.MjData(model)
    data.qpos[:] = d.qpos[0]
    mujoco.mj_kinematics(model, data)
    ankle = 0.5 * (
        data.xpos[model.body("left_foot").id, 2] + data.xpos[model.body("right_foot").id, 2]
    )
    torso = model.body("torso").id
    neck = data.xpos[torso, 2] + _neck_offset(model)
    pelvis = data.xpos[model.body("pelvis").id, 2]
    lean = _pelvis_displacement(d, "") / (pelvis - ankle)
    return abs(force) * (neck - ankle) / (2.0 * lean) if lean else math.nan
