"""Metrics from synthetic logs whose answers are known; the not-measurable contract.

The helpers here (:func:`write_log`, :class:`Tick`, :class:`Poser`) also build the paper
metrics' logs (``test_paper_metrics_*.py``): real MCAP logs of a real robot scene, with
hand-made states, contacts, signals and events.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest
import yaml

from walkrepro.evaluation.metrics import (
    LIFT_CLEARANCE,
    LogData,
    MetricArgError,
    MetricResults,
    NotMeasurable,
    check_metric_arg,
    compute,
    default_metric_names,
    detect_steps,
    evaluate,
    metric_names,
    split_metric,
)
from walkrepro.log import record
from walkrepro.runs.provenance import run_metadata
from walkrepro.sim.robot import load_robot
from walkrepro.sim.world import build_scene
from walkrepro.specs.models import ExperimentSpec

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"
DT = 0.01  # [s] between synthetic messages
SPEED = 0.1  # [m/s] of the synthetic pelvis
FEET = ("left_foot", "right_foot")

# ---- building synthetic logs ---------------------------------------------------------------


def measured(d: LogData, name: str) -> float:
    """The value of a metric that must be measurable on ``d``."""
    r = evaluate(d, [name])
    assert name not in r.reasons, r.reasons.get(name)
    return r.values[name]


def unmeasurable_reason(d: LogData, name: str) -> str:
    """Why a metric that must not be measurable on ``d`` is not (it must be NaN)."""
    r = evaluate(d, [name])
    assert math.isnan(r.values[name])
    return r.reasons[name]


@dataclass
class Tick:
    """One control tick of a synthetic log (``None``: the default of :func:`write_log`)."""

    t: float
    qpos: np.ndarray | None = None
    qvel: np.ndarray | None = None
    pairs: dict[str, list[float]] | None = None
    signals: dict[str, Any] = field(default_factory=dict)
    events: list[dict[str, Any]] = field(default_factory=list)
    xfrc: dict[str, list[float]] = field(default_factory=dict)
    ctrl: np.ndarray | None = None


@cache
def _robot(name: str):  # noqa: ANN202 (a Robot)
    return load_robot(name)


def make_spec(robot: str = "dyros_red", duration: float = 2.0, **fields: Any) -> ExperimentSpec:
    """A minimal spec for a synthetic log (``fields`` are top-level spec fields)."""
    return ExperimentSpec.model_validate(
        {
            "name": "synthetic",
            "description": "d",
            "paper": {"key": "walkrepro"},
            "robot": robot,
            "controller": {"type": "posture"},
            "sim": {"duration": duration, "timestep": DT, "control_period": DT},
            **fields,
        }
    )


def standing_pairs(
    robot: str = "dyros_red", loaded: Iterable[str] = FEET
) -> dict[str, list[float]]:
    """Floor wrenches sharing the robot's weight between the ``loaded`` feet, each at its
    sole centre at ``home`` (torque about the world origin, as logged)."""
    r = _robot(robot)
    loaded = list(loaded)
    weight = r.total_mass * 9.81
    pairs = {}
    for foot in loaded:
        x, y = home_sole(robot, foot)[:2]
        fz = weight / len(loaded)
        pairs[f"{foot}/floor"] = [0.0, 0.0, fz, y * fz, -x * fz, 0.0]
    return pairs


def floor_wrench(x: float, y: float, fz: float) -> list[float]:
    """A floor wrench of vertical force ``fz`` [N] with its CoP at (x, y) [m]."""
    return [0.0, 0.0, fz, y * fz, -x * fz, 0.0]


@cache
def home_sole(robot: str, foot: str) -> tuple[float, float, float]:
    """Sole-centre position of a foot at ``home`` [m]."""
    r = _robot(robot)
    model = mujoco.MjModel.from_xml_path(str(r.xml_path))
    data = mujoco.MjData(model)
    data.qpos[:] = r.home_qpos
    mujoco.mj_kinematics(model, data)
    return tuple(float(v) for v in data.site(f"{foot.split('_')[0]}_sole").xpos)


def write_log(
    path: Path,
    ticks: Iterable[Tick],
    spec: ExperimentSpec | None = None,
    outcome: str = "complete",
    extra: dict[str, str] | None = None,
) -> LogData:
    """Write ticks as a real MCAP log of the spec's scene and read it back."""
    spec = spec or make_spec()
    robot = _robot(spec.robot)
    scene = build_scene(robot, spec)
    with record.LogWriter(
        path, scene_xml=scene.xml, spec_yaml=spec.to_yaml(), metadata=run_metadata(spec)
    ) as w:
        for tick in ticks:
            step = int(round(tick.t / spec.sim.timestep))
            qpos = robot.home_qpos if tick.qpos is None else tick.qpos
            state = {
                "step": step,
                "t": tick.t,
                "qpos": list(map(float, qpos)),
                "qvel": [0.0] * scene.model.nv
                if tick.qvel is None
                else list(map(float, tick.qvel)),
                "act": [],
            }
            w.write(record.TOPIC_STATE, state, tick.t)
            if tick.signals:
                w.write(record.TOPIC_SIGNALS, {"t": tick.t, **tick.signals}, tick.t)
            for e in tick.events:
                w.write(record.TOPIC_EVENTS, {"t": tick.t, **e}, tick.t)
            pairs = standing_pairs(spec.robot) if tick.pairs is None else tick.pairs
            w.write(record.TOPIC_CONTACTS, {"step": step, "t": tick.t, "pairs": pairs}, tick.t)
            w.write(
                record.TOPIC_INPUTS,
                {
                    "step": step,
                    "ctrl": [0.0] * scene.model.nu
                    if tick.ctrl is None
                    else list(map(float, tick.ctrl)),
                    "xfrc": tick.xfrc,
                },
                tick.t,
            )
        w.close(outcome, extra or {})
    return LogData.from_path(path)


class Poser:
    """``qpos`` with the pelvis and each sole centre where asked (feet kept flat), by
    damped least squares on the leg joints."""

    def __init__(self, robot: str = "dyros_red") -> None:
        r = _robot(robot)
        self.model = mujoco.MjModel.from_xml_path(str(r.xml_path))
        self.data = mujoco.MjData(self.model)
        self.home = r.home_qpos.copy()
        self.robot = robot
        self.sites = {f: self.model.site(f"{f.split('_')[0]}_sole").id for f in FEET}
        self._q = self.home.copy()
        self._solved: dict[tuple, np.ndarray] = {}

    def __call__(
        self,
        pelvis: tuple[float, float, float] = (0.0, 0.0, 0.0),
        **soles: tuple[float, float, float],
    ) -> np.ndarray:
        """qpos with the pelvis moved by ``pelvis`` from home and sole centres at ``soles``
        (world [m], e.g. ``left_foot=(0.1, 0.1, 0.03)``); unnamed feet stay at home."""
        key = (tuple(pelvis), tuple(sorted((f, tuple(p)) for f, p in soles.items())))
        if key not in self._solved:
            self._solved[key] = self._solve(pelvis, soles)
        return self._solved[key].copy()

    def _solve(
        self, pelvis: tuple[float, float, float], soles: dict[str, tuple[float, float, float]]
    ) -> np.ndarray:
        m, d = self.model, self.data
        q = self._q.copy()
        q[0:3] = self.home[0:3] + np.asarray(pelvis)
        q[3:7] = self.home[3:7]
        targets = {f: np.asarray(soles.get(f, home_sole(self.robot, f))) for f in FEET}
        jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        for _ in range(50):
            d.qpos[:] = q
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            rows, errs = [], []
            for f, site in self.sites.items():
                mujoco.mj_jacSite(m, d, jacp, jacr, site)
                rot = d.site_xmat[site].reshape(3, 3)
                # Rotation error towards the world axes (the feet are flat and straight at home).
                rot_err = 0.5 * sum(np.cross(rot[:, i], np.eye(3)[i]) for i in range(3))
                errs += [targets[f] - d.site_xpos[site], rot_err]
                rows += [jacp[:, 6:].copy(), jacr[:, 6:].copy()]
            err = np.concatenate(errs)
            if np.max(np.abs(err)) < 1e-7:
                break
            jac = np.vstack(rows)
            dq = jac.T @ np.linalg.solve(jac @ jac.T + 1e-8 * np.eye(jac.shape[0]), err)
            q[7:] += dq
        else:
            raise AssertionError(f"Poser: no pose reaches {soles} with the pelvis at {pelvis}")
        self._q = q
        return q


# ---- the generic metrics on a walking log ------------------------------------------------------

LIFT = {"left_foot": (0.5, 0.7), "right_foot": (1.0, 1.2)}  # swing windows [s]
SWING_HEIGHT = 0.04  # [m]


@pytest.fixture(scope="module")
def log(tmp_path_factory: pytest.TempPathFactory) -> LogData:
    """A 2 s log: the pelvis moves forward at SPEED, each foot lifts 4 cm once and lands
    0.1 m further on, a 40 N push, an FSM signal, a touch on an obstacle."""
    spec = make_spec(
        world={
            "obstacles": [
                {"name": "obstacle_box", "size": [0.1, 0.1, 0.1], "position": [1, 0, 0.05]}
            ]
        }
    )
    poser = Poser()
    ticks = []
    for step in range(201):
        t = step * DT
        soles, loaded = {}, []
        for foot, (lo, hi) in LIFT.items():
            x0, y0, _ = home_sole("dyros_red", foot)
            s = min(max((t - lo) / (hi - lo), 0.0), 1.0)
            z = SWING_HEIGHT * math.sin(math.pi * s)
            soles[foot] = (x0 + 0.1 * s, y0, z)
            if not lo <= t < hi:
                loaded.append(foot)
        pairs = standing_pairs(loaded=loaded)
        if 1.5 <= t < 1.6:
            pairs["right_foot/obstacle_box"] = [30.0, 0.0, 40.0, 0.0, 0.0, 0.0]
        ticks.append(
            Tick(
                t,
                qpos=poser((SPEED * t, 0, 0), **soles),
                pairs=pairs,
                signals={"fsm_state": -1.0 if t < 0.5 else 1.0},
                xfrc={"pelvis": [0.0, 40.0, 0.0, 0.0, 0.0, 0.0]} if 1.0 <= t < 1.1 else {},
            )
        )
    return write_log(tmp_path_factory.mktemp("log") / "log.mcap", ticks, spec)


def test_touchdowns_found_where_feet_land_after_a_lift(log: LogData) -> None:
    """A step is found where each lifted foot is loaded again; standing at t = 0 is not one."""
    steps = log.footsteps
    assert [s.foot for s in steps] == ["left_foot", "right_foot"]
    assert [round(s.t, 2) for s in steps] == [0.7, 1.2]
    assert steps[0].position[1] > 0 > steps[1].position[1]  # left foot at +y
    assert steps[0].clearance == pytest.approx(SWING_HEIGHT, abs=2e-3)


def test_speed_drift_and_step_metrics(log: LogData) -> None:
    """Speed, drift, step length and step timing match the synthetic motion."""
    m = compute(
        log,
        [
            "mean_forward_speed",
            "pelvis_drift",
            "mean_step_length",
            "footsteps",
            "footsteps:left_foot",
            "mean_step_duration",
            "fell",
            "fall_time",
            "sim_time",
            "slid_steps",
        ],
    )
    assert m["mean_forward_speed"] == pytest.approx(SPEED)
    assert m["pelvis_drift"] == pytest.approx(SPEED * 2.0)
    assert m["footsteps"] == 2 and m["footsteps:left_foot"] == 1
    # The right foot lands 0.5 s later, as far forward as the left (both moved 0.1 m).
    assert m["mean_step_length"] == pytest.approx(0.0, abs=1e-6)
    assert m["mean_step_duration"] == pytest.approx(0.5)
    assert m["fell"] == 0 and math.isnan(m["fall_time"]) and m["sim_time"] == pytest.approx(2.0)
    assert m["slid_steps"] == 0


def test_windowed_speed(log: LogData) -> None:
    """A speed window restricts the average to that interval."""
    m = compute(log, ["mean_forward_speed:0.5-1.5"])
    assert m["mean_forward_speed:0.5-1.5"] == pytest.approx(SPEED)


def test_window_past_the_data_is_not_measurable(log: LogData) -> None:
    """A speed window that ends after the log is not measurable, with the reason."""
    r = evaluate(log, ["mean_forward_speed:0.5-5"])
    assert math.isnan(r.values["mean_forward_speed:0.5-5"])
    assert "before the end of the speed window" in r.reasons["mean_forward_speed:0.5-5"]


def test_peak_forces(log: LogData) -> None:
    """Peak obstacle contact force and peak external force are the injected ones."""
    m = compute(
        log,
        [
            "peak_contact_force:right_foot/obstacle_box",
            "peak_contact_force:left_foot/obstacle*",
            "peak_external_force",
        ],
    )
    assert m["peak_contact_force:right_foot/obstacle_box"] == pytest.approx(50.0)
    assert m["peak_contact_force:left_foot/obstacle*"] == 0.0
    assert m["peak_external_force"] == pytest.approx(40.0)


def test_state_time(log: LogData) -> None:
    """Time spent in each FSM state adds up from the logged signal."""
    m = compute(log, ["state_time:-1", "state_time:1"])
    assert m["state_time:-1"] == pytest.approx(0.5, abs=DT)
    assert m["state_time:1"] == pytest.approx(1.5, abs=2 * DT)


def test_default_metrics_cover_obstacles_and_expectations(log: LogData) -> None:
    """Every run reports each foot's peak force on each obstacle."""
    names = default_metric_names(log.spec)
    assert "peak_contact_force:right_foot/obstacle_box" in names
    assert "peak_contact_force:left_foot/obstacle_box" in names
    values = compute(log, names)
    assert np.isfinite(values["mean_forward_speed"])


# ---- the step definition, on plain arrays ------------------------------------------------------

W = 1000.0  # [N] robot weight of the array tests


def _foot(t: np.ndarray, lifts: list[tuple[float, float, float]], dx: float = 0.0):
    """Arrays of a foot that is unloaded in each (t0, t1, height) window, its sole rising to
    ``height`` in it (sine), and moving ``dx`` forward over each window."""
    fz = np.full(t.size, W / 2)
    z = np.zeros(t.size)
    x = np.zeros(t.size)
    for t0, t1, h in lifts:
        inside = (t >= t0) & (t < t1)
        fz[inside] = 0.0
        s = np.clip((t - t0) / (t1 - t0), 0, 1)
        z[inside] = h * np.sin(np.pi * s[inside])
        x += dx * s
    return fz, z, np.stack([x, np.zeros(t.size)], axis=1)


T = np.arange(0, 3, 0.002)


def test_detect_steps_counts_lifted_swings() -> None:
    """Two swings that lift the sole 3 cm for 0.3 s are two steps, with their clearance."""
    fz, z, xy = _foot(T, [(0.5, 0.8, 0.03), (1.5, 1.8, 0.03)], dx=0.1)
    found = detect_steps(T, fz, z, xy, W)
    assert len(found.steps) == 2
    assert found.steps[0][2] == pytest.approx(0.03, abs=1e-4)
    assert all(shift < 1e-9 for *_, shift in found.ground_phases)


def test_detect_steps_ignores_a_sliding_foot() -> None:
    """A foot unloaded and pushed 10 cm along the floor without lifting is no step but a slide."""
    fz, z, xy = _foot(T, [(0.5, 0.8, 0.0)], dx=0.1)
    found = detect_steps(T, fz, z, xy, W)
    assert found.steps == []
    assert max(shift for *_, shift in found.ground_phases) == pytest.approx(0.1)


def test_detect_steps_ignores_a_loaded_foot_sliding() -> None:
    """A foot that slides 10 cm while carrying weight is no step but a slide."""
    fz = np.full(T.size, W / 2)
    xy = np.stack([np.linspace(0, 0.1, T.size), np.zeros(T.size)], axis=1)
    found = detect_steps(T, fz, np.zeros(T.size), xy, W)
    assert found.steps == [] and found.ground_phases[0][2] == pytest.approx(0.1)


def test_detect_steps_needs_the_clearance() -> None:
    """A swing whose sole rises only 8 mm (below LIFT_CLEARANCE) is not a step."""
    assert LIFT_CLEARANCE > 0.008
    fz, z, xy = _foot(T, [(0.5, 0.8, 0.008)], dx=0.1)
    assert detect_steps(T, fz, z, xy, W).steps == []


def test_detect_steps_needs_the_time() -> None:
    """A 3 cm hop lasting 40 ms (shorter than LIFT_TIME above the clearance) is not a step."""
    fz, z, xy = _foot(T, [(0.5, 0.54, 0.03)])
    assert detect_steps(T, fz, z, xy, W).steps == []


def test_detect_steps_measures_clearance_above_a_block() -> None:
    """Stepping onto a 4 cm block counts only if the sole clears the block's top by 1 cm."""
    for peak, expected in ((0.055, 1), (0.045, 0)):
        fz, _, xy = _foot(T, [(0.5, 0.9, 0.0)], dx=0.2)
        s = np.clip((T - 0.5) / 0.4, 0, 1)
        # Rise to `peak` by 60 % of the swing, then settle onto the block top at 0.04 m.
        z = np.where(
            s < 0.6, peak * np.sin(np.pi / 2 * s / 0.6), peak - (peak - 0.04) * (s - 0.6) / 0.4
        )
        z[T >= 0.9] = 0.04
        assert len(detect_steps(T, fz, z, xy, W).steps) == expected


def test_detect_steps_foot_sliding_off_a_block_is_no_step() -> None:
    """A foot that drops off a 5 cm block's edge to the floor without lifting is no step."""
    fz = np.full(T.size, W / 2)
    fz[(T >= 0.5) & (T < 0.6)] = 0.0
    z = np.where(T < 0.5, 0.05, np.where(T < 0.6, 0.05 * (0.6 - T) / 0.1, 0.0))
    xy = np.zeros((T.size, 2))
    assert detect_steps(T, fz, z, xy, W).steps == []


# ---- the not-measurable contract ---------------------------------------------------------------


def _spec_metric_names() -> list[str]:
    """Every registered metric, with each argument the shipped specs use (and none)."""
    names = set(metric_names())
    for path in sorted(EXPERIMENTS.glob("*.yaml")):
        for e in yaml.safe_load(path.read_text()).get("expect") or []:
            names.add(e["metric"])
            ref = (e.get("relative_to") or {}).get("metric")
            if ref:
                names.add(ref)
    return sorted(n for n in names if split_metric(n)[0] in metric_names())


def _specs_with_pushes() -> ExperimentSpec:
    return make_spec(
        controller={"type": "efsm", "params": {}},
        disturbances=[
            {
                "name": "push",
                "body": "pelvis",
                "frame": "world",
                "force": [5, 0, 0],
                "start": 0.0,
                "duration": 0.01,
            }
        ],
        world={
            "obstacles": [
                {"name": "obstacle_box", "size": [0.1, 0.1, 0.1], "position": [1, 0, 0.05]}
            ]
        },
    )


def _assert_only_not_measurable(data: LogData) -> MetricResults:
    names = _spec_metric_names()
    results = evaluate(data, names)  # no exception other than NotMeasurable escapes
    for name in names:
        value = results.values[name]
        if name in results.reasons:
            assert math.isnan(value) and results.reasons[name]
        else:
            assert not math.isnan(value), f"{name} is NaN without a reason"
    return results


def test_empty_log_every_metric_not_measurable(tmp_path: Path) -> None:
    """On a log interrupted before its first tick every metric is NaN with a reason."""
    data = write_log(
        tmp_path / "log.mcap", [], _specs_with_pushes(), "interrupted", {"sim_time": "0.0"}
    )
    assert data.t.shape == (0,) and data.qpos.shape == (0, data.model.nq)
    assert data.qvel.shape == (0, data.model.nv) and data.footsteps == []
    results = _assert_only_not_measurable(data)
    assert set(results.reasons) == set(results.values)
    assert "interrupted at t = 0.000 s" in results.reasons["fell"]


def test_short_log_never_raises(tmp_path: Path) -> None:
    """On a three-tick log every metric gives a value or NaN with a reason, never an error."""
    ticks = [Tick(k * DT, signals={"efsm_phase": 2.0, "swing_foot": 0.0}) for k in range(3)]
    data = write_log(tmp_path / "log.mcap", ticks, _specs_with_pushes(), "interrupted")
    results = _assert_only_not_measurable(data)
    assert "fell" in results.reasons


def test_unclosed_log_outcome_is_unknown(tmp_path: Path) -> None:
    """A log whose writer never closed reads as outcome ``unknown``; ``fell`` is not measurable."""
    data = write_log(tmp_path / "log.mcap", [Tick(0.0), Tick(DT)])
    unclosed = dataclasses.replace(data.log, metadata={"outcome": record.OUTCOME_NOT_CLOSED})
    data = LogData(unclosed)
    assert data.outcome == "unknown"
    assert "not closed" in evaluate(data, ["fell"]).reasons["fell"]


def test_not_measurable_carries_its_reason() -> None:
    """NotMeasurable keeps the human reason it was raised with."""
    exc = NotMeasurable("no steps")
    assert exc.reason == "no steps" and str(exc) == "no steps"


def test_compute_is_evaluate_values(log: LogData) -> None:
    """compute() returns evaluate()'s values, NaN where not measurable."""
    names = ["fell", "fall_time", "footsteps"]
    r = evaluate(log, names)
    assert r.reasons == {"fall_time": "the robot did not fall"}
    assert compute(log, names).keys() == r.values.keys()


# ---- falls ------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def fallen(tmp_path_factory: pytest.TempPathFactory) -> LogData:
    """A log whose robot falls at t = 1.0 s; the ticks after it must never be read."""
    ticks = [
        Tick(
            k * DT,
            qpos=None,
            signals={"fsm_state": 1.0},
            events=[{"kind": "fall", "reason": "pelvis low"}] if k == 100 else [],
        )
        for k in range(201)
    ]
    return write_log(
        tmp_path_factory.mktemp("fell") / "log.mcap",
        ticks,
        outcome="fell",
        extra={"fall_time": "1.0"},
    )


def test_fall_cuts_every_series(fallen: LogData) -> None:
    """States, contacts, signals and inputs end before the fall; the fall event stays."""
    assert fallen.fall_time == pytest.approx(1.0)
    assert fallen.t.max() < 1.0 and fallen.contact_t.max() < 1.0
    assert max(m["t"] for m in fallen.signals) < 1.0
    assert len(fallen.inputs_xfrc) == 100
    assert [e["kind"] for e in fallen.events] == ["fall"]


def test_fall_metrics(fallen: LogData) -> None:
    """fell is 1 with its time; a metric about a completed walk is not measurable."""
    r = evaluate(fallen, ["fell", "fall_time", "time_after_last_step", "pelvis_drift"])
    assert r.values["fell"] == 1 and r.values["fall_time"] == pytest.approx(1.0)
    assert r.reasons["time_after_last_step"].startswith("the robot fell at t = 1.000 s, before")
    assert r.values["pelvis_drift"] == 0.0  # pre-fall: the robot stood still until then


def _fsm_log(path: Path, visits: list[float]) -> LogData:
    """A standing log whose ``fsm_state`` visits state 1 for each duration in ``visits``
    [s], with 0.1 s of state 0 between them."""
    ticks, t = [], 0.0
    for duration in visits:
        for state, span in ((0.0, 0.1), (1.0, duration)):
            end = t + span
            while t < end - 1e-9:
                ticks.append(Tick(round(t, 6), signals={"fsm_state": state}))
                t = round(t + DT, 6)
    ticks.append(Tick(round(t, 6), signals={"fsm_state": 0.0}))
    return write_log(path, ticks)


def test_state_duration_spread_tells_clock_from_event_timing(tmp_path: Path) -> None:
    """Equal visits of a state give a spread of 0 (clock-like); unequal ones give their std/mean."""
    even = _fsm_log(tmp_path / "even.mcap", [0.2, 0.2, 0.2])
    assert measured(even, "state_duration_spread:1") == pytest.approx(0.0, abs=1e-9)
    uneven = _fsm_log(tmp_path / "uneven.mcap", [0.1, 0.2, 0.3])
    assert measured(uneven, "state_duration_spread:1") == pytest.approx(
        np.std([0.1, 0.2, 0.3]) / 0.2, rel=0.05
    )
    once = _fsm_log(tmp_path / "once.mcap", [0.2])
    assert unmeasurable_reason(once, "state_duration_spread:1")


def test_step_duration_spread_needs_two_intervals(log: LogData, tmp_path: Path) -> None:
    """Two lifted steps give one interval: not measurable; a standing log has no steps at all."""
    assert unmeasurable_reason(log, "step_duration_spread")
    standing = write_log(tmp_path / "stand.mcap", [Tick(round(k * DT, 6)) for k in range(50)])
    assert unmeasurable_reason(standing, "step_duration_spread")


# ---- metric arguments ------------------------------------------------------------------------


def test_metric_arguments_checked_before_a_run() -> None:
    """Windows, numbers and choices a metric cannot read, and an argument to a metric that
    takes none, are refused with the reason; readable ones, and metrics that read any
    argument, pass."""
    for ok in (
        "mean_forward_speed",
        "mean_forward_speed:2.9-12.9",
        "footsteps:right_foot",
        "state_time:1",
        "peak_contact_force:right_foot/obstacle*",
        "tracking_delay:knee@2-10",
        "switch_torque_jump:left@SSA-DS",
    ):
        check_metric_arg(ok)
    for bad, reason in (
        ("mean_forward_speed:12.9-2.9", "t0 < t1"),
        ("mean_forward_speed:2.9", "t0-t1"),
        ("footsteps:left", "left_foot, right_foot"),
        ("state_time", "needs a number"),
        ("recovery_steps:soon", "not a number"),
        ("tracking_delay:knee@2-x", "t0-t1"),
        ("switch_torque_jump:left@DS-SSA", "SSD-SSA, SSA-DS, DS-SSD"),
        ("fell:x", "takes no argument"),
    ):
        with pytest.raises(MetricArgError, match=reason):
            check_metric_arg(bad)


def test_unreadable_argument_of_an_old_spec_is_not_measurable(tmp_path: Path) -> None:
    """A log whose spec predates the argument checks gets NaN and the reason, not a crash."""
    d = write_log(tmp_path / "a.mcap", [Tick(0.0), Tick(DT)])
    r = evaluate(d, ["mean_forward_speed:2-x"])
    assert math.isnan(r.values["mean_forward_speed:2-x"])
    assert "t0-t1" in r.reasons["mean_forward_speed:2-x"]


def _fallen_variant(path: Path, after: float) -> LogData:
    """A walking-like log that falls at t = 1.0 s, identical before the fall; after it the
    pelvis drops by ``after`` [m], both feet carry ``after`` × 1 kN more, the signals and
    the pushes change, and more events come."""
    home = _robot("dyros_red").home_qpos
    ticks = []
    for k in range(201):
        t = k * DT
        late = k > 100
        qpos = home.copy()
        qpos[0] = 0.1 * t
        if late:
            qpos[2] -= after
        pairs = standing_pairs()
        if late:
            pairs = {key: [v + after * 1e3 for v in w] for key, w in pairs.items()}
        ticks.append(
            Tick(
                t,
                qpos=qpos,
                pairs=pairs,
                signals={"fsm_state": 1.0 + (after if late else 0.0), "com": [0.0, 0.0, 0.8]},
                events=[{"kind": "fall", "reason": "pelvis low"}]
                if k == 100
                else ([{"kind": "phase", "state": 2.0}] if late and k % 10 == 0 else []),
                xfrc={"pelvis": [after * 100, 0, 0, 0, 0, 0]} if late else {},
            )
        )
    return write_log(path, ticks, outcome="fell", extra={"fall_time": "1.0"})


def test_no_metric_reads_anything_after_the_fall(tmp_path: Path) -> None:
    """Every registered metric (core and the papers') gives the same value, or the same
    reason, on two fallen logs that differ only after the fall: nothing is measured after a
    fall, whatever the metric."""
    from walkrepro.evaluation.metrics import _registry

    a = _fallen_variant(tmp_path / "a.mcap", 0.0)
    b = _fallen_variant(tmp_path / "b.mcap", 0.5)

    def outcome(d: LogData, name: str) -> str:
        try:
            r = evaluate(d, [name])
        except Exception as exc:  # noqa: BLE001 - a synthetic log lacks a paper's signals
            return f"{type(exc).__name__}: {exc}".replace(str(d.log.path), "LOG")
        return repr(r.values[name]) if name not in r.reasons else r.reasons[name]

    names = sorted(_registry())
    assert len(names) > 40
    differ = {n: (outcome(a, n), outcome(b, n)) for n in names}
    differ = {n: v for n, v in differ.items() if v[0] != v[1]}
    assert differ == {}
