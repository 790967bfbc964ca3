"""Running a declared calibration on the sweep engine, and comparing with the committed one.

Parameters are calibrated in the file's order. Each candidate is one run of the parameter's
experiment with the candidate set through ``--set``'s path (``parameter.set``), so the
spec's own ``{calibrated: NAME}`` there is replaced; the parameters calibrated before it in
this call take their new values, not the committed ones; those after it may not be used
(:class:`~walkrepro.specs.calibrated.Withheld`: their references are left out, so
those fields take their defaults). A batch of candidates is a batch
of sweep cells (:mod:`walkrepro.studies.sweep.engines`): the engine and ``jobs`` only schedule, so
the result is the same on any engine and with any number of jobs.
"""

from __future__ import annotations

import math
import shutil
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from walkrepro.errors import UnknownNameError
from walkrepro.specs.calibrated import Withheld
from walkrepro.specs.calibration_files import (
    ChosenSearch,
    LoadedCalibration,
    MeasureSearch,
    Parameter,
    Provenance,
    Result,
    RootSearch,
    close_value,
)
from walkrepro.studies.calibration.search import (
    CalibrationFailed,
    Evaluator,
    RootProblem,
    SearchResult,
    find_root,
    measure,
    measure_at,
)
from walkrepro.studies.sweep.engines import Engine

#: Makes the evaluator of one parameter: ``(parameter, calibrated values) -> Evaluator``.
EvaluatorFactory = Callable[[Parameter, Mapping[str, Any]], Evaluator]


@dataclass(frozen=True)
class CalibrateOptions:
    """How to run a calibration.

    Attributes:
        jobs: parallel runs (worker processes or Ray CPUs).
        engine: ``process`` or ``ray`` (as ``walkrepro sweep --engine``).
        address: an existing Ray cluster (with ``engine="ray"``).
        only: calibrate this parameter alone (the others keep their committed results).
    """

    jobs: int = 1
    engine: str = "process"
    address: str | None = None
    only: str | None = None


@dataclass(frozen=True)
class ParameterRun:
    """One parameter calibrated now.

    Attributes:
        parameter: the parameter as the file declares it.
        result: the new result (provenance of this call).
        wall_time: the search's wall time [s].
    """

    parameter: Parameter
    result: Result
    wall_time: float

    @property
    def runs(self) -> int:
        """Runs the search made."""
        return len(self.result.evaluations) or 1


def calibrate(
    loaded: LoadedCalibration,
    options: CalibrateOptions,
    factory: EvaluatorFactory | None = None,
    on_done: Callable[[ParameterRun], None] | None = None,
) -> list[ParameterRun]:
    """Calibrate the parameters of ``loaded`` in order (or ``options.only``).

    Args:
        loaded: the calibration file.
        options: engine, jobs and which parameter.
        factory: makes each parameter's evaluator (default: runs on the sweep engine; the
            tests give a fake one).
        on_done: called as each parameter finishes.

    Raises:
        CalibrationFailed: a search missed its target (nothing is returned then).
        UnknownNameError: ``options.only`` names no parameter.
    """
    names = [p.name for p in loaded.model.parameters]
    if options.only is not None and options.only not in names:
        raise UnknownNameError(
            "calibration parameter", options.only, names, f"--only ({loaded.source})"
        )
    make = factory or EngineEvaluators(loaded, options).make
    provenance = current_provenance()
    values: dict[str, Any] = {}
    done = []
    for i, parameter in enumerate(loaded.model.parameters):
        if options.only is not None and parameter.name != options.only:
            continue
        context: dict[str, Any] = {**values}
        for later in names[i + 1 :]:
            context[later] = Withheld(
                f"calibrated after {parameter.name!r}, whose criterion runs may not use it "
                "(a result that depended on a later one could not be reproduced)"
            )
        if isinstance(parameter.search, MeasureSearch):
            context[parameter.name] = Withheld(
                "measured by this run, which may not use it (it would depend on itself)"
            )
        t0 = time.perf_counter()
        found = search(parameter, make(parameter, context))
        _check_range(loaded, i, parameter, found)
        result = Result(
            value=found.value,
            measured=found.measured,
            evaluations=list(found.evaluations),
            provenance=provenance,
        )
        values[parameter.name] = found.value
        run = ParameterRun(parameter, result, time.perf_counter() - t0)
        done.append(run)
        if on_done is not None:
            on_done(run)
    return done


def search(parameter: Parameter, evaluate: Evaluator) -> SearchResult:
    """Run ``parameter``'s declared search with ``evaluate``."""
    if isinstance(parameter.search, RootSearch):
        assert parameter.target is not None and parameter.metric is not None  # the model's rule
        s = parameter.search
        problem = RootProblem(
            parameter.metric,
            parameter.target.value,
            parameter.target.tolerance,
            s.bracket,
            s.xtol,
            s.points,
        )
        try:
            return find_root(problem, evaluate)
        except CalibrationFailed as exc:
            raise CalibrationFailed(f"{parameter.name}: {exc}") from None
    try:
        if isinstance(parameter.search, ChosenSearch):
            return measure_at(parameter.search.value, parameter.criterion_metrics, evaluate)
        return measure(parameter.criterion_metrics, evaluate)
    except CalibrationFailed as exc:
        raise CalibrationFailed(f"{parameter.name}: {exc}") from None


def _check_range(
    loaded: LoadedCalibration, i: int, parameter: Parameter, found: SearchResult
) -> None:
    if parameter.range is None:
        return
    if isinstance(found.value, str):
        return  # a chosen option has no range
    lo, hi = parameter.range
    values = found.value if isinstance(found.value, tuple) else (found.value,)
    outside = [v for v in values if not lo <= v <= hi]
    if outside:
        raise CalibrationFailed(
            f"{parameter.name}: the value {found.value!r} lies outside the declared range "
            f"[{lo:g}, {hi:g}] ({loaded.where(('parameters', i, 'range'))})."
        )


def current_provenance() -> Provenance:
    """The commit, date and library versions of this process."""
    from walkrepro.runs.provenance import git_commit, library_versions, utc_now

    versions = library_versions()
    return Provenance(
        commit=git_commit(),
        date=utc_now().isoformat(timespec="seconds"),
        mujoco=versions["mujoco"],
        pinocchio=versions["pinocchio"],
        numpy=versions["numpy"],
        python=versions["python"],
    )


@dataclass(frozen=True)
class Difference:
    """Where a new result differs from the committed one.

    Attributes:
        name: the parameter.
        what: ``no committed result``, or the fields that differ.
    """

    name: str
    what: str


def compare(loaded: LoadedCalibration, runs: Sequence[ParameterRun]) -> list[Difference]:
    """The parameters whose new value or measurement differs from the committed one by more
    than :data:`~walkrepro.specs.calibration_files.CALIBRATION_RTOL` (relative)."""
    out = []
    for run in runs:
        committed = loaded.model.parameter(run.parameter.name).result
        if committed is None:
            out.append(Difference(run.parameter.name, "no committed result (result: null)"))
            continue
        fields = [
            f"{key}: committed {getattr(committed, key)!r}, now {getattr(run.result, key)!r}"
            for key in ("value", "measured")
            if not close_value(getattr(committed, key), getattr(run.result, key))
        ]
        if fields:
            out.append(Difference(run.parameter.name, "; ".join(fields)))
    return out


class EngineEvaluators:
    """Evaluators that run candidates as sweep cells on the engine of ``options``.

    Args:
        loaded: the calibration file (its experiments are specs beside its folder).
        options: engine, jobs, Ray address.
        engine: an engine to use instead (the tests give one whose cells are fake).
    """

    def __init__(
        self, loaded: LoadedCalibration, options: CalibrateOptions, engine: Engine | None = None
    ) -> None:
        from walkrepro.studies.sweep.engines import make_engine

        self.loaded = loaded
        self.engine = engine or make_engine(options.engine, options.jobs, options.address)
        self.batches = 0

    def make(self, parameter: Parameter, context: Mapping[str, Any]) -> Evaluator:
        """The evaluator of ``parameter``'s candidates, with ``context``'s values."""

        def evaluate(candidates: Sequence[float | None]) -> list[Mapping[str, float]]:
            return self.run(parameter, context, candidates)

        return evaluate

    def run(
        self,
        parameter: Parameter,
        context: Mapping[str, Any],
        candidates: Sequence[float | None],
    ) -> list[Mapping[str, float]]:
        """Run one batch; every candidate's spec is resolved (validated) before any runs.

        Raises:
            CalibrationFailed: a run broke (error, crashed worker) or was interrupted.
        """
        from walkrepro.runs.resolve import resolve_spec
        from walkrepro.specs.files import load_spec
        from walkrepro.studies.sweep.cells import CellTask
        from walkrepro.studies.sweep.grid import value_text

        spec_path = self.loaded.experiments_dir / f"{parameter.experiment}.yaml"
        work = Path(tempfile.mkdtemp(prefix="walkrepro-calibrate-"))
        self.batches += 1
        tasks = []
        try:
            for k, x in enumerate(candidates):
                overrides = [] if x is None else [f"{parameter.set}={value_text(x)}"]
                values = dict(context) if x is None else {**context, parameter.name: x}
                spec = resolve_spec(load_spec(spec_path, overrides, calibrated=values)).spec
                spec = spec.model_copy(update={"sweeps": [], "sweep_parameters": {}})
                tasks.append(
                    CellTask(k, spec, work / f"cell-{k}", False, parameter.criterion_metrics)
                )
            results = {r.index: r for r in self.engine.run(tasks)}
        finally:
            shutil.rmtree(work, ignore_errors=True)
        out = []
        for k, x in enumerate(candidates):
            r = results[k]
            if r.outcome not in ("complete", "fell"):
                at = "" if x is None else f" at {x!r}"
                raise CalibrationFailed(
                    f"{parameter.name}: the run of {parameter.experiment}{at} ended "
                    f"{r.outcome}: {r.message}"
                )
            missing = [m for m in parameter.criterion_metrics if not _finite(r.metrics.get(m))]
            if missing:
                at = "" if x is None else f" at {x!r}"
                fall = f" at {r.fall_time:.2f} s" if math.isfinite(r.fall_time) else ""
                raise CalibrationFailed(
                    f"{parameter.name}: the run of {parameter.experiment}{at} ended "
                    f"{r.outcome}{fall} and gives no value of {', '.join(missing)}; the search "
                    "needs a measurable criterion over the whole bracket."
                )
            out.append(r.metrics)
        return out


def _finite(value: float | None) -> bool:
    return value is not None and math.isfinite(value)
