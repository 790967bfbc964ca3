"""E-FSM walking controller of Lee et al. 2021: E-FSM (§III) + OS-WBC (§IV, Appendices).

Each control tick: build O_w from the feet (§III-A1), run the E-FSM (Table I) on the CoM,
capture point and swing-foot position, then compute Γ = Γ_t + Γ_c + Γ_gc (Eq. 7) with
three prioritized tasks (Eq. 11):

1. CoM x-force realising x_p^des (Appendix D-1);
2. CoM y/z, upper-body yaw and, out of DS, the 6-D swing foot (Eq. 6, saturated F_s × ε);
3. upper-body roll and pitch (Eq. 6), plus F_3^bal when the expected CoP leaves the
   shrunk support polygon (Appendix D-3, Eqs. 23–29).

The equations live in :mod:`.fsm` (the E-FSM, Eqs. 2–4, Table I) and :mod:`.wbc` (P, W,
Φ, Λ, Ñ, the hierarchy of Eq. 11, Appendices A–D). Speed: the tick runs at 2 kHz, so it
calls Pinocchio's combined algorithm once (``computeAllTerms``, then ``computeMinverse`` for
A⁻¹), reads their results through
views of ``Data`` taken at reset, and does everything else (O_w, the E-FSM, footsteps, the
WBC, the CoPs) in one compiled numba call, :func:`.kernels.tick`, which runs those modules'
functions (why numba: see :mod:`.kernels`). Python keeps the first tick's set-up, the
events and the signal dict.
"""

from __future__ import annotations

import math
import warnings
from typing import Literal

import numpy as np
import pinocchio as pin
from numba import NumbaPerformanceWarning
from pydantic import Field

from walkrepro.controllers.base import Command, Controller, ControllerParams
from walkrepro.controllers.ranges import (
    MAX_COUNT,
    MAX_DAMPING,
    MAX_FORCE,
    MAX_LENGTH,
    MAX_PHASE_TIME,
    MAX_SPEED,
    MAX_STIFFNESS,
    MAX_TORQUE,
)
from walkrepro.log.signals import SignalLayout, Signals
from walkrepro.papers.lee2021 import kernels, wbc
from walkrepro.papers.lee2021.fsm import DS_TO_SSD, SSA_TO_DS, SSD_TO_SSA, FsmParams, Phase
from walkrepro.papers.lee2021.tasks import HIERARCHY, TaskSpec, task_set
from walkrepro.sim.robot import Robot, pin_state_into
from walkrepro.sim.sensors import SensorSnapshot
from walkrepro.specs.origin import assumed, calibrated, paper, source

GRAVITY = 9.81  # [m/s^2]
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
FEET = ("left", "right")  # a foot is its index here: 0 left, 1 right; 1 - i the other one
PELVIS_JOINT = 1  # the free-flyer root: the rigid upper body
UNIVERSE = 0  # Pinocchio's joint 0, the world
X, Y, Z = 0, 1, 2  # axes (of a point; a rotation's columns)
#: A free joint's qpos in MuJoCo: position [m], then quaternion (w, x, y, z).
FREE_POS, FREE_QUAT = slice(0, 3), slice(3, 7)


def signal_layout(n_actuators: int) -> SignalLayout:
    """The logged signals, :data:`.kernels.SIGNALS`, for ``n_actuators`` joints."""
    return kernels.signal_layout(n_actuators)


#: Largest margin or threshold [m] (ζ, r, d^thr): DYROS RED's 0.30 m sole length; a margin
#: longer than the foot is no margin of it.
MAX_MARGIN = 0.3
#: Largest Δx_p^des per control period [m]: 1 cm per 0.5 ms tick moves the desired CoP
#: across the whole 0.30 m sole in 15 ms, beyond any CoP shift of a step.
MAX_CP_STEP = 0.01
#: Largest support-polygon margin [m]: half DYROS RED's 0.15 m sole width; a wider margin
#: leaves no polygon.
MAX_COP_MARGIN = 0.075


class EfsmParams(ControllerParams):
    """Parameters of the E-FSM walking controller (Lee et al. 2021, §V-B unless noted)."""

    zeta: float = Field(
        0.03,
        gt=0,
        le=MAX_MARGIN,
        description="margin ζ of law L1 [m] (§V-B)",
        json_schema_extra=paper("§V-B: ζ = 0.03 m"),
    )
    r: float = Field(
        0.08,
        gt=0,
        le=MAX_MARGIN,
        description="margin r of law L2 [m] (§V-B)",
        json_schema_extra=paper("§V-B: r = 0.08 m"),
    )
    dxp: float = Field(
        0.0007,
        gt=0,
        le=MAX_CP_STEP,
        description="Δx_p^des per control period [m] (§V-B)",
        json_schema_extra=paper("§V-B: Δx_p^des = 0.0007 m per control period"),
    )
    d_thr: float = Field(
        0.01,
        gt=0,
        le=MAX_MARGIN,
        description="ε threshold d^thr [m] (§V-B)",
        json_schema_extra=paper("§V-B: d_thr = 0.01 m"),
    )
    v_stop: float = Field(
        0.005,
        ge=0,
        le=MAX_SPEED,
        description="|ẋ_m| counted as ≈ 0 ending SSD [m/s] (assumed; Table I)",
        json_schema_extra=assumed(
            "Table I ends SSD when ẋ_m ≈ 0; 5 mm/s, an order below the 0.11 m/s walk"
        ),
    )
    use_epsilon: bool = Field(
        True,
        description="False: ε ≡ 1, the ablation of §VI-D1",
        json_schema_extra=paper(
            "§IV-B: the state-transition parameter ε", scenario="§VI-D1 ablation switch"
        ),
    )
    ds_onset_ramp: bool = Field(
        True,
        description="ε's ramp also at DS onset: the landing foot's wrench grows from 0 over "
        "the first d^thr of the x_p^des ramp (walkrepro extension of §IV-B; off without ε)",
        json_schema_extra=assumed(
            "walkrepro extension of §IV-B: the same ε ramp on the landing foot's wrench at DS onset"
        ),
    )
    kp: float = Field(
        100.0,
        gt=0,
        le=MAX_STIFFNESS,
        description="task stiffness k_p [1/s^2] (§V-B)",
        json_schema_extra=paper("§V-B: k_p = 100"),
    )
    kv: float = Field(
        20.0,
        gt=0,
        le=MAX_DAMPING,
        description="task damping k_v [1/s] (§V-B)",
        json_schema_extra=paper("§V-B: k_v = 20"),
    )
    raise_height: float = Field(
        0.05,
        ge=0,
        le=MAX_LENGTH,
        description="swing-foot height in SSD [m] (Table II)",
        json_schema_extra=paper("§V-B, Table II: 0.05 m in SSD"),
    )
    land_height: float = Field(
        0.005,
        ge=0,
        le=MAX_LENGTH,
        description="swing-foot height in SSA [m] (Table II)",
        json_schema_extra=paper("§V-B, Table II: 0.005 m in SSA"),
    )
    fs_max_force: float = Field(
        30.0,
        gt=0,
        le=MAX_FORCE,
        description="saturation of each F_s force component [N]. §V-B gives no value; "
        "a completely blocked swing foot presses the obstacle with it, and §VI-B measured "
        "≈ 32 N there (27.8 N with this bound, experiments/obstacle_collision.yaml)",
        json_schema_extra=calibrated(
            "chosen on §VI-B / Fig. 10's ≈ 32 N on the completely blocked swing foot (obstacle_collision · the blocked foot's peak force); §V-B gives no value"
        ),
    )
    fs_max_moment: float = Field(
        10.0,
        gt=0,
        le=MAX_TORQUE,
        description="saturation of each F_s moment component [Nm] (assumed)",
        json_schema_extra=assumed(
            "§V-B bounds F_s without a value; 10 Nm, a third of the force bound times the 0.3 m foot"
        ),
    )
    fs_decoupled_saturation: bool = Field(
        True,
        description="saturate F_s's force rows without disturbing the orientation "
        "acceleration (Λ_s couples them; see _task2_force)",
        json_schema_extra=assumed(
            "§V-B: each F_s component saturates; the orientation rows are not F_s's"
        ),
    )
    fs_saturation: Literal["component", "uniform"] = Field(
        "uniform",
        description="how F_s's force rows meet the bound (§V-B: each component saturates): "
        "'component' clips each row of Λ ẍ* alone, which through Λ_s's x–z coupling can "
        "leave a far swing foot with no upward acceleration (it slides); 'uniform' scales "
        "the commanded linear swing acceleration by the largest factor ≤ 1 that keeps every "
        "force component within the bound, so the foot heads for its target",
        json_schema_extra=calibrated(
            "adopted over 'component' after forward_walk's first swings slid 4–13 cm (docs/analysis/lee2021.md); §V-B says only that each component saturates"
        ),
    )
    step_length: float = Field(
        0.1,
        ge=-MAX_LENGTH,
        le=MAX_LENGTH,
        description="forward step length [m] (§VI-A)",
        json_schema_extra=paper("§VI-A: 0.1 m steps", scenario="the experiment's step length"),
    )
    step_width: float | None = Field(
        None,
        gt=0,
        le=MAX_LENGTH,
        description="lateral foot spacing [m]; None keeps the initial spacing",
        json_schema_extra=assumed("None keeps the initial foot spacing (the robot's hip spacing)"),
    )
    n_steps: int | None = Field(
        None,
        ge=0,
        le=MAX_COUNT,
        description="footsteps of step_length, then in place; None: no limit",
        json_schema_extra=assumed("None: no limit"),
    )
    first_ds_shift: float = Field(
        0.0,
        ge=0,
        le=MAX_PHASE_TIME,
        description="length of the first DS's weight shift [s]: the capture point is driven "
        "onto the first support foot (the lab's start-up, fsm.weight_shift_cop) before Eq. 4 "
        "ends that DS; 0: the first DS is Eq. 4's ramp alone",
        json_schema_extra=assumed(
            "0: the first DS as every DS (Eq. 4); the lab's start-up, saga0619/dyros_red @ "
            "281ef7e dyros_red_controller/src/control_base.cpp mode 15 (line 590; "
            "time_segment 1.0 s, line 597), is 1.0 s"
        ),
    )
    first_step_scale: float = Field(
        1.0,
        gt=0,
        le=1.0,
        description="the first footstep's length as a fraction of step_length",
        json_schema_extra=assumed(
            "1: every footstep step_length; the lab's first step is half "
            "(saga0619/dyros_red @ 281ef7e control_base.cpp:626-627, 635-636, st_temp = "
            "step_length / 2 when loop_ == 1)"
        ),
    )
    first_swing: Literal["left", "right"] = Field(
        "right",
        description="foot that swings first (§VI-B: the right foot)",
        json_schema_extra=paper(
            "§VI-B: the right foot swings first", scenario="the experiment's first swing foot"
        ),
    )
    balance: bool = Field(
        True,
        description="F_3^bal when the expected CoP leaves the polygon",
        json_schema_extra=paper(
            "§IV-C, Fig. 16: F_3^bal when the expected CoP leaves the support polygon"
        ),
    )
    cop_margin: float = Field(
        0.03,
        ge=0,
        le=MAX_COP_MARGIN,
        description="safety margin of the support polygon [m] (Fig. 16; assumed)",
        json_schema_extra=assumed(
            "Fig. 16 shows a margin inside the polygon without a value; 0.03 m, ζ"
        ),
    )
    torque_limit: float = Field(
        300.0,
        gt=0,
        le=MAX_TORQUE,
        description="actuator saturation [Nm] (robot)",
        json_schema_extra=source(
            "saga0619/dyros_red @ 281ef7e82850dbc9cca68234512293dacfee6a9e : "
            "dyros_red_description/mujoco_model/dyros_red_robot.xml (line 9): default motor "
            "ctrlrange -300 300 [Nm], every joint (robots/dyros_red/parameters.yaml, torque_limit)"
        ),
    )


class _PoseViews:
    """Numpy views of the Pinocchio ``Data`` fields a tick reads, taken once.

    Pinocchio returns its vectors and matrices as views of ``Data``'s own memory, which
    the algorithms overwrite in place, so views taken once stay current: reading a field
    per tick then costs nothing. :meth:`aliases` proves that on this Pinocchio; where it
    does not hold, the controller calls :meth:`refresh` every tick. ``terms`` and ``feet``
    (left, right, indexed like :data:`FEET`: the joint carrying each foot's sole and F/T
    frame) are the kernel's records (the controller gathers them with its own records into
    :class:`.kernels.TickRecords`).
    """

    def __init__(self, data: pin.Data, foot: tuple[int, int]):
        """Views of ``data``; ``foot``: the joint of each foot."""
        self._data, self._foot = data, foot
        self.refresh()

    def refresh(self) -> None:
        """(Re)take every view from ``Data``."""
        data = self._data
        self.terms = kernels.PinocchioTerms(
            mass_inv=data.Minv,
            nle=data.nle,
            j_world=data.J,
            j_com=data.Jcom,
            com=data.com[0],  # [m], world
            vcom=data.vcom[0],  # [m/s], world
            pelvis_rot=data.oMi[PELVIS_JOINT].rotation,
        )
        self.feet = tuple(
            kernels.FootJoint(
                rot=data.oMi[j].rotation,
                pos=data.oMi[j].translation,
                vel=data.v[j].vector,  # (v, ω), joint axes
                acc=data.a[j].vector,  # bias (q̈ = 0)
            )
            for j in self._foot
        )

    def aliases(self) -> bool:
        """True if every view holds what a fresh read of ``Data`` gives."""
        fresh = _PoseViews(self._data, self._foot)
        pairs = list(zip(self.terms, fresh.terms, strict=True))
        for mine, theirs in zip(self.feet, fresh.feet, strict=True):
            pairs += zip(mine, theirs, strict=True)
        return all(np.array_equal(a, b) for a, b in pairs)


#: The E-FSM transitions of kernels.tick's result bits, as logged.
_TRANSITIONS = (
    (SSD_TO_SSA, Phase.SSD, Phase.SSA),
    (SSA_TO_DS, Phase.SSA, Phase.DS),
    (DS_TO_SSD, Phase.DS, Phase.SSD),
)


class EfsmController(Controller):
    """Event-based FSM walking with the operational-space whole-body controller."""

    Params = EfsmParams
    FRAMES = ("O_w",)
    #: The task hierarchy of Eq. (11) (:data:`.tasks.HIERARCHY`); a subclass, or an
    #: instance before reset, may set another.
    TASKS: tuple[TaskSpec, ...] = HIERARCHY

    def reset(self, robot: Robot, params: ControllerParams, control_period: float) -> None:
        """Cache models and start in DS with the CoP moving onto the first support foot.

        Also compiles the tick kernel (or loads it from numba's cache) with a throwaway
        tick in DS and one out of DS, so that the first real tick is not slow.
        """
        self._setup(robot, params, control_period)
        self._check_views()
        self._warm_up(robot, params, control_period)

    def _setup(self, robot: Robot, params: ControllerParams, control_period: float) -> None:
        """Models, parameters, buffers and the initial state of a run."""
        assert isinstance(params, EfsmParams)
        if robot.control_mode != "torque":
            raise ValueError("the E-FSM controller needs a torque-controlled robot")
        self._robot, self._p = robot, params
        self._model = model = robot.pin_model
        self._data = data = model.createData()
        self._sole = {f: robot.pin_frame_id(f"{f}_sole") for f in FEET}
        self._ft = {f: robot.pin_frame_id(f"{f}_foot_ft") for f in FEET}
        ankle = tuple(robot.pin_joint_id(f"{f[0]}_ankle_roll") for f in FEET)
        for f, joint in zip(FEET, ankle, strict=True):
            for frame in (self._sole[f], self._ft[f]):
                if model.frames[frame].parentJoint != joint:
                    raise ValueError(f"{model.frames[frame].name} must be on {f[0]}_ankle_roll")
        if model.joints[PELVIS_JOINT].nv != 6 or model.joints[PELVIS_JOINT].idx_v:
            raise ValueError("the E-FSM controller needs the pelvis as the free-flyer root")
        self._pose = _PoseViews(data, ankle)
        self._refresh_pose = False
        nv, n_act = model.nv, len(robot.pin_v_idx)
        self._params = self._tick_params(robot, params, control_period, ankle)
        self._targets = _placeholder_targets()  # recorded on the first tick (_start)
        # The state the tick kernel keeps, as one record; the controller works through views
        # of its fields.
        self._state = state = kernels.tick_state(model.nq, nv, n_act)
        self._st = st = state[0]
        # Pinocchio's (q, v), rewritten in place every tick (nothing keeps them across ticks).
        self._pin_buffer = st["pin_state"]
        self._q = self._pin_buffer[kernels.Q_ROW, : model.nq]
        self._v = self._pin_buffer[kernels.V_ROW, :nv]
        self._tau, self._rot_w, self._ft_wrench = st["tau"], st["rot_w"], st["ft_wrench"]
        self._signal_layout = signal_layout(n_act)
        # The tick writes the signals by name into a record whose bytes are the log's vector.
        self._signal_record = np.zeros(1, dtype=kernels.signal_dtype(n_act))
        self._signals = self._signal_record.view(np.float64)
        st["support"] = FEET.index("left" if params.first_swing == "right" else "right")
        st["phase"] = Phase.DS  # Table I: the first footstep starts in DS
        st["ds_start_xp"] = math.nan
        self._rot_w[:] = np.eye(3)  # world-from-O_w, rewritten in place every tick
        self._started = False
        self._records = self._tick_records()

    def _tick_params(
        self, robot: Robot, p: EfsmParams, control_period: float, ankle: tuple[int, ...]
    ) -> kernels.TickParams:
        """The tick's parameter record (:class:`.kernels.TickParams`): ``p``, the task
        hierarchy :attr:`TASKS`, and the feet's frames in the model."""
        wbc_params = wbc.WbcParams(
            tasks=task_set(self.TASKS, p.kp, p.kv),
            fs_max_force=p.fs_max_force,
            fs_max_moment=p.fs_max_moment,
            fs_saturation=int(_saturation_mode(p)),
            balance=p.balance,
            cop_margin=p.cop_margin,
            torque_limit=p.torque_limit,
            half_sole=np.asarray(robot.sole_size, dtype=float) / 2.0,
            # Γ is in joint order, ctrl in actuator order: each actuator's joint-torque row.
            actuator_rows=np.asarray(robot.pin_v_idx, dtype=np.int64) - 6,
        )
        return kernels.TickParams(
            fsm=FsmParams(p.zeta, p.r, p.dxp, p.d_thr, p.v_stop, p.use_epsilon),
            wbc=wbc_params,
            ds_onset_ramp=p.ds_onset_ramp,
            raise_height=p.raise_height,
            land_height=p.land_height,
            step_length=p.step_length,
            n_steps=-1 if p.n_steps is None else p.n_steps,
            first_step_scale=p.first_step_scale,
            shift_ticks=round(p.first_ds_shift / control_period),
            control_period=control_period,
            feet=self._foot_frames(ankle),
        )

    def _foot_frames(self, ankle: tuple[int, ...]) -> kernels.FootFrames:
        """Each sole and F/T frame in its joint, the coordinates that move the sole (the
        joint's ancestors in the tree), and the part of the foot below its F/T sensor (the
        ankle-roll link): its weight and its CoM in the sensor frame (both on that link, so
        the offset is constant)."""
        model = self._model
        chain = np.zeros((len(FEET), model.nv), dtype=np.int64)
        for i, joint in enumerate(ankle):
            for j in model.supports[joint]:
                if j != UNIVERSE:
                    first = model.joints[j].idx_v
                    chain[i, first : first + model.joints[j].nv] = 1
        sole = [model.frames[self._sole[f]].placement for f in FEET]
        ft = [model.frames[self._ft[f]].placement for f in FEET]
        inertia = [model.inertias[j] for j in ankle]
        return kernels.FootFrames(
            sole_chain=chain,
            sole_local_rot=np.array([x.rotation for x in sole]),
            sole_local_pos=np.array([x.translation for x in sole]),
            ft_local_rot=np.array([x.rotation for x in ft]),
            ft_local_pos=np.array([x.translation for x in ft]),
            foot_com=np.array([x.actInv(m.lever) for x, m in zip(ft, inertia, strict=True)]),
            foot_weight=np.array([m.mass * GRAVITY for m in inertia]),  # [N]
        )

    def _home_snapshot(self) -> SensorSnapshot:
        """The robot standing still in its home posture, as sensed."""
        robot, qpos = self._robot, self._robot.home_qpos
        n, zeros3 = len(self._tau), np.zeros(3)
        return SensorSnapshot(
            t=0.0,
            joint_pos=robot.link_joint_pos(qpos),
            joint_vel=np.zeros(n),
            imu_quat=np.array([1.0, 0.0, 0.0, 0.0]),
            imu_gyro=zeros3,
            imu_acc=zeros3,
            left_ft=np.zeros(6),
            right_ft=np.zeros(6),
            base_pos=qpos[FREE_POS].copy(),
            base_quat=qpos[FREE_QUAT].copy(),
            base_linvel=zeros3,
            base_angvel=zeros3,
        )

    def _check_views(self) -> None:
        """Use the views of :class:`_PoseViews` only if they follow ``Data`` on this Pinocchio."""
        model, data = self._model, self._data
        q, v = self._home_snapshot().pinocchio_state(self._robot)
        for scale in (0.0, 0.01):  # two states: the views must follow
            dq = np.full(model.nv, scale)
            q_moved = pin.integrate(model, q, dq)
            pin.computeAllTerms(model, data, q_moved, v + scale)
            pin.computeMinverse(model, data, q_moved)
            if not self._pose.aliases():
                self._refresh_pose = True

    def _warm_up(self, robot: Robot, params: ControllerParams, control_period: float) -> None:
        """Compile the kernels with a throwaway controller: one tick in DS, one in SSD.

        numba notes, when it compiles, that ``@`` on a block of a matrix (a strided view)
        copies it for BLAS; at these sizes (≤ 18 × 18) the copy costs less than writing the
        blocks out, so that note is silenced here, and only here.
        """
        twin = type(self)()
        twin.TASKS = self.TASKS
        twin._setup(robot, params, control_period)
        twin._refresh_pose = self._refresh_pose
        home = self._home_snapshot()
        with warnings.catch_warnings():
            warnings.filterwarnings(
                "ignore", ".*is faster on contiguous arrays", NumbaPerformanceWarning
            )
            twin.step(0.0, home)
            twin._st["phase"] = Phase.SSD
            twin.step(0.0, home)

    # ---- frames ------------------------------------------------------------------------

    def frame(self, name: str) -> np.ndarray | None:
        """World-from-O_w rotation (the push of §VI-C is along +x of O_w)."""
        return self._rot_w.copy() if name == "O_w" else None

    @staticmethod
    def _ow_rotation(p_sup: np.ndarray, p_sw: np.ndarray) -> np.ndarray:
        """O_w axes (§III-A1): x from the support to the swing foot's ground projection."""
        dx, dy = float(p_sw[X] - p_sup[X]), float(p_sw[Y] - p_sup[Y])
        return _yaw_rotation(math.atan2(dy, dx))

    # ---- the control tick ----------------------------------------------------------------

    def step(self, t: float, sensors: SensorSnapshot) -> Command:
        """One control period of the E-FSM + OS-WBC.

        (q, v) from the snapshot, Pinocchio's computeAllTerms, then :func:`.kernels.tick`
        (frames, O_w, E-FSM, footsteps, Γ, CoPs) in one compiled call; Python turns its
        outputs into the logged signals and events.
        """
        q, v = self._pin_state(sensors)
        # One pass: M, b + g, joint Jacobians and placements, CoM and its Jacobian, and (with
        # q̈ = 0) the bias accelerations of every joint; then A⁻¹.
        pin.computeAllTerms(self._model, self._data, q, v)
        pin.computeMinverse(self._model, self._data, q)
        if self._refresh_pose:
            self._pose.refresh()
            self._records = self._tick_records()
        if not self._started:
            self._start()
        self._ft_wrench[kernels.LEFT] = sensors.left_ft
        self._ft_wrench[kernels.RIGHT] = sensors.right_ft
        transitions = kernels.tick(self._records)
        signals = Signals(self._signal_layout, self._signals.copy())
        events = self._events(transitions) if transitions else ()
        return Command(ctrl=self._tau.copy(), signals=signals, events=events)

    # ---- helpers -------------------------------------------------------------------------

    def _tick_records(self) -> kernels.TickRecords:
        """The one argument of :func:`.kernels.tick`: the views of ``Data``, the tick state
        and the signal record (made once at reset; again only if the views are re-taken)."""
        pose = self._pose
        return kernels.tick_records(
            pose.terms, pose.feet, self._params, self._targets, self._state, self._signal_record
        )

    def _events(self, transitions: int) -> tuple[dict, ...]:
        """The E-FSM transitions of a tick, then the footstep when the feet swapped roles."""
        events: list[dict] = [
            {"kind": "fsm", "from": old.name, "to": new.name}
            for bit, old, new in _TRANSITIONS
            if transitions & bit
        ]
        if transitions & DS_TO_SSD:
            foot = FEET[int(self._st["support"])]
            events.append({"kind": "support", "foot": foot, "step": int(self._st["steps_done"])})
        return tuple(events)

    def _pin_state(self, sensors: SensorSnapshot) -> tuple[np.ndarray, np.ndarray]:
        """Pinocchio's (q, v), as ``sensors.pinocchio_state`` gives them, into reused buffers.

        The same compiled kernel as :meth:`Robot.pin_state`, without its two allocations and
        argument conversions (a few µs per tick at 2 kHz).
        """
        if sensors.base_pos is None or sensors.base_quat is None:
            return sensors.pinocchio_state(self._robot, "the E-FSM controller")  # raises
        pin_state_into(
            sensors.base_pos,
            sensors.base_quat,
            sensors.base_linvel,
            sensors.base_angvel,
            sensors.joint_pos,
            sensors.joint_vel,
            self._robot.pin_joint_index,
            self._pin_buffer,
        )
        return self._q, self._v

    def _start(self) -> None:
        """Record the initial targets (Table II) and start the first DS (Table I)."""
        p, model, data, st = self._p, self._model, self._data, self._st
        self._started = True
        pin.updateFramePlacements(model, data)  # once: the kernel places the frames it needs
        p_left, p_right = (data.oMf[self._sole[f]].translation for f in FEET)
        rot_ub_des = _yaw_only(data.oMi[PELVIS_JOINT].rotation)
        spacing = float(rot_ub_des[:, Y] @ (p_left - p_right))
        self._targets = kernels.WalkTargets(
            z_m0=float(data.com[0][Z] - 0.5 * (p_left[Z] + p_right[Z])),
            width=spacing if p.step_width is None else p.step_width,
            heading=rot_ub_des[:, X].copy(),
            lateral=rot_ub_des[:, Y].copy(),
            rot_des_pelvis=rot_ub_des,  # Table II: the upper body level, initial heading
            rot_des_swing=_yaw_only(data.oMf[self._sole["left"]].rotation),  # sole level
        )
        self._records = self._tick_records()
        # The first DS: O_w sits on the first swing foot, the CoP moves onto the support
        # foot (x_s); it starts where the CoM projects (standing still, CoP ≈ CoM).
        sw = int(st["support"])  # roles in the first DS
        sup = 1 - sw
        st["support"] = sup
        p_sup, p_sw = (p_left, p_right) if FEET[sup] == "left" else (p_right, p_left)
        rot = self._ow_rotation(p_sup, p_sw)
        st["xp_des"] = float((rot.T @ (data.com[0] - p_sup))[X])
        self._rot_w[:] = rot

    def _task2_force(
        self, lam: np.ndarray, acc: np.ndarray, double: bool, eps: float, phase: Phase
    ) -> np.ndarray:
        """F = Λ ẍ* (Eq. 6) of task 2 of :attr:`TASKS` (the swing foot's level), with the
        swing-foot wrench F_s saturated and scaled by ε in SSA, as the tick computes it
        (:func:`.wbc.task2_force`, which documents the saturation modes).

        Args:
            lam: Λ_2; acc: ẍ*, in the level's row order (the swing rows left out in DS).
        """
        tasks = task_set(self.TASKS, self._p.kp, self._p.kv)
        layout = tasks.double if double else tasks.single
        level_first = layout.first[layout.swing_level] if layout.swing_level >= 0 else 0
        p = self._p
        return wbc.task2_force(
            np.ascontiguousarray(lam, dtype=float),
            np.ascontiguousarray(acc, dtype=float),
            max(layout.swing_first - level_first, 0),
            layout.swing_lin.size,
            layout.swing_ang.size,
            eps if phase is Phase.SSA else 1.0,
            p.fs_max_force,
            p.fs_max_moment,
            _saturation_mode(p),
        )

    def _measured_cop(self, sensors: SensorSnapshot) -> tuple[float, float]:
        """CoP (x, y) in the world from the two F/T sensors (§VI-D2) [m]; NaN if unloaded.

        Each sensor reads the wrench the foot applies to the leg; adding back the static
        weight of the part below the sensor (the ankle-roll link, i.e. the foot) gives the
        ground reaction. Feet carrying no vertical load are left out
        (:func:`.kernels.measured_cop`; the tick calls it with the frames it places). Reads
        the F/T frames of ``Data``'s last ``updateFramePlacements``.
        """
        frames = [self._data.oMf[self._ft[f]] for f in FEET]
        feet = self._params.feet
        return kernels.measured_cop(
            np.array([f.rotation for f in frames]),
            np.array([f.translation for f in frames]),
            sensors.left_ft,
            sensors.right_ft,
            feet.foot_com,
            feet.foot_weight,
        )


def _placeholder_targets() -> kernels.WalkTargets:
    """Targets of the right types until the first tick records the real ones."""
    return kernels.WalkTargets(0.0, 0.0, np.zeros(3), np.zeros(3), np.eye(3), np.eye(3))


def _saturation_mode(p: EfsmParams) -> wbc.Saturation:
    """F_s saturation as :func:`.wbc.task2_force` reads it."""
    if not p.fs_decoupled_saturation:
        return wbc.CLIP
    return wbc.UNIFORM if p.fs_saturation == "uniform" else wbc.DECOUPLED_CLIP


def _rot_z(c: float, s: float) -> np.ndarray:
    """Rotation about z with cosine ``c`` and sine ``s``."""
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _yaw_rotation(yaw: float) -> np.ndarray:
    """Rotation about z by ``yaw`` [rad]."""
    return _rot_z(math.cos(yaw), math.sin(yaw))


def _yaw_only(rot: np.ndarray) -> np.ndarray:
    """The yaw part of a rotation: level, with the same heading."""
    return _yaw_rotation(math.atan2(rot[Y, X], rot[X, X]))
