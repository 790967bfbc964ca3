"""One experiment end to end: run dir → simulation → metrics → checks → figures.

Metrics, checks and figures are computed from the written log only (never from the live
simulation), exactly as ``walkrepro check --run DIR`` recomputes them later.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from walkrepro import checks, metrics, results
from walkrepro.runner import ProgressCallback, RunResult, run
from walkrepro.spec import ExperimentSpec


@dataclass(frozen=True)
class RunSummary:
    """A finished run: where it is, how the simulation ended, and the verdict."""

    run_dir: Path
    result: RunResult
    metrics: dict[str, float]
    verdict: checks.Verdict


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
        values, verdict = evaluate_log(run_dir.work / results.LOG_FILE, run_dir.work)
        if figures and result.outcome != "interrupted":
            from walkrepro.figures import plot_run

            plot_run(run_dir.work / results.LOG_FILE, run_dir.work / results.FIGURES_DIR)
    finally:
        final = run_dir.finish()
    return RunSummary(run_dir=final, result=_moved(result, final), metrics=values, verdict=verdict)


def evaluate_log(log_path: Path, run_dir: Path) -> tuple[dict[str, float], checks.Verdict]:
    """Compute metrics and the verdict from a log; write ``metrics.json`` and ``check.json``."""
    data = metrics.LogData.from_path(log_path)
    values = metrics.compute(data, metrics.default_metric_names(data.spec))
    verdict = checks.evaluate(data.spec, values, data.outcome)
    results.write_json(run_dir / results.METRICS_FILE, values)
    results.write_json(run_dir / results.CHECK_FILE, verdict.to_json())
    return values, verdict


def _moved(result: RunResult, final: Path) -> RunResult:
    """The result with its log path under the run's final directory name."""
    from dataclasses import replace

    return replace(result, log_path=final / result.log_path.name)
