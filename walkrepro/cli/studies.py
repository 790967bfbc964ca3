"""The commands that run many experiments: ``sweep`` (a grid of cells and its maps) and
``bench`` (speed against MuJoCo's floor)."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.table import Table

from walkrepro.cli.common import (
    AllowDirtyOption,
    ForceOption,
    OutOption,
    SetOption,
    friendly_errors,
    make_console,
    needs_checkout,
    needs_clean_tree,
    options_from,
    resolved_spec,
)
from walkrepro.runs import results

if TYPE_CHECKING:
    from walkrepro.specs.models import ExperimentSpec
    from walkrepro.studies.bench import BenchResult


@dataclasses.dataclass(frozen=True)
class SweepOptions:
    """``walkrepro sweep``: the sweep to run or resume, and where its cells run."""

    experiment: Annotated[
        str | None, typer.Argument(help="Experiment name or spec path (not with --resume).")
    ] = None
    grid: Annotated[
        list[str] | None,
        typer.Option(
            "--grid",
            help="FIELD=VALUES: a spec path or sweep parameter, and a comma list (20,40,60) "
            "or a range start:stop:count. Repeat for more axes (Cartesian product).",
        ),
    ] = None
    jobs: Annotated[int, typer.Option(help="Parallel cells.")] = os.cpu_count() or 1
    engine: Annotated[str, typer.Option(help="process or ray.")] = "process"
    address: Annotated[
        str | None, typer.Option(help="An existing Ray cluster (with --engine ray).")
    ] = None
    out: OutOption = results.DEFAULT_ROOT
    resume: Annotated[
        Path | None, typer.Option(help="Run only the missing cells of this sweep directory.")
    ] = None
    keep_logs: Annotated[bool, typer.Option(help="Keep every cell's run directory.")] = False
    metric: Annotated[
        list[str] | None,
        typer.Option("--metric", help="Also record this metric; the first one is mapped."),
    ] = None
    set_: SetOption = None
    map_name: Annotated[
        str | None, typer.Option("--map", help="Run the spec's declared sweep of this name.")
    ] = None
    update_reference: Annotated[
        bool,
        typer.Option("--update-reference", help="Copy the finished map to results/maps/<map>/."),
    ] = False
    allow_dirty: AllowDirtyOption = False
    force: ForceOption = False


@friendly_errors
@options_from(SweepOptions)
def sweep(options: SweepOptions) -> None:
    """Sweep spec fields over a grid: one run per cell, a cells.csv table and maps.

    Every cell is validated before any runs. Without --grid, runs the spec's declared map.
    """
    from walkrepro.studies.sweep.command import EngineChoice, SweepRequest, sweep_command

    if options.update_reference:
        needs_checkout("--update-reference")
        needs_clean_tree("sweep --update-reference", options.allow_dirty)
    request = SweepRequest(
        experiment=options.experiment,
        out=options.out,
        grid=options.grid or [],
        overrides=options.set_ or [],
        metrics=options.metric or [],
        map_name=options.map_name,
        resume=options.resume,
        keep_logs=options.keep_logs,
        update_reference=options.update_reference,
        force=options.force or options.out == results.DEFAULT_ROOT,
    )
    engine = EngineChoice(options.engine, options.jobs, options.address)
    code = sweep_command(make_console(stderr=True), request, engine)
    if code:
        raise typer.Exit(code=code)


@friendly_errors
def bench(
    experiments: Annotated[
        list[str] | None, typer.Argument(help="Experiments (default: all).")
    ] = None,
    set_: SetOption = None,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Also write results as JSON.")
    ] = None,
    repeat: Annotated[
        int,
        typer.Option(
            min=1,
            help="Runs per experiment, taken round the experiments; the fastest counts "
            "(the machine's speed drifts).",
        ),
    ] = 1,
    compare: Annotated[
        Path | None,
        typer.Option(
            "--compare",
            help="An earlier `bench --json` file: show its real-time factors next to these "
            "and keep its results under `before` in --json.",
        ),
    ] = None,
) -> None:
    """Measure speed: real-time factor, per-stage cost per tick, and the MuJoCo-only floor.

    Runs one experiment at a time (one core), logging on, so the numbers are comparable. The
    floor is MuJoCo alone replaying the run's logged inputs; "× floor" is run / floor.
    """
    import json

    from walkrepro.specs.files import experiment_names
    from walkrepro.studies.bench import bench_experiments, load_bench, machine_info

    names = list(experiments or experiment_names())
    specs = [resolved_spec(n, set_ or []) for n in names]
    before = load_bench(compare) if compare is not None else None

    def announce(spec: ExperimentSpec, round_: int) -> None:
        of = f", run {round_ + 1} of {repeat}" if repeat > 1 else ""
        make_console(stderr=True).print(
            f"benchmarking {spec.name} ({spec.sim.duration:g} s simulated{of})…"
        )

    rows = bench_experiments(specs, repeat, on_start=announce)
    make_console().print(bench_table(rows, before))
    if json_out is not None:
        payload: dict = {"machine": machine_info(), "results": [r.to_json() for r in rows]}
        if compare is not None:
            payload["before"] = json.loads(compare.read_text())
            payload["before"].pop("before", None)  # one level of history is enough
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(json.dumps(payload, indent=2) + "\n")
        make_console().print(f"wrote {json_out}")


#: The runner's stages, each a column of ``walkrepro bench``; a controller's own split
#: (``controller.<part>``, which differs per controller) is one column of "part cost" pairs.
STAGES = ("physics", "sensors", "controller", "logging", "bookkeeping")


def bench_table(rows: list[BenchResult], before: dict[str, dict] | None) -> Table:
    """``walkrepro bench``'s table: per experiment, the real-time factor (and ``before``'s,
    from ``--compare``), the ratio to the floor, the tick's median and p99, logging's share,
    and each stage's cost per tick [µs]."""
    table = Table(title="walkrepro bench (per-tick costs in µs)")
    columns = ["experiment", "outcome", "RTF", *(["RTF before"] if before else [])]
    columns += ["× floor", "tick median", "tick p99", "log %", "log MB/s", "mem Δ MB", *STAGES]
    columns += ["controller split"]
    for col in columns:
        table.add_column(col, justify="right" if col != "experiment" else "left")
    for r in rows:
        earlier = (before or {}).get(r.experiment)
        table.add_row(
            r.experiment,
            r.outcome,
            f"{r.real_time_factor:.2f}",
            *([f"{earlier['real_time_factor']:.2f}" if earlier else "–"] if before else []),
            f"{r.floor_ratio:.1f}",
            f"{r.tick_median * 1e6:.0f}",
            f"{r.tick_p99 * 1e6:.0f}",
            f"{r.logging_share * 100:.0f}",
            f"{r.log_rate:.2f}",
            f"{r.memory_growth / 1e6:.1f}",
            *(f"{r.per_tick.get(k, 0.0) * 1e6:.1f}" for k in STAGES),
            " ".join(
                f"{k.removeprefix('controller.')} {v * 1e6:.0f}"
                for k, v in r.per_tick.items()
                if k.startswith("controller.")
            ),
        )
    return table
