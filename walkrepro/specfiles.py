"""Experiment specs as files: finding them by name, loading them, and checking them against
what is installed.

:mod:`walkrepro.spec` is the data model and its YAML reading (a leaf: it imports no other
part of walkrepro that could import it back). This module puts a spec file through the whole
chain: the file found by name (the user's folder from ``--experiments DIR``, then the
shipped ``experiments/``, see :mod:`walkrepro.locations`), ``--set`` overrides, the declared
calibration's committed results (:mod:`walkrepro.calibration.references`), the schema, and
then (:func:`resolve_spec`) the names against the registries: robot, controller and its
parameter model, metrics, bodies, and obstacles against the robot's home pose.
"""

from __future__ import annotations

import fnmatch
import functools
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from walkrepro import locations
from walkrepro.errors import SpecError, UnknownNameError
from walkrepro.spec import (
    ControllerSpec,
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
    (:mod:`walkrepro.calibration.references`).

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
        from walkrepro.calibration.references import resolve_references

        where = functools.partial(_where, source, lines, overridden=overridden)
        resolve_references(data, path, where, calibrated or {})
    _check_plain_data(data, source, lines, overridden)
    try:
        spec = ExperimentSpec.model_validate(data)
    except ValidationError as exc:
        raise SpecError(_format_validation(exc, source, lines, overridden)) from None
    loaded = LoadedSpec(spec=spec, source=source, lines=lines, overridden=frozenset(overridden))
    _check_across_sections(loaded)
    if uses_calibration:
        from walkrepro.calibration.references import check_marks

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


# --------------------------------------------------------------------------------------
# Resolution against registries


def resolve_spec(loaded: LoadedSpec) -> LoadedSpec:
    """Check every name in the spec against the real registries and validate params.

    Returns the same spec with ``controller.params`` normalised by the controller's model.

    Raises:
        SpecError / UnknownNameError: naming file, line, field and the valid names.
    """
    # Imported here: the registries import heavy modules (mujoco, pinocchio).
    import mujoco

    from walkrepro.controllers import controller_class, controller_names, controller_params
    from walkrepro.metrics import MetricArgError, check_metric_arg, metric_names, split_metric
    from walkrepro.robot import list_robots, load_robot

    spec = loaded.spec
    if spec.robot not in list_robots():
        raise UnknownNameError("robot", spec.robot, list_robots(), loaded.where(("robot",)))
    if spec.controller.type not in controller_names():
        raise UnknownNameError(
            "controller",
            spec.controller.type,
            controller_names(),
            loaded.where(("controller", "type")),
        )
    cls = controller_class(spec.controller.type)
    params_where = ("controller", "params")
    for name, value in spec.controller.params.items():
        field = cls.Params.model_fields.get(name)
        if isinstance(value, bool) and field is not None and field.annotation in (float, int):
            raise SpecError(
                f"{loaded.where((*params_where, name))}: expected a number, not a boolean "
                f"(got {value!r})."
            )
    try:
        params = controller_params(spec.controller)
    except ValidationError as exc:
        raise SpecError(
            _format_validation(exc, loaded.source, loaded.lines, loaded.overridden, params_where)
        ) from None
    # The controller's model may turn a string such as "nan" into a float.
    _check_plain_data(
        params.model_dump(), loaded.source, loaded.lines, loaded.overridden, params_where
    )

    robot = load_robot(spec.robot)
    bodies = robot.body_names()
    for i, dist in enumerate(spec.disturbances):
        if dist.body not in bodies:
            raise UnknownNameError(
                "body", dist.body, bodies, loaded.where(("disturbances", i, "body"))
            )
        frames = ("world", *cls.FRAMES)
        if dist.frame not in frames:
            raise UnknownNameError(
                "frame", dist.frame, frames, loaded.where(("disturbances", i, "frame"))
            )
    actuator_names = robot.joint_names
    for pattern in spec.actuators.position_gain:
        matched = fnmatch.filter(actuator_names, pattern)
        if not matched:
            raise UnknownNameError(
                "actuator",
                pattern,
                actuator_names,
                loaded.where(("actuators", "position_gain", pattern)),
            )
        if robot.control_mode != "position":
            raise SpecError(
                f"{loaded.where(('actuators', 'position_gain'))}: robot {robot.name!r} has torque "
                "actuators; position_gain applies to position servos only."
            )
    if spec.actuators.torque_lag is not None:
        filtered = mujoco.mjtDyn.mjDYN_FILTEREXACT
        if not all(int(d) == filtered for d in robot.mj_model.actuator_dyntype):
            raise SpecError(
                f"{loaded.where(('actuators', 'torque_lag'))}: robot {robot.name!r} has no "
                "torque-loop dynamics to set (its actuators are not first-order filters)."
            )
    for pattern in spec.sensors.joint_backlash:
        if not fnmatch.filter(actuator_names, pattern):
            raise UnknownNameError(
                "actuator",
                pattern,
                actuator_names,
                loaded.where(("sensors", "joint_backlash", pattern)),
            )
    valid_metrics = metric_names()

    def check_metric(full: str, path: tuple[str | int, ...]) -> None:
        """A registered metric whose argument it can read, else an error at ``path``."""
        base, _ = split_metric(full)
        if base not in valid_metrics:
            raise UnknownNameError("metric", base, valid_metrics, loaded.where(path))
        try:
            check_metric_arg(full)
        except MetricArgError as exc:
            raise SpecError(f"{loaded.where(path)}: {exc}") from None

    for i, exp in enumerate(spec.expect):
        if exp.known_deviation is not None and exp.known_deviation.observed is None:
            raise SpecError(
                f"{loaded.where(('expect', i, 'known_deviation'))}: a known deviation needs "
                "the band the reproduction measures today, e.g. known_deviation: {observed: "
                "[0.065, 0.070], reason: '...'}; its row fails when the value leaves the band."
            )
        check_metric(exp.metric, ("expect", i, "metric"))
        if exp.relative_to is not None:
            where = ("expect", i, "relative_to")
            if exp.relative_to.experiment not in all_experiment_names():
                raise UnknownNameError(
                    "experiment",
                    exp.relative_to.experiment,
                    all_experiment_names(),
                    loaded.where((*where, "experiment")),
                )
            check_metric(exp.reference_metric, (*where, "metric"))
    for i, sweep in enumerate(spec.sweeps):
        if sweep.metric is not None:
            check_metric(sweep.metric, ("sweeps", i, "metric"))
        if sweep.success is not None:
            check_metric(sweep.success.metric, ("sweeps", i, "success", "metric"))
        for j, claim in enumerate(sweep.claims):
            check_metric(claim.region.metric, ("sweeps", i, "claims", j, "region", "metric"))
            # A selector on a field the grid does not vary matches no cell, and a claim over
            # no cells would hold whatever the map shows.
            for key in ("where", "contains", "than"):
                for field in getattr(claim, key) or {}:
                    if field not in sweep.grid:
                        raise SpecError(
                            f"{loaded.where(('sweeps', i, 'claims', j, key))}: {field!r} is not "
                            f"a field of this map's grid ({', '.join(sweep.grid)}); a claim "
                            "selects cells by their grid values."
                        )
    if spec.sim.duration < spec.sim.control_period:
        raise SpecError(
            f"{loaded.where(('sim', 'duration'))}: duration must cover one control period."
        )
    for i, dist in enumerate(spec.disturbances):
        if dist.start >= spec.sim.duration:
            raise SpecError(
                f"{loaded.where(('disturbances', i, 'start'))}: starts after the run ends "
                f"(duration {spec.sim.duration} s)."
            )
    _check_obstacle_overlap(loaded, robot)
    normalised = spec.model_copy(
        update={
            "controller": ControllerSpec(
                type=spec.controller.type, params=params.model_dump(mode="json")
            )
        }
    )
    return loaded.model_copy(update={"spec": normalised})


def _check_obstacle_overlap(loaded: LoadedSpec, robot: Any) -> None:
    """Refuse an obstacle that overlaps the robot's collision geoms at the home pose.

    MuJoCo would resolve the overlap at the first step by launching the robot out of the
    box. An obstacle with ``allow_overlap: true`` is let through with a warning on stderr.

    Raises:
        SpecError: naming the obstacle's file, line and field, and the robot geoms it hits.
    """
    if not loaded.spec.world.obstacles:
        return
    from walkrepro.world import home_overlaps  # imports mujoco

    overlaps = home_overlaps(robot, loaded.spec)
    for i, obstacle in enumerate(loaded.spec.world.obstacles):
        hits = overlaps.get(obstacle.name)
        if not hits:
            continue
        depth = max(hits.values())
        message = (
            f"{loaded.where(('world', 'obstacles', i))}: obstacle {obstacle.name!r} overlaps "
            f"the robot at its home pose ({', '.join(sorted(hits))}; up to {depth * 1000:.1f} "
            "mm deep), so MuJoCo would launch the robot out of it at the first step"
        )
        if not obstacle.allow_overlap:
            raise SpecError(
                f"{message}. Move or shrink the obstacle, or set allow_overlap: true on it "
                "if the overlap is intended."
            )
        print(f"warning: {message} (allowed by allow_overlap: true).", file=sys.stderr)
