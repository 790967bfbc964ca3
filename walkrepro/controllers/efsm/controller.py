"""E-FSM walking controller of Lee et al. 2021: E-FSM (§III) + OS-WBC (§IV, Appendices).

Each control tick: build O_w from the feet (§III-A1), run the E-FSM (Table I) on the CoM,
capture point and swing-foot position, then compute Γ = Γ_t + Γ_c + Γ_gc (Eq. 7) with
three prioritized tasks (Eq. 11):

1. CoM x-force realising x_p^des (Appendix D-1);
2. CoM y/z, upper-body yaw and, out of DS, the 6-D swing foot (Eq. 6, saturated F_s × ε);
3. upper-body roll and pitch (Eq. 6), plus F_3^bal when the expected CoP leaves the
   shrunk support polygon (Appendix D-3, Eqs. 23–29).

Speed (issue 6): the tick runs at 2 kHz, so it calls Pinocchio's combined algorithm once
(``computeAllTerms``), reads its results through views of ``Data`` taken at reset, and does
all the WBC algebra in one compiled numba call, :func:`.kernels.whole_body_torques` (why
numba: see :mod:`.kernels`); :mod:`.wbc` keeps the same algebra in numpy as the reference.
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
import pinocchio as pin
from pydantic import Field

from walkrepro.controllers.base import Command, Controller, ControllerParams
from walkrepro.controllers.efsm import kernels
from walkrepro.controllers.efsm.fsm import (
    EventFsm,
    FsmInput,
    FsmParams,
    Phase,
    capture_point,
    epsilon,
)
from walkrepro.robot import Robot, pin_state_into
from walkrepro.sensors import SensorSnapshot

GRAVITY = 9.81  # [m/s^2]
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
FEET = ("left", "right")
OTHER_FOOT = {"left": "right", "right": "left"}


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


class _PoseViews:
    """Numpy views of the Pinocchio ``Data`` fields a tick reads, taken once.

    Pinocchio returns its vectors and matrices as views of ``Data``'s own memory, which
    the algorithms overwrite in place, so views taken once stay current: reading a field
    per tick then costs nothing. :meth:`aliases` proves that on this Pinocchio; where it
    does not hold, the controller calls :meth:`refresh` every tick.
    """

    def __init__(self, data: pin.Data, sole: dict[str, int], ft: dict[str, int], pelvis: int):
        self._data, self._sole, self._ft, self._pelvis = data, sole, ft, pelvis
        self.refresh()

    def refresh(self) -> None:
        """(Re)take every view from ``Data``."""
        data = self._data
        self.com, self.vcom = data.com[0], data.vcom[0]  # [m], [m/s], world
        self.nle, self.j_com, self.j_world = data.nle, data.Jcom, data.J
        self.sole_pos = {f: data.oMf[i].translation for f, i in self._sole.items()}
        self.sole_rot = {f: data.oMf[i].rotation for f, i in self._sole.items()}
        self.ft_pos = tuple(data.oMf[self._ft[f]].translation for f in FEET)
        self.ft_rot = tuple(data.oMf[self._ft[f]].rotation for f in FEET)
        self.pelvis_rot = data.oMi[self._pelvis].rotation

    def aliases(self) -> bool:
        """True if every view holds what a fresh read of ``Data`` gives."""
        fresh = _PoseViews(self._data, self._sole, self._ft, self._pelvis)
        pairs = [
            (self.com, fresh.com),
            (self.vcom, fresh.vcom),
            (self.nle, fresh.nle),
            (self.j_com, fresh.j_com),
            (self.j_world, fresh.j_world),
            (self.pelvis_rot, fresh.pelvis_rot),
            *zip(self.ft_pos, fresh.ft_pos, strict=True),
            *zip(self.ft_rot, fresh.ft_rot, strict=True),
            *((self.sole_pos[f], fresh.sole_pos[f]) for f in FEET),
            *((self.sole_rot[f], fresh.sole_rot[f]) for f in FEET),
        ]
        return all(np.array_equal(a, b) for a, b in pairs)


class EfsmController(Controller):
    """Event-based FSM walking with the operational-space whole-body controller."""

    Params = EfsmParams
    FRAMES = ("O_w",)

    def reset(self, robot: Robot, params: ControllerParams, control_period: float) -> None:
        """Cache models and start in DS with the CoP moving onto the first support foot.

        Also compiles the WBC kernels (or loads them from numba's cache) with a throwaway
        tick in DS and one out of DS, so that the first real tick is not slow.
        """
        self._setup(robot, params)
        self._check_views()
        self._warm_up(robot, params)

    def _setup(self, robot: Robot, params: ControllerParams) -> None:
        """Models, constants, buffers and the initial state of a run."""
        assert isinstance(params, EfsmParams)
        if robot.control_mode != "torque":
            raise ValueError("the E-FSM controller needs a torque-controlled robot")
        self._robot, self._p = robot, params
        self._model = model = robot.pin_model
        self._data = model.createData()
        self._sole = {f: robot.pin_frame_id(f"{f}_sole") for f in FEET}
        self._ft = {f: robot.pin_frame_id(f"{f}_foot_ft") for f in FEET}
        foot_joint = {f: robot.pin_joint_id(f"{f[0]}_ankle_roll") for f in FEET}
        self._pelvis_joint = 1  # the free-flyer root: the rigid upper body
        self._pose = _PoseViews(self._data, self._sole, self._ft, self._pelvis_joint)
        self._refresh_pose = False
        self._nv = nv = model.nv
        # Pinocchio's (q, v), rewritten in place every tick (nothing keeps them across ticks).
        self._q, self._v = np.zeros(model.nq), np.zeros(nv)
        # Joint-torque row of each actuator (Γ is in joint order, ctrl in actuator order).
        self._actuator_rows = np.asarray(robot.pin_v_idx, dtype=np.int64) - 6
        self._tau = np.empty(len(self._actuator_rows))
        half_sole = np.asarray(robot.sole_size, dtype=float) / 2.0
        # The parameters of kernels.whole_body_torques, in its order.
        self._kernel_params = np.array(
            [
                params.kp,
                params.kv,
                params.fs_max_force,
                params.fs_max_moment,
                float(params.fs_decoupled_saturation),
                float(params.balance),
                params.cop_margin,
                params.torque_limit,
                *half_sole,
            ]
        )
        # The velocity coordinates that move each sole (its joint's ancestors in the tree).
        self._sole_support = {}
        for f, frame_id in self._sole.items():
            joint = model.frames[frame_id].parentJoint
            support = np.zeros(nv, dtype=np.bool_)
            for j in model.supports[joint][1:]:  # without the universe
                support[model.joints[j].idx_v : model.joints[j].idx_v + model.joints[j].nv] = True
            self._sole_support[f] = support
        if model.joints[self._pelvis_joint].nv != 6 or model.joints[self._pelvis_joint].idx_v:
            raise ValueError("the E-FSM controller needs the pelvis as the free-flyer root")
        # Buffers the kernel reads: J̇_c q̇ (support foot first), the targets of Eq. (6).
        self._jc_dot_v = {1: np.empty(6), 2: np.empty(12)}
        self._task_ref = np.zeros(7)
        self._rot_des = np.zeros((2, 3, 3))  # Table II: pelvis, swing sole
        # The part of each foot below its F/T sensor (the ankle-roll link): its weight and
        # its CoM in the sensor frame (both on that link, so the offset is constant).
        self._foot_weight = np.empty(2)
        self._foot_com_ft = np.empty((2, 3))
        for i, f in enumerate(FEET):
            frame = model.frames[self._ft[f]]
            if frame.parentJoint != foot_joint[f]:
                raise ValueError(f"{f}_foot_ft must be on the {f[0]}_ankle_roll link")
            inertia = model.inertias[foot_joint[f]]
            self._foot_weight[i] = inertia.mass * GRAVITY  # [N]
            self._foot_com_ft[i] = frame.placement.actInv(inertia.lever)  # [m]
        self._fsm = EventFsm(
            FsmParams(
                params.zeta, params.r, params.dxp, params.d_thr, params.v_stop, params.use_epsilon
            )
        )
        self._support = "left" if params.first_swing == "right" else "right"
        self._started = False
        self._steps_done = 0
        self._ds_start_xp: float | None = None
        self._swing_target = [0.0, 0.0, 0.0]  # [m], world; floats: read as floats per tick
        self._rot_w = np.eye(3)  # world-from-O_w, rewritten in place every tick

    def _home_snapshot(self) -> SensorSnapshot:
        """The robot standing still in its home posture, as sensed."""
        robot, qpos = self._robot, self._robot.home_qpos
        n, zeros3 = len(self._actuator_rows), np.zeros(3)
        return SensorSnapshot(
            t=0.0,
            joint_pos=robot.link_joint_pos(qpos),
            joint_vel=np.zeros(n),
            imu_quat=np.array([1.0, 0.0, 0.0, 0.0]),
            imu_gyro=zeros3,
            imu_acc=zeros3,
            left_ft=np.zeros(6),
            right_ft=np.zeros(6),
            base_pos=qpos[0:3].copy(),
            base_quat=qpos[3:7].copy(),
            base_linvel=zeros3,
            base_angvel=zeros3,
        )

    def _check_views(self) -> None:
        """Use the views of :class:`_PoseViews` only if they follow ``Data`` on this Pinocchio."""
        model, data = self._model, self._data
        q, v = self._home_snapshot().pinocchio_state(self._robot)
        for scale in (0.0, 0.01):  # two states: the views must follow
            dq = np.full(model.nv, scale)
            pin.computeAllTerms(model, data, pin.integrate(model, q, dq), v + scale)
            pin.updateFramePlacements(model, data)
            if not self._pose.aliases():
                self._refresh_pose = True

    def _warm_up(self, robot: Robot, params: ControllerParams) -> None:
        """Compile the kernels with a throwaway controller: one tick in DS, one in SSD."""
        twin = EfsmController()
        twin._setup(robot, params)
        twin._refresh_pose = self._refresh_pose
        home = self._home_snapshot()
        twin.step(0.0, home)
        twin._fsm.phase = Phase.SSD
        twin.step(0.0, home)

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
        p, model, data, pose = self._p, self._model, self._data, self._pose
        q, v = self._pin_state(sensors)
        # One pass: M, b + g, joint Jacobians, CoM and its Jacobian, and (with q̈ = 0) the
        # bias accelerations J̇ q̇ of every frame.
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        if self._refresh_pose:
            pose.refresh()
        com, vcom = pose.com, pose.vcom  # views: read within this tick only
        if not self._started:
            self._start(com)
        events: list[dict[str, Any]] = []

        # O_w and the E-FSM inputs (§III-A1, Eq. 2).
        sup, sw = self._support, OTHER_FOOT[self._support]
        p_sup, p_sw = pose.sole_pos[sup], pose.sole_pos[sw]
        # Python floats of this tick's positions: the scalar math below is cheaper on them.
        sup_xyz, sw_xyz = p_sup.tolist(), p_sw.tolist()
        com_xyz, vcom_xyz = com.tolist(), vcom.tolist()
        rot = self._rot_w
        cos_w, sin_w, com_w, vcom_w, x_s = _ow_frame(sup_xyz, sw_xyz, com_xyz, vcom_xyz, rot)
        x_cp = capture_point(com_w[0], vcom_w[0], self._z_m0)
        out = self._fsm.step(FsmInput(com_w[0], vcom_w[0], x_cp, x_s))
        for old, new in out.transitions:
            events.append({"kind": "fsm", "from": old.name, "to": new.name})
        xp_des, eps = out.xp_des, out.epsilon
        if out.switched_support:
            # DS ends: the swing foot becomes the support foot; next footstep target.
            self._support, sup, sw = sw, sw, sup
            p_sup, p_sw = p_sw, p_sup
            sup_xyz, sw_xyz = sw_xyz, sup_xyz
            self._plan_next_step(p_sup, sw)
            cos_w, sin_w, com_w, vcom_w, x_s = _ow_frame(sup_xyz, sw_xyz, com_xyz, vcom_xyz, rot)
            x_cp = capture_point(com_w[0], vcom_w[0], self._z_m0)
            xp_des = 0.0
            self._fsm.reframe(xp_des)
            events.append({"kind": "support", "foot": sup, "step": self._steps_done})
        phase = self._fsm.phase
        double = phase is Phase.DS

        # Contact set: the support foot, plus the swing foot in DS (its rows second).
        jc_dot_v = self._jc_dot_v[2 if double else 1]
        sole = self._sole
        jc_dot_v[0:6] = pin.getFrameClassicalAcceleration(model, data, sole[sup], LWA).vector
        if double:
            jc_dot_v[6:12] = pin.getFrameClassicalAcceleration(model, data, sole[sw], LWA).vector
        pin.cholesky.decompose(model, data)  # A = U D Uᵀ of the M from computeAllTerms
        a_inv = pin.cholesky.computeMinv(model, data)  # A⁻¹, both triangles

        # Task-space errors of Eq. (6) (Table II targets); the kernel forms ẍ* = k_p e − k_v ẋ.
        task_ref = self._task_ref
        sw_ref = self._swing_ref(phase, sup_xyz[2])
        task_ref[0] = 0.0 - com_w[1]
        task_ref[1] = self._z_m0 - com_w[2]
        task_ref[2], task_ref[3] = vcom_w[1], vcom_w[2]
        task_ref[4], task_ref[5], task_ref[6] = sw_ref

        # Γ = Γ_t + Γ_c + Γ_gc (Eqs. 7 and 11, Appendices A–D), saturated, actuator order.
        eps_on = 1.0
        if double:
            if self._ds_start_xp is None:
                self._ds_start_xp = xp_des
            if p.use_epsilon and p.ds_onset_ramp:
                eps_on = epsilon(abs(xp_des - self._ds_start_xp), p.d_thr)
        else:
            self._ds_start_xp = None  # Γ_c = 0
        tau = self._tau
        f1, balancing, cop_exp_x, cop_exp_y = kernels.whole_body_torques(
            a_inv,
            pose.nle,
            pose.j_world,
            jc_dot_v,
            self._sole_support[sup],
            self._sole_support[sw],
            pose.j_com,
            v,
            rot,
            p_sup,
            p_sw,
            pose.sole_rot[sup],
            pose.sole_rot[sw],
            pose.pelvis_rot,
            self._rot_des,
            task_ref,
            int(phase),
            eps,
            eps_on,
            xp_des,
            x_s,
            self._kernel_params,
            self._actuator_rows,
            tau,
        )

        # Expected CoP from the reference torques (Eqs. 9, 18, 22), and measured CoP (F/T).
        r00, r01, r10, r11 = cos_w, -sin_w, sin_w, cos_w  # rot[:2, :2], as _ow_frame wrote it
        sup_x, sup_y, _ = sup_xyz
        cop_exp_world = [
            sup_x + (r00 * cop_exp_x + r01 * cop_exp_y),
            sup_y + (r10 * cop_exp_x + r11 * cop_exp_y),
        ]
        cop_meas = list(self._measured_cop(sensors))
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
            "com_world": com_xyz,
            "com_vel_world": vcom_xyz,
            "cp_w": x_cp,
            "cp_ref_w": x_s - p.r,
            "x_s_w": x_s,
            "xp_des_w": xp_des,
            "xp_des_world": xp_world,
            "cop_exp_w": [cop_exp_x, cop_exp_y],
            "cop_exp_world": cop_exp_world,
            "cop_meas_world": cop_meas,
            "cop_meas_valid": int(meas_valid),
            "swing_pos_world": sw_xyz,
            "swing_ref_world": sw_ref,
            "swing_foot": 0 if double else (1 if sw == "right" else -1),
            "support_pos_world": sup_xyz,
            "ow_yaw": math.atan2(r10, r00),
            "com_force_x": f1,
            "balancing": int(balancing),
            "tau_ref": tau.tolist(),
            "steps_done": self._steps_done,
        }
        return Command(ctrl=tau.copy(), signals=signals, events=tuple(events))

    # ---- helpers -------------------------------------------------------------------------

    def _pin_state(self, sensors: SensorSnapshot) -> tuple[np.ndarray, np.ndarray]:
        """Pinocchio's (q, v), as ``sensors.pinocchio_state`` gives them, into reused buffers.

        The same compiled kernel as :meth:`Robot.pin_state`, without its two allocations and
        argument conversions (a few µs per tick at 2 kHz).
        """
        if sensors.base_pos is None or sensors.base_quat is None:
            return sensors.pinocchio_state(self._robot, "the E-FSM controller")  # raises
        robot, q, v = self._robot, self._q, self._v
        pin_state_into(
            sensors.base_pos,
            sensors.base_quat,
            sensors.base_linvel,
            sensors.base_angvel,
            sensors.joint_pos,
            sensors.joint_vel,
            robot.pin_q_idx,
            robot.pin_v_idx,
            q,
            v,
        )
        return q, v

    def _start(self, com: np.ndarray) -> None:
        """Record the initial targets (Table II) and start the first DS (Table I)."""
        p, pose = self._p, self._pose
        self._started = True
        rot_ub_des = _yaw_only(pose.pelvis_rot)
        self._rot_des[0] = rot_ub_des  # Table II: the upper body level, initial heading
        self._rot_des[1] = _yaw_only(pose.sole_rot["left"])  # the swing sole level
        self._heading = rot_ub_des[:, 0].copy()
        self._lateral = rot_ub_des[:, 1].copy()
        p_left, p_right = pose.sole_pos["left"], pose.sole_pos["right"]
        spacing = float(self._lateral @ (p_left - p_right))
        self._width = spacing if p.step_width is None else p.step_width
        self._z_m0 = float(com[2] - 0.5 * (p_left[2] + p_right[2]))
        # The first DS: O_w sits on the first swing foot, the CoP moves onto the support
        # foot (x_s); it starts where the CoM projects (standing still, CoP ≈ CoM).
        sup, sw = OTHER_FOOT[self._support], self._support  # roles in the first DS
        self._support = sup
        p_sup, p_sw = pose.sole_pos[sup], pose.sole_pos[sw]
        rot = self._ow_rotation(p_sup, p_sw)
        self._fsm.xp_des = float((rot.T @ (com - p_sup))[0])
        self._rot_w[:] = rot

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
        self._swing_target = target.tolist()

    def _swing_ref(self, phase: Phase, support_z: float) -> list[float]:
        """Swing-foot position reference (Table II) [m]: planned xy, raise/land height.

        Args:
            phase: E-FSM phase: SSD raises the foot, the others lower it.
            support_z: height of the support sole centre [m].
        """
        h = self._p.raise_height if phase is Phase.SSD else self._p.land_height
        target_x, target_y, _ = self._swing_target
        return [target_x, target_y, support_z + h]

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

        The tick computes this inside :func:`.kernels.whole_body_torques`
        (:func:`.kernels.task2_force`); this method is that kernel with the parameters.
        """
        p = self._p
        return kernels.task2_force(
            np.ascontiguousarray(lam, dtype=float),
            np.ascontiguousarray(acc, dtype=float),
            double,
            eps if phase is Phase.SSA else 1.0,
            p.fs_max_force,
            p.fs_max_moment,
            p.fs_decoupled_saturation,
        )

    def _measured_cop(self, sensors: SensorSnapshot) -> tuple[float, float]:
        """CoP (x, y) in the world from the two F/T sensors (§VI-D2) [m]; NaN if unloaded.

        Each sensor reads the wrench the foot applies to the leg; adding back the static
        weight of the part below the sensor (the ankle-roll link, i.e. the foot) gives the
        ground reaction. Feet carrying no vertical load are left out
        (:func:`.kernels.measured_cop`).
        """
        (rot_left, rot_right), (pos_left, pos_right) = self._pose.ft_rot, self._pose.ft_pos
        return kernels.measured_cop(
            rot_left,
            pos_left,
            sensors.left_ft,
            rot_right,
            pos_right,
            sensors.right_ft,
            self._foot_com_ft,
            self._foot_weight,
        )


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
    p_sup: list[float],
    p_sw: list[float],
    com: list[float],
    vcom: list[float],
    rot: np.ndarray,
) -> tuple[float, float, list[float], list[float], float]:
    """O_w (§III-A1) and the CoM and swing foot in it.

    Plain float math: on three-vectors it costs less than numpy's per-call overhead.

    Args:
        p_sup: support sole centre, the origin of O_w [m].
        p_sw: swing sole centre [m]; O_w's x points to its ground projection.
        com: CoM in the world [m].
        vcom: CoM velocity in the world [m/s].
        rot: out: the world-from-O_w rotation (3, 3); only its top-left 2 × 2 is written
            (the rest stays that of a rotation about z).

    Returns:
        cos and sin of O_w's yaw; com_w [m] and vcom_w [m/s] (3 floats each); x_s, the
        swing sole centre along x of O_w [m].
    """
    ox, oy, oz = p_sup
    sx, sy, _ = p_sw
    yaw = math.atan2(sy - oy, sx - ox)
    c, s = math.cos(yaw), math.sin(yaw)
    rot[0, 0], rot[0, 1], rot[1, 0], rot[1, 1] = c, -s, s, c
    cx, cy, cz = com
    vx, vy, vz = vcom
    dx, dy = cx - ox, cy - oy
    com_w = [c * dx + s * dy, c * dy - s * dx, cz - oz]
    vcom_w = [c * vx + s * vy, c * vy - s * vx, vz]
    return c, s, com_w, vcom_w, c * (sx - ox) + s * (sy - oy)
