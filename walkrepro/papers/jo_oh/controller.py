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
from typing import Annotated, Literal

import numpy as np
import pinocchio as pin
from pydantic import Field

from walkrepro.controllers.base import Command, Controller, ControllerParams
from walkrepro.controllers.ranges import (
    MAX_BANDWIDTH,
    MAX_CONTROL_PERIOD,
    MAX_COUNT,
    MAX_DAMPING,
    MAX_DURATION,
    MAX_FORCE,
    MAX_FRICTION,
    MAX_LENGTH,
    MAX_PHASE_TIME,
    MAX_STIFFNESS,
    MAX_TORQUE,
    MAX_WEIGHT,
)
from walkrepro.log.signals import SignalLayout, Signals
from walkrepro.papers.jo_oh.centroidal_qp import (
    CentroidalQP,
    CentroidalTasks,
    Dynamics,
    QPWeights,
    SupportContacts,
    contact_wrench_basis,
    empty_stack,
    friction_basis,
)
from walkrepro.papers.jo_oh.footsteps import (
    LEFT,
    RIGHT,
    SIDES,
    FootstepPlan,
    WalkPattern,
    plan_walk,
)
from walkrepro.papers.jo_oh.preview import generate_com, preview_gains
from walkrepro.papers.jo_oh.tasks import (
    COM_SAMPLE,
    FOOT_SIGNALS,
    IMPEDANCE_STATE,
    PITCH,
    ROLL,
    SPATIAL_AXES,
    SWING_PLAN,
    FrameKinematics,
    ImpedanceGains,
    RobotTerms,
    SensorReadings,
    TaskKind,
    TaskOutputs,
    TaskParams,
    TaskSpec,
    TaskState,
    TickParams,
    X,
    Y,
    Z,
    kinematic_chain,
    pack_swing,
    task_records,
    task_row_count,
    task_rows,
    task_table,
)
from walkrepro.sim.robot import Robot, pin_state_buffer, pin_state_into
from walkrepro.sim.sensors import SensorSnapshot
from walkrepro.specs.origin import assumed, calibrated, paper

#: Support sets, each with its own QP (its β blocks differ).
SUPPORTS = ((LEFT, RIGHT), (RIGHT,), (LEFT,))
#: The support set of each phase, by its swing foot (−1: none, LEFT, RIGHT).
SUPPORT_OF_SWING = {-1: SUPPORTS[0], LEFT: (RIGHT,), RIGHT: (LEFT,)}
#: The logged signals, declared once, all floats. :func:`.tasks.task_rows` writes the plan's
#: time, the swing foot, each foot's block (``left_fz`` …, :data:`.tasks.FOOT_SIGNALS`) and
#: the CoM; the tick adds each foot's f_z from the QP [N] (NaN, so not in the tick's
#: message, when the foot is not in the QP's support or the QP failed), the ZMP reference
#: [m] and the count of failed QPs.
SIGNALS = np.dtype(
    [
        ("t_plan", np.float64),
        ("swing_foot", np.float64),
        ("left", FOOT_SIGNALS),
        ("right", FOOT_SIGNALS),
        ("left_fz_qp", np.float64),
        ("right_fz_qp", np.float64),
        *((name, np.float64) for name in ("com_x", "com_y", "com_z")),
        *((name, np.float64) for name in ("com_x_d", "com_y_d", "com_z_d")),
        ("zmp_x_ref", np.float64),
        ("zmp_y_ref", np.float64),
        ("qp_failures", np.float64),
    ]
)
SIGNAL_LAYOUT = SignalLayout.of_record(SIGNALS)
#: Each foot's ``…_fz_qp`` field of :data:`SIGNALS`, by side.
FZ_QP = tuple(f"{side}_fz_qp" for side in SIDES)
#: Where each signal sits in the float64 view of a :data:`SIGNALS` record, by name: the tick
#: writes its own few signals there (numpy sets a structured record's fields, and copies a
#: nested record, ≈ 20× slower than a float vector's).
SIGNAL_AT = {name: at for name, (at, _, _) in SIGNAL_LAYOUT.slots.items()}


#: Longest preview sample time [s]: the spec's longest control period (10 Hz).
MAX_PREVIEW_DT = MAX_CONTROL_PERIOD
#: Largest damping ratio ζ [-]: ten times critical, as a spec's contact (ContactSpec).
MAX_DAMPING_RATIO = 10.0
#: Most edges of a friction pyramid: 64 edges approximate the cone within 0.2 %.
MAX_PYRAMID_EDGES = 64
#: Coarsest QP tolerance [N, m/s²]: an error of 1 N or 1 m/s² is no solution of the QP.
MAX_QP_TOLERANCE = 1.0
#: Largest desired mass [kg, kg m²] of Eq. (1): ten times the KIST humanoid's 57 kg body.
MAX_DESIRED_MASS = 1e3
#: Largest desired damping [N s/m, N m s/rad]: a spec's hold damping bound.
MAX_DESIRED_DAMPING = 1e5
#: Largest desired stiffness [N/m, N m/rad]: a stiff servo's 1e6.
MAX_DESIRED_STIFFNESS = 1e6
DesiredMass = Annotated[float, Field(gt=0, le=MAX_DESIRED_MASS)]
DesiredDamping = Annotated[float, Field(ge=0, le=MAX_DESIRED_DAMPING)]
DesiredStiffness = Annotated[float, Field(ge=0, le=MAX_DESIRED_STIFFNESS)]


class QPImpedanceParams(ControllerParams):
    """Parameters of the walking pattern, the impedance law and the QP (paper §II–IV)."""

    # Walking pattern (§IV).
    stride: float = Field(
        0.35,
        gt=0,
        le=2 * MAX_LENGTH,
        description="swing-foot travel per step [m] (§IV: 0.35 m stride)",
        json_schema_extra=paper("§IV: 0.35 m stride"),
    )
    t_single: float = Field(
        0.56,
        gt=0,
        le=MAX_PHASE_TIME,
        description="single-support time [s] (§IV)",
        json_schema_extra=paper("§IV: 0.56 s single support"),
    )
    t_double: float = Field(
        0.14,
        gt=0,
        le=MAX_PHASE_TIME,
        description="double-support time [s] (§IV)",
        json_schema_extra=paper("§IV: 0.14 s double support"),
    )
    n_steps: int = Field(
        6,
        ge=2,
        le=MAX_COUNT,
        description="number of steps",
        json_schema_extra=assumed(
            "6 steps: the obstacle step and room to step off it",
            scenario="the experiment's number of steps",
        ),
    )
    first_swing: str = Field(
        "right",
        pattern="^(left|right)$",
        description="first swing foot",
        json_schema_extra=paper(
            "§IV-A: the right foot meets the obstacle", scenario="the experiment's first swing foot"
        ),
    )
    t_start: float = Field(
        1.0,
        gt=0,
        le=MAX_DURATION,
        description="initial double support [s]",
        json_schema_extra=assumed("1 s of double support before the first step"),
    )
    t_end_hold: float = Field(
        0.5,
        ge=0,
        le=MAX_DURATION,
        description="planned stance after the last step [s]",
        json_schema_extra=assumed("0.5 s of planned stance after the last step"),
    )
    foot_y: float = Field(
        0.09,
        gt=0,
        le=MAX_LENGTH / 2,
        description="lateral offset of each sole centre [m] (robot: hip ±0.09)",
        json_schema_extra=assumed(
            "the reconstruction's hip spacing, ±0.09 m (robots/kist_humanoid)"
        ),
    )
    swing_height: float = Field(
        0.10,
        gt=0,
        le=MAX_LENGTH,
        description="swing apex above the higher of lift-off and landing [m] (assumed)",
        json_schema_extra=assumed(
            "§IV gives no swing height; 0.10 m clears the paper's 5 cm obstacle by 5 cm"
        ),
    )
    swing_rise_fraction: float = Field(
        0.4,
        gt=0,
        lt=1,
        description="share of the swing spent rising [-] (assumed)",
        json_schema_extra=assumed(
            "40 % of the swing rising, the rest descending onto the landing point"
        ),
    )
    com_height: float | None = Field(
        None,
        gt=0,
        le=2 * MAX_LENGTH,
        description="CoM height of the LIPM [m]; default: the robot's home CoM",
        json_schema_extra=assumed("None: the robot's home CoM height"),
    )
    preview_dt: float = Field(
        0.005,
        gt=0,
        le=MAX_PREVIEW_DT,
        description="sample time of the preview controller [s]",
        json_schema_extra=assumed("5 ms preview sample time (Kajita 2003's order)"),
    )
    preview_time: float = Field(
        1.0,
        gt=0,
        le=MAX_PHASE_TIME,
        description="preview horizon [s] (Kajita 2003: 1.6 s)",
        json_schema_extra=assumed(
            "1 s preview horizon (Kajita 2003: 1.6 s), longer than a 0.7 s step"
        ),
    )
    preview_q: float = Field(
        1.0,
        gt=0,
        le=MAX_WEIGHT,
        description="ZMP error weight Q_e [1/m²]",
        json_schema_extra=assumed("Kajita 2003's weights: Q_e = 1"),
    )
    preview_r: float = Field(
        1e-6,
        gt=0,
        le=MAX_WEIGHT,
        description="CoM jerk weight R [s⁶/m²]",
        json_schema_extra=assumed("Kajita 2003's weights: R = 1e-6"),
    )
    # Impedance (§II, §IV).
    impedance: bool = Field(
        True,
        description="modify the swing reference by Eqs. (1)–(3)",
        json_schema_extra=paper("§II, Eqs. 1-3", scenario="with and without impedance (Figs. 4-7)"),
    )
    m_d: tuple[DesiredMass, DesiredMass, DesiredMass] = Field(
        (30.0, 0.3, 0.3),
        description="desired mass M_d for (z, φx, φy) [kg, kg m², kg m²]",
        json_schema_extra=assumed(
            "§II gives no values; M_d, B_d, K_d: 7 rad/s natural frequency, damping ratio 1.06 on z"
        ),
    )
    b_d: tuple[DesiredDamping, DesiredDamping, DesiredDamping] = Field(
        (450.0, 3.0, 3.0),
        description="desired damping B_d [N s/m, N m s/rad]",
        json_schema_extra=assumed("§II gives no values; see m_d"),
    )
    k_d: tuple[DesiredStiffness, DesiredStiffness, DesiredStiffness] = Field(
        (1500.0, 10.0, 10.0),
        description="desired stiffness K_d [N/m, N m/rad]",
        json_schema_extra=assumed("§II gives no values; see m_d"),
    )
    force_threshold: float = Field(
        10.0,
        gt=0,
        le=MAX_FORCE,
        description="|λ_z| that switches impedance on [N] (§IV)",
        json_schema_extra=paper("§IV: 10 N on z"),
    )
    torque_threshold: float = Field(
        3.0,
        gt=0,
        le=MAX_TORQUE,
        description="|λ_φx|, |λ_φy| that switch it on [N m] (§IV)",
        json_schema_extra=paper("§IV: 3 Nm about x and y"),
    )
    # Task gains (§III-D: ẍ_r = ẍ_d + K_V(ẋ_d − ẋ) + K_P(x_d − x), Eq. 3).
    # Swing gains K_P = ω², K_V = 2ζω. The paper gives no values; §II: low gains cause
    # "insufficient tracking", high gains "instability at the contact moment". ω is fixed on
    # flat ground (walk_flat_kist), a criterion stated after obstacle runs at an earlier ω = 25
    # (experiments/calibration/jo_oh.yaml, swing_omega): the softest ω, in steps of 2.5 rad/s,
    # whose tracking lands the feet without an impact, i.e. the peak foot force of the flat
    # walk stays within 5 % of the robot's weight (ω = 20: 1.14 m g; 22.5: 1.02 m g).
    swing_omega: float = Field(
        22.5,
        gt=0,
        le=MAX_BANDWIDTH,
        description="swing-foot tracking bandwidth ω [rad/s] (K_P = ω², K_V = 2ζω)",
        json_schema_extra=calibrated(
            "the softest ω (2.5 rad/s steps) whose flat walk's peak foot force stays within 1.05 m g (walk_flat_kist's peak-force rows)"
        ),
    )
    swing_zeta: float = Field(
        1.0,
        gt=0,
        le=MAX_DAMPING_RATIO,
        description="swing-foot damping ratio ζ [-]",
        json_schema_extra=assumed("critical damping"),
    )
    kp_swing: float | None = Field(
        None,
        ge=0,
        le=MAX_STIFFNESS,
        description="swing-foot K_P [1/s²]; default ω² (overrides ω when given)",
        json_schema_extra=assumed("None: ω²"),
    )
    kv_swing: float | None = Field(
        None,
        ge=0,
        le=MAX_DAMPING,
        description="swing-foot K_V [1/s]; default 2ζω (overrides ω when given)",
        json_schema_extra=assumed("None: 2ζω"),
    )
    kp_orient: float = Field(
        200.0,
        ge=0,
        le=MAX_STIFFNESS,
        description="pelvis and torso orientation K_P [1/s²]",
        json_schema_extra=assumed("§III-D gives no gains; 200 1/s², critically damped with 28 1/s"),
    )
    kv_orient: float = Field(
        28.0,
        ge=0,
        le=MAX_DAMPING,
        description="pelvis and torso orientation K_V [1/s]",
        json_schema_extra=assumed("≈ 2√200, critical damping"),
    )
    kp_posture: float = Field(
        100.0,
        ge=0,
        le=MAX_STIFFNESS,
        description="arm and waist joint K_P [1/s²]",
        json_schema_extra=assumed("§III-D gives no gains; 100 1/s² (Paper I's task gains)"),
    )
    kv_posture: float = Field(
        20.0,
        ge=0,
        le=MAX_DAMPING,
        description="arm and waist joint K_V [1/s]",
        json_schema_extra=assumed("2√100, critical damping"),
    )
    k_h: float = Field(
        20.0,
        ge=0,
        le=MAX_BANDWIDTH,
        description="linear momentum gain K_h [1/s]",
        json_schema_extra=assumed("§III-D gives no K_h; 20 1/s"),
    )
    k_i: float = Field(
        100.0,
        ge=0,
        le=MAX_STIFFNESS,
        description="linear momentum integral gain K_I [1/s²]",
        json_schema_extra=assumed("§III-D gives no K_I; 100 1/s²"),
    )
    k_h_angular: float = Field(
        5.0,
        ge=0,
        le=MAX_BANDWIDTH,
        description="angular momentum gain K_h [1/s]",
        json_schema_extra=assumed("§III-D gives no K_h; 5 1/s on the angular rows"),
    )
    # QP weights (§III-D: W_1 … W_4).
    w_momentum_linear: float = Field(
        1.0,
        gt=0,
        le=MAX_WEIGHT,
        description="W_1, force rows [1/N²]",
        json_schema_extra=assumed("§III-D: W_1 determined for the walking motion, no values; 1"),
    )
    w_momentum_angular: float = Field(
        1.0,
        gt=0,
        le=MAX_WEIGHT,
        description="W_1, moment rows [1/(N m)²]",
        json_schema_extra=assumed("§III-D gives no W_1; 1"),
    )
    w_swing: float = Field(
        100.0,
        gt=0,
        le=MAX_WEIGHT,
        description="W_t of the swing foot",
        json_schema_extra=assumed("§III-D gives no W_t; 100, the swing foot first"),
    )
    w_pelvis: float = Field(
        100.0,
        gt=0,
        le=MAX_WEIGHT,
        description="W_t of the pelvis orientation",
        json_schema_extra=assumed("§III-D gives no W_t; 100"),
    )
    w_torso: float = Field(
        10.0,
        gt=0,
        le=MAX_WEIGHT,
        description="W_t of the torso orientation",
        json_schema_extra=assumed("§III-D gives no W_t; 10"),
    )
    w_posture: float = Field(
        1.0,
        gt=0,
        le=MAX_WEIGHT,
        description="W_t of the arm and waist joints",
        json_schema_extra=assumed("§III-D gives no W_t; 1"),
    )
    w_accel: float = Field(
        1e-4,
        gt=0,
        le=MAX_WEIGHT,
        description="W_3 regularisation of ξ̈",
        json_schema_extra=assumed("§III-D gives no W_3; 1e-4, regularisation only"),
    )
    w_force: float = Field(
        1e-6,
        gt=0,
        le=MAX_WEIGHT,
        description="W_4 regularisation of β",
        json_schema_extra=assumed("§III-D gives no W_4; 1e-6, regularisation only"),
    )
    friction: float = Field(
        0.6,
        gt=0,
        le=MAX_FRICTION,
        description="friction coefficient μ of the pyramid (Eq. 8)",
        json_schema_extra=assumed("§III-C gives no μ; 0.6, below the floor's 1.0"),
    )
    pyramid_edges: int = Field(
        4,
        ge=3,
        le=MAX_PYRAMID_EDGES,
        description="edges m of each pyramid (Eq. 8)",
        json_schema_extra=assumed("§III-C: an m-sided polygon, m not given; 4"),
    )
    qp_solver: Literal["active_set", "daqp", "quadprog", "proxqp", "osqp"] = Field(
        "daqp",
        description="solver of the §III-D QP: a qpsolvers backend (daqp, quadprog: exact "
        "active sets; proxqp, osqp: iterative, to qp_tolerance), or active_set (this "
        "package's exact active set on the same problem, ξ̈ eliminated, compiled and "
        "warm-started: an opt-in fast path)",
        json_schema_extra=assumed(
            "§III-D names no solver. Criterion, fixed before any run: the QP's exact "
            "minimiser through qpsolvers, and of the backends that reach it (KKT residuals, "
            "distance to the exact solution) the fastest per solve on Paper III's runs: daqp "
            "(docs/performance.md, Paper III's QP solver, chosen by measurement)"
        ),
    )
    qp_tolerance: float = Field(
        1e-9,
        gt=0,
        le=MAX_QP_TOLERANCE,
        description="absolute tolerance of the iterative QP solvers (proxqp, osqp) [N, m/s²]",
        json_schema_extra=assumed(
            "1e-9: three orders below the active set's 1e-6 agreement with the libraries"
        ),
    )

    @property
    def swing_gains(self) -> tuple[float, float]:
        """(K_P [1/s²], K_V [1/s]) of the swing foot: ω², 2ζω unless given explicitly."""
        kp = self.swing_omega**2 if self.kp_swing is None else self.kp_swing
        kv = 2.0 * self.swing_zeta * self.swing_omega if self.kv_swing is None else self.kv_swing
        return kp, kv


#: The leg joints' name prefixes: the QP moves them for support and swing; the other joints
#: (arms, waist) are the posture task's.
LEG_JOINTS = ("l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle")
#: The frame rows an orientation task selects: all three angular axes.
UPRIGHT = ("rx", "ry", "rz")
#: The floating base's joint in Pinocchio's model (joint 0 is the universe).
BASE_JOINT = 1
#: The free joint's position [m] and quaternion (w, x, y, z) in MuJoCo's ``qpos``.
BASE_POSITION, BASE_QUATERNION = slice(0, 3), slice(3, 7)


def paper_tasks(p: QPImpedanceParams, joint_names: tuple[str, ...]) -> tuple[TaskSpec, ...]:
    """The tasks of §III-D besides the centroidal momentum, in the order of their rows.

    This list is the one place to add, remove or re-weight a task (a controller subclass may
    return another list from :meth:`QPImpedanceController.tasks`); :func:`.tasks.stack_tasks`
    stacks whatever it holds.
    """
    kp_swing, kv_swing = p.swing_gains
    posture = tuple(name for name in joint_names if not name.startswith(LEG_JOINTS))
    return (
        TaskSpec("pelvis", TaskKind.ORIENTATION, "pelvis", UPRIGHT, p.kp_orient, p.kv_orient,
                 p.w_pelvis, "§III-D: the body orientation, ẍ_r of Eq. (3)'s form"),
        TaskSpec("torso", TaskKind.ORIENTATION, "torso", UPRIGHT, p.kp_orient, p.kv_orient,
                 p.w_torso, "§III-D: the trunk orientation"),
        TaskSpec("posture", TaskKind.POSTURE, posture, (), p.kp_posture, p.kv_posture,
                 p.w_posture, "§III-D: the arm and waist joints at home"),
        TaskSpec("swing_foot", TaskKind.SWING_FOOT, "", SPATIAL_AXES, kp_swing, kv_swing,
                 p.w_swing, "Eq. (3), with the impedance-modified reference of Eqs. (1)-(2)"),
    )  # fmt: skip


class _DataViews:
    """Numpy views of the Pinocchio ``Data`` fields a tick reads, taken once.

    Pinocchio returns ``Data``'s vectors and matrices as views of its own memory, which the
    algorithms overwrite in place, so views taken once stay current: a tick then reads them
    for free instead of through ≈ 25 getters (≈ 0.3–0.6 µs each at 1 kHz). :meth:`follows`
    proves that on this Pinocchio; where it does not hold, the controller calls
    :meth:`refresh` every tick.

    Args:
        model, data: the controller's Pinocchio model and data.
        frames: Pinocchio frame ids of the frames the tick reads (the soles first).
    """

    def __init__(self, model: pin.Model, data: pin.Data, frames: tuple[int, ...]):
        self._model, self._data, self._frames = model, data, frames
        self._offsets = [model.frames[f].placement.translation.copy() for f in frames]
        self._chains = [kinematic_chain(model, f) for f in frames]
        self.refresh()

    def refresh(self) -> None:
        """(Re)take every view from ``Data``."""
        data, model = self._data, self._model
        self.jacobians, self.mass_matrix, self.nle, self.g = data.J, data.M, data.nle, data.g
        self.com, self.vcom, self.angular_momentum = data.com[0], data.vcom[0], data.hg.angular
        base = data.oMi[BASE_JOINT]
        self.base_rotation, self.base_position = base.rotation, base.translation
        #: per frame: its placement, its parent joint's R, v, a, and its constants
        self.frames = tuple(
            FrameKinematics(
                rotation=data.oMf[frame].rotation,
                position=data.oMf[frame].translation,
                joint_rotation=data.oMi[model.frames[frame].parentJoint].rotation,
                joint_velocity=data.v[model.frames[frame].parentJoint].vector,
                joint_drift=data.a[model.frames[frame].parentJoint].vector,
                offset=offset,
                chain=chain,
            )
            for frame, offset, chain in zip(self._frames, self._offsets, self._chains, strict=True)
        )

    def _arrays(self) -> list[np.ndarray]:
        return [
            self.jacobians, self.mass_matrix, self.nle, self.g, self.com, self.vcom,
            self.angular_momentum, self.base_rotation, self.base_position,
            *(array for frame in self.frames for array in frame),
        ]  # fmt: skip

    def follows(self) -> bool:
        """True if every view holds what a fresh read of ``Data`` gives."""
        fresh = _DataViews(self._model, self._data, self._frames)
        return all(
            np.array_equal(a, b) for a, b in zip(self._arrays(), fresh._arrays(), strict=True)
        )


class QPImpedanceController(Controller):
    """Walks the flat-ground plan with the centroidal QP and impedance landing (Jo & Oh).

    A tick runs at 1 kHz, so :meth:`step` makes few Python calls: one compiled call forms
    (q, v), one ``computeAllTerms`` (and ``updateFramePlacements``) gives Pinocchio's terms,
    read through views of ``Data`` taken at reset (:class:`_DataViews`); one compiled call
    (:func:`.tasks.task_rows`) forms b_1, the declared tasks' rows (:meth:`tasks`), every
    frame drift, contact wrench and impedance update, and the QP (:class:`CentroidalQP`,
    whose inputs reference the controller's buffers) is solved. Arrays are preallocated in
    :meth:`reset`: the tick's parameters in one record (``_params``), its state in another
    (``_state``).
    """

    Params = QPImpedanceParams

    def tasks(self, params: QPImpedanceParams, robot: Robot) -> tuple[TaskSpec, ...]:
        """The task list of the QP (:func:`paper_tasks`); override to add or swap a task."""
        return paper_tasks(params, robot.joint_names)

    def reset(self, robot: Robot, params: ControllerParams, control_period: float) -> None:
        """Plan the walk, generate the CoM pattern, declare the tasks and build the QPs."""
        assert isinstance(params, QPImpedanceParams)
        if robot.control_mode != "torque":
            raise ValueError("qpimpedance needs a torque-controlled robot")
        self._robot, self._p = robot, params
        model = robot.pin_model
        self._model, self._data = model, model.createData()
        self._sole = [robot.pin_frame_id(f"{s}_sole") for s in SIDES]
        q0, v0 = robot.pin_state_from_mujoco(robot.home_qpos, np.zeros(robot.mj_model.nv))
        com0 = pin.centerOfMass(model, self._data, q0)
        com_plan = self._plan_walk(params, robot, com0)
        specs = self.tasks(params, robot)
        frame_names = tuple(dict.fromkeys(
            ("left_sole", "right_sole",
             *(s.target for s in specs if s.kind == TaskKind.ORIENTATION))
        ))  # fmt: skip
        self._views = _DataViews(model, self._data, tuple(map(robot.pin_frame_id, frame_names)))
        self._pin_state, self._q, self._v = pin_state_buffer(model)
        self._params = self._tick_params(
            params, robot, control_period, com_plan, task_table(specs, frame_names, robot.joint_names),
            float(com0[Z] if params.com_height is None else params.com_height),
        )  # fmt: skip
        self._state = TaskState(
            impedance=np.zeros(2, dtype=IMPEDANCE_STATE),
            prev_foot_vel=np.zeros((2, 6)),
            foot_acc_cmd=np.zeros((2, 3)),
            swing_plan=np.zeros(1, dtype=SWING_PLAN),  # tasks.pack_swing
            stance_z=np.zeros(2),  # planned height of each foot in support [m]
            swing_motion=np.zeros((3, 6)),
        )
        self._phase_index, self._qp_fail = -1, 0
        self._tau = np.zeros(robot.n_joints)
        self._build_outputs(params, self._params)
        self._refresh_views = False
        self._check_views(q0)
        self._bind_task_args()
        self._bind_qp_inputs()
        self._warm_up_tick(q0, v0)
        # Wall time of the tick's parts [s], for benchmarks only (never logged: logs stay
        # deterministic). Running totals: memory stays flat however long the run.
        self._timing = dict.fromkeys(("dynamics", "tasks", "qp_solve", "output"), 0.0)

    def _plan_walk(self, p: QPImpedanceParams, robot: Robot, com0: np.ndarray) -> np.ndarray:
        """Footsteps, ZMP reference and the preview-control CoM pattern (ref. [23]).

        Returns:
            The CoM pattern, shape (N,) of :data:`.tasks.COM_SAMPLE`.
        """
        com_height = p.com_height or robot.nominal_com_height
        first = LEFT if p.first_swing == "left" else RIGHT
        pattern = WalkPattern(
            p.foot_y, p.stride, p.n_steps, first, p.t_start, p.t_single, p.t_double, p.t_end_hold
        )
        self._plan: FootstepPlan = plan_walk(pattern, p.preview_dt)
        self._phase_ends = [ph.t1 for ph in self._plan.phases]
        gains = preview_gains(p.preview_dt, com_height, p.preview_time, p.preview_q, p.preview_r)
        ref = self._plan.zmp_xy
        columns = [
            generate_com(gains, ref[:, axis], np.array([com0[axis], 0.0, 0.0]))[0]
            for axis in (X, Y)
        ]  # each axis's (c, ċ, c̈) per sample
        com_plan = np.zeros(len(columns[X]), dtype=COM_SAMPLE)
        for order, name in enumerate(("position", "velocity", "acceleration")):
            com_plan[name] = np.column_stack([column[:, order] for column in columns])
        return com_plan

    def _tick_params(
        self,
        p: QPImpedanceParams,
        robot: Robot,
        control_period: float,
        com_plan: np.ndarray,
        table: np.ndarray,
        com_z: float,
    ) -> TaskParams:
        """The tick's parameters record (:class:`.tasks.TaskParams`), built once."""
        site_rotation, site_position, foot_com = _foot_geometry(robot)
        length, width = robot.sole_size
        corners = np.array(
            [[sx * length / 2, sy * width / 2, 0.0] for sx in (1, -1) for sy in (1, -1)]
        )
        pyramid = friction_basis(p.friction, p.pyramid_edges)
        tick = TickParams(
            dt=float(control_period),
            mass=float(robot.total_mass),
            foot_mass=_foot_mass(robot),
            k_h=p.k_h,
            k_i=p.k_i,
            k_h_angular=p.k_h_angular,
            impedance=bool(p.impedance),
            preview_dt=p.preview_dt,
            plan_end=float(self._plan.end),
            com_z=com_z,
        )
        impedance = ImpedanceGains(
            mass=np.array(p.m_d, dtype=np.float64),
            damping=np.array(p.b_d, dtype=np.float64),
            stiffness=np.array(p.k_d, dtype=np.float64),
            threshold=np.array((p.force_threshold, p.torque_threshold, p.torque_threshold)),
        )
        return TaskParams(
            tick, impedance, table,
            np.ascontiguousarray(robot.pin_v_idx, dtype=np.int64),
            robot.home_joint_pos.astype(np.float64),
            site_rotation, site_position, foot_com,
            contact_wrench_basis(np.eye(3), corners, pyramid), com_plan,
        )  # fmt: skip

    def _build_outputs(self, p: QPImpedanceParams, params: TaskParams) -> None:
        """The buffers the tick writes (cost terms, each foot's contact terms, signals) and
        each support set's QP."""
        nv, n_beta = self._model.nv, params.local_wrench_map.shape[1]
        # The QP's cost terms of §III-D (task_rows fills them each tick): b_1 and W_1, and
        # the declared tasks' rows.
        self._tasks = CentroidalTasks(
            np.zeros(6),
            np.array([p.w_momentum_linear] * 3 + [p.w_momentum_angular] * 3),
            empty_stack(task_row_count(params.tasks), params.tasks.size, nv),
        )
        # Each foot's sole Jacobian, drift and rotated wrench basis; the QP of a support set
        # takes the feet's slices of these (no copies).
        self._sole_jacobians = np.zeros((2, 6, nv))
        self._sole_drifts = np.zeros((2, 6))
        self._wrench_maps = np.zeros((2, 6, n_beta))
        self._support_slices = {
            support: slice(min(support), max(support) + 1) for support in SUPPORTS
        }
        weights = QPWeights(p.w_accel, p.w_force)
        self._qps = {
            support: CentroidalQP(nv, len(support), n_beta, weights, p.qp_solver, p.qp_tolerance)
            for support in SUPPORTS
        }
        self._warm_support: tuple[int, ...] | None = None  # QP solved on the previous tick
        # The tick's signals (SIGNALS): task_rows writes its fields; a QP f_z stays NaN here.
        self._signal_record = np.zeros(1, dtype=SIGNALS)
        self._signal_record[FZ_QP[LEFT]] = self._signal_record[FZ_QP[RIGHT]] = np.nan
        self._signal_vector = self._signal_record.view(np.float64)  # the same memory

    def timing(self) -> dict[str, float]:
        """Wall time [s] of the tick's parts: Pinocchio, tasks, QP (build, solve, Eq. 9), output."""
        return dict(self._timing)

    # ------------------------------------------------------------------------------------

    def _check_views(self, q0: np.ndarray) -> None:
        """Use the views of :class:`_DataViews` only if they follow ``Data`` on this Pinocchio."""
        model, data = self._model, self._data
        for scale in (0.0, 0.01):  # two states: the views must follow
            dq = np.full(model.nv, scale)
            pin.computeAllTerms(model, data, pin.integrate(model, q0, dq), dq)
            pin.updateFramePlacements(model, data)
            if not self._views.follows():
                self._refresh_views = True

    def _bind_qp_inputs(self) -> None:
        """Point each support set's QP at the tasks, its feet's slices of the contact buffers,
        and M, C ξ̇ + g.

        The QP keeps references, and the tick fills these arrays in place, so this runs once
        (and again only when the views of ``Data`` have to be refreshed).
        """
        views = self._views
        for support, qp in self._qps.items():
            feet = self._support_slices[support]
            qp.set_inputs(
                Dynamics(views.mass_matrix, views.nle),
                self._tasks,
                SupportContacts(
                    self._sole_jacobians[feet], self._sole_drifts[feet], self._wrench_maps[feet]
                ),
            )

    def _warm_up_tick(self, q0: np.ndarray, v0: np.ndarray) -> None:
        """Compile (or load from numba's cache) the tick's kernels for the argument types of a
        real tick, by running them once at home, at rest; then undo that tick's state."""
        robot = self._robot
        home = robot.home_qpos
        home_pos, home_quat = home[BASE_POSITION].copy(), home[BASE_QUATERNION].copy()
        home_joints, zero_joints = robot.home_joint_pos.copy(), np.zeros(robot.n_joints)
        zero3, zero_ft = np.zeros(3), np.zeros(6)
        pin_state_into(
            home_pos, home_quat, zero3, zero3, home_joints, zero_joints,
            robot.pin_joint_index, self._pin_state,
        )  # fmt: skip
        pin.computeAllTerms(self._model, self._data, q0, v0)
        pin.updateFramePlacements(self._model, self._data)
        self._task_rows(0.0, -1, home_joints, zero_joints, zero_ft, zero_ft)
        for qp in self._qps.values():  # the QP's kernels (a library solver's too)
            qp.solve(warm=False)
            qp.solution.x[:] = 0.0
        state = self._state
        state.impedance[:] = np.zeros(1, dtype=IMPEDANCE_STATE)
        state.prev_foot_vel[:] = 0.0
        state.foot_acc_cmd[:] = 0.0

    def _pin_state_of(self, s: SensorSnapshot) -> tuple[np.ndarray, np.ndarray]:
        """Pinocchio (q, v) as ``s.pinocchio_state``, written into preallocated arrays."""
        if s.base_pos is None or s.base_quat is None or s.base_linvel is None:
            return s.pinocchio_state(self._robot, "qpimpedance (as in §IV)")  # names the fix
        q, v = self._q, self._v
        pin_state_into(
            s.base_pos,
            s.base_quat,
            s.base_linvel,
            s.base_angvel,
            s.joint_pos,
            s.joint_vel,
            self._robot.pin_joint_index,
            self._pin_state,
        )
        return q, v

    def _enter_phase(self, index: int) -> None:
        """Start a phase: a swing builds its trajectory from the foot's actual pose."""
        phase = self._plan.phases[index]
        self._phase_index = index
        if phase.swing < 0:
            return
        sole = self._data.oMf[self._sole[phase.swing]]
        rpy = pin.rpy.matrixToRpy(sole.rotation)
        start = np.array([*sole.translation, rpy[ROLL], rpy[PITCH]])
        target = np.array([*phase.target, 0.0, 0.0])
        p = self._p
        pack_swing(
            phase.t0,
            phase.t1 - phase.t0,
            start,
            target,
            p.swing_height,
            p.swing_rise_fraction,
            self._state.swing_plan,
        )
        self._state.stance_z[phase.swing] = phase.target[Z]

    def _bind_task_args(self) -> None:
        """Gather :func:`.tasks.task_rows`' records, which hold the same arrays every tick.

        Data's views and ξ̇, the parameters, the state and the output buffers: all are filled
        in place, so a tick passes one prebuilt :class:`.tasks.TaskRecords` instead of
        looking up fifty attributes.
        """
        views = self._views
        terms = RobotTerms(
            views.jacobians,
            views.mass_matrix,
            views.nle,
            views.g,
            views.com,
            views.vcom,
            views.angular_momentum,
            views.base_rotation,
            views.base_position,
            views.frames,
            self._v,
        )
        outputs = TaskOutputs(
            self._tasks,
            self._sole_jacobians,
            self._sole_drifts,
            self._wrench_maps,
            self._signal_record,
        )
        self._task_records = task_records(terms, self._params, self._state, outputs)

    def _task_rows(
        self,
        t: float,
        swing: int,
        joint_pos: np.ndarray,
        joint_vel: np.ndarray,
        left_ft: np.ndarray,
        right_ft: np.ndarray,
    ) -> int:
        """Run :func:`.tasks.task_rows` on this tick's Pinocchio terms and sensor readings.

        Returns:
            A bit per foot (1 left, 2 right) whose impedance modification switched on.
        """
        readings = SensorReadings(joint_pos, joint_vel, left_ft, right_ft)
        return task_rows(t, swing, readings, self._task_records)

    def step(self, t: float, s: SensorSnapshot) -> Command:
        """One tick of §III-D: tasks → QP → Eq. (9)."""
        t0 = time.perf_counter()
        model, data = self._model, self._data
        q, v = self._pin_state_of(s)
        # M, C ξ̇ + g, g, the joint Jacobians, the CoM and h_G. Its forward pass also leaves
        # the drift accelerations (ξ̈ = 0) in data.a, so J̇ ξ̇ needs no second kinematics pass.
        pin.computeAllTerms(model, data, q, v)
        pin.updateFramePlacements(model, data)
        if self._refresh_views:
            self._views.refresh()
            self._bind_task_args()
            self._bind_qp_inputs()
        t1 = time.perf_counter()

        index = min(bisect_right(self._phase_ends, t), len(self._phase_ends) - 1)
        if index != self._phase_index:
            self._enter_phase(index)
        swing = self._plan.phases[index].swing
        support = SUPPORT_OF_SWING[swing]
        # Momentum, orientation, posture and swing rows; feet states, wrenches, impedance.
        switched_on = self._task_rows(t, swing, s.joint_pos, s.joint_vel, s.left_ft, s.right_ft)
        events: list[dict] = []
        if switched_on:
            for side in (LEFT, RIGHT):
                if switched_on >> side & 1:
                    fz = float(self._signal_record[SIDES[side]]["fz"][0])
                    events.append({"kind": "impedance_on", "foot": SIDES[side], "fz": fz})
        t2 = time.perf_counter()

        # ---- QP and Eq. (9): its inputs are this tick's buffers (_bind_qp_inputs) --------
        qp = self._qps[support]
        solved = qp.solve(warm=support == self._warm_support)
        t4 = time.perf_counter()
        if solved:
            self._warm_support = support
            self._tau = tau = qp.tau.copy()  # a new array each tick (ctrl), held for a failure
            fz_qp = qp.wrenches[:, Z].tolist()
        else:
            self._qp_fail += 1
            self._warm_support = None
            events.append({"kind": "qp_failed"})
            tau, fz_qp, support = self._tau.copy(), [], ()  # hold the last torques
        # task_rows' signals, then each foot's QP f_z (NaN: not solved for), ZMP, failures.
        values = self._signal_vector.copy()
        for side, fz in zip(support, fz_qp, strict=True):
            values[SIGNAL_AT[FZ_QP[side]]] = fz
        values[SIGNAL_AT["zmp_x_ref"]], values[SIGNAL_AT["zmp_y_ref"]] = self._plan.zmp_at(t)
        values[SIGNAL_AT["qp_failures"]] = self._qp_fail
        signals = Signals(SIGNAL_LAYOUT, values)
        command = Command(ctrl=tau, signals=signals, events=tuple(events))
        timing = self._timing
        timing["dynamics"] += t1 - t0
        timing["tasks"] += t2 - t1
        timing["qp_solve"] += t4 - t2
        timing["output"] += time.perf_counter() - t4
        return command


def _foot_mass(robot: Robot) -> float:
    """Mass of the foot body below the F/T sensor [kg] (both feet alike)."""
    model = robot.pin_model
    return float(model.inertias[model.frames[robot.pin_frame_id("left_foot")].parentJoint].mass)


def _foot_geometry(robot: Robot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each F/T sensor's placement and each foot body's CoM, in its sole frame.

    Sole, sensor site and foot body hang on the same joint (the ankle), so these are
    constants: per tick the sensor's and the CoM's world placements follow from the sole's.

    Returns:
        Sensor rotations (2, 3, 3), sensor positions (2, 3) [m], foot CoMs (2, 3) [m].
    """
    model = robot.pin_model
    rotations, positions, coms = np.zeros((2, 3, 3)), np.zeros((2, 3)), np.zeros((2, 3))
    for side, name in enumerate(SIDES):
        sole, site, foot = (
            model.frames[robot.pin_frame_id(f"{name}_{f}")] for f in ("sole", "foot_ft", "foot")
        )
        if not sole.parentJoint == site.parentJoint == foot.parentJoint:
            raise ValueError(f"qpimpedance needs {name}_sole, _foot_ft and _foot on one body")
        sole_site = sole.placement.actInv(site.placement)
        rotations[side], positions[side] = sole_site.rotation, sole_site.translation
        lever = model.inertias[foot.parentJoint].lever  # foot CoM in the foot frame
        coms[side] = sole.placement.actInv(foot.placement.act(lever))
    return rotations, positions, coms
