"""What every ``walkrepro`` command shares: the console, the user-error wrapper, the
options several commands take, and the guards of the commands that write committed files."""

from __future__ import annotations

import dataclasses
import functools
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, TypeVar

import typer
from rich.console import Console
from rich.markup import escape

from walkrepro.errors import WalkreproError
from walkrepro.runs import results

if TYPE_CHECKING:
    from walkrepro.specs.models import ExperimentSpec


def make_console(stderr: bool = False) -> Console:
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


def needs_checkout(what: str) -> None:
    """Refuse to write the repository's own files (references, calibration, docs) from an
    installed walkrepro: they live in a clone (walkrepro/locations.py)."""
    from walkrepro.locations import IS_CHECKOUT

    if not IS_CHECKOUT:
        raise WalkreproError(
            f"{what} writes the repository's committed files, and this walkrepro is an "
            "installed copy; run it from a clone with `pip install -e .`."
        )


def needs_clean_tree(what: str, allow_dirty: bool) -> None:
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
            make_console(stderr=True).print(
                f"[bold red]error:[/] {escape(str(exc))}", highlight=False, soft_wrap=True
            )
            raise typer.Exit(code=exc.exit_code) from None
        except KeyboardInterrupt:  # Ctrl-C outside a run (a run keeps its own directory)
            make_console(stderr=True).print("interrupted")
            raise typer.Exit(code=130) from None

    return wrapper  # type: ignore[return-value]


def resolved_spec(name: str, overrides: list[str]) -> ExperimentSpec:
    """The spec of experiment ``name`` with ``overrides``, loaded and checked against the
    registries and its parameters validated (:func:`walkrepro.runs.resolve.resolve_spec`)."""
    from walkrepro.runs.resolve import resolve_spec
    from walkrepro.specs.files import load_spec

    return resolve_spec(load_spec(name, overrides)).spec


def print_missing(run_dir: Path, stages: dict[str, str], signum: int | None = None) -> None:
    """On stderr: which stage a stop interrupted, and each output the run lacks (its
    ``run.json`` records the same)."""
    import signal

    console = make_console(stderr=True)
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


def complete_experiment(incomplete: str) -> list[str]:
    """Shell completion: the experiments whose names start with ``incomplete``."""
    from walkrepro.specs.files import all_experiment_names

    return [n for n in all_experiment_names() if n.startswith(incomplete)]
