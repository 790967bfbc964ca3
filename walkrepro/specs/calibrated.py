"""Specs and calibration files: ``{calibrated: NAME}`` references and ``calibrated:`` rows.

The spec loader (:func:`walkrepro.specs.files.load_spec`) calls these for a spec that mentions
calibration:

- :func:`resolve_references` replaces each mapping ``{calibrated: NAME}`` (after the
  ``--set`` overrides, so an override still wins) by the committed ``result.value`` of
  parameter NAME in the paper's calibration file; a list becomes a tuple where the field
  expects one (the models coerce it). Specs thus never copy calibrated numbers.
- :func:`check_marks` checks that each expectation marked ``calibrated: NAME`` is a
  criterion of NAME, so a row counted ``calibrated`` really was the calibration's target.

The paper's calibration file is ``calibration/<paper.key>.yaml`` beside the spec when there
is one (a folder of specs with its own calibration, as the tests build), else the shipped
``experiments/calibration/<paper.key>.yaml``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from walkrepro.errors import SpecError, UnknownNameError
from walkrepro.specs.calibration_files import (
    CALIBRATION_DIR,
    CALIBRATION_DIR_NAME,
    LoadedCalibration,
    calibration_papers,
    load_calibration,
)

if TYPE_CHECKING:
    from walkrepro.specs.models import LoadedSpec

#: ``where(path)`` → ``file, line N, field a.b.c`` of a spec field.
Where = Callable[[tuple[Any, ...]], str]


@dataclass(frozen=True)
class Withheld:
    """A calibrated value a run may not see, and why. ``walkrepro calibrate`` withholds the
    parameters calibrated after the one it runs, and a ``measure``'s own value from the run
    that measures it: a result that depended on them could not be reproduced. A withheld
    reference that is a mapping's entry is left out, so the field takes its model's default
    (the code's, the same on every run); elsewhere (a list item) it is an error."""

    reason: str


def calibration_for(spec_path: Path, paper: str) -> Path:
    """The calibration file a spec at ``spec_path`` of ``paper`` uses (may not exist)."""
    beside = spec_path.parent / CALIBRATION_DIR_NAME / f"{paper}.yaml"
    return beside if beside.is_file() else CALIBRATION_DIR / f"{paper}.yaml"


def references(data: Any, path: tuple[Any, ...] = ()) -> Iterator[tuple[tuple[Any, ...], Any]]:
    """Every ``{calibrated: NAME}`` mapping in ``data``: ``(field path, NAME)``."""
    stack: list[tuple[tuple[Any, ...], Any]] = [(path, data)]
    seen: set[int] = set()
    while stack:
        where, node = stack.pop()
        if isinstance(node, dict):
            if list(node) == ["calibrated"]:
                yield where, node["calibrated"]
                continue
            if id(node) in seen:
                continue
            seen.add(id(node))
            stack.extend(((*where, k), v) for k, v in reversed(list(node.items())))
        elif isinstance(node, list):
            if id(node) in seen:
                continue
            seen.add(id(node))
            stack.extend(((*where, i), v) for i, v in reversed(list(enumerate(node))))


def resolve_references(
    data: dict[str, Any], spec_path: Path, where: Where, context: Mapping[str, Any]
) -> None:
    """Replace every ``{calibrated: NAME}`` in ``data`` (in place).

    Args:
        data: the spec's parsed YAML, overrides applied.
        spec_path: the spec file (its paper's calibration file is looked for beside it).
        where: names file, line and field of a spec path.
        context: values that take the place of committed results, by name (an
            :class:`Unavailable` refuses the reference with its reason).

    Raises:
        SpecError / UnknownNameError: at the reference's file, line and field.
    """
    found = list(references(data))
    if not found:
        return
    calibration: LoadedCalibration | None = None
    for field_path, name in found:
        at = where(field_path)
        if not isinstance(name, str):
            raise SpecError(f"{at}: {{calibrated: NAME}} needs a parameter name (got {name!r}).")
        if name in context:
            value = context[name]
            if isinstance(value, Withheld):
                parent = _get(data, field_path[:-1])
                if not isinstance(parent, dict):
                    raise SpecError(f"{at}: calibrated value {name!r} is {value.reason}")
                del parent[field_path[-1]]
                continue
        else:
            if calibration is None:
                calibration = _calibration_of(data, spec_path, at)
            value = committed_value(calibration, name, at)
        _set(data, field_path, list(value) if isinstance(value, tuple) else value)


def committed_value(calibration: LoadedCalibration, name: str, at: str) -> Any:
    """The committed ``result.value`` of parameter ``name``.

    Raises:
        UnknownNameError: no such parameter; SpecError: it has no result yet.
    """
    names = [p.name for p in calibration.model.parameters]
    if name not in names:
        raise UnknownNameError(
            "calibrated parameter", name, names, f"{at} (looked up in {calibration.source})"
        ) from None
    parameter = calibration.model.parameters[names.index(name)]
    if parameter.result is None:
        raise SpecError(
            f"{at}: calibrated value {name!r} has no result yet in {calibration.source} "
            f"(result: null); run walkrepro calibrate {calibration.model.paper} --update."
        )
    return parameter.result.value


def _calibration_of(data: dict[str, Any], spec_path: Path, at: str) -> LoadedCalibration:
    """The calibration file of the spec's paper, or an error at the reference ``at``."""
    from walkrepro.plugins import papers

    paper = data.get("paper")
    key = paper.get("key") if isinstance(paper, dict) else None
    if not isinstance(key, str) or key not in papers():
        raise SpecError(
            f"{at}: a calibrated value is looked up in the calibration file of the spec's "
            f"paper, but paper.key is {key!r}; valid papers: {', '.join(sorted(papers()))}."
        )
    path = calibration_for(spec_path, key)
    if not path.is_file():
        raise SpecError(
            f"{at}: paper {key!r} has no calibration file ({path.name} in "
            f"experiments/{CALIBRATION_DIR_NAME}/; papers with one: "
            f"{', '.join(calibration_papers()) or 'none'}); see docs/calibration.md."
        )
    return load_calibration(path)


def _get(data: Any, path: tuple[Any, ...]) -> Any:
    node = data
    for part in path:
        node = node[part]
    return node


def _set(data: Any, path: tuple[Any, ...], value: Any) -> None:
    _get(data, path[:-1])[path[-1]] = value


def check_marks(loaded: LoadedSpec, spec_path: Path) -> None:
    """Each expectation marked ``calibrated: NAME`` must be a criterion row of parameter
    NAME: NAME's experiment is this spec and the row's metric is one of NAME's ``rows``
    (by default its metric or metrics).

    Raises:
        SpecError / UnknownNameError: at the row's ``calibrated`` field.
    """
    spec = loaded.spec
    marked = [(i, e) for i, e in enumerate(spec.expect) if e.calibrated is not None]
    if not marked:
        return
    path = calibration_for(spec_path, spec.paper.key)
    for i, e in marked:
        at = loaded.where(("expect", i, "calibrated"))
        if not path.is_file():
            raise SpecError(
                f"{at}: the row is marked calibrated, but paper {spec.paper.key!r} has no "
                f"calibration file ({path.name} in experiments/{CALIBRATION_DIR_NAME}/)."
            )
        calibration = load_calibration(path)
        names = [p.name for p in calibration.model.parameters]
        if e.calibrated not in names:
            raise UnknownNameError(
                "calibrated parameter",
                str(e.calibrated),
                names,
                f"{at} (looked up in {calibration.source})",
            )
        parameter = calibration.model.parameters[names.index(str(e.calibrated))]
        if parameter.experiment != spec.name or e.metric not in parameter.criterion_rows:
            criteria = ", ".join(f"{parameter.experiment} · {m}" for m in parameter.criterion_rows)
            raise SpecError(
                f"{at}: the row {spec.name} · {e.metric} is marked calibrated: {e.calibrated}, "
                f"but it is not a criterion of {e.calibrated!r} in {calibration.source} "
                f"(its criterion: {criteria}); a row is calibrated only if the calibration "
                "targeted it."
            )
