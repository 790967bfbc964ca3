"""The ``walkrepro sweep`` command and the map checks of ``walkrepro check`` (the CLI calls
these; they print and return, the CLI exits)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from walkrepro.errors import WalkreproError
from walkrepro.runtime.interrupt import exit_code
from walkrepro.studies.sweep import store
from walkrepro.studies.sweep.cells import CRASHED
from walkrepro.studies.sweep.engines import make_engine
from walkrepro.studies.sweep.sweeper import (
    MAPS_DIR_NAME,
    SweepPlan,
    plan_new,
    plan_resume,
    run_plan,
    update_reference,
)

#: Exit code of a sweep with crashed cells (workers that died): ``--resume`` retries them.
CRASHED_EXIT = 1


@dataclass(frozen=True)
class SweepRequest:
    """What ``walkrepro sweep`` was asked to do: a new sweep, or the rest of an earlier one.

    Attributes:
        experiment: experiment name or spec path (None with ``resume``).
        grid: ``FIELD=VALUES`` axes (empty: the spec's declared map ``map_name``).
        overrides: ``--set`` items applied to every cell; metrics: extra metrics to record.
        map_name: the spec's declared sweep to run.
        out: root directory of new sweeps; resume: an earlier sweep's directory.
        keep_logs: keep every cell's run directory.
        update_reference: copy the finished map to ``results/maps/<map>/``.
        force: write under ``out`` even if it holds files walkrepro did not write.
    """

    experiment: str | None
    out: Path
    grid: Sequence[str] = ()
    overrides: Sequence[str] = ()
    metrics: Sequence[str] = ()
    map_name: str | None = None
    resume: Path | None = None
    keep_logs: bool = False
    update_reference: bool = False
    force: bool = False


@dataclass(frozen=True)
class EngineChoice:
    """Where the cells run: ``process`` (a local pool of ``jobs``) or ``ray`` (a local
    cluster, or the one at ``address``)."""

    name: str = "process"
    jobs: int = 1
    address: str | None = None


def sweep_command(console: Any, request: SweepRequest, engine: EngineChoice) -> int:
    """Plan (validating every cell), run and map a sweep; returns the exit code: 0, 1 when
    cells crashed (their worker died), 130 or 143 when Ctrl-C or SIGTERM stopped it."""
    from walkrepro.studies.sweep.maps import plot_sweep

    # The engine first: a bad --engine or --jobs leaves no sweep directory behind.
    runner = make_engine(engine.name, engine.jobs, engine.address)
    plan = _plan(request)
    if request.update_reference and not plan.info.get("map"):
        raise WalkreproError("--update-reference applies to a declared map (--map NAME) only.")
    todo = len(plan.missing)
    console.print(
        f"sweep of {plan.info['experiment']}: {len(plan.cells)} cells, {todo} to run "
        f"({engine.name} engine, {engine.jobs} job(s)) → {plan.directory}",
        highlight=False,
    )
    report = run_plan(plan, runner, request.keep_logs, console) if todo else None
    written = plot_sweep(plan.directory)
    for path in written:
        console.print(f"wrote {path}", highlight=False)
    if report is not None:
        rate = report.ran / report.wall_time * 60 if report.wall_time > 0 else 0.0
        console.print(
            f"{report.ran} cell(s) in {report.wall_time:.1f} s ({rate:.1f} cells/min), "
            f"{report.failures} failed",
            highlight=False,
        )
        if report.interrupted:
            console.print(
                f"[yellow]interrupted:[/] {len(plan.done)} of {len(plan.cells)} cells done; "
                f"continue with: walkrepro sweep --resume {plan.directory}",
                highlight=False,
            )
            return exit_code(report.signum)
    crashed = [
        row["cell"]
        for row in store.read_cells(plan.directory / store.CELLS_FILE).rows
        if row["outcome"] == CRASHED
    ]
    if plan.info.get("claims"):
        _print_claims(console, plan)
    if crashed:
        console.print(
            f"[red]{len(crashed)} cell(s) crashed[/] (their worker process died: cells "
            f"{', '.join(map(str, crashed))}); the map is incomplete. Run them again with: "
            f"walkrepro sweep --resume {plan.directory}",
            highlight=False,
        )
        return CRASHED_EXIT
    if request.update_reference:
        target = update_reference(plan.directory, plan.info["map"])
        console.print(f"reference map updated: {target}", highlight=False)
    return 0


def _plan(request: SweepRequest) -> SweepPlan:
    """The sweep's plan: the rest of an earlier sweep (``--resume``, which takes no grid,
    ``--set`` or ``--metric``), or a new one, its cells validated and its output root
    claimed."""
    from walkrepro.runtime import outdir

    experiment, resume = request.experiment, request.resume
    if resume is not None:
        if request.grid or request.overrides or request.metrics or request.map_name:
            raise WalkreproError(
                "--resume continues a sweep with its own grid, --set and --metric; "
                "give only --resume (and engine options)."
            )
        plan = plan_resume(resume)
        if experiment is not None and experiment != plan.info["experiment"]:
            raise WalkreproError(
                f"--resume {resume}: that sweep is of {plan.info['experiment']!r}, "
                f"not {experiment!r}."
            )
    else:
        if experiment is None:
            raise WalkreproError("give an EXPERIMENT to sweep (or --resume SWEEP_DIR).")
        if request.update_reference and request.grid and request.map_name is None:
            raise WalkreproError("--update-reference applies to a declared map (--map NAME) only.")
        outdir.claim_root(request.out, outdir.RUNS, request.force, create=False)
        plan = plan_new(
            experiment,
            request.grid,
            request.overrides,
            request.out,
            request.metrics,
            request.map_name,
        )
        outdir.claim_root(request.out, outdir.RUNS, force=True)  # checked above: mark it
    return plan


def _print_claims(console: Any, plan: SweepPlan) -> None:
    """Each of the declared map's claims, evaluated on the sweep's cells, one line each."""
    from walkrepro.studies.sweep.claims import evaluate_sweep

    spec = _declared(plan.info)
    table = store.read_cells(plan.directory / store.CELLS_FILE)
    rows = evaluate_sweep(table.rows, table.fields, spec, plan.info["n_cells"])
    for r in rows:
        console.print(f"{r.status}: {r.metric} — {r.note}", highlight=False)


def _declared(info: dict) -> Any:
    """The declared sweep recorded in a sweep.yaml (its claims, for evaluation)."""
    from walkrepro.specs.sweeps import SweepSpec

    grid = {g["field"]: g["values"] for g in info["grid"]}
    return SweepSpec(name=info["map"], grid=grid, claims=info.get("claims", []))


def map_verdicts(
    names: Sequence[str],
    rerun: bool,
    out: Path,
    jobs: int,
    console: Any = None,
    engine: EngineChoice | None = None,
) -> list:  # list[checks.Verdict]
    """One verdict per declared map of the named experiments.

    Without ``rerun`` the claims are evaluated on the committed reference
    ``results/maps/<map>/cells.csv`` (no simulation); a reference made with another grid or
    other overrides than the spec now declares is reported as stale (fail). With ``rerun``
    each map is swept again under ``out`` on ``engine`` (default: ``jobs`` processes) and
    evaluated on the new cells.
    """
    from dataclasses import replace

    from walkrepro.evaluation.checks import FAIL, CheckRow, Verdict
    from walkrepro.locations import REFERENCES_DIR
    from walkrepro.specs.files import load_spec
    from walkrepro.studies.sweep.claims import evaluate_sweep
    from walkrepro.studies.sweep.engines import make_engine

    engine = engine or EngineChoice("process", jobs)
    verdicts = []
    for name in names:
        spec = load_spec(name).spec
        for declared in spec.sweeps:
            label = f"{spec.name} · map {declared.name}"
            if rerun:
                plan = plan_new(name, [], [], out, (), declared.name)
                run_plan(
                    plan, make_engine(engine.name, engine.jobs, engine.address), False, console
                )
                from walkrepro.studies.sweep.maps import plot_sweep

                plot_sweep(plan.directory)
                directory, origin = plan.directory, f"sweep {plan.directory.name}"
            else:
                directory = REFERENCES_DIR / MAPS_DIR_NAME / declared.name
                origin = f"results/{MAPS_DIR_NAME}/{declared.name}"
            cells = directory / store.CELLS_FILE
            if not cells.is_file():
                row = CheckRow(
                    metric=f"map {declared.name}",
                    op="==",
                    paper=0.0,
                    measured=float("nan"),
                    status=FAIL,
                    source=declared.claims[0].source if declared.claims else "",
                    note=f"no reference map: run walkrepro sweep {name} --map {declared.name} "
                    "--update-reference",
                )
                verdicts.append(Verdict(label, "complete", (row,)))
                continue
            info = store.read_info(directory)
            table = store.read_cells(cells)
            rows = evaluate_sweep(table.rows, table.fields, declared, info["n_cells"], origin)
            stale = _stale(info, declared)
            if stale:
                rows = [
                    replace(
                        r,
                        status=FAIL,
                        observed=None,
                        note=f"stale reference map ({stale}); re-run walkrepro sweep {name} "
                        f"--map {declared.name} --update-reference. {r.note}",
                    )
                    for r in rows
                ]
            verdicts.append(Verdict(label, "complete", tuple(rows)))
    return verdicts


def _stale(info: dict, declared: Any) -> str:
    """Why a committed map no longer matches the spec's declared sweep ('' if it does)."""
    from walkrepro.studies.sweep.grid import parse_grid_item

    axes = [parse_grid_item(g) for g in declared.grid_items()]
    if [(a.field, list(a.values)) for a in axes] != [
        (g["field"], list(g["values"])) for g in info["grid"]
    ]:
        return "its grid differs from the spec's"
    if list(declared.set_items()) != list(info["set"]):
        return "its --set overrides differ from the spec's"
    return ""
