"""An experiment resolved against what is installed, once, into the record a run takes.

:func:`resolve` checks every name in a loaded spec against the real registries (robot,
bodies, actuators, controller and its parameters, metrics, partner experiments) and the
obstacles against the robot's home pose, and keeps what the checks built: the robot, the
compiled scene and the controller's typed parameters, in one :class:`Experiment`. The loop
(:func:`walkrepro.runs.runner.run`) takes that record, so the robot is looked up, the scene
compiled and the parameters validated once per run.

Reading a spec file (:mod:`walkrepro.specs.files`) needs only the spec's own model; this
step needs the robot (:mod:`walkrepro.sim`), the controllers and the metrics, so it stands
above them.
"""

from __future__ import annotations

import fnmatch
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from walkrepro.errors import SpecError, UnknownNameError

if TYPE_CHECKING:  # the record's types; importing this module stays light (walkrepro.api)
    from walkrepro.controllers import ControllerParams
    from walkrepro.sim.robot import Robot
    from walkrepro.sim.world import Scene
    from walkrepro.specs.models import ExperimentSpec, LoadedSpec


@dataclass(frozen=True)
class Experiment:
    """An experiment resolved once: what a run of it, its metrics and its figures take.

    Attributes:
        spec: the validated spec, its controller parameters normalised by the controller's
            model (what a run logs as ``spec.yaml``).
        robot: the robot's MuJoCo and Pinocchio models (``robots/<spec.robot>/``).
        scene: the compiled scene: the robot with the spec's world, contact and timestep.
        params: the controller's typed parameters (its ``Params`` model).
        overrides: the ``--set`` strings the spec was loaded with (a run records them, so
            that partner runs with the same overrides are matched later).
        source: the spec file it was read from.
    """

    spec: ExperimentSpec
    robot: Robot = field(repr=False)
    scene: Scene = field(repr=False)
    params: ControllerParams
    overrides: tuple[str, ...] = ()
    source: str = ""

    @property
    def name(self) -> str:
        """The experiment's name (``spec.name``)."""
        return self.spec.name


def resolve(loaded: LoadedSpec, overrides: Sequence[str] = ()) -> Experiment:
    """Check ``loaded`` against the registries and keep the robot, scene and parameters.

    Args:
        loaded: a spec as :func:`walkrepro.specs.files.load_spec` read it.
        overrides: the ``--set`` strings it was loaded with (recorded, not applied again).

    Raises:
        SpecError / UnknownNameError: naming file, line, field and the valid names.
    """
    from walkrepro.sim.robot import with_scene_springs
    from walkrepro.sim.world import build_scene  # imports mujoco

    checked, robot, params = _check_names(loaded)
    scene = build_scene(robot, checked.spec)
    robot = with_scene_springs(robot, scene.model)  # a spec's springs: home re-solved
    _check_obstacle_overlap(loaded, robot, scene)
    return Experiment(
        spec=checked.spec,
        robot=robot,
        scene=scene,
        params=params,
        overrides=tuple(overrides),
        source=loaded.source,
    )


def assemble(spec: ExperimentSpec) -> Experiment:
    """The record of a spec that was resolved already (a sweep cell's, a bench run's, one
    read back from a log): its robot, its scene and its parameters, with no check again."""
    from walkrepro.controllers import controller_params
    from walkrepro.sim.robot import load_robot, with_scene_springs
    from walkrepro.sim.world import build_scene

    robot = load_robot(spec.robot)
    scene = build_scene(robot, spec)
    return Experiment(
        spec=spec,
        robot=with_scene_springs(robot, scene.model),  # a spec's springs: home re-solved
        scene=scene,
        params=controller_params(spec.controller),
    )


# --------------------------------------------------------------------------------------
# Resolution against registries


def resolve_spec(loaded: LoadedSpec) -> LoadedSpec:
    """Check every name in the spec against the real registries and validate params, for a
    caller that keeps only the spec (a sweep's cells, the ledger): :func:`resolve`'s checks,
    without keeping the scene.

    Returns the same spec with ``controller.params`` normalised by the controller's model.

    Raises:
        SpecError / UnknownNameError: naming file, line, field and the valid names.
    """
    checked, robot, _ = _check_names(loaded)
    if loaded.spec.world.obstacles:
        from walkrepro.sim.world import build_scene

        _check_obstacle_overlap(loaded, robot, build_scene(robot, loaded.spec))
    return checked


def _check_names(loaded: LoadedSpec) -> tuple[LoadedSpec, Robot, ControllerParams]:
    """Every check but the obstacles': the spec with its parameters normalised, the robot,
    and the parameters as the controller's model validated them."""
    # Imported here: the registries import heavy modules (mujoco, pinocchio), and the
    # record above is imported by walkrepro.api, which imports none.
    from walkrepro.sim.robot import list_robots, load_robot
    from walkrepro.specs.models import ControllerSpec

    spec = loaded.spec
    if spec.robot not in list_robots():
        raise UnknownNameError("robot", spec.robot, list_robots(), loaded.where(("robot",)))
    frames, params = _check_controller(loaded)
    robot = load_robot(spec.robot)
    _check_disturbance_names(loaded, robot, frames)
    _check_actuators(loaded, robot)
    _check_metrics(loaded)
    _check_times(loaded)
    normalised = spec.model_copy(
        update={
            "controller": ControllerSpec(
                type=spec.controller.type, params=params.model_dump(mode="json")
            )
        }
    )
    return loaded.model_copy(update={"spec": normalised}), robot, params


def _check_controller(loaded: LoadedSpec) -> tuple[tuple[str, ...], ControllerParams]:
    """The controller's name and parameters: the frames its disturbances may name
    (``world`` and the controller's own) and its parameters, as its model validated them."""
    from pydantic import ValidationError

    from walkrepro.controllers import controller_class, controller_names, controller_params
    from walkrepro.specs.models import _check_plain_data, _format_validation

    spec = loaded.spec
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
        declared = cls.Params.model_fields.get(name)
        if isinstance(value, bool) and declared is not None and declared.annotation in (float, int):
            raise SpecError(
                f"{loaded.where((*params_where, name))}: expected a number, not a boolean "
                f"(got {value!r})."
            )
    try:
        params = controller_params(spec.controller)
    except ValidationError as exc:
        raise SpecError(
            _format_validation(
                exc,
                loaded.source,
                loaded.lines,
                loaded.overridden,
                params_where,
                model=cls.Params,
            )
        ) from None
    # The controller's model may turn a string such as "nan" into a float.
    _check_plain_data(
        params.model_dump(), loaded.source, loaded.lines, loaded.overridden, params_where
    )
    return ("world", *cls.FRAMES), params


def _check_disturbance_names(loaded: LoadedSpec, robot: Robot, frames: tuple[str, ...]) -> None:
    """Each disturbance's body is the robot's and its frame one of ``frames``."""
    bodies = robot.body_names()
    for i, dist in enumerate(loaded.spec.disturbances):
        if dist.body not in bodies:
            raise UnknownNameError(
                "body", dist.body, bodies, loaded.where(("disturbances", i, "body"))
            )
        if dist.frame not in frames:
            raise UnknownNameError(
                "frame", dist.frame, frames, loaded.where(("disturbances", i, "frame"))
            )


def _check_actuators(loaded: LoadedSpec, robot: Robot) -> None:
    """The spec's actuator and sensor patterns match the robot's joints, and what they set
    (position gains, springs, backlash, torque lag) exists on the robot."""
    import mujoco

    from walkrepro.sim.springs import series_elastic_joints

    actuators, actuator_names = loaded.spec.actuators, robot.joint_names
    for pattern in actuators.position_gain:
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
    for field_name in ("spring", "backlash"):
        for pattern in getattr(actuators, field_name):
            at = loaded.where(("actuators", field_name, pattern))
            springs = series_elastic_joints(robot.mj_model, field_name == "backlash")
            if not springs:
                kind = "dead-band (backlash) springs" if field_name == "backlash" else "springs"
                raise SpecError(f"{at}: robot {robot.name!r} has no {kind} to set.")
            if not fnmatch.filter(springs, pattern):
                raise UnknownNameError("series-elastic joint", pattern, springs, at)
    if actuators.torque_lag is not None:
        filtered = mujoco.mjtDyn.mjDYN_FILTEREXACT
        if not all(int(d) == filtered for d in robot.mj_model.actuator_dyntype):
            raise SpecError(
                f"{loaded.where(('actuators', 'torque_lag'))}: robot {robot.name!r} has no "
                "torque-loop dynamics to set (its actuators are not first-order filters)."
            )
    for pattern in loaded.spec.sensors.joint_backlash:
        if not fnmatch.filter(actuator_names, pattern):
            raise UnknownNameError(
                "actuator",
                pattern,
                actuator_names,
                loaded.where(("sensors", "joint_backlash", pattern)),
            )


def _check_metrics(loaded: LoadedSpec) -> None:
    """Every metric the expectations and sweeps name is registered and reads its argument;
    a known deviation has its band; a partner experiment exists; a claim selects cells by
    the fields its map's grid varies."""
    from walkrepro.specs.files import all_experiment_names

    check_metric = _metric_checker(loaded)
    for i, exp in enumerate(loaded.spec.expect):
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
    for i, sweep in enumerate(loaded.spec.sweeps):
        if sweep.metric is not None:
            check_metric(sweep.metric, ("sweeps", i, "metric"))
        if sweep.success is not None:
            check_metric(sweep.success.metric, ("sweeps", i, "success", "metric"))
        for j, claim in enumerate(sweep.claims):
            check_metric(claim.region.metric, ("sweeps", i, "claims", j, "region", "metric"))
            # A selector on a field the grid does not vary matches no cell, and a claim over
            # no cells would hold whatever the map shows.
            for key in ("where", "contains", "than"):
                for grid_field in getattr(claim, key) or {}:
                    if grid_field not in sweep.grid:
                        raise SpecError(
                            f"{loaded.where(('sweeps', i, 'claims', j, key))}: {grid_field!r} is not "
                            f"a field of this map's grid ({', '.join(sweep.grid)}); a claim "
                            "selects cells by their grid values."
                        )


def _metric_checker(loaded: LoadedSpec) -> Callable[[str, tuple[str | int, ...]], None]:
    """A check that a metric name is registered and its argument readable, raising an error
    at the spec path it is given."""
    from walkrepro.evaluation.metrics import (
        MetricArgError,
        check_metric_arg,
        metric_names,
        split_metric,
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

    return check_metric


def _check_times(loaded: LoadedSpec) -> None:
    """The run covers one control period, and every disturbance starts before it ends."""
    spec = loaded.spec
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


def _check_obstacle_overlap(loaded: LoadedSpec, robot: Any, scene: Scene) -> None:
    """Refuse an obstacle that overlaps the robot's collision geoms at the home pose.

    MuJoCo would resolve the overlap at the first step by launching the robot out of the
    box. An obstacle with ``allow_overlap: true`` is let through with a warning on stderr.

    Raises:
        SpecError: naming the obstacle's file, line and field, and the robot geoms it hits.
    """
    if not loaded.spec.world.obstacles:
        return
    from walkrepro.sim.world import home_overlaps  # imports mujoco

    overlaps = home_overlaps(robot, scene.model, loaded.spec)
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
