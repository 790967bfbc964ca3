"""The per-tick task algebra of §III-D in one compiled call: cost rows, contact terms, impedance.

Each tick the controller turns Pinocchio's quantities and the sensor readings into

- the QP's cost terms, named as in the paper (:class:`.centroidal_qp.CentroidalTasks`): the
  centroidal momentum target b_1 (Eq. 7), and each task's Φ_t and b_t = ẍ_r − Φ̇_t ξ̇: pelvis
  and torso orientation, arm and waist posture, swing foot (Eq. 3);
- each foot's sole Jacobian, drift J̇ ξ̇ and rotated wrench basis R̃ U_k (Eq. 8), which the
  QP takes for the support feet;
- each foot's contact wrench from its F/T sensor and the impedance modification of the
  swing reference (Eqs. 1–3), with the signals the log records.

Why numba: written in Python this is ≈ 70 small numpy calls and Python-float expressions on
3- to 28-vectors, ≈ 65 µs of the ≈ 200 µs a 1 kHz tick may take at 5× real time (numpy
costs about 1 µs per call on such small arrays). One compiled call, :func:`task_rows`, does
the same arithmetic, in the same order, in a few µs. Its inputs are views of Pinocchio's
``Data`` after ``computeAllTerms`` (M, C ξ̇ + g, the joint Jacobians, frame and joint
placements, the joints' velocities and drift accelerations), passed without copies. The
frames' drifts J̇ ξ̇, log₃ and roll–pitch–yaw angles are formed here
(:func:`~walkrepro.sim.robot.frame_classical_acceleration`, :func:`~walkrepro.sim.robot.log3`,
:func:`matrix_to_rpy`) in Pinocchio's operations, tested against its Python functions to
1e-12, instead of eight calls from Python (≈ 0.4–1 µs each;
``benchmarks/pinocchio_ports.py``). The small kernels it calls are compiled functions too,
each tested against a reference (Pinocchio's frame Jacobians, numpy expressions) or for its
properties (the swing trajectory, the impedance filter). Like
:mod:`.condensed`, the kernels are cached on disk (``cache=True``) and compiled or loaded
when the controller resets.

:func:`task_rows` takes its inputs in records of named fields (named tuples,
:class:`RobotTerms` … :class:`TaskOutputs`), which the controller builds once at reset and
gathers into one :class:`TaskRecords` (a numba StructRef: numba reads its type from the
object, where it would type a named tuple's fields one by one in Python on every call); the
arrays in them are filled in place every tick; the gains and times are a record of floats
(:class:`TaskGains`). The signals it writes are fields of a structured record
(:data:`FOOT_SIGNALS` per foot), named as in the log.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
import pinocchio as pin
from numba.core import types
from numba.experimental import structref

from walkrepro.papers.jo_oh.centroidal_qp import CentroidalTasks, Task
from walkrepro.sim.robot import eigen_rotate, frame_classical_acceleration, frame_jacobian, log3

GRAVITY = 9.81  # [m/s^2]


class TaskGains(NamedTuple):
    """The tick's gains, masses and times, set at reset.

    Attributes:
        dt: control period [s].
        mass: robot mass m [kg].
        foot_mass: mass of the foot below the F/T sensor [kg].
        k_h: linear momentum gain K_h [1/s].
        k_i: linear momentum integral gain K_I [1/s²].
        k_h_angular: angular momentum gain [1/s].
        kp_orient, kv_orient: pelvis and torso K_P [1/s²], K_V [1/s].
        kp_posture, kv_posture: arm and waist K_P [1/s²], K_V [1/s].
        kp_swing, kv_swing: swing-foot K_P [1/s²], K_V [1/s] (Eq. 3).
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
    kp_orient: float
    kv_orient: float
    kp_posture: float
    kv_posture: float
    kp_swing: float
    kv_swing: float
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


class FrameChains(NamedTuple):
    """Which velocities move each frame whose Jacobian :func:`task_rows` forms (see
    :func:`kinematic_chain`), each of shape (nv,) bool.

    Attributes:
        left_sole, right_sole: the soles (contact and swing rows).
        pelvis, torso: the orientation tasks' frames.
    """

    left_sole: np.ndarray
    right_sole: np.ndarray
    pelvis: np.ndarray
    torso: np.ndarray


class SoleKinematics(NamedTuple):
    """A sole frame's placement and its parent joint's motion, from Pinocchio's ``Data``.

    Attributes:
        rotation, position: world placement of the sole frame (``data.oMf``) [-, m].
        joint_rotation: its parent joint's world rotation (``data.oMi[j].rotation``).
        joint_velocity: its parent joint's spatial velocity, joint axes (``data.v[j]``).
        joint_drift: its parent joint's drift acceleration, joint axes (``data.a[j]``).
    """

    rotation: np.ndarray
    position: np.ndarray
    joint_rotation: np.ndarray
    joint_velocity: np.ndarray
    joint_drift: np.ndarray


class RobotTerms(NamedTuple):
    """Pinocchio's terms of the tick (after ``computeAllTerms`` and ``updateFramePlacements``;
    the drifts J̇ ξ̇ follow from the joints' ``data.v``, ``data.a`` by
    :func:`~walkrepro.sim.robot.frame_classical_acceleration`), and ξ̇.

    Attributes:
        joint_jacobians: ``data.J``, shape (6, nv).
        mass_matrix: M (``data.M``), shape (nv, nv).
        nonlinear: C ξ̇ + g (``data.nle``), shape (nv,).
        gravity_torques: g (``data.g``), shape (nv,).
        com, com_vel: CoM position [m] and velocity [m/s] in the world, shape (3,).
        angular_momentum: k, the angular part of h_G [kg m²/s], shape (3,).
        base_rotation, base_position: world-from-base placement (``data.oMi[1]``), which
            is also the pelvis frame's parent joint.
        base_drift: the base joint's drift acceleration (``data.a[1].vector``), shape (6,).
        pelvis_rotation, torso_rotation: the frame's world rotation (``data.oMf``).
        torso_joint_rotation, torso_joint_drift: the torso frame's parent joint's world
            rotation and drift acceleration (``data.oMi[j].rotation``, ``data.a[j].vector``).
        left, right: the soles.
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
    base_drift: np.ndarray
    pelvis_rotation: np.ndarray
    torso_rotation: np.ndarray
    torso_joint_rotation: np.ndarray
    torso_joint_drift: np.ndarray
    left: SoleKinematics
    right: SoleKinematics
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


class TaskConstants(NamedTuple):
    """Gains, weights and the robot's geometry, set at reset.

    Attributes:
        gains: gains, masses and times.
        impedance_gains: M_d, B_d, K_d and thresholds (see :func:`advance_impedance`).
        chains: per frame, whether each velocity moves it.
        posture_idx: actuator indices of the arm and waist joints.
        sole_site_rotation, sole_site_position: each F/T sensor's placement in its sole
            frame, shapes (2, 3, 3) and (2, 3) [-, m].
        sole_foot_com: each foot body's centre of mass in its sole frame, shape (2, 3) [m].
        sole_offset: each sole frame's origin in its parent joint's frame [m], shape (2, 3).
        local_wrench_map: U_k in the contact frame (Eq. 8), shape (6, m N_c).
    """

    gains: TaskGains
    impedance_gains: ImpedanceGains
    chains: FrameChains
    posture_idx: np.ndarray
    sole_site_rotation: np.ndarray
    sole_site_position: np.ndarray
    sole_foot_com: np.ndarray
    sole_offset: np.ndarray
    local_wrench_map: np.ndarray


class TaskReferences(NamedTuple):
    """The walking pattern the tasks track: set at reset, the swing at each phase's start.

    Attributes:
        com_plan: the preview CoM pattern, shape (N,) of :data:`COM_SAMPLE`.
        swing_plan: this phase's swing trajectory, shape (1,) of :data:`SWING_PLAN`.
        stance_z: each foot's planned stance height [m], shape (2,).
        posture_home: home angles of the arm and waist joints [rad] (``posture_idx``).
    """

    com_plan: np.ndarray
    swing_plan: np.ndarray
    stance_z: np.ndarray
    posture_home: np.ndarray


class TaskState(NamedTuple):
    """Each foot's state carried from tick to tick, updated in place.

    Attributes:
        impedance: each foot's impedance state, shape (2,) of :data:`IMPEDANCE_STATE`.
        prev_foot_vel: each sole's spatial velocity of the previous tick, shape (2, 6).
        foot_acc_cmd: each sole's commanded linear acceleration [m/s²], shape (2, 3).
    """

    impedance: np.ndarray
    prev_foot_vel: np.ndarray
    foot_acc_cmd: np.ndarray


class TaskOutputs(NamedTuple):
    """What :func:`task_rows` writes each tick.

    Attributes:
        tasks: the QP's cost terms: b_1, and each task's Φ_t and b_t (the posture's Φ_t is
            a constant selection, set at reset, and the weights are constants).
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


class RowGains(NamedTuple):
    """A task's gains in ẍ_r = ẍ_d + K_V (ẋ_d − ẋ) + K_P (x_d − x).

    Attributes:
        kp: K_P [1/s²].
        kv: K_V [1/s].
    """

    kp: float
    kv: float


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


def kinematic_chain(model: pin.Model, frame_id: int) -> np.ndarray:
    """Which velocities move a frame: those of its parent joint and the joints supporting it.

    Returns:
        Shape (nv,) bool: the columns Pinocchio's ``getFrameJacobian`` fills.
    """
    chain = np.zeros(model.nv, dtype=bool)
    for joint in list(model.supports[model.frames[frame_id].parentJoint])[1:]:  # not universe
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
    yaw = math.atan2(r[1, 0], r[0, 0])
    c2 = math.sqrt(r[2, 2] * r[2, 2] + r[2, 1] * r[2, 1])
    if yaw < 0.0:
        yaw += math.pi
        pitch = math.atan2(-r[2, 0], -c2)
    else:
        pitch = math.atan2(-r[2, 0], c2)
    s1, c1 = math.sin(yaw), math.cos(yaw)
    roll = math.atan2(s1 * r[0, 2] - c1 * r[1, 2], c1 * r[1, 1] - s1 * r[0, 1])
    if pitch < -math.pi / 2:
        pitch += 2 * math.pi
    if pitch > math.pi / 2:
        pitch = math.pi - pitch
        roll = roll + math.pi if roll < 0.0 else roll - math.pi
        yaw -= math.pi
    rpy[0], rpy[1], rpy[2] = roll, pitch, yaw


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
    top = max(start[2], target[2]) + apex
    t_rise = rise_fraction * duration
    if s < t_rise:
        bz, dbz, ddbz = quintic(s, t_rise)
        z0, z1 = start[2], top
    else:
        bz, dbz, ddbz = quintic(s - t_rise, duration - t_rise)
        z0, z1 = top, target[2]
    pos[2] = z0 + bz * (z1 - z0)
    vel[2] = dbz * (z1 - z0)
    acc[2] = ddbz * (z1 - z0)


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
            site_rotation[i, 0] * ft[0] + site_rotation[i, 1] * ft[1] + site_rotation[i, 2] * ft[2]
        )
        s[i] = (
            site_rotation[i, 0] * ft[3] + site_rotation[i, 1] * ft[4] + site_rotation[i, 2] * ft[5]
        )
    m = foot_mass
    a0, a1, a2 = foot_acc[0], foot_acc[1], foot_acc[2]
    p0, p1, p2 = site_position[0], site_position[1], site_position[2]
    # f_c = f_s − m g_vec + m a, with g_vec = (0, 0, −g).
    fc0, fc1, fc2 = f[0] + m * a0, f[1] + m * a1, f[2] + m * GRAVITY + m * a2
    r0, r1, r2 = foot_com[0] - p0, foot_com[1] - p1, foot_com[2] - p2  # foot CoM from sensor
    h0, h1, h2 = -m * a0, -m * a1, m * (-GRAVITY - a2)  # m (g_vec − a)
    mc0 = s[0] - (r1 * h2 - r2 * h1)
    mc1 = s[1] - (r2 * h0 - r0 * h2)
    d0, d1, d2 = p0 - sole_position[0], p1 - sole_position[1], p2 - sole_position[2]
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
    n = com_plan.shape[0]
    if t >= plan_end:
        last = com_plan[n - 1].position
        pos[0], pos[1], pos[2] = last[0], last[1], com_z
        vel[:] = 0.0
        acc[:] = 0.0
        return
    k = t / preview_dt
    i = int(min(max(np.floor(k), 0.0), n - 2))
    a = min(max(k - i, 0.0), 1.0)
    before, after = com_plan[i], com_plan[i + 1]
    for axis in range(2):
        pos[axis] = (1 - a) * before.position[axis] + a * after.position[axis]
        vel[axis] = (1 - a) * before.velocity[axis] + a * after.velocity[axis]
        acc[axis] = (1 - a) * before.acceleration[axis] + a * after.acceleration[axis]
    pos[2], vel[2], acc[2] = com_z, 0.0, 0.0


@numba.njit(cache=True)
def _write_references(foot: np.void, refs: np.ndarray) -> None:
    """A foot's reference signals (:data:`FOOT_SIGNALS`) from ``refs``, rows x_d, ẋ_d, ẍ_d,
    x_m, ẋ_m, ẍ_m, columns (z [m], φ_x, φ_y [rad]) and their rates."""
    foot.z_d, foot.roll_d, foot.pitch_d = refs[0, 0], refs[0, 1], refs[0, 2]
    foot.z_dot_d, foot.roll_dot_d, foot.pitch_dot_d = refs[1, 0], refs[1, 1], refs[1, 2]
    foot.z_ddot_d, foot.roll_ddot_d, foot.pitch_ddot_d = refs[2, 0], refs[2, 1], refs[2, 2]
    foot.z_m, foot.roll_m, foot.pitch_m = refs[3, 0], refs[3, 1], refs[3, 2]
    foot.z_dot_m, foot.roll_dot_m, foot.pitch_dot_m = refs[4, 0], refs[4, 1], refs[4, 2]
    foot.z_ddot_m, foot.roll_ddot_m, foot.pitch_ddot_m = refs[5, 0], refs[5, 1], refs[5, 2]


@numba.njit(cache=True)
def _set_task(
    task: Task, source: np.ndarray, first: int, acc_ref: np.ndarray, drift: np.ndarray
) -> None:
    """A task's Φ_t = ``source[first:first+r]`` and b_t = ẍ_r − Φ̇_t ξ̇ (r rows of ``task``)."""
    jacobian, target = task.jacobian, task.target
    for r in range(target.shape[0]):
        for j in range(source.shape[1]):
            jacobian[r, j] = source[first + r, j]
        target[r] = acc_ref[r] - drift[r]


@numba.njit(cache=True)
def _orientation_task(
    terms: RobotTerms,
    chain: np.ndarray,
    log_r: np.ndarray,
    drift: np.ndarray,
    gains: RowGains,
    frame_jac: np.ndarray,
    task: Task,
) -> None:
    """A frame held upright, heading +x: Φ_t its angular Jacobian, ẍ_r = K_P log(R⁻¹) − K_V ω.

    ``chain`` marks the velocities that move the frame; ``log_r`` is log₃ R of the frame's
    world rotation (so −log_r is the error), ``drift`` the angular part of its J̇ ξ̇;
    ``frame_jac`` is scratch (6, nv).
    """
    velocity, kp, kv = terms.velocity, gains.kp, gains.kv
    origin = np.zeros(3)  # the angular rows do not depend on the point
    frame_jacobian(terms.joint_jacobians, chain, origin, frame_jac)
    acc_ref = np.empty(3)
    for i in range(3):
        omega = 0.0
        for j in range(velocity.shape[0]):
            omega += frame_jac[3 + i, j] * velocity[j]
        acc_ref[i] = -kp * log_r[i] - kv * omega
    _set_task(task, frame_jac, 3, acc_ref, drift)


@structref.register
class TaskRecordsType(types.StructRef):
    """numba's type of :class:`TaskRecords` (its fields typed as given, not literal)."""

    def preprocess_fields(self, fields: tuple) -> tuple:
        """The fields' types without literal values."""
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class TaskRecords(structref.StructRefProxy):
    """Everything :func:`task_rows` reads and writes besides the readings, as one argument;
    make it with :func:`task_records` once at reset (its arrays are filled in place).

    Fields: ``terms`` (:class:`RobotTerms`), ``constants`` (:class:`TaskConstants`),
    ``references`` (:class:`TaskReferences`), ``state`` (:class:`TaskState`), ``outputs``
    (:class:`TaskOutputs`). Why not the named tuples themselves: numba finds the type of a
    named tuple argument in Python, field by field, at every call (≈ 0.2 µs a field, ≈ 15 µs
    for these); a StructRef carries its type, and its arrays were unboxed once, when it was
    made.
    """


structref.define_proxy(
    TaskRecords, TaskRecordsType, ["terms", "constants", "references", "state", "outputs"]
)


@numba.njit(cache=True)
def task_records(
    terms: RobotTerms,
    constants: TaskConstants,
    references: TaskReferences,
    state: TaskState,
    outputs: TaskOutputs,
) -> TaskRecords:
    """The :class:`TaskRecords` of these records (compiled and cached, unlike the proxy's own
    constructor)."""
    return TaskRecords(terms, constants, references, state, outputs)


@numba.njit(cache=True)
def task_rows(t: float, swing: int, readings: SensorReadings, records: TaskRecords) -> int:
    """One tick's task rows (§III-D), foot states, contact wrenches and impedance (Eqs. 1–3).

    Args:
        t: time [s].
        swing: the swing foot (0 left, 1 right), or −1 in double support.
        readings: the joint encoders and each foot's F/T reading.
        records: (:class:`TaskRecords`) Pinocchio's terms of the tick and ξ̇; the gains,
            weights and geometry (set at reset); the CoM pattern, this phase's swing
            trajectory, stance heights and home posture; each foot's impedance state,
            previous velocity and commanded acceleration (updated in place); the outputs: the
            QP's cost terms, each foot's J_k, J̇_k ξ̇ and R̃ U_k, and the signals.

    Returns:
        A bit per foot (1 left, 2 right) whose impedance modification switched on this tick.
    """
    terms, constants = records.terms, records.constants
    references, state, outputs = records.references, records.state, records.outputs
    joint_jacobians, velocity = terms.joint_jacobians, terms.velocity
    nonlinear, gravity_torques = terms.nonlinear, terms.gravity_torques
    com, com_vel, angular_momentum = terms.com, terms.com_vel, terms.angular_momentum
    base_rotation, base_position, base_drift = (
        terms.base_rotation, terms.base_position, terms.base_drift
    )  # fmt: skip
    joint_pos, joint_vel = readings.joint_pos, readings.joint_vel
    gains, chains = constants.gains, constants.chains
    posture_idx, posture_home = constants.posture_idx, references.posture_home
    local_wrench_map = constants.local_wrench_map
    impedance = state.impedance
    prev_foot_vel, foot_acc_cmd = state.prev_foot_vel, state.foot_acc_cmd
    tasks = outputs.tasks
    sole_jacobians, sole_drifts, wrench_maps = (
        outputs.sole_jacobians,
        outputs.sole_drifts,
        outputs.wrench_maps,
    )
    signals = outputs.signals[0]
    nv = velocity.shape[0]
    m = gains.mass
    # ---- centroidal momentum reference (§III-D) --------------------------------------
    c_d, v_d, a_d = np.empty(3), np.empty(3), np.empty(3)
    desired_com(
        references.com_plan,
        t,
        gains.preview_dt,
        gains.plan_end,
        gains.com_z,
        c_d,
        v_d,
        a_d,
    )
    kh, ki = gains.k_h, gains.k_i
    # ḣ_lin = m (c̈_d + K_h (ċ_d − ċ) + K_I (c_d − c)), with ∫(h_d − h) = m (c_d − c).
    lin = np.empty(3)
    for i in range(3):
        lin[i] = m * (a_d[i] + kh * (v_d[i] - com_vel[i]) + ki * (c_d[i] - com[i]))
    r0, r1, r2 = com[0] - base_position[0], com[1] - base_position[1], com[2] - base_position[2]
    ang = np.empty(3)  # ḣ_ang + (c − p_B) × ḣ_lin, with ḣ_ang = −K_h k
    ang[0] = -gains.k_h_angular * angular_momentum[0] + (r1 * lin[2] - r2 * lin[1])
    ang[1] = -gains.k_h_angular * angular_momentum[1] + (r2 * lin[0] - r0 * lin[2])
    ang[2] = -gains.k_h_angular * angular_momentum[2] + (r0 * lin[1] - r1 * lin[0])
    # b_1 = X_GBᵀ ḣ_{G,r} − C_B ξ̇ (Eq. 7): both halves in the base frame, minus (C ξ̇)_B.
    b_1 = tasks.momentum_target
    for i in range(3):
        h_lin = base_rotation[0, i] * lin[0] + base_rotation[1, i] * lin[1]
        h_lin += base_rotation[2, i] * lin[2]
        h_ang = base_rotation[0, i] * ang[0] + base_rotation[1, i] * ang[1]
        h_ang += base_rotation[2, i] * ang[2]
        b_1[i] = h_lin - (nonlinear[i] - gravity_torques[i])
        b_1[3 + i] = h_ang - (nonlinear[3 + i] - gravity_torques[3 + i])

    # ---- pelvis and torso upright, heading +x ----------------------------------------
    frame_jac = np.empty((6, nv))
    orientation = RowGains(gains.kp_orient, gains.kv_orient)
    drift = np.empty(3)  # angular part of the frame's J̇ ξ̇: the joint's α in world axes
    log_r = np.empty(3)
    drift[0], drift[1], drift[2] = eigen_rotate(
        base_rotation, base_drift[3], base_drift[4], base_drift[5]
    )
    log3(terms.pelvis_rotation, log_r)
    _orientation_task(terms, chains.pelvis, log_r, drift, orientation, frame_jac, tasks.pelvis)
    torso_drift = terms.torso_joint_drift
    drift[0], drift[1], drift[2] = eigen_rotate(
        terms.torso_joint_rotation, torso_drift[3], torso_drift[4], torso_drift[5]
    )
    log3(terms.torso_rotation, log_r)
    _orientation_task(terms, chains.torso, log_r, drift, orientation, frame_jac, tasks.torso)

    # ---- arm and waist joints: hold home ---------------------------------------------
    n_post = posture_idx.shape[0]
    for r in range(n_post):
        k = posture_idx[r]
        acc = gains.kp_posture * (posture_home[r] - joint_pos[k])
        acc -= gains.kv_posture * joint_vel[k]
        tasks.posture.target[r] = acc  # Φ_t selects the joint (constant), Φ̇_t = 0

    # ---- feet: state, measured contact wrench, impedance, swing rows -----------------
    signals.t_plan, signals.swing_foot = t, float(swing)
    dt = gains.dt
    switched_on = 0
    acc_ref = np.empty(6)
    site_rot, site_pos, foot_com = np.empty((3, 3)), np.empty(3), np.empty(3)
    pos_d, vel_d, acc_d = np.empty(5), np.empty(5), np.empty(5)
    rpy = np.empty(3)
    for side in range(2):
        if side == 0:  # the sole's placement and parent joint's R, v, a; its F/T reading
            sole, ft, foot = terms.left, readings.left_ft, signals.left
            chain = chains.left_sole
        else:
            sole, ft, foot = terms.right, readings.right_ft, signals.right
            chain = chains.right_sole
        rot, pos = sole.rotation, sole.position
        joint_r, joint_v, joint_a = sole.joint_rotation, sole.joint_velocity, sole.joint_drift
        sole_jac = sole_jacobians[side]
        frame_jacobian(joint_jacobians, chain, pos, sole_jac)
        drift = sole_drifts[side]
        frame_classical_acceleration(joint_r, joint_v, joint_a, constants.sole_offset[side], drift)
        # R̃ U_k: both halves (forces, moments) of the contact-frame basis rotated.
        for half in range(2):
            for i in range(3):
                for c in range(local_wrench_map.shape[1]):
                    s = 0.0
                    for k in range(3):
                        s += rot[i, k] * local_wrench_map[3 * half + k, c]
                    wrench_maps[side, 3 * half + i, c] = s
        # Sensor and foot-CoM placements from the sole's (all on the ankle's body).
        for i in range(3):
            site_pos[i] = pos[i]
            foot_com[i] = pos[i]
            for k in range(3):
                site_pos[i] += rot[i, k] * constants.sole_site_position[side, k]
                foot_com[i] += rot[i, k] * constants.sole_foot_com[side, k]
                s = 0.0
                for j in range(3):
                    s += rot[i, j] * constants.sole_site_rotation[side, j, k]
                site_rot[i, k] = s
        vel = np.empty(6)
        for i in range(6):
            s = 0.0
            for j in range(nv):
                s += sole_jac[i, j] * velocity[j]
            vel[i] = s
        acc_meas = (vel - prev_foot_vel[side]) / dt
        prev_foot_vel[side] = vel
        fz, mx, my = contact_wrench(
            ft, site_rot, site_pos, foot_com, pos, foot_acc_cmd[side], gains.foot_mass
        )
        matrix_to_rpy(rot, rpy)
        roll, pitch, yaw = rpy[0], rpy[1], rpy[2]
        foot.fz, foot.mx, foot.my = fz, mx, my
        foot.x, foot.z, foot.roll, foot.pitch = pos[0], pos[2], roll, pitch
        foot.vz, foot.wx, foot.wy = vel[2], vel[3], vel[4]
        foot.az, foot.alphax, foot.alphay = acc_meas[2], acc_meas[3], acc_meas[4]
        foot_state = impedance[side]
        if side != swing:
            # Support: re-initialise the impedance at the foot's state (§IV), no command.
            foot_state.armed = foot_state.active = False
            x_m = foot_state.position
            x_m[0], x_m[1], x_m[2] = pos[2], roll, pitch
            foot_state.velocity[:] = 0.0
            foot_state.acceleration[:] = 0.0
            foot_acc_cmd[side] = 0.0
            foot.impedance_on = 0.0
            # The references of a support foot: at its planned height, at rest, level.
            stance = np.zeros((6, 3))  # x_d, ẋ_d, ẍ_d, x_m, ẋ_m, ẍ_m of (z, φ_x, φ_y)
            stance[0, 0] = stance[3, 0] = references.stance_z[side]
            _write_references(foot, stance)
            continue
        swing_reference(references.swing_plan, t, pos_d, vel_d, acc_d)
        wrench = np.array((fz, mx, my))
        desired = DesiredMotion(pos_d[2:5], vel_d[2:5], acc_d[2:5])
        if advance_impedance(
            foot_state,
            desired,
            wrench,
            constants.impedance_gains,
            dt,
            gains.impedance,
        ):
            switched_on |= 1 << side
        # Eq. (3), ẍ_r = ẍ_m + K_v (ẋ_m − ẋ) + K_p (x_m − x), for (z, φx, φy) with the
        # modified reference; x, y and yaw follow the plan (the same form, unmodified).
        kp, kv = gains.kp_swing, gains.kv_swing
        x_now = (pos[2], roll, pitch)
        acc_ref[0] = acc_d[0] + kv * (vel_d[0] - vel[0]) + kp * (pos_d[0] - pos[0])
        acc_ref[1] = acc_d[1] + kv * (vel_d[1] - vel[1]) + kp * (pos_d[1] - pos[1])
        for i in range(3):
            acc_ref[2 + i] = (
                foot_state.acceleration[i]
                + kv * (foot_state.velocity[i] - vel[2 + i])
                + kp * (foot_state.position[i] - x_now[i])
            )
        acc_ref[5] = -kv * vel[5] - kp * yaw
        foot_acc_cmd[side] = acc_ref[:3]
        _set_task(tasks.swing, sole_jac, 0, acc_ref, drift)
        foot.impedance_on = 1.0 if foot_state.active else 0.0
        swing_refs = np.empty((6, 3))  # x_d, ẋ_d, ẍ_d, x_m, ẋ_m, ẍ_m of (z, φ_x, φ_y)
        swing_refs[0], swing_refs[1], swing_refs[2] = pos_d[2:5], vel_d[2:5], acc_d[2:5]
        swing_refs[3], swing_refs[4] = foot_state.position, foot_state.velocity
        swing_refs[5] = foot_state.acceleration
        _write_references(foot, swing_refs)
    signals.com_x, signals.com_y, signals.com_z = com[0], com[1], com[2]
    signals.com_x_d, signals.com_y_d, signals.com_z_d = c_d[0], c_d[1], c_d[2]
    return switched_on
