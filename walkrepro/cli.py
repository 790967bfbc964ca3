"""The ``walkrepro`` command line: list, run, check, plot, verify, render, export, calibrate.

Thin by design: parse arguments, call the library, print. A user error (bad spec, unknown
name, unwritable directory) prints one paragraph and exits with code 2, no traceback.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import os
import re
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, TypeVar

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from walkrepro.errors import WalkreproError
from walkrepro.locations import REFERENCES_DIR
from walkrepro.runs import results

if TYPE_CHECKING:
    from walkrepro.specs.models import ExperimentSpec


def command_setup() -> None:
    """The ``walkrepro`` command's process set-up, done when the command starts (importing
    walkrepro does none of it, so a program that uses the library keeps its own):

    - stop signals (Ctrl-C, SIGTERM) that come during the start-up imports are held and
      handed to the run or sweep that follows (:mod:`walkrepro.runtime.interrupt`);
    - ``OPENBLAS_NUM_THREADS=1`` unless the user set it: a run is one simulation loop on one
      core with matrices of at most 60 x 60, where OpenBLAS's worker threads only add
      hand-offs (≈ 2.5 µs on Paper I's 12 x 12 eigh at 2 kHz) and ``check --jobs N`` would
      oversubscribe the cores; OpenBLAS reads it when numpy loads, so before that;
    - MuJoCo imported with no GL backend bound (:func:`walkrepro.runtime.gl.import_mujoco`);
    - numba's cache in walkrepro's source-keyed directory, through ``NUMBA_CACHE_DIR`` so
      that worker processes inherit it (:mod:`walkrepro.runtime.numbacache`).
    """
    from walkrepro.runtime.interrupt import hold_stop_signals_if_command

    hold_stop_signals_if_command()
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from walkrepro.runtime import gl, numbacache

    gl.import_mujoco()
    numbacache.install()


class _Command(typer.Typer):
    """The typer app whose call (the console script, ``python -m walkrepro``) first does the
    command's set-up; tests invoke its commands without it."""

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        command_setup()
        return super().__call__(*args, **kwargs)


app = _Command(
    help="Reproduce published biped-walking controllers in MuJoCo and check the reproduction.",
    no_args_is_help=True,
    add_completion=True,
    pretty_exceptions_enable=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)


def version_text() -> str:
    """walkrepro's version and git commit, and the MuJoCo and Pinocchio versions."""
    import mujoco

    from walkrepro._version import __version__
    from walkrepro.runs.provenance import git_commit, pinocchio_version

    return (
        f"walkrepro {__version__} (git {git_commit()}), MuJoCo {mujoco.__version__}, "
        f"Pinocchio {pinocchio_version()}"
    )


def _show_version(value: bool) -> None:
    if value:
        print(version_text())
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[
        bool,
        typer.Option(
            "--version",
            callback=_show_version,
            is_eager=True,
            help="Show walkrepro's version, git commit, and the MuJoCo and Pinocchio versions.",
        ),
    ] = False,
    experiments: Annotated[
        Path | None,
        typer.Option(
            "--experiments",
            help="A folder of your own specs (NAME.yaml), searched before the shipped "
            "experiments; `check` without names runs the folder's.",
            file_okay=False,
            dir_okay=True,
            exists=True,
            envvar="WALKREPRO_EXPERIMENTS",
        ),
    ] = None,
) -> None:
    """Reproduce published biped-walking controllers in MuJoCo and check the reproduction."""
    from walkrepro.locations import USER_EXPERIMENTS_ENV

    if experiments is not None:
        # The environment carries it to --jobs workers and Ray workers too.
        os.environ[USER_EXPERIMENTS_ENV] = str(experiments.resolve())


def _console(stderr: bool = False) -> Console:
    """A console for this call; when output is not a terminal (pipes, CI logs), tables get a
    wide fixed width instead of being squeezed to 80 columns."""
    stream = sys.stderr if stderr else sys.stdout
    return Console(stderr=stderr, width=None if stream.isatty() else 200)


F = TypeVar("F", bound=Callable[..., Any])

SetOption = Annotated[
    list[str] | None,
    typer.Option("--set", help="Override a spec field, e.g. --set controller.params.zeta=0.04"),
]
#: Lets --update-reference write from uncommitted changes (local work; marked +dirty).
AllowDirtyOption = Annotated[
    bool,
    typer.Option(
        "--allow-dirty",
        help="With --update-reference: write references from uncommitted changes "
        "(local work; their provenance says +dirty).",
    ),
]
OutOption = Annotated[
    Path,
    typer.Option(
        "--out",
        help="Root directory for run outputs: a new or empty directory, or one walkrepro "
        "wrote (it holds a .walkrepro-output file); any other is refused unless --force.",
        show_default=True,
    ),
]
#: Lets a reader use a cut or damaged log for what it holds (walkrepro/log/integrity.py).
PartialOption = Annotated[
    bool,
    typer.Option(
        "--partial",
        help="Use a cut or damaged log for what it holds (without it, such a log is an error "
        "naming what it holds and lacks); every output then says partial.",
    ),
]
#: Lets a command write into a directory (or over a file) that walkrepro did not write.
ForceOption = Annotated[
    bool,
    typer.Option(
        "--force",
        help="Write into --out even if it holds files walkrepro did not write (a replaced "
        "output's old contents are deleted).",
    ),
]


def options_from(record: type) -> Callable[[Callable[[Any], None]], Callable[..., None]]:
    """A command whose options are the fields of ``record``, a dataclass whose field types
    are typer's ``Annotated`` declarations: typer reads them from the signature of the
    function returned, and the command's body receives one ``record`` rather than a
    parameter per option."""
    import dataclasses
    import inspect
    import typing

    hints = typing.get_type_hints(record, include_extras=True)
    parameters = [
        inspect.Parameter(
            field.name,
            inspect.Parameter.KEYWORD_ONLY,
            default=field.default,
            annotation=hints[field.name],
        )
        for field in dataclasses.fields(record)
    ]

    def decorate(body: Callable[[Any], None]) -> Callable[..., None]:
        @functools.wraps(body)
        def command(**options: Any) -> None:
            return body(record(**options))

        command.__signature__ = inspect.Signature(parameters)  # type: ignore[attr-defined]
        command.__annotations__ = {q.name: q.annotation for q in parameters}
        return command

    return decorate


def _needs_checkout(what: str) -> None:
    """Refuse to write the repository's own files (references, calibration, docs) from an
    installed walkrepro: they live in a clone (walkrepro/locations.py)."""
    from walkrepro.locations import IS_CHECKOUT

    if not IS_CHECKOUT:
        raise WalkreproError(
            f"{what} writes the repository's committed files, and this walkrepro is an "
            "installed copy; run it from a clone with `pip install -e .`."
        )


def _needs_clean_tree(what: str, allow_dirty: bool) -> None:
    """Refuse to write committed results from uncommitted changes to ``walkrepro/``,
    ``robots/`` or ``experiments/``: a reference must come from a commit a reader can check
    out. ``--allow-dirty`` lets local work go on; its results' provenance then says
    ``+dirty``."""
    from walkrepro.runs.provenance import RESULT_INPUTS, dirty_paths

    changed = dirty_paths(RESULT_INPUTS)
    if changed and not allow_dirty:
        shown = ", ".join(changed[:5]) + (" …" if len(changed) > 5 else "")
        raise WalkreproError(
            f"{what} writes committed results, and the files that decide them (walkrepro/, robots/, experiments/, pyproject.toml, setup.py) have "
            f"uncommitted changes ({shown}); commit them first, or pass --allow-dirty for "
            "local work (the results' provenance then says +dirty)."
        )


def friendly_errors(fn: F) -> F:
    """Turn user errors into one paragraph on stderr and exit code 2."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except WalkreproError as exc:
            _console(stderr=True).print(
                f"[bold red]error:[/] {escape(str(exc))}", highlight=False, soft_wrap=True
            )
            raise typer.Exit(code=exc.exit_code) from None
        except KeyboardInterrupt:  # Ctrl-C outside a run (a run keeps its own directory)
            _console(stderr=True).print("interrupted")
            raise typer.Exit(code=130) from None

    return wrapper  # type: ignore[return-value]


@app.command("list")
@friendly_errors
def list_cmd(
    long: Annotated[
        bool,
        typer.Option("--long", "-l", help="Also the robot, the controller and the description."),
    ] = False,
) -> None:
    """List every experiment: its name, paper, figures and what it runs.

    Your own folder's experiments are listed too, with --experiments DIR. On a terminal the
    list is a table that fits its width; piped, it is one line per experiment. --long adds
    the robot, the controller and the whole description.
    """
    from walkrepro.specs.files import all_experiment_names, load_spec

    rows = [ListRow.of(name, load_spec(name).spec) for name in all_experiment_names()]
    if sys.stdout.isatty():
        console = _console()
        if long:
            console.print(*experiments_long(rows), sep="\n")
        else:
            console.print(experiments_table(rows, console.width))
    else:
        for line in list_lines(rows, long):
            print(line)


@dataclasses.dataclass(frozen=True)
class ListRow:
    """One experiment as ``walkrepro list`` shows it.

    Attributes:
        name: the experiment's name.
        paper: the paper's key (``lee2021``, ``faraji``, ``jo_oh``; ``walkrepro``: its own).
        figure: the paper's figures (``6, 7, 8, 15``), or ``-``.
        summary: the description's first sentence, without a leading citation the other
            columns repeat.
        robot: the robot's name.
        controller: the controller's type.
        description: the whole description.
    """

    name: str
    paper: str
    figure: str
    summary: str
    robot: str
    controller: str
    description: str

    @classmethod
    def of(cls, name: str, spec: ExperimentSpec) -> ListRow:
        """The row of experiment ``name`` with spec ``spec``."""
        description = " ".join(spec.description.split())
        return cls(
            name=name,
            paper=spec.paper.key,
            figure=spec.paper.figure or "-",
            summary=_summary(description),
            robot=spec.robot,
            controller=spec.controller.type,
            description=description,
        )


#: A leading citation of a description ("Paper II Fig. 14 B: ", "Lee et al. 2021 §VI-A
#: (Figs. 6–8): "), which the paper and figure columns already show.
_CITATION = re.compile(r"^(Paper [IV]+|Lee et al\. 2021)\b[^:]{0,40}:\s+")


#: Abbreviations whose full stop ends no sentence.
_ABBREVIATIONS = ("al.", "Fig.", "Figs.", "Eq.", "Eqs.", "e.g.", "i.e.", "vs.", "cf.", "approx.")
#: Longest summary of piped ``walkrepro list`` [characters].
SUMMARY_CHARS = 100


def _summary(description: str) -> str:
    """The description's first sentence without its leading citation, at most
    :data:`SUMMARY_CHARS` characters (cut at a word, ending in an ellipsis)."""
    text = _CITATION.sub("", description, count=1)
    for match in re.finditer(r"[.;] ", text):
        end = match.start() + 1
        if not text[:end].endswith(_ABBREVIATIONS):
            text = text[:end] if match.group()[0] == "." else text[: end - 1]
            break
    if len(text) > SUMMARY_CHARS:
        text = text[: SUMMARY_CHARS - 1].rsplit(" ", 1)[0].rstrip(",;:") + "…"
    return text


def experiments_table(rows: list[ListRow], width: int) -> Table:
    """The terminal table of ``walkrepro list`` for a terminal ``width`` columns wide: name,
    paper and figures never shrink, the summary takes what is left and ends in an ellipsis."""
    # One space after each column, none before the first or after the last.
    table = Table(box=None, padding=(0, 1, 0, 0), pad_edge=False, header_style="bold")
    used = 0
    for header, values in (
        ("experiment", [r.name for r in rows]),
        ("paper", [r.paper for r in rows]),
        ("fig.", [r.figure for r in rows]),
    ):
        column_width = max(len(header), *(len(v) for v in values))
        table.add_column(header, no_wrap=True, width=column_width)
        used += column_width + 1  # one space between columns
    rest = max(10, width - used)  # at least 10 characters of text on a very narrow terminal
    table.add_column("what it runs", no_wrap=True, overflow="ellipsis", width=rest)
    for row in rows:
        table.add_row(row.name, row.paper, row.figure, row.summary)
    return table


def experiments_long(rows: list[ListRow]) -> list[Any]:
    """``walkrepro list --long`` on a terminal: per experiment, a line with its name, paper,
    figures, robot and controller, then its whole description, indented and wrapped to the
    terminal's width (a table would squeeze it to a few characters on 80 columns)."""
    from rich.padding import Padding
    from rich.text import Text

    out: list[Any] = []
    for row in rows:
        head = Text.assemble(
            (row.name, "bold"),
            f"  {row.paper} · fig. {row.figure} · {row.robot} · {row.controller}",
        )
        out += [head, Padding(Text(row.description), (0, 0, 1, 4))]
    return out


def list_lines(rows: list[ListRow], long: bool = False) -> list[str]:
    """``walkrepro list`` piped: one line per experiment, columns aligned by spaces (name,
    paper, figures, then the summary, or with ``long`` the robot, controller and whole
    description), so ``grep``, ``head`` and ``cut`` read it."""
    if not rows:
        return []
    fields = [
        (r.name, r.paper, r.figure, r.robot, r.controller) if long else (r.name, r.paper, r.figure)
        for r in rows
    ]
    widths = [max(len(f[i]) for f in fields) for i in range(len(fields[0]))]
    return [
        "  ".join(f.ljust(w) for f, w in zip(field, widths, strict=True))
        + "  "
        + (r.description if long else r.summary)
        for field, r in zip(fields, rows, strict=True)
    ]


@app.command()
@friendly_errors
def provenance(
    experiments: Annotated[
        list[str], typer.Argument(help="Experiment names or paths to spec YAML files.")
    ],
    set_: SetOption = None,
    unclassified_only: Annotated[
        bool, typer.Option("--unclassified", help="List only the numbers without a class.")
    ] = False,
) -> None:
    """List every number an experiment's run uses, with its provenance class and source.

    The numbers of the robot, the scene, the spec and the controller, each classed paper,
    source, assumed or calibrated, with where it comes from (docs/provenance.md). Exit 1
    when one has no class."""
    from walkrepro.publish.ledger import LISTED, UNCLASSIFIED, counts, experiment_ledger

    console = _console()
    missing = 0
    for name in experiments:
        numbers = experiment_ledger(name, tuple(set_ or ()))
        table = Table(title=f"{name}: every number the run uses")
        for col in ("group", "parameter", "value", "class"):
            table.add_column(col, overflow="fold")
        table.add_column("source", overflow="fold")
        for n in numbers:
            if unclassified_only and n.klass != UNCLASSIFIED:
                continue
            style = "bold red" if n.klass == UNCLASSIFIED else None
            table.add_row(n.group, n.name, n.value, n.klass, n.source, style=style)
        console.print(table)
        c = counts(numbers)
        console.print(
            f"{name}: " + ", ".join(f"{c[k]} {k}" for k in LISTED if c[k] or k != "override"),
            highlight=False,
        )
        missing += c[UNCLASSIFIED]
    if missing:
        raise typer.Exit(code=1)


@app.command()
@friendly_errors
def claims(
    papers: Annotated[
        list[str] | None,
        typer.Argument(help="Paper keys (lee2021, faraji, jo_oh); default: every register."),
    ] = None,
    details: Annotated[
        bool, typer.Option("--details", help="Also print the paper's words and each row.")
    ] = False,
) -> None:
    """List each paper's claims with their status from the committed references.

    The claim register (experiments/claims/<paper>.yaml): every claim reproduced,
    calibrated, deviating, failed, not covered or uncheckable, with the rows that test it and
    their measured values (docs/claims.md). Exit 1 when a claim fails."""
    from walkrepro.locations import REFERENCES_DIR
    from walkrepro.publish.claim_register import FAILED, paper_totals
    from walkrepro.specs.claims import find_register, register_papers

    console = _console()
    keys = list(papers or register_papers())
    for key in keys:
        find_register(key)  # an unknown paper lists the valid ones before anything runs
    found = paper_totals(REFERENCES_DIR)
    failed = False
    for key in keys:
        totals, results = found[key]
        console.print(f"[bold]{escape(_paper_label(key))}[/]", highlight=False)
        width = max((len(r.claim.id) for r in results), default=0)
        for r in results:
            colour = _CLAIM_COLOURS.get(r.status, "default")
            brief = "" if details else f"  {_rows_brief(r.rows)}"
            line = f"  [{colour}]{r.status:<11}[/] {escape(r.claim.id):<{width}}{escape(brief)}"
            console.print(
                line.rstrip(),
                highlight=False,
                soft_wrap=True,
            )
            if details:
                _print_claim_details(console, r)
        console.print(
            f"{key}: the paper's claims: {totals.claims_text()}; walkrepro's own rows: {totals.own}",
            highlight=False,
        )
        failed |= totals.by_status[FAILED] > 0
    if failed:
        raise typer.Exit(code=1)


def _print_claim_details(console: Console, result: Any) -> None:  # ClaimResult
    """A claim's where, words, uncheckable reason and every row, indented under it."""
    lines = [f"{result.claim.where} ({result.claim.kind}): “{result.claim.words}”"]
    if result.claim.uncheckable:
        lines.append(f"uncheckable: {result.claim.uncheckable}")
    if result.claim.not_covered:
        lines.append(f"not covered: {result.claim.not_covered}")
    lines += [f"row: {t.text}" for t in result.rows]
    for line in lines:
        console.print(f"      {escape(line)}", highlight=False, soft_wrap=True)


_CLAIM_COLOURS = {
    "reproduced": "green",
    "calibrated": "blue",
    "deviating": "yellow",
    "failed": "red",
    "not covered": "magenta",
}


def _paper_label(key: str) -> str:
    from walkrepro import plugins

    paper = plugins.papers().get(key)
    return f"{paper.label} ({key})" if paper is not None else key


def _rows_brief(rows: tuple) -> str:
    """The rows behind a claim, short: ``experiment metric = value`` for the first, and how
    many more."""
    if not rows:
        return ""
    first = rows[0].text
    return first if len(rows) == 1 else f"{first} (+{len(rows) - 1} rows)"


@app.command()
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
    summary = _run_one(experiment, set_ or [], out, (figures, figures), show_progress=True)
    _print_verdicts([summary.verdict], details, per_claim=True)
    _console().print(f"run directory: [bold]{summary.run_dir}[/]")
    for what, name in (("figures", results.FIGURES_DIR), ("video", "video.mp4")):
        if (summary.run_dir / name).exists():
            _console().print(f"{what}: {summary.run_dir / name}", highlight=False)
    _print_missing(summary.run_dir, summary.stages, summary.signum if summary.interrupted else None)
    if summary.interrupted:  # 130 after Ctrl-C, 143 after SIGTERM
        raise typer.Exit(code=summary.exit_code)
    if summary.result.outcome == "error":
        _console(stderr=True).print(f"[bold red]error:[/] {escape(summary.result.message)}")
        raise typer.Exit(code=1)
    if not summary.verdict.passed:  # a CI can use the exit code, as with `check`
        raise typer.Exit(code=1)


def _print_missing(run_dir: Path, stages: dict[str, str], signum: int | None = None) -> None:
    """On stderr: which stage a stop interrupted, and each output the run lacks (its
    ``run.json`` records the same)."""
    import signal

    console = _console(stderr=True)
    if signum is not None:
        name = signal.Signals(signum).name
        during = [n for n, status in stages.items() if status == results.INTERRUPTED]
        where = f"the {during[0]} stage" if during else "the run"
        console.print(
            f"[yellow]interrupted ({name}) during {where}[/]; {run_dir / results.RUN_FILE} "
            "records what was done.",
            highlight=False,
            soft_wrap=True,
        )
    for text in results.missing_outputs({"stages": stages}):
        console.print(f"[yellow]missing:[/] {escape(text)}", highlight=False, soft_wrap=True)


def _complete_experiment(incomplete: str) -> list[str]:
    """Shell completion: the experiments whose names start with ``incomplete``."""
    from walkrepro.specs.files import all_experiment_names

    return [n for n in all_experiment_names() if n.startswith(incomplete)]


@dataclasses.dataclass(frozen=True)
class CheckOptions:
    """``walkrepro check``: the experiments and runs to check, and how."""

    experiments: Annotated[
        list[str] | None,
        typer.Argument(help="Experiments to run and check.", autocompletion=_complete_experiment),
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


@app.command()
@friendly_errors
@options_from(CheckOptions)
def check(options: CheckOptions) -> None:
    """Run experiments (or re-check runs) and compare them with the papers. Exit 1 on failure.

    An expectation relative to another experiment (its partner) compares with the partner's
    run in this batch, else its committed reference. With --set, the partners run in the
    same batch with the same overrides (paired runs).

    The claims of each experiment's declared maps (spec ``sweeps:``) are checked too.
    """
    from walkrepro import api
    from walkrepro.evaluation import checks
    from walkrepro.runs.experiment import References, evaluate_log
    from walkrepro.specs.files import experiment_names
    from walkrepro.studies.sweep.command import EngineChoice
    from walkrepro.studies.sweep.engines import ENGINES

    if options.engine not in ENGINES:
        raise WalkreproError(
            f"unknown engine {options.engine!r}. Valid engines: {', '.join(ENGINES)}."
        )
    if options.address is not None and options.engine != "ray":
        raise WalkreproError("--address applies to --engine ray only.")
    overrides = list(options.set_ or [])
    figures = options.figures or options.update_reference
    if options.update_reference and overrides:
        raise WalkreproError(
            "--update-reference takes runs of the experiments as shipped; drop --set "
            f"({' '.join(overrides)})."
        )
    if options.update_reference:
        _needs_checkout("--update-reference")
        _needs_clean_tree("check --update-reference", options.allow_dirty)
    if options.experiments or not options.run_dir:  # it writes runs under --out
        from walkrepro.runtime import outdir

        default = options.out == results.DEFAULT_ROOT
        outdir.claim_root(options.out, outdir.RUNS, options.force or default, create=False)
    verdicts: list[checks.Verdict] = []
    for path in options.run_dir or []:
        verdicts.append(api.evaluate(path, partial=options.partial))
        directory, _ = results.resolve_run(path)
        _print_missing(directory, results.read_record(directory).get("stages") or {})
    names = list(options.experiments or [])
    if not names and not options.run_dir:
        names = experiment_names()
    specs = {name: _resolved(name, overrides) for name in names}  # validate all before running
    partners, unpaired = _paired_partners(specs, overrides)
    batch_names = names + partners
    # Videos only where a reference keeps one (a video per run would cost a check minutes).
    video = _with_reference_video(batch_names) if options.update_reference else frozenset()
    summaries = (
        _run_batch(
            batch_names,
            overrides,
            options.out,
            (figures, video),
            EngineChoice(options.engine, options.jobs, options.address),
        )
        if batch_names
        else []
    )
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
            _plot_comparisons(summaries)
    if names and not overrides:  # committed maps were made without overrides
        from walkrepro.studies.sweep.command import map_verdicts

        verdicts += map_verdicts(
            names,
            options.sweeps,
            options.out,
            options.jobs,
            _console(stderr=True),
            EngineChoice(options.engine, options.jobs, options.address),
        )
    _print_verdicts(verdicts, options.details)
    interrupted = any(s.interrupted for s in summaries)
    if options.update_reference and not interrupted:
        _update_references(summaries)
        _update_docs()
    if options.junit is not None:
        checks.write_junit(verdicts, options.junit)
    if interrupted:  # 130 after Ctrl-C, 143 after SIGTERM
        raise typer.Exit(code=next(s.exit_code for s in summaries if s.interrupted))
    if not all(v.passed for v in verdicts):
        raise typer.Exit(code=1)


def _update_docs() -> None:
    """Regenerate the documents made from the references (``walkrepro docs``): new
    references change the README's status table and the deviations' measured values."""
    from walkrepro.publish.docsgen import generated_files, write_docs

    _needs_checkout("walkrepro docs")

    for path in write_docs(generated_files()):
        _console().print(f"docs updated: {path}", highlight=False)


def _paired_partners(
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
            _resolved(name, overrides)
            partners.append(name)
        except WalkreproError as exc:
            unpaired[name] = f"the overrides do not apply to it ({exc})"
    return partners, unpaired


def _run_batch(
    names: list[str],
    overrides: list[str],
    out: Path,
    outputs: tuple[bool, frozenset[str]],
    engine: Any,  # sweep.command.EngineChoice
) -> list:
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
    _console().print(f"running {len(names)} experiment(s) with {where}…")
    done: list = []

    def report(summary: Any) -> None:
        done.append(summary)
        wall = summary.result.wall_time
        # A verdict with partner rows is final only once the whole batch has run.
        verdict = (
            "verdict when its partners are done" if summary.relative else count([summary.verdict])
        )
        _console().print(
            f"[{len(done)}/{len(names)}] {summary.verdict.experiment}: {summary.result.message} "
            f"in {wall:.0f} s ({verdict}) → {summary.run_dir}",
            highlight=False,
        )
        signum = summary.signum if summary.interrupted else None
        _print_missing(summary.run_dir, summary.stages, signum)

    if workers == 1 and engine.name == "process":
        for name in names:
            summary = _run_one(name, overrides, out, _outputs_of(name, outputs), False)
            report(summary)
            if summary.interrupted:
                break
        return done
    # The sweep's engines: workers reused across runs, a dead worker named, and a stop
    # (Ctrl-C or SIGTERM here) passed on to the runs under way, whose results still come
    # (with Ray: cancelled, their run directories kept but not reported).
    tasks = [
        _BatchTask(i, n, tuple(overrides), out, _outputs_of(n, outputs))
        for i, n in enumerate(names)
    ]
    runner = make_engine(engine.name, workers, engine.address, _run_task, _BatchResult.crashed)
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
class _BatchTask:
    """One experiment of a ``check --jobs`` batch, as a pool worker runs it."""

    index: int
    name: str
    overrides: tuple[str, ...]
    out: Path
    outputs: tuple[bool, bool]


@dataclasses.dataclass(frozen=True)
class _BatchResult:
    """What a pool worker returns for a :class:`_BatchTask`: the run's summary, or the
    exception the run raised (re-raised here, as a run in this process would), or, when the
    worker died, neither and a message."""

    index: int
    summary: Any = None
    error: BaseException | None = None
    message: str = ""
    engine_time: float = float("nan")

    @staticmethod
    def crashed(index: int, message: str, engine_time: float) -> _BatchResult:
        """The result of a task whose worker died."""
        return _BatchResult(index, message=message, engine_time=engine_time)


def _run_task(task: _BatchTask) -> _BatchResult:
    """Run one experiment of a batch in a pool worker (module-level: the pool pickles it)."""
    try:
        summary = _run_one(task.name, list(task.overrides), task.out, task.outputs, False)
    except Exception as exc:  # noqa: BLE001 - handed to the parent, which raises it
        if hasattr(exc, "add_note"):  # Python >= 3.11: the worker's traceback comes along
            import traceback

            exc.add_note("in the worker:\n" + "".join(traceback.format_tb(exc.__traceback__)))
        return _BatchResult(task.index, error=exc)
    return _BatchResult(task.index, summary)


def _update_references(summaries: list) -> None:
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
            _console(stderr=True).print(f"[yellow]no snapshot strip:[/] {exc}", highlight=False)
        target = results.save_reference(s.run_dir)
        # A reference keeps a video where it has one (the headline experiments: a size budget).
        video = s.run_dir / VIDEO_FILE
        if video.is_file() and (target / VIDEO_FILE).is_file():
            shutil.copy2(video, target / VIDEO_FILE)
        _console().print(f"reference updated: {target}")


@app.command()
@friendly_errors
def plot(
    runs: Annotated[
        list[Path],
        typer.Argument(help="Run directory or log (two to compare runs), or a sweep directory."),
    ],
    out: Annotated[
        Path | None,
        typer.Option(
            help="Figure directory (default: RUN/figures): new, empty, or one walkrepro "
            "wrote; any other is refused unless --force."
        ),
    ] = None,
    force: ForceOption = False,
    partial: PartialOption = False,
) -> None:
    """Redraw the paper's figures from one run, or compare two runs, or a sweep's maps."""
    from walkrepro.present.figures import plot_compare, plot_run
    from walkrepro.runtime import outdir
    from walkrepro.studies.sweep.store import is_sweep_dir

    if out is not None:
        outdir.claim_root(out, outdir.FIGURES, force)

    if len(runs) == 1 and is_sweep_dir(runs[0]):
        from walkrepro.studies.sweep.maps import plot_sweep

        for path in plot_sweep(runs[0], out):
            _console().print(f"wrote {path}")
        return
    if len(runs) > 2:
        raise WalkreproError("plot takes one run, or two runs to compare.")
    resolved = [results.resolve_run(r) for r in runs]
    if len(resolved) == 1:
        directory, log = resolved[0]
        written = plot_run(log, out or directory / results.FIGURES_DIR, partial)
    else:
        written = plot_compare(
            resolved[0][1], resolved[1][1], out or resolved[0][0] / results.FIGURES_DIR, partial
        )
    for path in written:
        _console().print(f"wrote {path}")


@app.command()
@friendly_errors
def verify(
    log: Annotated[Path, typer.Argument(help="A log.mcap (or its run directory).")],
    tolerance: Annotated[float, typer.Option(help="Largest allowed deviation.")] = 1e-9,
) -> None:
    """Re-simulate a log from its scene, initial state and inputs; compare with its states.

    Exit 1 when the replay deviates beyond the tolerance, or when the log is truncated or
    damaged (what could be read is still replayed and reported).
    """
    from walkrepro.sim.replay import verify_log

    directory, log_path = results.resolve_run(log)
    if not log_path.is_file():
        raise WalkreproError(
            f"{directory}: this run has no {results.LOG_FILE} (it stopped before its log was "
            f"opened; see its {results.RUN_FILE}); there is nothing to verify."
        )
    report = verify_log(log_path, tolerance)
    logged = "?" if report.n_logged is None else str(report.n_logged)
    replayed = f"replayed {report.n_steps} of {logged} logged steps"
    compared = f"compared {report.n_states_compared} states"
    if report.n_states_compared:
        compared += (
            f"; largest deviation {report.max_deviation:.3g} (step {report.worst_step}, "
            f"{report.worst_field}); tolerance {report.tolerance:g}"
        )
    if report.damage:
        upto = f" (up to t = {report.last_time:.4g} s)" if report.n_states_read else ""
        unknown = ""
        if report.n_logged is None:
            lost = "cut off" if report.damage.startswith("truncated") else "damaged"
            unknown = f" (? = unknown: the summary that counts them is {lost})"
        _console().print(
            f"[red]DAMAGED[/]: {escape(str(log_path))} is {escape(report.damage)}. Read "
            f"{report.n_states_read} states{upto} and the inputs of {report.n_steps} steps; "
            f"{replayed}{unknown}; {compared}.",
            highlight=False,
        )
        raise typer.Exit(code=1)
    status = "[green]OK[/]" if report.ok else "[red]FAILED[/]"
    _console().print(f"{status}: {replayed}, {compared}", highlight=False)
    if not report.ok:
        raise typer.Exit(code=1)


@app.command()
@friendly_errors
def render(
    run_path: Annotated[Path, typer.Argument(help="Run directory or log.")],
    video: Annotated[
        bool,
        typer.Option(
            "--video",
            help="Write an MP4 (H.264) of the whole run at real time instead of a strip.",
        ),
    ] = False,
    at: Annotated[str, typer.Option(help="Comma-separated times [s] (strip).")] = "0,1,2,3,4",
    out: Annotated[
        Path | None,
        typer.Option(
            help="Output path (default: RUN/figures/snapshots.png, or RUN/video.mp4 with --video)."
        ),
    ] = None,
    width: Annotated[
        int | None,
        typer.Option(min=2, help="Frame width [px] (default: 480 strip, 640 video)."),
    ] = None,
    height: Annotated[
        int | None,
        typer.Option(min=2, help="Frame height [px] (default: 640 strip, 360 video)."),
    ] = None,
    fps: Annotated[int, typer.Option(min=1, help="Video frames per simulated second.")] = 30,
    contact_forces: Annotated[
        bool, typer.Option("--contact-forces", help="Draw contact forces in the video.")
    ] = False,
    force: Annotated[
        bool, typer.Option("--force", help="Replace the --out file if it exists.")
    ] = False,
    partial: PartialOption = False,
) -> None:
    """Render a snapshot strip of a run, or with --video an MP4 of it, headless.

    The video follows the pelvis from the side, colours each link, draws disturbance forces
    as red arrows and overlays the time and the controller's state.
    """
    from walkrepro.runtime import outdir

    directory, log = results.resolve_run(run_path)
    if video:
        from walkrepro.present.video import DEFAULT_HEIGHT, DEFAULT_WIDTH, VIDEO_FILE, render_video

        target = outdir.check_file(out or directory / VIDEO_FILE, force, ours=out is None)
        info = render_video(
            log,
            target,
            fps=fps,
            width=width or DEFAULT_WIDTH,
            height=height or DEFAULT_HEIGHT,
            contact_forces=contact_forces,
            partial=partial,
        )
        _console().print(
            f"wrote {info.path} ({info.n_frames} frames, {info.duration:.2f} s at {info.fps} fps)"
        )
        return
    from walkrepro.present.render import render_strip

    try:
        times = [float(x) for x in at.split(",") if x.strip()]
    except ValueError:
        raise WalkreproError(
            f"--at {at!r}: expected comma-separated times in seconds, e.g. 0,2,4."
        ) from None
    target = out or directory / results.FIGURES_DIR / "snapshots.png"
    target = outdir.check_file(target, force, ours=out is None)
    path = render_strip(log, times, target, width or 480, height or 640, partial)
    _console().print(f"wrote {path}")


@app.command()
@friendly_errors
def export(
    run_path: Annotated[Path, typer.Argument(help="Run directory or log.")],
    rerun: Annotated[
        bool,
        typer.Option(
            "--rerun",
            help="A Rerun recording (.rrd): the robot, contact and disturbance arrows, the "
            'paper\'s plots, on simulated time. Needs pip install "walkrepro\\[rerun]".',
        ),
    ] = False,
    out: Annotated[
        Path | None,
        typer.Option(help="Output file (default: the log's name with .rrd: RUN/log.rrd)."),
    ] = None,
    force: Annotated[
        bool, typer.Option("--force", help="Replace the output file if it exists.")
    ] = False,
    partial: PartialOption = False,
) -> None:
    """Export a run's log for another viewer, from the log alone (no re-simulation).

    With --rerun, writes a recording that opens in Rerun (`rerun RUN/log.rrd`) on a 3D view
    of the robot and the plots of its controller; the run's verdict comes along if the run
    directory has one.
    """
    if not rerun:
        raise WalkreproError("export: choose a format: --rerun (the only one so far).")
    from walkrepro.present.rerun_export import export_rerun, import_rerun

    import_rerun()  # the missing SDK is the first thing to say
    directory, log = results.resolve_run(run_path)
    if not log.is_file():
        raise WalkreproError(
            f"{directory}: this run has no {results.LOG_FILE} (see its {results.RUN_FILE}); "
            "there is nothing to export."
        )
    check = directory / results.CHECK_FILE  # the verdict of a run directory's log
    verdict = check if log.name == results.LOG_FILE and check.is_file() else None
    from walkrepro.runtime import outdir

    target = outdir.check_file(out or log.with_suffix(".rrd"), force)
    done = export_rerun(log, target, verdict, force, partial)
    for note in done.skipped:
        _console(stderr=True).print(f"[yellow]skipped:[/] {escape(note)}", highlight=False)
    size = done.path.stat().st_size / 1e6
    _console().print(
        f"wrote {done.path} ({size:.1f} MB: {done.n_poses} poses over {done.duration:.2f} s, "
        f"{len(done.plots)} plots, in {done.seconds:.1f} s); open it with: rerun {done.path}",
        highlight=False,
    )


@app.command()
@friendly_errors
def report(
    source: Annotated[
        Path,
        typer.Option(
            "--from",
            help="results/ (the committed references) or a walkrepro check --out directory.",
        ),
    ] = REFERENCES_DIR,
    out: Annotated[
        Path | None,
        typer.Option(
            help="Site directory, replaced as a whole (default: next to --from, report/): a "
            "new or empty directory or an earlier report; any other is refused unless --force."
        ),
    ] = None,
    force: ForceOption = False,
) -> None:
    """Build the static HTML reproduction report.

    The index shows each paper's robot, headline figure and claims counted, and your own
    runs; a page per paper lists each claim with the paper's value, the measured value and
    the verdict, next to the figures, the video and the maps."""
    from walkrepro.publish.report import build_report

    site = build_report(source, out, force=force)
    for note in site.notes:
        _console(stderr=True).print(f"[yellow]skipped:[/] {escape(note)}", highlight=False)
    for key, t in site.tallies.items():
        registered = key in site.claims and site.claims[key].totals.total > 0
        if registered:
            _console().print(
                f"{key}: the paper's claims: {site.claims[key].totals.claims_text()}",
                highlight=False,
            )
        _console().print(
            f"{key}: {'all ' if registered else ''}rows (maps' claims included): "
            f"{t.reproduced} reproduced, {t.calibrated} calibrated, {t.known} known "
            f"deviations, {t.failed} failed",
            highlight=False,
        )
    _console().print(f"wrote {site.index.as_uri()}", highlight=False)


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


@app.command()
@friendly_errors
@options_from(SweepOptions)
def sweep(options: SweepOptions) -> None:
    """Sweep spec fields over a grid: one run per cell, a cells.csv table and maps.

    Every cell is validated before any runs. Without --grid, runs the spec's declared map.
    """
    from walkrepro.studies.sweep.command import EngineChoice, SweepRequest, sweep_command

    if options.update_reference:
        _needs_checkout("--update-reference")
        _needs_clean_tree("sweep --update-reference", options.allow_dirty)
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
    code = sweep_command(_console(stderr=True), request, engine)
    if code:
        raise typer.Exit(code=code)


@app.command()
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
    specs = [_resolved(n, set_ or []) for n in names]
    before = load_bench(compare) if compare is not None else None

    def announce(spec: ExperimentSpec, round_: int) -> None:
        of = f", run {round_ + 1} of {repeat}" if repeat > 1 else ""
        _console(stderr=True).print(
            f"benchmarking {spec.name} ({spec.sim.duration:g} s simulated{of})…"
        )

    rows = bench_experiments(specs, repeat, on_start=announce)
    # The runner's stages as columns; a controller's own split (``controller.<part>``, which
    # differs per controller) as one column of "part cost" pairs.
    stages = ["physics", "sensors", "controller", "logging", "bookkeeping"]
    table = Table(title="walkrepro bench (per-tick costs in µs)")
    columns = ["experiment", "outcome", "RTF", *(["RTF before"] if before else [])]
    columns += ["× floor", "tick median", "tick p99", "log %", "log MB/s", "mem Δ MB", *stages]
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
            *(f"{r.per_tick.get(k, 0.0) * 1e6:.1f}" for k in stages),
            " ".join(
                f"{k.removeprefix('controller.')} {v * 1e6:.0f}"
                for k, v in r.per_tick.items()
                if k.startswith("controller.")
            ),
        )
    _console().print(table)
    if json_out is not None:
        payload: dict = {"machine": machine_info(), "results": [r.to_json() for r in rows]}
        if compare is not None:
            payload["before"] = json.loads(compare.read_text())
            payload["before"].pop("before", None)  # one level of history is enough
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(json.dumps(payload, indent=2) + "\n")
        _console().print(f"wrote {json_out}")


@app.command()
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
        CALIBRATION_RTOL,
        calibration_papers,
        find_calibration,
        load_calibration,
        with_results,
        write_calibration,
    )
    from walkrepro.studies.calibration.rules import check_consistency
    from walkrepro.studies.calibration.run import CalibrateOptions, calibrate, compare

    if update:
        _needs_checkout("walkrepro calibrate --update")
        _needs_clean_tree("walkrepro calibrate --update", allow_dirty)
    if paper is None:
        _print_calibrations([load_calibration(find_calibration(p)) for p in calibration_papers()])
        return
    loaded = load_calibration(find_calibration(paper))
    check_consistency(loaded)
    options = CalibrateOptions(jobs=jobs, engine=engine, address=address, only=only)
    console = _console()
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
        _console(stderr=True).print(f"interrupted: {loaded.source} is untouched", highlight=False)
        raise typer.Exit(code=received.exit_code) from None
    console.print(_calibration_table(loaded, runs))
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
    _console().print(table)


@app.command("docs")
@friendly_errors
def docs_cmd(
    check_only: Annotated[
        bool,
        typer.Option("--check", help="Write nothing; exit 1 if a generated document is stale."),
    ] = False,
) -> None:
    """Regenerate the generated documents from the specs and the committed results.

    docs/ (the spec reference, the experiments, the known deviations) and the README's
    status table."""
    from walkrepro.publish.docsgen import generated_files, stale_files, write_docs

    _needs_checkout("walkrepro docs")
    files = generated_files()
    if check_only:
        stale = stale_files(files)
        for path in stale:
            _console().print(f"stale: {path} (run walkrepro docs)", highlight=False)
        if stale:
            raise typer.Exit(code=1)
        _console().print(f"{len(files)} generated documents up to date")
        return
    written = write_docs(files)
    for path in written:
        _console().print(f"wrote {path}", highlight=False)
    _console().print(f"{len(files) - len(written)} of {len(files)} already up to date")


# --------------------------------------------------------------------------------------


def _resolved(name: str, overrides: list[str]):  # noqa: ANN202 - returns ExperimentSpec
    from walkrepro.runs.resolve import resolve_spec
    from walkrepro.specs.files import load_spec

    return resolve_spec(load_spec(name, overrides)).spec


def _experiment(name: str, overrides: list[str]):  # noqa: ANN202 - returns Experiment
    """``name`` loaded and resolved once: its spec, robot, compiled scene and parameters."""
    from walkrepro.runs.resolve import resolve
    from walkrepro.specs.files import load_spec

    return resolve(load_spec(name, overrides), overrides)


def _with_reference_video(names: list[str]) -> frozenset[str]:
    """The experiments among ``names`` whose committed reference keeps a video."""
    from walkrepro.locations import REFERENCES_DIR
    from walkrepro.present.video import VIDEO_FILE

    return frozenset(n for n in names if (REFERENCES_DIR / n / VIDEO_FILE).is_file())


def _outputs_of(name: str, outputs: tuple[bool, frozenset[str]]) -> tuple[bool, bool]:
    """(figures, video) for one experiment of a batch."""
    figures, video = outputs
    return figures, name in video


def _run_one(  # noqa: ANN202
    name: str, overrides: list[str], out: Path, outputs: tuple[bool, bool], show_progress: bool
):
    """Resolve and execute one experiment (module-level so a process pool can pickle it).

    ``outputs`` is (figures, video): draw the paper's figures, render the run's video.

    The stop signals (Ctrl-C, SIGTERM) are taken as requests from here on, and the run
    directory is created as soon as the spec is valid, before the slow imports and set-up:
    a stop at any moment after that leaves a run directory with outcome ``interrupted``.
    """
    from walkrepro.runtime import outdir
    from walkrepro.runtime.interrupt import InterruptFlag

    with InterruptFlag() as flag, _compile_watch(name, overrides, show_progress) as watch:
        experiment = _experiment(name, overrides)
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
            return execute(spec, out, None, outputs, overrides, flag, run_dir, experiment)
        with Progress(
            TextColumn(f"[bold]{spec.name}[/]"),
            BarColumn(),
            TextColumn("{task.fields[sim]}"),
            TextColumn("RTF {task.fields[rtf]}"),
            TimeElapsedColumn(),
            console=_console(stderr=True),
            transient=False,
        ) as bar:
            task = bar.add_task("run", total=spec.sim.duration, sim="", rtf="")
            if watch is not None:  # numba's compiling shows in the bar until the first tick
                watch.hand_over(lambda text: bar.update(task, sim=text))

            def progress(t: float, duration: float, rtf: float) -> None:
                if watch is not None and (compiled := watch.finish()) is not None:
                    bar.console.print(compiled, highlight=False)
                bar.update(task, completed=t, sim=f"{t:6.2f}/{duration:.2f} s", rtf=f"{rtf:5.2f}x")

            return execute(spec, out, progress, outputs, overrides, flag, run_dir, experiment)


@contextlib.contextmanager
def _compile_watch(name: str, overrides: list[str], show: bool) -> Iterator[Any]:
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
    with compilenote.CompileWatch(_console(stderr=True), message if cold else None, message) as w:
        yield w


def _plot_comparisons(summaries: list) -> None:  # list[RunSummary]
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


def _print_verdicts(
    verdicts: list,  # list[checks.Verdict]
    details: bool = True,
    per_claim: bool = False,
) -> None:
    """Print a batch's verdicts and the count line ``N reproduced, C calibrated, M known
    deviations, K failed``.

    With ``details``, the table of every row (paper value, measured value and a known
    deviation's observed band side by side). Without, one line per experiment (with
    ``per_claim``, one line per claim: ``walkrepro run``), then the failing rows in full: a
    failure is never hidden.
    """
    from walkrepro.evaluation.checks import FAIL, claim_lines, count, failing_row_text, summary_line

    console = _console()
    if details:
        console.print(_verdict_table(verdicts))
    elif per_claim:
        for v in verdicts:
            for row, text in zip(v.rows, claim_lines(v), strict=True):
                colour = "red" if row.status == FAIL else "default"
                console.print(f"[{colour}]{escape(text)}[/]", highlight=False, soft_wrap=True)
        for v in verdicts:
            for text in failing_row_text(v):
                console.print(f"[red]{escape(text)}[/]", highlight=False, soft_wrap=True)
    else:
        width = max((len(v.experiment) for v in verdicts), default=0)
        for v in verdicts:
            colour = "green" if v.passed else "red"
            console.print(
                f"[{colour}]{escape(summary_line(v, width))}[/]", highlight=False, soft_wrap=True
            )
        for v in verdicts:
            for text in failing_row_text(v):
                console.print(f"[red]{escape(text)}[/]", highlight=False, soft_wrap=True)
    from walkrepro.publish.claim_register import batch_lines

    for line in batch_lines(verdicts):
        console.print(escape(line), highlight=False, soft_wrap=True)
    counts = count(verdicts)
    colour = "red" if counts.failed else ("yellow" if counts.known else "green")
    console.print(f"[bold {colour}]all rows: {counts}[/]")


def _verdict_table(verdicts: list) -> Table:  # list[checks.Verdict]
    """Every row of ``verdicts`` as a table; long sources and notes fold, never cut."""
    from walkrepro.evaluation.checks import CALIBRATED, FAIL, KNOWN, PASS, tag_text

    label = {
        PASS: "[green]reproduced[/]",
        CALIBRATED: "[blue]calibrated[/]",
        FAIL: "[red]failed[/]",
        KNOWN: "[yellow]known deviation[/]",
    }
    table = Table(title="paper expectations")
    columns = ("experiment", "metric", "tests", "paper", "measured", "observed", "result")
    for col in (*columns, "source / note"):
        table.add_column(col, overflow="fold")
    for v in verdicts:
        if not v.run_ok:
            table.add_row(v.experiment, "run", "", "", v.outcome, "", label[FAIL], "")
        for r in v.rows:
            note = f" — {r.note}" if r.note else ""
            table.add_row(
                v.experiment,
                r.metric,
                tag_text(r),
                r.band,
                r.measured_text,
                r.observed_band,
                label[r.status],
                escape(f"{r.source}{note}"),
            )
    return table


def reflow(doc: str) -> str:
    """A docstring as a command's help: its paragraphs with their single line breaks joined.

    typer's rich help keeps a docstring's line breaks, so a paragraph wrapped at the source's
    width would break mid-sentence on any terminal; joined, rich wraps it to the terminal.
    A line that starts a list item (``- ``) keeps its break.
    """
    paragraphs = []
    for paragraph in doc.strip().split("\n\n"):
        lines = [line.strip() for line in paragraph.splitlines()]
        text = lines[0] if lines else ""
        for line in lines[1:]:
            text += ("\n" if line.startswith("- ") else " ") + line
        paragraphs.append(text)
    return "\n\n".join(paragraphs)


def _reflow_help(typer_app: typer.Typer) -> None:
    """Give every command without an explicit help its docstring, reflowed (:func:`reflow`)."""
    import inspect

    for info in typer_app.registered_commands:
        if info.help is None and info.callback is not None:
            info.help = reflow(inspect.getdoc(info.callback) or "")


_reflow_help(app)


def main() -> None:  # pragma: no cover - console entry point alias
    """Entry point for ``python -m walkrepro``."""
    app()
    sys.exit(0)
