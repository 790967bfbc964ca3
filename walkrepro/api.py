"""The library API: :func:`load` an experiment, :func:`run` it, :func:`evaluate` a log.

The same steps as ``walkrepro run`` and ``walkrepro check --run``, from Python, on the same
code: :func:`load` is the CLI's spec loading and resolution
(:func:`walkrepro.specs.files.load_spec`, :func:`~walkrepro.runs.resolve.resolve`),
:func:`run` is :func:`walkrepro.runs.experiment.execute` (simulation, log, metrics and verdict
from the log, figures), :func:`evaluate` is :func:`walkrepro.runs.experiment.evaluate_log`.

Importing this module (and ``walkrepro``) imports neither MuJoCo, numpy nor numba, sets no
environment variable and installs no signal handler. :func:`load` points numba's on-disk
cache at walkrepro's source-keyed directory before the first kernel compiles
(:func:`walkrepro.runtime.numbacache.install`, through ``numba.config``, not the environment). A
:func:`run` takes Ctrl-C as a request to stop while it runs (the log is closed, the run
directory kept, marked ``interrupted``) and puts the caller's handlers back when it ends.

Example::

    import walkrepro

    exp = walkrepro.load("stand_dyros_red", {"sim.duration": 0.5})
    exp.params                      # the controller's typed parameters
    exp.scene.model.opt.timestep    # the compiled scene [s]
    done = walkrepro.run(exp)       # results/runs/stand_dyros_red/<stamp>/
    done.metrics["pelvis_drift"]    # [m]
    done.verdict.passed
"""

from __future__ import annotations

import functools
import json
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from walkrepro.runs.resolve import Experiment

if TYPE_CHECKING:
    from walkrepro.evaluation.checks import Verdict
    from walkrepro.runs.experiment import RunSummary

#: Overrides as ``--set`` takes them (``"sim.duration=0.5"``), or as a mapping from the
#: dotted field to its value (``{"sim.duration": 0.5}``).
Overrides = Sequence[str] | Mapping[str, Any] | None


@functools.cache
def _library_setup() -> None:
    """What the library needs before MuJoCo and the first kernel load, once per process:
    MuJoCo imported with no GL backend bound (physics needs none, and a ``MUJOCO_GL`` naming
    a missing library must not stop it), numba's cache in walkrepro's source-keyed directory
    through ``numba.config`` (a kernel that inlines an edited helper recompiles). The
    environment is left as it was."""
    from walkrepro.runtime import gl, numbacache

    gl.import_mujoco()
    numbacache.install(environ=False)


def _override_strings(overrides: Overrides) -> tuple[str, ...]:
    """``overrides`` as ``--set`` strings; a mapping's values are written as JSON (which is
    YAML, what ``--set`` parses), so ``{"sim.duration": 0.5}`` is ``sim.duration=0.5``."""
    if overrides is None:
        return ()
    if isinstance(overrides, str):
        return (overrides,)
    if isinstance(overrides, Mapping):
        return tuple(f"{key}={json.dumps(value)}" for key, value in overrides.items())
    return tuple(str(item) for item in overrides)


def load(name_or_path: str | Path, overrides: Overrides = None) -> Experiment:
    """Load, override, validate and resolve an experiment, as ``walkrepro run`` does.

    Args:
        name_or_path: an experiment name (``forward_walk``) or a spec file's path.
        overrides: ``["sim.duration=0.5"]`` or ``{"sim.duration": 0.5}``; the dotted path of
            a spec field and its value.

    Raises:
        walkrepro.errors.WalkreproError: an unknown name, or a spec error naming the file,
            line and field (a ``SpecError``).
    """
    _library_setup()
    from walkrepro.runs.resolve import resolve
    from walkrepro.specs.files import load_spec
    from walkrepro.specs.models import API_OVERRIDES, overrides_named

    strings = _override_strings(overrides)
    with overrides_named(API_OVERRIDES):  # the caller typed no --set
        return resolve(load_spec(name_or_path, strings), strings)


def run(
    experiment: Experiment | str | Path,
    overrides: Overrides = None,
    *,
    out: str | Path | None = None,
    figures: bool = False,
    progress: Callable[[float, float, float], None] | None = None,
) -> RunSummary:
    """Run an experiment headless into a new run directory: log, metrics, verdict (and the
    paper's figures with ``figures=True``), as ``walkrepro run`` does.

    Args:
        experiment: a loaded :class:`Experiment`, or a name or path to :func:`load`.
        overrides: with a name or path: the overrides to load it with.
        out: root of run directories (default ``results/runs``, as the CLI's ``--out``).
        figures: draw the paper's figures into the run's ``figures/``.
        progress: called as ``progress(sim_time [s], duration [s], real-time factor)`` a few
            times per second.

    Returns:
        The finished run (:class:`walkrepro.runs.experiment.RunSummary`): ``run_dir``,
        ``log_path``, ``outcome``, ``metrics``, ``verdict``; ``interrupted`` when Ctrl-C
        stopped it.

    Raises:
        walkrepro.errors.WalkreproError: as :func:`load`; an exception inside the run is
            re-raised once its run directory records it.
    """
    from walkrepro.runs import results
    from walkrepro.runs.experiment import execute

    if not isinstance(experiment, Experiment):
        experiment = load(experiment, overrides)
    elif overrides:
        raise TypeError("run(experiment, overrides): give the overrides to load() instead.")
    return execute(
        experiment.spec,
        Path(out) if out is not None else results.DEFAULT_ROOT,
        progress=progress,
        outputs=figures,
        overrides=experiment.overrides,
        resolved=experiment,
    )


def evaluate(run_or_log: RunSummary | str | Path, *, partial: bool = False) -> Verdict:
    """Recompute a run's metrics and verdict from its log alone, as ``walkrepro check
    --run`` does, and rewrite its ``metrics.json`` and ``check.json``.

    Args:
        run_or_log: a run from :func:`run`, a run directory, or a ``log.mcap``.
        partial: use a cut or damaged log for what it holds (the verdict's outcome is then
            ``partial``); without it such a log is refused.

    Returns:
        The verdict (:class:`walkrepro.evaluation.checks.Verdict`): ``passed``, ``rows`` (claim, paper
        value, measured value, ``status`` as ``check.json`` stores it, ``word`` as the CLI
        says it: reproduced, calibrated, known deviation, failed), ``outcome``;
        ``print(verdict)`` prints it as ``walkrepro run`` does.

    Raises:
        walkrepro.errors.WalkreproError: not a run, run directory or log; a log that is
            cut or damaged, without ``partial``
            (:class:`walkrepro.log.integrity.DamagedLogError`, naming what it holds).
    """
    import os

    from walkrepro.errors import WalkreproError

    _library_setup()  # a metric may compile a kernel
    from walkrepro.runs import results
    from walkrepro.runs.experiment import References, RunSummary, evaluate_log

    if not isinstance(run_or_log, RunSummary | str | os.PathLike):
        raise WalkreproError(
            f"walkrepro.evaluate({run_or_log!r}): give a run (what walkrepro.run returns), a "
            f"run directory or a log.mcap path, not a {type(run_or_log).__name__}."
        )
    path = run_or_log.run_dir if isinstance(run_or_log, RunSummary) else Path(run_or_log)
    directory, log = results.resolve_run(path)
    # Partners of relative expectations: runs with the same overrides beside this one
    # (<root>/<experiment>/<run>), else the committed references.
    made_with = results.recorded_overrides(directory)
    lookup = References(overrides=made_with, search_root=directory.parent.parent)
    return evaluate_log(log, directory, lookup, partial)[1]
