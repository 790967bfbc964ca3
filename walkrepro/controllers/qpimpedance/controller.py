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
from bisect import bisect_right

import numpy as np
import pinocchio as pin
from pydantic import Field

from walkrepro.controllers.base import Command, Controller, ControllerParams
from walkrepro.controllers.qpimpedance.centroidal_qp import (
    SOLVERS,
    CentroidalQP,
    contact_wrench_basis,
    friction_basis,
)
from walkrepro.controllers.qpimpedance.condensed import warm_up
from walkrepro.controllers.qpimpedance.footsteps import (
    LEFT,
    RIGHT,
    SIDES,
    FootstepPlan,
    SwingTrajectory,
    plan_walk,
)
from walkrepro.controllers.qpimpedance.impedance import ImpedanceFilter
from walkrepro.controllers.qpimpedance.preview import generate_com, preview_gains
from walkrepro.robot import Robot
from walkrepro.sensors import SensorSnapshot

GRAVITY = 9.81  # [m/s^2]
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
Vec3 = tuple[float, float, float]
#: Support sets, each with its own QP (its β blocks differ).
SUPPORTS = ((LEFT, RIGHT), (RIGHT,), (LEFT,))
#: Names of the per-foot signals, in the order :meth:`QPImpedanceController._update_foot` fills them.
FOOT_SIGNALS = (
    "fz", "mx", "my", "x", "z", "roll", "pitch", "vz", "wx", "wy", "az", "alphax", "alphay"
)  # fmt: skip
#: Names of the reference signals per axis, in the order of ``(x_d, ẋ_d, ẍ_d, x_m, ẋ_m, ẍ_m)``.
REFERENCE_SIGNALS = ("_d", "_dot_d", "_ddot_d", "_m", "_dot_m", "_ddot_m")


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
    solver: str = Field(
        "active_set",
        description=f"QP solver, one of {SOLVERS}: active_set solves the QP exactly with ξ̈"
        " eliminated (compiled, warm-started), proxqp runs ProxSuite directly on the full QP"
        " (warm-started), the others go through qpsolvers",
    )
    solver_eps: float = Field(1e-6, gt=0, description="solver absolute tolerance")


class QPImpedanceController(Controller):
    """Walks the flat-ground plan with the centroidal QP and impedance landing (Jo & Oh).

    A tick runs at 1 kHz, so :meth:`step` keeps to a few dozen numpy calls: arrays are
    preallocated in :meth:`reset`, 3-vector algebra is done on Python floats (numpy costs
    about 1 µs per call on 3-vectors), and the QP is a preallocated :class:`CentroidalQP`
    per support set.
    """

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
        self._oMf = self._data.oMf  # a live view of the frame placements
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
        self._phase_ends = [ph.t1 for ph in self._plan.phases]
        gains = preview_gains(
            p.preview_dt, self._com_height, p.preview_time, p.preview_q, p.preview_r
        )
        q0, _ = robot.pin_state_from_mujoco(robot.home_qpos, np.zeros(robot.mj_model.nv))
        com0 = pin.centerOfMass(model, self._data, q0)
        ref = self._plan.zmp_xy.copy()
        com_x, _ = generate_com(gains, ref[:, 0], np.array([com0[0], 0.0, 0.0]))
        com_y, _ = generate_com(gains, ref[:, 1], np.array([com0[1], 0.0, 0.0]))
        # (x, ẋ, ẍ) samples as Python floats: the tick interpolates two of them.
        self._com_x: list[list[float]] = com_x.tolist()
        self._com_y: list[list[float]] = com_y.tolist()
        self._com_z = float(com0[2] if p.com_height is None else p.com_height)

        names = robot.joint_names
        self._posture_idx = np.array(
            [
                i
                for i, j in enumerate(names)
                if not j.startswith(("l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle"))
            ]
        )
        self._q_home_posture = robot.home_joint_pos[self._posture_idx].copy()
        self._q_idx, self._v_idx = robot.pin_q_idx, robot.pin_v_idx
        self._q, self._v = np.zeros(model.nq), np.zeros(model.nv)
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
        self._foot_acc_cmd = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]  # commanded ẍ of each sole
        self._prev_foot_vel = [np.zeros(6), np.zeros(6)]
        self._tau = np.zeros(robot.n_joints)
        self._int_k = np.zeros(3)
        self._qp_fail = 0

        # Stacked weighted cost rows √W Φ ξ̈ ≈ √W b of §III-D, in a fixed order: momentum (6),
        # pelvis (3), torso (3), posture (one per arm/waist joint), swing foot (6, single
        # support only). The posture rows are constant selections.
        nv, n_post = model.nv, self._posture_idx.size
        self._rows_post = 12
        self._rows_swing = 12 + n_post
        self._cost_rows = np.zeros((self._rows_swing + 6, nv))
        self._cost_rhs = np.zeros(self._rows_swing + 6)
        self._sqrt_w1 = np.sqrt(np.array([p.w_momentum_linear] * 3 + [p.w_momentum_angular] * 3))[
            :, None
        ]
        self._sqrt_w = {
            k: float(np.sqrt(w))
            for k, w in (
                ("pelvis", p.w_pelvis),
                ("torso", p.w_torso),
                ("posture", p.w_posture),
                ("swing", p.w_swing),
            )
        }
        self._cost_rows[self._rows_post + np.arange(n_post), self._v_idx[self._posture_idx]] = (
            self._sqrt_w["posture"]
        )
        local_map = contact_wrench_basis(np.eye(3), self._corners, self._pyramid)
        self._qps = {
            support: CentroidalQP(
                nv,
                support,
                [local_map] * len(support),
                p.w_accel,
                p.w_force,
                p.solver,
                p.solver_eps,
            )
            for support in SUPPORTS
        }
        self._warm_support: tuple[int, ...] | None = None  # QP solved on the previous tick
        warm_up()  # compile the QP kernels now (or load them from numba's cache), not on tick 1
        self._foot_keys = [tuple(f"{name}_{s}" for s in FOOT_SIGNALS) for name in SIDES]
        self._ref_keys = [
            tuple(
                f"{name}_{axis}{kind}"
                for kind in REFERENCE_SIGNALS
                for axis in ("z", "roll", "pitch")
            )
            for name in SIDES
        ]
        self._fz_qp_keys = [f"{name}_fz_qp" for name in SIDES]
        self._impedance_keys = [f"{name}_impedance_on" for name in SIDES]
        # Wall time of each QP solve [s] and of the tick's parts, for benchmarks only
        # (never logged: logs stay deterministic).
        self.qp_solve_times: list[float] = []
        self._timing = dict.fromkeys(("dynamics", "tasks", "qp_build", "qp_solve", "output"), 0.0)

    def timing(self) -> dict[str, float]:
        """Wall time [s] of the tick's parts: Pinocchio, tasks, QP assembly, QP solve, output."""
        return dict(self._timing)

    # ------------------------------------------------------------------------------------

    def _state(self, s: SensorSnapshot) -> tuple[np.ndarray, np.ndarray]:
        """Pinocchio (q, v) as ``s.pinocchio_state``, written into preallocated arrays."""
        if s.base_pos is None or s.base_quat is None or s.base_linvel is None:
            return s.pinocchio_state(self._robot, "qpimpedance (as in §IV)")  # names the fix
        q, v = self._q, self._v
        w, x, y, z = s.base_quat.tolist()
        q[0:3] = s.base_pos
        q[3:7] = (x, y, z, w)
        rot = pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()  # world-from-pelvis
        v[0:3] = s.base_linvel @ rot  # world -> pelvis frame (Rᵀ v)
        v[3:6] = s.base_angvel
        q[self._q_idx] = s.joint_pos
        v[self._v_idx] = s.joint_vel
        return q, v

    def _desired_com(self, t: float) -> tuple[list[float], list[float], list[float]]:
        """CoM position, velocity, acceleration of the preview pattern at ``t`` [m, m/s, m/s²]."""
        if t >= self._plan.end:
            return [self._com_x[-1][0], self._com_y[-1][0], self._com_z], [0.0] * 3, [0.0] * 3
        k = t / self._p.preview_dt
        i = int(min(max(np.floor(k), 0), len(self._com_x) - 2))
        a = min(max(k - i, 0.0), 1.0)
        x0, x1, y0, y1 = self._com_x[i], self._com_x[i + 1], self._com_y[i], self._com_y[i + 1]
        sx = [(1 - a) * x0[j] + a * x1[j] for j in range(3)]
        sy = [(1 - a) * y0[j] + a * y1[j] for j in range(3)]
        return [sx[0], sy[0], self._com_z], [sx[1], sy[1], 0.0], [sx[2], sy[2], 0.0]

    def _contact_wrench(self, side: int, ft: np.ndarray) -> tuple[float, float, float]:
        """Contact wrench on a foot from its F/T reading: (f_z [N], μ_x, μ_y [N m]).

        The sensor (site ``*_foot_ft``) reads the foot-on-leg wrench, which includes the
        weight and inertia of the foot below it (≈ 14 N). Newton–Euler of that foot body:
        f_c = f_s + m (g ẑ + a), μ_c = μ_s − r_c × m (g_vec − a) about the sensor, then moved
        to the sole centre; world axes. a is the foot's commanded acceleration.
        """
        oMf = self._oMf
        site = oMf[self._ft[side]]
        (f0, f1, f2), (s0, s1, s2) = (site.rotation @ ft.reshape(2, 3).T).T.tolist()
        p0, p1, p2 = site.translation.tolist()
        c0, c1, c2 = oMf[self._foot[side]].act(self._foot_com[side]).tolist()
        o0, o1, o2 = oMf[self._sole[side]].translation.tolist()
        a0, a1, a2 = self._foot_acc_cmd[side]
        m = self._foot_mass
        # f_c = f_s − m g_vec + m a, with g_vec = (0, 0, −g).
        fc0, fc1, fc2 = f0 + m * a0, f1 + m * a1, f2 + m * GRAVITY + m * a2
        r0, r1, r2 = c0 - p0, c1 - p1, c2 - p2  # r_c: foot CoM from the sensor
        h0, h1, h2 = -m * a0, -m * a1, m * (-GRAVITY - a2)  # m (g_vec − a)
        mc0 = s0 - (r1 * h2 - r2 * h1)
        mc1 = s1 - (r2 * h0 - r0 * h2)
        d0, d1, d2 = p0 - o0, p1 - o1, p2 - o2  # sensor from the sole centre
        return fc2, mc0 + (d1 * fc2 - d2 * fc1), mc1 + (d2 * fc0 - d0 * fc2)

    def _enter_phase(self, index: int, t: float) -> None:
        """Start a phase: a swing builds its trajectory from the foot's actual pose."""
        phase = self._plan.phases[index]
        self._phase_index = index
        if phase.swing < 0:
            self._swing = None
            return
        sole = self._oMf[self._sole[phase.swing]]
        rpy = pin.rpy.matrixToRpy(sole.rotation)
        start = np.array([*sole.translation, rpy[0], rpy[1]])
        target = np.array([*phase.target, 0.0, 0.0])
        p = self._p
        self._swing = SwingTrajectory(
            phase.t0, phase.t1 - phase.t0, start, target, p.swing_height, p.swing_rise_fraction
        )
        self._stance[phase.swing] = np.array(phase.target)

    def _orientation_task(self, fid: int, row: int, sqrt_w: float) -> None:
        """Upright frame, heading +x: ẍ_r = K_P log(R⁻¹) − K_V ω, rows ``row:row+3``."""
        model, data, p = self._model, self._data, self._p
        jac = pin.getFrameJacobian(model, data, fid, LWA)[3:]
        drift = pin.getFrameClassicalAcceleration(model, data, fid, LWA).angular
        err = pin.log3(self._oMf[fid].rotation)  # minus the world rotation to identity
        acc_r = -p.kp_orient * err - p.kv_orient * (jac @ self._v)
        np.multiply(jac, sqrt_w, out=self._cost_rows[row : row + 3])
        np.multiply(acc_r - drift, sqrt_w, out=self._cost_rhs[row : row + 3])

    def _update_foot(
        self, side: int, ft: np.ndarray, t: float, swing: int, signals: dict, events: list[dict]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A foot's state, wrench, impedance and (in swing) task rows (Eqs. 1–3).

        Args:
            side: LEFT or RIGHT.
            ft: the foot's F/T reading (see :meth:`_contact_wrench`).
            t: time [s].
            swing: the swing foot, or −1.
            signals: the tick's signals, updated in place.
            events: the tick's events, appended to.

        Returns:
            The sole Jacobian (6, nv), its drift J̇ ξ̇ (6,) and rotation (3, 3), world axes.
        """
        model, data, p = self._model, self._data, self._p
        fid = self._sole[side]
        jac = pin.getFrameJacobian(model, data, fid, LWA)
        drift = pin.getFrameClassicalAcceleration(model, data, fid, LWA).vector
        vel = jac @ self._v
        sole = self._oMf[fid]
        rot = sole.rotation
        rpy = pin.rpy.matrixToRpy(rot)
        acc_meas = (vel - self._prev_foot_vel[side]) / self._dt
        self._prev_foot_vel[side] = vel
        lam = self._contact_wrench(side, ft)
        px, py, pz = sole.translation.tolist()
        roll, pitch, yaw = rpy.tolist()
        vl = vel.tolist()
        al = acc_meas.tolist()
        x_now = (pz, roll, pitch)
        v_now = (vl[2], vl[3], vl[4])
        signals.update(
            zip(
                self._foot_keys[side],
                (*lam, px, pz, roll, pitch, vl[2], vl[3], vl[4], al[2], al[3], al[4]),
                strict=True,
            )
        )
        imp = self._impedance[side]
        if side != swing:
            z = float(self._stance[side][2])
            imp.reset(x_now, 0.0, 0.0)  # type: ignore[arg-type]  # broadcast into x_m, ẋ_m, ẍ_m
            self._foot_acc_cmd[side] = [0.0, 0.0, 0.0]
            signals[self._impedance_keys[side]] = 0.0
            zero = (0.0,) * 6
            signals.update(
                zip(self._ref_keys[side], (z, 0.0, 0.0, *zero, z, 0.0, 0.0, *zero), strict=True)
            )
            return jac, drift, rot
        assert self._swing is not None
        pos_d, vel_d, acc_d = self._swing.at(t)
        xd, vd, ad = pos_d[2:5], vel_d[2:5], acc_d[2:5]  # (z, φx, φy)
        was_active = imp.active
        xm, vm, am = imp.update(xd, vd, ad, np.array(lam), self._dt, enabled=p.impedance)
        if imp.active and not was_active:
            events.append({"kind": "impedance_on", "foot": SIDES[side], "fz": float(lam[0])})
        # Eq. (3), ẍ_r = ẍ_m + K_v (ẋ_m − ẋ) + K_p (x_m − x), for (z, φx, φy) with the
        # modified reference; x, y and yaw follow the plan (the same form, unmodified).
        kp, kv = p.kp_swing, p.kv_swing
        pd, vd_, ad_ = pos_d.tolist(), vel_d.tolist(), acc_d.tolist()
        xl, vml, aml = xm.tolist(), vm.tolist(), am.tolist()
        acc_r_list = [
            ad_[0] + kv * (vd_[0] - vl[0]) + kp * (pd[0] - px),
            ad_[1] + kv * (vd_[1] - vl[1]) + kp * (pd[1] - py),
            *(aml[i] + kv * (vml[i] - v_now[i]) + kp * (xl[i] - x_now[i]) for i in range(3)),
            -kv * vl[5] - kp * yaw,
        ]
        self._foot_acc_cmd[side] = acc_r_list[:3]
        acc_r = np.array(acc_r_list)
        sqrt_w = self._sqrt_w["swing"]
        row = self._rows_swing
        np.multiply(jac, sqrt_w, out=self._cost_rows[row : row + 6])
        np.multiply(acc_r - drift, sqrt_w, out=self._cost_rhs[row : row + 6])
        signals[self._impedance_keys[side]] = float(imp.active)
        signals.update(
            zip(
                self._ref_keys[side], (*pd[2:5], *vd_[2:5], *ad_[2:5], *xl, *vml, *aml), strict=True
            )
        )
        return jac, drift, rot

    def step(self, t: float, s: SensorSnapshot) -> Command:
        """One tick of §III-D: tasks → QP → Eq. (9)."""
        t0 = time.perf_counter()
        p, model, data = self._p, self._model, self._data
        q, v = self._state(s)
        # M, C ξ̇ + g, g, the joint Jacobians, the CoM and h_G. Its forward pass also leaves
        # the drift accelerations (ξ̈ = 0) in data.a, so J̇ ξ̇ needs no second kinematics pass.
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        mass_matrix, nle = data.M, data.nle
        t1 = time.perf_counter()

        index = min(bisect_right(self._phase_ends, t), len(self._phase_ends) - 1)
        if index != self._phase_index:
            self._enter_phase(index, t)
        swing = self._plan.phases[index].swing
        support = SUPPORTS[swing + 1]

        signals: dict[str, float] = {"t_plan": t, "swing_foot": float(swing)}
        events: list[dict] = []

        # ---- centroidal momentum reference (§III-D) -------------------------------------
        c0, c1, c2 = com = data.com[0].tolist()
        v0, v1, v2 = data.vcom[0].tolist()
        c_d, v_d, a_d = self._desired_com(t)
        m, kh, ki = self._mass, p.k_h, p.k_i
        # ḣ_lin = m (c̈_d + K_h (ċ_d − ċ) + K_I (c_d − c)), with ∫(h_d − h) = m (c_d − c).
        l0 = m * (a_d[0] + kh * (v_d[0] - v0) + ki * (c_d[0] - c0))
        l1 = m * (a_d[1] + kh * (v_d[1] - v1) + ki * (c_d[1] - c1))
        l2 = m * (a_d[2] + kh * (v_d[2] - v2) + ki * (c_d[2] - c2))
        k0, k1, k2 = (-p.k_h_angular * data.hg.angular).tolist()  # ḣ_ang = −K_h k
        base = data.oMi[1]
        b0, b1, b2 = base.translation.tolist()
        r0, r1, r2 = c0 - b0, c1 - b1, c2 - b2
        # (ḣ_lin, ḣ_ang + (c − p_B) × ḣ_lin) in the base frame: X_GBᵀ ḣ_{G,r} of Eq. (7).
        h_world = np.array(
            [
                [l0, k0 + (r1 * l2 - r2 * l1)],
                [l1, k1 + (r2 * l0 - r0 * l2)],
                [l2, k2 + (r0 * l1 - r1 * l0)],
            ]
        )
        rhs, rows = self._cost_rhs, self._cost_rows
        rhs[0:6] = (base.rotation.T @ h_world).T.ravel()
        rhs[0:6] -= nle[:6] - data.g[:6]  # b_1 = X_GBᵀ ḣ_{G,r} − C_B ξ̇
        rhs[0:6] *= self._sqrt_w1[:, 0]
        np.multiply(mass_matrix[:6], self._sqrt_w1, out=rows[:6])

        # ---- tasks --------------------------------------------------------------------
        self._orientation_task(self._pelvis, 6, self._sqrt_w["pelvis"])
        self._orientation_task(self._torso, 9, self._sqrt_w["torso"])
        # Arm and waist joints: hold home.
        idx = self._posture_idx
        acc_post = p.kp_posture * (self._q_home_posture - s.joint_pos[idx])
        acc_post -= p.kv_posture * s.joint_vel[idx]
        np.multiply(acc_post, self._sqrt_w["posture"], out=rhs[self._rows_post : self._rows_swing])
        # Feet: measured contact wrench, state, impedance (and the swing rows).
        feet = [
            self._update_foot(LEFT, s.left_ft, t, swing, signals, events),
            self._update_foot(RIGHT, s.right_ft, t, swing, signals, events),
        ]
        n_rows = self._rows_swing + (6 if swing >= 0 else 0)
        t2 = time.perf_counter()

        # ---- QP and Eq. (9) -----------------------------------------------------------
        qp = self._qps[support]
        qp.update(
            mass_matrix,
            nle,
            rows[:n_rows],
            rhs[:n_rows],
            [feet[k][0] for k in support],
            [feet[k][1] for k in support],
            [feet[k][2] for k in support],
        )
        t3 = time.perf_counter()
        solved = qp.solve(warm=support == self._warm_support)
        t4 = time.perf_counter()
        self.qp_solve_times.append(t4 - t3)
        if not solved:
            self._qp_fail += 1
            self._warm_support = None
            events.append({"kind": "qp_failed"})
        else:
            self._warm_support = support
            self._tau[:] = qp.tau
            for side, wrench in zip(support, qp.wrenches.tolist(), strict=True):
                signals[self._fz_qp_keys[side]] = wrench[2]
        zmp_x, zmp_y = self._plan.zmp_at(t)
        signals.update(
            com_x=com[0],
            com_y=com[1],
            com_z=com[2],
            com_x_d=c_d[0],
            com_y_d=c_d[1],
            com_z_d=c_d[2],
            zmp_x_ref=zmp_x,
            zmp_y_ref=zmp_y,
            qp_failures=float(self._qp_fail),
        )
        command = Command(ctrl=self._tau.copy(), signals=signals, events=tuple(events))
        timing = self._timing
        timing["dynamics"] += t1 - t0
        timing["tasks"] += t2 - t1
        timing["qp_build"] += t3 - t2
        timing["qp_solve"] += t4 - t3
        timing["output"] += time.perf_counter() - t4
        return command
