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
5. motor targets for the position servos (``Command.ctrl``).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
from pydantic import Field

from walkrepro.controllers.base import Command, Controller, ControllerParams
from walkrepro.controllers.timeprojection import lift
from walkrepro.controllers.timeprojection.dlqr import Dlqr
from walkrepro.controllers.timeprojection.estimation import (
    IirFilter,
    KinematicState,
    MovingAverageDerivative,
    smooth_dead_zone,
)
from walkrepro.controllers.timeprojection.gait import PeriodicGait
from walkrepro.controllers.timeprojection.openloop import (
    LegIk,
    LegTargets,
    relative_footstep_gains,
    threelp_params_from_robot,
)
from walkrepro.controllers.timeprojection.projection import TimeProjection, truncate_footstep
from walkrepro.controllers.timeprojection.threelp import ThreeLP
from walkrepro.robot import Robot
from walkrepro.sensors import SensorSnapshot

GRAVITY = 9.81  # [m/s^2]
#: Indices of the sagittal components in e = [p − f, p − s, ḟ, ṗ] (x, y interleaved).
SAGITTAL = np.array([0, 2, 4, 6])
LEG = slice(0, 12)
HIP_PITCH = {"l": 2, "r": 8}
KNEE = (3, 9)
#: Sagittal spring joints of a leg (hip pitch, knee, ankle pitch), indices within the leg.
SAGITTAL_JOINTS = (2, 3, 4)


class TimeProjectionParams(ControllerParams):
    """Parameters of Paper II's controller (defaults: the paper's values)."""

    stepping: bool = Field(True, description="time-projection footstep adjustment on/off")
    dead_zone: bool = Field(True, description="smooth dead-zones (Eq. 27) on the errors")
    adaptive_lift: bool = Field(True, description="adaptive lift and foot pitch (Eqs. 28-30)")
    speed: float = Field(0.0, description="commanded 3LP speed v [m/s] (Fig. 19)")
    step_time: float = Field(0.4, gt=0, description="T [s] (2.5 steps/s)")
    step_width: float = Field(0.25, gt=0, description="W [m] (Paper II: 25 cm)")
    roll_amplitude: float = Field(0.1, ge=0, description="pelvis roll, Eq. 22 [rad]")
    lift_amplitude: float = Field(0.01, ge=0, description="swing lift, Eq. 23 [m]")
    hip_switch_ratio: float = Field(0.2, gt=0, description="t1 / T of Eq. 24")
    zeta: float = Field(0.1, gt=0, le=1, description="IIR ζ, Eq. 26")
    velocity_window: int = Field(30, ge=1, description="derivative averaging window [samples]")
    dead_zone_thresholds: tuple[float, float, float, float] = Field(
        (0.022, 0.023, 0.23, 0.051),
        description="a of Eq. 27 for e1x, e2x [m], de1x, de2x [m/s]: the std of the "
        "open-loop in-place errors (Fig. 9 procedure; see in_place_open_loop)",
    )
    footstep_limit: float = Field(0.15, gt=0, description="truncation [m] (Fig. 13: 15 cm)")
    knee_deflection: float | None = Field(
        None,
        description="μ of Eq. 21 [rad]; None derives it from the home keyframe's knee "
        "pre-load (deflection at full body weight)",
    )
    footstep_scale: float = Field(
        1.0,
        ge=0,
        description="scale on the time-projection footstep gains (1 = the 3LP tables; see "
        "README known deviations: 3LP has free ankles, coman's stance ankle is a stiff "
        "servo behind a 125 Nm/rad spring)",
    )
    attack_in_ik: bool = Field(
        False,
        description="add the footstep adjustment to the swing foot's Cartesian target "
        "(IK keeps the foot flat) instead of the swing hip angle (Paper II)",
    )
    table_samples: int = Field(100, ge=2, description="look-up-table samples per step")
    start_time: float = Field(0.5, ge=0, description="stand still before the first step [s]")
    ramp_steps: int = Field(3, ge=1, description="steps over which roll/lift/width/speed ramp up")
    sway_steps: float = Field(0.0, ge=0, description="double-support sway before walking [steps]")
    velocity_ramp_steps: int = Field(5, ge=1, description="steps over which the speed ramps up")


class TimeProjectionController(Controller):
    """Paper II: 3LP + DLQR + time-projection footstep adjustment, position-controlled."""

    Params = TimeProjectionParams

    def reset(self, robot: Robot, params: ControllerParams, control_period: float) -> None:
        """Build the 3LP model, gait, DLQR and look-up tables; reset the filters."""
        assert isinstance(params, TimeProjectionParams)
        self._p = p = params
        self._robot = robot
        self._dt = control_period
        self.model = ThreeLP(threelp_params_from_robot(robot))
        self._h = self.model.params.h1
        self._pw = self.model.params.pw
        self.dlqr = Dlqr.solve(self.model, p.step_time)
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
        if p.knee_deflection is not None:
            for i in KNEE:
                self._leg_offset_full[i] = -p.knee_deflection
        self._waist_roll = robot.joint_names.index("waist_roll")
        self._pin_data = robot.pin_model.createData()
        self._pin_q = pin.neutral(robot.pin_model)
        self._sole_frames = tuple(
            robot.pin_model.getFrameId(n) for n in ("left_sole", "right_sole")
        )
        lf, rf, _, _ = self._kin.feet(np.array([1.0, 0, 0, 0]), robot.home_joint_pos)
        self._home_width = float(lf[1] - rf[1])
        self._home_x = 0.5 * float(lf[0] + rf[0])
        self._pos_filter = IirFilter(p.zeta, 4)
        self._vel_filter = MovingAverageDerivative(p.velocity_window, 4, control_period)
        self._force_filter = IirFilter(p.zeta, 2)
        self._thresholds = np.array(p.dead_zone_thresholds)
        self._k = -1
        self._side = 1
        self._speed_k = 0.0
        self._width_prev = self._width_k = self._home_width
        # Commanded sagittal sole positions relative to the pelvis at the end of the last step.
        self._end_x = {"l": self._home_x, "r": self._home_x}
        self._end_y = {"l": 0.5 * self._home_width, "r": -0.5 * self._home_width}
        self._start_off = {"swing": 0.0, "stance": 0.0}
        self._attack = 0.0
        self._gaits: dict[float, PeriodicGait] = {0.0: gait0}

    def _gait(self, speed: float) -> PeriodicGait:
        gaits = getattr(self, "_gaits", {})
        if speed not in gaits:
            gaits[speed] = PeriodicGait.solve(
                self.model, speed, self._p.step_time, self._p.step_width
            )
            self._gaits = gaits
        return gaits[speed]

    def _rel_gain(self, t: float) -> np.ndarray:
        """Interpolated Δ(f − p)(T) gains, shape (2, 8)."""
        i, a = self.tp._locate(t)
        return self.rel_gains[i] + a * self._rel_slopes[i]

    # ------------------------------------------------------------------------------------

    def step(self, t: float, sensors: SensorSnapshot) -> Command:
        """One control tick (see the module docstring)."""
        p = self._p
        # ---- estimation (runs from t = 0 so the filters are warm at the first step)
        left, right, _, pitch = self._kin.feet(sensors.imu_quat, sensors.joint_pos)
        feet = self._pos_filter.update(np.array([left[0], left[1], right[0], right[1]]))
        feet_vel = self._vel_filter.update(feet)
        forces = self._force_filter.update(
            np.array([max(sensors.left_ft[2], 0.0), max(sensors.right_ft[2], 0.0)])
        )
        t_walk = t - p.start_time
        if t_walk < -p.sway_steps * p.step_time:
            return Command(ctrl=self._home_ctrl.copy(), signals={"phase": -1.0})
        if t_walk < 0.0:
            return self._sway(t_walk)

        T = p.step_time
        k = int(t_walk // T)
        phase = t_walk - k * T
        events: tuple[dict, ...] = ()
        if k != self._k:
            events = self._new_step(k)
        d = self._side
        sw, st = ("l", "r") if d > 0 else ("r", "l")
        gait = self._gait(self._speed_k)
        rel = gait.relative_state(phase, d)  # nominal [p−f, p−s, ḟ, ṗ]

        # ---- measured errors (Eq. 15), sagittal
        f_i, s_i = (0, 2) if d > 0 else (2, 0)
        f_x, s_x = feet[f_i], feet[s_i]
        fv_x, sv_x = feet_vel[f_i], feet_vel[s_i]
        meas = np.array([-f_x, -s_x, fv_x - sv_x, -sv_x])
        err = meas - rel[SAGITTAL]
        err_dz = smooth_dead_zone(err, self._thresholds) if p.dead_zone else err

        # ---- time-projection footstep adjustment (Fig. 13 B, relative to the pelvis)
        e8 = np.zeros(8)
        e8[SAGITTAL] = err_dz
        step_raw = p.footstep_scale * float(self._rel_gain(phase)[0] @ e8)
        step = truncate_footstep(step_raw, p.footstep_limit)
        self._attack = step / self._h if p.stepping else 0.0

        # ---- adaptive lift (Eqs. 28-30), from the filtered (not dead-zoned) errors
        theta_hat = lift.hip_angle_estimate(err[0], self._h) if p.adaptive_lift else 0.0
        dz_adapt = lift.adaptive_lift(phase, T, theta_hat, self._h)

        # ---- Cartesian targets in the level frame at the pelvis
        ramp = min(1.0, (k + phase / T) / p.ramp_steps)
        roll_mag = lift.pelvis_roll(phase, T, ramp * p.roll_amplitude)  # ≥ 0
        blend = 0.5 * (1.0 - math.cos(math.pi * phase / T))
        swing_y = d * 0.5 * (self._width_prev + (self._width_k - self._width_prev) * blend)
        stance_y = -d * 0.5 * self._width_k
        hip_rise = self._pw * math.sin(roll_mag)
        swing_x = -rel[0] + self._start_off["swing"] * (1.0 - blend)
        if p.attack_in_ik:
            swing_x += self._h * math.tan(self._attack)
        stance_x = -rel[2] + self._start_off["stance"] * (1.0 - blend)
        swing_z = (
            -self._h + hip_rise + lift.fixed_lift(phase, T, ramp * p.lift_amplitude) + dz_adapt
        )
        stance_z = -self._h - hip_rise
        swing = np.array([swing_x, swing_y, swing_z])
        stance = np.array([stance_x, stance_y, stance_z])
        swing_pitch = lift.foot_pitch_feedback(theta_hat)  # coman: +pitch = toes down
        targets = LegTargets(
            pelvis_roll=d * roll_mag,
            left=swing if d > 0 else stance,
            right=stance if d > 0 else swing,
            left_pitch=swing_pitch if d > 0 else 0.0,
            right_pitch=swing_pitch if d < 0 else 0.0,
        )
        q_des = self._ik.solve(targets)
        q_open = q_des.copy()  # the open-loop posture, before the footstep feedback
        self._last_x = {sw: swing_x, st: stance_x}
        self._last_y = {sw: swing_y, st: stance_y}

        # ---- attack angle on the swing hip; hip switch (Eq. 24)
        t1 = p.hip_switch_ratio * T
        if not p.attack_in_ik:
            q_des[HIP_PITCH[sw]] -= self._attack  # hip flexion is negative pitch in coman
        ctrl_legs = q_des.copy()
        for leg, swinging in ((sw, True), (st, False)):
            i = HIP_PITCH[leg]
            gamma = lift.hip_switch_gamma(phase, t1, swinging)
            torso = sensors.joint_pos[i] + pitch  # drives the pelvis pitch to zero
            ctrl_legs[i] = gamma * q_des[i] + (1.0 - gamma) * torso

        # ---- spring compensation (Eq. 21, knees; the other leg joints alike)
        load = forces / self._weight
        ctrl_legs[0:6] += load[0] * self._leg_offset_full[0:6]
        ctrl_legs[6:12] += load[1] * self._leg_offset_full[6:12]
        if p.knee_deflection is None and self._robot.spring_stiffness is not None:
            # Eq. 21 with μ from the commanded posture instead of home: the sagittal springs'
            # static deflection under the body weight at the sole point (the 3LP CoP).
            for leg in (0, 1):
                mu = self._spring_deflection(q_open, leg, d * roll_mag)
                for j in SAGITTAL_JOINTS:
                    i = 6 * leg + j
                    ctrl_legs[i] += load[leg] * (mu[j] - self._leg_offset_full[i])

        ctrl = self._home_ctrl.copy()
        ctrl[LEG] = ctrl_legs
        ctrl[self._waist_roll] -= d * roll_mag  # keep the torso upright (Eq. 22)

        signals = {
            "phase": phase,
            "step_index": float(k),
            "swing_side": float(d),
            "e_raw": meas - rel[SAGITTAL],
            "e_dead_zone": err_dz,
            "e_meas": meas,
            "e_nominal": rel[SAGITTAL],
            "footstep_raw": step_raw,
            "footstep": step,
            "attack_angle": self._attack,
            "theta_hat": theta_hat,
            "adaptive_lift": dz_adapt,
            "pelvis_roll_cmd": d * roll_mag,
            "pelvis_pitch": pitch,
            "q_cmd_legs": q_des,
            "load": load,
        }
        return Command(ctrl=ctrl, signals=signals, events=events)

    def _spring_deflection(self, q_legs: np.ndarray, leg: int, roll: float) -> np.ndarray:
        """Motor-minus-link offsets of leg ``leg``'s joints at full body weight [rad], shape (6,).

        τ = Jᵀ (0, 0, m g): the sole-point Jacobian (Pinocchio, rigid twin) in the commanded
        posture ``q_legs``, the world-vertical weight expressed in the pelvis frame rolled by
        ``roll``; the offset is −τ / k (the home keyframe's pre-load is this at home).
        """
        robot = self._robot
        model, data, q = robot.pin_model, self._pin_data, self._pin_q
        q[robot.pin_q_idx[LEG]] = q_legs
        frame = self._sole_frames[leg]
        # computeFrameJacobian runs the forward kinematics it needs itself.
        jac = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)
        sl = slice(6 * leg, 6 * leg + 6)
        up = np.array([0.0, math.sin(roll), math.cos(roll)])
        torque = (up @ jac[:3, robot.pin_v_idx[sl]]) * self._weight
        return -torque / robot.spring_stiffness[sl]

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
        return Command(ctrl=ctrl, signals={"phase": -1.0, "sway": y_p})

    def _new_step(self, k: int) -> tuple[dict, ...]:
        """Touchdown bookkeeping at a phase change: side, width/speed ramps, blends."""
        p = self._p
        if self._k >= 0:
            self._side = -self._side
            last = getattr(self, "_last_x", self._end_x)
            # The landing swing foot got the attack angle: h·tan(attack) further forward.
            sw_prev = "r" if self._side > 0 else "l"
            self._end_x = dict(last)
            if not self._p.attack_in_ik:
                self._end_x[sw_prev] = last[sw_prev] + self._h * math.tan(self._attack)
            self._end_y = dict(getattr(self, "_last_y", self._end_y))
        self._k = k
        ramp = min(1.0, (k + 1) / p.ramp_steps)
        self._width_prev = self._width_k
        self._width_k = self._home_width + (p.step_width - self._home_width) * ramp
        self._speed_k = p.speed * min(1.0, (k + 1) / p.velocity_ramp_steps)
        gait = self._gait(self._speed_k)
        d = self._side
        rel0 = gait.relative_state(0.0, d)
        sw, st = ("l", "r") if d > 0 else ("r", "l")
        self._start_off = {
            "swing": self._end_x[sw] - (-rel0[0]),
            "stance": self._end_x[st] - (-rel0[2]),
        }
        self._attack = 0.0
        return ({"kind": "phase", "step": k, "swing": "left" if d > 0 else "right"},)
