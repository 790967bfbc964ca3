"""Running experiments for ``run`` and ``check``: one in this process with a progress bar,
or a batch on the sweep's engines; the partners of paired runs; the references written after."""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from walkrepro.cli.common import make_console, print_missing, resolved_spec
from walkrepro.errors import WalkreproError
from walkrepro.locations import REFERENCES_DIR
from walkrepro.runs import results

if TYPE_CHECKING:
    from walkrepro.runs.experiment import RunSummary
    from walkrepro.runs.resolve import Experiment
    from walkrepro.specs.models import ExperimentSpec
    from walkrepro.studies.sweep.command import EngineChoice


def paired_partners(
    specs: dict[str, ExperimentSpec], overrides: list[str]
) -> tuple[list[str], dict[str, str]]:
    """With overrides, the partner experiments to run alongside (same overrides), and for
    each partner that cannot take them, why. Without overrides, none: partners come from
    the batch or the committed references."""
    if not overrides:
        return [], {}
    wanted = [
        e.relative_to.experiment
        for spec in specs.values()
        for e in spec.expect
        if e.relative_to is not None and e.relative_to.experiment not in specs
    ]
    partners, unpaired = [], {}
    for name in dict.fromkeys(wanted):
        try:
            resolved_spec(name, overrides)
            partners.append(name)
        except WalkreproError as exc:
            unpaired[name] = f"the overrides do not apply to it ({exc})"
    return partners, unpaired


def run_batch(
    names: list[str],
    overrides: list[str],
    out: Path,
    outputs: tuple[bool, frozenset[str]],
    engine: EngineChoice,
) -> list[RunSummary]:
    """Run ``names`` on ``engine`` (``jobs`` processes, or Ray), printing a line as each
    finishes.

    ``outputs`` is (figures, the experiments whose runs render a video).

    Ctrl-C stops the runs under way (each keeps a complete, interrupted run directory) and
    starts no more.
    """
    from walkrepro.evaluation.checks import count
    from walkrepro.runtime.interrupt import InterruptFlag
    from walkrepro.studies.sweep.engines import make_engine

    workers = max(1, min(engine.jobs, len(names)))
    where = f"{workers} process(es)" if engine.name == "process" else f"Ray ({workers} CPUs)"
    make_console().print(f"running {len(names)} experiment(s) with {where}…")
    done: list = []

    def report(summary: Any) -> None:
        done.append(summary)
        wall = summary.result.wall_time
        # A verdict with partner rows is final only once the whole batch has run.
        verdict = (
            "verdict when its partners are done" if summary.relative else count([summary.verdict])
        )
        make_console().print(
            f"[{len(done)}/{len(names)}] {summary.verdict.experiment}: {summary.result.message} "
            f"in {wall:.0f} s ({verdict}) → {summary.run_dir}",
            highlight=False,
        )
        signum = summary.signum if summary.interrupted else None
        print_missing(summary.run_dir, summary.stages, signum)

    if workers == 1 and engine.name == "process":
        for name in names:
            summary = run_one(name, overrides, out, outputs_of(name, outputs), False)
            report(summary)
            if summary.interrupted:
                break
        return done
    # The sweep's engines: workers reused across runs, a dead worker named, and a stop
    # (Ctrl-C or SIGTERM here) passed on to the runs under way, whose results still come
    # (with Ray: cancelled, their run directories kept but not reported).
    tasks = [
        BatchTask(i, n, tuple(overrides), out, outputs_of(n, outputs)) for i, n in enumerate(names)
    ]
    runner = make_engine(engine.name, workers, engine.address, run_task, BatchResult.crashed)
    start = getattr(runner, "start", None)
    if start is not None:
        start(len(tasks))
    with InterruptFlag() as flag:
        for result in runner.run(tasks, stop=lambda: flag.signum if flag.requested else None):
            if result.error is not None:
                raise result.error
            if result.summary is None:  # its worker died
                raise WalkreproError(f"{names[result.index]}: {result.message}.")
            report(result.summary)
    return done


@dataclasses.dataclass(frozen=True)
class BatchTask:
    """One experiment of a ``check --jobs`` batch, as a pool worker runs it."""

    index: int
    name: str
    overrides: tuple[str, ...]
    out: Path
    outputs: tuple[bool, bool]


@dataclasses.dataclass(frozen=True)
class BatchResult:
    """What a pool worker returns for a :class:`BatchTask`: the run's summary, or the
    exception the run raised (re-raised here, as a run in this process would), or, when the
    worker died, neither and a message."""

    index: int
    summary: Any = None
    error: BaseException | None = None
    message: str = ""
    engine_time: float = float("nan")

    @staticmethod
    def crashed(index: int, message: str, engine_time: float) -> BatchResult:
        """The result of a task whose worker died."""
        return BatchResult(index, message=message, engine_time=engine_time)


def run_task(task: BatchTask) -> BatchResult:
    """Run one experiment of a batch in a pool worker (module-level: the pool pickles it)."""
    try:
        summary = run_one(task.name, list(task.overrides), task.out, task.outputs, False)
    except Exception as exc:  # noqa: BLE001 - handed to the parent, which raises it
        if hasattr(exc, "add_note"):  # Python >= 3.11: the worker's traceback comes along
            import traceback

            exc.add_note("in the worker:\n" + "".join(traceback.format_tb(exc.__traceback__)))
        return BatchResult(task.index, error=exc)
    return BatchResult(task.index, summary)


def update_references(summaries: list) -> None:
    """Snapshot strips (when a GL backend exists) and the committed references."""
    import shutil

    from walkrepro.present.render import render_strip
    from walkrepro.present.video import VIDEO_FILE
    from walkrepro.runtime.gl import RenderingUnavailable

    for s in summaries:
        # A snapshot strip over the run, like the papers' photo sequences.
        times = [s.result.sim_time * k / 4 for k in range(5)]
        try:
            render_strip(
                s.result.log_path,
                times,
                s.run_dir / results.FIGURES_DIR / "snapshots.png",
                480,
                640,
            )
        except RenderingUnavailable as exc:
            make_console(stderr=True).print(f"[yellow]no snapshot strip:[/] {exc}", highlight=False)
        target = results.save_reference(s.run_dir)
        # A reference keeps a video where it has one (the headline experiments: a size budget).
        video = s.run_dir / VIDEO_FILE
        if video.is_file() and (target / VIDEO_FILE).is_file():
            shutil.copy2(video, target / VIDEO_FILE)
        make_console().print(f"reference updated: {target}")


def resolved_experiment(name: str, overrides: list[str]) -> Experiment:
    """``name`` loaded and resolved once: its spec, robot, compiled scene and parameters."""
    from walkrepro.runs.resolve import resolve
    from walkrepro.specs.files import load_spec

    return resolve(load_spec(name, overrides), overrides)


def with_reference_video(names: list[str]) -> frozenset[str]:
    """The experiments among ``names`` whose committed reference keeps a video."""
    from walkrepro.present.video import VIDEO_FILE

    return frozenset(n for n in names if (REFERENCES_DIR / n / VIDEO_FILE).is_file())


def outputs_of(name: str, outputs: tuple[bool, frozenset[str]]) -> tuple[bool, bool]:
    """(figures, video) for one experiment of a batch."""
    figures, video = outputs
    return figures, name in video


def run_one(
    name: str, overrides: list[str], out: Path, outputs: tuple[bool, bool], show_progress: bool
) -> RunSummary:
    """Resolve and execute one experiment (module-level so a process pool can pickle it).

    ``outputs`` is (figures, video): draw the paper's figures, render the run's video.

    The stop signals (Ctrl-C, SIGTERM) are taken as requests from here on, and the run
    directory is created as soon as the spec is valid, before the slow imports and set-up:
    a stop at any moment after that leaves a run directory with outcome ``interrupted``.
    """
    from walkrepro.runtime import outdir
    from walkrepro.runtime.interrupt import InterruptFlag

    with InterruptFlag() as flag, compile_watch(name, overrides, show_progress) as watch:
        experiment = resolved_experiment(name, overrides)
        spec = experiment.spec
        outdir.claim_root(out, outdir.RUNS, force=True)  # the command checked it
        run_dir = results.new_run_dir(out, spec.name)
        try:
            from walkrepro.runs.experiment import execute
        except BaseException as exc:  # a second Ctrl-C during the import
            outcome = "interrupted" if isinstance(exc, KeyboardInterrupt) else "error"
            message = f"{outcome} before the run started"
            results.abandon(run_dir, spec.to_yaml(), spec.name, outcome, message)
            raise
        if not show_progress:
            return execute(
                spec,
                out,
                outputs=outputs,
                overrides=overrides,
                interrupt=flag,
                run_dir=run_dir,
                resolved=experiment,
            )
        with Progress(
            TextColumn(f"[bold]{spec.name}[/]"),
            BarColumn(),
            TextColumn("{task.fields[sim]}"),
            TextColumn("RTF {task.fields[rtf]}"),
            TimeElapsedColumn(),
            console=make_console(stderr=True),
            transient=False,
        ) as bar:
            task = bar.add_task("run", total=spec.sim.duration, sim="", rtf="")
            if watch is not None:  # numba's compiling shows in the bar until the first tick
                watch.hand_over(lambda text: bar.update(task, sim=text))

            def progress(t: float, duration: float, rtf: float) -> None:
                if watch is not None and (compiled := watch.finish()) is not None:
                    bar.console.print(compiled, highlight=False)
                bar.update(task, completed=t, sim=f"{t:6.2f}/{duration:.2f} s", rtf=f"{rtf:5.2f}x")

            return execute(
                spec,
                out,
                progress=progress,
                outputs=outputs,
                overrides=overrides,
                interrupt=flag,
                run_dir=run_dir,
                resolved=experiment,
            )


@contextlib.contextmanager
def compile_watch(name: str, overrides: list[str], show: bool) -> Iterator[Any]:
    """With ``show``: says that numba compiles the controller, before the imports that
    compile it, when its cache is cold, and shows the compile's progress
    (:mod:`walkrepro.runtime.compilenote`); yields the watch, or None without ``show`` or
    for a spec that does not load (its error comes from the run's own loading)."""
    if not show:
        yield None
        return
    from walkrepro import plugins
    from walkrepro.runtime import compilenote
    from walkrepro.specs.files import load_spec

    try:
        spec = load_spec(name, overrides).spec
    except WalkreproError:
        yield None
        return
    paper = plugins.papers().get(spec.paper.key)
    label = paper.label.split(" — ")[0] if paper is not None else None  # "Paper I"
    label = label if label and label.startswith("Paper ") else None
    controller = spec.controller.type
    message = compilenote.note(controller, label)
    target = plugins.controllers().get(controller)
    cold = target is not None and compilenote.is_cold(target)
    with compilenote.CompileWatch(
        make_console(stderr=True), message if cold else None, message
    ) as w:
        yield w


def plot_comparisons(summaries: list[RunSummary]) -> None:
    """Comparison figures for each relative expectation whose two runs are in this batch."""
    from walkrepro.present.figures import plot_compare
    from walkrepro.specs.models import spec_from_yaml_text

    logs = {s.verdict.experiment: s.result.log_path for s in summaries}
    for s in summaries:
        if not s.relative:
            continue
        spec = spec_from_yaml_text((s.run_dir / results.SPEC_FILE).read_text())
        others = {e.relative_to.experiment for e in spec.expect if e.relative_to is not None}
        for other in sorted(others & logs.keys()):
            plot_compare(s.result.log_path, logs[other], s.run_dir / results.FIGURES_DIR)
