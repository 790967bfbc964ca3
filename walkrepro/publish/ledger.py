"""The provenance ledger of a run: every number it uses, with its class and its source.

Four places hold the classes (:mod:`walkrepro.specs.origin` defines them):

- the robot: ``robots/<robot>/parameters.yaml``, the ledger ``robots/build_models.py``
  builds ``robot.xml`` from (``inherits`` names the robot a variant extends);
- the scene: MuJoCo's options and the contact of the floor and of every obstacle, read from
  the compiled scene. An option the robot's ledger sets (``option_<attribute>``, written into
  its MJCF by ``robots/build_models.py``) takes that entry's class; a value equal to MuJoCo's
  own default is ``assumed: MuJoCo's default`` (with the paper's ``scene_default`` reason
  when ``experiments/provenance/<paper>.yaml`` gives one: Paper III's simulator was MuJoCo);
  a value a spec field sets (``world.cone``, ``world.condim``) is listed under that field;
- the spec's sections (``sim``, ``world``, ``sensors``, ``actuators``) and the controller's
  parameters: each field's default carries its class (``json_schema_extra``); a value a spec
  sets is the experiment's scenario (fields marked so), a declared calibration's result
  (``{calibrated: NAME}``), or classed in the spec's ``provenance:`` block or in
  ``experiments/provenance/<paper>.yaml``;
- the disturbances: every number of each push (force, torque, start, duration, ramp) and
  each hold (the hand's stiffness, damping, force cap and anchor offset, its grab time,
  duration and ramp), by ``disturbances.<name>.<field>``: a ``{calibrated: NAME}`` value is
  the declared calibration's, the others are classed in the spec's ``provenance:`` block or
  in ``experiments/provenance/<paper>.yaml`` (a field's default keeps its own class);
- a ``--set`` on the command line is listed as ``override``: the user's, not the paper's.

A number with no class is listed as ``unclassified``; ``walkrepro provenance`` then exits 1,
and ``tests/test_ledger.py`` fails on any shipped experiment that has one.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import mujoco
import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from walkrepro.errors import SpecError
from walkrepro.locations import EXPERIMENTS_DIR, ROBOTS_DIR
from walkrepro.specs.models import DisturbanceSpec, LoadedSpec, Origin
from walkrepro.specs.origin import CLASSES, SCENARIO, field_origin

#: What a number without a class is listed as.
UNCLASSIFIED = "unclassified"
#: What a value given by ``--set`` is listed as.
OVERRIDE = "override"
#: Every listed class, in report order.
LISTED = (*CLASSES, SCENARIO, OVERRIDE, UNCLASSIFIED)

#: The spec sections whose fields are numbers of the run (the rest is the scenario: the
#: experiment's obstacles, disturbances, expectations and maps).
SPEC_SECTIONS = ("sim", "world", "sensors", "actuators")
#: The numbers of a disturbance by its kind (a push's force is of time only; a hold's force is
#: an outcome of the hand's impedance, so its numbers are the hand's). A ramp's ``ramp_time``
#: is listed only with ``profile: ramp``.
DISTURBANCE_FIELDS = {
    "push": ("force", "torque", "start", "duration", "ramp_time"),
    "hold": ("stiffness", "damping", "max_force", "hold_offset", "start", "duration", "ramp_time"),
}
#: Spec fields that are the scenario whatever their value (obstacles and the departures
#: of a whole experiment's contact are listed from the compiled scene instead).
SCENARIO_FIELDS = frozenset({"world.obstacles", "world.contact"})


@dataclass(frozen=True)
class Number:
    """One number a run uses.

    Attributes:
        group: ``robot``, ``scene``, ``sim``, ``world``, ``sensors``, ``actuators``, ``disturbance`` or
            ``controller``.
        name: the parameter's name in its group (a dotted spec path without the group).
        value: the value as text.
        klass: one of :data:`LISTED`.
        source: the section, file or criterion behind the class.
    """

    group: str
    name: str
    value: str
    klass: str
    source: str


# --------------------------------------------------------------------------------------
# Ledger files


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True)


class SourceValue(_Strict):
    """A lab's value that is not in force, with its citation."""

    value: Any
    source: str = Field(min_length=1)


#: The physical range of a robot ledger's numbers by unit, [lo, hi], and why: a value
#: outside is a typo or a unit slip. Units not listed (``-``, MJCF keywords, mixed units) are
#: not checked. Every bound is far beyond the papers' robots (≤ 90 kg, ≤ 1.6 m tall).
UNIT_RANGES: dict[str, tuple[float, float, str]] = {
    "kg": (1e-6, 1e3, "a body's mass is positive and below ten times a 100 kg robot's"),
    "kg m^2": (-1e2, 1e2, "an inertia entry of a body under 1000 kg and 3 m"),
    "m": (-3.0, 3.0, "a length or position of a robot under 3 m"),
    "rad": (-math.pi, math.pi, "an angle, within a half turn either way"),
    "deg": (-180.0, 180.0, "an angle, within a half turn either way"),
    "Nm": (
        0.0,
        1e3,
        "a torque bound or friction, at most ten times a 100 kg robot's weight on 1 m",
    ),
    "Nm/rad": (0.0, 1e6, "a joint stiffness, at most a stiff servo's 1e6"),
    "Nms/rad": (0.0, 1e4, "a joint damping, at most critical damping of 1e6 Nm/rad on 25 kg m^2"),
    "Nms^2/rad": (0.0, 1e2, "a reflected inertia, within the inertia entries' range"),
    "N/m": (0.0, 1e9, "a contact stiffness, below steel's on a square centimetre"),
    "N s/m": (0.0, 1e6, "a contact damping"),
    "m/s": (0.0, 10.0, "a speed scale, beyond any walking speed"),
    "s": (1e-6, 1.0, "a time constant, positive and at most a second"),
    "V": (0.0, 1e3, "a motor supply voltage"),
    "V/rad": (0.0, 1e4, "a servo's voltage gain"),
    "V/Nm": (0.0, 1e3, "a torque-to-voltage ratio"),
    "Vs/rad": (0.0, 1e3, "a back-EMF constant"),
}


def _numbers(value: Any) -> Iterator[float]:
    """Every number in a ledger value (a number or nested lists of numbers)."""
    if isinstance(value, bool):
        return
    if isinstance(value, int | float):
        yield float(value)
    elif isinstance(value, list):
        for item in value:
            yield from _numbers(item)


class RobotEntry(_Strict):
    """One number of a robot's ledger (``robots/<robot>/parameters.yaml``); its value lies
    in its unit's physical range (:data:`UNIT_RANGES`)."""

    value: Any
    unit: str
    klass: Literal["paper", "source", "assumed", "calibrated"] = Field(alias="class")
    source: str = Field(min_length=1)
    description: str = ""
    source_value: SourceValue | None = Field(None, description="a lab's value not in force")

    @model_validator(mode="after")
    def _in_physical_range(self) -> RobotEntry:
        if self.unit not in UNIT_RANGES:
            return self
        lo, hi, why = UNIT_RANGES[self.unit]
        for number in _numbers(self.value):
            if not lo <= number <= hi:  # also refuses NaN
                raise ValueError(
                    f"{number!r} {self.unit} is out of range: must be in [{lo:g}, {hi:g}] ({why})"
                )
        return self


class RobotLedger(_Strict):
    """A robot's ledger: its parameters, and the robot whose ledger it extends."""

    robot: str
    inherits: str | None = None
    parameters: dict[str, RobotEntry]


class SharedValue(Origin):
    """A value a paper's specs set, with its class (``experiments/provenance/<paper>.yaml``)."""

    value: Any


class PaperValues(_Strict):
    """The classes of the values a paper's specs share, by dotted spec path."""

    paper: str
    scene_default: str | None = Field(
        None, description="why MuJoCo's defaults are this paper's scene (its own simulator)"
    )
    values: dict[str, list[SharedValue]]


def _read_yaml(path: Path) -> Any:
    try:
        return yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as exc:
        raise SpecError(f"{path}: cannot read the ledger ({exc}).") from None


def _validated(model: type[BaseModel], path: Path) -> Any:
    try:
        return model.model_validate(_read_yaml(path))
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        msg = first["msg"].removeprefix("Value error, ")
        raise SpecError(f"{path}, field {where}: {msg}.") from None


def robot_ledger(robot: str, robots_dir: Path = ROBOTS_DIR) -> dict[str, RobotEntry] | None:
    """The robot's ledger entries, a variant's own over those it inherits; None if the
    robot has no ``parameters.yaml``."""
    path = robots_dir / robot / "parameters.yaml"
    if not path.is_file():
        return None
    ledger: RobotLedger = _validated(RobotLedger, path)
    entries: dict[str, RobotEntry] = {}
    if ledger.inherits is not None:
        inherited = robot_ledger(ledger.inherits, robots_dir)
        if inherited is None:
            raise SpecError(f"{path}: inherits {ledger.inherits!r}, which has no ledger.")
        entries.update(inherited)
    entries.update(ledger.parameters)
    return entries


def paper_values(paper: str, experiments_dir: Path = EXPERIMENTS_DIR) -> PaperValues | None:
    """``experiments/provenance/<paper>.yaml``, or None."""
    path = experiments_dir / "provenance" / f"{paper}.yaml"
    return _validated(PaperValues, path) if path.is_file() else None


# --------------------------------------------------------------------------------------
# The numbers of a run


def _text(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_text(v) for v in value) + "]"
    if isinstance(value, np.ndarray):
        return _text(value.tolist())
    return str(value)


def _same(a: Any, b: Any) -> bool:
    try:
        return bool(np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float)))
    except (TypeError, ValueError):
        return a == b


def _calibration_marks(data: Any, prefix: str = "") -> dict[str, str]:
    """Dotted paths of the raw spec's ``{calibrated: NAME}`` values -> NAME."""
    marks: dict[str, str] = {}
    if isinstance(data, Mapping):
        if set(data) == {"calibrated"} and isinstance(data["calibrated"], str):
            return {prefix: data["calibrated"]}
        for key, value in data.items():
            marks.update(_calibration_marks(value, f"{prefix}.{key}" if prefix else str(key)))
    return marks


def _set_paths(data: Any, prefix: str = "") -> Iterator[str]:
    """Every leaf path the raw spec sets (a mapping's keys, not a list's items)."""
    if isinstance(data, Mapping) and not (set(data) == {"calibrated"}):
        for key, value in data.items():
            yield from _set_paths(value, f"{prefix}.{key}" if prefix else str(key))
    else:
        yield prefix


class _Classifier:
    """Classes a value a spec sets: its own block, the paper's shared file, a calibration."""

    def __init__(self, loaded: LoadedSpec, raw: Any):
        spec = loaded.spec
        self.own = spec.provenance
        shared = paper_values(spec.paper.key)
        self.shared = shared.values if shared is not None else {}
        self.marks = _calibration_marks(raw)
        self.set_paths = set(_set_paths(raw))
        self.overridden = {".".join(str(p) for p in path) for path in loaded.overridden}
        self.paper = spec.paper.key

    def is_set(self, path: str) -> bool:
        return any(p == path or p.startswith(path + ".") for p in self.set_paths)

    def classify_set(self, path: str, value: Any) -> tuple[str, str]:
        """(class, source) of a value the spec sets at ``path``, from the spec's own
        ``provenance:`` block or the paper's shared file (matched by value); unclassified
        when neither has it."""
        if path in self.own:
            return self.own[path].klass, self.own[path].source
        for shared in self.shared.get(path, []):
            if _same(shared.value, value):
                return shared.klass, f"{shared.source} (experiments/provenance/{self.paper}.yaml)"
        return UNCLASSIFIED, f"set by the spec with no class ({path})"

    def classify(
        self, path: str, value: Any, default: Any, extra: Any, has_default: bool = True
    ) -> tuple[str, str]:
        """(class, source) of the value at ``path``."""
        origin, scenario = field_origin(extra)
        if path in self.overridden:
            return OVERRIDE, "--set on the command line"
        if not self.is_set(path):
            if origin is not None:
                return origin["class"], f"default: {origin['source']}"
            if scenario is not None:
                return SCENARIO, scenario
            return UNCLASSIFIED, "a default with no class"
        if path in self.marks:
            return (
                "calibrated",
                f"experiments/calibration/{self.paper}.yaml: {self.marks[path]}",
            )
        if scenario is not None:
            return SCENARIO, scenario
        klass, source = self.classify_set(path, value)
        if klass != UNCLASSIFIED:
            return klass, source
        if has_default and origin is not None and _same(value, default):
            return origin["class"], f"default: {origin['source']}"
        return UNCLASSIFIED, f"set by the spec with no class ({path})"


def _marked(value: Any) -> list[str]:
    """The calibration names of ``{calibrated: NAME}`` in a raw value (itself or its items)."""
    if isinstance(value, Mapping) and set(value) == {"calibrated"}:
        return [str(value["calibrated"])]
    if isinstance(value, list):
        return [name for item in value for name in _marked(item)]
    return []


def disturbance_fields(disturbance: DisturbanceSpec) -> tuple[str, ...]:
    """The fields of ``disturbance`` that are numbers of its run (:data:`DISTURBANCE_FIELDS`)."""
    fields = DISTURBANCE_FIELDS[disturbance.kind]
    if disturbance.profile != "ramp":
        fields = tuple(f for f in fields if f != "ramp_time")
    return fields


def _disturbance_numbers(loaded: LoadedSpec, raw: Any, classifier: _Classifier) -> Iterator[Number]:
    """Every number of every disturbance, classed (group ``disturbance``, named
    ``<disturbance>.<field>``).

    A value the spec leaves at its default takes the field's class; a value it sets is an
    override (``--set``), a declared calibration's result (``{calibrated: NAME}``, also as
    one item of a vector), or classed by ``disturbances.<name>.<field>`` in the spec's
    ``provenance:`` block or in ``experiments/provenance/<paper>.yaml`` (matched by value).
    """
    items = raw.get("disturbances") if isinstance(raw, Mapping) else None
    items = items if isinstance(items, list) else []
    for i, d in enumerate(loaded.spec.disturbances):
        given = items[i] if i < len(items) and isinstance(items[i], Mapping) else {}
        for field in disturbance_fields(d):
            value = getattr(d, field)
            path = f"disturbances.{d.name}.{field}"
            info = DisturbanceSpec.model_fields[field]
            origin, _ = field_origin(info.json_schema_extra)
            if any(p[:3] == ("disturbances", i, field) for p in loaded.overridden):
                klass, source = OVERRIDE, "--set on the command line"
            elif marks := _marked(given.get(field)):
                klass = "calibrated"
                source = f"experiments/calibration/{classifier.paper}.yaml: {', '.join(marks)}"
                if isinstance(given.get(field), list):
                    source += " (the marked components; the others as the spec writes them)"
            elif field not in given and origin is not None:
                klass, source = origin["class"], f"default: {origin['source']}"
            else:
                klass, source = classifier.classify_set(path, value)
            yield Number("disturbance", f"{d.name}.{field}", _text(value), klass, source)


def _model_numbers(
    model: BaseModel, group: str, prefix: str, classifier: _Classifier
) -> Iterator[Number]:
    """The fields of a pydantic model instance (nested models and dicts entry by entry)."""
    for name, info in type(model).model_fields.items():
        path = f"{prefix}.{name}"
        if path in SCENARIO_FIELDS:
            continue
        value = getattr(model, name)
        label = path.split(".", 1)[1]
        if isinstance(value, BaseModel):
            yield from _model_numbers(value, group, path, classifier)
        elif isinstance(value, dict):
            for key, item in value.items():
                klass, source = classifier.classify(
                    f"{path}.{key}", item, None, info.json_schema_extra, has_default=False
                )
                yield Number(group, f"{label}.{key}", _text(item), klass, source)
            if not value:
                klass, source = classifier.classify(path, value, {}, info.json_schema_extra)
                yield Number(group, label, "{}", klass, source)
        else:
            default = None if info.is_required() else info.get_default(call_default_factory=True)
            klass, source = classifier.classify(path, value, default, info.json_schema_extra)
            yield Number(group, label, _text(value), klass, source)


def _robot_numbers(robot: str) -> Iterator[Number]:
    from walkrepro.specs.calibration_files import robot_calibration

    declared = robot_calibration(robot)
    declared_names = {v.ledger: v.name for v in declared.values if v.ledger} if declared else {}
    entries = robot_ledger(robot)
    if entries is None:
        yield Number(
            "robot",
            "(every parameter)",
            "?",
            UNCLASSIFIED,
            f"robots/{robot}/parameters.yaml is missing",
        )
        return
    for name, entry in entries.items():
        if name.startswith(OPTION_PREFIX):
            continue  # listed with the scene's options (scene_origins)
        value = f"{_text(entry.value)} {entry.unit}".strip()
        source = entry.source
        if entry.source_value is not None:
            source += (
                f" [a lab's value NOT in force: {_text(entry.source_value.value)}, "
                f"{entry.source_value.source}]"
            )
        if name in declared_names:
            source += (
                f" (declared: experiments/calibration/robots/{robot}.yaml: {declared_names[name]})"
            )
        yield Number("robot", name, value, entry.klass, source)


#: Robot ledger entries ``option_<attribute>`` set the robot's MJCF ``<option>``.
OPTION_PREFIX = "option_"


def scene_origins(robot: str) -> dict[str, dict[str, str]]:
    """``option.<attribute>`` -> ``{"class", "source"}`` of every option the robot's ledger
    sets (``robots/<robot>/parameters.yaml``, entries ``option_<attribute>``)."""
    entries = robot_ledger(robot) or {}
    return {
        f"option.{name[len(OPTION_PREFIX) :]}": {
            "class": entry.klass,
            "source": f"{entry.source} (robots/{robot}/parameters.yaml: {name})",
        }
        for name, entry in entries.items()
        if name.startswith(OPTION_PREFIX)
    }


#: MuJoCo's default options and floor-plane geom, for comparison.
_DEFAULT_MODEL = mujoco.MjModel.from_xml_string(
    '<mujoco><worldbody><geom type="plane" size="1 1 1"/></worldbody></mujoco>'
)
#: Scene options listed (``timestep`` is the spec's ``sim.timestep``).
OPTIONS = (
    "integrator",
    "cone",
    "solver",
    "jacobian",
    "iterations",
    "tolerance",
    "ls_iterations",
    "ls_tolerance",
    "noslip_iterations",
    "noslip_tolerance",
    "ccd_iterations",
    "ccd_tolerance",
    "impratio",
    "gravity",
    "wind",
    "density",
    "viscosity",
    "o_margin",
    "o_solref",
    "o_solimp",
    "o_friction",
    "disableflags",
    "enableflags",
)
#: Contact fields of the floor geom listed (friction's sliding part is world.floor_friction).
FLOOR_FIELDS = ("friction", "solref", "solimp", "solmix", "condim", "margin", "gap")
#: Contact fields of an obstacle's geom listed (its sliding friction is the floor's,
#: ``world.floor_friction``, or its own ``friction``: spec fields, listed there; so is its own
#: ``solref`` when the spec sets one).
OBSTACLE_FIELDS = ("friction", "solref", "solimp", "solmix", "condim", "margin", "gap")


def _scene_numbers(
    model: mujoco.MjModel,
    origins: Mapping[str, dict[str, str]],
    obstacles: tuple[str, ...] = (),
    default_reason: str | None = None,
    own_solref: frozenset[str] = frozenset(),
) -> Iterator[Number]:
    """MuJoCo's options and the contact of the floor and the obstacles as compiled: MuJoCo's
    default, or declared."""
    default_note = f"MuJoCo's default (mujoco {mujoco.__version__})"
    if default_reason:
        default_note = f"{default_reason}: {default_note}"

    def classed(name: str, value: Any, default: Any) -> Number:
        if name in origins:
            origin = origins[name]
            return Number("scene", name, _text(value), origin["class"], origin["source"])
        if _same(value, default):
            return Number("scene", name, _text(value), "assumed", default_note)
        return Number("scene", name, _text(value), UNCLASSIFIED, "departs from MuJoCo's default")

    for name in OPTIONS:
        yield classed(
            f"option.{name}", np.copy(getattr(model.opt, name)), getattr(_DEFAULT_MODEL.opt, name)
        )
    floor = model.geom("floor").id
    for name in FLOOR_FIELDS:
        value = np.copy(getattr(model, f"geom_{name}")[floor])
        default = getattr(_DEFAULT_MODEL, f"geom_{name}")[0]
        if name == "friction":  # the sliding part is the spec's world.floor_friction
            value, default = value[1:], default[1:]
            name = "friction.torsional_rolling"
        yield classed(f"floor.{name}", value, default)
    for obstacle in obstacles:
        geom = model.geom(obstacle).id
        for name in OBSTACLE_FIELDS:
            if name == "solref" and obstacle in own_solref:
                continue  # the spec's own solref, listed under world.obstacles
            value = np.copy(getattr(model, f"geom_{name}")[geom])
            default = getattr(_DEFAULT_MODEL, f"geom_{name}")[0]
            if name == "friction":
                value, default = value[1:], default[1:]
                name = "friction.torsional_rolling"
            yield classed(f"{obstacle}.{name}", value, default)


def experiment_numbers(loaded: LoadedSpec, raw: Any, scene_model: mujoco.MjModel) -> list[Number]:
    """Every number the experiment's run uses, with its class and source.

    Args:
        loaded: the resolved spec (with ``--set`` overrides applied).
        raw: the spec file's YAML as plain data (it tells which values the spec sets and
            which it takes from a declared calibration).
        scene_model: the run's compiled scene (:func:`walkrepro.sim.world.build_scene`).
    """
    from walkrepro.controllers import controller_params

    spec = loaded.spec
    classifier = _Classifier(loaded, raw)
    numbers = list(_robot_numbers(spec.robot))
    origins = scene_origins(spec.robot)
    obstacles = tuple(o.name for o in spec.world.obstacles)
    for field, scene_names in (
        ("cone", ("option.cone",)),
        ("condim", ("floor.condim", *(f"{o}.condim" for o in obstacles))),
    ):
        if getattr(spec.world, field) is not None:
            for name in scene_names:
                origins[name] = {"class": SCENARIO, "source": f"the spec's world.{field}"}
    shared = paper_values(spec.paper.key)
    default_reason = shared.scene_default if shared is not None else None
    own_solref = frozenset(o.name for o in spec.world.obstacles if o.solref is not None)
    numbers += _scene_numbers(scene_model, origins, obstacles, default_reason, own_solref)
    for section in SPEC_SECTIONS:
        numbers += _model_numbers(getattr(spec, section), section, section, classifier)
    for obstacle in spec.world.obstacles:
        for field in ("friction", "solref"):
            value = getattr(obstacle, field)
            if value is None:
                continue
            path = f"world.obstacles.{obstacle.name}.{field}"
            own = classifier.own.get(path)
            klass, source = (own.klass, own.source) if own else (UNCLASSIFIED, "set with no class")
            numbers.append(Number("world", path.split(".", 1)[1], _text(value), klass, source))
    numbers += _disturbance_numbers(loaded, raw, classifier)
    params = controller_params(spec.controller)
    numbers += _model_numbers(params, "controller", "controller.params", classifier)
    return numbers


def unused_entries(loaded: LoadedSpec, raw: Any) -> list[str]:
    """Paths of the spec's ``provenance:`` block that name no value the spec sets (an entry
    without a number)."""
    paths = set(_set_paths(raw))
    obstacles = {
        f"world.obstacles.{o.name}.{field}"
        for o in loaded.spec.world.obstacles
        for field in ("friction", "solref")
        if getattr(o, field) is not None
    }
    disturbances = {
        f"disturbances.{d.name}.{field}"
        for d in loaded.spec.disturbances
        for field in disturbance_fields(d)
    }
    named = obstacles | disturbances
    return sorted(p for p in loaded.spec.provenance if p not in paths and p not in named)


def undeclared_calibrated(
    numbers: list[Number], robot: str, directory: Path | None = None
) -> list[str]:
    """The calibrated numbers of a run on ``robot`` that no declaration covers: a paper's
    calibration file (``{calibrated: NAME}``) or the robot's declaration
    (``experiments/calibration/robots/<robot>.yaml``: a robot ledger entry by name, a spec
    value by path and value). Empty when every calibrated value is declared."""
    from walkrepro.specs.calibration_files import robot_calibration

    declared = robot_calibration(robot, directory)
    values = declared.values if declared is not None else []
    missing = []
    for n in numbers:
        if n.klass != "calibrated" or n.source.startswith("experiments/calibration/"):
            continue
        if n.group == "robot":
            entry = (robot_ledger(robot) or {}).get(n.name)
            found = any(
                v.ledger == n.name and entry is not None and _same(v.value, entry.value)
                for v in values
            )
        else:
            path = f"{n.group}.{n.name}"
            found = any(v.set == path and _text(v.value) == n.value for v in values)
        if not found:
            missing.append(f"{n.group} {n.name} = {n.value}")
    return missing


def unclassified_fields(model: type[BaseModel]) -> list[str]:
    """Fields of a parameter model whose default has no class and that are not scenario."""
    out = []
    for name, info in model.model_fields.items():
        origin, scenario = field_origin(info.json_schema_extra)
        if origin is None and scenario is None:
            out.append(name)
    return out


def counts(numbers: list[Number]) -> dict[str, int]:
    """How many numbers of each listed class (zeros included), in :data:`LISTED` order."""
    c = Counter(n.klass for n in numbers)
    return {k: c.get(k, 0) for k in LISTED}


def experiment_ledger(name: str, overrides: tuple[str, ...] = ()) -> list[Number]:
    """:func:`experiment_numbers` of a shipped experiment or spec file, as ``run`` sees it."""
    from walkrepro.runs.resolve import resolve_spec
    from walkrepro.sim.robot import load_robot
    from walkrepro.sim.world import build_scene
    from walkrepro.specs import yamlload
    from walkrepro.specs.files import find_spec_file, load_spec

    path = find_spec_file(name)
    raw, _ = yamlload.load_with_node(path.read_text(encoding="utf-8"))
    loaded = resolve_spec(load_spec(name, overrides))
    scene = build_scene(load_robot(loaded.spec.robot), loaded.spec)
    return experiment_numbers(loaded, raw, scene.model)
