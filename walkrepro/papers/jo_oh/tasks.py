"""Paper III's tasks (§III-D), declared by name, and the per-tick algebra that stacks them.

A researcher edits a list of :class:`TaskSpec` (the controller's
:meth:`~.controller.QPImpedanceController.tasks`): each task's name, its kind, the frame or
joints it moves, the axes it selects, its gains K_P, K_V, its weight W_t and the paper's
equation. One compiled routine, :func:`stack_tasks`, stacks them each tick into the rows of
Σ_t ‖Φ_t ξ̈ − b_t‖²_{W_t} (a :class:`.centroidal_qp.TaskStack`), every task in the same form
(pink's ``compute_error`` / ``compute_jacobian``):

    ẍ_r = ẍ_d + K_V (ẋ_d − ẋ) + K_P e,     b_t = ẍ_r − Φ̇_t ξ̇,                     (Eq. 3)

with e = x_d − x (an orientation's e = log₃(R_d R⁻¹), R_d = I: upright, heading +x). The rows
and their offsets are counted from the selected axes, never typed.

Besides the tasks, each tick forms the centroidal momentum target b_1 (Eq. 7), each foot's
sole Jacobian, drift J̇ ξ̇ and rotated wrench basis R̃ U_k (Eq. 8), which the QP takes for the
support feet, and each foot's contact wrench from its F/T sensor and the impedance
modification of the swing reference (Eqs. 1–3), with the signals the log records.

Why numba: written in Python this is ≈ 70 small numpy calls on 3- to 28-vectors, ≈ 65 µs of
the ≈ 200 µs a 1 kHz tick may take at 5× real time. One compiled call, :func:`task_rows`,
does it in a few µs. Its inputs are views of Pinocchio's ``Data`` after ``computeAllTerms``
(M, C ξ̇ + g, the joint Jacobians, frame and joint placements, the joints' velocities and
drift accelerations), passed without copies, in one :class:`TaskRecords` (a StructRef made by
:func:`walkrepro.runtime.records.define_record`): its ``params`` are set at reset, its
``state`` is carried from tick to tick, both records of named fields.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum
from typing import NamedTuple

import numba
import numpy as np
import pinocchio as pin

from walkrepro.papers.jo_oh.centroidal_qp import CentroidalTasks
from walkrepro.papers.jo_oh.footsteps import LEFT, RIGHT
from walkrepro.runtime.records import define_record
from walkrepro.sim.robot import frame_classical_acceleration, frame_jacobian, log3

GRAVITY = 9.81  # [m/s^2]
#: The universe joint of a Pinocchio model (no velocity; not in a frame's chain).
UNIVERSE = 0
#: The axes of a 3-vector, and the rows and columns of a rotation matrix.
X, Y, Z = 0, 1, 2
#: The angles of (roll, pitch, yaw) [rad].
ROLL, PITCH, YAW = 0, 1, 2
#: A spatial vector's rows (LOCAL_WORLD_ALIGNED): linear x, y, z, then angular rx, ry, rz.
RX, RY, RZ = 3, 4, 5
#: The first row of a spatial vector's linear and angular halves.
LINEAR_ROW, ANGULAR_ROW = 0, 3
#: A spatial vector's axes by name, in row order (a frame task selects among them).
SPATIAL_AXES = ("x", "y", "z", "rx", "ry", "rz")
#: The swing plan's coordinates: the sole centre's (x, y, z [m], roll, pitch [rad]).
SWING_X, SWING_Y, SWING_Z, SWING_ROLL, SWING_PITCH = 0, 1, 2, 3, 4
#: The swing plan's coordinates the impedance modifies, (z, φ_x, φ_y) (§II).
IMPEDANCE_COORDS = slice(SWING_Z, SWING_PITCH + 1)
#: Rows of a foot's reference signals: x_d, ẋ_d, ẍ_d (desired), x_m, ẋ_m, ẍ_m (modified).
DESIRED_POS, DESIRED_VEL, DESIRED_ACC, MODIFIED_POS, MODIFIED_VEL, MODIFIED_ACC = range(6)
#: Rows of a task's desired motion: x_d, ẋ_d, ẍ_d.
POSITION, VELOCITY, ACCELERATION = 0, 1, 2


class TaskKind(IntEnum):
    """What a task moves, and so how its Jacobian and error are formed (:func:`stack_tasks`)."""

    #: A frame held upright, heading +x: Φ_t its angular Jacobian rows, e = −log₃ R.
    ORIENTATION = 0
    #: Joints held at their home angles: Φ_t selects them, e = q_home − q.
    POSTURE = 1
    #: The swing foot's sole on its swing trajectory (Eq. 3), impedance-modified on
    #: (z, φ_x, φ_y) (Eqs. 1–2); in the QP in single support only.
    SWING_FOOT = 2


@dataclass(frozen=True)
class TaskSpec:
    """One task of the §III-D QP, ‖Φ_t ξ̈ − b_t‖²_{W_t}, as a researcher declares it.

    Attributes:
        name: the task's name (its rows' name in tests and docs).
        kind: what it moves (:class:`TaskKind`).
        target: the Pinocchio frame of an ORIENTATION task; the joint names of a POSTURE
            task (one row each); unused by SWING_FOOT (the swinging sole).
        axes: the selected rows of a frame task, names of :data:`SPATIAL_AXES` (an
            orientation selects among rx, ry, rz); ignored by POSTURE.
        kp: K_P [1/s²].
        kv: K_V [1/s].
        weight: W_t, the same on each row [-].
        equation: where the paper states it.
    """

    name: str
    kind: TaskKind
    target: str | tuple[str, ...]
    axes: tuple[str, ...]
    kp: float
    kv: float
    weight: float
    equation: str


def task_table(
    specs: tuple[TaskSpec, ...], frames: tuple[str, ...], joint_names: tuple[str, ...]
) -> np.ndarray:
    """The compiled form of ``specs``: a structured array of :func:`task_dtype`, one per task.

    Args:
        specs: the tasks, in the order their rows are stacked.
        frames: the frames of :class:`FrameKinematics` the tick has, by name (a task's
            ``frame`` field is its index here).
        joint_names: the actuated joints, actuator order.

    Raises:
        ValueError: an unknown frame, joint or axis, or an orientation selecting a linear axis.
    """
    table = np.zeros(len(specs), dtype=task_dtype(len(joint_names)))
    for row, spec in zip(table, specs, strict=True):
        row["kind"], row["kp"], row["kv"], row["weight"] = spec.kind, spec.kp, spec.kv, spec.weight
        row["frame"] = -1
        if spec.kind == TaskKind.POSTURE:
            unknown = set(spec.target) - set(joint_names)
            if unknown:
                raise ValueError(
                    f"task {spec.name!r}: unknown joints {sorted(unknown)}; valid: {joint_names}"
                )
            row["joints"] = [name in spec.target for name in joint_names]
            continue
        allowed = SPATIAL_AXES[ANGULAR_ROW:] if spec.kind == TaskKind.ORIENTATION else SPATIAL_AXES
        if not spec.axes or not set(spec.axes) <= set(allowed):
            raise ValueError(f"task {spec.name!r}: axes {spec.axes} not among {allowed}")
        row["axes"] = [axis in spec.axes for axis in SPATIAL_AXES]
        if spec.kind == TaskKind.ORIENTATION:
            if spec.target not in frames:
                raise ValueError(f"task {spec.name!r}: unknown frame {spec.target!r}")
            row["frame"] = frames.index(spec.target)
    return table


def task_dtype(n_joints: int) -> np.dtype:
    """A compiled task's fields: kind, frame index (−1: none), selected spatial axes (6,) and
    joints (n_joints,) (1: selected; numba takes no nested bool arrays), K_P [1/s²], K_V [1/s], W_t."""
    return np.dtype(
        [
            ("kind", np.int64),
            ("frame", np.int64),
            ("axes", np.uint8, (len(SPATIAL_AXES),)),
            ("joints", np.uint8, (n_joints,)),
            ("kp", np.float64),
            ("kv", np.float64),
            ("weight", np.float64),
        ],
        align=True,
    )


def task_row_count(table: np.ndarray) -> int:
    """Most rows the tasks can stack (every task active)."""
    return int(sum(row["joints"].sum() if row["kind"] == TaskKind.POSTURE else row["axes"].sum()
                   for row in table))  # fmt: skip


class TickParams(NamedTuple):
    """The tick's parameters besides the tasks, set at reset.

    Attributes:
        dt: control period [s].
        mass: robot mass m [kg].
        foot_mass: mass of the foot below the F/T sensor [kg].
        k_h: linear momentum gain K_h [1/s].
        k_i: linear momentum integral gain K_I [1/s²].
        k_h_angular: angular momentum gain [1/s].
        impedance: modify the swing reference by Eqs. (1)–(3).
        preview_dt: sample time of the CoM pattern [s].
        plan_end: time the footstep plan ends [s].
        com_z: desired CoM height [m].
    """

    dt: float
    mass: float
    foot_mass: float
    k_h: float
    k_i: float
    k_h_angular: float
    impedance: bool
    preview_dt: float
    plan_end: float
    com_z: float


#: The axes of the swing foot that the impedance modifies, x = (z, φ_x, φ_y) (§II).
IMPEDANCE_AXES = ("z", "roll", "pitch")
#: Kinds of the per-axis references: x_d, ẋ_d, ẍ_d (desired), x_m, ẋ_m, ẍ_m (modified).
REFERENCE_KINDS = ("_d", "_dot_d", "_ddot_d", "_m", "_dot_m", "_ddot_m")
#: The signals :func:`task_rows` writes for each foot (the log names them ``left_fz`` …):
#: the measured contact wrench at the sole [N, N m], the sole's x, z [m], roll, pitch [rad],
#: its velocity (v_z [m/s], ω_x, ω_y [rad/s]) and finite-difference acceleration, whether
#: the impedance modification is on, and the references of each impedance axis.
FOOT_SIGNALS = np.dtype(
    [
        (name, np.float64)
        for name in (
            "fz", "mx", "my", "x", "z", "roll", "pitch",
            "vz", "wx", "wy", "az", "alphax", "alphay", "impedance_on",
            *(f"{axis}{kind}" for kind in REFERENCE_KINDS for axis in IMPEDANCE_AXES),
        )
    ]
)  # fmt: skip
#: The signals :func:`task_rows` writes besides the feet: the plan's time [s], the swing foot
#: (0 left, 1 right, −1 none), the CoM and the desired CoM [m]. A controller's signal record
#: holds these fields and ``left``, ``right`` of :data:`FOOT_SIGNALS`, in its own order.
TICK_SIGNALS = ("t_plan", "swing_foot", "com_x", "com_y", "com_z", "com_x_d", "com_y_d", "com_z_d")
#: A foot's impedance state (see :func:`advance_impedance`): the modified reference x_m, ẋ_m,
#: ẍ_m of (z [m], φ_x, φ_y [rad]) and its rates; ``armed``: the foot has been unloaded since
#: lift-off; ``active``: the modification is on.
IMPEDANCE_STATE = np.dtype(
    [
        ("position", np.float64, (3,)),
        ("velocity", np.float64, (3,)),
        ("acceleration", np.float64, (3,)),
        ("armed", np.bool_),
        ("active", np.bool_),
    ],
    align=True,
)
#: A sample of the preview-control CoM pattern (ref. [23]): the CoM's horizontal (x, y)
#: position [m], velocity [m/s] and acceleration [m/s²] in the world.
COM_SAMPLE = np.dtype(
    [
        ("position", np.float64, (2,)),
        ("velocity", np.float64, (2,)),
        ("acceleration", np.float64, (2,)),
    ]
)
#: A swing trajectory (see :func:`swing_reference`): start time [s], duration [s], the sole
#: centre's (x, y, z [m], roll, pitch [rad]) at lift-off and at landing, the apex [m] above the
#: higher of the two, and the share of the swing spent rising [-].
SWING_PLAN = np.dtype(
    [
        ("t0", np.float64),
        ("duration", np.float64),
        ("start", np.float64, (5,)),
        ("target", np.float64, (5,)),
        ("apex", np.float64),
        ("rise_fraction", np.float64),
    ]
)


class ImpedanceGains(NamedTuple):
    """The impedance law's gains and switch-on thresholds (§II Eq. 1, §IV), per coordinate
    x = (z, φ_x, φ_y), each of shape (3,).

    Attributes:
        mass: M_d [kg, kg m², kg m²].
        damping: B_d [N s/m, N m s/rad, N m s/rad].
        stiffness: K_d [N/m, N m/rad, N m/rad].
        threshold: |λ| that switches the modification on [N, N m, N m] (§IV: 10 N, 3 N m).
    """

    mass: np.ndarray
    damping: np.ndarray
    stiffness: np.ndarray
    threshold: np.ndarray


class FrameKinematics(NamedTuple):
    """A frame's placement and its parent joint's motion (views of Pinocchio's ``Data``), and
    its constants.

    Attributes:
        rotation, position: world placement of the frame (``data.oMf``) [-, m].
        joint_rotation: its parent joint's world rotation (``data.oMi[j].rotation``).
        joint_velocity: its parent joint's spatial velocity, joint axes (``data.v[j]``).
        joint_drift: its parent joint's drift acceleration, joint axes (``data.a[j]``).
        offset: the frame origin in its parent joint's frame [m], shape (3,).
        chain: which velocities move the frame (:func:`kinematic_chain`), shape (nv,) bool.
    """

    rotation: np.ndarray
    position: np.ndarray
    joint_rotation: np.ndarray
    joint_velocity: np.ndarray
    joint_drift: np.ndarray
    offset: np.ndarray
    chain: np.ndarray


class RobotTerms(NamedTuple):
    """Pinocchio's terms of the tick (after ``computeAllTerms`` and ``updateFramePlacements``),
    and ξ̇.

    Attributes:
        joint_jacobians: ``data.J``, shape (6, nv).
        mass_matrix: M (``data.M``), shape (nv, nv).
        nonlinear: C ξ̇ + g (``data.nle``), shape (nv,).
        gravity_torques: g (``data.g``), shape (nv,).
        com, com_vel: CoM position [m] and velocity [m/s] in the world, shape (3,).
        angular_momentum: k, the angular part of h_G [kg m²/s], shape (3,).
        base_rotation, base_position: world-from-base placement (``data.oMi`` of the base).
        frames: the frames the tick reads, :class:`FrameKinematics` each: the left and right
            soles (indices LEFT, RIGHT), then those the tasks name (a task's ``frame``).
        velocity: ξ̇ (Pinocchio's v), shape (nv,).
    """

    joint_jacobians: np.ndarray
    mass_matrix: np.ndarray
    nonlinear: np.ndarray
    gravity_torques: np.ndarray
    com: np.ndarray
    com_vel: np.ndarray
    angular_momentum: np.ndarray
    base_rotation: np.ndarray
    base_position: np.ndarray
    frames: tuple
    velocity: np.ndarray


class SensorReadings(NamedTuple):
    """The tick's sensor readings, actuator order.

    Attributes:
        joint_pos, joint_vel: joint angles [rad] and velocities [rad/s], shape (n,).
        left_ft, right_ft: each foot's F/T reading (force [N], torque [N m]) in its sensor
            frame, shape (6,).
    """

    joint_pos: np.ndarray
    joint_vel: np.ndarray
    left_ft: np.ndarray
    right_ft: np.ndarray


class TaskParams(NamedTuple):
    """The tick's parameters, built once at reset.

    Attributes:
        tick: gains, masses and times (:class:`TickParams`).
        impedance_gains: M_d, B_d, K_d and thresholds (see :func:`advance_impedance`).
        tasks: the declared tasks, compiled (:func:`task_table`), in stacking order.
        joint_v_index: each actuated joint's column in ξ̇, shape (n,) int.
        home_joint_pos: the joints' home angles [rad], shape (n,) (a posture's q_home).
        sole_site_rotation, sole_site_position: each F/T sensor's placement in its sole
            frame, shapes (2, 3, 3) and (2, 3) [-, m].
        sole_foot_com: each foot body's centre of mass in its sole frame, shape (2, 3) [m].
        local_wrench_map: U_k in the contact frame (Eq. 8), shape (6, m N_c).
        com_plan: the preview CoM pattern, shape (N,) of :data:`COM_SAMPLE`.
    """

    tick: TickParams
    impedance_gains: ImpedanceGains
    tasks: np.ndarray
    joint_v_index: np.ndarray
    home_joint_pos: np.ndarray
    sole_site_rotation: np.ndarray
    sole_site_position: np.ndarray
    sole_foot_com: np.ndarray
    local_wrench_map: np.ndarray
    com_plan: np.ndarray


class TaskState(NamedTuple):
    """What a tick carries to the next, updated in place.

    Attributes:
        impedance: each foot's impedance state, shape (2,) of :data:`IMPEDANCE_STATE`.
        prev_foot_vel: each sole's spatial velocity of the previous tick, shape (2, 6).
        foot_acc_cmd: each sole's commanded linear acceleration [m/s²], shape (2, 3).
        swing_plan: this phase's swing trajectory, shape (1,) of :data:`SWING_PLAN`.
        stance_z: each foot's planned stance height [m], shape (2,).
        swing_motion: the swing sole's desired (x, y, z, φ_x, φ_y, φ_z) [m, rad], rates and
            accelerations (rows POSITION, VELOCITY, ACCELERATION), the impedance-modified
            reference on (z, φ_x, φ_y), shape (3, 6).
    """

    impedance: np.ndarray
    prev_foot_vel: np.ndarray
    foot_acc_cmd: np.ndarray
    swing_plan: np.ndarray
    stance_z: np.ndarray
    swing_motion: np.ndarray


class TaskOutputs(NamedTuple):
    """What :func:`task_rows` writes each tick.

    Attributes:
        tasks: the QP's cost terms: b_1 (W_1 constant) and the stacked task rows.
        sole_jacobians, sole_drifts, wrench_maps: per foot, J_k (6, nv), J̇_k ξ̇ (6,) and
            R̃ U_k (6, m N_c).
        signals: the controller's signal record, shape (1,): a structured array with the
            fields of :data:`TICK_SIGNALS` and ``left``, ``right`` of :data:`FOOT_SIGNALS`
            (others are the controller's to write).
    """

    tasks: CentroidalTasks
    sole_jacobians: np.ndarray
    sole_drifts: np.ndarray
    wrench_maps: np.ndarray
    signals: np.ndarray


class DesiredMotion(NamedTuple):
    """Desired coordinates, their rates and accelerations, each of shape (3,).

    Attributes:
        position: x_d.
        velocity: ẋ_d.
        acceleration: ẍ_d.
    """

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


#: Everything :func:`task_rows` reads and writes besides the readings, as one argument (a
#: StructRef: numba reads its type from the object, where it would type named tuples field by
#: field in Python at every call, ≈ 15 µs here): ``terms`` (:class:`RobotTerms`), ``params``
#: (:class:`TaskParams`), ``state`` (:class:`TaskState`), ``outputs`` (:class:`TaskOutputs`).
TaskRecordsType, TaskRecords = define_record(
    "TaskRecords", ("terms", "params", "state", "outputs"), __name__
)


@numba.njit(cache=True)
def task_records(
    terms: RobotTerms, params: TaskParams, state: TaskState, outputs: TaskOutputs
) -> TaskRecords:
    """The :class:`TaskRecords` of these records (compiled and cached)."""
    return TaskRecords(terms, params, state, outputs)


def kinematic_chain(model: pin.Model, frame_id: int) -> np.ndarray:
    """Which velocities move a frame: those of its parent joint and the joints supporting it.

    Returns:
        Shape (nv,) bool: the columns Pinocchio's ``getFrameJacobian`` fills.
    """
    chain = np.zeros(model.nv, dtype=bool)
    for joint in list(model.supports[model.frames[frame_id].parentJoint]):
        if joint == UNIVERSE:
            continue
        start = model.joints[joint].idx_v
        chain[start : start + model.joints[joint].nv] = True
    return chain


@numba.njit(cache=True)
def matrix_to_rpy(rotation: np.ndarray, rpy: np.ndarray) -> None:
    """``pin.rpy.matrixToRpy``: roll, pitch, yaw [rad] with R = R_z(yaw) R_y(pitch) R_x(roll).

    Eigen's ``eulerAngles(2, 1, 0)`` (Graphics Gems IV) reversed, then Pinocchio's fold of
    the pitch into [−π/2, π/2], in the same operations (tested against it to 1e-12).

    Args:
        rotation: R, shape (3, 3).
        rpy: out, (roll, pitch, yaw) [rad], shape (3,).
    """
    r = rotation
    yaw = math.atan2(r[Y, X], r[X, X])
    c2 = math.sqrt(r[Z, Z] * r[Z, Z] + r[Z, Y] * r[Z, Y])
    if yaw < 0.0:
        yaw += math.pi
        pitch = math.atan2(-r[Z, X], -c2)
    else:
        pitch = math.atan2(-r[Z, X], c2)
    s1, c1 = math.sin(yaw), math.cos(yaw)
    roll = math.atan2(s1 * r[X, Z] - c1 * r[Y, Z], c1 * r[Y, Y] - s1 * r[X, Y])
    if pitch < -math.pi / 2:
        pitch += 2 * math.pi
    if pitch > math.pi / 2:
        pitch = math.pi - pitch
        roll = roll + math.pi if roll < 0.0 else roll - math.pi
        yaw -= math.pi
    rpy[ROLL], rpy[PITCH], rpy[YAW] = roll, pitch, yaw


@numba.njit(cache=True)
def quintic(s: float, duration: float) -> tuple[float, float, float]:
    """Minimum-jerk blend b(s) = u³ (10 − 15 u + 6 u²), u = s / duration clipped to [0, 1],
    with ḃ [1/s] and b̈ [1/s²] (zero velocity and acceleration at both ends; 1, 0, 0 for a
    non-positive duration)."""
    if duration <= 0:
        return 1.0, 0.0, 0.0
    u = min(max(s / duration, 0.0), 1.0)
    # Float exponents: the same libm pow() as Python's float ** int (not repeated products).
    b = u**3.0 * (10 - 15 * u + 6 * u**2.0)
    db = 30 * u**2.0 * (1 - u) ** 2.0 / duration
    ddb = 60 * u * (1 - u) * (1 - 2 * u) / duration**2.0
    return b, db, ddb


def pack_swing(
    t0: float,
    duration: float,
    start: np.ndarray,
    target: np.ndarray,
    apex: float,
    rise_fraction: float,
    out: np.ndarray,
) -> None:
    """Write a swing trajectory into ``out``, shape (1,) of :data:`SWING_PLAN` (its fields
    are these arguments: t0 [s], duration [s], start and target (5,), apex [m],
    rise_fraction [-])."""
    plan = out[0]
    plan["t0"], plan["duration"] = t0, duration
    plan["start"], plan["target"] = start, target
    plan["apex"], plan["rise_fraction"] = apex, rise_fraction


@numba.njit(cache=True)
def swing_reference(
    swing: np.ndarray, t: float, pos: np.ndarray, vel: np.ndarray, acc: np.ndarray
) -> None:
    """The swing-foot sole-centre reference at ``t``, from lift-off to the planned landing.

    x, y and the roll/pitch angles blend from ``start`` to ``target`` by minimum jerk
    (:func:`quintic`) over the whole swing; z rises from the lift-off height to ``apex``
    above the higher of start and target over the first ``rise_fraction`` of the swing,
    then descends to the landing height by the end.

    Args:
        swing: the trajectory, shape (1,) of :data:`SWING_PLAN` (see :func:`pack_swing`).
        t: time [s].
        pos, vel, acc: out, desired (x, y, z, roll, pitch), rates and accelerations, (5,).
    """
    plan = swing[0]
    t0, duration, apex, rise_fraction = plan.t0, plan.duration, plan.apex, plan.rise_fraction
    start, target = plan.start, plan.target
    s = t - t0
    b, db, ddb = quintic(s, duration)
    for i in range(5):
        delta = target[i] - start[i]
        pos[i] = start[i] + b * delta
        vel[i] = db * delta
        acc[i] = ddb * delta
    top = max(start[SWING_Z], target[SWING_Z]) + apex
    t_rise = rise_fraction * duration
    if s < t_rise:
        bz, dbz, ddbz = quintic(s, t_rise)
        z0, z1 = start[SWING_Z], top
    else:
        bz, dbz, ddbz = quintic(s - t_rise, duration - t_rise)
        z0, z1 = top, target[SWING_Z]
    pos[SWING_Z] = z0 + bz * (z1 - z0)
    vel[SWING_Z] = dbz * (z1 - z0)
    acc[SWING_Z] = ddbz * (z1 - z0)


@numba.njit(cache=True)
def advance_impedance(
    state: np.void,
    desired: DesiredMotion,
    wrench: np.ndarray,
    gains: ImpedanceGains,
    dt: float,
    enabled: bool,
) -> bool:
    """Impedance modification of the swing-foot reference (§II, Eqs. 1–3).

    The foot is modelled as a mass–spring–damper driven by the contact wrench (Fig. 2):

        M_d (ẍ − ẍ_d) + B_d (ẋ − ẋ_d) + K_d (x − x_d) = λ,                          (1)

    over the coordinates x = (z, φ_x, φ_y) of the paper's x_{C_k} = [0 0 z φx φy 0]ᵀ. The
    modified acceleration

        ẍ_m = ẍ_d + M_d⁻¹ (λ + B_d ė + K_d e),   e = x_d − x_m,                     (2)

    is integrated (semi-implicit Euler) to the modified velocity and position. Eq. (2) writes
    e with the foot's state; we use the modified state x_m, which equals the foot's state when
    the QP tracks Eq. (3), and makes the modified reference an exact mass–spring–damper of λ
    (no feedback of tracking noise into the integrator). The reference acceleration for the QP
    is Eq. (3):

        ẍ_r = ẍ_m + K_v (ẋ_m − ẋ) + K_p (x_m − x).                                  (3)

    The modification switches on in swing, once the foot has been unloaded after lift-off,
    when |λ_z| exceeds the force threshold or |λ_φx|, |λ_φy| the torque threshold (§IV:
    10 N, 3 N m), stays on to the end of that swing, and is re-initialised (x_m = x_d) in
    support (§IV).

    ``tests/test_qpimpedance_impedance.py`` tests its properties (the closed-form response
    of Eq. 1, the thresholds, lift-off, switch-on, the run without impedance).

    Args:
        state: the foot's record of :data:`IMPEDANCE_STATE` (x_m, ẋ_m, ẍ_m, armed,
            active), updated in place.
        desired: desired (z [m], φ_x, φ_y [rad]), rates and accelerations.
        wrench: contact wrench λ = (f_z [N], μ_x [N m], μ_y [N m]).
        gains: M_d, B_d, K_d and the switch-on thresholds.
        dt: control period [s].
        enabled: False runs without impedance (the modified reference is the desired one).

    Returns:
        Whether the modification switched on this tick.
    """
    x_d, v_d, a_d = desired.position, desired.velocity, desired.acceleration
    over = False
    for i in range(3):
        if abs(wrench[i]) > gains.threshold[i]:
            over = True
    if not state.armed and not over:
        state.armed = True  # the foot has left the ground: a new contact is unexpected
    switched_on = False
    if enabled and state.armed and not state.active and over:
        state.active = switched_on = True  # start from the desired state: continuous reference
        state.position[:] = x_d
        state.velocity[:] = v_d
    if not state.active:
        state.position[:] = x_d
        state.velocity[:] = v_d
        state.acceleration[:] = a_d
        return False
    x_m, v_m, a_m = state.position, state.velocity, state.acceleration
    for i in range(3):
        e = x_d[i] - x_m[i]
        e_dot = v_d[i] - v_m[i]
        a_m[i] = (
            a_d[i] + (wrench[i] + gains.damping[i] * e_dot + gains.stiffness[i] * e) / gains.mass[i]
        )
        v_m[i] += a_m[i] * dt
        x_m[i] += v_m[i] * dt
    return switched_on


@numba.njit(cache=True)
def contact_wrench(
    ft: np.ndarray,
    site_rotation: np.ndarray,
    site_position: np.ndarray,
    foot_com: np.ndarray,
    sole_position: np.ndarray,
    foot_acc: np.ndarray,
    foot_mass: float,
) -> tuple[float, float, float]:
    """Contact wrench on a foot from its F/T reading: (f_z [N], μ_x, μ_y [N m]), world axes.

    The sensor reads the foot-on-leg wrench, which includes the weight and inertia of the
    foot below it (≈ 14 N). Newton–Euler of that foot body: f_c = f_s + m (g ẑ + a),
    μ_c = μ_s − r_c × m (g_vec − a) about the sensor, then moved to the sole centre.

    Args:
        ft: the F/T reading (force, torque) in the sensor frame, shape (6,).
        site_rotation: world-from-sensor rotation, shape (3, 3).
        site_position: sensor origin in the world [m], shape (3,).
        foot_com: centre of mass of the foot body in the world [m], shape (3,).
        sole_position: sole centre in the world [m], shape (3,).
        foot_acc: the foot's commanded acceleration a [m/s²], shape (3,).
        foot_mass: mass of the foot body m [kg].
    """
    f = np.empty(3)
    s = np.empty(3)
    for i in range(3):  # sensor axes -> world axes
        f[i] = (
            site_rotation[i, X] * ft[X] + site_rotation[i, Y] * ft[Y] + site_rotation[i, Z] * ft[Z]
        )
        s[i] = (
            site_rotation[i, X] * ft[RX]
            + site_rotation[i, Y] * ft[RY]
            + site_rotation[i, Z] * ft[RZ]
        )
    m = foot_mass
    a0, a1, a2 = foot_acc[X], foot_acc[Y], foot_acc[Z]
    p0, p1, p2 = site_position[X], site_position[Y], site_position[Z]
    # f_c = f_s − m g_vec + m a, with g_vec = (0, 0, −g).
    fc0, fc1, fc2 = f[X] + m * a0, f[Y] + m * a1, f[Z] + m * GRAVITY + m * a2
    r0, r1, r2 = foot_com[X] - p0, foot_com[Y] - p1, foot_com[Z] - p2  # foot CoM from sensor
    h0, h1, h2 = -m * a0, -m * a1, m * (-GRAVITY - a2)  # m (g_vec − a)
    mc0 = s[X] - (r1 * h2 - r2 * h1)
    mc1 = s[Y] - (r2 * h0 - r0 * h2)
    d0, d1, d2 = p0 - sole_position[X], p1 - sole_position[Y], p2 - sole_position[Z]
    return fc2, mc0 + (d1 * fc2 - d2 * fc1), mc1 + (d2 * fc0 - d0 * fc2)


@numba.njit(cache=True)
def desired_com(
    com_plan: np.ndarray,
    t: float,
    preview_dt: float,
    plan_end: float,
    com_z: float,
    pos: np.ndarray,
    vel: np.ndarray,
    acc: np.ndarray,
) -> None:
    """CoM position, velocity, acceleration of the preview pattern at ``t`` [m, m/s, m/s²].

    Linear between the pattern's samples; after the plan, its last position at rest.

    Args:
        com_plan: the preview pattern's samples, shape (N,) of :data:`COM_SAMPLE`.
        t: time [s].
        preview_dt: sample time of the pattern [s].
        plan_end: time the plan ends [s].
        com_z: desired CoM height [m].
        pos, vel, acc: out, shape (3,).
    """
    n = com_plan.shape[X]
    if t >= plan_end:
        final = n - 1
        last = com_plan[final].position
        pos[X], pos[Y], pos[Z] = last[X], last[Y], com_z
        vel[:] = 0.0
        acc[:] = 0.0
        return
    k = t / preview_dt
    i = int(min(max(np.floor(k), 0.0), n - 2))
    a = min(max(k - i, 0.0), 1.0)
    after = i + 1
    before, after = com_plan[i], com_plan[after]
    for axis in (X, Y):
        pos[axis] = (1 - a) * before.position[axis] + a * after.position[axis]
        vel[axis] = (1 - a) * before.velocity[axis] + a * after.velocity[axis]
        acc[axis] = (1 - a) * before.acceleration[axis] + a * after.acceleration[axis]
    pos[Z], vel[Z], acc[Z] = com_z, 0.0, 0.0


@numba.njit(cache=True)
def _write_references(foot: np.void, refs: np.ndarray) -> None:
    """A foot's reference signals (:data:`FOOT_SIGNALS`) from ``refs``: rows x_d, ẋ_d, ẍ_d,
    x_m, ẋ_m, ẍ_m (:data:`DESIRED_POS` …), columns (z [m], φ_x, φ_y [rad]) and their rates."""
    z, roll, pitch = X, Y, Z  # the columns of refs: the impedance coordinates
    foot.z_d, foot.roll_d, foot.pitch_d = (
        refs[DESIRED_POS, z],
        refs[DESIRED_POS, roll],
        refs[DESIRED_POS, pitch],
    )
    foot.z_dot_d, foot.roll_dot_d, foot.pitch_dot_d = (
        refs[DESIRED_VEL, z],
        refs[DESIRED_VEL, roll],
        refs[DESIRED_VEL, pitch],
    )
    foot.z_ddot_d, foot.roll_ddot_d, foot.pitch_ddot_d = (
        refs[DESIRED_ACC, z],
        refs[DESIRED_ACC, roll],
        refs[DESIRED_ACC, pitch],
    )
    foot.z_m, foot.roll_m, foot.pitch_m = (
        refs[MODIFIED_POS, z],
        refs[MODIFIED_POS, roll],
        refs[MODIFIED_POS, pitch],
    )
    foot.z_dot_m, foot.roll_dot_m, foot.pitch_dot_m = (
        refs[MODIFIED_VEL, z],
        refs[MODIFIED_VEL, roll],
        refs[MODIFIED_VEL, pitch],
    )
    foot.z_ddot_m, foot.roll_ddot_m, foot.pitch_ddot_m = refs[MODIFIED_ACC, z], refs[MODIFIED_ACC, roll], refs[MODIFIED_ACC, pitch]  # fmt: skip


@numba.njit(cache=True)
def momentum_target(
    t: float, terms: RobotTerms, params: TaskParams, b_1: np.ndarray, c_d: np.ndarray
) -> None:
    """b_1 = X_GBᵀ ḣ_{G,r} − C_B ξ̇ (Eq. 7), with the momentum rate reference of §III-D
    ḣ_lin = m (c̈_d + K_h (ċ_d − ċ) + K_I (c_d − c)) and ḣ_ang = −K_h k (about the CoM), moved
    to the base origin; both halves in the base frame [N, N m].

    Args:
        t: time [s].
        terms: Pinocchio's terms of the tick.
        params: the tick's parameters (gains, the CoM pattern).
        b_1: out, shape (6,).
        c_d: out, the desired CoM [m], shape (3,).
    """
    tick = params.tick
    com, com_vel, base_rotation = terms.com, terms.com_vel, terms.base_rotation
    v_d, a_d = np.empty(3), np.empty(3)
    desired_com(params.com_plan, t, tick.preview_dt, tick.plan_end, tick.com_z, c_d, v_d, a_d)
    m, kh, ki = tick.mass, tick.k_h, tick.k_i
    # ḣ_lin = m (c̈_d + K_h (ċ_d − ċ) + K_I (c_d − c)), with ∫(h_d − h) = m (c_d − c).
    lin = np.empty(3)
    for i in range(3):
        lin[i] = m * (a_d[i] + kh * (v_d[i] - com_vel[i]) + ki * (c_d[i] - com[i]))
    r = com - terms.base_position  # the CoM from the base origin [m]
    k, kh_ang = terms.angular_momentum, tick.k_h_angular
    ang = np.empty(3)  # ḣ_ang + (c − p_B) × ḣ_lin, with ḣ_ang = −K_h k
    ang[X] = -kh_ang * k[X] + (r[Y] * lin[Z] - r[Z] * lin[Y])
    ang[Y] = -kh_ang * k[Y] + (r[Z] * lin[X] - r[X] * lin[Z])
    ang[Z] = -kh_ang * k[Z] + (r[X] * lin[Y] - r[Y] * lin[X])
    # Both halves in the base frame, minus (C ξ̇)_B = (nle − g)_B.
    bias = terms.nonlinear - terms.gravity_torques
    for i in range(3):
        h_lin = base_rotation[X, i] * lin[X] + base_rotation[Y, i] * lin[Y]
        h_lin += base_rotation[Z, i] * lin[Z]
        h_ang = base_rotation[X, i] * ang[X] + base_rotation[Y, i] * ang[Y]
        h_ang += base_rotation[Z, i] * ang[Z]
        b_1[LINEAR_ROW + i] = h_lin - bias[LINEAR_ROW + i]
        b_1[ANGULAR_ROW + i] = h_ang - bias[ANGULAR_ROW + i]


@numba.njit(cache=True)
def _sole_terms(
    side: int,
    records: TaskRecords,
    site_rot: np.ndarray,
    site_pos: np.ndarray,
    foot_com: np.ndarray,
) -> np.ndarray:
    """A sole's J_k, J̇_k ξ̇, R̃ U_k (into the outputs), its F/T sensor's and foot CoM's world
    placements (into ``site_rot``, ``site_pos``, ``foot_com``); returns its spatial velocity."""
    terms, params, outputs = records.terms, records.params, records.outputs
    sole = terms.frames[side]
    rot, pos, velocity = sole.rotation, sole.position, terms.velocity
    sole_jac = outputs.sole_jacobians[side]
    frame_jacobian(terms.joint_jacobians, sole.chain, pos, sole_jac)
    frame_classical_acceleration(
        sole.joint_rotation, sole.joint_velocity, sole.joint_drift, sole.offset,
        outputs.sole_drifts[side],
    )  # fmt: skip
    # R̃ U_k: both halves (forces, moments) of the contact-frame basis rotated.
    local, maps = params.local_wrench_map, outputs.wrench_maps[side]
    for half in (LINEAR_ROW, ANGULAR_ROW):
        for i in range(3):
            for c in range(local.shape[1]):
                s = 0.0
                for k in range(3):
                    s += rot[i, k] * local[half + k, c]
                maps[half + i, c] = s
    # Sensor and foot-CoM placements from the sole's (all on the ankle's body).
    for i in range(3):
        site_pos[i] = pos[i]
        foot_com[i] = pos[i]
        for k in range(3):
            site_pos[i] += rot[i, k] * params.sole_site_position[side, k]
            foot_com[i] += rot[i, k] * params.sole_foot_com[side, k]
            s = 0.0
            for j in range(3):
                s += rot[i, j] * params.sole_site_rotation[side, j, k]
            site_rot[i, k] = s
    vel = np.empty(6)
    for i in range(6):
        s = 0.0
        for j in range(velocity.shape[0]):
            s += sole_jac[i, j] * velocity[j]
        vel[i] = s
    return vel


@numba.njit(cache=True)
def _foot_state(
    side: int, t: float, swing: int, ft: np.ndarray, foot: np.void, records: TaskRecords
) -> bool:
    """A foot's sole terms, measured contact wrench, signals and impedance (Eqs. 1–2); for
    the swing foot, its desired motion (``state.swing_motion``). Returns whether its
    impedance modification switched on."""
    terms, params, state = records.terms, records.params, records.state
    tick, sole = params.tick, terms.frames[side]
    site_rot, site_pos, foot_com, rpy = np.empty((3, 3)), np.empty(3), np.empty(3), np.empty(3)
    vel = _sole_terms(side, records, site_rot, site_pos, foot_com)
    acc_meas = (vel - state.prev_foot_vel[side]) / tick.dt
    state.prev_foot_vel[side] = vel
    pos = sole.position
    fz, mx, my = contact_wrench(
        ft, site_rot, site_pos, foot_com, pos, state.foot_acc_cmd[side], tick.foot_mass
    )
    matrix_to_rpy(sole.rotation, rpy)
    foot.fz, foot.mx, foot.my = fz, mx, my
    foot.x, foot.z, foot.roll, foot.pitch = pos[X], pos[Z], rpy[ROLL], rpy[PITCH]
    foot.vz, foot.wx, foot.wy = vel[Z], vel[RX], vel[RY]
    foot.az, foot.alphax, foot.alphay = acc_meas[Z], acc_meas[RX], acc_meas[RY]
    foot_state = state.impedance[side]
    refs = np.zeros((6, 3))  # x_d, ẋ_d, ẍ_d, x_m, ẋ_m, ẍ_m of (z, φ_x, φ_y)
    if side != swing:
        # Support: re-initialise the impedance at the foot's state (§IV), no command.
        foot_state.armed = foot_state.active = False
        x_m = foot_state.position
        x_m[X], x_m[Y], x_m[Z] = pos[Z], rpy[ROLL], rpy[PITCH]
        foot_state.velocity[:] = 0.0
        foot_state.acceleration[:] = 0.0
        state.foot_acc_cmd[side] = 0.0
        foot.impedance_on = 0.0
        # The references of a support foot: at its planned height, at rest, level.
        refs[DESIRED_POS, X] = refs[MODIFIED_POS, X] = state.stance_z[side]
        _write_references(foot, refs)
        return False
    pos_d, vel_d, acc_d = np.empty(5), np.empty(5), np.empty(5)
    swing_reference(state.swing_plan, t, pos_d, vel_d, acc_d)
    desired = DesiredMotion(
        pos_d[IMPEDANCE_COORDS], vel_d[IMPEDANCE_COORDS], acc_d[IMPEDANCE_COORDS]
    )
    wrench = np.array((fz, mx, my))
    switched_on = advance_impedance(
        foot_state, desired, wrench, params.impedance_gains, tick.dt, tick.impedance
    )
    foot.impedance_on = 1.0 if foot_state.active else 0.0
    # The swing task's desired motion: x, y and yaw follow the plan (yaw 0), (z, φx, φy)
    # the modified reference x_m, ẋ_m, ẍ_m.
    motion = state.swing_motion
    motion[:] = 0.0
    for row, plan, modified in (
        (POSITION, pos_d, foot_state.position),
        (VELOCITY, vel_d, foot_state.velocity),
        (ACCELERATION, acc_d, foot_state.acceleration),
    ):
        motion[row, X], motion[row, Y] = plan[SWING_X], plan[SWING_Y]
        motion[row, Z], motion[row, RX], motion[row, RY] = modified[X], modified[Y], modified[Z]
    refs[DESIRED_POS], refs[DESIRED_VEL], refs[DESIRED_ACC] = desired
    refs[MODIFIED_POS], refs[MODIFIED_VEL] = foot_state.position, foot_state.velocity
    refs[MODIFIED_ACC] = foot_state.acceleration
    _write_references(foot, refs)
    return switched_on


@numba.njit(cache=True)
def _frame_motion(
    spec: np.void,
    swing: int,
    records: TaskRecords,
    jac: np.ndarray,
    motion: np.ndarray,
    actual: np.ndarray,
    drift: np.ndarray,
) -> None:
    """A frame task's Φ_t (``jac``), Φ̇_t ξ̇ (``drift``), desired motion (rows POSITION,
    VELOCITY, ACCELERATION) and actual (x, ẋ) on the six spatial axes (compute_jacobian,
    compute_error); an orientation's x is log₃ R, its x_d = 0 (R_d = I)."""
    terms, outputs = records.terms, records.outputs
    velocity = terms.velocity
    if spec.kind == TaskKind.SWING_FOOT:
        sole = terms.frames[swing]
        jac[:] = outputs.sole_jacobians[swing]
        drift[:] = outputs.sole_drifts[swing]
        motion[:] = records.state.swing_motion
        rpy = np.empty(3)
        matrix_to_rpy(sole.rotation, rpy)
        for i in range(3):
            actual[POSITION, LINEAR_ROW + i] = sole.position[i]
            actual[POSITION, ANGULAR_ROW + i] = rpy[i]
    else:  # ORIENTATION
        frame = terms.frames[spec.frame]
        frame_jacobian(terms.joint_jacobians, frame.chain, frame.position, jac)
        frame_classical_acceleration(
            frame.joint_rotation, frame.joint_velocity, frame.joint_drift, frame.offset, drift
        )
        motion[:] = 0.0
        actual[POSITION] = 0.0
        log3(frame.rotation, actual[POSITION, ANGULAR_ROW:])
    for i in range(jac.shape[0]):
        s = 0.0
        for j in range(velocity.shape[0]):
            s += jac[i, j] * velocity[j]
        actual[VELOCITY, i] = s


@numba.njit(cache=True)
def reference_acceleration(
    kp: float, kv: float, x_d: float, v_d: float, a_d: float, x: float, v: float
) -> float:
    """ẍ_r = ẍ_d + K_V (ẋ_d − ẋ) + K_P (x_d − x) (Eq. 3, and every task of §III-D)."""
    return a_d + kv * (v_d - v) + kp * (x_d - x)


@numba.njit(cache=True)
def stack_tasks(swing: int, readings: SensorReadings, records: TaskRecords) -> int:
    """Stack the declared tasks (``params.tasks``) into the rows √W … of the QP's task term:
    for each task in order, its selected rows of Φ_t, b_t = ẍ_r − Φ̇_t ξ̇ and W_t, from the next
    free row (its first row is written to ``stack.first_row``; −1 when inactive: a swing-foot
    task in double support). Writes the swing foot's commanded linear acceleration.

    Returns:
        The number of rows stacked (also ``stack.rows``).
    """
    params, state = records.params, records.state
    stack, specs = records.outputs.tasks.stack, params.tasks
    nv = records.terms.velocity.shape[0]
    jac, drift = np.empty((6, nv)), np.empty(6)
    motion, actual, acc_ref = np.empty((3, 6)), np.empty((2, 6)), np.empty(6)
    row = 0
    for k in range(specs.shape[0]):
        spec = specs[k]
        kp, kv = spec.kp, spec.kv
        if spec.kind == TaskKind.SWING_FOOT and swing < 0:
            stack.first_row[k] = -1
            continue
        stack.first_row[k] = row
        if spec.kind == TaskKind.POSTURE:  # Φ_t selects each joint (Φ̇_t = 0), x_d = q_home
            q, qd, home = readings.joint_pos, readings.joint_vel, params.home_joint_pos
            for joint in range(q.shape[0]):
                if spec.joints[joint]:
                    stack.jacobian[row] = 0.0
                    stack.jacobian[row, params.joint_v_index[joint]] = 1.0
                    acc = reference_acceleration(kp, kv, home[joint], 0.0, 0.0, q[joint], qd[joint])
                    stack.target[row], stack.weight[row] = acc, spec.weight
                    row += 1
            continue
        _frame_motion(spec, swing, records, jac, motion, actual, drift)
        for i in range(6):
            acc_ref[i] = reference_acceleration(
                kp, kv, motion[POSITION, i], motion[VELOCITY, i], motion[ACCELERATION, i],
                actual[POSITION, i], actual[VELOCITY, i],
            )  # fmt: skip
            if spec.axes[i]:
                stack.jacobian[row] = jac[i]
                stack.target[row], stack.weight[row] = acc_ref[i] - drift[i], spec.weight
                row += 1
        if spec.kind == TaskKind.SWING_FOOT:
            for i in range(3):
                state.foot_acc_cmd[swing, i] = acc_ref[LINEAR_ROW + i]
    stack.rows[0] = row
    return row


@numba.njit(cache=True)
def task_rows(t: float, swing: int, readings: SensorReadings, records: TaskRecords) -> int:
    """One tick's QP cost terms (§III-D), foot states, contact wrenches and impedance (Eqs. 1–3).

    Args:
        t: time [s].
        swing: the swing foot (0 left, 1 right), or −1 in double support.
        readings: the joint encoders and each foot's F/T reading.
        records: (:class:`TaskRecords`) Pinocchio's terms of the tick and ξ̇; the parameters
            (set at reset); the state (updated in place); the outputs: b_1, the stacked task
            rows, each foot's J_k, J̇_k ξ̇ and R̃ U_k, and the signals.

    Returns:
        A bit per foot (1 left, 2 right) whose impedance modification switched on this tick.
    """
    terms, outputs = records.terms, records.outputs
    signals = outputs.signals[0]
    c_d = np.empty(3)
    momentum_target(t, terms, records.params, outputs.tasks.momentum_target, c_d)
    signals.t_plan, signals.swing_foot = t, float(swing)
    switched_on = 0
    if _foot_state(LEFT, t, swing, readings.left_ft, signals.left, records):
        switched_on |= 1 << LEFT
    if _foot_state(RIGHT, t, swing, readings.right_ft, signals.right, records):
        switched_on |= 1 << RIGHT
    stack_tasks(swing, readings, records)
    com = terms.com
    signals.com_x, signals.com_y, signals.com_z = com[X], com[Y], com[Z]
    signals.com_x_d, signals.com_y_d, signals.com_z_d = c_d[X], c_d[Y], c_d[Z]
    return switched_on
