"""Where the report reads an experiment's result: a committed reference or a check run.

Two layouts are recognised under the source directory:

- references (``results/``): ``<experiment>/check.json``, ``figures/``, ``video.mp4``,
  ``log.rrd`` (a Rerun recording, where ``walkrepro export --rerun`` wrote one);
- a ``walkrepro check --out DIR`` tree: ``<experiment>/<run>/check.json`` (the latest run
  of each experiment is used), with the run's ``spec.yaml``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from walkrepro.errors import UnknownNameError, WalkreproError
from walkrepro.runs import results
from walkrepro.specs.files import load_spec
from walkrepro.specs.models import ExperimentSpec, spec_from_yaml_text

#: Figure files the report shows, in order of preference for the full-size link.
FIGURE_SUFFIXES = (".png", ".svg")
#: The video's file name in a run directory or a reference (as :data:`walkrepro.present.video.VIDEO_FILE`,
#: repeated so that building a report never imports MuJoCo's renderer).
VIDEO_FILE = "video.mp4"
#: The Rerun recording's file name, as ``walkrepro export --rerun`` writes it in a run directory.
RECORDING_FILE = "log.rrd"


@dataclass(frozen=True)
class ExperimentResult:
    """One experiment's result as the report sees it.

    Attributes:
        name: the experiment.
        spec: its spec (the run's own ``spec.yaml`` where there is one, else the shipped spec).
        check: the parsed ``check.json`` (``outcome``, ``rows``, ``counts``).
        directory: the reference or run directory.
        figures: the figure images (PNG), sorted by name.
        video: the run's MP4, if any.
        run: the parsed ``run.json`` (``{}`` if absent).
        recording: the run's Rerun recording (``log.rrd``), if one was exported.
    """

    name: str
    spec: ExperimentSpec
    check: dict
    directory: Path
    figures: tuple[Path, ...]
    video: Path | None
    run: dict
    recording: Path | None = None


def find_results(source: Path) -> tuple[list[ExperimentResult], list[str]]:
    """Every experiment result under ``source``, sorted by name, and notes on what was
    skipped (a directory whose experiment is no longer shipped and has no ``spec.yaml``).

    Raises:
        WalkreproError: ``source`` is not a directory, or holds no result at all.
    """
    if not source.is_dir():
        raise WalkreproError(f"{source}: no such directory (give results/ or a check --out DIR).")
    found, skipped = [], []
    for child in sorted(p for p in source.iterdir() if p.is_dir()):
        directory = _result_directory(child)
        if directory is None:
            continue
        try:
            found.append(_read(child.name, directory))
        except UnknownNameError:
            skipped.append(f"{child.name}: no shipped spec and no spec.yaml (skipped)")
    if not found:
        raise WalkreproError(
            f"{source}: no experiment results (expected <experiment>/{results.CHECK_FILE} as in "
            f"results/, or <experiment>/<run>/{results.CHECK_FILE} as written by walkrepro check)."
        )
    return found, skipped


def _result_directory(child: Path) -> Path | None:
    """The directory holding ``check.json`` for this experiment folder, if any."""
    if (child / results.CHECK_FILE).is_file():
        return child
    runs = [r for r in results.runs(child.parent, child.name) if (r / results.CHECK_FILE).is_file()]
    return runs[-1] if runs else None


def _read(name: str, directory: Path) -> ExperimentResult:
    """Read one result directory."""
    spec_file = directory / results.SPEC_FILE
    spec = (
        spec_from_yaml_text(spec_file.read_text(), str(spec_file))
        if spec_file.is_file()
        else load_spec(name).spec
    )
    check_file = directory / results.CHECK_FILE
    try:
        check = json.loads(check_file.read_text())
    except json.JSONDecodeError as exc:
        raise WalkreproError(
            f"{check_file}, line {exc.lineno}: not valid JSON ({exc.msg})."
        ) from None
    run_file = directory / results.RUN_FILE
    run = json.loads(run_file.read_text()) if run_file.is_file() else {}
    figure_dir = directory / results.FIGURES_DIR
    figures = tuple(sorted(figure_dir.glob("*.png"))) if figure_dir.is_dir() else ()
    video, recording = directory / VIDEO_FILE, directory / RECORDING_FILE
    return ExperimentResult(
        name,
        spec,
        check,
        directory,
        figures,
        video if video.is_file() else None,
        run,
        recording if recording.is_file() else None,
    )
