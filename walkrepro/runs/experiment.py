"""One experiment end to end: run dir → simulation → metrics → checks → figures.

Metrics, checks and figures are computed from the written log only (never from the live
simulation), exactly as ``walkrepro check --run DIR`` recomputes them later.
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from walkrepro.errors import WalkreproError
from walkrepro.evaluation import checks, metrics
from walkrepro.locations import REFERENCES_DIR
from walkrepro.runs import provenance, results
from walkrepro.runs.resolve import Experiment
from walkrepro.runs.runner import ProgressCallback, RunResult, run
from walkrepro.runtime.interrupt import InterruptFlag
from walkrepro.specs.models import ExperimentSpec


@dataclass(frozen=True)
class RunSummary:
    """A finished run: where it is, how the simulation ended, and the verdict.

    ``relative`` says whether the verdict compares with other experiments' runs (so a
    batch re-evaluates it once every run of the batch is done). ``interrupted`` is true
    when Ctrl-C stopped the run or the work after it (metrics and verdict are then still
    written; figures are skipped); ``signum`` is the signal that stopped it. ``stages`` is
    each post-simulation stage's status as ``run.json`` records it
    (:class:`walkrepro.runs.results.Stages`).
    """

    run_dir: Path
    result: RunResult
    metrics: dict[str, float]
    verdict: checks.Verdict
    relative: bool = False
    interrupted: bool = False
    signum: int | None = None
    stages: dict[str, str] = field(default_factory=dict)

    @property
    def log_path(self) -> Path:
        """The run's MCAP log (``run_dir/log.mcap``; absent if it stopped before logging)."""
        return self.result.log_path

    @property
    def outcome(self) -> str:
        """How the simulation ended: ``complete``, ``fell``, ``interrupted`` or ``error``."""
        return self.result.outcome

    @property
    def exit_code(self) -> int:
        """The exit code of a command stopped here: ``128 + signum`` (130 for Ctrl-C, 143
        for SIGTERM); 0 when the run was not stopped."""
        from walkrepro.runtime.interrupt import exit_code

        return exit_code(self.signum) if self.interrupted else 0


class References:
    """Finds another experiment's metric for a relative expectation (its *partner*).

    Without spec overrides: that experiment's run in the current batch, else its committed
    reference ``results/<experiment>/metrics.json`` (regenerated from runs of the landed
    code). With overrides (``--set``), only a partner run with the same overrides counts:
    the run in this batch, else, when re-checking an old run, the latest run of the
    partner under ``search_root`` whose ``run.json`` records the same overrides. A
    committed reference was run without overrides and is never used then. The answer says
    which run it is, or why there is none, and the verdict table shows it.
    """

    def __init__(
        self,
        batch: Mapping[str, Path] | None = None,
        overrides: Sequence[str] = (),
        search_root: Path | None = None,
        unpaired: Mapping[str, str] | None = None,
    ) -> None:
        self._batch = dict(batch or {})
        self._overrides = list(overrides)
        self._search_root = search_root
        self._unpaired = dict(unpaired or {})
        self._logs: dict[Path, metrics.LogData] = {}

    def __call__(self, experiment: str, metric: str) -> tuple[float, str]:
        """``(value, where it came from)``; NaN and the reason when there is no partner."""
        log, origin = self._batch.get(experiment), "this batch"
        if log is None and self._search_root is not None:
            run_dir = _latest_run_with(self._search_root, experiment, self._overrides)
            if run_dir is not None:
                log, origin = run_dir / results.LOG_FILE, f"run {run_dir}"
        if log is not None:
            if log not in self._logs:
                from walkrepro.log.integrity import DamagedLogError

                try:
                    self._logs[log] = metrics.LogData.from_path(log)
                except DamagedLogError as exc:
                    return math.nan, f"{origin}, whose log is damaged: {exc}"
            found = metrics.evaluate(self._logs[log], [metric])
            if metric in found.reasons:
                return (
                    math.nan,
                    f"{origin}, where {metric} is not measurable: {found.reasons[metric]}",
                )
            return found.values[metric], origin
        if self._overrides:
            why = self._unpaired.get(experiment, "it was not run in this batch")
            return math.nan, (
                f"no run of {experiment} with the same overrides ({' '.join(self._overrides)}): "
                f"{why}"
            )
        committed = REFERENCES_DIR / experiment / results.METRICS_FILE
        if committed.is_file():
            try:
                saved = results.read_metrics(committed)
            except WalkreproError as exc:
                return math.nan, f"the committed reference is unreadable: {exc}"
            value = saved.values.get(metric)
            if value is not None:
                return float(value), f"the committed reference results/{experiment}"
            reason = saved.reasons.get(metric, "it does not hold this metric")
            return math.nan, f"the committed reference results/{experiment}: {reason}"
        return math.nan, f"no run of {experiment} and no committed reference"


def _latest_run_with(root: Path, experiment: str, overrides: Sequence[str]) -> Path | None:
    """The latest finished run of ``experiment`` under ``root`` made with ``overrides``."""
    for run_dir in reversed(results.runs(root, experiment)):
        record = run_dir / results.RUN_FILE
        if record.is_file() and json.loads(record.read_text()).get("overrides", []) == list(
            overrides
        ):
            return run_dir
    return None


@functools.cache
def partner_metric_names(experiment: str) -> tuple[str, ...]:
    """Metrics of ``experiment`` that other shipped experiments' relative expectations read,
    so that its run (and its committed reference) holds them.

    Read from the specs' YAML alone: a partner's expectations need none of its values, so a
    spec whose calibrated value has no result yet (``walkrepro calibrate`` writing the first)
    does not stop another experiment's run.
    """
    import yaml

    from walkrepro.errors import WalkreproError
    from walkrepro.specs import yamlload
    from walkrepro.specs.files import all_experiment_names, find_spec_file

    names = []
    for other in all_experiment_names():
        try:
            data, _ = yamlload.load_with_node(find_spec_file(other).read_text(encoding="utf-8"))
        except (
            OSError,
            UnicodeDecodeError,
            yaml.YAMLError,
            WalkreproError,
        ):  # a broken spec is reported when it is loaded itself
            continue
        rows = data.get("expect") if isinstance(data, dict) else None
        for e in rows if isinstance(rows, list) else []:
            relative = e.get("relative_to") if isinstance(e, dict) else None
            if isinstance(relative, dict) and relative.get("experiment") == experiment:
                names.append(relative.get("metric") or e.get("metric"))
    return tuple(dict.fromkeys(n for n in names if isinstance(n, str)))


def metric_names(spec: ExperimentSpec) -> list[str]:
    """Every metric a run of ``spec`` reports: the defaults, its expectations', and those its
    partners' relative expectations need from it."""
    names = metrics.default_metric_names(spec)
    return list(dict.fromkeys([*names, *partner_metric_names(spec.name)]))


def execute(
    spec: ExperimentSpec,
    out_root: Path = results.DEFAULT_ROOT,
    *,
    progress: ProgressCallback | None = None,
    outputs: bool | tuple[bool, bool] = True,
    overrides: Sequence[str] = (),
    interrupt: InterruptFlag | None = None,
    run_dir: results.RunDir | None = None,
    resolved: Experiment | None = None,
) -> RunSummary:
    """Run ``spec`` (already resolved) and write the complete run directory.

    Ctrl-C or SIGTERM at any moment still leaves a complete run directory: the log (closed,
    marked ``interrupted``; none if the stop came before the run started), ``run.json``,
    ``metrics.json`` (what cannot be computed is null, with its reason) and ``check.json``.
    An exception anywhere (in the run, the metrics or the figures) is recorded in
    ``run.json`` as outcome ``error`` with its message and traceback, and re-raised once the
    directory has its final name: a run directory without ``run.json`` never appears.

    Args:
        spec: the resolved spec.
        out_root: root of run directories.
        progress: called a few times per second during the run.
        outputs: what to draw after the run: the paper's figures (a bool), or (figures,
            video) to also render the run's video (when a GL backend exists).
        overrides: the ``--set`` strings the spec was resolved with; ``run.json`` records
            them so partner runs can be matched later.
        interrupt: the caller's flag, installed before the caller's own slow set-up (so a
            stop from the moment the command started counts); by default one is installed
            here.
        run_dir: a run directory the caller created (under ``out_root``); by default a new
            one.
        resolved: ``spec`` resolved once into its robot, compiled scene and typed controller
            parameters (:func:`walkrepro.runs.resolve.resolve`, :func:`walkrepro.load`); by
            default the run assembles them from ``spec``.
    """
    if interrupt is None:
        with InterruptFlag() as own:
            given = {"progress": progress, "outputs": outputs, "overrides": overrides}
            return execute(
                spec, out_root, interrupt=own, run_dir=run_dir, resolved=resolved, **given
            )
    flag = interrupt
    # The flag is installed before the run directory exists: a stop from the moment the
    # directory appears is a request, and the directory is always finished.
    run_dir = run_dir or results.new_run_dir(out_root, spec.name)
    log_path = run_dir.work / results.LOG_FILE
    job = _RunRecord(run_dir.work, {"experiment": spec.name, "overrides": list(overrides)})
    try:
        job.record.update(commit=provenance.git_commit(), versions=provenance.library_versions())
        (run_dir.work / results.SPEC_FILE).write_text(spec.to_yaml())
        result = job.result = _simulate(spec, log_path, progress, flag, resolved, job)
        figures, video = outputs if isinstance(outputs, tuple) else (outputs, False)
        job.stages = results.Stages(figures=figures, video=video)
        job.record["stages"] = job.stages.record
        job.write()
        job.begin("metrics", "computing the metrics and the verdict")
        values, verdict, measured = _evaluate_interruptible(
            spec, log_path, run_dir.work, result, References(overrides=overrides)
        )
        job.end("metrics", results.COMPLETED if measured else results.INTERRUPTED)
        _draw_outputs(job, log_path, flag, figures, video)
    except BaseException as exc:
        _record_failure(spec, run_dir.work, job.record, job.result, job.stage, exc)
        final = run_dir.finish()
        if hasattr(exc, "add_note"):  # Python >= 3.11
            exc.add_note(f"run directory: {final} (run.json records the failure)")
        raise
    return _summary(spec, run_dir.finish(), job, values, verdict, flag)


def _summary(
    spec: ExperimentSpec,
    final: Path,
    job: _RunRecord,
    values: dict,
    verdict: checks.Verdict,
    flag: InterruptFlag,
) -> RunSummary:
    """The finished run's :class:`RunSummary` (its result moved to the final directory)."""
    stopped = flag.requested or job.result.outcome == "interrupted"
    return RunSummary(
        run_dir=final,
        result=_moved(job.result, final),
        metrics=values,
        verdict=verdict,
        relative=any(e.relative_to is not None for e in spec.expect),
        interrupted=stopped,
        signum=flag.signum if stopped else None,
        stages=dict(job.stages.record),
    )


class _RunRecord:
    """``run.json`` as the run goes: the provenance ``record``, the simulation's ``result``,
    each post-simulation stage's status (``stages``) and the stage under way (``stage``, in
    words, which the record of a failure names)."""

    def __init__(self, work: Path, record: dict[str, object]) -> None:
        self.work, self.record = work, record
        self.result: RunResult | None = None
        self.stages = results.Stages(figures=False, video=False)
        self.stage = "setting up the run"

    def write(self) -> None:
        """Write ``run.json`` as it stands."""
        _write_run_record(self.work, self.record, self.result)  # type: ignore[arg-type]

    def begin(self, name: str, words: str) -> None:
        """Stage ``name`` started (recorded before it runs: true even if the process is
        killed in it)."""
        self.stage = words
        self.stages.set(name, results.STARTED)
        self.write()

    def end(self, name: str, status: str) -> None:
        """Stage ``name`` ended with ``status``."""
        self.stages.set(name, status)
        self.write()


def _simulate(
    spec: ExperimentSpec,
    log_path: Path,
    progress: ProgressCallback | None,
    flag: InterruptFlag,
    resolved: Experiment | None,
    job: _RunRecord,
) -> RunResult:
    """The simulation, or the result of a run stopped before it (while the command started,
    or by a second Ctrl-C in its set-up, before the log was opened)."""
    if flag.requested:  # stopped while the command started: no simulation at all
        return RunResult(spec.name, log_path, "interrupted", 0.0, 0.0, None, _stopped_before(flag))
    job.stage = "running the simulation"
    try:
        return run(spec, log_path, progress, flag, resolved)
    except KeyboardInterrupt:  # a second Ctrl-C in set-up, before the log was opened
        return RunResult(
            spec.name, log_path, "interrupted", 0.0, 0.0, None, "interrupted in set-up"
        )


def _draw_outputs(
    job: _RunRecord, log_path: Path, flag: InterruptFlag, figures: bool, video: bool
) -> None:
    """The figures and the video, each when wanted; skipped after a stop, and a Ctrl-C in
    one keeps the run without it (the flag then records the stop)."""
    for name, wanted, draw in (
        ("figures", figures, _draw_figures),
        ("video", video, _render_video),
    ):
        if not wanted:
            continue
        if job.result.outcome == "interrupted" or flag.requested:  # type: ignore[union-attr]
            job.end(name, results.SKIPPED)
            continue
        job.begin(name, f"{'drawing the figures' if name == 'figures' else 'rendering the video'}")
        try:
            status = draw(log_path, job.work, flag)
        except KeyboardInterrupt:  # optional outputs: the run is kept without them
            flag.requested, status = True, results.INTERRUPTED
            if flag.signum is None:
                import signal

                flag.signum = signal.SIGINT
        job.end(name, status)


def _draw_figures(log_path: Path, work: Path, flag: InterruptFlag) -> str:
    """The paper's figures into ``work/figures``; returns the stage's status."""
    from walkrepro.present.figures import plot_run

    plot_run(log_path, work / results.FIGURES_DIR)
    return results.INTERRUPTED if flag.requested else results.COMPLETED


def _render_video(log_path: Path, work: Path, flag: InterruptFlag) -> str:
    """The run's video, when a GL backend exists; a stop request ends it between frames
    (the partial file is removed). Returns the stage's status."""
    from walkrepro.present.video import render_run_video

    done = render_run_video(log_path, work, stop=lambda: flag.requested)
    return results.COMPLETED if done is not None else results.UNAVAILABLE


def _stopped_before(flag: InterruptFlag) -> str:
    """The message of a run stopped before its simulation started."""
    import signal

    name = signal.Signals(flag.signum).name if flag.signum is not None else "a signal"
    return f"interrupted ({name}) before the simulation started"


def _write_run_record(work: Path, record: dict[str, object], result: RunResult) -> None:
    """``run.json``: the run's outcome and timing, with the provenance in ``record``."""
    results.write_json(
        work / results.RUN_FILE,
        {
            "experiment": record["experiment"],
            "outcome": result.outcome,
            "message": result.message,
            "sim_time": result.sim_time,
            "wall_time": result.wall_time,
            "real_time_factor": result.real_time_factor,
            **{k: v for k, v in record.items() if k != "experiment"},
        },
    )


def _record_failure(
    spec: ExperimentSpec,
    work: Path,
    record: dict[str, object],
    result: RunResult | None,
    stage: str,
    exc: BaseException,
) -> None:
    """Write ``run.json`` for a run that raised ``exc`` while at ``stage``: outcome ``error``
    (``interrupted`` for a second Ctrl-C) with the message and traceback; and, where they
    are missing, ``metrics.json`` (every metric null, with the reason) and ``check.json``.

    Never raises: the original exception is what the caller re-raises.
    """
    import traceback

    interrupted = isinstance(exc, KeyboardInterrupt)
    what = "interrupted" if interrupted else f"{type(exc).__name__}: {exc}"
    message = f"{what} (while {stage})"
    stages = record.get("stages")
    if isinstance(stages, dict):  # the stage under way ended here; the later ones never ran
        for name, status in stages.items():
            if status == results.STARTED:
                stages[name] = results.INTERRUPTED if interrupted else results.FAILED
            elif status == results.PENDING:
                stages[name] = results.SKIPPED
    try:
        results.write_json(
            work / results.RUN_FILE,
            {
                "experiment": record["experiment"],
                "outcome": "interrupted" if interrupted else "error",
                "message": message,
                # How the simulation itself ended, when it did before the failure.
                "run_outcome": result.outcome if result is not None else None,
                "run_message": result.message if result is not None else None,
                "sim_time": result.sim_time if result is not None else None,
                "wall_time": result.wall_time if result is not None else None,
                "traceback": "".join(traceback.format_exception(exc)),
                **{k: v for k, v in record.items() if k != "experiment"},
            },
        )
        if not (work / results.CHECK_FILE).is_file():
            names = metric_names(spec)
            values = {n: math.nan for n in names}
            reasons = dict.fromkeys(names, f"the run failed: {message}")
            outcome = "interrupted" if interrupted else "error"
            verdict = checks.evaluate(spec, values, outcome, References(), reasons)
            results.write_metrics(work / results.METRICS_FILE, values, reasons)
            results.write_json(work / results.CHECK_FILE, verdict.to_json())
    except Exception:  # noqa: BLE001, S110 - best effort: run.json is written first
        pass


def _evaluate_interruptible(
    spec: ExperimentSpec,
    log_path: Path,
    run_dir: Path,
    result: RunResult,
    references: checks.ReferenceLookup,
) -> tuple[dict[str, float], checks.Verdict, bool]:
    """:func:`evaluate_log`, or, without a log or on a second Ctrl-C, every metric null
    with the reason (a verdict is written either way); the last item says whether the
    metrics were computed."""
    try:
        if log_path.is_file():
            return (*evaluate_log(log_path, run_dir, references), True)
        reason = "the run was interrupted before its log was opened"
        return (*_unmeasured(spec, run_dir, result.outcome, reason, references), True)
    except KeyboardInterrupt:
        reason = "interrupted again while the metrics were computed"
    return (*_unmeasured(spec, run_dir, result.outcome, reason, references), False)


def _unmeasured(
    spec: ExperimentSpec,
    run_dir: Path,
    outcome: str,
    reason: str,
    references: checks.ReferenceLookup,
) -> tuple[dict[str, float], checks.Verdict]:
    """Every metric null with ``reason``, and the verdict on that; both written to
    ``run_dir``."""
    names = metric_names(spec)
    values = {n: math.nan for n in names}
    reasons = dict.fromkeys(names, reason)
    verdict = checks.evaluate(spec, values, outcome, references, reasons)
    results.write_metrics(run_dir / results.METRICS_FILE, values, reasons)
    results.write_json(run_dir / results.CHECK_FILE, verdict.to_json())
    return values, verdict


def evaluate_log(
    log_path: Path,
    run_dir: Path,
    references: checks.ReferenceLookup | None = None,
    partial: bool = False,
) -> tuple[dict[str, float], checks.Verdict]:
    """Compute metrics and the verdict from a log; write ``metrics.json`` and ``check.json``.

    ``references`` finds partner runs for relative expectations; by default the committed
    references (the right partner for a run made without overrides). A run stopped before
    its log was opened has no log: its ``run.json`` and ``spec.yaml`` give the verdict
    (every metric null, with the reason). A cut or damaged log is refused
    (:class:`walkrepro.log.integrity.DamagedLogError`) unless ``partial``: its verdict's
    outcome is then ``partial`` (never a pass) and what it cannot measure says why.
    """
    if not log_path.is_file() and (run_dir / results.RUN_FILE).is_file():
        return _evaluate_unlogged(run_dir, references or References())
    data = metrics.LogData.from_path(log_path, partial)
    found = metrics.evaluate(data, metric_names(data.spec))
    verdict = checks.evaluate(
        data.spec, found.values, data.outcome, references or References(), found.reasons
    )
    results.write_metrics(run_dir / results.METRICS_FILE, found.values, found.reasons)
    results.write_json(run_dir / results.CHECK_FILE, verdict.to_json())
    return found.values, verdict


def _evaluate_unlogged(
    run_dir: Path, references: checks.ReferenceLookup
) -> tuple[dict[str, float], checks.Verdict]:
    """The verdict of a run directory without a log, from its ``run.json`` and
    ``spec.yaml``.

    Raises:
        WalkreproError: ``run.json`` or ``spec.yaml`` is missing or unreadable.
    """
    from walkrepro.specs.models import spec_from_yaml_text

    record_path, spec_path = run_dir / results.RUN_FILE, run_dir / results.SPEC_FILE
    try:
        record = json.loads(record_path.read_text())
        outcome, message = str(record["outcome"]), str(record.get("message", ""))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise WalkreproError(f"{record_path}: not a walkrepro run record ({exc}).") from None
    if not spec_path.is_file():
        raise WalkreproError(
            f"{run_dir}: this run has no {results.LOG_FILE} and no {results.SPEC_FILE} "
            f"({outcome}: {message}); there is nothing to check."
        )
    spec = spec_from_yaml_text(spec_path.read_text(), str(spec_path))
    reason = f"the run has no log ({outcome}: {message})"
    return _unmeasured(spec, run_dir, outcome, reason, references)


def _moved(result: RunResult, final: Path) -> RunResult:
    """The result with its log path under the run's final directory name."""
    from dataclasses import replace

    return replace(result, log_path=final / result.log_path.name)
