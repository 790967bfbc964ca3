"""Experiment specs: pydantic models, YAML loading with file:line errors, ``--set`` overrides.

A spec is the whole description of an experiment (robot, controller and its parameters,
world, disturbances, sensors, duration, and the paper's expectations). Loading happens in
two stages so every error can name the file, the line and the field:

1. :func:`walkrepro.specs.files.load_spec` parses YAML (remembering the line of every field), applies ``--set``
   overrides and validates the schema with pydantic.
2. :func:`walkrepro.runs.resolve.resolve_spec` checks names against the real registries: the robot folder, the
   controller type and its parameter model, body names in the compiled robot, metric names.
"""

from __future__ import annotations

import contextvars
import math
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any, Literal, NamedTuple

import yaml
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)

from walkrepro.errors import SpecError
from walkrepro.specs import yamlload
from walkrepro.specs.deviation import KnownDeviation
from walkrepro.specs.origin import assumed, scenario
from walkrepro.specs.sweeps import SweepParameter, SweepSpec
from walkrepro.specs.tags import ClaimTag


def _not_bool(value: Any) -> Any:
    """Refuse ``true``/``false`` where a number is expected (pydantic would read 1 and 0)."""
    if isinstance(value, bool):
        raise ValueError("expected a number, not a boolean")
    return value


#: A real number that is not a boolean; every spec model also refuses NaN and ±inf.
Real = Annotated[float, BeforeValidator(_not_bool)]
#: An integer that is not a boolean.
Count = Annotated[int, BeforeValidator(_not_bool)]
Vec3 = tuple[Real, Real, Real]

# Physical ranges of spec values. A value outside is a typo or a unit slip, never an
# experiment: each bound is far beyond anything the papers' robots could meet.
#: Longest run: one simulated hour [s].
MAX_DURATION = 3600.0
#: Physics timestep range [s]: below 1 µs a run would take days; above 10 ms MuJoCo's
#: contacts of a walking robot are unstable.
MIN_TIMESTEP, MAX_TIMESTEP = 1e-6, 0.01
#: Longest control period [s] (10 Hz).
MAX_CONTROL_PERIOD = 0.1
#: Memory a run may preallocate [bytes]: the runner's stage clock keeps one int64 per
#: control tick (``walkrepro.runs.runner.StageClock``), checked before anything is allocated.
MAX_RUN_MEMORY = 2**30
BYTES_PER_TICK = 8
#: Largest disturbance force [N] and torque [Nm] (norms): ten times a 100 kg robot's weight.
MAX_FORCE, MAX_TORQUE = 1e4, 1e3
#: Largest distance [m] of a hold's anchor from the held body's centre of mass at the grab
#: (``hold_offset``): an arm's reach.
MAX_HOLD_OFFSET = 0.5
#: Largest Coulomb friction coefficient (floor and obstacles).
MAX_FRICTION = 10.0
#: Longest contact time constant 1/ω [s] a spec may set (MuJoCo's default contact is 0.02 s).
MAX_CONTACT_TIME_CONSTANT = 0.1
#: Largest sensing delay [s].
MAX_DELAY = 1.0
#: Largest servo stiffness [Nm/rad] and joint friction loss [Nm].
MAX_POSITION_GAIN, MAX_FRICTION_LOSS = 1e6, 1e3
MAX_SPRING, MAX_DRIVE_BACKLASH = 1e5, 0.5  # [Nm/rad], [rad]
#: Obstacles: largest extent [m], distance of the centre from the origin [m], tilt [deg],
#: mass [kg].
MAX_OBSTACLE_SIZE, MAX_OBSTACLE_DISTANCE, MAX_TILT_DEG, MAX_OBSTACLE_MASS = 100.0, 1e3, 90.0, 1e5
#: Nesting depth and value count of a spec's YAML beyond which it is refused unread.
MAX_NESTING, MAX_VALUES = 32, 100_000


class _Strict(BaseModel):
    """Unknown fields are errors: a typo must never be silently ignored."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class PaperRef(_Strict):
    """Which paper, section and figure an experiment reproduces."""

    key: str = Field(description="paper key: a paper an installed plugin declares")
    section: str = ""
    figure: str = ""

    @field_validator("key")
    @classmethod
    def _known_paper(cls, key: str) -> str:
        return known_paper(key)


def known_paper(key: str) -> str:
    """``key`` if an installed plugin declares that paper (:func:`walkrepro.plugins.papers`),
    else a ``ValueError`` (a pydantic validator's error) listing them."""
    from walkrepro import plugins

    papers = plugins.papers()
    if key not in papers:
        raise ValueError(f"unknown paper {key!r}; valid papers: {', '.join(sorted(papers))}")
    return key


def require_unique(what: str, names: Sequence[str]) -> None:
    """Raise ``ValueError`` (a pydantic validator's error) naming the names that repeat."""
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ValueError(f"{what} names must be unique; repeated: {', '.join(repeated)}")


class ControllerSpec(_Strict):
    """Controller type (a registry name) and its parameters (validated by the controller)."""

    type: str
    params: dict[str, Any] = Field(default_factory=dict)


class FallSpec(_Strict):
    """When a run counts as a fall (TARGETS.md: pelvis below 60 % of nominal, or ground contact)."""

    pelvis_height_ratio: Real = Field(
        0.6,
        gt=0.0,
        lt=1.0,
        json_schema_extra=assumed(
            "TARGETS.md: a fall is the pelvis below 60 % of its nominal height"
        ),
    )
    non_foot_ground_contact: bool = Field(
        True,
        json_schema_extra=assumed("TARGETS.md: a fall is also any body but the feet on the ground"),
    )


class SimSpec(_Strict):
    """Physics and control timing.

    ``timestep`` and ``control_period`` in [s]; the control period must be a whole multiple
    of the timestep (zero-order hold between control ticks). ``duration`` is at most
    :data:`MAX_DURATION` (one simulated hour), and the memory the run preallocates per
    control tick must fit in :data:`MAX_RUN_MEMORY`.
    """

    timestep: Real = Field(
        0.0005,
        ge=MIN_TIMESTEP,
        le=MAX_TIMESTEP,
        description="[s]",
        json_schema_extra=assumed("2 kHz physics, the rate Papers I (§V-A) and III (§IV) ran at"),
    )
    control_period: Real = Field(
        0.0005,
        gt=0.0,
        le=MAX_CONTROL_PERIOD,
        description="[s]",
        json_schema_extra=assumed("control at the physics rate unless the paper gives its own"),
    )
    duration: Real = Field(
        gt=0.0,
        le=MAX_DURATION,
        description="[s], at most one hour",
        json_schema_extra=scenario("the experiment's duration"),
    )
    seed: Count = Field(
        0, ge=0, le=2**32 - 1, json_schema_extra=scenario("the experiment's noise seed")
    )
    fall: FallSpec = Field(default_factory=FallSpec)

    @field_validator("control_period")
    @classmethod
    def _control_multiple_of_timestep(cls, period: float, info: ValidationInfo) -> float:
        timestep = info.data.get("timestep")
        if timestep is None:
            return period  # the timestep's own error is reported
        ratio = period / timestep
        if round(ratio) < 1 or abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio):
            raise ValueError(
                f"must be a whole multiple of sim.timestep ({timestep} s), e.g. "
                f"{max(1, round(ratio)) * timestep:g} s"
            )
        return period

    @model_validator(mode="after")
    def _memory_fits(self) -> SimSpec:
        ticks = self.duration / self.control_period
        need = (ticks + 1) * BYTES_PER_TICK  # [bytes]
        if need > MAX_RUN_MEMORY:
            raise ValueError(
                f"{ticks:.3g} control ticks (duration / control_period) would need "
                f"{need / 2**30:.3g} GiB for the run's per-tick clock, more than "
                f"{MAX_RUN_MEMORY / 2**30:g} GiB; shorten sim.duration or lengthen "
                "sim.control_period"
            )
        return self

    @property
    def substeps(self) -> int:
        """Physics steps per control tick."""
        return int(round(self.control_period / self.timestep))

    @property
    def n_steps(self) -> int:
        """Physics steps in the whole run."""
        return int(round(self.duration / self.timestep))


class ObstacleSpec(_Strict):
    """A box in the world. ``size`` is the full extent [m]; ``position`` its centre [m], or
    with ``anchor: top`` the centre of its top face, about which it is then tilted (a step's
    height and tilt are set independently: the top face stays centred at ``position``)."""

    name: str = Field(pattern=r"^obstacle\w*$", description="geom name, must start with 'obstacle'")
    size: Vec3 = Field(description=f"full extent [m], each in (0, {MAX_OBSTACLE_SIZE:g}]")
    position: Vec3 = Field(description=f"[m], each within ±{MAX_OBSTACLE_DISTANCE:g}")
    anchor: Literal["center", "top"] = Field(
        "center", description="what `position` places and the tilt turns about"
    )
    tilt_x_deg: Real = Field(0.0, ge=-MAX_TILT_DEG, le=MAX_TILT_DEG, description="[deg]")
    tilt_y_deg: Real = Field(0.0, ge=-MAX_TILT_DEG, le=MAX_TILT_DEG, description="[deg]")
    fixed: bool = True
    mass: Real | None = Field(
        None, gt=0.0, le=MAX_OBSTACLE_MASS, description="[kg], required when not fixed"
    )
    friction: Real | None = Field(None, gt=0.0, le=MAX_FRICTION)
    allow_overlap: bool = Field(
        False,
        description="let the box overlap the robot's collision geoms at the home pose (a "
        "warning is printed); otherwise such an obstacle is an error, since MuJoCo would "
        "push the robot out of it at the first step",
    )
    solref: tuple[Real, Real] | None = Field(
        None,
        description="MuJoCo contact solref of the obstacle's contacts, in MuJoCo's own form "
        "((time constant [s], damping ratio), or (-stiffness, -damping)); default the contact "
        "in force (docs/contact.md). Requires `solref_reason`",
    )
    solref_reason: str | None = Field(
        None, min_length=1, description="why this obstacle departs from the contact in force"
    )

    @field_validator("size")
    @classmethod
    def _positive_size(cls, size: Vec3) -> Vec3:
        if min(size) <= 0:
            raise ValueError("every size component must be > 0 [m]")
        if max(size) > MAX_OBSTACLE_SIZE:
            raise ValueError(f"every size component must be <= {MAX_OBSTACLE_SIZE:g} [m]")
        return size

    @field_validator("position")
    @classmethod
    def _near_origin(cls, position: Vec3) -> Vec3:
        if max(abs(p) for p in position) > MAX_OBSTACLE_DISTANCE:
            raise ValueError(
                f"every position component must be within ±{MAX_OBSTACLE_DISTANCE:g} [m]"
            )
        return position

    @field_validator("solref")
    @classmethod
    def _sane_solref(cls, solref: tuple[float, float] | None) -> tuple[float, float] | None:
        # Positive: (time constant [s], damping ratio); negative: -(stiffness, damping).
        if solref is not None and not all(0 < abs(s) <= 1e6 for s in solref):
            raise ValueError("solref components must be non-zero and within ±1e6")
        return solref

    @model_validator(mode="after")
    def _free_needs_mass(self) -> ObstacleSpec:
        if not self.fixed and self.mass is None:
            raise ValueError("a movable obstacle (fixed: false) needs a mass [kg]")
        if self.solref is not None and self.solref_reason is None:
            raise ValueError(
                "an obstacle's own solref departs from the contact in force (docs/contact.md): "
                "say why in solref_reason"
            )
        return self


class ContactSpec(_Strict):
    """A departure from the contact in force (docs/contact.md) for a whole experiment, floor
    and obstacles: a linear contact of time constant 1/ω and damping ratio ζ, or (``sourced:
    true``) the sole's sourced stiffness under the robot's weight. ``reason`` says why."""

    time_constant: Real | None = Field(
        None, gt=0.0, le=MAX_CONTACT_TIME_CONSTANT, description="1/ω [s], at least 2 × sim.timestep"
    )
    sourced: bool = Field(False, description="the sole's sourced stiffness (docs/contact.md)")
    damping_ratio: Real = Field(1.0, gt=0.0, le=10.0, description="ζ [-]")
    reason: str = Field(min_length=1, description="why this experiment departs from the contact")

    @model_validator(mode="after")
    def _one_stiffness(self) -> ContactSpec:
        if (self.time_constant is None) == (not self.sourced):
            raise ValueError("give either time_constant [s] or sourced: true, not both or neither")
        return self


class WorldSpec(_Strict):
    """Ground and obstacles; the contact is docs/contact.md's unless ``contact`` departs."""

    floor_friction: Real = Field(
        1.0,
        gt=0.0,
        le=MAX_FRICTION,
        json_schema_extra=assumed("MuJoCo's default sliding friction, 1"),
    )
    obstacles: list[ObstacleSpec] = Field(default_factory=list)
    contact: ContactSpec | None = None
    cone: Literal["pyramidal", "elliptic"] | None = Field(
        None,
        description="MuJoCo's friction cone of the scene; None keeps the robot's own",
        json_schema_extra=assumed(
            "None: the robot's own cone (robots/<robot>/parameters.yaml, option_cone)"
        ),
    )
    condim: Literal[1, 3, 4, 6] | None = Field(
        None,
        description="contact dimensionality of the floor and obstacles (which set every "
        "robot contact's, by their priority); None keeps MuJoCo's default 3",
        json_schema_extra=assumed("None: MuJoCo's default condim 3 on the floor and obstacles"),
    )

    @field_validator("obstacles")
    @classmethod
    def _unique_names(cls, obstacles: list[ObstacleSpec]) -> list[ObstacleSpec]:
        require_unique("obstacle", [o.name for o in obstacles])
        return obstacles


class DisturbanceSpec(_Strict):
    """An external wrench on a named body over a time window: a push, or a human's hold.

    ``frame`` is ``world`` or a controller frame name (e.g. ``O_w``); a controller frame is
    frozen at the disturbance onset. ``ramp`` rises linearly over ``ramp_time`` and falls
    linearly over the last ``ramp_time`` of the window (a human's push that builds up, is
    held and is let go).

    ``kind: push`` (the default) is a force of time only: the profile times ``force`` and
    ``torque``; it never reads the robot's state, so it models a force the paper applied.

    ``kind: hold`` is a human's hand that grabs the body and holds it where it was at the
    onset (Lee et al. §VI-C: a human "pushes ... to block its motion"): a spring-damper
    between the body's centre of mass and its position at the grab (the human stands
    still), acting only along ``axes`` of ``frame``, engaged over the ramp and let go by
    ramping it down ("reduces the pushing force"), its force capped at ``max_force``. The
    force is an outcome of the hand's impedance and the robot's motion; it is logged every
    physics step like any disturbance, so a log replays exactly. ``hold_offset`` says where
    the hand holds: its anchor is the body's centre of mass at the grab plus this offset,
    along the held axes of ``frame`` (frozen at the grab) [m]; 0 holds the body where it was.
    """

    name: str
    body: str
    kind: Literal["push", "hold"] = "push"
    frame: str = "world"
    force: Vec3 = Field((0.0, 0.0, 0.0), description=f"[N], norm at most {MAX_FORCE:g}")
    torque: Vec3 = Field(
        (0.0, 0.0, 0.0),
        description=f"[Nm], norm at most {MAX_TORQUE:g}",
        json_schema_extra=assumed(
            "no torque: a push is a force at the body's centre of mass unless the spec gives one"
        ),
    )
    start: Real = Field(ge=0.0, le=MAX_DURATION, description="[s]")
    duration: Real = Field(gt=0.0, le=MAX_DURATION, description="[s]")
    profile: Literal["constant", "ramp"] = "constant"
    ramp_time: Real = Field(0.0, ge=0.0, le=MAX_DURATION)
    stiffness: Real = Field(0.0, ge=0.0, le=1e6, description="hold: the hand's stiffness [N/m]")
    damping: Real = Field(0.0, ge=0.0, le=1e5, description="hold: the hand's damping [N s/m]")
    max_force: Real = Field(
        0.0, ge=0.0, le=MAX_FORCE, description="hold: the largest force the hand exerts [N]"
    )
    axes: list[Literal["x", "y", "z"]] = Field(
        default_factory=list, description="hold: the axes of ``frame`` the hand holds"
    )
    hold_offset: Vec3 = Field(
        (0.0, 0.0, 0.0),
        json_schema_extra=assumed(
            "0: the hand holds the body's centre of mass where it grabbed it"
        ),
        description=(
            "hold: where the hand holds, along x, y, z of ``frame`` (frozen at the grab) from "
            "the body's centre of mass at the grab [m]; non-zero only on held axes, norm at "
            f"most {MAX_HOLD_OFFSET:g} m"
        ),
    )

    @field_validator("force", "torque")
    @classmethod
    def _bounded_wrench(cls, value: Vec3, info: ValidationInfo) -> Vec3:
        limit, unit = (MAX_FORCE, "N") if info.field_name == "force" else (MAX_TORQUE, "Nm")
        if math.hypot(*value) > limit:
            raise ValueError(f"the {info.field_name}'s norm must be <= {limit:g} [{unit}]")
        return value

    @model_validator(mode="after")
    def _profile_fits(self) -> DisturbanceSpec:
        if self.profile == "ramp" and not 0 < 2 * self.ramp_time <= self.duration:
            raise ValueError("a ramp needs 0 < 2 * ramp_time <= duration")
        return self

    @model_validator(mode="after")
    def _kind_fits(self) -> DisturbanceSpec:
        hold_fields = {
            "stiffness": self.stiffness,
            "damping": self.damping,
            "max_force": self.max_force,
            "axes": self.axes,
            "hold_offset": any(self.hold_offset),
        }
        if self.kind == "push":
            given = [k for k, v in hold_fields.items() if v]
            if given:
                raise ValueError(f"{', '.join(given)} belong to a hold (kind: hold), not a push")
            return self
        if any(self.force) or any(self.torque):
            raise ValueError("a hold's force is an outcome of its stiffness; give no force/torque")
        if self.stiffness <= 0 or self.max_force <= 0 or not self.axes:
            raise ValueError("a hold needs stiffness > 0, max_force > 0 and at least one axis")
        if len(set(self.axes)) != len(self.axes):
            raise ValueError("a hold's axes must not repeat")
        if self.profile != "ramp":
            raise ValueError("a hand grabs and lets go over a ramp: a hold needs profile: ramp")
        free = [a for a, v in zip("xyz", self.hold_offset, strict=True) if v and a not in self.axes]
        if free:
            raise ValueError(
                f"hold_offset is non-zero along {', '.join(free)}, which the hand does not hold "
                f"(axes: {', '.join(self.axes)}): an offset along a free axis would do nothing"
            )
        if math.hypot(*self.hold_offset) > MAX_HOLD_OFFSET:
            raise ValueError(
                f"hold_offset's norm must be <= {MAX_HOLD_OFFSET:g} m (an arm's reach from the "
                "held body's centre of mass)"
            )
        return self


class SensorsSpec(_Strict):
    """Sensor imperfections (standard deviations of white noise, quantization step, delay)."""

    joint_position_noise: Real = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description="[rad]",
        json_schema_extra=assumed("no noise unless the experiment models the robot's sensors"),
    )
    joint_position_quantization: Real = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description="encoder step [rad]",
        json_schema_extra=assumed("ideal encoders unless the experiment models them"),
    )
    joint_velocity_noise: Real = Field(
        0.0,
        ge=0.0,
        le=100.0,
        description="[rad/s]",
        json_schema_extra=assumed("no noise unless the experiment models the robot's sensors"),
    )
    imu_gyro_noise: Real = Field(
        0.0,
        ge=0.0,
        le=100.0,
        description="[rad/s]",
        json_schema_extra=assumed("no noise unless the experiment models the robot's sensors"),
    )
    imu_acc_noise: Real = Field(
        0.0,
        ge=0.0,
        le=1000.0,
        description="[m/s^2]",
        json_schema_extra=assumed("no noise unless the experiment models the robot's sensors"),
    )
    ft_force_noise: Real = Field(
        0.0,
        ge=0.0,
        le=MAX_FORCE,
        description="[N]",
        json_schema_extra=assumed("no noise unless the experiment models the robot's sensors"),
    )
    ft_torque_noise: Real = Field(
        0.0,
        ge=0.0,
        le=MAX_TORQUE,
        description="[Nm]",
        json_schema_extra=assumed("no noise unless the experiment models the robot's sensors"),
    )
    delay: Real = Field(
        0.0,
        ge=0.0,
        le=MAX_DELAY,
        description="sensor-to-controller delay [s], a whole number of control periods",
        json_schema_extra=assumed("no sensing delay unless the paper gives one"),
    )
    joint_position_offset: Real = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description="σ of each link encoder's fixed calibration offset, drawn once per seed "
        "(a systematic error: the same in every reading of the run) [rad]",
        json_schema_extra=assumed("no encoder offset unless the experiment models one"),
    )
    joint_backlash: dict[str, Real] = Field(
        default_factory=dict,
        description="total play between a link and its encoder by actuator name or glob "
        "(``*knee*``): the encoder follows the link only once the link has crossed the play "
        "[rad]; later entries win where globs overlap",
        json_schema_extra=assumed("no backlash unless the experiment models it"),
    )
    base_state: bool = Field(
        True,
        description="the simulator provides the floating-base pose and velocity",
        json_schema_extra=assumed(
            "the simulator gives the base state; a paper whose robot estimates it sets false"
        ),
    )

    @field_validator("joint_backlash")
    @classmethod
    def _non_negative(cls, play: dict[str, float]) -> dict[str, float]:
        bad = [k for k, v in play.items() if not 0 <= v <= 1.0]
        if bad:
            raise ValueError(f"backlash must be in [0, 1] [rad]; not so for {', '.join(bad)}")
        return play


class ActuatorsSpec(_Strict):
    """Per-experiment settings of the robot's actuators (hardware settings, not control).

    ``position_gain`` maps actuator names (or shell-style globs such as ``*ankle*``) to the
    stiffness of a position servo [Nm/rad]; e.g. Paper II's "stiffest gains" set every
    COMAN servo to 500 V/rad / β. Later entries win where globs overlap.
    """

    position_gain: dict[str, Real] = Field(
        default_factory=dict,
        json_schema_extra=assumed("the robot's own servo gains (robots/<robot>/parameters.yaml)"),
    )
    friction_loss: Real | None = Field(
        None,
        ge=0,
        le=MAX_FRICTION_LOSS,
        description="Coulomb friction [Nm] (MuJoCo frictionloss) on the DoF each actuator "
        "drives: the motor DoF of a drive or series-elastic joint, else the joint; None keeps "
        "the robot's value (dyros_red_actuated: the lab's published 0.9 Nm, 22 Nm at the ankle "
        "roll; robots/dyros_red_actuated/README.md)",
        json_schema_extra=assumed("None keeps the robot's value (robots/<robot>/parameters.yaml)"),
    )
    spring: dict[str, Real] = Field(
        default_factory=dict,
        description="spring constant K [Nm/rad] of the series-elastic joints whose actuator "
        "names match the globs (``*ankle_pitch``); the home pre-load is re-solved for it "
        "(walkrepro.sim.robot.with_scene_springs); later entries win where globs overlap",
        json_schema_extra=assumed("the robot's own springs (robots/<robot>/parameters.yaml)"),
    )
    backlash: dict[str, Real] = Field(
        default_factory=dict,
        description="width b [rad] of the dead band in series with the spring (drive "
        "backlash, walkrepro.sim.springs) of the joints whose actuator names match the globs; "
        "only joints whose spring is a dead-band tendon (coman_lab: knees, ankle pitch); not "
        "the encoder play of sensors.joint_backlash",
        json_schema_extra=assumed("the robot's own backlash (robots/<robot>/parameters.yaml)"),
    )
    torque_lag: Real | None = Field(
        None,
        gt=0,
        le=1.0,
        description="time constant [s] of the first-order torque loop of robots whose "
        "actuators have one (MuJoCo dyntype filterexact; dyros_red_actuated: 0.5 ms, "
        "assumed); None keeps the robot's value",
        json_schema_extra=assumed("None keeps the robot's value (robots/<robot>/parameters.yaml)"),
    )

    @field_validator("position_gain")
    @classmethod
    def _positive(cls, gains: dict[str, float]) -> dict[str, float]:
        return _each_in(gains, "gains", 0.0, MAX_POSITION_GAIN, "Nm/rad", low_open=True)

    @field_validator("spring")
    @classmethod
    def _positive_spring(cls, springs: dict[str, float]) -> dict[str, float]:
        return _each_in(springs, "springs", 0.0, MAX_SPRING, "Nm/rad", low_open=True)

    @field_validator("backlash")
    @classmethod
    def _band(cls, bands: dict[str, float]) -> dict[str, float]:
        return _each_in(bands, "backlash", 0.0, MAX_DRIVE_BACKLASH, "rad", low_open=False)


def _each_in(
    values: dict[str, float], what: str, low: float, high: float, unit: str, low_open: bool
) -> dict[str, float]:
    """``values`` if each lies in (low, high] (``low_open``) or [low, high], else a
    ValueError naming the range and the keys outside it."""
    bad = [k for k, v in values.items() if not (low < v if low_open else low <= v) or v > high]
    if bad:
        bracket = "(" if low_open else "["
        raise ValueError(
            f"{what} must be in {bracket}{low:g}, {high:g}] [{unit}]; not so for {', '.join(bad)}"
        )
    return values


Op = Literal["<", "<=", ">", ">=", "==", "between"]


class RelativeTo(_Strict):
    """An expectation value taken from another experiment: ``scale × experiment's metric``.

    For the papers' comparisons between runs ("scatter ≥ 2× the closed-loop spread",
    "lower peak force with impedance than without").
    """

    experiment: str
    metric: str | None = Field(None, description="defaults to the expectation's own metric")
    scale: Real = 1.0


class Expectation(ClaimTag, _Strict):
    """One of the paper's expectations: ``metric op value``, with its source in the paper.

    The value is either given (``value``) or taken from another experiment's run
    (``relative_to``). ``known_deviation`` marks an expectation the reproduction is known to
    miss: the reason and the band it measures today (:class:`KnownDeviation`).
    """

    metric: str
    op: Op
    value: Real | tuple[Real, Real] | None = None
    relative_to: RelativeTo | None = None
    source: str
    note: str = ""
    known_deviation: KnownDeviation | None = None
    calibrated: str | None = Field(
        None,
        description="the calibration parameter (experiments/calibration/<paper>.yaml) whose "
        "criterion this claim is: its row reads `calibrated` when it holds, counted apart "
        "from reproduced (docs/calibration.md)",
    )

    @model_validator(mode="after")
    def _calibrated_is_no_deviation(self) -> Expectation:
        if self.calibrated is not None and self.known_deviation is not None:
            raise ValueError(
                "a row cannot be both calibrated and a known deviation: a calibration "
                "criterion is met by construction; drop one of the two"
            )
        if self.known_deviation is not None and self.known_deviation.unmeasurable_cells:
            raise ValueError(
                "unmeasurable_cells belongs to a map claim's known deviation; an expectation "
                "that cannot be measured says observed: not measurable"
            )
        return self

    @model_validator(mode="after")
    def _value_matches_op(self) -> Expectation:
        if (self.value is None) == (self.relative_to is None):
            raise ValueError("give exactly one of value and relative_to")
        if self.relative_to is not None:
            if self.op == "between":
                raise ValueError("relative_to needs a single-number op (<, <=, >, >=, ==)")
            return self
        if self.op == "between":
            if not isinstance(self.value, tuple):
                raise ValueError("op 'between' needs value: [low, high]")
            if self.value[0] > self.value[1]:
                raise ValueError("op 'between' needs low <= high")
        elif isinstance(self.value, tuple):
            raise ValueError(f"op {self.op!r} needs a single number as value")
        return self

    @property
    def reference_metric(self) -> str:
        """The other experiment's metric a relative expectation compares with."""
        assert self.relative_to is not None
        return self.relative_to.metric or self.metric


class Origin(_Strict):
    """The provenance of a value a spec sets (walkrepro/specs/origin.py, docs/provenance.md)."""

    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True)

    klass: Literal["paper", "source", "assumed", "calibrated"] = Field(alias="class")
    source: str = Field(
        min_length=1,
        description="paper: section, table or equation; source: repository @ commit : path; "
        "assumed: the criterion, which uses no result; calibrated: the result it was chosen on",
    )


class ExperimentSpec(_Strict):
    """A whole experiment."""

    name: str = Field(
        pattern=r"^[A-Za-z0-9_\-]+$",
        max_length=100,
        description="names the run's folder: letters, digits, _ and -, at most 100",
    )
    description: str
    paper: PaperRef
    robot: str
    controller: ControllerSpec
    sim: SimSpec
    world: WorldSpec = Field(default_factory=WorldSpec)
    disturbances: list[DisturbanceSpec] = Field(default_factory=list)
    sensors: SensorsSpec = Field(default_factory=SensorsSpec)
    actuators: ActuatorsSpec = Field(default_factory=ActuatorsSpec)
    expect: list[Expectation] = Field(default_factory=list)
    #: Named sweep axes that set several fields (``walkrepro sweep``; see walkrepro/studies/sweep/).
    sweep_parameters: dict[str, SweepParameter] = Field(default_factory=dict)
    #: Declared maps: a sweep and the paper's claims about its result.
    sweeps: list[SweepSpec] = Field(default_factory=list)
    #: The class of each value this spec sets that is not the experiment's scenario, by
    #: dotted path (``controller.params.footstep_scale``); values shared by a paper's specs
    #: are classed in ``experiments/provenance/<paper>.yaml`` instead (docs/provenance.md).
    provenance: dict[str, Origin] = Field(default_factory=dict)

    @field_validator("world")
    @classmethod
    def _contact_within_guidance(cls, world: WorldSpec, info: ValidationInfo) -> WorldSpec:
        # MuJoCo's guidance (walkrepro/sim/contact_model.py): a contact's time constant is at least two
        # timesteps. The sourced contact's depends on the robot and is checked at build time.
        sim = info.data.get("sim")
        tc = world.contact.time_constant if world.contact is not None else None
        if sim is not None and tc is not None and tc < 2.0 * sim.timestep:
            raise ValueError(
                f"world.contact.time_constant ({tc:g} s) must be at least 2 × sim.timestep "
                f"({2.0 * sim.timestep:g} s), MuJoCo's guidance"
            )
        return world

    def to_yaml(self) -> str:
        """The resolved spec as YAML (every default filled in; empty sweep sections left out,
        so a spec without sweeps writes the same YAML as before they existed; likewise an
        obstacle's ``allow_overlap`` unless set)."""
        data = self.model_dump(mode="json")
        for key in ("sweep_parameters", "sweeps", "provenance"):
            if not data[key]:
                del data[key]
        for obstacle in data["world"]["obstacles"]:
            if not obstacle["allow_overlap"]:
                del obstacle["allow_overlap"]
        return yaml.safe_dump(data, sort_keys=False)


# --------------------------------------------------------------------------------------
# Loading with line numbers


class LoadedSpec(BaseModel):
    """A validated spec plus where it came from, so later errors can still cite lines."""

    model_config = ConfigDict(arbitrary_types_allowed=True, frozen=True)

    spec: ExperimentSpec
    source: str  # file path, for messages
    lines: dict[tuple[Any, ...], int]  # field path -> 1-based line
    overridden: frozenset[tuple[Any, ...]] = frozenset()

    def where(self, path: Sequence[Any]) -> str:
        """``file, line N, field a.b.c`` for a field path (nearest known line)."""
        return _where(self.source, self.lines, tuple(path), self.overridden)


def spec_from_yaml_text(text: str, source: str = "<spec>") -> ExperimentSpec:
    """Validate a spec given as YAML text (e.g. the ``spec.yaml`` attachment of a log)."""
    data, lines = _parse_yaml(text, source)
    _check_plain_data(data, source, lines, set())
    try:
        return ExperimentSpec.model_validate(data)
    except ValidationError as exc:
        raise SpecError(
            _format_validation(exc, source, lines, set(), model=ExperimentSpec)
        ) from None


def _display_path(path: Path) -> str:
    """The path as the user would type it: relative to the working directory if inside it."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


#: PyYAML's own error for nesting past its limit (6.0.4 and later).
_TOO_DEEP = "maximum nesting depth"


def _parse_yaml(text: str, source: str) -> tuple[Any, dict[tuple[Any, ...], int]]:
    """YAML to plain data plus the 1-based line of every mapping key and list item."""
    try:
        data, node = yamlload.load_with_node(text)
    except RecursionError:
        raise SpecError(
            f"{source}: the YAML is nested too deeply to read (a spec nests a few levels; "
            f"at most {MAX_NESTING})."
        ) from None
    except yamlload.DuplicateKeyError as exc:
        mark = exc.problem_mark
        raise SpecError(
            f"{source}, line {mark.line + 1}, column {mark.column + 1}: {exc.problem}. "
            "Remove one of the two."
        ) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = f", line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        if _TOO_DEEP in str(exc.problem):  # PyYAML >= 6.0.4 stops deep nesting itself
            raise SpecError(
                f"{source}{line}: the YAML is nested too deeply to read (a spec nests a few "
                f"levels; at most {MAX_NESTING})."
            ) from None
        raise SpecError(
            f"{source}{line}: YAML syntax error: {exc.problem or exc}. "
            "Check indentation, colons and quotes there."
        ) from None
    except yaml.YAMLError as exc:
        raise SpecError(f"{source}: YAML syntax error: {exc}.") from None
    if not isinstance(data, dict):
        raise SpecError(f"{source}: a spec must be a YAML mapping of fields (name, robot, ...).")
    lines: dict[tuple[Any, ...], int] = {}
    assert node is not None  # data is a mapping
    _collect_lines(node, lines)
    return data, lines


def _collect_lines(node: yaml.Node, out: dict[tuple[Any, ...], int]) -> None:
    """The 1-based line of every key and item under ``node`` (iterative: any depth)."""
    stack: list[tuple[yaml.Node, tuple[Any, ...]]] = [(node, ())]
    seen: set[int] = set()
    while stack:
        node, path = stack.pop()
        out.setdefault(path, node.start_mark.line + 1)  # a mapping value keeps its key's line
        if id(node) in seen or len(path) > MAX_NESTING:
            # An alias (``*name``) has its anchor's lines, read once; deeper than any spec
            # nests, _check_plain_data reports the data at the level where it got too deep.
            continue
        seen.add(id(node))
        if isinstance(node, yaml.MappingNode):
            for key_node, value_node in node.value:
                key = key_node.value
                out[(*path, key)] = key_node.start_mark.line + 1
                stack.append((value_node, (*path, key)))
        elif isinstance(node, yaml.SequenceNode):
            stack.extend((item, (*path, i)) for i, item in enumerate(node.value))


def _check_plain_data(
    data: Any,
    source: str,
    lines: Mapping[tuple[Any, ...], int],
    overridden: Iterable[tuple[Any, ...]],
    prefix: tuple[Any, ...] = (),
) -> None:
    """Refuse NaN and ±inf anywhere, and data nested or aliased beyond any spec's size.

    Runs before the schema, so fields the schema leaves open (``controller.params``,
    sweep grids, known deviations) are covered too.

    Raises:
        SpecError: naming file, line and field of the first offending value.
    """
    stack: list[tuple[tuple[Any, ...], Any]] = [(prefix, data)]
    count = 0  # aliases count each time they are used: pydantic would expand them too
    while stack:
        path, value = stack.pop()
        count += 1
        if count > MAX_VALUES:
            raise SpecError(
                f"{source}: more than {MAX_VALUES} values (YAML aliases expanded); a spec "
                "has a few hundred."
            )
        if isinstance(value, float) and not math.isfinite(value):
            raise SpecError(
                f"{_where(source, lines, path, overridden)}: must be a finite number "
                f"(got {value!r})."
            )
        if isinstance(value, dict | list):
            if len(path) - len(prefix) >= MAX_NESTING:
                raise SpecError(
                    f"{_where(source, lines, path, overridden)}: nested more than "
                    f"{MAX_NESTING} levels deep; a spec nests a few."
                )
            items = value.items() if isinstance(value, dict) else enumerate(value)
            stack.extend(((*path, k), v) for k, v in reversed(list(items)))


def _check_across_sections(loaded: LoadedSpec) -> None:
    """Checks that need two sections of the spec: the sensing delay is a whole number of
    control periods (the sensors hold back whole readings)."""
    sim, delay = loaded.spec.sim, loaded.spec.sensors.delay
    ticks = delay / sim.control_period
    if abs(ticks - round(ticks)) > 1e-6:
        raise SpecError(
            f"{loaded.where(('sensors', 'delay'))}: must be a whole number of control periods "
            f"({sim.control_period:g} s), e.g. {round(ticks) * sim.control_period:g} s "
            f"(got {delay:g})."
        )


#: How errors name an override: (prefix of the item, where the field's value came from).
#: The command line's ``--set``; the Python API's overrides (:func:`overrides_named`).
CLI_OVERRIDES = ("--set", "set with --set")
API_OVERRIDES = ("override", "set by an override")
_OVERRIDE_NAMES: contextvars.ContextVar[tuple[str, str]] = contextvars.ContextVar(
    "override_names", default=CLI_OVERRIDES
)


@contextmanager
def overrides_named(names: tuple[str, str]) -> Iterator[None]:
    """Inside, spec errors name overrides as ``names`` (:data:`API_OVERRIDES` for
    :func:`walkrepro.load`, whose user typed no ``--set``)."""
    token = _OVERRIDE_NAMES.set(names)
    try:
        yield
    finally:
        _OVERRIDE_NAMES.reset(token)


def _where(
    source: str,
    lines: Mapping[tuple[Any, ...], int],
    path: tuple[Any, ...],
    overridden: Iterable[tuple[Any, ...]] = (),
) -> str:
    field = ".".join(str(p) for p in path) or "(top level)"
    for o in overridden:
        if path[: len(o)] == o:
            return f"{source}, field {field} ({_OVERRIDE_NAMES.get()[1]})"
    for n in range(len(path), -1, -1):
        if path[:n] in lines:
            return f"{source}, line {lines[path[:n]]}, field {field}"
    return f"{source}, field {field}"


#: pydantic's error types of a number outside a bound.
_BOUND_ERRORS = frozenset({"greater_than", "greater_than_equal", "less_than", "less_than_equal"})


class Bounds(NamedTuple):
    """A number's bounds from its pydantic constraints (None: unbounded on that side).

    Attributes:
        lower: the lower bound, or None.
        lower_inclusive: whether ``lower`` itself is allowed (``ge``) or not (``gt``).
        upper: the upper bound, or None.
        upper_inclusive: whether ``upper`` itself is allowed (``le``) or not (``lt``).
    """

    lower: float | None
    lower_inclusive: bool
    upper: float | None
    upper_inclusive: bool

    @property
    def text(self) -> str:
        """Interval text, e.g. ``[-0.2, 0.2]`` or ``(0, 5]``."""
        lo = (
            "(-inf"
            if self.lower is None
            else f"{'[' if self.lower_inclusive else '('}{self.lower:g}"
        )
        hi = (
            "inf)"
            if self.upper is None
            else f"{self.upper:g}{']' if self.upper_inclusive else ')'}"
        )
        return f"{lo}, {hi}"


def _bounds(metadata: Iterable[Any]) -> Bounds | None:
    """The bounds among pydantic constraint metadata; None if there is none."""
    lo: float | None = None
    hi: float | None = None
    lo_in = hi_in = True
    for m in metadata:
        if getattr(m, "gt", None) is not None:
            lo, lo_in = m.gt, False
        if getattr(m, "ge", None) is not None:
            lo, lo_in = m.ge, True
        if getattr(m, "lt", None) is not None:
            hi, hi_in = m.lt, False
        if getattr(m, "le", None) is not None:
            hi, hi_in = m.le, True
    if lo is None and hi is None:
        return None
    return Bounds(lo, lo_in, hi, hi_in)


def _annotation_at(annotation: Any, part: Any) -> tuple[Any, list[Any]]:
    """The type one step into ``annotation`` (a model's field, a tuple's or list's item, a
    dict's value) and that step's constraint metadata."""
    import typing

    metadata: list[Any] = []
    while True:  # unwrap Annotated and Optional
        origin = typing.get_origin(annotation)
        if origin is Annotated:
            annotation, *extra = typing.get_args(annotation)
            for e in extra:
                metadata.extend(getattr(e, "metadata", [e]))
        elif origin in (typing.Union, type(int | None)):
            args = [a for a in typing.get_args(annotation) if a is not type(None)]
            if len(args) != 1:
                return None, metadata
            annotation = args[0]
        else:
            break
    if part is None:
        return annotation, metadata
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        field = annotation.model_fields.get(part) if isinstance(part, str) else None
        if field is None:
            return None, []
        inner, more = _annotation_at(field.annotation, None)
        return inner, [*field.metadata, *more]
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is tuple and isinstance(part, int) and args:
        item = args[0] if len(args) == 2 and args[1] is Ellipsis else args[min(part, len(args) - 1)]
        return _annotation_at(item, None)
    if origin is list and isinstance(part, int) and args:
        return _annotation_at(args[0], None)
    if origin is dict and args:
        return _annotation_at(args[1], None)
    return None, []


def field_bounds(model: type[BaseModel], loc: Sequence[Any]) -> Bounds | None:
    """The bounds of the number at ``loc`` in ``model`` (a field path: names, tuple or
    list indices, dict keys); None if it has none or ``loc`` is not a field."""
    annotation: Any = model
    metadata: list[Any] = []
    for part in loc:
        annotation, metadata = _annotation_at(annotation, part)
        if annotation is None:
            return None
    return _bounds(metadata)


def _format_validation(
    exc: ValidationError,
    source: str,
    lines: Mapping[tuple[Any, ...], int],
    overridden: Iterable[tuple[Any, ...]],
    prefix: tuple[Any, ...] = (),
    model: type[BaseModel] | None = None,
) -> str:
    """One paragraph: each error with file, line and field; a number out of its bounds
    names the field's whole range (``model``: the model validated, to look the range up)."""
    parts = []
    for err in exc.errors():
        # Drop pydantic's union-branch tags (e.g. 'float', 'tuple[float, float]') from paths.
        loc = tuple(
            p for p in err["loc"] if not (isinstance(p, str) and ("[" in p or p in _TYPE_TAGS))
        )
        path = (*prefix, *loc)
        msg = err["msg"]
        if msg.startswith("Value error, "):
            msg = msg[len("Value error, ") :]
        if err["type"] == "extra_forbidden":
            msg = "unknown field (check the spelling; see docs/spec-reference.md)"
        elif err["type"] == "missing":
            msg = "required field is missing"
        if err["type"] in _BOUND_ERRORS and model is not None:
            bounds = field_bounds(model, loc)
            if bounds is not None:
                msg = f"{msg}; must be in {bounds.text}"
        got = err.get("input")
        if err["type"] not in ("missing", "extra_forbidden") and not isinstance(got, dict | list):
            msg += f" (got {got!r})"
        parts.append(f"{_where(source, lines, path, overridden)}: {msg}")
    # Unions report one error per branch; keep each message once.
    unique = list(dict.fromkeys(parts))
    return "; ".join(unique) + "."


_TYPE_TAGS = {"float", "int", "str", "bool", "tuple", "list", "dict"}


def _apply_override(data: dict[str, Any], item: str) -> tuple[Any, ...]:
    """Apply one ``a.b.0.c=value`` override in place; returns the key path."""
    if "=" not in item:
        raise SpecError(
            f"{_OVERRIDE_NAMES.get()[0]} {item!r}: expected FIELD=VALUE, e.g. sim.duration=3."
        )
    key, _, raw = item.partition("=")
    parts: list[Any] = [int(p) if p.isdigit() else p for p in key.strip().split(".")]
    if not all(str(p) for p in parts):
        raise SpecError(f"{_OVERRIDE_NAMES.get()[0]} {item!r}: empty field name in {key!r}.")
    try:
        value = yamlload.load(raw) if raw.strip() else ""
    except RecursionError:
        raise SpecError(
            f"{_OVERRIDE_NAMES.get()[0]} {item!r}: the value is nested too deeply."
        ) from None
    except yamlload.DuplicateKeyError as exc:
        raise SpecError(f"{_OVERRIDE_NAMES.get()[0]} {item!r}: {exc.problem}.") from None
    except yaml.YAMLError as exc:
        if _TOO_DEEP in str(exc):
            raise SpecError(
                f"{_OVERRIDE_NAMES.get()[0]} {item!r}: the value is nested too deeply."
            ) from None
        value = raw
    node: Any = data
    for i, part in enumerate(parts[:-1]):
        nxt = parts[i + 1]
        if isinstance(node, list):
            if not isinstance(part, int) or part >= len(node):
                raise SpecError(
                    f"{_OVERRIDE_NAMES.get()[0]} {item!r}: {key} has no list item {part}."
                )
            node = node[part]
        elif not isinstance(node, dict):
            inner = ".".join(str(p) for p in parts[:i])
            raise SpecError(
                f"{_OVERRIDE_NAMES.get()[0]} {item!r}: {inner} is a single value ({node!r}), not a mapping with "
                f"a field {part!r}."
            )
        else:
            if part not in node or node[part] is None:
                node[part] = [] if isinstance(nxt, int) else {}
            node = node[part]
    last = parts[-1]
    if isinstance(node, list):
        if not isinstance(last, int) or last >= len(node):
            raise SpecError(f"{_OVERRIDE_NAMES.get()[0]} {item!r}: {key} has no list item {last}.")
        node[last] = value
    elif isinstance(node, dict):
        node[last] = value
    else:
        inner = ".".join(str(p) for p in parts[:-1])
        raise SpecError(
            f"{_OVERRIDE_NAMES.get()[0]} {item!r}: {inner} is a single value ({node!r}), not a mapping with a "
            f"field {last!r}."
        )
    return tuple(parts)
