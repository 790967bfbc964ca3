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

import contextlib
import math
import os
import sys
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from walkrepro.controllers import controller_class
from walkrepro.log import record
from walkrepro.log.foxglove import frame_every
from walkrepro.runs.provenance import run_metadata
from walkrepro.runs.resolve import Experiment, assemble
from walkrepro.runtime.interrupt import InterruptFlag
from walkrepro.sim import contact_law
from walkrepro.sim.contact_reader import ContactReader, FallDetector
from walkrepro.sim.disturbances import DisturbanceSchedule
from walkrepro.sim.robot import Robot, with_servo_gains
from walkrepro.sim.sensors import SensorModel
from walkrepro.specs.models import ExperimentSpec

#: Called as ``progress(sim_time, duration, real_time_factor)`` a few times per second.
ProgressCallback = Callable[[float, float, float], None]


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
    spec: ExperimentSpec,
    log_path: Path,
    progress: ProgressCallback | None = None,
    interrupt: InterruptFlag | None = None,
    resolved: Experiment | None = None,
) -> RunResult:
    """Simulate ``spec`` and write its log to ``log_path``.

    Ctrl-C ends the run cleanly at any moment, set-up included: the log is closed and marked
    ``interrupted`` (with no state at all if it came before the first step). ``interrupt``
    is the caller's flag (``walkrepro.runs.experiment`` holds one over the whole run); without
    one, the run installs its own. Any other exception marks the log ``error`` and is
    re-raised after the log is closed. ``resolved`` is ``spec`` resolved once
    (:func:`walkrepro.runs.resolve.resolve`: its robot, compiled scene and typed controller
    parameters), when the caller has it; by default they are assembled here from ``spec``.
    """
    if interrupt is None:
        with InterruptFlag() as own:
            return run(spec, log_path, progress, own, resolved)
    sim = _Simulation(spec, resolved if resolved is not None else assemble(spec), log_path)
    sim.simulate(interrupt, progress)
    return sim.finish(log_path, progress)


class _Simulation:
    """One run's parts, built once: the model and its data, the controller, the sensors, the
    disturbances, the contact reader, the fall detector, the log writer and the stage clock;
    and how the run ended so far (``outcome``, ``message``, ``fall_time``, ``step``)."""

    def __init__(self, spec: ExperimentSpec, resolved: Experiment, log_path: Path) -> None:
        robot, scene = resolved.robot, resolved.scene
        self.spec = spec
        self.model = model = scene.model
        self.data = data = mujoco.MjData(model)
        _set_home(robot, model, data)
        mujoco.mj_forward(model, data)
        self.controller = controller_class(spec.controller.type)()
        self.controller.reset(
            with_servo_gains(robot, model),  # the spec's servo gains, as the controller runs them
            resolved.params,
            spec.sim.control_period,
        )
        self.sensors = SensorModel(
            robot, model, spec.sensors, spec.sim.control_period, spec.sim.seed
        )
        self.disturbances = DisturbanceSchedule(spec.disturbances)
        self.contacts = ContactReader(model)
        self.body_ids = {d.body: model.body(d.body).id for d in spec.disturbances}
        self.body_state = _body_state_reader(model, data, self.body_ids)
        self.fall = FallDetector(robot, model, spec)
        self.writer = record.LogWriter(
            log_path, scene_xml=scene.xml, spec_yaml=spec.to_yaml(), metadata=run_metadata(spec)
        )
        self.outcome, self.message, self.fall_time = "complete", "", None
        self.step = 0
        self.wall_start = self.last_report = time.perf_counter()
        self.clock = StageClock(spec.sim.n_steps // spec.sim.substeps + 1)
        # Live views of MuJoCo's warning counters: a non-finite or huge state (caught at the
        # start of mj_step1) or acceleration (in mj_step2) makes MuJoCo reset the data and
        # count it.
        warnings = data.warning
        self.bad_state = (
            warnings[mujoco.mjtWarning.mjWARN_BADQPOS],
            warnings[mujoco.mjtWarning.mjWARN_BADQVEL],
        )
        self.bad_qacc = warnings[mujoco.mjtWarning.mjWARN_BADQACC]
        # MjData's arrays live as long as `data`: one view each instead of one per access.
        self.qpos, self.qvel, self.act, self.ctrl_in = data.qpos, data.qvel, data.act, data.ctrl
        self.xpos, self.xquat = data.xpos, data.xquat
        # Foxglove's body frames at >= 30 Hz, on control ticks.
        self.frame_steps = spec.sim.substeps * frame_every(spec.sim.control_period)

    def simulate(self, interrupt: InterruptFlag, progress: ProgressCallback | None) -> None:
        """Step the physics to the end of the run, a fall, an error or Ctrl-C, and log the
        final state; a Python error closes the log as ``error`` and is re-raised."""
        # A robot whose lab's simulator computed its ground contact carries that law in its
        # model (walkrepro/sim/contact_law.py); it acts in the steps, as it does in a replay.
        ground = contextlib.ExitStack()
        ground.enter_context(contact_law.applied_to(self.model))
        try:
            self._steps(interrupt, progress)
            if self.outcome == "complete":
                # The state after the last step (a fall already logged the state it was seen in).
                data = self.data
                _check_finite(data, data.time)
                self.writer.write_state(self.step, data.time, self.qpos, self.qvel, self.act)
        except KeyboardInterrupt:
            self.outcome = "interrupted"
            self.message = f"interrupted at t = {self.step * self.spec.sim.timestep:.3f} s"
        except SimulationError as exc:
            self.outcome, self.message = "error", str(exc)
        except BaseException as exc:
            self.writer.close(
                "error", {"error": "".join(traceback.format_exception_only(exc)).strip()}
            )
            raise
        finally:
            ground.close()

    def _steps(self, interrupt: InterruptFlag, progress: ProgressCallback | None) -> None:
        """The physics steps, each ``mj_step1``, a control tick every ``substeps`` steps,
        the disturbances, the step's log, ``mj_step2``; ``step`` is the step reached."""
        model, data, writer, contacts = self.model, self.data, self.writer, self.contacts
        disturbances, clock, lap = self.disturbances, self.clock, self.clock.lap
        qpos, qvel, act, bad_qacc = self.qpos, self.qvel, self.act, self.bad_qacc
        substeps, n_steps, timestep = (
            self.spec.sim.substeps,
            self.spec.sim.n_steps,
            self.spec.sim.timestep,
        )
        ctrl_held = np.asarray(data.ctrl, dtype=np.float64).copy()
        wrenches: dict[str, np.ndarray] = {}
        for step in range(n_steps):
            self.step = step
            if interrupt.requested:  # also a Ctrl-C during set-up: stop before step 0
                raise KeyboardInterrupt
            tick = step % substeps == 0
            if tick:
                clock.tick()
            # Positions, velocities, collisions and their sensors for this state; the
            # acceleration stage (constraint forces, F/T, accelerometer) comes after the command.
            # Time is the step count times the timestep, never accumulated by addition (which
            # drifts: 7.257999999998697). MuJoCo's clock is set to it; no dynamics reads it.
            t = step * timestep
            data.time = t
            mujoco.mj_step1(model, data)
            lap("physics")
            if tick:
                ticked = self._control_tick(step, t, progress)
                if ticked is None:  # fell: logged, the run ends in this state
                    return
                snapshot, command, ctrl_held = ticked
            if disturbances.active_at(t):
                wrenches = self._disturb(t)
            elif wrenches:
                wrenches = {}
                data.xfrc_applied[:] = 0.0
            lap("bookkeeping")  # the disturbances (RunTiming's definition of the stage)
            if tick:
                # The state this tick saw (unchanged since mj_step1), the snapshot, the
                # signals, and the inputs of this step.
                state = record.SimState(step, t, qpos, qvel, act)
                writer.write_tick(state, snapshot, command.signals, ctrl_held, wrenches)
            else:
                writer.write_inputs(step, ctrl_held, wrenches, t)
            lap("logging")
            # Actuation, constraint forces and acceleration-stage sensors, then integration:
            # mj_step1 + mj_step2 is mj_step, so `walkrepro verify` replays it bit for bit.
            mujoco.mj_step2(model, data)
            lap("physics")
            if bad_qacc.number:
                raise SimulationError(
                    f"simulation became unstable at t = {t:.4f} s (MuJoCo reported a "
                    "bad acceleration); the controller's torques or the timestep are too large"
                )
            if tick:
                # The contact forces that acted during this step (data.contact is still this
                # step's, efc_force was just solved with the new command).
                pair_names, pair_wrenches = contacts.read_pairs(data)
                lap("bookkeeping")
                writer.write_contact_pairs(step, t, pair_names, pair_wrenches)
                lap("logging")
        self.step = n_steps
        data.time = n_steps * timestep

    def _control_tick(
        self, step: int, t: float, progress: ProgressCallback | None
    ) -> tuple[object, object, np.ndarray] | None:
        """One control tick, after ``mj_step1``: the fall check, Foxglove's frames, the
        sensors, the controller and its command (set in ``ctrl``, held until the next tick).

        Returns:
            The sensor snapshot, the controller's command and the command as logged, or None
            when the robot fell (the state and the fall are logged, the outcome set).
        """
        writer, lap = self.writer, self.clock.lap
        if self.bad_state[0].number or self.bad_state[1].number:
            raise SimulationError(f"simulation state became NaN/inf at t = {t:.4f} s")
        reason = self.fall.check(self.data)
        lap("bookkeeping")
        if step % self.frame_steps == 0:
            writer.write_frames(t, self.xpos, self.xquat)
        if reason:
            writer.write_state(step, t, self.qpos, self.qvel, self.act)
            self.outcome, self.fall_time = "fell", t
            self.message = f"fell at t = {t:.3f} s ({reason})"
            writer.write(record.TOPIC_EVENTS, {"t": t, "kind": "fall", "reason": reason}, t)
            return None
        lap("logging")
        snapshot = self.sensors.read(self.model, self.data)
        lap("sensors")
        command = self.controller.step(t, snapshot)
        lap("controller")
        # The command as MuJoCo will hold it (float64), checked once.
        ctrl = np.asarray(command.ctrl, dtype=np.float64)
        ctrl_held = _checked_ctrl(writer, ctrl, self.model.nu, t)
        self.ctrl_in[:] = ctrl  # mj_step leaves ctrl alone: held until the next tick
        now = time.perf_counter()
        if progress is not None and now - self.last_report > 0.2:
            progress(t, self.spec.sim.duration, t / max(now - self.wall_start, 1e-9))
            self.last_report = now
        lap("bookkeeping")
        for event in command.events:
            writer.write(record.TOPIC_EVENTS, {"t": t, **_jsonable(event)}, t)
        lap("logging")
        return snapshot, command, ctrl_held

    def _disturb(self, t: float) -> dict[str, np.ndarray]:
        """The disturbances' wrenches at ``t``, written to ``xfrc_applied`` (their events
        logged); returns them by body name."""
        wrenches, events = self.disturbances.wrenches(t, self.controller.frame, self.body_state)
        for event in events:
            self.writer.write(record.TOPIC_EVENTS, {"t": t, **event}, t)
        xfrc = self.data.xfrc_applied
        xfrc[:] = 0.0
        for body, wrench in wrenches.items():
            xfrc[self.body_ids[body]] = wrench
        self.clock.lap("bookkeeping")
        return wrenches

    def finish(self, log_path: Path, progress: ProgressCallback | None) -> RunResult:
        """Close the log with the outcome and report what the run produced."""
        wall = time.perf_counter() - self.wall_start
        # Steps completed (a fall or Ctrl-C stops at the top of a step, whose state is the last).
        sim_time = self.step * self.spec.sim.timestep
        extra = {"sim_time": repr(sim_time), "wall_time": f"{wall:.3f}"}
        if self.fall_time is not None:
            extra["fall_time"] = repr(float(self.fall_time))
        if self.message:
            extra["message"] = self.message
        self.writer.close(self.outcome, extra)
        if progress is not None:
            progress(sim_time, self.spec.sim.duration, sim_time / max(wall, 1e-9))
        return RunResult(
            experiment=self.spec.name,
            log_path=log_path,
            outcome=self.outcome,
            sim_time=sim_time,
            wall_time=wall,
            fall_time=self.fall_time,
            message=self.message or f"completed {sim_time:.3f} s",
            timing=self.clock.summary(self.controller.timing()),
        )


def _body_state_reader(
    model: mujoco.MjModel, data: mujoco.MjData, body_ids: dict[str, int]
) -> Callable[[str], tuple[np.ndarray, np.ndarray]]:
    """What a hand that holds a body feels: the body's centre of mass [m] and its linear
    velocity [m/s] in the world, read after ``mj_step1`` (positions and velocities of this
    step). Only the disturbance model reads it, never the controller."""
    velocity = np.zeros(6)

    def state(body: str) -> tuple[np.ndarray, np.ndarray]:
        body_id = body_ids[body]
        # [angular; linear] at the body's centre of mass, world orientation.
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, body_id, velocity, 0)
        return data.xipos[body_id].copy(), velocity[3:].copy()

    return state


def _set_home(robot: Robot, model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Start from the robot's ``home`` keyframe; obstacles keep their compiled pose."""
    data.qpos[: robot.home_qpos.size] = robot.home_qpos
    data.ctrl[:] = robot.home_ctrl


def _check_finite(data: mujoco.MjData, t: float) -> None:
    # One reduction instead of two elementwise checks: any NaN/inf makes the sum non-finite.
    if not math.isfinite(float(data.qpos.sum() + data.qvel.sum())):
        raise SimulationError(f"simulation state became NaN/inf at t = {t:.4f} s")


def _checked_ctrl(writer: record.LogWriter, ctrl: np.ndarray, nu: int, t: float) -> np.ndarray:
    """A controller's command, which must be ``nu`` finite numbers."""
    if ctrl.shape != (nu,):
        raise ValueError(f"controller returned ctrl of shape {ctrl.shape}, expected ({nu},)")
    try:
        return writer.encode_ctrl(ctrl)  # rejects NaN and infinity
    except ValueError:
        raise SimulationError(
            f"controller returned a non-finite command at t = {t:.4f} s"
        ) from None


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
