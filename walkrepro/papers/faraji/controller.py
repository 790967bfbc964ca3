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
from typing import Annotated, Literal

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
LEG = slice(0, 12)
HIP_PITCH = {"l": 2, "r": 8}
KNEE = (3, 9)
ANKLE_PITCH = 4  # within a leg
#: Sagittal spring joints of a leg (hip pitch, knee, ankle pitch), indices within the leg.
SAGITTAL_JOINTS = (2, 3, 4)
#: Parts of a control tick reported by `TimeProjectionController.timing`.
SPLIT = ("estimation", "feedback", "ik", "output")
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


class TimeProjectionController(Controller):
    """Paper II: 3LP + DLQR + time-projection footstep adjustment, position-controlled."""

    Params = TimeProjectionParams

    def reset(self, robot: Robot, params: ControllerParams, control_period: float) -> None:
        """Build the 3LP model, gait, DLQR and look-up tables; reset the filters."""
        assert isinstance(params, TimeProjectionParams)
        self._p = p = params
        self._robot = robot
        self._dt = control_period
        self.model = ThreeLP(threelp_params_from_robot(robot, p.leg_inertia))
        self._h = self.model.params.h1
        self._pw = self.model.params.pw
        self.dlqr = Dlqr.solve(self.model, p.step_time)
        self._gaits: dict[float, PeriodicGait] = {}
        gait0 = self._gait(0.0)
        self.tp = TimeProjection.build(self.model, gait0, self.dlqr, p.table_samples)
        self.rel_gains = relative_footstep_gains(self.model, self.tp)
        self._rel_slopes = np.diff(self.rel_gains, axis=0)
        self._ik = LegIk(robot)
        self._kin = KinematicState(robot)
        self._weight = robot.total_mass * GRAVITY
        self._home_ctrl = robot.home_ctrl.copy()
        offset = robot.home_ctrl - robot.home_joint_pos  # static spring + servo pre-load
        # Leg joints carry half the weight at home: the offset at full load is twice it.
        self._leg_offset_full = 2.0 * offset[LEG]
        if p.spring_compensation == "knees":  # the knees' load-scaled offsets only
            knees = self._leg_offset_full[list(KNEE)].copy()
            self._leg_offset_full[:] = 0.0
            self._leg_offset_full[list(KNEE)] = knees
        if p.knee_deflection is not None:  # Eq. 21: δθ = −|F|/(m g) μ, per knee
            for i, mu_i in zip(KNEE, p.knee_deflection, strict=True):  # (left, right)
                self._leg_offset_full[i] = -mu_i
        self._offset_full = self._leg_offset_full.tolist()
        self._waist_roll = robot.joint_names.index("waist_roll")
        self._pin_data = robot.pin_model.createData()
        self._pin_q = pin.neutral(robot.pin_model)
        legs = robot.pin_q_idx[LEG]
        contiguous = np.array_equal(legs, np.arange(legs[0], legs[0] + legs.size))
        # A slice assigns a list of floats cheaper than an index array.
        self._pin_legs = slice(int(legs[0]), int(legs[-1]) + 1) if contiguous else legs
        self._sole_frames = tuple(
            robot.pin_model.getFrameId(n) for n in ("left_sole", "right_sole")
        )
        # Eq. 21 with μ from the commanded posture (see `step`): the legs' Jacobian columns
        # and spring stiffnesses.
        self._posture_springs = (
            p.spring_compensation != "knees"
            and p.knee_deflection is None
            and robot.spring_stiffness is not None
        )
        self._v_legs = [int(i) for i in robot.pin_v_idx[LEG]]
        stiffness = robot.spring_stiffness
        if stiffness is None:
            self._stiffness_legs = []
        elif p.spring_compensation == "posture_series":
            self._stiffness_legs = [series_stiffness(robot, j) for j in robot.joint_names[LEG]]
        else:
            self._stiffness_legs = [float(k) for k in stiffness[LEG]]
        lf, rf, _, _ = self._kin.feet(np.array([1.0, 0, 0, 0]), robot.home_joint_pos)
        self._home_width = float(lf[1] - rf[1])
        self._home_x = 0.5 * float(lf[0] + rf[0])
        # Only the sagittal (x) sole positions feed the controller: filter those.
        self._pos_filter = IirFilter(p.zeta, 2)
        self._vel_filter = MovingAverageDerivative(p.velocity_window, 2, control_period)
        self._force_filter = IirFilter(p.zeta, 2)
        self._thresholds = tuple(float(a) for a in p.dead_zone_thresholds)
        # The footstep row of the Δ(f − p)(T) table on the sagittal errors, as floats.
        self._step_gains = self.rel_gains[:, 0, SAGITTAL].tolist()
        self._step_slopes = self._rel_slopes[:, 0, SAGITTAL].tolist()
        self._k = -1
        self._side = 1
        self._speed_k = 0.0
        self._width_prev = self._width_k = self._home_width
        # Commanded sagittal sole positions relative to the pelvis at the end of the last step.
        self._end_x = {"l": self._home_x, "r": self._home_x}
        self._end_y = {"l": 0.5 * self._home_width, "r": -0.5 * self._home_width}
        self._start_off = {"swing": 0.0, "stance": 0.0}
        self._attack = 0.0
        self._last: tuple[float, float, float, float] | None = None
        # Every speed of the velocity ramp (`_new_step`), solved now rather than mid-run.
        for k in range(p.velocity_ramp_steps):
            self._gait(p.speed * min(1.0, (k + 1) / p.velocity_ramp_steps))
        self._gait_k = gait0
        # Stance-ankle push-off: gain [Nm s/m], the commanded direction, and the motor offset
        # per Nm of a forward (pelvis-advancing) ankle torque [rad/Nm], signed by the IK.
        b = p.ankle_damping * self.model.axis.mass[0, 0] * self.model.omega_fall
        self._ankle_b = float(b) if p.speed else 0.0
        self._direction = math.copysign(1.0, p.speed)
        k_eff = ankle_series_stiffness(robot)
        self._ankle_rad_per_nm = self._ankle_forward_sign() / k_eff if k_eff > 0 else 0.0
        self._split_ns = [0] * len(SPLIT)

    def _ankle_forward_sign(self) -> float:
        """Sign of the ankle pitch change that moves the pelvis forward over a stance foot.

        From the IK at the start posture: the sole 1 mm further behind the pelvis.
        """
        z = -self._h
        y = 0.5 * self._home_width
        q0 = self._ik.solve_level(0.0, (self._home_x, y, z), (self._home_x, -y, z), 0.0, 0.0)
        q1 = self._ik.solve_level(0.0, (self._home_x - 1e-3, y, z), (self._home_x, -y, z), 0.0, 0.0)
        return math.copysign(1.0, q1[ANKLE_PITCH] - q0[ANKLE_PITCH])

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
        clock, split = time.perf_counter_ns, self._split_ns
        t0 = clock()
        p = self._p
        # ---- estimation (runs from t = 0 so the filters are warm at the first step)
        left, right, _, pitch = self._kin.feet(sensors.imu_quat, sensors.joint_pos)
        feet = self._pos_filter.update((left[0], right[0]))  # sagittal [left, right]
        if p.role_velocities and self._k >= 0 and t - p.start_time >= (self._k + 1) * p.step_time:
            self._vel_filter.swap(0, 1)  # a touchdown: the rates of s₁, s₂ carry on by role
        feet_vel = self._vel_filter.update(feet)
        forces = self._force_filter.update(
            (max(float(sensors.left_ft[2]), 0.0), max(float(sensors.right_ft[2]), 0.0))
        )
        t1 = clock()
        split[0] += t1 - t0
        t_walk = t - p.start_time
        if t_walk < -p.sway_steps * p.step_time:
            return Command(
                ctrl=self._home_ctrl.copy(), signals=Signals.of(SIGNAL_LAYOUT, {"phase": -1.0})
            )
        if t_walk < 0.0:
            command = self._sway(t_walk)
            split[2] += clock() - t1
            return command

        T = p.step_time
        k = int(t_walk // T)
        phase = t_walk - k * T
        events: tuple[dict, ...] = ()
        if k != self._k:
            events = self._new_step(k)
        d = self._side
        # Nominal sagittal [p−f, p−s, ḟ, ṗ] (e's entries 0, 2, 4, 6; the same on both sides).
        rel = self._gait_k.sagittal_relative_state(phase)

        # ---- measured errors (Eq. 15), sagittal
        f_x, s_x = (feet[0], feet[1]) if d > 0 else (feet[1], feet[0])
        fv_x, sv_x = (feet_vel[0], feet_vel[1]) if d > 0 else (feet_vel[1], feet_vel[0])
        meas = [-f_x, -s_x, fv_x - sv_x, -sv_x]
        err = [meas[0] - rel[0], meas[1] - rel[1], meas[2] - rel[2], meas[3] - rel[3]]
        if p.dead_zone:
            a0, a1, a2, a3 = self._thresholds
            err_dz = [
                dead_zone(err[0], a0),
                dead_zone(err[1], a1),
                dead_zone(err[2], a2),
                dead_zone(err[3], a3),
            ]
        else:
            err_dz = list(err)

        # ---- time-projection footstep adjustment (Fig. 13 B, relative to the pelvis)
        i, a = self.tp._locate(phase)
        gain, slope = self._step_gains[i], self._step_slopes[i]
        step_raw = p.footstep_scale * (
            (gain[0] + a * slope[0]) * err_dz[0]
            + (gain[1] + a * slope[1]) * err_dz[1]
            + (gain[2] + a * slope[2]) * err_dz[2]
            + (gain[3] + a * slope[3]) * err_dz[3]
        )
        step = truncate_footstep(step_raw, p.footstep_limit)
        self._attack = step / self._h if p.stepping else 0.0
        t2 = clock()
        split[1] += t2 - t1

        # ---- adaptive lift (Eqs. 28-30), from the filtered (not dead-zoned) errors
        theta_hat = lift.hip_angle_estimate(err[0], self._h) if p.adaptive_lift else 0.0
        dz_adapt = lift.adaptive_lift(phase, T, theta_hat, self._h)

        # ---- Cartesian targets in the level frame at the pelvis
        ramp = min(1.0, (k + phase / T) / p.ramp_steps)
        roll_mag = lift.pelvis_roll(phase, T, ramp * p.roll_amplitude)  # ≥ 0
        roll_cmd = d * roll_mag
        blend = 0.5 * (1.0 - math.cos(math.pi * phase / T))
        swing_y = d * 0.5 * (self._width_prev + (self._width_k - self._width_prev) * blend)
        stance_y = -d * 0.5 * self._width_k
        hip_rise = self._pw * math.sin(roll_mag)
        swing_x = -rel[0] + self._start_off["swing"] * (1.0 - blend)
        if p.attack_in_ik:
            swing_x += self._h * math.tan(self._attack)
        stance_x = -rel[1] + self._start_off["stance"] * (1.0 - blend)
        swing_z = (
            -self._h + hip_rise + lift.fixed_lift(phase, T, ramp * p.lift_amplitude) + dz_adapt
        )
        stance_z = -self._h - hip_rise
        swing = (swing_x, swing_y, swing_z)
        stance = (stance_x, stance_y, stance_z)
        swing_pitch = lift.foot_pitch_feedback(theta_hat)  # coman: +pitch = toes down
        if d > 0:
            q_open = self._ik.solve_level(roll_cmd, swing, stance, swing_pitch, 0.0)
        else:
            q_open = self._ik.solve_level(roll_cmd, stance, swing, 0.0, swing_pitch)
        self._last = (swing_x, stance_x, swing_y, stance_y)
        t3 = clock()
        split[2] += t3 - t2

        # ---- attack angle on the swing hip
        # q_open: the open-loop posture, before the footstep feedback.
        q_des = list(q_open)
        sw_hip, st_hip = (
            (HIP_PITCH["l"], HIP_PITCH["r"]) if d > 0 else (HIP_PITCH["r"], HIP_PITCH["l"])
        )
        if not p.attack_in_ik:
            q_des[sw_hip] -= self._attack  # hip flexion is negative pitch in coman

        # ---- hip switch (Eq. 24) and spring compensation (Eq. 21, knees; the other leg
        # joints alike). Eq. 24 is v = k_d(γ(θ_des − θ_act) + (1 − γ)(−θ_pitch)) and the servo
        # is v = k_d(ctrl − θ_m), θ_m the motor encoder ("position control only on the motor
        # shaft"): the paper's torso term is the target θ_m + θ_pitch ('motor'), a voltage
        # from the IMU pitch alone, a motor torque k_d/β·θ_pitch that the spring passes on.
        # It gets no spring offset (a constant voltage there would be a torque bias on the
        # torso). 'link' targets the link encoder + θ_pitch: k_d(θ_pitch − spring deflection),
        # the servo in series with the hip spring, with the offsets added after the switch.
        t1 = p.hip_switch_ratio * T
        paper_torso = p.torso_term == "motor"
        ctrl_legs = list(q_des)
        if paper_torso:
            self._compensate_springs(ctrl_legs, forces, q_open, roll_cmd)
        encoder = sensors.joint_pos
        if paper_torso and sensors.motor_pos is not None:
            encoder = sensors.motor_pos  # a robot without springs: the link angle is θ_m
        for i, swinging in ((sw_hip, True), (st_hip, False)):
            gamma = lift.hip_switch_gamma(phase, t1, swinging)
            torso = float(encoder[i]) + pitch  # drives the pelvis pitch to zero
            ctrl_legs[i] = gamma * ctrl_legs[i] + (1.0 - gamma) * torso
        if not paper_torso:
            self._compensate_springs(ctrl_legs, forces, q_open, roll_cmd)
        load = [forces[0] / self._weight, forces[1] / self._weight]

        # ---- stance-ankle push-off through the ankle spring: adds only the speed the pelvis
        # lacks along the commanded direction, after the force transfer (the stance weight
        # 1 − γ of Eq. 24's law, which also skips the rate estimates' touchdown transient)
        ankle_torque = 0.0
        if self._ankle_b > 0.0:
            lack = max(0.0, -self._direction * err[3])  # [m/s]
            ramp_in = 1.0 - lift.hip_switch_gamma(phase, t1, False)
            ankle_torque = self._direction * self._ankle_b * lack * ramp_in  # forward + [Nm]
            st_leg = 6 if d > 0 else 0
            ctrl_legs[st_leg + ANKLE_PITCH] += ankle_torque * self._ankle_rad_per_nm

        ctrl = self._home_ctrl.copy()
        ctrl[LEG] = ctrl_legs
        ctrl[self._waist_roll] -= roll_cmd  # keep the torso upright (Eq. 22)

        signals = {
            "phase": phase,
            "step_index": float(k),
            "swing_side": float(d),
            "e_raw": err,
            "e_dead_zone": err_dz,
            "e_meas": meas,
            "e_nominal": list(rel),
            "footstep_raw": step_raw,
            "footstep": step,
            "attack_angle": self._attack,
            "theta_hat": theta_hat,
            "adaptive_lift": dz_adapt,
            "pelvis_roll_cmd": roll_cmd,
            "pelvis_pitch": pitch,
            "q_cmd_legs": q_des,
            "load": load,
            "ankle_torque": ankle_torque,
        }
        command = Command(ctrl=ctrl, signals=Signals.of(SIGNAL_LAYOUT, signals), events=events)
        split[3] += clock() - t3
        return command

    def _compensate_springs(
        self, ctrl_legs: list[float], forces: tuple[float, float], q_open: list[float], roll: float
    ) -> None:
        """Add the spring compensation of Eq. 21 to the legs' targets ``ctrl_legs`` in place.

        The load-scaled offsets at full weight (home-based); with posture springs, the
        sagittal joints' (hip pitch, knee, ankle pitch) static deflection under the body
        weight at the sole point of the commanded posture ``q_open`` instead [rad].
        """
        load = (forces[0] / self._weight, forces[1] / self._weight)
        offset = self._offset_full
        for i in range(12):
            ctrl_legs[i] += load[i // 6] * offset[i]
        bias = self._p.stance_ankle_bias
        if bias:
            ctrl_legs[ANKLE_PITCH] += load[0] * bias
            ctrl_legs[6 + ANKLE_PITCH] += load[1] * bias
        if self._posture_springs:
            # Eq. 21 with μ from the commanded posture instead of home: the sagittal springs'
            # static deflection under the body weight at the sole point (the 3LP CoP).
            self._pin_q[self._pin_legs] = q_open
            for leg in (0, 1):
                mu = self._deflection(leg, roll, SAGITTAL_JOINTS)
                for j, mu_j in zip(SAGITTAL_JOINTS, mu, strict=True):
                    i = 6 * leg + j
                    ctrl_legs[i] += load[leg] * (mu_j - offset[i])

    def timing(self) -> dict[str, float]:
        """Wall time [s] of the tick's parts: estimation (kinematics, filters), feedback
        (gait reference, errors, footstep table), ik (Cartesian targets, IK), output (hip
        switch, spring compensation, command and signals)."""
        return {name: ns * 1e-9 for name, ns in zip(SPLIT, self._split_ns, strict=True)}

    def _spring_deflection(self, q_legs: np.ndarray, leg: int, roll: float) -> np.ndarray:
        """Motor-minus-link offsets of leg ``leg``'s joints at full body weight [rad], shape (6,).

        τ = Jᵀ (0, 0, m g): the sole-point Jacobian (Pinocchio, rigid twin) in the commanded
        posture ``q_legs``, the world-vertical weight expressed in the pelvis frame rolled by
        ``roll``; the offset is −τ / k, k the spring's stiffness (the home keyframe's
        pre-load is this at home within 10 %), or the servo and spring in series with
        ``spring_compensation="posture_series"``.
        """
        self._pin_q[self._pin_legs] = q_legs
        return np.array(self._deflection(leg, roll, range(6)))

    def _deflection(self, leg: int, roll: float, joints: Iterable[int]) -> list[float]:
        """:meth:`_spring_deflection` of ``joints`` at the legs' posture already in the
        Pinocchio configuration (``step`` sets it once for both legs) [rad]."""
        # computeFrameJacobian runs the forward kinematics it needs itself.
        jac = pin.computeFrameJacobian(
            self._robot.pin_model,
            self._pin_data,
            self._pin_q,
            self._sole_frames[leg],
            pin.LOCAL_WORLD_ALIGNED,
        )
        # (0, sin roll, cos roll) · J[:3]: the x row has a zero weight.
        jac_y, jac_z = jac[1], jac[2]
        s, c = math.sin(roll), math.cos(roll)
        weight, cols, stiffness = self._weight, self._v_legs, self._stiffness_legs
        out = []
        for j in joints:
            i = 6 * leg + j
            torque = (s * float(jac_y[cols[i]]) + c * float(jac_z[cols[i]])) * weight
            out.append(-torque / stiffness[i])
        return out

    def _sway(self, t_walk: float) -> Command:
        """Lateral sway in double support before the first step (walkrepro start-up).

        Paper II does not describe how the gait starts. The in-place 3LP gait needs a
        lateral pelvis velocity toward the stance foot at each touchdown; a pendulum of
        offset D = W/2 gets v₀ = D ω tanh(ω T / 2) (ω: 3LP falling frequency). The sway
        y(τ) = −A sin(π τ / T), A = v₀ T / π, growing over the sway, reaches it at τ = 0,
        moving toward the first stance foot (right).
        """
        p = self._p
        T = p.step_time
        dist = 0.5 * self._home_width
        w = self.model.omega_fall
        v0 = dist * w * math.tanh(0.5 * w * T)
        grow = min(1.0, 1.0 + t_walk / (p.sway_steps * T) * 1.0 + 0.5)
        y_p = -grow * v0 * T / math.pi * math.sin(math.pi * t_walk / T)
        z = -self._h
        targets = LegTargets(
            pelvis_roll=0.0,
            left=np.array([self._home_x, dist - y_p, z]),
            right=np.array([self._home_x, -dist - y_p, z]),
            left_pitch=0.0,
            right_pitch=0.0,
        )
        q = self._ik.solve(targets)
        ctrl = self._home_ctrl.copy()
        ctrl[LEG] = q + 0.5 * self._leg_offset_full
        return Command(ctrl=ctrl, signals=Signals.of(SIGNAL_LAYOUT, {"phase": -1.0, "sway": y_p}))

    def _new_step(self, k: int) -> tuple[dict, ...]:
        """Touchdown bookkeeping at a phase change: side, width/speed ramps, blends."""
        p = self._p
        if self._k >= 0:
            self._side = -self._side
            sw_prev, st_prev = ("r", "l") if self._side > 0 else ("l", "r")
            if self._last is not None:  # the last tick's targets, by leg
                swing_x, stance_x, swing_y, stance_y = self._last
                self._end_x = {sw_prev: swing_x, st_prev: stance_x}
                self._end_y = {sw_prev: swing_y, st_prev: stance_y}
            else:
                self._end_x = dict(self._end_x)
                self._end_y = dict(self._end_y)
            # The landing swing foot got the attack angle: h·tan(attack) further forward.
            if not self._p.attack_in_ik:
                self._end_x[sw_prev] += self._h * math.tan(self._attack)
        self._k = k
        ramp = min(1.0, (k + 1) / p.ramp_steps)
        self._width_prev = self._width_k
        self._width_k = self._home_width + (p.step_width - self._home_width) * ramp
        self._speed_k = p.speed * min(1.0, (k + 1) / p.velocity_ramp_steps)
        gait = self._gait_k = self._gait(self._speed_k)
        d = self._side
        rel0 = gait.relative_state(0.0, d)
        sw, st = ("l", "r") if d > 0 else ("r", "l")
        self._start_off = {
            "swing": self._end_x[sw] - (-rel0[0]),
            "stance": self._end_x[st] - (-rel0[2]),
        }
        self._attack = 0.0
        return ({"kind": "phase", "step": k, "swing": "left" if d > 0 else "right"},)
