"""Where walkrepro finds its robots, experiments and committed references, and where runs go.

Two layouts, told apart by what sits beside the package (stdlib only, read at import):

- **A checkout** (a clone, with ``pip install -e .``): ``robots/``, ``experiments/`` and
  ``results/`` are the repository's own. ``results/`` holds the committed references and,
  under ``results/runs/``, new runs.
- **An installed package** (``pip install .`` or a wheel): the robots, the experiment specs,
  their calibration files and the committed references (each experiment's metrics, verdict
  and run record, each map's cells) ship inside the package as ``walkrepro/_shipped/``
  (``setup.py`` maps the repository's folders there). New runs go to ``./results`` under the
  directory walkrepro is started from.

A user's own folder of specs (``walkrepro --experiments DIR``, or ``$WALKREPRO_EXPERIMENTS``)
is searched before the shipped experiments: its names are what ``walkrepro check`` runs by
default, and a shipped experiment is still found by its name.
"""

from __future__ import annotations

import os
from pathlib import Path

#: The environment variable that names a user's folder of specs (set by ``--experiments``,
#: and so inherited by the worker processes of ``--jobs`` and of a Ray sweep).
USER_EXPERIMENTS_ENV = "WALKREPRO_EXPERIMENTS"

_PACKAGE_DIR = Path(__file__).resolve().parent
_CHECKOUT = _PACKAGE_DIR.parent
_SHIPPED = _PACKAGE_DIR / "_shipped"

#: True when walkrepro runs from a clone of its repository (not from an installed copy).
IS_CHECKOUT = (_CHECKOUT / "pyproject.toml").is_file() and (_CHECKOUT / "experiments").is_dir()

if IS_CHECKOUT:
    #: The repository root (a checkout), else the working directory walkrepro started in.
    PROJECT_ROOT = _CHECKOUT
    ROBOTS_DIR = _CHECKOUT / "robots"
    #: The shipped experiment specs (``experiments/<name>.yaml``, ``calibration/<paper>.yaml``).
    EXPERIMENTS_DIR = _CHECKOUT / "experiments"
    #: The committed references: ``<experiment>/metrics.json``, ``maps/<map>/cells.csv``, ...
    REFERENCES_DIR = _CHECKOUT / "results"
    #: Where new runs, sweeps and updated references are written.
    RESULTS_DIR = _CHECKOUT / "results"
else:
    PROJECT_ROOT = Path.cwd()
    ROBOTS_DIR = _SHIPPED / "robots"
    EXPERIMENTS_DIR = _SHIPPED / "experiments"
    REFERENCES_DIR = _SHIPPED / "references"
    RESULTS_DIR = Path.cwd() / "results"


def user_experiments_dir() -> Path | None:
    """The user's folder of specs named by ``--experiments`` / ``$WALKREPRO_EXPERIMENTS``."""
    value = os.environ.get(USER_EXPERIMENTS_ENV)
    return Path(value) if value else None


def experiment_dirs() -> list[Path]:
    """Folders searched for ``<name>.yaml``, first match wins: the user's, then the shipped."""
    user = user_experiments_dir()
    return [user, EXPERIMENTS_DIR] if user is not None else [EXPERIMENTS_DIR]
