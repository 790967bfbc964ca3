"""Experiment specs as files: finding them by name and loading them.

:mod:`walkrepro.specs.models` is the data model and its YAML reading (a leaf: it imports no other
part of walkrepro that could import it back). This module puts a spec file through the whole
chain: the file found by name (the user's folder from ``--experiments DIR``, then the
shipped ``experiments/``, see :mod:`walkrepro.locations`), ``--set`` overrides, the declared
calibration's committed results (:mod:`walkrepro.specs.calibrated`), and the schema.
Checking the names against the registries (robot, controller and its parameter model,
metrics, bodies, obstacles against the robot's home pose) needs the simulation, so it is
:func:`walkrepro.runs.resolve.resolve_spec`, one floor up.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from walkrepro import locations
from walkrepro.errors import SpecError, UnknownNameError
from walkrepro.specs.models import (
    ExperimentSpec,
    LoadedSpec,
    _apply_override,
    _check_across_sections,
    _check_plain_data,
    _display_path,
    _format_validation,
    _parse_yaml,
    _where,
)


def shipped_experiment_names() -> list[str]:
    """Names of the experiments shipped in ``experiments/``."""
    return sorted(p.stem for p in locations.EXPERIMENTS_DIR.glob("*.yaml"))


def experiment_names() -> list[str]:
    """Names of the experiments ``walkrepro check`` runs by default: those in the user's
    folder (``--experiments DIR``) when one is given, else the shipped ones."""
    user = locations.user_experiments_dir()
    return sorted(p.stem for p in user.glob("*.yaml")) if user else shipped_experiment_names()


def all_experiment_names() -> list[str]:
    """Every name an experiment can be found by: the user's folder's and the shipped."""
    return sorted({p.stem for d in locations.experiment_dirs() for p in d.glob("*.yaml")})


def find_spec_file(name_or_path: str) -> Path:
    """An experiment name (``NAME.yaml`` in the user's folder, else in the shipped
    ``experiments/``) or a path to any spec file."""
    looks_like_path = name_or_path.endswith((".yaml", ".yml")) or "/" in name_or_path
    given = Path(name_or_path)
    if given.is_dir() and (looks_like_path or _is_output_dir(given)):
        _not_a_spec(given)
    if looks_like_path:
        path = Path(name_or_path)
        if not path.is_file():
            raise SpecError(f"{name_or_path}: no such spec file.")
        return path
    for directory in locations.experiment_dirs():
        path = directory / f"{name_or_path}.yaml"
        if path.is_file():
            return path
    raise UnknownNameError("experiment", name_or_path, all_experiment_names())


def _is_output_dir(path: Path) -> bool:
    """A run or sweep directory (what ``run`` may be given by mistake)."""
    return any((path / name).is_file() for name in ("run.json", "log.mcap", "sweep.yaml"))


def _not_a_spec(path: Path) -> None:
    """Raise the error for a directory given where a spec is expected, saying what it is."""
    if (path / "run.json").is_file() or (path / "log.mcap").is_file():
        raise SpecError(
            f"{path}: that is a run directory, not a spec; re-check it with "
            f"`walkrepro check --run {path}` (or plot, render, export, verify it); to run its "
            f"experiment again, give its spec: {path / 'spec.yaml'}."
        )
    if (path / "sweep.yaml").is_file():
        raise SpecError(
            f"{path}: that is a sweep directory, not a spec; continue it with "
            f"`walkrepro sweep --resume {path}`, or draw its maps with `walkrepro plot {path}`."
        )
    raise SpecError(f"{path}: that is a directory; give an experiment name or a spec file.")


def load_spec(
    name_or_path: str | Path,
    overrides: Iterable[str] = (),
    calibrated: Mapping[str, Any] | None = None,
) -> LoadedSpec:
    """Parse, override and schema-validate a spec.

    A mapping ``{calibrated: NAME}`` anywhere in the spec is replaced, after the overrides,
    by the committed result of parameter NAME in the paper's calibration file
    (``calibration/<paper.key>.yaml`` beside the spec, else the shipped one); an
    expectation marked ``calibrated: NAME`` must be a criterion of NAME there
    (:mod:`walkrepro.specs.calibrated`).

    Args:
        name_or_path: experiment name or spec file path.
        overrides: ``dotted.path=value`` strings (the value is parsed as YAML).
        calibrated: values that take the place of committed calibration results (what
            ``walkrepro calibrate`` is calibrating now), by parameter name.

    Raises:
        SpecError: naming file, line and field for any problem.
    """
    path = find_spec_file(str(name_or_path))
    source = _display_path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise SpecError(f"{source}: cannot read the spec ({exc.strerror}).") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise SpecError(
            f"{source}, line {line}: not UTF-8 text (byte {raw[exc.start]:#04x} at offset "
            f"{exc.start}); save the spec as UTF-8."
        ) from None
    data, lines = _parse_yaml(text, source)
    overridden: set[tuple[Any, ...]] = set()
    for item in overrides:
        key_path = _apply_override(data, item)
        overridden.add(key_path)
    # Imported only for a spec that uses calibration (it reads the calibration file).
    uses_calibration = _mentions_calibration(data)
    if uses_calibration:
        from walkrepro.specs.calibrated import resolve_references

        where = functools.partial(_where, source, lines, overridden=overridden)
        resolve_references(data, path, where, calibrated or {})
    _check_plain_data(data, source, lines, overridden)
    try:
        spec = ExperimentSpec.model_validate(data)
    except ValidationError as exc:
        raise SpecError(
            _format_validation(exc, source, lines, overridden, model=ExperimentSpec)
        ) from None
    loaded = LoadedSpec(spec=spec, source=source, lines=lines, overridden=frozenset(overridden))
    _check_across_sections(loaded)
    if uses_calibration:
        from walkrepro.specs.calibrated import check_marks

        check_marks(loaded, path)
    return loaded


def _mentions_calibration(data: Any) -> bool:
    """Whether ``data`` holds a ``calibrated`` key anywhere (a reference or a marked row)."""
    stack, seen = [data], set()
    while stack:
        node = stack.pop()
        if id(node) in seen:  # a YAML alias: read once (it may even contain itself)
            continue
        seen.add(id(node))
        if isinstance(node, dict):
            if "calibrated" in node:
                return True
            stack.extend(node.values())
        elif isinstance(node, list):
            stack.extend(node)
    return False
