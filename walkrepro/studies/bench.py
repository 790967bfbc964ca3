"""Speed measurement: real-time factor, per-stage cost, and the MuJoCo-only floor.

The floor is MuJoCo alone replaying the run's own logged inputs (its ``ctrl`` and external
wrenches, step by step from the logged initial state, in the same process right after the
run): the same contacts and the same solver work as the run, with nothing else. The ratio
run time / floor time says how far the whole stack (sensors, controller, logging) is from
the physical limit.
"""

from __future__ import annotations

import json
import math
import os
import platform
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import mujoco

from walkrepro.errors import WalkreproError
from walkrepro.log.record import read_log
from walkrepro.runs.runner import RunResult, run
from walkrepro.sim import contact_law
from walkrepro.sim.replay import replay_inputs, set_initial_state
from walkrepro.specs.models import ExperimentSpec


@dataclass(frozen=True)
class BenchResult:
    """One experiment's speed.

    Attributes:
        experiment: spec name.
        outcome: how the run ended (a benchmark of a fallen run is flagged, not hidden).
        sim_time: simulated time [s].
        wall_time: wall time of the simulation loop, logging on [s].
        real_time_factor: sim_time / wall_time.
        floor_wall_time: MuJoCo alone replaying the run's logged inputs (``mj_step`` per
            physics step) [s].
        floor_ratio: wall_time / floor_wall_time.
        per_tick: mean wall time per control tick of each stage [s].
        tick_median: median wall time of a control period, all stages [s].
        tick_p99: 99th percentile of the same [s].
        control_rate: control ticks per simulated second [Hz].
        logging_share: fraction of the wall time spent writing the log.
        memory_growth: growth of resident memory from a tenth of the run to its end [bytes]
            (flat memory: about zero).
        log_size: size of the run's log [bytes].
        log_rate: log size per simulated second [MB/s].
    """

    experiment: str
    outcome: str
    sim_time: float
    wall_time: float
    real_time_factor: float
    floor_wall_time: float
    floor_ratio: float
    per_tick: dict[str, float]
    tick_median: float
    tick_p99: float
    control_rate: float
    logging_share: float
    memory_growth: float
    log_size: int = 0
    log_rate: float = 0.0

    def to_json(self) -> dict:
        """Plain data for ``--json``."""
        return asdict(self)


def bench_experiment(spec: ExperimentSpec, repeat: int = 1) -> BenchResult:
    """:func:`bench_experiments` for one experiment."""
    return bench_experiments([spec], repeat)[0]


def bench_experiments(
    specs: Sequence[ExperimentSpec],
    repeat: int = 1,
    on_start: Callable[[ExperimentSpec, int], None] | None = None,
) -> list[BenchResult]:
    """Run each spec with logging on (to a temporary file) and measure its floor, ``repeat``
    times each, keeping the fastest run and the fastest floor of each.

    On a shared or virtual machine the speed drifts (here by up to 40 % for a minute or
    more, for MuJoCo alone as much as for the whole stack), and the fastest run is the one
    least disturbed. The repeats go round the experiments (A, B, …, A, B, …), so one slow
    spell of the host does not meet every run of the same experiment.

    Args:
        specs: the experiments, in order.
        repeat: runs per experiment.
        on_start: called as ``on_start(spec, round)`` before each run (progress output).
    """
    best: list[RunResult | None] = [None] * len(specs)
    floors = [math.inf] * len(specs)
    sizes = [0] * len(specs)
    for round_ in range(max(repeat, 1)):
        for i, spec in enumerate(specs):
            if on_start is not None:
                on_start(spec, round_)
            with tempfile.TemporaryDirectory(prefix="walkrepro-bench-") as tmp:
                log_path = Path(tmp) / "log.mcap"
                attempt = run(spec, log_path)
                floors[i] = min(floors[i], floor_time(log_path))
                sizes[i] = log_path.stat().st_size if log_path.exists() else 0
            current = best[i]
            if current is None or attempt.wall_time < current.wall_time:
                best[i] = attempt
    return [
        _bench_result(spec, result, floor, size)
        for spec, result, floor, size in zip(specs, best, floors, sizes, strict=True)
        if result is not None
    ]


def _bench_result(
    spec: ExperimentSpec, result: RunResult, floor: float, log_size: int = 0
) -> BenchResult:
    timing = result.timing
    assert timing is not None
    n_ticks = max(timing.n_ticks, 1)
    return BenchResult(
        experiment=spec.name,
        outcome=result.outcome,
        sim_time=result.sim_time,
        wall_time=result.wall_time,
        real_time_factor=result.real_time_factor,
        floor_wall_time=floor,
        floor_ratio=result.wall_time / floor if floor > 0 else float("inf"),
        per_tick={k: v / n_ticks for k, v in timing.stages.items()},
        tick_median=timing.tick_median,
        tick_p99=timing.tick_p99,
        control_rate=1.0 / spec.sim.control_period,
        logging_share=timing.stages["logging"] / result.wall_time,
        memory_growth=timing.memory_growth,
        log_size=log_size,
        log_rate=log_size / 1e6 / result.sim_time if result.sim_time > 0 else 0.0,
    )


def floor_time(log_path: Path) -> float:
    """Wall time [s] of MuJoCo alone replaying a log's inputs (see :func:`replay_inputs`);
    reading the log is not timed. 0 for a log without inputs."""
    log = read_log(log_path)
    model = mujoco.MjModel.from_xml_string(log.scene_xml)
    data = mujoco.MjData(model)
    inputs = replay_inputs(log, model)
    set_initial_state(log, data)
    ctrl_in, xfrc_in = data.ctrl, data.xfrc_applied
    step = mujoco.mj_step
    # A scene's own ground law is physics: the floor runs it too (walkrepro/sim/contact_law.py).
    with contact_law.applied_to(model):
        start = time.perf_counter()
        for ctrl, xfrc in zip(inputs.ctrl, inputs.xfrc, strict=True):
            ctrl_in[:] = ctrl
            if xfrc is not None:
                xfrc_in[:] = xfrc
            step(model, data)
        return time.perf_counter() - start


def load_bench(path: Path) -> dict[str, dict]:
    """An earlier ``walkrepro bench --json`` file's results, by experiment name.

    Raises:
        WalkreproError: the file is missing or is not a bench result.
    """
    try:
        results = json.loads(Path(path).read_text())["results"]
        return {r["experiment"]: r for r in results}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise WalkreproError(
            f"{path}: not a `walkrepro bench --json` file ({type(exc).__name__}: {exc})."
        ) from None


def machine_info() -> dict[str, str]:
    """The machine a benchmark ran on (cores, CPU model, Python and MuJoCo versions)."""
    cpu = platform.processor() or "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "cores": str(os.cpu_count()),
        "cpu": cpu,
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
        "platform": platform.platform(),
    }
