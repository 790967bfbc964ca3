"""The rules a calibration file and the specs must keep between them (docs/calibration.md).

Checked by ``walkrepro calibrate`` before anything runs, and by the tests over the shipped
files. The rules the spec loader can check on one spec (a row marked ``calibrated: NAME``
is a criterion of NAME; a row is not both calibrated and a known deviation) live with it
(:mod:`walkrepro.specs.calibrated`, :class:`walkrepro.specs.models.Expectation`).

For each parameter of the file, in order:

1. its experiment exists;
2. every criterion row (``rows``, by default the metric or metrics) is an expectation of
   that experiment marked ``calibrated: NAME``:
   a claim used as a criterion is not also checked as a reproduction (an unmarked row is a
   checked claim and is refused), and a criterion must be visible as a row;
3. its ``set`` path exists (a field of the controller's parameter model for
   ``controller.params.X``; a field of the spec's models otherwise);
4. a root search's experiment uses the calibrated value: ``{calibrated: NAME}`` at ``set``;
5. a chosen value (kind ``result``) is the value its experiment runs with.

A criterion run never sees a parameter calibrated after it, nor a ``measure`` the value it
measures: ``walkrepro calibrate`` leaves those references out, so the fields take their
defaults (:class:`~walkrepro.specs.calibrated.Withheld`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import BaseModel

from walkrepro.errors import SpecError, UnknownNameError
from walkrepro.specs.calibration_files import ChosenSearch, LoadedCalibration, Parameter, RootSearch


def check_consistency(loaded: LoadedCalibration) -> None:
    """Check rules 1-4 for every parameter of ``loaded``.

    Raises:
        SpecError / UnknownNameError: naming the calibration file's (or the spec's) file,
            line and field.
    """
    for i, parameter in enumerate(loaded.model.parameters):
        spec_path, data, where = _spec_of(loaded, i, parameter)
        _check_rows(loaded, i, parameter, data, where)
        _check_set_path(loaded, i, parameter, data)
        _check_reference(loaded, i, parameter, data)
        _check_chosen(loaded, i, parameter, data)


def _spec_of(loaded: LoadedCalibration, i: int, parameter: Parameter) -> tuple[Path, Any, Any]:
    """The criterion experiment's file, its raw data, and its ``where(path)``."""
    from walkrepro.specs.models import _parse_yaml, _where

    directory = loaded.experiments_dir
    path = directory / f"{parameter.experiment}.yaml"
    if not path.is_file():
        names = sorted(p.stem for p in directory.glob("*.yaml"))
        raise UnknownNameError(
            "experiment", parameter.experiment, names, loaded.where(("parameters", i, "experiment"))
        )
    from walkrepro.specs.models import _display_path

    source = _display_path(path)
    data, lines = _parse_yaml(path.read_text(encoding="utf-8"), source)

    def where(field_path: tuple[Any, ...]) -> str:
        return _where(source, lines, field_path)

    return path, data, where


def _check_rows(
    loaded: LoadedCalibration, i: int, parameter: Parameter, data: Any, where: Any
) -> None:
    """Rule 2: each criterion metric is a row of the experiment marked calibrated: NAME."""
    rows = data.get("expect") or []
    key = "rows" if parameter.rows is not None else "metric" if parameter.metric else "metrics"
    for j, metric in enumerate(parameter.criterion_rows):
        at = loaded.where(("parameters", i, key) if key == "metric" else ("parameters", i, key, j))
        matches = [
            (k, row)
            for k, row in enumerate(rows)
            if isinstance(row, dict) and row.get("metric") == metric
        ]
        if not matches:
            raise SpecError(
                f"{at}: the criterion {parameter.experiment} · {metric} is no expectation of "
                f"{parameter.experiment}; a criterion must be visible as a row marked "
                f"calibrated: {parameter.name} (docs/calibration.md)."
            )
        for k, row in matches:
            mark = row.get("calibrated")
            if mark is None:
                raise SpecError(
                    f"{at}: the criterion names a checked claim: {where(('expect', k))} "
                    f"({parameter.experiment} · {metric}) is a row without calibrated: "
                    f"{parameter.name}. A claim used as a criterion is not also checked as a "
                    f"reproduction: mark the row calibrated: {parameter.name}, or choose "
                    "another criterion."
                )
            if mark != parameter.name:
                raise SpecError(
                    f"{where(('expect', k, 'calibrated'))}: the row is marked calibrated: "
                    f"{mark}, but it is the criterion of {parameter.name!r} "
                    f"({loaded.where(('parameters', i, 'name'))})."
                )


def _check_set_path(loaded: LoadedCalibration, i: int, parameter: Parameter, data: Any) -> None:
    """Rule 3: the ``set`` path names a field of the spec (or of the controller's params)."""
    from walkrepro.specs.models import ExperimentSpec

    at = loaded.where(("parameters", i, "set"))
    parts = parameter.set.split(".")
    if parts[:2] == ["controller", "params"]:
        from walkrepro.controllers import controller_class, controller_names

        controller = (data.get("controller") or {}).get("type")
        if controller not in controller_names():
            raise UnknownNameError("controller", str(controller), controller_names(), at)
        fields = controller_class(controller).Params.model_fields
        if len(parts) != 3 or parts[2] not in fields:
            raise UnknownNameError(
                f"parameter of controller {controller!r}", ".".join(parts[2:]), fields, at
            )
        return
    model: Any = ExperimentSpec
    for part in parts:
        if not (isinstance(model, type) and issubclass(model, BaseModel)):
            return  # a dict, list or tuple field: its items are the spec's own to check
        if part not in model.model_fields:
            raise UnknownNameError("spec field", part, model.model_fields, at)
        model = model.model_fields[part].annotation


def _check_reference(loaded: LoadedCalibration, i: int, parameter: Parameter, data: Any) -> None:
    """Rule 4: a root search's experiment uses the value being found."""
    if isinstance(parameter.search, RootSearch):
        node = _at_path(data, parameter.set)
        if node != {"calibrated": parameter.name}:
            raise SpecError(
                f"{loaded.where(('parameters', i, 'set'))}: the criterion experiment "
                f"{parameter.experiment} does not use the calibrated value: give "
                f"{parameter.set}: {{calibrated: {parameter.name}}} in its spec (it has "
                f"{node!r}), so that its rows check the value the calibration found."
            )


def _check_chosen(loaded: LoadedCalibration, i: int, parameter: Parameter, data: Any) -> None:
    """Rule 5: a chosen value is the one the criterion experiment runs with (its spec's value,
    its ``{calibrated: NAME}`` mark, or the controller's default it leaves in place)."""
    if not isinstance(parameter.search, ChosenSearch):
        return
    node = _at_path(data, parameter.set)
    if node == {"calibrated": parameter.name}:
        return
    parts = parameter.set.split(".")
    if node is None and parts[:2] == ["controller", "params"] and len(parts) == 3:
        from walkrepro.controllers import controller_class

        controller = (data.get("controller") or {}).get("type")
        field = controller_class(controller).Params.model_fields[parts[2]]
        node = field.get_default(call_default_factory=True)
    if isinstance(node, list):
        node = tuple(node)
    if node != parameter.search.value:
        raise SpecError(
            f"{loaded.where(('parameters', i, 'search', 'value'))}: the chosen value "
            f"{parameter.search.value!r} is not the one {parameter.experiment} runs with "
            f"({parameter.set} = {node!r}); the declaration must describe the model in force."
        )


def _at_path(data: Any, dotted: str) -> Any:
    """The raw spec's value at a ``set`` path (a list's items by index), or None."""
    node: Any = data
    for part in dotted.split("."):
        if isinstance(node, dict):
            node = node.get(part)
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        else:
            return None
    return node
