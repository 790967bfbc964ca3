"""Where a run came from: versions, git commit, seed, start time (the log's metadata)."""

from __future__ import annotations

import subprocess
from datetime import datetime, timezone
from functools import lru_cache
from typing import TYPE_CHECKING

from walkrepro._version import __version__
from walkrepro.locations import IS_CHECKOUT, PROJECT_ROOT

if TYPE_CHECKING:
    from walkrepro.specs.models import ExperimentSpec


@lru_cache(maxsize=1)
def git_commit() -> str:
    """Commit of the checkout walkrepro runs from, ``+dirty`` when the files that decide a
    run's numbers (:data:`RESULT_INPUTS`: the package, the robots, the specs, the build) have
    uncommitted changes, or ``unknown`` (an installed copy has no commit; the version says
    which walkrepro it is). Uncommitted results (``results/``) or docs do not make it dirty."""
    if not IS_CHECKOUT:
        return "unknown"
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=PROJECT_ROOT,
            capture_output=True,
            text=True,
            timeout=5,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    if not commit:
        return "unknown"
    return commit + ("+dirty" if dirty_paths(RESULT_INPUTS) else "")


#: The files whose uncommitted changes make a run's provenance ``+dirty`` and make the
#: commands that write committed results refuse (``--allow-dirty`` overrides).
RESULT_INPUTS: tuple[str, ...] = (
    "walkrepro",
    "robots",
    "experiments",
    "pyproject.toml",
    "setup.py",
)


def dirty_paths(folders: tuple[str, ...]) -> list[str]:
    """Files under ``folders`` of the checkout with uncommitted changes (tracked files only;
    empty in an installed copy or where git cannot tell)."""
    if not IS_CHECKOUT:
        return []
    try:
        out = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", *folders],
            cwd=PROJECT_ROOT,
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout
    except (OSError, subprocess.SubprocessError):
        return []
    return [line[3:] for line in out.splitlines() if line.strip()]


def pinocchio_version() -> str:
    """Pinocchio's version string."""
    import pinocchio

    return str(pinocchio.__version__)


def library_versions() -> dict[str, str]:
    """The versions of the libraries a run's numbers depend on (physics, dynamics, arrays,
    compiled kernels) and of Python: floating-point results can differ between them in the
    last digits, which contact chaos can grow."""
    import platform

    import mujoco
    import numba
    import numpy

    return {
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
        "pinocchio": pinocchio_version(),
        "numpy": numpy.__version__,
        "numba": numba.__version__,
    }


def utc_now() -> datetime:
    """Now, in UTC."""
    return datetime.now(timezone.utc)


def run_metadata(spec: ExperimentSpec) -> dict[str, str]:
    """The ``walkrepro`` metadata record of a log (outcome is added when the log closes)."""
    import mujoco

    return {
        "version": __version__,
        "git_commit": git_commit(),
        "mujoco_version": mujoco.__version__,
        "pinocchio_version": pinocchio_version(),
        "seed": str(spec.sim.seed),
        "experiment": spec.name,
        "start_time": utc_now().isoformat(timespec="seconds"),
    }
