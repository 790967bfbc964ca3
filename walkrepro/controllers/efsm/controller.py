"""E-FSM walking controller of Lee et al. 2021: E-FSM (§III) + OS-WBC (§IV, Appendices).

Each control tick: build O_w from the feet (§III-A1), run the E-FSM (Table I) on the CoM,
capture point and swing-foot position, then compute Γ = Γ_t + Γ_c + Γ_gc (Eq. 7) with
three prioritized tasks (Eq. 11):

1. CoM x-force realising x_p^des (Appendix D-1);
2. CoM y/z, upper-body yaw and, out of DS, the 6-D swing foot (Eq. 6, saturated F_s × ε);
3. upper-body roll and pitch (Eq. 6), plus F_3^bal when the expected CoP leaves the
   shrunk support polygon (Appendix D-3, Eqs. 23–29).
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
import pinocchio as pin
from pydantic import Field

from walkrepro.controllers.base import Command, Controller, ControllerParams
from walkrepro.controllers.efsm import wbc
from walkrepro.controllers.efsm.fsm import (
    EventFsm,
    FsmInput,
    FsmParams,
    Phase,
    capture_point,
    epsilon,
)
from walkrepro.robot import Robot
from walkrepro.sensors import SensorSnapshot

GRAVITY = 9.81  # [m/s^2]
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
FEET = ("left", "right")


class EfsmParams(ControllerParams):
    """Parameters of the E-FSM walking controller (Lee et al. 2021, §V-B unless noted)."""

    zeta: float = Field(0.03, gt=0, description="margin ζ of law L1 [m] (§V-B)")
    r: float = Field(0.08, gt=0, description="margin r of law L2 [m] (§V-B)")
    dxp: float = Field(0.0007, gt=0, description="Δx_p^des per control period [m] (§V-B)")
    d_thr: float = Field(0.01, gt=0, description="ε threshold d^thr [m] (§V-B)")
    v_stop: float = Field(
        0.005, ge=0, description="|ẋ_m| counted as ≈ 0 ending SSD [m/s] (assumed; Table I)"
    )
    use_epsilon: bool = Field(True, description="False: ε ≡ 1, the ablation of §VI-D1")
    ds_onset_ramp: bool = Field(
        True,
        description="ε's ramp also at DS onset: the landing foot's wrench grows from 0 over "
        "the first d^thr of the x_p^des ramp (walkrepro extension of §IV-B; off without ε)",
    )
    kp: float = Field(100.0, gt=0, description="task stiffness k_p [1/s^2] (§V-B)")
    kv: float = Field(20.0, gt=0, description="task damping k_v [1/s] (§V-B)")
    raise_height: float = Field(0.05, description="swing-foot height in SSD [m] (Table II)")
    land_height: float = Field(0.005, description="swing-foot height in SSA [m] (Table II)")
    fs_max_force: float = Field(
        30.0,
        gt=0,
        description="saturation of each F_s force component [N]. §V-B gives no value; "
        "a completely blocked swing foot presses the obstacle with it, and §VI-B measured "
        "≈ 32 N there. (With 50 N the blocked foot held the CoM still in SSD and the robot "
        "fell; see experiments/obstacle_collision.yaml)",
    )
    fs_max_moment: float = Field(
        10.0, gt=0, description="saturation of each F_s moment component [Nm] (assumed)"
    )
    fs_decoupled_saturation: bool = Field(
        True,
        description="saturate F_s's force rows without disturbing the orientation "
        "acceleration (Λ_s couples them; see _task2_force)",
    )
    step_length: float = Field(0.1, description="forward step length [m] (§VI-A)")
    step_width: float | None = Field(
        None, description="lateral foot spacing [m]; None keeps the initial spacing"
    )
    n_steps: int | None = Field(
        None, ge=0, description="footsteps of step_length, then in place; None: no limit"
    )
    first_swing: Literal["left", "right"] = Field(
        "right", description="foot that swings first (§VI-B: the right foot)"
    )
    balance: bool = Field(True, description="F_3^bal when the expected CoP leaves the polygon")
    cop_margin: float = Field(
        0.03, ge=0, description="safety margin of the support polygon [m] (Fig. 16; assumed)"
    )
    torque_limit: float = Field(300.0, gt=0, description="actuator saturation [Nm] (robot)")


class EfsmController(Controller):
    """Event-based FSM walking with the operational-space whole-body controller."""

    Params = EfsmParams
    FRAMES = ("O_w",)

    def reset(self, robot: Robot, params: ControllerParams, control_period: float) -> None:
        """Cache models and start in DS with the CoP moving onto the first support foot."""
        assert isinstance(params, EfsmParams)
        if robot.control_mode != "torque":
            raise ValueError("the E-FSM controller needs a torque-controlled robot")
        self._robot, self._p = robot, params
        self._model = robot.pin_model
        self._data = self._model.createData()
        self._sole = {f: robot.pin_frame_id(f"{f}_sole") for f in FEET}
        self._ft = {f: robot.pin_frame_id(f"{f}_foot_ft") for f in FEET}
        self._foot_joint = {f: robot.pin_joint_id(f"{f[0]}_ankle_roll") for f in FEET}
        self._pelvis_joint = 1  # the free-flyer root: the rigid upper body
        self._v_idx = np.asarray(robot.pin_v_idx) - 6  # actuator i -> joint-torque row
        self._half_sole = np.asarray(robot.sole_size) / 2.0
        self._fsm = EventFsm(
            FsmParams(
                params.zeta, params.r, params.dxp, params.d_thr, params.v_stop, params.use_epsilon
            )
        )
        self._support = "left" if params.first_swing == "right" else "right"
        self._started = False
        self._steps_done = 0
        self._ds_start_xp: float | None = None
        self._swing_target = np.zeros(3)
        self._rot_w = np.eye(3)
        self._nv = self._model.nv

    # ---- frames ------------------------------------------------------------------------

    def frame(self, name: str) -> np.ndarray | None:
        """World-from-O_w rotation (the push of §VI-C is along +x of O_w)."""
        return self._rot_w.copy() if name == "O_w" else None

    @staticmethod
    def _ow_rotation(p_sup: np.ndarray, p_sw: np.ndarray) -> np.ndarray:
        """O_w axes (§III-A1): x from the support to the swing foot's ground projection."""
        dx, dy = p_sw[0] - p_sup[0], p_sw[1] - p_sup[1]
        yaw = math.atan2(dy, dx)
        c, s = math.cos(yaw), math.sin(yaw)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    # ---- the control tick ----------------------------------------------------------------

    def step(self, t: float, sensors: SensorSnapshot) -> Command:
        """One control period of the E-FSM + OS-WBC."""
        p, model, data = self._p, self._model, self._data
        q, v = sensors.pinocchio_state(self._robot, "the E-FSM controller")
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        com, vcom = data.com[0].copy(), data.vcom[0].copy()
        sole = {f: data.oMf[self._sole[f]] for f in FEET}
        if not self._started:
            self._start(sole, com)
        events: list[dict[str, Any]] = []

        # O_w and the E-FSM inputs (§III-A1, Eq. 2).
        sup, sw = self._support, self._other(self._support)
        p_sup, p_sw = sole[sup].translation.copy(), sole[sw].translation.copy()
        rot = self._ow_rotation(p_sup, p_sw)
        com_w, vcom_w = rot.T @ (com - p_sup), rot.T @ vcom
        x_s = float((rot.T @ (p_sw - p_sup))[0])
        x_cp = capture_point(com_w[0], vcom_w[0], self._z_m0)
        out = self._fsm.step(FsmInput(com_w[0], vcom_w[0], x_cp, x_s))
        for old, new in out.transitions:
            events.append({"kind": "fsm", "from": old.name, "to": new.name})
        xp_des, eps = out.xp_des, out.epsilon
        if out.switched_support:
            # DS ends: the swing foot becomes the support foot; next footstep target.
            self._support, sup, sw = sw, sw, sup
            p_sup, p_sw = p_sw, p_sup
            self._plan_next_step(p_sup, sw)
            rot = self._ow_rotation(p_sup, p_sw)
            com_w, vcom_w = rot.T @ (com - p_sup), rot.T @ vcom
            x_s = float((rot.T @ (p_sw - p_sup))[0])
            x_cp = capture_point(com_w[0], vcom_w[0], self._z_m0)
            xp_des = 0.0
            self._fsm.reframe(xp_des)
            events.append({"kind": "support", "foot": sup, "step": self._steps_done})
        self._rot_w = rot
        phase = self._fsm.phase
        double = phase is Phase.DS

        # Contact set: the support foot, plus the swing foot in DS.
        contacts = [sup, sw] if double else [sup]
        jc_blocks, jdv = [], []
        pin.forwardKinematics(model, data, q, v, np.zeros(self._nv))
        for f in contacts:
            jc_blocks.append(pin.getFrameJacobian(model, data, self._sole[f], LWA))
            acc = pin.getFrameClassicalAcceleration(model, data, self._sole[f], LWA)
            jdv.append(acc.vector)
        jc, jc_dot_v = np.vstack(jc_blocks), np.concatenate(jdv)
        a = np.triu(data.M) + np.triu(data.M, 1).T
        a_inv = np.linalg.inv(a)
        cd = wbc.contact_dynamics(a_inv, data.nle, jc, jc_dot_v)

        # Task Jacobians (Eq. 11), CoM rows in O_w axes, upper body = pelvis (rigid).
        jcom_w = rot.T @ data.Jcom
        j_ub = pin.getJointJacobian(model, data, self._pelvis_joint, LWA)[3:]
        rot_pelvis = data.oMi[self._pelvis_joint].rotation
        w_pelvis = j_ub @ v
        j1 = jcom_w[0:1]
        j2_rows = [jcom_w[1:3], j_ub[2:3]]
        if not double:
            j_sw = pin.getFrameJacobian(model, data, self._sole[sw], LWA)
            j2_rows.append(j_sw)
        j2 = np.vstack(j2_rows)
        j3 = (rot.T @ j_ub)[0:2]

        # Reference accelerations, Eq. (6) (Table II targets).
        kp, kv = p.kp, p.kv
        e_ub = pin.log3(self._rot_ub_des @ rot_pelvis.T)  # world-axes orientation error
        acc2 = [
            kp * (0.0 - com_w[1]) - kv * vcom_w[1],
            kp * (self._z_m0 - com_w[2]) - kv * vcom_w[2],
            kp * e_ub[2] - kv * w_pelvis[2],
        ]
        sw_pos = sole[sw].translation
        sw_ref = self._swing_ref(phase, p_sup)
        if not double:
            v_sw = j_sw @ v
            e_sw = np.r_[sw_ref - sw_pos, pin.log3(self._rot_foot_des @ sole[sw].rotation.T)]
            acc2.extend(kp * e_sw - kv * v_sw)
        acc3 = (rot.T @ (kp * e_ub - kv * w_pelvis))[0:2]

        # The hierarchy (Eq. 11, Appendix A).
        phi1 = wbc.task_phi(cd, j1)
        phi2 = wbc.task_phi(cd, j2)
        phi3 = wbc.task_phi(cd, j3)
        n1 = wbc.null_space_t(cd, phi1)
        n12 = wbc.null_space_t(cd, np.vstack([phi1, phi2]))
        task1 = wbc.prioritized_task(cd, phi1, None)
        task2 = wbc.prioritized_task(cd, phi2, n1)
        task3 = wbc.prioritized_task(cd, phi3, n12)
        f2 = self._task2_force(task2.lam, np.asarray(acc2), double, eps, phase)
        f3 = task3.lam @ acc3
        g2, g3 = task2.torque_map @ f2, task3.torque_map @ f3

        # CoM x-force for x_p^des (Appendix D-1, Eqs. 17–21) in O_w at the support centre.
        points = [sole[f].translation for f in contacts]
        kmap = wbc.grasp_map(rot, p_sup, points)
        kpsi = kmap @ cd.psi
        fc2, fc3 = kpsi @ g2, kpsi @ g3
        fcb = kmap @ (cd.psi @ cd.gamma_gc + cd.f_bias)
        q1 = float((kpsi @ task1.torque_map)[4, 0])
        f1 = wbc.com_force_for_cop(xp_des, q1, fc2[2] + fc3[2] + fcb[2], fcb[4])
        g1 = task1.torque_map[:, 0] * f1

        # Balancing (Appendix D-3): expected CoP out of the shrunk polygon -> F_3^bal.
        fc = kpsi @ g1 + fc2 + fc3 + fcb
        balancing = False
        if p.balance:
            f3_new = self._balance_force(
                fc, fc3, kpsi @ task3.torque_map, rot, sole[sup], x_s if double else None
            )
            if f3_new is not None:
                balancing = True
                g3 = task3.torque_map @ f3_new
                fc = fc - fc3 + kpsi @ g3
        gamma_t = g1 + g2 + g3

        # Contact wrench redistribution in DS (Appendix C) with ε (§IV-B).
        gamma_c = np.zeros_like(gamma_t)
        eps_on = 1.0
        if double:
            if self._ds_start_xp is None:
                self._ds_start_xp = xp_des
            if p.use_epsilon and p.ds_onset_ramp:
                eps_on = epsilon(abs(xp_des - self._ds_start_xp), p.d_thr)
            f_now = cd.psi @ (gamma_t + cd.gamma_gc) + cd.f_bias
            gamma_c, _ = wbc.redistribution_torque(
                cd, f_now, slice(0, 6), eps, eps_on, p_sup - p_sw
            )
        else:
            self._ds_start_xp = None
        gamma = gamma_t + gamma_c + cd.gamma_gc  # Eq. (7)
        tau = np.clip(gamma[self._v_idx], -p.torque_limit, p.torque_limit)

        # Expected CoP from the reference torques (Eqs. 9, 18, 22) and measured CoP (F/T).
        fc_all = kmap @ (cd.psi @ gamma + cd.f_bias)
        cop_exp_w = np.array(wbc.cop_of(fc_all))
        cop_exp_world = p_sup[:2] + rot[:2, :2] @ cop_exp_w
        cop_meas_world = self._measured_cop(sensors, data, contacts)
        meas_valid = bool(np.all(np.isfinite(cop_meas_world)))
        if not meas_valid:  # no foot loaded: logs hold finite numbers only
            cop_meas_world = np.zeros(2)
        fsm_state = 0 if double else (1 if sup == "left" else -1)
        xp_world = p_sup[:2] + rot[:2, 0] * xp_des
        signals = {
            "fsm_state": fsm_state,
            "efsm_phase": int(phase),
            "epsilon": eps,
            "epsilon_onset": eps_on,
            "d": out.d if math.isfinite(out.d) else 1.0,
            "com_w": com_w.tolist(),
            "com_vel_w": vcom_w.tolist(),
            "com_world": com.tolist(),
            "com_vel_world": vcom.tolist(),
            "cp_w": x_cp,
            "cp_ref_w": x_s - p.r,
            "x_s_w": x_s,
            "xp_des_w": xp_des,
            "xp_des_world": xp_world.tolist(),
            "cop_exp_w": cop_exp_w.tolist(),
            "cop_exp_world": cop_exp_world.tolist(),
            "cop_meas_world": cop_meas_world.tolist(),
            "cop_meas_valid": int(meas_valid),
            "swing_pos_world": sw_pos.tolist(),
            "swing_ref_world": sw_ref.tolist(),
            "swing_foot": 0 if double else (1 if sw == "right" else -1),
            "support_pos_world": p_sup.tolist(),
            "ow_yaw": math.atan2(rot[1, 0], rot[0, 0]),
            "com_force_x": f1,
            "balancing": int(balancing),
            "tau_ref": tau.tolist(),
            "steps_done": self._steps_done,
        }
        return Command(ctrl=tau, signals=signals, events=tuple(events))

    # ---- helpers -------------------------------------------------------------------------

    @staticmethod
    def _other(foot: str) -> str:
        return "right" if foot == "left" else "left"

    def _start(self, sole: dict[str, pin.SE3], com: np.ndarray) -> None:
        """Record the initial targets (Table II) and start the first DS (Table I)."""
        p = self._p
        self._started = True
        self._rot_ub_des = _yaw_only(self._data.oMi[self._pelvis_joint].rotation)
        self._rot_foot_des = _yaw_only(sole["left"].rotation)
        self._heading = self._rot_ub_des[:, 0].copy()
        self._lateral = self._rot_ub_des[:, 1].copy()
        spacing = float(self._lateral @ (sole["left"].translation - sole["right"].translation))
        self._width = spacing if p.step_width is None else p.step_width
        self._z_m0 = float(
            com[2] - 0.5 * (sole["left"].translation[2] + sole["right"].translation[2])
        )
        # The first DS: O_w sits on the first swing foot, the CoP moves onto the support
        # foot (x_s); it starts where the CoM projects (standing still, CoP ≈ CoM).
        sup, sw = self._other(self._support), self._support  # roles in the first DS
        self._support = sup
        p_sup, p_sw = sole[sup].translation, sole[sw].translation
        rot = self._ow_rotation(p_sup, p_sw)
        self._fsm.xp_des = float((rot.T @ (com - p_sup))[0])
        self._rot_w = rot

    def _plan_next_step(self, p_sup: np.ndarray, swing: str) -> None:
        """Footstep planner: the next swing-foot target, step_length ahead of the support.

        After ``n_steps`` footsteps the targets are beside the support foot (stepping in
        place), so the E-FSM keeps its cycle without a separate stopping state.
        """
        self._steps_done += 1
        side = 1.0 if swing == "left" else -1.0
        n = self._p.n_steps
        length = self._p.step_length if n is None or self._steps_done <= n else 0.0
        target = p_sup + self._heading * length + side * self._width * self._lateral
        self._swing_target = target

    def _swing_ref(self, phase: Phase, p_sup: np.ndarray) -> np.ndarray:
        """Swing-foot position reference (Table II): planned xy, raise/land height."""
        h = self._p.raise_height if phase is Phase.SSD else self._p.land_height
        ref = self._swing_target.copy()
        ref[2] = p_sup[2] + h
        return ref

    def _task2_force(
        self, lam: np.ndarray, acc: np.ndarray, double: bool, eps: float, phase: Phase
    ) -> np.ndarray:
        """F_2 = Λ ẍ* (Eq. 6) with the swing-foot wrench F_s saturated and scaled by ε.

        Out of DS the last six rows are the swing foot. F_s is bounded component-wise
        (§V-B) and multiplied by ε in SSA (§IV-C). The force rows are saturated with the
        orientation acceleration kept (``fs_decoupled_saturation``): clipping the force
        rows of Λ ẍ* alone leaves in the moment rows the coupling term of an acceleration
        that is no longer produced, which pitched the swing foot 14° toe-up in free swing
        and 35° against the obstacle. The CoM/yaw forces are then computed
        with the swing-foot acceleration that this bounded F_s actually produces, so that
        they do not carry the coupling of an unbounded swing acceleration.
        """
        if double:
            return lam @ acc
        p = self._p
        c, s = slice(0, 3), slice(3, 9)
        fs = lam[s] @ acc
        if p.fs_decoupled_saturation:
            # Λ_s couples the swing foot's linear and angular rows: Λ ẍ* puts into the
            # moment rows the part Λ_rt ẍ*_t that pairs with the (large) linear
            # acceleration. Clipping only the force rows would leave that moment and
            # spin the foot. Instead keep the orientation acceleration ẍ*_r and take
            # the linear acceleration that the saturated force really produces.
            t_, r_ = slice(3, 6), slice(6, 9)
            f_t = np.clip(fs[:3], -p.fs_max_force, p.fs_max_force)
            rhs = f_t - lam[t_, c] @ acc[c] - lam[t_, r_] @ acc[r_]
            a_t = np.linalg.solve(lam[t_, t_], rhs)
            m_r = lam[r_, c] @ acc[c] + lam[r_, t_] @ a_t + lam[r_, r_] @ acc[r_]
            fs = np.concatenate([f_t, m_r])
        fs[:3] = np.clip(fs[:3], -p.fs_max_force, p.fs_max_force)
        fs[3:] = np.clip(fs[3:], -p.fs_max_moment, p.fs_max_moment)
        fs *= eps if phase is Phase.SSA else 1.0  # ε F_s (§IV-C)
        acc_s = np.linalg.solve(lam[s, s], fs - lam[s, c] @ acc[c])
        return np.concatenate([lam[c, c] @ acc[c] + lam[c, s] @ acc_s, fs])

    def _balance_force(
        self,
        fc: np.ndarray,
        fc3: np.ndarray,
        kpsi3: np.ndarray,
        rot: np.ndarray,
        sole_sup: pin.SE3,
        x_s: float | None,
    ) -> np.ndarray | None:
        """F_3 + F_3^bal (Eqs. 23–29), or None when the expected CoP is inside (Eq. 23).

        The support polygon is the square of Eq. (23) in O_w: the support sole's extent
        along the O_w axes, stretched to the swing foot (x_s) in DS (Fig. 16), shrunk by the
        safety margin.
        """
        cop_w = np.array(wbc.cop_of(fc))
        if not np.all(np.isfinite(cop_w)):
            return None
        rel = rot[:2, :2].T @ sole_sup.rotation[:2, :2]  # O_w-from-foot (xy)
        half = np.abs(rel) @ self._half_sole - self._p.cop_margin  # extent along O_w axes
        lo, hi = -half, half.copy()
        if x_s is not None:
            hi[0] += x_s
        clamped = np.clip(cop_w, lo, hi)
        if np.allclose(clamped, cop_w):
            return None
        fsig = fc - fc3
        m_des = np.array(
            [clamped[1] * fsig[2] - fsig[3], -clamped[0] * fsig[2] - fsig[4]]
        )  # Eqs. (26)-(27)
        q3 = kpsi3[3:5]  # Eq. (28)
        if abs(np.linalg.det(q3)) < 1e-12:
            return None
        return np.linalg.solve(q3, m_des)  # F_3 + F_3^bal, Eq. (29)

    def _measured_cop(
        self, sensors: SensorSnapshot, data: pin.Data, contacts: list[str]
    ) -> np.ndarray:
        """CoP in the world from the two F/T sensors (§VI-D2) [m].

        Each sensor reads the wrench the foot applies to the leg; adding back the static
        weight of the part below the sensor (the ankle-roll link, i.e. the foot) gives the
        ground reaction. Feet carrying no vertical load are left out.
        """
        force = np.zeros(3)
        moment = np.zeros(3)  # about the world origin
        for f in FEET:
            ft = sensors.left_ft if f == "left" else sensors.right_ft
            m_ft = data.oMf[self._ft[f]]
            fw, tw = m_ft.rotation @ ft[:3], m_ft.rotation @ ft[3:]
            inertia = self._model.inertias[self._foot_joint[f]]
            weight = np.array([0.0, 0.0, inertia.mass * GRAVITY])
            com_foot = data.oMi[self._foot_joint[f]].act(inertia.lever)
            fg = fw + weight
            if fg[2] <= 0.0:
                continue
            force += fg
            moment += tw + np.cross(m_ft.translation, fw) + np.cross(com_foot, weight)
        if force[2] <= 1e-6:
            return np.array([math.nan, math.nan])
        # Ground-level CoP: the point on z = 0 about which the moment has no x/y part.
        return np.array([-moment[1] / force[2], moment[0] / force[2]])


def _yaw_only(rot: np.ndarray) -> np.ndarray:
    """The yaw part of a rotation: level, with the same heading."""
    yaw = math.atan2(rot[1, 0], rot[0, 0])
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
