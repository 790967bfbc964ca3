"""The ``walkrepro`` command line: list, run, check, plot, verify, render, export, calibrate.

Thin by design: parse arguments, call the library, print. A user error (bad spec, unknown
name, unwritable directory) prints one paragraph and exits with code 2, no traceback.

This module is the typer app, the process set-up at start and the registration of the
commands; each group of commands is a module of this package:

- :mod:`~walkrepro.cli.listing`: ``list``;
- :mod:`~walkrepro.cli.registers`: ``provenance``, ``claims``, ``report``, ``docs``;
- :mod:`~walkrepro.cli.running`: ``run``, ``check`` (with :mod:`~walkrepro.cli.batch`, which
  runs the experiments, and :mod:`~walkrepro.cli.verdicts`, which prints their verdicts);
- :mod:`~walkrepro.cli.logs`: ``plot``, ``verify``, ``render``, ``export``;
- :mod:`~walkrepro.cli.studies`: ``sweep``, ``bench``;
- :mod:`~walkrepro.cli.calibration`: ``calibrate``;
- :mod:`~walkrepro.cli.common`: what they share (console, errors, options, guards).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Annotated, Any

import typer

from walkrepro.cli import calibration, listing, logs, registers, running, studies


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


# The commands, in the order ``walkrepro --help`` lists them.
app.command("list")(listing.list_cmd)
app.command()(registers.provenance)
app.command()(registers.claims)
app.command()(running.run)
app.command()(running.check)
app.command()(logs.plot)
app.command()(logs.verify)
app.command()(logs.render)
app.command()(logs.export)
app.command()(registers.report)
app.command()(studies.sweep)
app.command()(studies.bench)
app.command()(calibration.calibrate)
app.command("docs")(registers.docs_cmd)


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
