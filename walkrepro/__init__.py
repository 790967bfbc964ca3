"""walkrepro: reproduce published biped-walking controllers in MuJoCo and check the result.

The library API (:mod:`walkrepro.api`), importable without side effects: importing walkrepro
sets no environment variable, installs no signal handler and imports neither MuJoCo nor
numpy; the ``walkrepro`` command does its own set-up (:func:`walkrepro.cli.command_setup`).

Example::

    import walkrepro

    exp = walkrepro.load("stand_dyros_red", {"sim.duration": 0.5})
    run = walkrepro.run(exp)          # simulate, log, measure, check: a new run directory
    run.metrics["pelvis_drift"]       # [m], computed from the log
    walkrepro.evaluate(run.run_dir)   # re-check the log later: the same verdict
"""

from walkrepro._version import __version__  # noqa: F401
from walkrepro.api import Experiment, evaluate, load, run  # noqa: E402, F401

# Where the robots, experiments and references are, and where runs go: a checkout's own
# folders, or the installed package's shipped copies and ./results (see locations.py;
# stdlib only).
from walkrepro.locations import (  # noqa: E402, F401
    EXPERIMENTS_DIR,
    IS_CHECKOUT,
    PROJECT_ROOT,
    REFERENCES_DIR,
    RESULTS_DIR,
    ROBOTS_DIR,
)

__all__ = ["Experiment", "Run", "evaluate", "load", "run", "__version__"]


def __getattr__(name: str) -> object:
    """``walkrepro.Run``, what :func:`run` returns (:class:`walkrepro.runs.experiment.RunSummary`),
    imported when first asked for: its module imports MuJoCo and numpy."""
    if name == "Run":
        from walkrepro.runs.experiment import RunSummary

        return RunSummary
    raise AttributeError(f"module 'walkrepro' has no attribute {name!r}")
