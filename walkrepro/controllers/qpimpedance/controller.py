"""Jo & Oh's walking controller: ZMP preview pattern, impedance landing, centroidal QP.

Each control tick (1 kHz, §IV):

1. the floating-base state (from the simulator, §IV) and the joint encoders give
   Pinocchio's (q, v); one ``computeAllTerms`` gives M, C ξ̇ + g, the Jacobians, the CoM and
   the centroidal momentum h_G;
2. the footstep plan (flat ground, §IV) gives the phase; the preview-control CoM pattern
   (ref. [23]) gives the desired CoM; the swing trajectory gives the swing foot's desired
   pose;
3. the swing foot's F/T wrench, with the foot's own weight and inertia removed (the sensor
   sits between ankle and sole, §IV), drives the impedance modification (Eqs. 1–3);
4. the QP of §III-D gives ξ̈* and the contact wrenches, Eq. (9) the joint torques.

The controller knows nothing about obstacles: its plan is for a flat floor.
"""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin
from pydantic import Field

from walkrepro.controllers.base import Command, Controller, ControllerParams
from walkrepro.controllers.qpimpedance.centroidal_qp import (
    SOLVERS,
    Task,
    build_qp,
    contact_wrench_basis,
    friction_basis,
    joint_torques,
)
from walkrepro.controllers.qpimpedance.footsteps import (
    LEFT,
    RIGHT,
    SIDES,
    FootstepPlan,
    SwingTrajectory,
    plan_walk,
)
from walkrepro.controllers.qpimpedance.impedance import ImpedanceFilter, reference_acceleration
from walkrepro.controllers.qpimpedance.preview import generate_com, preview_gains
from walkrepro.robot import Robot
from walkrepro.sensors import SensorSnapshot

GRAVITY = 9.81  # [m/s^2]
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
Vec3 = tuple[float, float, float]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b of two 3-vectors (np.cross costs ~20 µs per call on tiny arrays)."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


class QPImpedanceParams(ControllerParams):
    """Parameters of the walking pattern, the impedance law and the QP (paper §II–IV)."""

    # Walking pattern (§IV).
    stride: float = Field(
        0.35, gt=0, description="swing-foot travel per step [m] (§IV: 0.35 m stride)"
    )
    t_single: float = Field(0.56, gt=0, description="single-support time [s] (§IV)")
    t_double: float = Field(0.14, gt=0, description="double-support time [s] (§IV)")
    n_steps: int = Field(6, ge=2, description="number of steps")
    first_swing: str = Field("right", pattern="^(left|right)$", description="first swing foot")
    t_start: float = Field(1.0, gt=0, description="initial double support [s]")
    t_end_hold: float = Field(0.5, ge=0, description="planned stance after the last step [s]")
    foot_y: float = Field(
        0.09, gt=0, description="lateral offset of each sole centre [m] (robot: hip ±0.09)"
    )
    swing_height: float = Field(
        0.10, gt=0, description="swing apex above the higher of lift-off and landing [m] (assumed)"
    )
    swing_rise_fraction: float = Field(
        0.4, gt=0, lt=1, description="share of the swing spent rising [-] (assumed)"
    )
    com_height: float | None = Field(
        None, gt=0, description="CoM height of the LIPM [m]; default: the robot's home CoM"
    )
    preview_dt: float = Field(0.005, gt=0, description="sample time of the preview controller [s]")
    preview_time: float = Field(1.0, gt=0, description="preview horizon [s] (Kajita 2003: 1.6 s)")
    preview_q: float = Field(1.0, gt=0, description="ZMP error weight Q_e [1/m²]")
    preview_r: float = Field(1e-6, gt=0, description="CoM jerk weight R [s⁶/m²]")
    # Impedance (§II, §IV).
    impedance: bool = Field(True, description="modify the swing reference by Eqs. (1)–(3)")
    m_d: Vec3 = Field(
        (30.0, 0.3, 0.3), description="desired mass M_d for (z, φx, φy) [kg, kg m², kg m²]"
    )
    b_d: Vec3 = Field((450.0, 3.0, 3.0), description="desired damping B_d [N s/m, N m s/rad]")
    k_d: Vec3 = Field((1500.0, 10.0, 10.0), description="desired stiffness K_d [N/m, N m/rad]")
    force_threshold: float = Field(
        10.0, gt=0, description="|λ_z| that switches impedance on [N] (§IV)"
    )
    torque_threshold: float = Field(
        3.0, gt=0, description="|λ_φx|, |λ_φy| that switch it on [N m] (§IV)"
    )
    # Task gains (§III-D: ẍ_r = ẍ_d + K_V(ẋ_d − ẋ) + K_P(x_d − x), Eq. 3).
    # Swing gains ω² and 2ω with ω = 25 rad/s: the stiffest tracking (§II: "the robot
    # controller needs proper control gains to keep tracking") in steps of 5 rad/s with which
    # the QP alone still overcomes the 4 cm obstacle, as §IV-A states (ω = 30 falls).
    kp_swing: float = Field(625.0, ge=0, description="swing-foot K_P [1/s²] (see above)")
    kv_swing: float = Field(50.0, ge=0, description="swing-foot K_V [1/s] (see above)")
    kp_orient: float = Field(200.0, ge=0, description="pelvis and torso orientation K_P [1/s²]")
    kv_orient: float = Field(28.0, ge=0, description="pelvis and torso orientation K_V [1/s]")
    kp_posture: float = Field(100.0, ge=0, description="arm and waist joint K_P [1/s²]")
    kv_posture: float = Field(20.0, ge=0, description="arm and waist joint K_V [1/s]")
    k_h: float = Field(20.0, ge=0, description="linear momentum gain K_h [1/s]")
    k_i: float = Field(100.0, ge=0, description="linear momentum integral gain K_I [1/s²]")
    k_h_angular: float = Field(5.0, ge=0, description="angular momentum gain K_h [1/s]")
    # QP weights (§III-D: W_1 … W_4).
    w_momentum_linear: float = Field(1.0, gt=0, description="W_1, force rows [1/N²]")
    w_momentum_angular: float = Field(1.0, gt=0, description="W_1, moment rows [1/(N m)²]")
    w_swing: float = Field(100.0, gt=0, description="W_t of the swing foot")
    w_pelvis: float = Field(100.0, gt=0, description="W_t of the pelvis orientation")
    w_torso: float = Field(10.0, gt=0, description="W_t of the torso orientation")
    w_posture: float = Field(1.0, gt=0, description="W_t of the arm and waist joints")
    w_accel: float = Field(1e-4, gt=0, description="W_3 regularisation of ξ̈")
    w_force: float = Field(1e-6, gt=0, description="W_4 regularisation of β")
    friction: float = Field(0.6, gt=0, description="friction coefficient μ of the pyramid (Eq. 8)")
    pyramid_edges: int = Field(4, ge=3, description="edges m of each pyramid (Eq. 8)")
    solver: str = Field("proxqp", description=f"qpsolvers backend, one of {SOLVERS}")
    solver_eps: float = Field(1e-6, gt=0, description="solver absolute tolerance")


class QPImpedanceController(Controller):
    """Walks the flat-ground plan with the centroidal QP and impedance landing (Jo & Oh)."""

    Params = QPImpedanceParams

    def reset(self, robot: Robot, params: ControllerParams, control_period: float) -> None:
        """Plan the walk, generate the CoM pattern and cache the model quantities."""
        assert isinstance(params, QPImpedanceParams)
        if robot.control_mode != "torque":
            raise ValueError("qpimpedance needs a torque-controlled robot")
        self._robot, self._p, self._dt = robot, params, control_period
        p = params
        model = robot.pin_model
        self._model, self._data = model, model.createData()
        self._mass = robot.total_mass
        self._sole = [robot.pin_frame_id(f"{s}_sole") for s in SIDES]
        self._ft = [robot.pin_frame_id(f"{s}_foot_ft") for s in SIDES]
        self._foot = [robot.pin_frame_id(f"{s}_foot") for s in SIDES]
        self._pelvis = robot.pin_frame_id("pelvis")
        self._torso = robot.pin_frame_id("torso")
        # Foot body below the F/T sensor: its mass and centre (in the foot frame) [kg, m].
        foot_joint = model.frames[self._foot[0]].parentJoint
        self._foot_mass = float(model.inertias[foot_joint].mass)
        self._foot_com = [
            np.array(model.inertias[model.frames[f].parentJoint].lever) for f in self._foot
        ]
        length, width = robot.sole_size
        self._corners = np.array(
            [[sx * length / 2, sy * width / 2, 0.0] for sx in (1, -1) for sy in (1, -1)]
        )
        self._pyramid = friction_basis(p.friction, p.pyramid_edges)
        if p.solver not in SOLVERS:
            raise ValueError(f"unknown QP solver {p.solver!r}; valid: {', '.join(SOLVERS)}")

        # Walking pattern: footsteps, ZMP reference and the preview-control CoM (ref. [23]).
        self._com_height = p.com_height or robot.nominal_com_height
        first = LEFT if p.first_swing == "left" else RIGHT
        self._plan: FootstepPlan = plan_walk(
            p.foot_y,
            p.stride,
            p.n_steps,
            first,
            p.t_start,
            p.t_single,
            p.t_double,
            p.t_end_hold,
            p.preview_dt,
        )
        gains = preview_gains(
            p.preview_dt, self._com_height, p.preview_time, p.preview_q, p.preview_r
        )
        q0, _ = robot.pin_state_from_mujoco(robot.home_qpos, np.zeros(robot.mj_model.nv))
        com0 = pin.centerOfMass(model, self._data, q0)
        ref = self._plan.zmp_xy.copy()
        self._com_x, _ = generate_com(gains, ref[:, 0], np.array([com0[0], 0.0, 0.0]))
        self._com_y, _ = generate_com(gains, ref[:, 1], np.array([com0[1], 0.0, 0.0]))
        self._com_x = self._com_x.copy()
        self._com_z = com0[2] if p.com_height is None else p.com_height

        n = robot.n_joints
        names = robot.joint_names
        self._posture_idx = np.array(
            [
                i
                for i, j in enumerate(names)
                if not j.startswith(("l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle"))
            ]
        )
        self._q_home = robot.home_joint_pos.copy()
        self._v_idx = robot.pin_v_idx
        self._zero_v = np.zeros(model.nv)
        self._impedance = [
            ImpedanceFilter(
                np.array(p.m_d),
                np.array(p.b_d),
                np.array(p.k_d),
                p.force_threshold,
                p.torque_threshold,
            )
            for _ in SIDES
        ]
        self._phase_index = -1
        self._swing: SwingTrajectory | None = None
        self._stance = [np.array([0.0, p.foot_y, 0.0]), np.array([0.0, -p.foot_y, 0.0])]
        self._foot_acc_cmd = [np.zeros(6), np.zeros(6)]
        self._prev_foot_vel = [np.zeros(6), np.zeros(6)]
        self._tau = np.zeros(n)
        self._x_prev: np.ndarray | None = None
        self._int_k = np.zeros(3)
        self._qp_fail = 0
        self.qp_solve_times: list[float] = []

    # ------------------------------------------------------------------------------------

    def _desired_com(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """CoM position, velocity, acceleration of the preview pattern at ``t`` [m, m/s, m/s²]."""
        k = t / self._p.preview_dt
        i = int(min(max(np.floor(k), 0), self._com_x.shape[0] - 2))
        a = min(max(k - i, 0.0), 1.0)
        sx = (1 - a) * self._com_x[i] + a * self._com_x[i + 1]
        sy = (1 - a) * self._com_y[i] + a * self._com_y[i + 1]
        if t >= self._plan.end:
            sx = np.array([self._com_x[-1, 0], 0.0, 0.0])
            sy = np.array([self._com_y[-1, 0], 0.0, 0.0])
        return (
            np.array([sx[0], sy[0], self._com_z]),
            np.array([sx[1], sy[1], 0.0]),
            np.array([sx[2], sy[2], 0.0]),
        )

    def _contact_wrench(self, side: int, ft: np.ndarray) -> np.ndarray:
        """Contact wrench on a foot from its F/T reading: (f_z [N], μ_x, μ_y [N m]).

        The sensor (site ``*_foot_ft``) reads the foot-on-leg wrench, which includes the
        weight and inertia of the foot below it (≈ 14 N). Newton–Euler of that foot body:
        f_c = f_s + m (g ẑ + a), μ_c = μ_s − r_c × m (g_vec − a) about the sensor, then moved
        to the sole centre; world axes. a is the foot's commanded acceleration.
        """
        data = self._data
        site = data.oMf[self._ft[side]]
        foot = data.oMf[self._foot[side]]
        sole = data.oMf[self._sole[side]]
        rot = site.rotation
        f_s, m_s = rot @ ft[:3], rot @ ft[3:]
        acc = self._foot_acc_cmd[side][:3]
        m = self._foot_mass
        gravity = np.array([0.0, 0.0, -GRAVITY])
        f_c = f_s - m * gravity + m * acc
        r_c = foot.act(self._foot_com[side]) - site.translation
        m_c = m_s - _cross(r_c, m * (gravity - acc))
        m_sole = m_c + _cross(site.translation - sole.translation, f_c)
        return np.array([f_c[2], m_sole[0], m_sole[1]])

    def _enter_phase(self, index: int, t: float) -> None:
        """Start a phase: a swing builds its trajectory from the foot's actual pose."""
        phase = self._plan.phases[index]
        self._phase_index = index
        if phase.swing < 0:
            self._swing = None
            return
        sole = self._data.oMf[self._sole[phase.swing]]
        rpy = pin.rpy.matrixToRpy(sole.rotation)
        start = np.array([*sole.translation, rpy[0], rpy[1]])
        target = np.array([*phase.target, 0.0, 0.0])
        p = self._p
        self._swing = SwingTrajectory(
            phase.t0, phase.t1 - phase.t0, start, target, p.swing_height, p.swing_rise_fraction
        )
        self._stance[phase.swing] = np.array(phase.target)

    def step(self, t: float, s: SensorSnapshot) -> Command:
        """One tick of §III-D: tasks → QP → Eq. (9)."""
        p, model, data = self._p, self._model, self._data
        q, v = s.pinocchio_state(self._robot, "qpimpedance (as in §IV)")
        pin.computeAllTerms(model, data, q, v)
        mass_matrix, nle = data.M, data.nle.copy()
        # Drift accelerations J̇ ξ̇: forward kinematics with ξ̈ = 0.
        pin.forwardKinematics(model, data, q, v, self._zero_v)
        pin.updateFramePlacements(model, data)

        index = next(
            i
            for i, ph in enumerate(self._plan.phases)
            if t < ph.t1 or i == len(self._plan.phases) - 1
        )
        if index != self._phase_index:
            self._enter_phase(index, t)
        phase = self._plan.phases[index]
        swing = phase.swing
        support = tuple(k for k in (LEFT, RIGHT) if k != swing)

        signals: dict[str, float] = {"t_plan": t, "swing_foot": float(swing)}
        events: list[dict] = []

        # ---- centroidal momentum reference (§III-D) -------------------------------------
        com, vcom = data.com[0].copy(), data.vcom[0].copy()
        c_d, v_d, a_d = self._desired_com(t)
        m = self._mass
        hdot_lin = m * (
            a_d + p.k_h * (v_d - vcom) + p.k_i * (c_d - com)
        )  # ∫(h_d − h) = m (c_d − c)
        k_ang = data.hg.angular.copy()
        hdot_ang = -p.k_h_angular * k_ang
        base = data.oMi[1]
        rot_b, pos_b = base.rotation, base.translation
        f_b = rot_b.T @ hdot_lin
        n_b = rot_b.T @ (hdot_ang + _cross(com - pos_b, hdot_lin))
        c_b = nle[:6] - data.g[:6]
        b1 = np.concatenate([f_b, n_b]) - c_b
        w1 = np.array([p.w_momentum_linear] * 3 + [p.w_momentum_angular] * 3)

        # ---- tasks --------------------------------------------------------------------
        tasks: list[Task] = []
        # Pelvis and torso orientation: upright, heading +x.
        for name, fid, w in (
            ("pelvis", self._pelvis, p.w_pelvis),
            ("torso", self._torso, p.w_torso),
        ):
            jac = pin.getFrameJacobian(model, data, fid, LWA)[3:]
            drift = pin.getFrameClassicalAcceleration(model, data, fid, LWA).angular
            rot = data.oMf[fid].rotation
            omega = jac @ v
            err = -pin.log3(rot)  # world-frame rotation from current to identity
            acc_r = p.kp_orient * err - p.kv_orient * omega
            tasks.append(Task(name, jac, acc_r - drift, np.full(3, w)))
        # Arm and waist joints: hold home.
        idx = self._posture_idx
        jac_post = np.zeros((idx.size, model.nv))
        jac_post[np.arange(idx.size), self._v_idx[idx]] = 1.0
        acc_post = (
            p.kp_posture * (self._q_home[idx] - s.joint_pos[idx]) - p.kv_posture * s.joint_vel[idx]
        )
        tasks.append(Task("posture", jac_post, acc_post, np.full(idx.size, p.w_posture)))

        # Feet: measured contact wrench, state, impedance.
        for side in (LEFT, RIGHT):
            fid = self._sole[side]
            jac = pin.getFrameJacobian(model, data, fid, LWA)
            drift_m = pin.getFrameClassicalAcceleration(model, data, fid, LWA)
            drift = np.concatenate([drift_m.linear, drift_m.angular])
            vel = jac @ v
            sole = data.oMf[fid]
            rpy = pin.rpy.matrixToRpy(sole.rotation)
            x_now = np.array([sole.translation[2], rpy[0], rpy[1]])
            v_now = np.array([vel[2], vel[3], vel[4]])
            acc_meas = (vel - self._prev_foot_vel[side]) / self._dt
            self._prev_foot_vel[side] = vel
            lam = self._contact_wrench(side, s.left_ft if side == LEFT else s.right_ft)
            name = SIDES[side]
            signals.update(
                {
                    f"{name}_fz": lam[0],
                    f"{name}_mx": lam[1],
                    f"{name}_my": lam[2],
                    f"{name}_x": sole.translation[0],
                    f"{name}_z": x_now[0],
                    f"{name}_roll": x_now[1],
                    f"{name}_pitch": x_now[2],
                    f"{name}_vz": v_now[0],
                    f"{name}_wx": v_now[1],
                    f"{name}_wy": v_now[2],
                    f"{name}_az": acc_meas[2],
                    f"{name}_alphax": acc_meas[3],
                    f"{name}_alphay": acc_meas[4],
                }
            )
            imp = self._impedance[side]
            if side != swing:
                st = np.array([self._stance[side][2], 0.0, 0.0])
                imp.reset(x_now, np.zeros(3), np.zeros(3))
                self._foot_acc_cmd[side][:] = 0.0
                signals.update(
                    self._reference_signals(
                        name, st, np.zeros(3), np.zeros(3), st, np.zeros(3), np.zeros(3), False
                    )
                )
                continue
            assert self._swing is not None
            pos_d, vel_d, acc_d = self._swing.at(t)
            xd = np.array([pos_d[2], pos_d[3], pos_d[4]])
            vd = np.array([vel_d[2], vel_d[3], vel_d[4]])
            ad = np.array([acc_d[2], acc_d[3], acc_d[4]])
            was_active = imp.active
            xm, vm, am = imp.update(xd, vd, ad, lam, self._dt, enabled=p.impedance)
            if imp.active and not was_active:
                events.append({"kind": "impedance_on", "foot": name, "fz": float(lam[0])})
            kp = np.full(3, p.kp_swing)
            kv = np.full(3, p.kv_swing)
            a_mod = reference_acceleration(xm, vm, am, x_now, v_now, kp, kv)  # Eq. (3)
            # x, y and yaw follow the plan (Eq. 3 form with the unmodified reference).
            yaw = rpy[2]
            acc_r = np.empty(6)
            acc_r[0:2] = (
                acc_d[0:2]
                + p.kv_swing * (vel_d[0:2] - vel[0:2])
                + p.kp_swing * (pos_d[0:2] - sole.translation[0:2])
            )
            acc_r[2] = a_mod[0]
            acc_r[3] = a_mod[1]
            acc_r[4] = a_mod[2]
            acc_r[5] = -p.kv_swing * vel[5] - p.kp_swing * yaw
            self._foot_acc_cmd[side][:] = acc_r
            tasks.append(Task(f"{name}_swing", jac, acc_r - drift, np.full(6, p.w_swing)))
            signals.update(self._reference_signals(name, xd, vd, ad, xm, vm, am, imp.active))
        # Support feet: contact constraints and wrench bases.
        jacs, drifts, maps = [], [], []
        for side in support:
            fid = self._sole[side]
            jac = pin.getFrameJacobian(model, data, fid, LWA)
            drift_m = pin.getFrameClassicalAcceleration(model, data, fid, LWA)
            jacs.append(jac)
            drifts.append(np.concatenate([drift_m.linear, drift_m.angular]))
            maps.append(contact_wrench_basis(data.oMf[fid].rotation, self._corners, self._pyramid))

        problem = build_qp(
            mass_matrix, nle, b1, w1, jacs, drifts, maps, support, tasks, p.w_accel, p.w_force
        )
        init = (
            self._x_prev
            if self._x_prev is not None and self._x_prev.size == problem.P.shape[0]
            else None
        )
        t_qp = time.perf_counter()
        x = problem.solve(p.solver, initvals=init, eps_abs=p.solver_eps)
        # Wall time of each solve [s], for benchmarks only (never logged: logs stay deterministic).
        self.qp_solve_times.append(time.perf_counter() - t_qp)
        if x is None:
            self._qp_fail += 1
            events.append({"kind": "qp_failed"})
        else:
            self._x_prev = x
            accel, wrenches = problem.split(x)
            self._tau = joint_torques(mass_matrix, nle, accel, jacs, wrenches)
            for side, w in zip(support, wrenches, strict=True):
                signals[f"{SIDES[side]}_fz_qp"] = float(w[2])
        signals.update(
            {
                "com_x": com[0],
                "com_y": com[1],
                "com_z": com[2],
                "com_x_d": c_d[0],
                "com_y_d": c_d[1],
                "com_z_d": c_d[2],
                "zmp_x_ref": float(self._plan.zmp_at(t)[0]),
                "zmp_y_ref": float(self._plan.zmp_at(t)[1]),
                "qp_failures": float(self._qp_fail),
            }
        )
        return Command(ctrl=self._tau.copy(), signals=signals, events=tuple(events))

    @staticmethod
    def _reference_signals(
        name: str,
        xd: np.ndarray,
        vd: np.ndarray,
        ad: np.ndarray,
        xm: np.ndarray,
        vm: np.ndarray,
        am: np.ndarray,
        active: bool,
    ) -> dict[str, float]:
        """Desired and impedance-modified (z, φx, φy) references of one foot, for the log."""
        out: dict[str, float] = {f"{name}_impedance_on": float(active)}
        for i, axis in enumerate(("z", "roll", "pitch")):
            out[f"{name}_{axis}_d"] = float(xd[i])
            out[f"{name}_{axis}_dot_d"] = float(vd[i])
            out[f"{name}_{axis}_ddot_d"] = float(ad[i])
            out[f"{name}_{axis}_m"] = float(xm[i])
            out[f"{name}_{axis}_dot_m"] = float(vm[i])
            out[f"{name}_{axis}_ddot_m"] = float(am[i])
        return out
