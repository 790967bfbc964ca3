"""``walkrepro calibrate``: a paper's declared calibration, run and compared with the
committed one, or listed."""

from __future__ import annotations

import os
from typing import Annotated, Any

import typer
from rich.markup import escape
from rich.table import Table

from walkrepro.cli.common import friendly_errors, make_console, needs_checkout, needs_clean_tree


@friendly_errors
def calibrate(
    paper: Annotated[
        str | None, typer.Argument(help="Paper key (e.g. faraji); none lists the calibrations.")
    ] = None,
    jobs: Annotated[int, typer.Option(help="Parallel runs.")] = os.cpu_count() or 1,
    engine: Annotated[str, typer.Option(help="process or ray (as walkrepro sweep).")] = "process",
    address: Annotated[
        str | None, typer.Option(help="An existing Ray cluster (with --engine ray).")
    ] = None,
    update: Annotated[
        bool, typer.Option("--update", help="Write the results into the calibration file.")
    ] = False,
    only: Annotated[
        str | None,
        typer.Option("--only", help="Calibrate this parameter alone (the others keep theirs)."),
    ] = None,
    allow_dirty: Annotated[
        bool,
        typer.Option(
            "--allow-dirty",
            help="With --update: write results from uncommitted changes (local work; their "
            "provenance says +dirty).",
        ),
    ] = False,
) -> None:
    """Run a paper's declared calibration and compare it with the committed results.

    The calibration is experiments/calibration/<paper>.yaml; --update writes its results
    there. Exit 1 when a calibration misses its target or differs from the committed one."""
    from walkrepro.runtime.interrupt import Received, stop_signals_raise
    from walkrepro.specs.calibration_files import (
        calibration_papers,
        find_calibration,
        load_calibration,
    )
    from walkrepro.studies.calibration.rules import check_consistency
    from walkrepro.studies.calibration.run import CalibrateOptions, calibrate

    if update:
        needs_checkout("walkrepro calibrate --update")
        needs_clean_tree("walkrepro calibrate --update", allow_dirty)
    if paper is None:
        _print_calibrations([load_calibration(find_calibration(p)) for p in calibration_papers()])
        return
    loaded = load_calibration(find_calibration(paper))
    check_consistency(loaded)
    options = CalibrateOptions(jobs=jobs, engine=engine, address=address, only=only)
    console = make_console()
    console.print(
        f"calibrating {paper} ({loaded.source}): "
        f"{only or ', '.join(p.name for p in loaded.model.parameters)} "
        f"({engine} engine, {jobs} job(s))…",
        highlight=False,
    )

    def done(run: Any) -> None:
        console.print(
            f"{run.parameter.name}: {_value_text(run.result.value)} in {run.runs} run(s), "
            f"{run.wall_time:.0f} s",
            highlight=False,
        )

    received = Received()
    try:
        with stop_signals_raise(received):
            runs = calibrate(loaded, options, on_done=done)
    except KeyboardInterrupt:
        make_console(stderr=True).print(
            f"interrupted: {loaded.source} is untouched", highlight=False
        )
        raise typer.Exit(code=received.exit_code) from None
    console.print(_calibration_table(loaded, runs))
    _write_or_compare(paper, loaded, runs, update)


def _write_or_compare(paper: str, loaded: Any, runs: list, update: bool) -> None:
    """After the calibration of ``paper`` (the key as typed): with ``update``, write its
    results into the calibration file; without, compare them with the committed ones and
    exit 1 when they differ."""
    from walkrepro.specs.calibration_files import CALIBRATION_RTOL, with_results, write_calibration
    from walkrepro.studies.calibration.run import compare

    console = make_console()
    if update:
        new = with_results(loaded.model, {r.parameter.name: r.result for r in runs})
        write_calibration(loaded.path, new)
        console.print(f"wrote {loaded.source}", highlight=False)
        return
    differences = compare(loaded, runs)
    if not differences:
        console.print(
            "[green]reproduces the committed calibration[/] (every value and measurement "
            f"within {CALIBRATION_RTOL:g} relative)"
        )
        return
    for d in differences:
        console.print(f"[red]differs:[/] {d.name}: {escape(d.what)}", highlight=False)
    console.print(f"(write the new results with: walkrepro calibrate {paper} --update)")
    raise typer.Exit(code=1)


def _value_text(value: Any) -> str:
    """A calibrated value as the file holds it (``repr``: every digit), or ``—``."""
    if value is None:
        return "—"
    if isinstance(value, str):  # a chosen option
        return value
    if isinstance(value, tuple | list):
        return "(" + ", ".join(repr(float(v)) for v in value) + ")"
    return repr(float(value))


def _calibration_table(loaded: Any, runs: list) -> Table:
    """One row per parameter calibrated now: criterion, target, committed and new values."""
    table = Table(title=f"calibration of {loaded.model.paper}")
    columns = ("parameter", "criterion", "target", "committed", "reproduced", "measured")
    for col in (*columns, "runs", "time [s]"):
        table.add_column(col, overflow="fold")
    for run in runs:
        p = run.parameter
        target = (
            f"{p.target.value:g} ± {p.target.tolerance:g}"
            if p.target is not None
            else p.search.method
        )
        committed = p.result.value if p.result is not None else None
        table.add_row(
            f"{p.name} [{p.unit}]",
            escape(f"{p.experiment} · {', '.join(p.criterion_metrics)} ({p.criterion.kind})"),
            target,
            _value_text(committed),
            _value_text(run.result.value),
            _value_text(run.result.measured),
            str(run.runs),
            f"{run.wall_time:.0f}",
        )
    return table


def _print_calibrations(files: list) -> None:
    """The calibration files: one row per parameter with its criterion and committed value."""
    table = Table(title="walkrepro calibrations (walkrepro calibrate PAPER)")
    for col in ("paper", "parameter", "set", "criterion", "search", "committed value"):
        table.add_column(col, overflow="fold")
    for f in files:
        for p in f.model.parameters:
            table.add_row(
                f.model.paper,
                f"{p.name} [{p.unit}]",
                p.set,
                escape(f"{p.experiment} · {', '.join(p.criterion_metrics)}"),
                p.search.method,
                _value_text(p.result.value if p.result is not None else None),
            )
    make_console().print(table)
