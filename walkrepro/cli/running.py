"""``walkrepro run`` (one experiment, its verdict per claim) and ``walkrepro check``
(experiments or existing runs against the papers)."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.markup import escape

from walkrepro.cli.batch import (
    paired_partners,
    plot_comparisons,
    run_batch,
    run_one,
    update_references,
    with_reference_video,
)
from walkrepro.cli.common import (
    AllowDirtyOption,
    ForceOption,
    OutOption,
    PartialOption,
    SetOption,
    complete_experiment,
    friendly_errors,
    make_console,
    needs_checkout,
    needs_clean_tree,
    options_from,
    print_missing,
    resolved_spec,
)
from walkrepro.cli.registers import update_docs
from walkrepro.cli.verdicts import print_verdicts
from walkrepro.errors import WalkreproError
from walkrepro.runs import results

if TYPE_CHECKING:
    from walkrepro.evaluation.checks import Verdict
    from walkrepro.runs.experiment import RunSummary
    from walkrepro.studies.sweep.command import EngineChoice


@friendly_errors
def run(
    experiment: Annotated[str, typer.Argument(help="Experiment name or path to a spec YAML.")],
    set_: SetOption = None,
    out: OutOption = results.DEFAULT_ROOT,
    figures: Annotated[bool, typer.Option(help="Draw the paper's figures after the run.")] = True,
    details: Annotated[
        bool,
        typer.Option(
            "--details",
            help="Print every row in full (paper value, measured, observed band, source and "
            "note); default: one line per claim, failing rows in full.",
        ),
    ] = False,
    force: ForceOption = False,
) -> None:
    """Run one experiment headless: log, metrics, verdict and figures in a new run directory.

    Exit code: 0 when every claim holds (a known deviation inside its observed band holds),
    1 when a claim fails or is not measurable or the run ended in an error, 2 for a usage
    error (bad spec, --out refused), 130/143 after Ctrl-C/SIGTERM; as `walkrepro check`.
    """
    from walkrepro.runtime import outdir

    outdir.claim_root(out, outdir.RUNS, force or out == results.DEFAULT_ROOT, create=False)
    summary = run_one(experiment, set_ or [], out, (figures, figures), show_progress=True)
    print_verdicts([summary.verdict], details, per_claim=True)
    make_console().print(f"run directory: [bold]{summary.run_dir}[/]")
    for what, name in (("figures", results.FIGURES_DIR), ("video", "video.mp4")):
        if (summary.run_dir / name).exists():
            make_console().print(f"{what}: {summary.run_dir / name}", highlight=False)
    print_missing(summary.run_dir, summary.stages, summary.signum if summary.interrupted else None)
    if summary.interrupted:  # 130 after Ctrl-C, 143 after SIGTERM
        raise typer.Exit(code=summary.exit_code)
    if summary.result.outcome == "error":
        make_console(stderr=True).print(f"[bold red]error:[/] {escape(summary.result.message)}")
        raise typer.Exit(code=1)
    if not summary.verdict.passed:  # a CI can use the exit code, as with `check`
        raise typer.Exit(code=1)


@dataclasses.dataclass(frozen=True)
class CheckOptions:
    """``walkrepro check``: the experiments and runs to check, and how."""

    experiments: Annotated[
        list[str] | None,
        typer.Argument(help="Experiments to run and check.", autocompletion=complete_experiment),
    ] = None
    run_dir: Annotated[
        list[Path] | None, typer.Option("--run", help="Re-check an existing run directory or log.")
    ] = None
    partial: PartialOption = False
    set_: SetOption = None
    out: OutOption = results.DEFAULT_ROOT
    jobs: Annotated[int, typer.Option(help="Parallel runs (processes).")] = os.cpu_count() or 1
    engine: Annotated[
        str, typer.Option(help="Where parallel runs go: process or ray (as walkrepro sweep).")
    ] = "process"
    address: Annotated[
        str | None, typer.Option(help="An existing Ray cluster (with --engine ray).")
    ] = None
    junit: Annotated[Path | None, typer.Option(help="Also write a JUnit XML report.")] = None
    figures: Annotated[bool, typer.Option(help="Draw figures for each run.")] = False
    update_reference: Annotated[
        bool,
        typer.Option(
            "--update-reference",
            help="Copy each run's metrics, verdict and PNG figures to results/<experiment>/ "
            "(implies --figures: a reference's figures are drawn from its own run).",
        ),
    ] = False
    allow_dirty: AllowDirtyOption = False
    force: ForceOption = False
    sweeps: Annotated[
        bool,
        typer.Option(
            "--sweeps",
            help="Re-run the experiments' declared maps (default: check their claims on the "
            "committed results/maps/<map>/cells.csv).",
        ),
    ] = False
    details: Annotated[
        bool,
        typer.Option(
            "--details",
            help="Print every row (paper value, measured, observed band, source and note); "
            "default: one line per experiment, failing rows in full.",
        ),
    ] = False


@friendly_errors
@options_from(CheckOptions)
def check(options: CheckOptions) -> None:
    """Run experiments (or re-check runs) and compare them with the papers. Exit 1 on failure.

    An expectation relative to another experiment (its partner) compares with the partner's
    run in this batch, else its committed reference. With --set, the partners run in the
    same batch with the same overrides (paired runs).

    The claims of each experiment's declared maps (spec ``sweeps:``) are checked too.
    """
    from walkrepro.evaluation import checks
    from walkrepro.runs.experiment import References, evaluate_log
    from walkrepro.specs.files import experiment_names

    _refuse_bad_options(options)
    overrides = list(options.set_ or [])
    verdicts = _recheck_runs(options.run_dir or [], options.partial)
    names = list(options.experiments or [])
    if not names and not options.run_dir:
        names = experiment_names()
    figures = options.figures or options.update_reference
    summaries, unpaired = _run_with_partners(names, overrides, options, figures)
    if summaries:
        # Comparisons between experiments use this batch's runs, now that all are done.
        batch = References(
            {s.verdict.experiment: s.result.log_path for s in summaries},
            overrides,
            unpaired=unpaired,
        )
        verdicts += [
            evaluate_log(s.result.log_path, s.run_dir, batch)[1]
            if s.relative and s.result.log_path.is_file()
            else s.verdict
            for s in summaries
        ]
        if figures:
            plot_comparisons(summaries)
    if names and not overrides:  # committed maps were made without overrides
        from walkrepro.studies.sweep.command import map_verdicts

        verdicts += map_verdicts(
            names,
            options.sweeps,
            options.out,
            options.jobs,
            make_console(stderr=True),
            _engine(options),
        )
    print_verdicts(verdicts, options.details)
    interrupted = any(s.interrupted for s in summaries)
    if options.update_reference and not interrupted:
        update_references(summaries)
        update_docs()
    if options.junit is not None:
        checks.write_junit(verdicts, options.junit)
    if interrupted:  # 130 after Ctrl-C, 143 after SIGTERM
        raise typer.Exit(code=next(s.exit_code for s in summaries if s.interrupted))
    if not all(v.passed for v in verdicts):
        raise typer.Exit(code=1)


def _refuse_bad_options(options: CheckOptions) -> None:
    """Refuse, before anything runs, an unknown engine, --address without Ray, references
    written from overrides or uncommitted changes or an installed copy, and an --out that
    walkrepro may not write into."""
    from walkrepro.studies.sweep.engines import ENGINES

    if options.engine not in ENGINES:
        raise WalkreproError(
            f"unknown engine {options.engine!r}. Valid engines: {', '.join(ENGINES)}."
        )
    if options.address is not None and options.engine != "ray":
        raise WalkreproError("--address applies to --engine ray only.")
    overrides = list(options.set_ or [])
    if options.update_reference and overrides:
        raise WalkreproError(
            "--update-reference takes runs of the experiments as shipped; drop --set "
            f"({' '.join(overrides)})."
        )
    if options.update_reference:
        needs_checkout("--update-reference")
        needs_clean_tree("check --update-reference", options.allow_dirty)
    if options.experiments or not options.run_dir:  # it writes runs under --out
        from walkrepro.runtime import outdir

        default = options.out == results.DEFAULT_ROOT
        outdir.claim_root(options.out, outdir.RUNS, options.force or default, create=False)


def _engine(options: CheckOptions) -> EngineChoice:
    """Where the batch's runs go: the sweep's engine, its job count and Ray address."""
    from walkrepro.studies.sweep.command import EngineChoice

    return EngineChoice(options.engine, options.jobs, options.address)


def _recheck_runs(paths: list[Path], partial: bool) -> list[Verdict]:
    """The verdicts of existing run directories or logs (``--run``), each followed by the
    outputs it lacks."""
    from walkrepro import api

    verdicts = []
    for path in paths:
        verdicts.append(api.evaluate(path, partial=partial))
        directory, _ = results.resolve_run(path)
        print_missing(directory, results.read_record(directory).get("stages") or {})
    return verdicts


def _run_with_partners(
    names: list[str], overrides: list[str], options: CheckOptions, figures: bool
) -> tuple[list[RunSummary], dict[str, str]]:
    """Run ``names`` and the partners their relative rows need, all with ``overrides``
    (every spec validated before any runs); with the partners that could not take the
    overrides, each with why."""
    specs = {name: resolved_spec(name, overrides) for name in names}  # validate all before running
    partners, unpaired = paired_partners(specs, overrides)
    batch_names = names + partners
    # Videos only where a reference keeps one (a video per run would cost a check minutes).
    video = with_reference_video(batch_names) if options.update_reference else frozenset()
    if not batch_names:
        return [], unpaired
    return run_batch(
        batch_names, overrides, options.out, (figures, video), _engine(options)
    ), unpaired
