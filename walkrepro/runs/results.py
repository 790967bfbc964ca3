"""Run directories: ``<root>/<experiment>/<UTC timestamp>-<short id>/``.

A run is written into a hidden temporary directory and renamed to its final name when it
ends, whatever the outcome, so a run never overwrites another and a half-written run is
never mistaken for a finished one. The outcome is recorded in ``run.json``.
"""

from __future__ import annotations

import json
import os
import secrets
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

from walkrepro.errors import WalkreproError
from walkrepro.locations import RESULTS_DIR
from walkrepro.runs.provenance import utc_now

DEFAULT_ROOT = RESULTS_DIR / "runs"
SPEC_FILE, LOG_FILE, METRICS_FILE, CHECK_FILE, RUN_FILE, FIGURES_DIR = (
    "spec.yaml",
    "log.mcap",
    "metrics.json",
    "check.json",
    "run.json",
    "figures",
)


@dataclass(frozen=True)
class RunDir:
    """A run directory being written (``work``) and its final name (``final``)."""

    work: Path
    final: Path

    def finish(self) -> Path:
        """Move the run to its final name; returns it."""
        os.replace(self.work, self.final)
        return self.final


#: A post-simulation stage's status in ``run.json``'s ``stages``.
COMPLETED, INTERRUPTED, FAILED = "completed", "interrupted", "failed"
#: ... not yet begun; begun and not ended (the process died in it: its output is missing).
PENDING, STARTED = "pending", "started"
#: ... not run because the run was stopped before it; not asked for (``--no-figures``);
#: no OpenGL backend here (the video).
SKIPPED, NOT_REQUESTED, UNAVAILABLE = "skipped", "not requested", "unavailable"
#: The post-simulation stages, in order, and the output each one writes.
STAGE_OUTPUTS = {"metrics": "metrics.json", "figures": "figures/", "video": "video.mp4"}


class Stages:
    """The post-simulation stages of a run and their status: ``run.json``'s ``stages``
    (``{"metrics": "completed", "figures": "not requested", "video": "interrupted"}``).

    The run rewrites ``run.json`` as each stage begins (``started``) and ends, so the record
    is true after any stop: Ctrl-C, SIGTERM, even a kill in the middle of a stage (which
    leaves ``started``).
    """

    def __init__(self, figures: bool, video: bool) -> None:
        self.record: dict[str, str] = {
            "metrics": PENDING,
            "figures": PENDING if figures else NOT_REQUESTED,
            "video": PENDING if video else NOT_REQUESTED,
        }

    def set(self, name: str, status: str) -> None:
        """Record ``status`` for the stage ``name``."""
        self.record[name] = status


def missing_outputs(record: dict) -> list[str]:
    """What a run was asked for and does not have, from its ``run.json`` (``record``): e.g.
    ``["video.mp4 (the video stage was interrupted)"]``; empty for a run recorded before
    stages were."""
    stages = record.get("stages")
    if not isinstance(stages, dict):
        return []
    return [
        f"{STAGE_OUTPUTS.get(name, name)} (the {name} stage "
        + {
            STARTED: "began and never ended",
            PENDING: "never ran",
            SKIPPED: "was skipped: the run was stopped before it",
            UNAVAILABLE: "could not run: no OpenGL backend",
        }.get(status, f"was {status}")
        + ")"
        for name, status in stages.items()
        if status not in (COMPLETED, NOT_REQUESTED)
    ]


def read_record(run_dir: Path) -> dict:
    """A run directory's ``run.json`` ({} when it has none or it is unreadable)."""
    try:
        data = json.loads((run_dir / RUN_FILE).read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def new_run_dir(root: Path, experiment: str) -> RunDir:
    """Create a fresh working directory for a run of ``experiment`` under ``root``.

    Raises:
        WalkreproError: if ``root`` cannot be created or written.
    """
    parent = root / experiment
    try:
        parent.mkdir(parents=True, exist_ok=True)
        stamp = utc_now().strftime("%Y%m%dT%H%M%SZ")
        for _ in range(100):
            name = f"{stamp}-{secrets.token_hex(3)}"
            final = parent / name
            work = parent / f".{name}.partial"
            if not final.exists() and not work.exists():
                work.mkdir()
                return RunDir(work=work, final=final)
    except OSError as exc:
        raise WalkreproError(
            f"cannot write run outputs under {root}: {exc.strerror or exc}. "
            "Choose a writable directory with --out DIR."
        ) from None
    raise WalkreproError(f"could not find a free run directory name under {parent}")


def abandon(run_dir: RunDir, spec_yaml: str, experiment: str, outcome: str, message: str) -> Path:
    """Give a run that never started its ``spec.yaml``, its ``run.json`` (``outcome`` and
    ``message``) and its final name; returns the final directory. Never leaves the
    directory hidden."""
    try:
        (run_dir.work / SPEC_FILE).write_text(spec_yaml)
        write_json(
            run_dir.work / RUN_FILE,
            {"experiment": experiment, "outcome": outcome, "message": message},
        )
    finally:
        final = run_dir.finish()
    return final


def write_json(path: Path, data: object) -> None:
    """Write JSON with a trailing newline (NaN written as null)."""
    path.write_text(json.dumps(_nan_to_none(data), indent=2) + "\n")


class SavedMetrics(NamedTuple):
    """A ``metrics.json``: values (None where not measurable) and the reasons."""

    values: dict[str, float | None]
    reasons: dict[str, str]


def write_metrics(path: Path, values: dict[str, float], reasons: dict[str, str]) -> None:
    """Write ``metrics.json``: ``{"metrics": {name: value or null}, "not_measurable":
    {name: reason}}``; every null value has its reason."""
    why = {
        name: reasons.get(name, "the metric gave no value") for name, v in values.items() if v != v
    }
    write_json(path, {"metrics": values, "not_measurable": why})


def read_metrics(path: Path) -> SavedMetrics:
    """Read a ``metrics.json`` written by :func:`write_metrics`.

    Raises:
        WalkreproError: if the file is not such a record.
    """
    try:
        data = json.loads(path.read_text())
        if "metrics" not in data:  # written before reasons existed: a flat name -> value map
            return SavedMetrics({k: v for k, v in data.items() if not isinstance(v, dict)}, {})
        return SavedMetrics(dict(data["metrics"]), dict(data.get("not_measurable", {})))
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise WalkreproError(f"{path}: not a walkrepro metrics.json ({exc}).") from None


def _nan_to_none(x: object) -> object:
    if isinstance(x, float) and x != x:
        return None
    if isinstance(x, dict):
        return {k: _nan_to_none(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_nan_to_none(v) for v in x]
    return x


def resolve_run(path: Path) -> tuple[Path, Path]:
    """A run directory or a log file -> (run directory, log path).

    A run stopped before its log was opened has a ``run.json`` and no log: its directory
    and the log path it would have are returned (the log path does not exist).

    Raises:
        WalkreproError: if neither a run directory with ``log.mcap`` or ``run.json`` nor a
            log file.
    """
    if path.is_dir():
        log = path / LOG_FILE
        if not log.is_file() and not (path / RUN_FILE).is_file():
            raise WalkreproError(f"{path}: not a run directory (no {LOG_FILE} inside).")
        return path, log
    if path.is_file():
        return path.parent, path
    raise WalkreproError(f"{path}: no such run directory or log file.")


def save_reference(run_dir: Path) -> Path:
    """Copy a run's metrics, verdict, run record and PNG figures to ``results/<experiment>/``.

    The committed reference of an experiment (logs stay out of git). Old PNGs are removed
    first so the reference holds exactly this run's figures.
    """
    experiment = run_dir.parent.name
    target = RESULTS_DIR / experiment
    (target / FIGURES_DIR).mkdir(parents=True, exist_ok=True)
    for old in (target / FIGURES_DIR).glob("*.png"):
        old.unlink()
    for name in (METRICS_FILE, CHECK_FILE, RUN_FILE):
        if (run_dir / name).is_file():
            shutil.copy2(run_dir / name, target / name)
    for png in (run_dir / FIGURES_DIR).glob("*.png"):
        shutil.copy2(png, target / FIGURES_DIR / png.name)
    return target


def runs(root: Path, experiment: str) -> list[Path]:
    """Finished runs of ``experiment`` under ``root``, oldest first (names sort by time)."""
    parent = root / experiment
    return sorted(p for p in parent.glob("*") if p.is_dir() and not p.name.startswith("."))


def latest_run(root: Path, experiment: str) -> Path | None:
    """The most recent finished run of ``experiment`` under ``root``, if any."""
    found = runs(root, experiment)
    return found[-1] if found else None


def recorded_overrides(run_dir: Path) -> list[str]:
    """The ``--set`` overrides a run was made with (its ``run.json``; none if unrecorded)."""
    record = run_dir / RUN_FILE
    if not record.is_file():
        return []
    return list(json.loads(record.read_text()).get("overrides", []))
