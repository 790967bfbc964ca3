"""Calibration files: ``experiments/calibration/<paper>.yaml``, their model and loading.

A calibration file declares, for one paper, the model parameters that no source gives and
that a statement of the paper itself pins (TARGETS.md, Calibration; docs/calibration.md):
for each, the spec path it sets, its range, the quoted criterion, the experiment and
metric(s) that measure it, the target, the search, and the committed result with its
provenance. Parameters are calibrated in the order written.

Loading reports errors as the spec loader does: file, line and field, no traceback.
``walkrepro calibrate --update`` rewrites the file through this model (every authored field
is kept; comments are not, so the file carries none: its ``description`` says why).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from walkrepro.errors import SpecError, UnknownNameError
from walkrepro.locations import EXPERIMENTS_DIR
from walkrepro.specs.models import (
    Count,
    Real,
    _check_plain_data,
    _display_path,
    _format_validation,
    _parse_yaml,
    _where,
    known_paper,
    require_unique,
)

#: Where the shipped calibration files live: ``experiments/calibration/<paper>.yaml``.
CALIBRATION_DIR_NAME = "calibration"
CALIBRATION_DIR = EXPERIMENTS_DIR / CALIBRATION_DIR_NAME
#: Interior points of a root search's round when the file does not say.
DEFAULT_POINTS = 2
#: Most interior points per round (a round is one batch of runs).
MAX_POINTS = 64


class _Strict(BaseModel):
    """Unknown fields are errors: a typo must never be silently ignored."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class Criterion(_Strict):
    """The paper's statement that pins the parameter, quoted.

    ``setup_statement``: a statement about the experiment's set-up ("the robot only bounces
    left and right without any forward or backward progression"). ``identification_procedure``:
    a procedure the paper describes for identifying its own robot ("set the threshold a to
    their standard deviation"). ``disturbance_description``: the paper's description of a
    disturbance it applied (a force's magnitude, where or when a human held); it may pin only
    that disturbance's own parameters (``set`` under ``disturbances.``), never the robot's or
    the controller's. ``result``: a result the paper reports, on which walkrepro chose the
    value by looking (a ``chosen`` search): declared so that the rows it was chosen on count
    calibrated, never reproduced. Every other result the paper reports stays a prediction.
    """

    kind: Literal[
        "setup_statement", "identification_procedure", "disturbance_description", "result"
    ]
    quote: str = Field(min_length=1, description="the paper's words, verbatim")
    section: str = Field(min_length=1, description="where in the paper (section, figure)")


class Target(_Strict):
    """The criterion as a number: the search succeeds when ``|measured - value| <= tolerance``."""

    value: Real = Field(description="the metric's target, in the metric's unit")
    tolerance: Real = Field(gt=0.0, description="largest accepted |measured - value|")


class RootSearch(_Strict):
    """A deterministic bracketing root find of ``metric - target.value`` over the parameter.

    Each round evaluates ``points`` interior points of the bracket (splitting it into
    ``points + 1`` equal parts; the first round also evaluates both ends) and keeps the first
    part whose ends' residuals change sign, until the bracket is narrower than ``xtol``. The
    points are the file's, not the number of jobs': any ``--jobs`` computes the same runs.
    """

    method: Literal["root"]
    bracket: tuple[Real, Real] = Field(description="[low, high] in the parameter's unit")
    xtol: Real = Field(gt=0.0, description="the bracket width at which the search stops")
    points: Count = Field(
        DEFAULT_POINTS,
        ge=1,
        le=MAX_POINTS,
        description="interior points per round (runs per round after the first)",
    )

    @model_validator(mode="after")
    def _ordered(self) -> RootSearch:
        if not self.bracket[0] < self.bracket[1]:
            raise ValueError("a bracket needs [low, high] with low < high")
        return self


class MeasureSearch(_Strict):
    """The parameter's value is the measured metric (a tuple for several metrics): one run."""

    method: Literal["measure"]


class ChosenSearch(_Strict):
    """The value was chosen by walkrepro by looking at the criterion's result, not found by a
    search: one run at ``value`` measures the criterion, which its rows then meet by
    construction (so they count calibrated). Declared so that the choice is visible and
    re-measured, never so that it counts as a prediction."""

    method: Literal["chosen"]
    value: Real | str | tuple[Real, ...] = Field(
        description="the value chosen (a number, a named option, or a tuple such as a solref)"
    )
    how: str = Field(min_length=1, description="how it was chosen, and on which result")


Search = Annotated[RootSearch | MeasureSearch | ChosenSearch, Field(discriminator="method")]
#: A parameter's value: one number, one per metric of a ``measure`` search, or a ``chosen``
#: option's name.
Value = Real | tuple[Real, ...] | str


class Provenance(_Strict):
    """Where a result was computed: the walkrepro commit, the date and the libraries."""

    commit: str
    date: str = Field(description="UTC, ISO 8601")
    mujoco: str
    pinocchio: str
    numpy: str
    python: str


class Result(_Strict):
    """A committed calibration result.

    Attributes:
        value: the parameter's value (what specs' ``{calibrated: NAME}`` resolve to).
        measured: the criterion metric(s) at ``value``.
        evaluations: every ``[parameter, metric]`` a root search evaluated, in order.
        provenance: commit, date and library versions of the calibration run.
    """

    value: Value
    measured: Real | tuple[Real, ...]
    evaluations: list[tuple[Real, Real]] = Field(default_factory=list)
    provenance: Provenance


class Parameter(_Strict):
    """One calibrated parameter (see the module docstring)."""

    name: str = Field(pattern=r"^[A-Za-z_][A-Za-z0-9_]*$", description="what specs refer to")
    set: str = Field(
        pattern=r"^[A-Za-z0-9_]+(\.[A-Za-z0-9_]+)+$",
        description="the spec path the value goes to, as --set writes it",
    )
    unit: str
    range: tuple[Real, Real] | None = Field(
        None, description="[low, high]: a result outside fails (each element of a tuple)"
    )
    criterion: Criterion
    experiment: str = Field(description="the experiment whose run measures the criterion")
    metric: str | None = Field(None, description="the criterion metric (one of metric, metrics)")
    metrics: list[str] | None = Field(None, description="several criterion metrics (measure)")
    rows: list[str] | None = Field(
        None,
        description="the metrics of the experiment's rows that state the criterion, marked "
        "calibrated: NAME (default: metric or metrics); e.g. a measured value's rows compare "
        "the measurement with the calibrated value",
    )
    target: Target | None = Field(None, description="required by a root search")
    search: Search
    result: Result | None = Field(None, description="written by walkrepro calibrate --update")

    @model_validator(mode="after")
    def _consistent(self) -> Parameter:
        if (self.metric is None) == (self.metrics is None):
            raise ValueError("give exactly one of metric and metrics")
        if self.metrics is not None and (
            not self.metrics or len(set(self.metrics)) != len(self.metrics)
        ):
            raise ValueError("metrics needs at least one metric, none repeated")
        if self.rows is not None and (not self.rows or len(set(self.rows)) != len(self.rows)):
            raise ValueError("rows needs at least one metric, none repeated")
        if self.range is not None and not self.range[0] <= self.range[1]:
            raise ValueError("range needs [low, high] with low <= high")
        if isinstance(self.search, RootSearch):
            if self.target is None:
                raise ValueError("a root search needs a target: {value: ..., tolerance: ...}")
            if self.metric is None:
                raise ValueError("a root search finds the root of one metric: give metric")
            lo, hi = self.search.bracket
            if self.range is not None and not self.range[0] <= lo < hi <= self.range[1]:
                raise ValueError("the search bracket must lie inside range")
        elif self.target is not None:
            raise ValueError(
                f"a {self.search.method} search takes no target: its value is "
                + ("the measured one" if self.search.method == "measure" else "the chosen one")
            )
        if self.criterion.kind == "disturbance_description" and not self.set.startswith(
            "disturbances."
        ):
            raise ValueError(
                "a disturbance_description criterion pins only the disturbance's own "
                "parameters (set: disturbances.N.FIELD), never the robot's or the controller's"
            )
        if (self.criterion.kind == "result") != isinstance(self.search, ChosenSearch):
            raise ValueError(
                "a value chosen by looking at a result (search method chosen) declares that "
                "result as its criterion (kind: result), and only such a value does"
            )
        return self

    @property
    def criterion_metrics(self) -> tuple[str, ...]:
        """The metric or metrics that measure the criterion."""
        return (self.metric,) if self.metric is not None else tuple(self.metrics or ())

    @property
    def criterion_rows(self) -> tuple[str, ...]:
        """The metrics of the rows counted ``calibrated`` for this parameter."""
        return tuple(self.rows) if self.rows is not None else self.criterion_metrics


class CalibrationFile(_Strict):
    """One paper's declared calibration: its parameters, calibrated in order."""

    paper: str = Field(description="paper key, as the specs' paper.key")
    description: str
    parameters: list[Parameter] = Field(min_length=1)

    @field_validator("paper")
    @classmethod
    def _known_paper(cls, key: str) -> str:
        return known_paper(key)

    @field_validator("parameters")
    @classmethod
    def _unique(cls, parameters: list[Parameter]) -> list[Parameter]:
        require_unique("parameter", [p.name for p in parameters])
        return parameters

    def parameter(self, name: str) -> Parameter:
        """The parameter called ``name``.

        Raises:
            UnknownNameError: listing the file's parameters.
        """
        for p in self.parameters:
            if p.name == name:
                return p
        raise UnknownNameError("calibration parameter", name, [p.name for p in self.parameters])


class LoadedCalibration(BaseModel):
    """A validated calibration file plus where it came from, so errors can cite lines."""

    model_config = ConfigDict(arbitrary_types_allowed=True, frozen=True)

    model: CalibrationFile
    path: Path
    source: str
    lines: dict[tuple[Any, ...], int]

    def where(self, path: Sequence[Any]) -> str:
        """``file, line N, field a.b.c`` for a field path (nearest known line)."""
        return _where(self.source, self.lines, tuple(path))

    def index(self, name: str) -> int:
        """The position of parameter ``name`` in the file."""
        return [p.name for p in self.model.parameters].index(name)

    @property
    def experiments_dir(self) -> Path:
        """The directory of the specs the file's experiments name (the file's parent's)."""
        return self.path.parent.parent


def calibration_path(paper: str, directory: Path | None = None) -> Path:
    """The calibration file of ``paper`` in ``directory`` (default the shipped one)."""
    return (directory or CALIBRATION_DIR) / f"{paper}.yaml"


def calibration_papers(directory: Path | None = None) -> list[str]:
    """The papers that have a calibration file in ``directory`` (default the shipped one)."""
    return sorted(p.stem for p in (directory or CALIBRATION_DIR).glob("*.yaml"))


def find_calibration(paper: str, directory: Path | None = None) -> Path:
    """The calibration file of ``paper``.

    Raises:
        UnknownNameError: no such file; lists the papers that have one.
    """
    path = calibration_path(paper, directory)
    if not path.is_file():
        raise UnknownNameError(
            "calibrated paper", paper, calibration_papers(directory), "walkrepro calibrate"
        )
    return path


def load_calibration(path: Path) -> LoadedCalibration:
    """Parse and validate a calibration file.

    Raises:
        SpecError: naming file, line and field for any problem.
    """
    source = _display_path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SpecError(f"{source}: cannot read the calibration file ({exc.strerror}).") from None
    except UnicodeDecodeError:
        raise SpecError(f"{source}: not UTF-8 text; save the file as UTF-8.") from None
    data, lines = _parse_yaml(text, source)
    _check_plain_data(data, source, lines, ())
    try:
        model = CalibrationFile.model_validate(data)
    except ValidationError as exc:
        text = _format_validation(exc, source, lines, ())
        for tag in ("root", "measure"):  # the search's discriminator is no field
            text = text.replace(f".search.{tag}", ".search")
        raise SpecError(text) from None
    loaded = LoadedCalibration(model=model, path=path, source=source, lines=lines)
    if model.paper != path.stem:
        raise SpecError(
            f"{loaded.where(('paper',))}: the file of paper {model.paper!r} must be named "
            f"{model.paper}.yaml (it is {path.name})."
        )
    for i, p in enumerate(model.parameters):
        for value in _elements(p.result.value if p.result else None):
            if p.range is not None and not p.range[0] <= value <= p.range[1]:
                raise SpecError(
                    f"{loaded.where(('parameters', i, 'result', 'value'))}: {value!r} lies "
                    f"outside the parameter's range [{p.range[0]:g}, {p.range[1]:g}]."
                )
    return loaded


def _elements(value: Any) -> tuple[float, ...]:
    if value is None:
        return ()
    return tuple(value) if isinstance(value, tuple | list) else (value,)


def with_results(model: CalibrationFile, results: dict[str, Result]) -> CalibrationFile:
    """``model`` with the results of some of its parameters replaced."""
    parameters = [
        p.model_copy(update={"result": results[p.name]}) if p.name in results else p
        for p in model.parameters
    ]
    return model.model_copy(update={"parameters": parameters})


def dump_calibration(model: CalibrationFile) -> str:
    """The file's YAML: every authored field as written (defaults left out where the author
    left them out), results in full precision (``repr`` floats: they read back bit for bit)."""
    data = model.model_dump(mode="json", exclude_unset=True)
    for p, dumped in zip(model.parameters, data["parameters"], strict=True):
        dumped["result"] = None if p.result is None else p.result.model_dump(mode="json")
    return yaml.dump(data, Dumper=_Dumper, sort_keys=False, allow_unicode=True, width=88)


class _Dumper(yaml.SafeDumper):
    """Short lists of numbers in flow style (``[0.0, 0.03]``), long text folded (``>-``)."""


def _list(dumper: yaml.SafeDumper, data: list) -> yaml.Node:
    flow = all(isinstance(x, int | float | str) for x in data) and len(data) <= 8
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow or None)


def _text(dumper: yaml.SafeDumper, data: str) -> yaml.Node:
    style = ">" if len(data) > 80 and "\n" not in data and data == data.strip() else None
    return dumper.represent_scalar("tag:yaml.org,2002:str", data, style=style)


_Dumper.add_representer(list, _list)
_Dumper.add_representer(str, _text)


def write_calibration(path: Path, model: CalibrationFile) -> None:
    """Write ``model`` to ``path`` atomically (a temporary file renamed over it), after
    checking that the text reads back as the same model."""
    text = dump_calibration(model)
    data, _ = _parse_yaml(text, str(path))
    if CalibrationFile.model_validate(data) != model:  # pragma: no cover - a bug if reached
        raise AssertionError("the calibration file would not read back as written")
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


#: Relative tolerance within which a re-run calibration reproduces its committed result: the
#: same spec and seed give the same bits on one machine, but another machine's MuJoCo,
#: NumPy or BLAS build moves the last digits (as it moves the references' metrics, which are
#: compared by tolerance too).
CALIBRATION_RTOL = 1e-6


def close_value(a: Any, b: Any, rtol: float = CALIBRATION_RTOL) -> bool:
    """Equality of two values within ``rtol`` (relative, with an absolute floor of ``rtol``
    times 1e-6 for values at zero); a chosen option's name by equality; NaN never equal."""
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    xa, xb = _elements(a), _elements(b)
    if isinstance(a, tuple | list) != isinstance(b, tuple | list) or len(xa) != len(xb):
        return False
    return all(
        not (math.isnan(u) or math.isnan(v))
        and math.isclose(u, v, rel_tol=rtol, abs_tol=rtol * 1e-6)
        for u, v in zip(xa, xb, strict=True)
    )


# --------------------------------------------------------------------------------------
# A robot's calibrated values (experiments/calibration/robots/<robot>.yaml)

#: Where a robot's declaration of its calibrated values lives.
ROBOT_CALIBRATION_DIR = CALIBRATION_DIR / "robots"


class DeclaredValue(_Strict):
    """One calibrated value of a robot's experiments, declared with its criterion.

    A robot ledger entry (``ledger``: its name in ``robots/<robot>/parameters.yaml``) or a
    value its specs set (``set``: the dotted spec path, e.g. ``controller.params.footstep_scale``),
    with the value in force, the paper's statement or result it was chosen on (the kinds of
    :class:`Criterion`) and how it was chosen. Unlike a paper's calibration file these are
    not re-run by ``walkrepro calibrate``: a robot's values are built into its ``robot.xml``,
    and the ablation specs' values were chosen once, on the model's outcomes; the
    declaration makes each visible and tested against the ledger.
    """

    name: str = Field(pattern=r"^[A-Za-z_][A-Za-z0-9_]*$")
    ledger: str | None = Field(None, description="the robot ledger entry it is")
    set: str | None = Field(None, description="the spec path it is set at")
    value: Any = Field(description="the value in force")
    unit: str
    criterion: Criterion
    how: str = Field(min_length=1, description="how it was chosen, and on which result")

    @model_validator(mode="after")
    def _one_place(self) -> DeclaredValue:
        if (self.ledger is None) == (self.set is None):
            raise ValueError(
                "give exactly one of ledger (a robot ledger entry) and set (a spec path)"
            )
        return self


class RobotCalibrationFile(_Strict):
    """A robot's declared calibrated values."""

    robot: str
    description: str
    values: list[DeclaredValue] = Field(min_length=1)

    @field_validator("values")
    @classmethod
    def _unique(cls, values: list[DeclaredValue]) -> list[DeclaredValue]:
        require_unique("declared value", [v.name for v in values])
        return values


def robot_calibration(robot: str, directory: Path | None = None) -> RobotCalibrationFile | None:
    """The declaration ``<directory>/<robot>.yaml`` (default the shipped one), or None.

    Raises:
        SpecError: naming file, line and field for any problem.
    """
    path = (directory or ROBOT_CALIBRATION_DIR) / f"{robot}.yaml"
    if not path.is_file():
        return None
    source = _display_path(path)
    data, lines = _parse_yaml(path.read_text(encoding="utf-8"), source)
    _check_plain_data(data, source, lines, ())
    try:
        model = RobotCalibrationFile.model_validate(data)
    except ValidationError as exc:
        raise SpecError(_format_validation(exc, source, lines, ())) from None
    if model.robot != robot:
        raise SpecError(
            f"{_where(source, lines, ('robot',))}: the file of robot {model.robot!r} must be "
            f"named {model.robot}.yaml (it is {path.name})."
        )
    return model
