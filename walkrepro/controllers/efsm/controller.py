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
        v_idx = np.asarray(robot.pin_v_idx) - 6  # actuator i -> joint-torque row
        # None when the actuators are in joint-torque order (no reindexing per tick).
        self._v_idx = None if np.array_equal(v_idx, np.arange(len(v_idx))) else v_idx
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
        inertias = {f: self._model.inertias[self._foot_joint[f]] for f in FEET}
        self._foot_weight = {f: inertias[f].mass * GRAVITY for f in FEET}  # [N]
        self._foot_lever = {f: inertias[f].lever.copy() for f in FEET}  # CoM in the joint [m]

    # ---- frames ------------------------------------------------------------------------

    def frame(self, name: str) -> np.ndarray | None:
        """World-from-O_w rotation (the push of §VI-C is along +x of O_w)."""
        return self._rot_w.copy() if name == "O_w" else None

    @staticmethod
    def _ow_rotation(p_sup: np.ndarray, p_sw: np.ndarray) -> np.ndarray:
        """O_w axes (§III-A1): x from the support to the swing foot's ground projection."""
        dx, dy = float(p_sw[0] - p_sup[0]), float(p_sw[1] - p_sup[1])
        return _yaw_rotation(math.atan2(dy, dx))

    # ---- the control tick ----------------------------------------------------------------

    def step(self, t: float, sensors: SensorSnapshot) -> Command:
        """One control period of the E-FSM + OS-WBC."""
        p, model, data = self._p, self._model, self._data
        q, v = sensors.pinocchio_state(self._robot, "the E-FSM controller")
        # One pass: M, b + g, joint Jacobians, CoM and its Jacobian, and (with q̈ = 0) the
        # bias accelerations J̇ q̇ of every frame.
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        com, vcom = data.com[0], data.vcom[0]  # read within this tick only
        if not self._started:
            self._start({f: data.oMf[self._sole[f]] for f in FEET}, com)
        events: list[dict[str, Any]] = []

        # O_w and the E-FSM inputs (§III-A1, Eq. 2).
        sup, sw = self._support, self._other(self._support)
        m_sup, m_sw = data.oMf[self._sole[sup]], data.oMf[self._sole[sw]]
        p_sup, p_sw = m_sup.translation.copy(), m_sw.translation.copy()
        rot, com_w, vcom_w, x_s = _ow_frame(p_sup, p_sw, com, vcom)
        x_cp = capture_point(com_w[0], vcom_w[0], self._z_m0)
        out = self._fsm.step(FsmInput(com_w[0], vcom_w[0], x_cp, x_s))
        for old, new in out.transitions:
            events.append({"kind": "fsm", "from": old.name, "to": new.name})
        xp_des, eps = out.xp_des, out.epsilon
        if out.switched_support:
            # DS ends: the swing foot becomes the support foot; next footstep target.
            self._support, sup, sw = sw, sw, sup
            m_sup, m_sw, p_sup, p_sw = m_sw, m_sup, p_sw, p_sup
            self._plan_next_step(p_sup, sw)
            rot, com_w, vcom_w, x_s = _ow_frame(p_sup, p_sw, com, vcom)
            x_cp = capture_point(com_w[0], vcom_w[0], self._z_m0)
            xp_des = 0.0
            self._fsm.reframe(xp_des)
            events.append({"kind": "support", "foot": sup, "step": self._steps_done})
        rot_t = rot.T
        self._rot_w = rot
        phase = self._fsm.phase
        double = phase is Phase.DS

        # Contact set: the support foot, plus the swing foot in DS.
        contacts = (sup, sw) if double else (sup,)
        if double:
            jc, jc_dot_v = np.empty((12, self._nv)), np.empty(12)
            for i, f in enumerate(contacts):
                jc[6 * i : 6 * i + 6] = pin.getFrameJacobian(model, data, self._sole[f], LWA)
                acc = pin.getFrameClassicalAcceleration(model, data, self._sole[f], LWA)
                jc_dot_v[6 * i : 6 * i + 6] = acc.vector
        else:
            jc = pin.getFrameJacobian(model, data, self._sole[sup], LWA)
            jc_dot_v = pin.getFrameClassicalAcceleration(model, data, self._sole[sup], LWA).vector
        pin.cholesky.decompose(model, data)  # A = U D Uᵀ of the M from computeAllTerms
        a_inv = pin.cholesky.computeMinv(model, data)  # A⁻¹, both triangles
        cd = wbc.contact_dynamics(a_inv, data.nle, jc, jc_dot_v)

        # Task Jacobians (Eq. 11), CoM rows in O_w axes, upper body = pelvis (rigid), stacked:
        # task 1 = CoM x; task 2 = CoM y/z, pelvis yaw (+ swing foot); task 3 = pelvis roll/pitch.
        j_ub = pin.getJointJacobian(model, data, self._pelvis_joint, LWA)[3:]
        rot_pelvis = data.oMi[self._pelvis_joint].rotation
        w_pelvis = j_ub @ v
        m2 = 3 if double else 9
        j_com_w, j_ub_w = rot_t @ data.Jcom, rot_t[0:2] @ j_ub
        if double:
            j_all = np.concatenate((j_com_w, j_ub[2:3], j_ub_w))
        else:
            j_sw = pin.getFrameJacobian(model, data, self._sole[sw], LWA)
            j_all = np.concatenate((j_com_w, j_ub[2:3], j_sw, j_ub_w))

        # Reference accelerations, Eq. (6) (Table II targets).
        kp, kv = p.kp, p.kv
        e_ub = pin.log3(self._rot_ub_des @ rot_pelvis.T)  # world-axes orientation error
        _, cw_y, cw_z = com_w
        _, vw_y, vw_z = vcom_w
        acc2 = np.empty(m2)
        acc2[0:3] = (
            kp * (0.0 - cw_y) - kv * vw_y,
            kp * (self._z_m0 - cw_z) - kv * vw_z,
            kp * float(e_ub[2]) - kv * float(w_pelvis[2]),
        )
        sw_pos = p_sw
        sw_ref = self._swing_ref(phase, p_sup)
        if not double:
            acc2[3:6] = sw_ref - sw_pos
            acc2[6:9] = pin.log3(self._rot_foot_des @ m_sw.rotation.T)
            acc2[3:9] *= kp
            acc2[3:9] -= kv * (j_sw @ v)
        acc3 = rot_t[0:2] @ (kp * e_ub - kv * w_pelvis)

        # The hierarchy (Eq. 11, Appendix A): rows [task 1 (1), task 2 (m2), task 3 (2)].
        s2, s3 = slice(1, m2 + 1), slice(m2 + 1, m2 + 3)
        hier = wbc.task_hierarchy(cd, wbc.task_phi(cd, j_all), 1, m2)
        tmap, (_, lam2, lam3) = hier.torque_map, hier.lams
        f_all = np.empty(m2 + 3)  # [F_1; F_2; F_3]
        f_all[s2] = self._task2_force(lam2, acc2, double, eps, phase)
        f_all[s3] = lam3 @ acc3

        # CoM x-force for x_p^des (Appendix D-1, Eqs. 17–21) in O_w at the support centre.
        kmap = wbc.grasp_map(rot, p_sup, [p_sup, p_sw] if double else [p_sup])
        kpsi = kmap @ cd.psi
        kt = kpsi @ tmap  # resultant wrench per task force, shape (6, m)
        fc23 = kt[:, 1:] @ f_all[1:]  # of tasks 2 and 3
        fcb = kmap @ (cd.psi @ cd.gamma_gc + cd.f_bias)
        q1 = float(kt[4, 0])
        f1 = wbc.com_force_for_cop(xp_des, q1, float(fc23[2] + fcb[2]), float(fcb[4]))
        f_all[0] = f1

        # Balancing (Appendix D-3): expected CoP out of the shrunk polygon -> F_3^bal.
        fc = kt[:, 0] * f1 + fc23 + fcb
        balancing = False
        if p.balance:
            kt3, f3 = kt[:, s3], f_all[s3]
            f3_new = self._balance_force(fc, kt3, f3, rot, m_sup, x_s if double else None)
            if f3_new is not None:
                balancing = True
                fc = fc + kt3 @ (f3_new - f3)  # F_3 replaced
                f_all[s3] = f3_new
        gamma = tmap @ f_all + cd.gamma_gc  # Γ_t + Γ_gc, Γ_t = Σ Ñ_precᵀ J̃ᵀ F (Eq. 11)

        # Contact wrench redistribution in DS (Appendix C) with ε (§IV-B).
        eps_on = 1.0
        if double:
            if self._ds_start_xp is None:
                self._ds_start_xp = xp_des
            if p.use_epsilon and p.ds_onset_ramp:
                eps_on = epsilon(abs(xp_des - self._ds_start_xp), p.d_thr)
            f_now = cd.psi @ gamma + cd.f_bias
            gamma_c, _ = wbc.redistribution_torque(
                cd, f_now, slice(0, 6), eps, eps_on, p_sup - p_sw
            )
            gamma += gamma_c  # Γ = Γ_t + Γ_c + Γ_gc, Eq. (7)
            fc_all = fc + kpsi @ gamma_c
        else:
            self._ds_start_xp = None  # Γ_c = 0
            fc_all = fc
        tau_lim = p.torque_limit
        tau = gamma if self._v_idx is None else gamma[self._v_idx]
        tau = np.minimum(np.maximum(tau, -tau_lim), tau_lim)  # np.clip

        # Expected CoP from the reference torques (Eqs. 9, 18, 22): the resultant
        # K (Ψ Γ + f_bias) = fc (+ K Ψ Γ_c), and measured CoP (F/T).
        cop_exp_x, cop_exp_y = wbc.cop_of(fc_all)
        (r00, r01, _), (r10, r11, _) = rot[:2].tolist()
        sup_x, sup_y, _ = p_sup.tolist()
        cop_exp_world = [
            sup_x + (r00 * cop_exp_x + r01 * cop_exp_y),
            sup_y + (r10 * cop_exp_x + r11 * cop_exp_y),
        ]
        cop_meas = self._measured_cop(sensors, data)
        meas_valid = math.isfinite(cop_meas[0]) and math.isfinite(cop_meas[1])
        if not meas_valid:  # no foot loaded: logs hold finite numbers only
            cop_meas = [0.0, 0.0]
        fsm_state = 0 if double else (1 if sup == "left" else -1)
        xp_world = [sup_x + r00 * xp_des, sup_y + r10 * xp_des]
        signals = {
            "fsm_state": fsm_state,
            "efsm_phase": int(phase),
            "epsilon": eps,
            "epsilon_onset": eps_on,
            "d": out.d if math.isfinite(out.d) else 1.0,
            "com_w": com_w,
            "com_vel_w": vcom_w,
            "com_world": com.tolist(),
            "com_vel_world": vcom.tolist(),
            "cp_w": x_cp,
            "cp_ref_w": x_s - p.r,
            "x_s_w": x_s,
            "xp_des_w": xp_des,
            "xp_des_world": xp_world,
            "cop_exp_w": [cop_exp_x, cop_exp_y],
            "cop_exp_world": cop_exp_world,
            "cop_meas_world": cop_meas,
            "cop_meas_valid": int(meas_valid),
            "swing_pos_world": sw_pos.tolist(),
            "swing_ref_world": sw_ref.tolist(),
            "swing_foot": 0 if double else (1 if sw == "right" else -1),
            "support_pos_world": p_sup.tolist(),
            "ow_yaw": math.atan2(r10, r00),
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
        f_max, m_max = p.fs_max_force, p.fs_max_moment
        f_free = lam @ acc  # Λ ẍ*, unbounded
        fs = f_free[3:9].copy()
        if p.fs_decoupled_saturation:
            # Λ_s couples the swing foot's linear and angular rows: Λ ẍ* puts into the
            # moment rows the part Λ_rt ẍ*_t that pairs with the (large) linear
            # acceleration. Clipping only the force rows would leave that moment and
            # spin the foot. Instead keep the orientation acceleration ẍ*_r and take
            # the linear acceleration a_t that the saturated force f_t really produces:
            # Λ_tt (a_t − ẍ*_t) = f_t − (Λ ẍ*)_t, so m_r = (Λ ẍ*)_r + Λ_rt (a_t − ẍ*_t).
            f_t = fs[:3]  # a view: saturated in place (np.clip)
            np.minimum(np.maximum(f_t, -f_max, out=f_t), f_max, out=f_t)
            cut = f_t - f_free[3:6]
            if cut.any():
                fs[3:] += lam[6:9, 3:6] @ wbc.solve(lam[3:6, 3:6], cut)
        f_t, m_r = fs[:3], fs[3:]  # views: saturated in place (np.clip)
        np.minimum(np.maximum(f_t, -f_max, out=f_t), f_max, out=f_t)
        np.minimum(np.maximum(m_r, -m_max, out=m_r), m_max, out=m_r)
        if phase is Phase.SSA:
            fs *= eps  # ε F_s (§IV-C)
        # The CoM/yaw rows with the swing acceleration ẍ_s that F_s produces:
        # Λ_ss (ẍ_s − ẍ*_s) = F_s − (Λ ẍ*)_s, then F_c = (Λ ẍ*)_c + Λ_cs (ẍ_s − ẍ*_s).
        f2 = f_free
        cut = fs - f_free[3:9]
        if cut.any():
            f2[:3] += lam[0:3, 3:9] @ wbc.solve(lam[3:9, 3:9], cut)
        f2[3:] = fs
        return f2

    def _balance_force(
        self,
        fc: np.ndarray,
        kpsi3: np.ndarray,
        f3: np.ndarray,
        rot: np.ndarray,
        sole_sup: pin.SE3,
        x_s: float | None,
    ) -> np.ndarray | None:
        """F_3 + F_3^bal (Eqs. 23–29), or None when the expected CoP is inside (Eq. 23).

        The support polygon is the square of Eq. (23) in O_w: the support sole's extent
        along the O_w axes, stretched to the swing foot (x_s) in DS (Fig. 16), shrunk by the
        safety margin.

        Args:
            fc: resultant contact wrench in O_w, shape (6,).
            kpsi3: resultant wrench per task-3 force, K Ψ Ñ_12ᵀ J̃_3ᵀ, shape (6, 2).
            f3: task 3's force F_3, shape (2,).
            rot: world-from-O_w rotation (a yaw).
            sole_sup: support sole placement.
            x_s: swing-foot centre along x of O_w in DS [m], else None.
        """
        cop_x, cop_y = wbc.cop_of(fc)
        if not (math.isfinite(cop_x) and math.isfinite(cop_y)):
            return None
        # O_w-from-foot (xy): rot[:2, :2]ᵀ @ sole_sup.rotation[:2, :2] with rot a yaw.
        c, s = float(rot[0, 0]), float(rot[1, 0])
        (a00, a01, _), (a10, a11, _), _ = sole_sup.rotation.tolist()
        r00, r01 = c * a00 + s * a10, c * a01 + s * a11
        r10, r11 = c * a10 - s * a00, c * a11 - s * a01
        half_x, half_y = self._half_sole.tolist()
        margin = self._p.cop_margin
        # Extent along the O_w axes: |rel| @ half_sole − margin.
        hx = (abs(r00) * half_x + abs(r01) * half_y) - margin
        hy = (abs(r10) * half_x + abs(r11) * half_y) - margin
        hi_x = hx + x_s if x_s is not None else hx
        cx, cy = min(max(cop_x, -hx), hi_x), min(max(cop_y, -hy), hy)  # np.clip
        # Inside: np.allclose(clamped, cop), i.e. with its default tolerances.
        tol_x, tol_y = 1e-8 + 1e-5 * abs(cop_x), 1e-8 + 1e-5 * abs(cop_y)
        if abs(cx - cop_x) <= tol_x and abs(cy - cop_y) <= tol_y:
            return None
        fsig = fc - kpsi3 @ f3  # the wrench without task 3
        m_des = np.array([cy * fsig[2] - fsig[3], -cx * fsig[2] - fsig[4]])  # Eqs. (26)-(27)
        q3 = kpsi3[3:5]  # Eq. (28)
        if abs(np.linalg.det(q3)) < 1e-12:
            return None
        return np.linalg.solve(q3, m_des)  # F_3 + F_3^bal, Eq. (29)

    def _measured_cop(self, sensors: SensorSnapshot, data: pin.Data) -> list[float]:
        """CoP (x, y) in the world from the two F/T sensors (§VI-D2) [m]; NaN if unloaded.

        Each sensor reads the wrench the foot applies to the leg; adding back the static
        weight of the part below the sensor (the ankle-roll link, i.e. the foot) gives the
        ground reaction. Feet carrying no vertical load are left out. Only the vertical
        force and the horizontal moment about the world origin are needed, so the cross
        products are written out.
        """
        force_z = mom_x = mom_y = 0.0
        for f in FEET:
            ft = sensors.left_ft if f == "left" else sensors.right_ft
            m_ft = data.oMf[self._ft[f]]
            # Force and moment in world axes, as columns: [[fx, tx], [fy, ty], [fz, tz]].
            (fx, tx), (fy, ty), (fz, _) = (m_ft.rotation @ ft.reshape(2, 3).T).tolist()
            weight = self._foot_weight[f]  # [N], along +z
            if fz + weight <= 0.0:
                continue
            px, py, pz = m_ft.translation.tolist()
            cx, cy, _ = data.oMi[self._foot_joint[f]].act(self._foot_lever[f]).tolist()
            force_z += fz + weight
            # τ + p_ft × f + c_foot × (0, 0, weight), x and y rows.
            mom_x += tx + (py * fz - pz * fy) + cy * weight
            mom_y += ty + (pz * fx - px * fz) - cx * weight
        if force_z <= 1e-6:
            return [math.nan, math.nan]
        # Ground-level CoP: the point on z = 0 about which the moment has no x/y part.
        return [-mom_y / force_z, mom_x / force_z]


_EYE3 = np.eye(3)


def _rot_z(c: float, s: float) -> np.ndarray:
    """Rotation about z with cosine ``c`` and sine ``s``."""
    rot = _EYE3.copy()
    rot[0, 0], rot[0, 1], rot[1, 0], rot[1, 1] = c, -s, s, c
    return rot


def _yaw_rotation(yaw: float) -> np.ndarray:
    """Rotation about z by ``yaw`` [rad]."""
    return _rot_z(math.cos(yaw), math.sin(yaw))


def _yaw_only(rot: np.ndarray) -> np.ndarray:
    """The yaw part of a rotation: level, with the same heading."""
    return _yaw_rotation(math.atan2(rot[1, 0], rot[0, 0]))


def _ow_frame(
    p_sup: np.ndarray, p_sw: np.ndarray, com: np.ndarray, vcom: np.ndarray
) -> tuple[np.ndarray, list[float], list[float], float]:
    """O_w (§III-A1) and the CoM and swing foot in it.

    Args:
        p_sup: support sole centre, the origin of O_w [m].
        p_sw: swing sole centre [m]; O_w's x points to its ground projection.
        com: CoM in the world [m].
        vcom: CoM velocity in the world [m/s].

    Returns:
        world-from-O_w rotation (3, 3); com_w [m] and vcom_w [m/s] (3 floats each); x_s,
        the swing sole centre along x of O_w [m].
    """
    ox, oy, oz = p_sup.tolist()
    sx, sy, _ = p_sw.tolist()
    yaw = math.atan2(sy - oy, sx - ox)
    c, s = math.cos(yaw), math.sin(yaw)
    rot = _rot_z(c, s)
    cx, cy, cz = com.tolist()
    vx, vy, vz = vcom.tolist()
    dx, dy = cx - ox, cy - oy
    com_w = [c * dx + s * dy, c * dy - s * dx, cz - oz]
    vcom_w = [c * vx + s * vy, c * vy - s * vx, vz]
    return rot, com_w, vcom_w, c * (sx - ox) + s * (sy - oy)
