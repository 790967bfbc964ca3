"""``walkrepro sweep``: plan a sweep (every cell validated), run it on an engine, resume it.

Cells are appended to ``cells.csv`` as they finish. A Ctrl-C or SIGTERM stops the engine,
keeps every finished cell and reports the sweep as interrupted; ``--resume`` runs the cells
that have no row yet and those whose worker crashed, and refuses a sweep whose grid was
edited since it started.
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from walkrepro.errors import SpecError, UnknownNameError, WalkreproError
from walkrepro.runtime.interrupt import Received, stop_signals_raise
from walkrepro.specs.sweeps import SweepSpec
from walkrepro.studies.sweep import store
from walkrepro.studies.sweep.cells import CRASHED, CellTask
from walkrepro.studies.sweep.engines import Engine
from walkrepro.studies.sweep.grid import (
    Axis,
    Cell,
    parse_grid_item,
    parse_values,
    plan_cells,
    value_text,
)

#: Maps (declared sweeps) committed as references: ``results/maps/<name>/``.
MAPS_DIR_NAME = "maps"
DEFAULT_MAP_METRIC = "fall_time"


@dataclass
class SweepPlan:
    """A sweep ready to run: its directory, every cell, and the cells already done.

    Attributes:
        directory: the sweep directory.
        info: the contents of ``sweep.yaml``.
        cells: every cell of the grid.
        done: indices of cells with a row in ``cells.csv``.
        metrics: the extra metric names (``--metric``).
    """

    directory: Path
    info: dict[str, Any]
    cells: list[Cell]
    done: set[int] = field(default_factory=set)
    metrics: tuple[str, ...] = ()

    @property
    def missing(self) -> list[Cell]:
        """Cells still to run."""
        return [c for c in self.cells if c.index not in self.done]


@dataclass(frozen=True)
class SweepReport:
    """How a sweep run ended.

    Attributes:
        directory: the sweep directory.
        n_cells: cells in the grid.
        ran: cells run by this call.
        failures: cells of this call that errored or crashed.
        interrupted: stopped by Ctrl-C or SIGTERM, or cells are missing (finished cells
            are kept).
        wall_time: this call's wall time [s].
        signum: the signal that stopped it (None if none).
    """

    directory: Path
    n_cells: int
    ran: int
    failures: int
    interrupted: bool
    wall_time: float
    signum: int | None = None


def declared_sweep(spec: Any, name: str | None) -> SweepSpec:
    """The spec's declared sweep called ``name`` (or its only one)."""
    sweeps = {s.name: s for s in spec.sweeps}
    if name is None:
        if len(sweeps) == 1:
            return next(iter(sweeps.values()))
        if not sweeps:
            raise WalkreproError(
                f"experiment {spec.name!r} declares no sweeps: give the grid with "
                "--grid FIELD=VALUES (e.g. --grid controller.params.kp=300,400)."
            )
        raise WalkreproError(
            f"experiment {spec.name!r} declares several sweeps; choose one with --map NAME: "
            f"{', '.join(sorted(sweeps))}."
        )
    if name not in sweeps:
        raise UnknownNameError("sweep", name, sweeps, f"experiment {spec.name}")
    return sweeps[name]


def plan_new(
    experiment: str,
    grid: Sequence[str],
    overrides: Sequence[str],
    out: Path,
    metrics: Sequence[str] = (),
    map_name: str | None = None,
) -> SweepPlan:
    """Validate a new sweep completely, then create its directory (nothing runs here).

    Args:
        experiment: experiment name or spec path.
        grid: ``FIELD=VALUES`` items; empty for the spec's declared sweep (``map_name``).
        overrides: ``--set`` items for every cell.
        out: output root (the sweep goes to ``out/sweeps/<experiment>/``).
        metrics: extra metrics; the first one is the map's.
        map_name: a declared sweep of the spec.
    """
    from walkrepro.specs.files import find_spec_file, load_spec

    base = load_spec(experiment, overrides).spec
    declared = None
    if not grid or map_name is not None:
        declared = declared_sweep(base, map_name)
        if grid:
            raise WalkreproError("--map runs the declared grid; do not add --grid to it.")
        grid = declared.grid_items()
        overrides = [*declared.set_items(), *overrides]
    axes = [parse_grid_item(g) for g in grid]
    _check_metrics(metrics)
    cells = plan_cells(experiment, axes, overrides)
    map_metric = metrics[0] if metrics else (declared.metric if declared else None)
    map_metric = map_metric or _default_map_metric(cells[0].spec)
    success = declared.success if declared else None
    # The claims' metrics too, so that every claim can be evaluated on the cells table.
    claimed = [c.region.metric for c in declared.claims] if declared else []
    extra = [map_metric, *([success.metric] if success else []), *claimed] if declared else []
    metric_names = _metric_columns(cells, [*metrics, *extra])
    source = find_spec_file(experiment)
    directory = store.new_sweep_dir(out, cells[0].spec.name)
    shutil.copyfile(source, directory / store.BASE_FILE)
    info = {
        "experiment": cells[0].spec.name,
        "source": _relative(source),
        "map": declared.name if declared else None,
        "title": _title(cells[0].spec, declared),
        "grid": [
            {"field": a.field, "values": list(a.values), "unit": _unit(a.field, base)} for a in axes
        ],
        "set": list(overrides),
        "metrics": list(metrics),
        "map_metric": map_metric,
        **({"success": success.model_dump(mode="json")} if success else {}),
        "claims": [c.model_dump(mode="json") for c in declared.claims] if declared else [],
        "columns": store.columns([a.field for a in axes], metric_names),
        "n_cells": len(cells),
        "provenance": _provenance(),
    }
    store.write_info(directory, info)
    store.write_planned(directory, info)
    store.CellsWriter(directory / store.CELLS_FILE, info["columns"]).close()
    computed = [*metrics, map_metric, *([success.metric] if success else []), *claimed]
    return SweepPlan(directory, info, cells, set(), tuple(dict.fromkeys(computed)))


def plan_resume(directory: Path) -> SweepPlan:
    """Re-plan a sweep from its directory; ``done`` holds the cells already in cells.csv.

    The rows of crashed cells (their worker died: not a result of the cell) are removed, so
    those cells run again.

    Raises:
        WalkreproError: not a sweep directory, its ``sweep.yaml`` grid, ``--set`` or
            ``base.yaml`` changed since it started, or cells.csv does not match the grid.
    """
    info = store.read_info(directory)
    store.check_planned(directory, info)
    axes = [Axis(g["field"], parse_values(g["values"], str(directory))) for g in info["grid"]]
    cells = plan_cells(directory / store.BASE_FILE, axes, info["set"])
    table = store.read_cells(directory / store.CELLS_FILE, repair=True)
    if any(row["outcome"] == CRASHED for row in table.rows):
        store.drop_rows(directory / store.CELLS_FILE, CRASHED)
        table = store.read_cells(directory / store.CELLS_FILE)
    by_index = {c.index: c for c in cells}
    for row in table.rows:
        cell = by_index.get(row["cell"])
        if cell is None or any(value_text(row[f]) != value_text(v) for f, v in cell.values):
            raise WalkreproError(
                f"{directory / store.CELLS_FILE}: row of cell {row['cell']} does not match the "
                f"grid in {store.SWEEP_FILE}; this sweep cannot be resumed."
            )
    success = [info["success"]["metric"]] if info.get("success") else []
    claimed = [c["region"]["metric"] for c in info.get("claims", [])]
    metrics = tuple(dict.fromkeys([*info["metrics"], info["map_metric"], *success, *claimed]))
    return SweepPlan(directory, info, cells, {r["cell"] for r in table.rows}, metrics)


def run_plan(
    plan: SweepPlan, engine: Engine, keep_logs: bool = False, console: Any = None
) -> SweepReport:
    """Run the plan's missing cells on ``engine`` with a progress bar; Ctrl-C or SIGTERM
    keeps the finished cells and returns an interrupted report."""
    by_index = {c.index: c for c in plan.cells}
    tasks = _cell_tasks(plan, keep_logs)
    writer = store.CellsWriter(plan.directory / store.CELLS_FILE, plan.info["columns"])
    failures = ran = 0
    interrupted = False
    received = Received()
    t0 = time.perf_counter()
    start = getattr(engine, "start", None)
    if start is not None:
        start(len(tasks))  # workers first, then the progress bar's thread
    results = engine.run(tasks)
    progress = _progress_bar(plan, console)
    try:
        with stop_signals_raise(received), progress:
            bar = progress.add_task(
                "cells", total=len(plan.cells), completed=len(plan.done), failures=0
            )
            for result in results:
                if result.outcome == "interrupted":
                    continue  # not a finished cell: --resume runs it again
                writer.append(by_index[result.index], result)
                plan.done.add(result.index)
                ran += 1
                if result.outcome in ("error", "crashed"):
                    failures += 1
                    if console is not None:
                        progress.console.print(
                            f"[red]cell {result.index} ({by_index[result.index].label}) "
                            f"{result.outcome}:[/] {result.message}",
                            highlight=False,
                        )
                progress.update(bar, advance=1, failures=failures)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        close = getattr(results, "close", None)
        if close is not None:
            close()  # stops the engine's workers
        writer.close()
        shutil.rmtree(plan.directory / ".cells", ignore_errors=True)
    return SweepReport(
        plan.directory,
        len(plan.cells),
        ran,
        failures,
        interrupted or len(plan.done) < len(plan.cells),
        time.perf_counter() - t0,
        received.signum,
    )


def _cell_tasks(plan: SweepPlan, keep_logs: bool) -> list[CellTask]:
    """The plan's missing cells as tasks for an engine, each with its own work directory
    (under the sweep's cells when their logs are kept, else a scratch one)."""
    return [
        CellTask(
            index=c.index,
            spec=c.spec,
            work_root=plan.directory
            / (store.CELLS_DIR if keep_logs else ".cells")
            / f"{c.index:04d}",
            keep_log=keep_logs,
            metrics=plan.metrics,
        )
        for c in plan.missing
    ]


def _progress_bar(plan: SweepPlan, console: Any) -> Any:
    """The sweep's progress bar: cells done of all, failures, elapsed time and ETA."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(
        TextColumn(f"[bold]sweep {plan.info['experiment']}[/]"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("cells · failures {task.fields[failures]}"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=console,
        transient=False,
    )


def update_reference(directory: Path, name: str) -> Path:
    """Copy a finished declared sweep (sweep.yaml, cells.csv in cell order, map.png) to
    results/maps/<name>/."""
    from walkrepro.locations import RESULTS_DIR

    target = RESULTS_DIR / MAPS_DIR_NAME / name
    target.mkdir(parents=True, exist_ok=True)
    for old in target.glob("map*.png"):
        old.unlink()
    for f in [store.SWEEP_FILE, *(p.name for p in directory.glob("map*.png"))]:
        shutil.copyfile(directory / f, target / f)
    store.copy_cells_sorted(directory / store.CELLS_FILE, target / store.CELLS_FILE)
    return target


def _check_metrics(names: Sequence[str]) -> None:
    from walkrepro.evaluation.metrics import (
        MetricArgError,
        check_metric_arg,
        metric_names,
        split_metric,
    )

    valid = metric_names()
    for name in names:
        base, _ = split_metric(name)
        if base not in valid:
            raise UnknownNameError("metric", base, valid, f"--metric {name}")
        try:
            check_metric_arg(name)
        except MetricArgError as exc:
            raise SpecError(f"--metric {name}: {exc}") from None


def _metric_columns(cells: Sequence[Cell], extra: Sequence[str]) -> list[str]:
    from walkrepro.evaluation.metrics import default_metric_names

    names: list[str] = []
    for c in cells:
        names += default_metric_names(c.spec)
    return list(dict.fromkeys([*names, *extra]))


def _default_map_metric(spec: Any) -> str:
    """The map colours the first expectation that is not about falling, else the fall time."""
    for e in spec.expect:
        if e.metric not in ("fell", "fall_time", "sim_time"):
            return e.metric
    return DEFAULT_MAP_METRIC


def _title(spec: Any, declared: SweepSpec | None) -> str:
    ref = spec.paper
    where = ", ".join(
        x for x in (ref.section and f"§{ref.section}", ref.figure and f"Fig. {ref.figure}") if x
    )
    if declared is not None and declared.claims:
        claim = declared.claims[0].source
    elif spec.expect:
        claim = spec.expect[0].source
    else:
        claim = spec.description.strip().split(". ")[0]
    return f"{spec.name} ({ref.key}{', ' + where if where else ''}): {claim}"


def _unit(field_name: str, spec: Any) -> str:
    from walkrepro.studies.sweep.grid import unit_of

    return unit_of(field_name, spec.sweep_parameters)


def _relative(path: Path) -> str:
    """A spec path relative to the project root when inside it (committed maps stay portable)."""
    from walkrepro.locations import PROJECT_ROOT

    try:
        return str(path.resolve().relative_to(PROJECT_ROOT.resolve()))
    except ValueError:
        return str(path)


def _provenance() -> dict[str, Any]:
    from walkrepro._version import __version__
    from walkrepro.runs import provenance

    return {
        "created": provenance.utc_now().isoformat(),
        "walkrepro": __version__,
        "commit": provenance.git_commit(),
        "versions": provenance.library_versions(),
    }
