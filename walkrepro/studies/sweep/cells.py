"""One sweep cell: one run of a resolved spec, reduced to its outcome and metrics.

A cell is a pure function of its resolved spec (plus the names of the metrics asked for):
the engines only decide where and when it runs. Its run directory lives under the cell's
own ``work_root``, so a relative expectation never picks up another cell's run (it falls
back to the committed reference, the same for every cell).
"""

from __future__ import annotations

import math
import os
import shutil
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

#: Cell outcomes besides a run's own (``complete``, ``fell``, ``error``, ``interrupted``).
CRASHED = "crashed"


@dataclass(frozen=True)
class CellTask:
    """What a worker needs to run one cell.

    Attributes:
        index: the cell's index in the grid.
        spec: its resolved ``ExperimentSpec``.
        work_root: output root of the cell's run (deleted afterwards unless ``keep_log``).
        keep_log: keep the run directory (log, metrics, verdict).
        metrics: extra metric names to compute from the log (besides the spec's defaults).
    """

    index: int
    spec: Any
    work_root: Path
    keep_log: bool = False
    metrics: tuple[str, ...] = ()


@dataclass(frozen=True)
class CellResult:
    """A finished (or failed) cell.

    Attributes:
        index: the cell's index in the grid.
        outcome: ``complete``, ``fell``, ``error`` (the cell raised or the simulation broke),
            ``crashed`` (its worker died) or ``interrupted``.
        message: one line: the run's message, or the error.
        fall_time: time of the fall [s], NaN if none.
        metrics: metric name → value (NaN where not measurable).
        counts: verdict rows ``(pass, known deviation, fail)``.
        wall_time: the whole cell in its worker (run, metrics, verdict, clean-up) [s].
        run_wall_time: the simulation loop alone [s].
        engine_time: submission to result as the engine saw it [s] (NaN if unknown).
        pid: the worker's process id.
    """

    index: int
    outcome: str
    message: str
    fall_time: float = math.nan
    metrics: dict[str, float] = field(default_factory=dict)
    counts: tuple[int, int, int] = (0, 0, 0)
    wall_time: float = math.nan
    run_wall_time: float = math.nan
    engine_time: float = math.nan
    pid: int = 0


def run_cell(task: CellTask) -> CellResult:
    """Run one cell; every exception becomes an ``error`` result (the sweep goes on)."""
    from walkrepro.evaluation import checks, metrics
    from walkrepro.runs.experiment import execute

    t0 = time.perf_counter()
    try:
        summary = execute(task.spec, task.work_root, outputs=False)
        values = dict(summary.metrics)
        extra = [m for m in task.metrics if m not in values]
        if extra:
            data = metrics.LogData.from_path(summary.result.log_path)
            for name in extra:
                try:
                    values.update(metrics.compute(data, [name]))
                except Exception:  # noqa: BLE001 - one unmeasurable metric is NaN, not a failed cell
                    values[name] = math.nan
        rows = summary.verdict.rows
        counts = (
            sum(r.status == checks.PASS for r in rows),
            sum(r.status == checks.KNOWN for r in rows),
            sum(r.status == checks.FAIL for r in rows),
        )
        result = summary.result
        return CellResult(
            index=task.index,
            outcome=result.outcome,
            message=result.message,
            fall_time=math.nan if result.fall_time is None else float(result.fall_time),
            metrics=values,
            counts=counts,
            wall_time=time.perf_counter() - t0,
            run_wall_time=result.wall_time,
            pid=os.getpid(),
        )
    except Exception as exc:  # noqa: BLE001 - a failing cell is recorded, the sweep goes on
        last = traceback.extract_tb(exc.__traceback__)[-1:]
        at = f" at {Path(last[0].filename).name}:{last[0].lineno}" if last else ""
        return CellResult(
            index=task.index,
            outcome="error",
            message=f"{type(exc).__name__}: {exc}{at}",
            wall_time=time.perf_counter() - t0,
            pid=os.getpid(),
        )
    finally:
        if not task.keep_log:
            shutil.rmtree(task.work_root, ignore_errors=True)
