"""One experiment end to end: run dir → simulation → metrics → checks → figures.

Metrics, checks and figures are computed from the written log only (never from the live
simulation), exactly as ``walkrepro check --run DIR`` recomputes them later.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from walkrepro import RESULTS_DIR, checks, metrics, results
from walkrepro.runner import ProgressCallback, RunResult, run
from walkrepro.spec import ExperimentSpec


@dataclass(frozen=True)
class RunSummary:
    """A finished run: where it is, how the simulation ended, and the verdict.

    ``relative`` says whether the verdict compares with other experiments' runs (so a
    batch re-evaluates it once every run of the batch is done).
    """

    run_dir: Path
    result: RunResult
    metrics: dict[str, float]
    verdict: checks.Verdict
    relative: bool = False


class References:
    """Finds another experiment's metric for a relative expectation.

    In order: the run of that experiment in the current batch, else its latest run under
    the output root, else the committed reference ``results/<experiment>/metrics.json``.
    The answer says which, and the verdict table shows it.
    """

    def __init__(self, out_root: Path, batch: Mapping[str, Path] | None = None) -> None:
        self._out_root = out_root
        self._batch = dict(batch or {})
        self._logs: dict[Path, metrics.LogData] = {}

    def __call__(self, experiment: str, metric: str) -> tuple[float, str]:
        """``(value, where it came from)``; NaN when no run of ``experiment`` is found."""
        log = self._batch.get(experiment)
        origin = "this batch"
        if log is None:
            latest = results.latest_run(self._out_root, experiment)
            if latest is not None and (latest / results.LOG_FILE).is_file():
                log, origin = latest / results.LOG_FILE, f"run {latest.name}"
        if log is not None:
            if log not in self._logs:
                self._logs[log] = metrics.LogData.from_path(log)
            return metrics.compute(self._logs[log], [metric])[metric], origin
        committed = RESULTS_DIR / experiment / results.METRICS_FILE
        if committed.is_file():
            value = json.loads(committed.read_text()).get(metric)
            if value is not None:
                return float(value), "the committed reference run"
        return math.nan, f"no run of {experiment}"


def execute(
    spec: ExperimentSpec,
    out_root: Path = results.DEFAULT_ROOT,
    progress: ProgressCallback | None = None,
    figures: bool = True,
) -> RunSummary:
    """Run ``spec`` (already resolved) and write the complete run directory."""
    run_dir = results.new_run_dir(out_root, spec.name)
    try:
        (run_dir.work / results.SPEC_FILE).write_text(spec.to_yaml())
        result = run(spec, run_dir.work / results.LOG_FILE, progress)
        results.write_json(
            run_dir.work / results.RUN_FILE,
            {
                "experiment": spec.name,
                "outcome": result.outcome,
                "message": result.message,
                "sim_time": result.sim_time,
                "wall_time": result.wall_time,
                "real_time_factor": result.real_time_factor,
            },
        )
        values, verdict = evaluate_log(
            run_dir.work / results.LOG_FILE, run_dir.work, References(out_root)
        )
        if figures and result.outcome != "interrupted":
            from walkrepro.figures import plot_run

            plot_run(run_dir.work / results.LOG_FILE, run_dir.work / results.FIGURES_DIR)
    finally:
        final = run_dir.finish()
    relative = any(e.relative_to is not None for e in spec.expect)
    return RunSummary(
        run_dir=final,
        result=_moved(result, final),
        metrics=values,
        verdict=verdict,
        relative=relative,
    )


def evaluate_log(
    log_path: Path, run_dir: Path, references: checks.ReferenceLookup = checks.no_references
) -> tuple[dict[str, float], checks.Verdict]:
    """Compute metrics and the verdict from a log; write ``metrics.json`` and ``check.json``."""
    data = metrics.LogData.from_path(log_path)
    values = metrics.compute(data, metrics.default_metric_names(data.spec))
    verdict = checks.evaluate(data.spec, values, data.outcome, references)
    results.write_json(run_dir / results.METRICS_FILE, values)
    results.write_json(run_dir / results.CHECK_FILE, verdict.to_json())
    return values, verdict


def _moved(result: RunResult, final: Path) -> RunResult:
    """The result with its log path under the run's final directory name."""
    from dataclasses import replace

    return replace(result, log_path=final / result.log_path.name)
