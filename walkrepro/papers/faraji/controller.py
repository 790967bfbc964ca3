"""Paper II's whole controller (Fig. 3): 3LP gait, foot lift, IK, hip switch, SEA
compensation, state estimation and time-projection footstep adjustment.

Every control tick (≈ 2 ms):

1. phase clock: fixed step time T (Paper II keeps "a fixed timing instead of a phase-based
   control"), left swing first;
2. state estimation (:mod:`.estimation`): encoders + pelvis IMU → s₁ = p − f, s₂ = p − s,
   IIR (Eq. 26), derivative + 30-sample average, error e(t) against the 3LP gait (Eq. 15),
   smooth dead-zone (Eq. 27);
3. footstep adjustment (``stepping: on``): the time-projection footstep table (Fig. 13 B)
   times the sagittal error, truncated at 15 cm, divided by the pelvis height → attack
   angle added to the swing hip;
4. open loop (:mod:`.openloop`, :mod:`.lift`): Cartesian pelvis/feet targets with pelvis
   roll (Eq. 22), fixed and adaptive lift (Eqs. 23, 28-30) → IK; stance-hip torso
   regulation (Eq. 24); knee spring compensation (Eq. 21);
5. stance-ankle push-off (walkrepro, not in the paper; ``ankle_damping``, off by default and
   in every main spec): while walking, a motor offset on the stance ankle's spring adds the
   pelvis speed lacking along the commanded direction, τ_a = b max(0, −sign(v) e_ṗ) sign(v),
   b = D1 ω₁ (3LP's stance-ankle torque input, which the paper leaves free); none in place;
6. motor targets for the position servos (``Command.ctrl``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable
from dataclasses import astuple, dataclass, field, fields, replace
from functools import reduce
from operator import add
from typing import Annotated, Literal, NamedTuple

import numpy as np
import pinocchio as pin
from pydantic import Field, field_validator

from walkrepro.controllers.base import Command, Controller, ControllerParams
from walkrepro.controllers.ranges import (
    MAX_COUNT,
    MAX_DURATION,
    MAX_LENGTH,
    MAX_PHASE_TIME,
    MAX_SPEED,
)
from walkrepro.log.signals import SignalLayout, Signals
from walkrepro.papers.faraji import lift
from walkrepro.papers.faraji.dlqr import Dlqr
from walkrepro.papers.faraji.estimation import (
    IirFilter,
    KinematicState,
    MovingAverageDerivative,
    dead_zone,
)
from walkrepro.papers.faraji.gait import PeriodicGait
from walkrepro.papers.faraji.joints import LEFT, RIGHT, LegJoints, leg_joints
from walkrepro.papers.faraji.openloop import (
    LegIk,
    LegTargets,
    ankle_series_stiffness,
    relative_footstep_gains,
    series_stiffness,
    threelp_params_from_robot,
)
from walkrepro.papers.faraji.projection import TimeProjection, truncate_footstep
from walkrepro.papers.faraji.threelp import ThreeLP
from walkrepro.sim.robot import Robot
from walkrepro.sim.sensors import SensorSnapshot
from walkrepro.specs.origin import assumed, calibrated, paper

GRAVITY = 9.81  # [m/s^2]
#: Indices of the sagittal components in e = [p − f, p − s, ḟ, ṗ] (x, y interleaved).
SAGITTAL = np.array([0, 2, 4, 6])
#: Components of a point (x, y, z) [m], of a Jacobian's rows, and of a foot's force-torque
#: reading (fx, fy, fz, tx, ty, tz): fz is the normal load [N].
X, Y, Z = 0, 1, 2
FORCE_Z = 2
#: The logged signals, declared once (all floats; an array field is an array signal). Before
#: walking only ``phase`` (−1) is defined, and ``sway`` [m] only while swaying; a signal not
#: defined at a tick is NaN. A tick names its signals in a mapping (``Signals.of``).
SIGNALS = np.dtype(
    [(name, np.float64) for name in ("phase", "step_index", "swing_side")]
    + [(name, np.float64, (4,)) for name in ("e_raw", "e_dead_zone", "e_meas", "e_nominal")]
    + [
        (name, np.float64)
        for name in (
            "footstep_raw",
            "footstep",
            "attack_angle",
            "theta_hat",
            "adaptive_lift",
            "pelvis_roll_cmd",
            "pelvis_pitch",
        )
    ]  # fmt: skip
    + [("q_cmd_legs", np.float64, (12,)), ("load", np.float64, (2,))]
    + [("ankle_torque", np.float64), ("sway", np.float64)]
)
SIGNAL_LAYOUT = SignalLayout.of_record(SIGNALS)


#: Largest pelvis roll amplitude [rad]: π/2 lays the robot on its side.
MAX_ROLL = math.pi / 2
#: Largest knee spring deflection μ at full body weight [rad]: 0.5 rad (29°) of spring
#: travel under the weight would leave the knee no range to walk with.
MAX_KNEE_DEFLECTION = 0.5
#: Largest stance ankle bias b [rad]: tilting the stance leg by b about the ankle moves the
#: CoM by ≈ b h over the sole; with COMAN's CoM height h ≈ 0.5 m, 0.2 rad moves it 0.1 m,
#: beyond the toe or heel of its 0.19 m sole (half-length 0.095 m): the robot would topple.
MAX_ANKLE_BIAS = 0.2
#: Largest scale on a model gain [-] (footstep gains, ankle damping): ten times the model's
#: gain turns a centimetre's error into a step past the 15 cm truncation.
MAX_GAIN_SCALE = 10.0
#: A dead-zone threshold on a position error [m]: at most a leg length.
ErrorBand = Annotated[float, Field(ge=0, le=MAX_LENGTH)]
#: A dead-zone threshold on a velocity error [m/s]: at most a walking speed.
RateBand = Annotated[float, Field(ge=0, le=MAX_SPEED)]
#: μ of Eq. 21 [rad], one knee's spring deflection at full body weight.
KneeDeflection = Annotated[float, Field(ge=-MAX_KNEE_DEFLECTION, le=MAX_KNEE_DEFLECTION)]


class TimeProjectionParams(ControllerParams):
    """Parameters of Paper II's controller (defaults: the paper's values)."""

    stepping: bool = Field(
        True,
        description="time-projection footstep adjustment on/off",
        json_schema_extra=paper(
            "Closed-Loop Control: time-projection footstep adjustment",
            scenario="open loop vs closed loop (Figs. 14-15)",
        ),
    )
    dead_zone: bool = Field(
        True,
        description="smooth dead-zones (Eq. 27) on the errors",
        json_schema_extra=paper(
            "Eq. 27: smooth dead-zones", scenario="the no-dead-zone ablation (Fig. 15)"
        ),
    )
    adaptive_lift: bool = Field(
        True,
        description="adaptive lift and foot pitch (Eqs. 28-30)",
        json_schema_extra=paper("Eqs. 28-30: adaptive lift", scenario="an ablation switch"),
    )
    speed: float = Field(
        0.0,
        ge=-MAX_SPEED,
        le=MAX_SPEED,
        description="commanded 3LP speed v [m/s] (Fig. 19)",
        json_schema_extra=paper(
            "Fig. 14: in place, v = 0", scenario="the commanded speed (Fig. 19)"
        ),
    )
    step_time: float = Field(
        0.4,
        gt=0,
        le=MAX_PHASE_TIME,
        description="T [s] (2.5 steps/s)",
        json_schema_extra=paper("Gait: T = 0.4 s, 2.5 steps/s", scenario="the step-time map"),
    )
    step_width: float = Field(
        0.25,
        gt=0,
        le=MAX_LENGTH,
        description="W [m] (Paper II: 25 cm)",
        json_schema_extra=paper("Gait: step width 0.25 m"),
    )
    roll_amplitude: float = Field(
        0.1,
        ge=0,
        le=MAX_ROLL,
        description="pelvis roll, Eq. 22 [rad]",
        json_schema_extra=paper("Eq. 22: 0.1 sin(πt/T)"),
    )
    lift_amplitude: float = Field(
        0.01,
        ge=0,
        le=MAX_LENGTH,
        description="swing lift, Eq. 23 [m]",
        json_schema_extra=paper("Eq. 23: 0.01 sin(πt/T)"),
    )
    hip_switch_ratio: float = Field(
        0.2,
        gt=0,
        le=1,
        description="t1 / T of Eq. 24",
        json_schema_extra=paper("Eq. 24: t_1 = 0.2 T"),
    )
    torso_term: Literal["link", "motor"] = Field(
        "motor",
        description="the stance-hip torso term of Eq. 24 as a motor target: 'motor' (the "
        "paper's, the default) is v = k_d(γ(θ_des − θ_m) + (1 − γ)(−θ_pitch)), target "
        "θ_m + θ_pitch from the pre-spring motor encoder, a motor torque k_d/β·θ_pitch "
        "(222 Nm/rad at 100 V/rad), the spring compensation on the tracking part only; "
        "'link' (walkrepro's earlier departure on robots/coman, an ablation) targets the link "
        "encoder + θ_pitch, which also feeds back the hip spring's deflection: the servo in "
        "series with the spring",
        json_schema_extra=paper(
            "Eq. 24: v = k_d(γ(θ_des − θ_act) + (1 − γ)(−θ_pitch)) on the motor encoder"
        ),
    )
    zeta: float = Field(
        0.1, gt=0, le=1, description="IIR ζ, Eq. 26", json_schema_extra=paper("Eq. 26: ζ = 0.1")
    )
    velocity_window: int = Field(
        30,
        ge=1,
        le=MAX_COUNT,
        description="derivative averaging window [samples]",
        json_schema_extra=paper("State Estimation: 30-sample velocity averaging"),
    )
    dead_zone_thresholds: tuple[ErrorBand, ErrorBand, RateBand, RateBand] = Field(
        (0.0275, 0.0271, 0.275, 0.052),
        description="a of Eq. 27 for e1x, e2x [m], de1x, de2x [m/s]: the standard deviation "
        "of the filtered errors of the open-loop in-place gait (Fig. 9 procedure). The specs "
        "take the declared calibration's value (experiments/calibration/faraji.yaml, "
        "in_place_open_loop 2-10.5 s); this default is the first model's, before calibration",
        json_schema_extra=calibrated(
            "experiments/calibration/faraji.yaml (Fig. 9 procedure); this default is the first model's, before calibration"
        ),
    )
    footstep_limit: float = Field(
        0.15,
        gt=0,
        le=MAX_LENGTH,
        description="truncation [m] (Fig. 13: 15 cm)",
        json_schema_extra=paper("Fig. 13 / Strong Pushes: 15 cm truncation"),
    )
    knee_deflection: tuple[KneeDeflection, KneeDeflection] | None = Field(
        None,
        description="μ of Eq. 21 [rad]: (μ_left, μ_right) as the paper identifies them "
        "(Fig. 7), or one value for both knees (read as the pair); None derives it from the "
        "home keyframe's knee pre-load (deflection at full body weight)",
        json_schema_extra=assumed(
            "None derives μ from the home keyframe's knee pre-load at full body weight"
        ),
    )

    @field_validator("knee_deflection", mode="before")
    @classmethod
    def _one_mu_for_both_knees(cls, value: object) -> object:
        """One number is μ for both knees: (μ, μ)."""
        if isinstance(value, int | float) and not isinstance(value, bool):
            return (value, value)
        return value

    spring_compensation: Literal["posture", "posture_series", "knees"] = Field(
        "knees",
        description="Eq. 21: 'knees' (the paper's, the default) is a load-scaled offset "
        "−μ·|F|/(m g) on the knee targets only (μ: knee_deflection); 'posture_series' "
        "(walkrepro's earlier departure on robots/coman, an ablation) adds the hip pitch, knee "
        "and ankle pitch joints' static deflection under the body weight at the sole point of "
        "the commanded posture, each torque divided by the running servo in series with the "
        "spring, 1/(1/k + 1/kp), and the home pre-load on the other leg joints; 'posture' "
        "divides by the spring alone (docs/analysis/faraji.md)",
        json_schema_extra=paper("Eq. 21: a load-scaled offset on the knee targets"),
    )
    stance_ankle_bias: float = Field(
        0.0,
        ge=-MAX_ANKLE_BIAS,
        le=MAX_ANKLE_BIAS,
        description="a load-scaled offset added to the stance ankle pitch targets on top of "
        "the spring compensation, load·b [rad]: the stance bias of Eq. 21's compensation "
        "that no source gives; pinned by declared calibration (experiments/calibration/"
        "faraji.yaml: the open-loop in-place gait makes no progression). Within ±0.2 rad: "
        "the stance leg tilted by b moves the CoM by ≈ b·h over the sole, and at COMAN's "
        "h ≈ 0.5 m, 0.2 rad (0.1 m) puts it past the toe or heel of the 0.19 m sole",
        json_schema_extra=calibrated(
            "experiments/calibration/faraji.yaml: the open-loop in-place gait makes no progression"
        ),
    )
    footstep_scale: float = Field(
        1.0,
        ge=0,
        le=MAX_GAIN_SCALE,
        description="scale on the time-projection footstep gains (1 = the 3LP tables, the "
        "paper's; robots/coman's ablations run 0.5, walkrepro's earlier departure)",
        json_schema_extra=paper("Fig. 13: the 3LP time-projection footstep gains, unscaled"),
    )
    attack_in_ik: bool = Field(
        False,
        description="add the footstep adjustment to the swing foot's Cartesian target "
        "(IK keeps the foot flat) instead of the swing hip angle (Paper II)",
        json_schema_extra=paper("Fig. 3: the adjustment goes to the swing hip angle"),
    )
    leg_inertia: bool = Field(
        True,
        description="3LP legs with the robot's pitch inertia about their CoM (Paper II: each "
        "pendulum has 'a mass in the middle and inertia'); false: point-mass legs",
        json_schema_extra=paper("3LP: each pendulum has a mass in the middle and inertia"),
    )
    role_velocities: bool = Field(
        True,
        description="differentiate s1 = p - f and s2 = p - s by role (Paper II, State "
        "Estimation): the feet's rate histories swap at each touchdown; false: per foot",
        json_schema_extra=paper("State Estimation: velocities of s1 = p - f and s2 = p - s"),
    )
    ankle_damping: float = Field(
        0.0,
        ge=0,
        le=MAX_GAIN_SCALE,
        description="stance-ankle push-off gain (walkrepro's, not the paper's; 0, the "
        "default, is the paper's free ankle): τ_a = b · max(0, −sign(v) · e_ṗ) · sign(v), "
        "b = ankle_damping × D1 ω₁ [Nm s/m] (damping rate b / D1 = the 3LP falling rate ω₁), "
        "realised as a motor offset τ_a / k_eff through the ankle spring: it only adds speed "
        "along the commanded direction, none in place (v = 0)",
        json_schema_extra=paper(
            "3LP / Fig. 3: no stance-ankle torque command (the ankle is left free)"
        ),
    )
    table_samples: int = Field(
        100,
        ge=2,
        le=MAX_COUNT,
        description="look-up-table samples per step",
        json_schema_extra=assumed(
            "look-up table resolution: 100 samples per step, 4 ms at T = 0.4 s, twice the control period"
        ),
    )
    start_time: float = Field(
        0.5,
        ge=0,
        le=MAX_DURATION,
        description="stand still before the first step [s]",
        json_schema_extra=assumed(
            "the robot stands 0.5 s before its first step (the paper starts from standing)"
        ),
    )
    ramp_steps: int = Field(
        3,
        ge=1,
        le=MAX_COUNT,
        description="steps over which roll/lift/width/speed ramp up",
        json_schema_extra=assumed(
            "roll, lift, width and speed ramp up over 3 steps from standing (the paper starts from standing)"
        ),
    )
    sway_steps: float = Field(
        0.0,
        ge=0,
        le=MAX_COUNT,
        description="double-support sway before walking [steps]",
        json_schema_extra=assumed("no double-support sway before walking"),
    )
    velocity_ramp_steps: int = Field(
        5,
        ge=1,
        le=MAX_COUNT,
        description="steps over which the speed ramps up",
        json_schema_extra=assumed("the commanded speed ramps up over 5 steps (2 s)"),
    )


class Sagittal(NamedTuple):
    """The sagittal (x) components of the 3LP relative state e = [p − f, p − s, ḟ, ṗ]
    (Eq. 15), in the heading frame: f the swing foot, s the stance foot, p the pelvis."""

    p_f: float
    """(p − f)_x: the pelvis ahead of the swing foot [m]."""
    p_s: float
    """(p − s)_x: the pelvis ahead of the stance foot [m]."""
    f_dot: float
    """ḟ_x: the swing foot's velocity over the ground (relative to the stance foot) [m/s]."""
    p_dot: float
    """ṗ_x: the pelvis's velocity over the ground (relative to the stance foot) [m/s]."""


class Estimate(NamedTuple):
    """One tick's state estimation (Fig. 3 D), filtered (Eq. 26)."""

    feet: list[float]
    """Sagittal sole positions relative to the pelvis, (left, right) [m]."""
    feet_vel: list[float]
    """Their rates, 30-sample averaged derivative, (left, right) [m/s]."""
    forces: list[float]
    """Normal loads of the feet's F/T sensors, (left, right) [N]."""
    pitch: float
    """Pelvis pitch in the heading frame (IMU) [rad]."""


class OpenLoop(NamedTuple):
    """The open-loop posture of a tick (Fig. 3 B) and the terms it came from."""

    q_open: list[float]
    """IK joint angles of the leg vector, before the footstep feedback [rad], (12,)."""
    roll_cmd: float
    """Pelvis roll command, Eq. 22, positive lifts the left hip [rad]."""
    theta_hat: float
    """Swing-hip angle estimate θ̂ of Eq. 28 [rad]."""
    lift: float
    """Adaptive lift Δz of Eqs. 29-30 [m]."""


@dataclass(frozen=True)
class Setup:
    """What ``reset`` derives from the robot and :class:`TimeProjectionParams`: fixed for a run."""

    joints: LegJoints
    """Where the leg vector's joints sit (:func:`~.joints.leg_joints`)."""
    h: float
    """3LP pelvis height h1 [m]."""
    pw: float
    """Half the 3LP hip spacing pw [m]."""
    weight: float
    """Body weight m g [N]."""
    home_ctrl: np.ndarray
    """Motor targets of the home keyframe [rad], shape (nu,)."""
    home_width: float
    """Lateral distance between the soles at home [m]."""
    home_x: float
    """Mean sagittal sole position relative to the pelvis at home [m]."""
    leg_offset_full: np.ndarray
    """Eq. 21's motor offsets of the leg vector at full body weight [rad], shape (12,)."""
    thresholds: Sagittal
    """a of Eq. 27 per sagittal error [m, m, m/s, m/s]."""
    step_gains: list[list[float]]
    """The x row of the Δ(f − p)(T) table on the sagittal errors, shape (n, 4) [m/m, m s/m]."""
    step_slopes: list[list[float]]
    """Its slopes per interval, shape (n − 1, 4)."""
    posture_springs: bool
    """Eq. 21 with μ from the commanded posture (``spring_compensation`` posture*)."""
    v_legs: list[int]
    """Pinocchio velocity index of each leg-vector joint (Jacobian columns), shape (12,)."""
    stiffness_legs: list[float]
    """Spring (or spring-and-servo) stiffness of each leg-vector joint [Nm/rad]."""
    pin_legs: slice | np.ndarray
    """The leg vector's entries in Pinocchio's q."""
    sole_frames: tuple[int, int]
    """Pinocchio frame ids of the (left, right) sole points."""
    ankle_b: float
    """Stance-ankle push-off gain b [Nm s/m] (0: off)."""
    direction: float
    """Sign of the commanded speed [-]."""
    ankle_rad_per_nm: float
    """Motor offset per Nm of forward ankle torque through the spring [rad/Nm]."""


@dataclass
class StepState:
    """What a tick changes: the filters, the phase clock and the step-to-step blends."""

    pos_filter: IirFilter
    """Eq. 26's IIR on the sagittal sole positions."""
    vel_filter: MovingAverageDerivative
    """Their 30-sample averaged derivative."""
    force_filter: IirFilter
    """Eq. 26's IIR on the feet's normal loads."""
    gait: PeriodicGait
    """This step's periodic 3LP gait (its speed ramps up)."""
    width: float
    """This step's width [m]; ``width_prev`` the last step's."""
    width_prev: float
    end_x: dict[str, float]
    """Commanded sagittal sole positions relative to the pelvis at the end of the last step,
    by leg ("l", "r") [m]; ``end_y`` the lateral ones."""
    end_y: dict[str, float]
    k: int = -1
    """Step index (−1 before the first step)."""
    side: int = 1
    """d = +1 while the left leg swings, −1 for the right."""
    speed: float = 0.0
    """This step's commanded 3LP speed [m/s]."""
    start_off: dict[str, float] = field(default_factory=lambda: {"swing": 0.0, "stance": 0.0})
    """Offsets of the swing and stance targets from the gait at touchdown, blended out [m]."""
    attack: float = 0.0
    """Attack angle on the swing hip [rad] (footstep adjustment / h1)."""
    last: tuple[float, float, float, float] | None = None
    """The last tick's (swing x, stance x, swing y, stance y) targets [m]."""


@dataclass
class TickTiming:
    """Wall time of the tick's parts [ns], summed over the run."""

    estimation: int = 0
    feedback: int = 0
    ik: int = 0
    output: int = 0


def _sides(d: int) -> tuple[int, int]:
    """(swing, stance) legs for side d (+1: the left swings)."""
    return (LEFT, RIGHT) if d > 0 else (RIGHT, LEFT)


class TimeProjectionController(Controller):
    """Paper II: 3LP + DLQR + time-projection footstep adjustment, position-controlled."""

    Params = TimeProjectionParams

    def reset(self, robot: Robot, params: ControllerParams, control_period: float) -> None:
        """Build the 3LP model, gait, DLQR and look-up tables; reset the filters."""
        assert isinstance(params, TimeProjectionParams)
        self._p = p = params
        self._robot = robot
        self._dt = control_period
        # 3LP (Paper II's model), its DLQR (Eqs. 16-17) and the time-projection tables (Fig. 13).
        self.model = ThreeLP(threelp_params_from_robot(robot, p.leg_inertia))
        self.dlqr = Dlqr.solve(self.model, p.step_time)
        self._gaits: dict[float, PeriodicGait] = {}
        gait0 = self._gait(0.0)
        self.tp = TimeProjection.build(self.model, gait0, self.dlqr, p.table_samples)
        self.rel_gains = relative_footstep_gains(self.model, self.tp)
        self._ik = LegIk(robot)
        self._kin = KinematicState(robot)
        self._pin_data = robot.pin_model.createData()
        self._pin_q = pin.neutral(robot.pin_model)
        self._c = self._setup(robot, leg_joints(robot))
        c = self._c
        self._s = StepState(
            pos_filter=IirFilter(p.zeta, 2),  # only the sagittal (x) sole positions
            vel_filter=MovingAverageDerivative(p.velocity_window, 2, control_period),
            force_filter=IirFilter(p.zeta, 2),
            gait=gait0,
            width=c.home_width,
            width_prev=c.home_width,
            end_x={"l": c.home_x, "r": c.home_x},
            end_y={"l": 0.5 * c.home_width, "r": -0.5 * c.home_width},
        )
        # Every speed of the velocity ramp (`_new_step`), solved now rather than mid-run.
        for k in range(p.velocity_ramp_steps):
            self._gait(p.speed * min(1.0, (k + 1) / p.velocity_ramp_steps))
        self._timing = TickTiming()

    def _setup(self, robot: Robot, joints: LegJoints) -> Setup:
        """The run's fixed quantities (:class:`Setup`) from the robot and the parameters."""
        p = self._p
        legs = joints.actuators
        lf, rf, _, _ = self._kin.feet(np.array([1.0, 0, 0, 0]), robot.home_joint_pos)
        stiffness = robot.spring_stiffness
        if stiffness is None:
            stiffness_legs = []
        elif p.spring_compensation == "posture_series":
            names = [robot.joint_names[a] for a in joints.actuator_list]
            stiffness_legs = [series_stiffness(robot, name) for name in names]
        else:
            stiffness_legs = [float(k) for k in stiffness[legs]]
        pin_q = robot.pin_q_idx[legs]
        contiguous = np.array_equal(pin_q, np.arange(pin_q.min(), pin_q.min() + pin_q.size))
        # Stance-ankle push-off: gain [Nm s/m] (b = D1 ω₁ scaled), and the motor offset per Nm
        # of a forward (pelvis-advancing) ankle torque [rad/Nm], signed by the IK.
        b = p.ankle_damping * self.model.axis.mass[0, 0] * self.model.omega_fall
        k_eff = ankle_series_stiffness(robot)
        setup = Setup(
            joints=joints,
            h=self.model.params.h1,
            pw=self.model.params.pw,
            weight=robot.total_mass * GRAVITY,
            home_ctrl=robot.home_ctrl.copy(),
            home_width=float(lf[Y] - rf[Y]),
            home_x=0.5 * float(lf[X] + rf[X]),
            leg_offset_full=self._spring_offsets(robot, joints),
            thresholds=Sagittal(*(float(a) for a in p.dead_zone_thresholds)),
            step_gains=self.rel_gains[:, X, SAGITTAL].tolist(),
            step_slopes=np.diff(self.rel_gains, axis=0)[:, X, SAGITTAL].tolist(),
            posture_springs=(
                p.spring_compensation != "knees"
                and p.knee_deflection is None
                and robot.spring_stiffness is not None
            ),
            v_legs=[int(i) for i in robot.pin_v_idx[legs]],
            stiffness_legs=stiffness_legs,
            # A slice assigns a list of floats cheaper than an index array.
            pin_legs=slice(int(pin_q.min()), int(pin_q.max()) + 1) if contiguous else pin_q,
            sole_frames=(
                robot.pin_model.getFrameId("left_sole"),
                robot.pin_model.getFrameId("right_sole"),
            ),
            ankle_b=float(b) if p.speed else 0.0,
            direction=math.copysign(1.0, p.speed),
            ankle_rad_per_nm=0.0,
        )
        if k_eff > 0:  # the sign needs the IK at the start posture, so the setup first
            sign = self._ankle_forward_sign(setup)
            setup = replace(setup, ankle_rad_per_nm=sign / k_eff)
        return setup

    def _spring_offsets(self, robot: Robot, joints: LegJoints) -> np.ndarray:
        """Eq. 21's motor offsets of the leg vector at full body weight [rad], shape (12,).

        The home keyframe's motor-minus-link offset (static spring + servo pre-load) carries
        half the weight: twice it at full load. ``spring_compensation="knees"`` keeps the
        knees' only; ``knee_deflection`` gives them as −μ (δθ = −|F|/(m g) μ, per knee).
        """
        p = self._p
        offset = robot.home_ctrl - robot.home_joint_pos
        full = 2.0 * offset[joints.actuators]
        knees = list(joints.knee)
        if p.spring_compensation == "knees":
            kept = full[knees].copy()
            full[:] = 0.0
            full[knees] = kept
        if p.knee_deflection is not None:
            for i, mu_i in zip(knees, p.knee_deflection, strict=True):  # (left, right)
                full[i] = -mu_i
        return full

    def _ankle_forward_sign(self, c: Setup) -> float:
        """Sign of the ankle pitch change that moves the pelvis forward over a stance foot.

        From the IK at the start posture: the sole 1 mm further behind the pelvis.
        """
        z, y, x = -c.h, 0.5 * c.home_width, c.home_x
        q0 = self._ik.solve_level(0.0, (x, y, z), (x, -y, z), 0.0, 0.0)
        q1 = self._ik.solve_level(0.0, (x - 1e-3, y, z), (x, -y, z), 0.0, 0.0)
        ankle = c.joints.ankle_pitch.left
        return math.copysign(1.0, q1[ankle] - q0[ankle])

    def _gait(self, speed: float) -> PeriodicGait:
        """The periodic gait at ``speed`` [m/s], solved once per speed."""
        gaits = self._gaits
        if speed not in gaits:
            gaits[speed] = PeriodicGait.solve(
                self.model, speed, self._p.step_time, self._p.step_width
            )
        return gaits[speed]

    # ------------------------------------------------------------------------------------

    def step(self, t: float, sensors: SensorSnapshot) -> Command:
        """One control tick (see the module docstring).

        Plain-float arithmetic throughout: the quantities are a few scalars per tick, for
        which numpy's per-call overhead would dominate.
        """
        clock, timing = time.perf_counter_ns, self._timing
        p, c, s = self._p, self._c, self._s
        t0 = clock()
        # ---- estimation (runs from t = 0 so the filters are warm at the first step)
        est = self._estimate(t, sensors)
        t1 = clock()
        timing.estimation += t1 - t0
        t_walk = t - p.start_time
        if t_walk < -p.sway_steps * p.step_time:
            home = Signals.of(SIGNAL_LAYOUT, {"phase": -1.0})
            return Command(ctrl=c.home_ctrl.copy(), signals=home)
        if t_walk < 0.0:
            command = self._sway(t_walk)
            timing.ik += clock() - t1
            return command

        # ---- phase clock: a fixed step time T, left swing first
        T = p.step_time
        k = int(t_walk // T)
        phase = t_walk - k * T
        events = self._new_step(k) if k != s.k else ()
        rel = Sagittal(*s.gait.sagittal_relative_state(phase))  # the nominal 3LP gait
        meas, err, err_dz = self._errors(est, rel)
        step_raw, step = self._footstep(phase, err_dz)
        t2 = clock()
        timing.feedback += t2 - t1

        open_loop = self._open_loop(k, phase, rel, err)
        t3 = clock()
        timing.ik += t3 - t2

        q_des, ctrl_legs, ankle_torque = self._motor_targets(phase, sensors, est, open_loop, err)
        ctrl = c.home_ctrl.copy()
        ctrl[c.joints.actuators] = ctrl_legs
        ctrl[c.joints.waist_roll] -= open_loop.roll_cmd  # keep the torso upright (Eq. 22)
        signals = {
            "phase": phase,
            "step_index": float(k),
            "swing_side": float(s.side),
            "e_raw": err,
            "e_dead_zone": err_dz,
            "e_meas": meas,
            "e_nominal": rel,
            "footstep_raw": step_raw,
            "footstep": step,
            "attack_angle": s.attack,
            "theta_hat": open_loop.theta_hat,
            "adaptive_lift": open_loop.lift,
            "pelvis_roll_cmd": open_loop.roll_cmd,
            "pelvis_pitch": est.pitch,
            "q_cmd_legs": q_des,
            "load": [est.forces[LEFT] / c.weight, est.forces[RIGHT] / c.weight],
            "ankle_torque": ankle_torque,
        }
        command = Command(ctrl=ctrl, signals=Signals.of(SIGNAL_LAYOUT, signals), events=events)
        timing.output += clock() - t3
        return command

    def _estimate(self, t: float, sensors: SensorSnapshot) -> Estimate:
        """State estimation (Fig. 3 D): encoders + pelvis IMU → sole positions relative to
        the pelvis, IIR-filtered (Eq. 26), their derivative averaged over 30 samples, and the
        feet's filtered normal loads."""
        p, s = self._p, self._s
        left, right, _, pitch = self._kin.feet(sensors.imu_quat, sensors.joint_pos)
        feet = s.pos_filter.update((left[X], right[X]))  # sagittal [left, right]
        if p.role_velocities and s.k >= 0 and t - p.start_time >= (s.k + 1) * p.step_time:
            s.vel_filter.swap(LEFT, RIGHT)  # a touchdown: the rates of s₁, s₂ carry on by role
        feet_vel = s.vel_filter.update(feet)
        loads = (
            max(float(sensors.left_ft[FORCE_Z]), 0.0),
            max(float(sensors.right_ft[FORCE_Z]), 0.0),
        )
        return Estimate(feet, feet_vel, s.force_filter.update(loads), pitch)

    def _errors(self, est: Estimate, rel: Sagittal) -> tuple[Sagittal, Sagittal, Sagittal]:
        """The measured sagittal state, its error e(t) against the 3LP gait (Eq. 15) and the
        error through the smooth dead-zones (Eq. 27)."""
        swing, stance = _sides(self._s.side)
        f_x, s_x = est.feet[swing], est.feet[stance]
        fv_x, sv_x = est.feet_vel[swing], est.feet_vel[stance]
        meas = Sagittal(p_f=-f_x, p_s=-s_x, f_dot=fv_x - sv_x, p_dot=-sv_x)
        err = Sagittal(*(m - r for m, r in zip(meas, rel, strict=True)))
        if not self._p.dead_zone:
            return meas, err, err
        return meas, err, Sagittal(*map(dead_zone, err, self._c.thresholds))

    def _footstep(self, phase: float, err_dz: Sagittal) -> tuple[float, float]:
        """Time-projection footstep adjustment (Fig. 13 B, relative to the pelvis): the
        interpolated table times the error, truncated at 15 cm; sets the attack angle
        (adjustment / h1) on the swing hip. Returns (raw, truncated) adjustment [m]."""
        p, c = self._p, self._c
        i, a = self.tp.locate(phase)
        terms = (
            (g + a * slope) * e
            for g, slope, e in zip(c.step_gains[i], c.step_slopes[i], err_dz, strict=True)
        )
        step_raw = p.footstep_scale * reduce(add, terms)
        step = truncate_footstep(step_raw, p.footstep_limit)
        self._s.attack = step / c.h if p.stepping else 0.0
        return step_raw, step

    def _open_loop(self, k: int, phase: float, rel: Sagittal, err: Sagittal) -> OpenLoop:
        """The open-loop posture (Fig. 3 B): Cartesian targets in the level frame at the
        pelvis, with the pelvis roll (Eq. 22), the fixed (Eq. 23) and adaptive (Eqs. 28-30)
        lifts, and the gait's feet, through the leg IK."""
        p, c, s = self._p, self._c, self._s
        T, d = p.step_time, s.side
        # Adaptive lift (Eqs. 28-30), from the filtered (not dead-zoned) errors.
        theta_hat = lift.hip_angle_estimate(err.p_f, c.h) if p.adaptive_lift else 0.0
        dz_adapt = lift.adaptive_lift(phase, T, theta_hat, c.h)
        ramp = min(1.0, (k + phase / T) / p.ramp_steps)
        roll_mag = lift.pelvis_roll(phase, T, ramp * p.roll_amplitude)  # ≥ 0
        roll_cmd = d * roll_mag
        blend = 0.5 * (1.0 - math.cos(math.pi * phase / T))
        swing_y = d * 0.5 * (s.width_prev + (s.width - s.width_prev) * blend)
        stance_y = -d * 0.5 * s.width
        hip_rise = c.pw * math.sin(roll_mag)
        swing_x = -rel.p_f + s.start_off["swing"] * (1.0 - blend)
        if p.attack_in_ik:
            swing_x += c.h * math.tan(s.attack)
        stance_x = -rel.p_s + s.start_off["stance"] * (1.0 - blend)
        swing_z = -c.h + hip_rise + lift.fixed_lift(phase, T, ramp * p.lift_amplitude) + dz_adapt
        stance_z = -c.h - hip_rise
        swing = (swing_x, swing_y, swing_z)
        stance = (stance_x, stance_y, stance_z)
        swing_pitch = lift.foot_pitch_feedback(theta_hat)  # coman: +pitch = toes down
        if d > 0:
            q_open = self._ik.solve_level(roll_cmd, swing, stance, swing_pitch, 0.0)
        else:
            q_open = self._ik.solve_level(roll_cmd, stance, swing, 0.0, swing_pitch)
        s.last = (swing_x, stance_x, swing_y, stance_y)
        return OpenLoop(q_open, roll_cmd, theta_hat, dz_adapt)

    def _motor_targets(
        self,
        phase: float,
        sensors: SensorSnapshot,
        est: Estimate,
        open_loop: OpenLoop,
        err: Sagittal,
    ) -> tuple[list[float], list[float], float]:
        """The leg vector's motor targets: the attack angle on the swing hip, the hip switch
        (Eq. 24), the spring compensation (Eq. 21) and the stance-ankle push-off.

        Eq. 24 is v = k_d(γ(θ_des − θ_act) + (1 − γ)(−θ_pitch)) and the servo is
        v = k_d(ctrl − θ_m), θ_m the motor encoder ("position control only on the motor
        shaft"): the paper's torso term is the target θ_m + θ_pitch ('motor'), a voltage from
        the IMU pitch alone, a motor torque k_d/β·θ_pitch that the spring passes on. It gets
        no spring offset (a constant voltage there would be a torque bias on the torso).
        'link' targets the link encoder + θ_pitch: k_d(θ_pitch − spring deflection), the servo
        in series with the hip spring, with the offsets added after the switch.

        Returns:
            (q_des, the commanded posture with the attack angle [rad] (12,); the motor
            targets [rad] (12,); the push-off ankle torque [Nm]).
        """
        p, joints, s = self._p, self._c.joints, self._s
        swing, stance = _sides(s.side)
        q_des = list(open_loop.q_open)
        if not p.attack_in_ik:
            q_des[joints.hip_pitch[swing]] -= s.attack  # hip flexion is negative pitch in coman
        t1 = p.hip_switch_ratio * p.step_time
        paper_torso = p.torso_term == "motor"
        ctrl_legs = list(q_des)
        if paper_torso:
            self._compensate_springs(ctrl_legs, est.forces, open_loop.q_open, open_loop.roll_cmd)
        encoder = sensors.joint_pos
        if paper_torso and sensors.motor_pos is not None:
            encoder = sensors.motor_pos  # a robot without springs: the link angle is θ_m
        for leg, swinging in ((swing, True), (stance, False)):
            gamma = lift.hip_switch_gamma(phase, t1, swinging)
            torso = float(encoder[joints.hip_pitch_actuator[leg]]) + est.pitch  # pitch → 0
            i = joints.hip_pitch[leg]
            ctrl_legs[i] = gamma * ctrl_legs[i] + (1.0 - gamma) * torso
        if not paper_torso:
            self._compensate_springs(ctrl_legs, est.forces, open_loop.q_open, open_loop.roll_cmd)
        ankle_torque = self._ankle_push_off(phase, t1, err, ctrl_legs)
        return q_des, ctrl_legs, ankle_torque

    def _ankle_push_off(
        self, phase: float, t1: float, err: Sagittal, ctrl_legs: list[float]
    ) -> float:
        """Stance-ankle push-off through the ankle spring (walkrepro's, off by default): adds
        only the speed the pelvis lacks along the commanded direction, after the force
        transfer (the stance weight 1 − γ of Eq. 24's law, which also skips the rate
        estimates' touchdown transient). Adds its motor offset to ``ctrl_legs`` in place;
        returns the torque τ_a [Nm], forward positive."""
        c = self._c
        if not c.ankle_b > 0.0:
            return 0.0
        lack = max(0.0, -c.direction * err.p_dot)  # [m/s]
        ramp_in = 1.0 - lift.hip_switch_gamma(phase, t1, False)
        ankle_torque = c.direction * c.ankle_b * lack * ramp_in  # forward + [Nm]
        _, stance = _sides(self._s.side)
        ctrl_legs[c.joints.ankle_pitch[stance]] += ankle_torque * c.ankle_rad_per_nm
        return ankle_torque

    def _compensate_springs(
        self, ctrl_legs: list[float], forces: list[float], q_open: list[float], roll: float
    ) -> None:
        """Add the spring compensation of Eq. 21 to the legs' targets ``ctrl_legs`` in place.

        The load-scaled offsets at full weight (home-based); with posture springs, the
        sagittal joints' (hip pitch, knee, ankle pitch) static deflection under the body
        weight at the sole point of the commanded posture ``q_open`` instead [rad].
        """
        c, joints = self._c, self._c.joints
        load = (forces[LEFT] / c.weight, forces[RIGHT] / c.weight)
        offset = c.leg_offset_full
        for i, leg in enumerate(joints.leg_of):
            ctrl_legs[i] += load[leg] * offset[i]
        bias = self._p.stance_ankle_bias
        if bias:
            ctrl_legs[joints.ankle_pitch.left] += load[LEFT] * bias
            ctrl_legs[joints.ankle_pitch.right] += load[RIGHT] * bias
        if c.posture_springs:
            # Eq. 21 with μ from the commanded posture instead of home: the sagittal springs'
            # static deflection under the body weight at the sole point (the 3LP CoP).
            self._pin_q[c.pin_legs] = q_open
            for leg in (LEFT, RIGHT):
                sagittal = joints.sagittal[leg]
                mu = self._deflection(leg, roll, sagittal)
                for i, mu_i in zip(sagittal, mu, strict=True):
                    ctrl_legs[i] += load[leg] * (mu_i - offset[i])

    def timing(self) -> dict[str, float]:
        """Wall time [s] of the tick's parts: estimation (kinematics, filters), feedback
        (gait reference, errors, footstep table), ik (Cartesian targets, IK), output (hip
        switch, spring compensation, command and signals)."""
        spent = astuple(self._timing)
        return {f.name: ns * 1e-9 for f, ns in zip(fields(TickTiming), spent, strict=True)}

    def _spring_deflection(self, q_legs: np.ndarray, leg: int, roll: float) -> np.ndarray:
        """Motor-minus-link offsets of leg ``leg``'s joints at full body weight [rad], shape (6,).

        τ = Jᵀ (0, 0, m g): the sole-point Jacobian (Pinocchio, rigid twin) in the commanded
        posture ``q_legs``, the world-vertical weight expressed in the pelvis frame rolled by
        ``roll``; the offset is −τ / k, k the spring's stiffness (the home keyframe's
        pre-load is this at home within 10 %), or the servo and spring in series with
        ``spring_compensation="posture_series"``.
        """
        self._pin_q[self._c.pin_legs] = q_legs
        return np.array(self._deflection(leg, roll, self._c.joints.legs[leg]))

    def _deflection(self, leg: int, roll: float, joints: Iterable[int]) -> list[float]:
        """:meth:`_spring_deflection` of the leg-vector entries ``joints`` at the legs'
        posture already in the Pinocchio configuration (set once for both legs) [rad]."""
        c = self._c
        # computeFrameJacobian runs the forward kinematics it needs itself.
        jac = pin.computeFrameJacobian(
            self._robot.pin_model,
            self._pin_data,
            self._pin_q,
            c.sole_frames[leg],
            pin.LOCAL_WORLD_ALIGNED,
        )
        # (0, sin roll, cos roll) · J[:3]: the x row has a zero weight.
        jac_y, jac_z = jac[Y], jac[Z]
        s, co = math.sin(roll), math.cos(roll)
        out = []
        for i in joints:
            col = c.v_legs[i]
            torque = (s * float(jac_y[col]) + co * float(jac_z[col])) * c.weight
            out.append(-torque / c.stiffness_legs[i])
        return out

    def _sway(self, t_walk: float) -> Command:
        """Lateral sway in double support before the first step (walkrepro start-up).

        Paper II does not describe how the gait starts. The in-place 3LP gait needs a
        lateral pelvis velocity toward the stance foot at each touchdown; a pendulum of
        offset D = W/2 gets v₀ = D ω tanh(ω T / 2) (ω: 3LP falling frequency). The sway
        y(τ) = −A sin(π τ / T), A = v₀ T / π, growing over the sway, reaches it at τ = 0,
        moving toward the first stance foot (right).
        """
        p, c = self._p, self._c
        T = p.step_time
        dist = 0.5 * c.home_width
        w = self.model.omega_fall
        v0 = dist * w * math.tanh(0.5 * w * T)
        grow = min(1.0, 1.0 + t_walk / (p.sway_steps * T) * 1.0 + 0.5)
        y_p = -grow * v0 * T / math.pi * math.sin(math.pi * t_walk / T)
        z = -c.h
        targets = LegTargets(
            pelvis_roll=0.0,
            left=np.array([c.home_x, dist - y_p, z]),
            right=np.array([c.home_x, -dist - y_p, z]),
            left_pitch=0.0,
            right_pitch=0.0,
        )
        q = self._ik.solve(targets)
        ctrl = c.home_ctrl.copy()
        ctrl[c.joints.actuators] = q + 0.5 * c.leg_offset_full
        return Command(ctrl=ctrl, signals=Signals.of(SIGNAL_LAYOUT, {"phase": -1.0, "sway": y_p}))

    def _new_step(self, k: int) -> tuple[dict, ...]:
        """Touchdown bookkeeping at a phase change: side, width/speed ramps, blends."""
        p, c, s = self._p, self._c, self._s
        if s.k >= 0:
            s.side = -s.side
            sw_prev, st_prev = ("r", "l") if s.side > 0 else ("l", "r")
            if s.last is not None:  # the last tick's targets, by leg
                swing_x, stance_x, swing_y, stance_y = s.last
                s.end_x = {sw_prev: swing_x, st_prev: stance_x}
                s.end_y = {sw_prev: swing_y, st_prev: stance_y}
            else:
                s.end_x = dict(s.end_x)
                s.end_y = dict(s.end_y)
            # The landing swing foot got the attack angle: h·tan(attack) further forward.
            if not p.attack_in_ik:
                s.end_x[sw_prev] += c.h * math.tan(s.attack)
        s.k = k
        ramp = min(1.0, (k + 1) / p.ramp_steps)
        s.width_prev = s.width
        s.width = c.home_width + (p.step_width - c.home_width) * ramp
        s.speed = p.speed * min(1.0, (k + 1) / p.velocity_ramp_steps)
        gait = s.gait = self._gait(s.speed)
        d = s.side
        rel0 = Sagittal(*gait.relative_state(0.0, d)[SAGITTAL])
        sw, st = ("l", "r") if d > 0 else ("r", "l")
        s.start_off = {"swing": s.end_x[sw] - (-rel0.p_f), "stance": s.end_x[st] - (-rel0.p_s)}
        s.attack = 0.0
        return ({"kind": "phase", "step": k, "swing": "left" if d > 0 else "right"},)
