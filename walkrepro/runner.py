"""The simulation loop: sensors → controller → actuators → MuJoCo step, with disturbances.

This is the only module that writes ``MjData``. Physics runs at ``sim.timestep``; the
controller runs every ``sim.control_period`` and its command is held (zero-order hold)
between ticks. Every physics step's inputs are logged so that ``walkrepro verify`` can
replay the log bit for bit.

Each physics step is MuJoCo's ``mj_step`` split in two: ``mj_step1`` (kinematics, collisions,
position and velocity sensors of the current state), then the sensors and the controller,
then ``mj_step2`` (actuation, constraint forces, acceleration sensors, integration). One
forward pass per step: the controller never costs the physics a second one.
"""

from __future__ import annotations

import math
import os
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from walkrepro import record
from walkrepro.controllers import controller_class
from walkrepro.disturbances import DisturbanceSchedule
from walkrepro.provenance import run_metadata
from walkrepro.robot import Robot, load_robot
from walkrepro.sensors import SensorModel
from walkrepro.spec import ExperimentSpec
from walkrepro.world import FLOOR_NAME, build_scene

#: Called as ``progress(sim_time, duration, real_time_factor)`` a few times per second.
ProgressCallback = Callable[[float, float, float], None]

FOOT_BODIES = ("left_foot", "right_foot")
_XYZ = np.arange(3)


@dataclass(frozen=True)
class RunResult:
    """What a run produced (picklable, so runs can fan out over a process pool).

    Attributes:
        experiment: spec name.
        log_path: the MCAP log.
        outcome: ``complete``, ``fell``, ``interrupted`` or ``error``.
        sim_time: simulated time reached [s].
        wall_time: wall-clock duration of the loop [s].
        fall_time: time of the fall [s], or None.
        message: one line for humans (why it fell or what went wrong).
        timing: where the wall time went (see :class:`RunTiming`).
    """

    experiment: str
    log_path: Path
    outcome: str
    sim_time: float
    wall_time: float
    fall_time: float | None
    message: str
    timing: RunTiming | None = None

    @property
    def real_time_factor(self) -> float:
        """Simulated seconds per wall-clock second."""
        return self.sim_time / self.wall_time if self.wall_time > 0 else math.inf


@dataclass(frozen=True)
class RunTiming:
    """Where a run's wall time went.

    Attributes:
        stages: total wall time per stage [s]: ``physics`` (mj_step1, mj_step2),
            ``sensors``, ``controller``, ``logging``, ``bookkeeping`` (contacts, fall
            detection, disturbances), and ``controller.<part>`` entries for the
            controller's own split (part of ``controller``).
        tick_median: median wall time of one control period, all stages [s].
        tick_p99: 99th percentile of the same [s].
        n_ticks: control ticks measured.
        memory_growth: growth of the process's resident memory from a tenth of the run to its
            end [bytes]; near zero when memory stays flat (NaN where the platform cannot tell).
    """

    stages: dict[str, float]
    tick_median: float
    tick_p99: float
    n_ticks: int
    memory_growth: float = math.nan


class StageClock:
    """Accumulates wall time per stage with one ``perf_counter_ns`` call per lap.

    ``lap(stage)`` charges the time since the previous lap to ``stage``; ``tick()`` marks
    the start of a control period. Per-tick costs go to a preallocated array, so memory
    stays flat over a run.
    """

    STAGES = ("physics", "sensors", "controller", "logging", "bookkeeping")

    def __init__(self, n_ticks: int) -> None:
        self._totals = dict.fromkeys(self.STAGES, 0)
        self._last = time.perf_counter_ns()
        self._tick_start = np.zeros(n_ticks + 1, dtype=np.int64)
        self._n = 0
        # Memory is sampled once after a tenth of the run (past the warm-up: imports, first
        # log chunks, caches) and compared with the end.
        self._memory_tick = max(n_ticks // 10, 1)
        self._memory_warm = math.nan

    def lap(self, stage: str) -> None:
        """Charge the time since the previous lap to ``stage``."""
        now = time.perf_counter_ns()
        self._totals[stage] += now - self._last
        self._last = now

    def tick(self) -> None:
        """Mark the start of a control period."""
        now = time.perf_counter_ns()
        self._totals["bookkeeping"] += now - self._last
        self._last = now
        if self._n < self._tick_start.size:
            self._tick_start[self._n] = now
            self._n += 1
        if self._n == self._memory_tick:
            self._memory_warm = _resident_memory()

    def summary(self, controller_split: dict[str, float] | None = None) -> RunTiming:
        """Totals and per-tick statistics so far, with the controller's own split if given."""
        ticks = np.diff(self._tick_start[: self._n]) * 1e-9
        stages = {k: v * 1e-9 for k, v in self._totals.items()}
        stages.update({f"controller.{k}": v for k, v in (controller_split or {}).items()})
        return RunTiming(
            stages=stages,
            tick_median=float(np.median(ticks)) if ticks.size else float("nan"),
            tick_p99=float(np.percentile(ticks, 99)) if ticks.size else float("nan"),
            n_ticks=int(ticks.size),
            memory_growth=_resident_memory() - self._memory_warm,
        )


def _resident_memory() -> float:
    """Resident memory of this process now [bytes] (Linux), else its peak so far; NaN where
    neither is known."""
    try:
        with open("/proc/self/statm", "rb") as statm:
            return float(int(statm.read().split()[1]) * _PAGE_SIZE)
    except (OSError, ValueError, IndexError):
        pass
    try:
        import resource
    except ImportError:  # Windows
        return math.nan
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return float(peak if sys.platform == "darwin" else peak * 1024)  # bytes on macOS, else KiB


_PAGE_SIZE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096


class SimulationError(RuntimeError):
    """The physics became invalid (NaN, MuJoCo's bad-acceleration reset)."""


def run(
    spec: ExperimentSpec, log_path: Path, progress: ProgressCallback | None = None
) -> RunResult:
    """Simulate ``spec`` and write its log to ``log_path``.

    Ctrl-C ends the loop cleanly: the log is closed and marked ``interrupted``. Any other
    exception marks the log ``error`` and is re-raised after the log is closed.
    """
    robot = load_robot(spec.robot)
    scene = build_scene(robot, spec)
    model = scene.model
    data = mujoco.MjData(model)
    _set_home(robot, model, data)
    mujoco.mj_forward(model, data)

    cls = controller_class(spec.controller.type)
    controller = cls()
    controller.reset(
        robot, cls.Params.model_validate(spec.controller.params), spec.sim.control_period
    )
    sensors = SensorModel(robot, model, spec.sensors, spec.sim.control_period, spec.sim.seed)
    disturbances = DisturbanceSchedule(spec.disturbances)
    contacts = _ContactReader(model)

    def body_state(body: str) -> tuple[np.ndarray, np.ndarray]:
        """A body's CoM position and linear velocity, world frame, in the current state
        (``mj_step1`` has run; the resulting force is logged, so replay holds)."""
        i = model.body(body).id
        vel = np.zeros(6)
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, i, vel, 0)
        return data.xipos[i].copy(), vel[3:].copy()

    fall = _FallDetector(robot, model, spec)

    writer = record.LogWriter(
        log_path, scene_xml=scene.xml, spec_yaml=spec.to_yaml(), metadata=run_metadata(spec)
    )
    substeps, n_steps = spec.sim.substeps, spec.sim.n_steps
    ctrl = data.ctrl.copy()
    ctrl_json = b""
    wrenches: dict[str, np.ndarray] = {}
    body_ids = {d.body: model.body(d.body).id for d in spec.disturbances}
    outcome, message, fall_time = "complete", "", None
    wall_start = time.perf_counter()
    last_report = wall_start
    step = 0
    interrupt = _InterruptFlag()
    clock = StageClock(n_steps // substeps + 1)
    bad_qacc = data.warning[mujoco.mjtWarning.mjWARN_BADQACC]  # a live view of the counter
    lap = clock.lap
    try:
        for step in range(n_steps):
            if interrupt.requested:
                raise KeyboardInterrupt
            tick = step % substeps == 0
            if tick:
                clock.tick()
                _check_finite(data, data.time)
            # Positions, velocities, collisions and their sensors for this state; the
            # acceleration stage (constraint forces, F/T, accelerometer) comes after the command.
            mujoco.mj_step1(model, data)
            lap("physics")
            t = data.time
            if tick:
                reason = fall.check(data)
                lap("bookkeeping")
                writer.write_float64(record.TOPIC_STATE, _state_msg(step, data), t)
                lap("logging")
                if reason:
                    outcome, fall_time, message = "fell", t, f"fell at t = {t:.3f} s ({reason})"
                    writer.write(record.TOPIC_EVENTS, {"t": t, "kind": "fall", "reason": reason}, t)
                    break
                snapshot = sensors.read(model, data)
                lap("sensors")
                command = controller.step(t, snapshot)
                ctrl = _checked_ctrl(command.ctrl, model.nu, t)
                lap("controller")
                ctrl_json = writer.encode_ctrl(ctrl)
                writer.write_float64(record.TOPIC_SENSORS, snapshot.as_message(), t)
                writer.write_float64(record.TOPIC_SIGNALS, {"t": t, **command.signals}, t)
                for event in command.events:
                    writer.write(record.TOPIC_EVENTS, {"t": t, **_jsonable(event)}, t)
                lap("logging")
                now = time.perf_counter()
                if progress is not None and now - last_report > 0.2:
                    progress(t, spec.sim.duration, t / max(now - wall_start, 1e-9))
                    last_report = now
            if disturbances.active_at(t):
                wrenches, events = disturbances.wrenches(t, controller.frame, body_state)
                for event in events:
                    writer.write(record.TOPIC_EVENTS, {"t": t, **event}, t)
                data.xfrc_applied[:] = 0.0
                for body, wrench in wrenches.items():
                    data.xfrc_applied[body_ids[body]] = wrench
            elif wrenches:
                wrenches = {}
                data.xfrc_applied[:] = 0.0
            lap("bookkeeping")
            data.ctrl[:] = ctrl
            writer.write_inputs(step, ctrl_json, wrenches, t)
            lap("logging")
            # Actuation, constraint forces and acceleration-stage sensors, then integration:
            # mj_step1 + mj_step2 is mj_step, so `walkrepro verify` replays it bit for bit.
            mujoco.mj_step2(model, data)
            lap("physics")
            if bad_qacc.number > 0:
                raise SimulationError(
                    f"simulation became unstable at t = {t:.4f} s (MuJoCo reported a "
                    "bad acceleration); the controller's torques or the timestep are too large"
                )
            if tick:
                # The contact forces that acted during this step (data.contact is still this
                # step's, efc_force was just solved with the new command).
                pairs = contacts.read(data)
                lap("bookkeeping")
                writer.write_float64(
                    record.TOPIC_CONTACTS, {"step": step, "t": t, "pairs": pairs}, t
                )
                lap("logging")
        else:
            step = n_steps
        if outcome == "complete":
            # The state after the last step (a fall already logged the state it was seen in).
            _check_finite(data, data.time)
            writer.write_float64(record.TOPIC_STATE, _state_msg(step, data), data.time)
    except KeyboardInterrupt:
        outcome, message = "interrupted", f"interrupted at t = {data.time:.3f} s"
    except SimulationError as exc:
        outcome, message = "error", str(exc)
    except BaseException as exc:
        writer.close("error", {"error": "".join(traceback.format_exception_only(exc)).strip()})
        raise
    finally:
        interrupt.restore()
    wall = time.perf_counter() - wall_start
    extra = {"sim_time": repr(float(data.time)), "wall_time": f"{wall:.3f}"}
    if fall_time is not None:
        extra["fall_time"] = repr(float(fall_time))
    if message:
        extra["message"] = message
    writer.close(outcome, extra)
    if progress is not None:
        progress(float(data.time), spec.sim.duration, data.time / max(wall, 1e-9))
    return RunResult(
        experiment=spec.name,
        log_path=log_path,
        outcome=outcome,
        sim_time=float(data.time),
        wall_time=wall,
        fall_time=fall_time,
        message=message or f"completed {data.time:.3f} s",
        timing=clock.summary(controller.timing()),
    )


class _InterruptFlag:
    """Turns the first Ctrl-C into a flag the loop checks between steps.

    So the log is never cut in the middle of a message; a second Ctrl-C interrupts at once.
    """

    def __init__(self) -> None:
        self.requested = False
        self._previous = None
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._handle)

    def _handle(self, signum: int, frame: object) -> None:
        self.requested = True
        signal.signal(signal.SIGINT, self._previous or signal.default_int_handler)

    def restore(self) -> None:
        """Put back the SIGINT handler that was there before the run."""
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None


def _set_home(robot: Robot, model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Start from the robot's ``home`` keyframe; obstacles keep their compiled pose."""
    data.qpos[: robot.home_qpos.size] = robot.home_qpos
    data.ctrl[:] = robot.home_ctrl


def _state_msg(step: int, data: mujoco.MjData) -> dict:
    """The ``/sim/state`` message; MjData's float64 arrays go to the encoder as they are."""
    return {"step": step, "t": data.time, "qpos": data.qpos, "qvel": data.qvel, "act": data.act}


def _check_finite(data: mujoco.MjData, t: float) -> None:
    # One reduction instead of two elementwise checks: any NaN/inf makes the sum non-finite.
    if not math.isfinite(float(data.qpos.sum() + data.qvel.sum())):
        raise SimulationError(f"simulation state became NaN/inf at t = {t:.4f} s")


def _checked_ctrl(ctrl: np.ndarray, nu: int, t: float) -> np.ndarray:
    ctrl = np.asarray(ctrl, dtype=float)
    if ctrl.shape != (nu,):
        raise ValueError(f"controller returned ctrl of shape {ctrl.shape}, expected ({nu},)")
    if not np.all(np.isfinite(ctrl)):
        raise SimulationError(f"controller returned a non-finite command at t = {t:.4f} s")
    return ctrl.copy()


def _jsonable(values: object) -> dict:
    """numpy scalars and arrays to plain Python for the JSON log."""
    out = {}
    for key, value in dict(values).items():  # type: ignore[call-overload]
        if isinstance(value, np.ndarray):
            value = value.tolist()
        elif isinstance(value, np.generic):
            value = value.item()
        out[key] = value
    return out


@dataclass(frozen=True)
class _ContactPlan:
    """How to turn one set of contacts (a tuple of geom pairs) into pair wrenches.

    The same sets recur tick after tick, so everything that depends only on which geoms
    touch is worked out once per set.

    Attributes:
        rows: the robot-world contacts among all (a slice when they are all of them).
        sign: +1/-1 per row so the force is the one on the robot geom; None when all +1.
        keys: ``"<robot body>/<world geom>"`` of each pair, in order of first appearance.
        starts: first row of each pair's run of rows (``np.add.reduceat`` offsets).
        order: row order that makes each pair's rows one run (None when they already are).
    """

    rows: slice | np.ndarray
    sign: np.ndarray | None
    keys: tuple[str, ...]
    starts: np.ndarray
    order: np.ndarray | None


class _ContactReader:
    """Net contact wrench on each robot body from each world geom (floor, obstacles)."""

    #: Contact sets remembered; a walk sees tens. The cache is emptied when full, so memory
    #: stays bounded however long the run.
    MAX_PLANS = 4096

    def __init__(self, model: mujoco.MjModel) -> None:
        self._model = model
        self._world_geom = np.array(
            [
                (model.geom(i).name == FLOOR_NAME or model.geom(i).name.startswith("obstacle"))
                for i in range(model.ngeom)
            ]
        )
        self._geom_name = [model.geom(i).name for i in range(model.ngeom)]
        self._body_name = [model.body(model.geom_bodyid[i]).name for i in range(model.ngeom)]
        self._force = np.zeros(6)
        self._elliptic = model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
        self._plans: dict[bytes, _ContactPlan | None] = {}

    def read(self, data: mujoco.MjData) -> dict[str, np.ndarray]:
        """``{"<robot body>/<world geom>": [fx, fy, fz, tx, ty, tz]}`` in the world frame.

        The torque is about the world origin, so a pair's centre of pressure on a
        horizontal surface is ``(-ty / fz, tx / fz)``.
        """
        n = data.ncon
        if n == 0:
            return {}
        contact = data.contact  # each field access builds a view: read each once
        geom = contact.geom[:n]
        signature = geom.tobytes()
        plan = self._plans.get(signature, False)
        if plan is False:
            if len(self._plans) >= self.MAX_PLANS:
                self._plans.clear()
            plan = self._plans[signature] = self._plan(geom)
        if plan is None:
            return {}
        rows = plan.rows
        local = self._local_forces(data, rows)
        # mj_contactForce gives the force of geom1 on geom2 in the contact frame, whose rows
        # are the frame's axes in world coordinates: world force = frameᵀ · local.
        force = np.einsum("ni,nij->nj", local, contact.frame[rows].reshape(-1, 3, 3))
        if plan.sign is not None:
            force *= plan.sign
        # Torque about the world origin, p × f, on doubled columns: [1:4] is (y, z, x) and
        # [2:5] is (z, x, y), views instead of gathers.
        pos = contact.pos[rows]
        pp = np.concatenate((pos, pos), axis=1)
        ff = np.concatenate((force, force), axis=1)
        wrench = np.empty((force.shape[0], 6))
        wrench[:, :3] = force
        wrench[:, 3:] = pp[:, 1:4] * ff[:, 2:5] - pp[:, 2:5] * ff[:, 1:4]
        if plan.order is not None:
            wrench = wrench[plan.order]
        # Each pair's rows summed in row order.
        return dict(zip(plan.keys, np.add.reduceat(wrench, plan.starts, axis=0), strict=True))

    def _plan(self, geom: np.ndarray) -> _ContactPlan | None:
        """The plan for this contact set, or None when no contact is robot-world."""
        world = self._world_geom[geom]
        robot_world = world[:, 0] != world[:, 1]
        rows: slice | np.ndarray = (
            slice(0, len(geom)) if robot_world.all() else np.flatnonzero(robot_world)
        )
        geom, world = geom[rows], world[rows]
        if len(geom) == 0:
            return None
        world_first = world[:, 0]
        # The force on the robot geom: flip the rows where the robot geom is geom2's partner.
        sign = None if world_first.all() else np.where(world_first, 1.0, -1.0)[:, None]
        robot_geom = np.where(world_first, geom[:, 1], geom[:, 0]).tolist()
        world_geom = np.where(world_first, geom[:, 0], geom[:, 1]).tolist()
        labels = [
            f"{self._body_name[r]}/{self._geom_name[w]}"
            for r, w in zip(robot_geom, world_geom, strict=True)
        ]
        keys = tuple(dict.fromkeys(labels))
        rank = {key: i for i, key in enumerate(keys)}
        # A stable sort by pair keeps each pair's rows in their original order.
        order = np.argsort([rank[label] for label in labels], kind="stable")
        grouped = [labels[i] for i in order]
        starts = np.array(
            [i for i, label in enumerate(grouped) if i == 0 or label != grouped[i - 1]]
        )
        in_order = bool(np.all(order == np.arange(len(order))))
        return _ContactPlan(
            rows=rows, sign=sign, keys=keys, starts=starts, order=None if in_order else order
        )

    def _local_forces(self, data: mujoco.MjData, rows: slice | np.ndarray) -> np.ndarray:
        """Force of geom1 on geom2 in each contact's frame, shape (n_rows, 3).

        With elliptic cones and condim >= 3 these are the first three rows of the contact's
        constraint force, which is all ``mj_contactForce`` copies; read them at once.
        """
        contact = data.contact
        adr, dim = contact.efc_address[rows], contact.dim[rows]
        if self._elliptic and adr.min() >= 0 and dim.min() >= 3:
            return data.efc_force[adr[:, None] + _XYZ]
        index = np.arange(data.ncon)[rows]
        local = np.empty((index.size, 3))
        for row, i in enumerate(index.tolist()):
            mujoco.mj_contactForce(self._model, data, i, self._force)
            local[row] = self._force[:3]
        return local


class _FallDetector:
    """TARGETS.md: pelvis below a fraction of nominal height, or a non-foot body on the floor."""

    def __init__(self, robot: Robot, model: mujoco.MjModel, spec: ExperimentSpec) -> None:
        self._min_z = spec.sim.fall.pelvis_height_ratio * float(robot.home_qpos[2])
        self._check_contact = spec.sim.fall.non_foot_ground_contact
        self._pelvis = model.body("pelvis").id
        self._floor = floor = model.geom(FLOOR_NAME).id
        feet = {model.body(name).id for name in FOOT_BODIES}
        # Geoms of the robot's tree other than the feet (obstacles may rest on the floor).
        non_foot = np.array(
            [
                model.body_rootid[model.geom_bodyid[g]] == self._pelvis
                and model.geom_bodyid[g] not in feet
                for g in range(model.ngeom)
            ]
        )
        # falls[g1, g2]: a contact between these two geoms is a non-foot body on the floor.
        self._falls = np.zeros((model.ngeom, model.ngeom), dtype=bool)
        self._falls[floor, non_foot] = self._falls[non_foot, floor] = True
        self._geom_body = [model.body(model.geom_bodyid[g]).name for g in range(model.ngeom)]
        self._suspects: dict[bytes, np.ndarray] = {}

    def check(self, data: mujoco.MjData) -> str:
        """Reason for a fall, or an empty string."""
        z = data.xpos[self._pelvis, 2]
        if z < self._min_z:
            return f"pelvis height {z:.3f} m below {self._min_z:.3f} m"
        n = data.ncon
        if not (self._check_contact and n):
            return ""
        contact = data.contact
        geom = contact.geom[:n]
        # Which contacts pair the floor with a non-foot geom depends only on the contact set,
        # which recurs tick after tick: look it up once per set (usually: none).
        signature = geom.tobytes()
        rows = self._suspects.get(signature)
        if rows is None:
            if len(self._suspects) >= _ContactReader.MAX_PLANS:
                self._suspects.clear()
            rows = self._suspects[signature] = np.flatnonzero(self._falls[geom[:, 0], geom[:, 1]])
        if rows.size:
            touching = rows[contact.dist[rows] < 0]
            if touching.size:
                g1, g2 = geom[touching[0]]
                robot_geom = g2 if g1 == self._floor else g1
                return f"{self._geom_body[robot_geom]} touched the floor"
        return ""
