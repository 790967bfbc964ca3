"""A robot: the MuJoCo model and the Pinocchio model of the same MJCF, named frames, the
actuator layout and the ``home`` posture.

Conventions every ``robots/<name>/robot.xml`` follows (``robots/build_models.py`` writes
them; :func:`load_robot` checks the ones other modules rely on):

- Root body ``pelvis`` with a free joint ``root``; x forward, y left, z up at home.
- Feet ``left_foot`` / ``right_foot`` are the bodies after the ankle roll joints and own
  every sole geom. Sites ``left_sole`` / ``right_sole`` sit at the centre of each sole's
  bottom face, ``left_foot_ft`` / ``right_foot_ft`` at the force/torque sensors, ``imu`` on
  the upper body; all sites have z up and x forward at home.
- One actuator per actuated joint, named after its link-side joint, in the order: left
  leg, right leg, waist, left arm, right arm.
- A series-elastic joint ``j`` (COMAN) is two hinges on one axis in one body: the motor
  DoF ``j_motor`` (armature J_m, back-EMF damping, position servo) then the spring DoF
  ``j`` (``stiffness`` = spring constant). The link angle is their sum.

State conventions, MuJoCo vs Pinocchio (free-flyer root):

- base pose: MuJoCo ``qpos[0:7]`` = position [m], quaternion (w, x, y, z); Pinocchio
  ``q[0:7]`` = position [m], quaternion (x, y, z, w).
- base linear velocity (of the pelvis origin): MuJoCo ``qvel[0:3]`` in the WORLD frame;
  Pinocchio ``v[0:3]`` in the PELVIS frame. So ``qvel[0:3] = R v[0:3]``, R world-from-pelvis,
  and likewise MuJoCo's ``qacc[0:3] = R (v̇[0:3] + ω × v[0:3])``.
- base angular velocity: in the PELVIS frame in both (``qvel[3:6]`` = ``v[3:6]``).
- joints: MuJoCo has every hinge (COMAN: motor and spring DoFs), Pinocchio the link-side
  joints only. Both order them left leg, right leg, waist, left arm, right arm, but use
  :attr:`Robot.pin_q_idx` / :attr:`Robot.pin_v_idx` rather than assuming it.

Force/torque sensors: MuJoCo's ``force``/``torque`` sensors on ``*_foot_ft`` give the wrench
the leg exerts on the foot body, in the site frame, about the site. The foot body (whole
foot after the ankle roll joint) lies below the site, so standing still reads
fz = −(supported load − foot weight); :mod:`walkrepro.sim.sensors` flips the sign.

For COMAN the Pinocchio model is a *rigid twin*: the spring DoFs are removed, each link
joint is the motor joint made rigid with the spring (angle = motor + spring, range = the
motor's, armature = J_m, damping = motor + spring damping). Controllers plan with it; the
springs exist only in MuJoCo, as on the real robot.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, NamedTuple

import mujoco
import numba
import numpy as np
import pinocchio as pin

from walkrepro.errors import UnknownNameError
from walkrepro.locations import ROBOTS_DIR
from walkrepro.sim.springs import preload_deflection, spring_law, spring_tendon

ControlMode = Literal["torque", "position"]

#: Foot bodies (the bodies after the ankle roll joints).
FOOT_BODIES = ("left_foot", "right_foot")
#: Sites at the centres of the sole bottoms.
SOLE_SITES = ("left_sole", "right_sole")
#: Sites of the 6-axis force/torque sensors between ankle and sole.
FT_SITES = ("left_foot_ft", "right_foot_ft")
#: Site of the IMU on the upper body.
IMU_SITE = "imu"
#: Frames every robot has in both MuJoCo (bodies/sites) and Pinocchio (BODY/OP_FRAME frames).
FRAME_NAMES = ("pelvis", *FOOT_BODIES, *SOLE_SITES, *FT_SITES, IMU_SITE)
#: Sensor names every robot has, and no others.
SENSOR_NAMES = (
    "imu_quat",
    "imu_gyro",
    "imu_acc",
    "left_foot_force",
    "left_foot_torque",
    "right_foot_force",
    "right_foot_torque",
)
#: Suffix of the motor DoF of a series-elastic joint.
MOTOR_SUFFIX = "_motor"
#: MJCF ``<custom><text>`` naming where the joint encoders sit ("motor": before the gear).
ENCODERS_TEXT = "walkrepro_encoders"
#: Name of the home keyframe.
HOME_KEY = "home"


class LinkAddresses(NamedTuple):
    """Where the components of each link-side joint live in MuJoCo's ``qpos`` or ``qvel``.

    A rigid joint has one component; a series-elastic joint has two (motor, then spring).
    The link-side values in actuator order are ``np.add.reduceat(x[adr], starts)``, which
    :meth:`link_values` computes.

    Attributes:
        adr: flat ``qpos``/``qvel`` indices grouped joint by joint, shape (n_components,).
        starts: index into ``adr`` where each joint's group starts, shape (n_joints,).
    """

    adr: np.ndarray
    starts: np.ndarray

    def link_values(self, x: np.ndarray) -> np.ndarray:
        """Link-side values (sum of each joint's components), shape (n_joints,)."""
        if len(self.adr) == len(self.starts):  # rigid joints only: one component each
            return np.asarray(x)[self.adr]
        return np.add.reduceat(np.asarray(x)[self.adr], self.starts)


_READ = numba.types.Array(numba.types.float64, 1, "A", readonly=True)
_INDEX = numba.types.Array(numba.types.int64, 2, "A", readonly=True)
_WRITE = numba.types.Array(numba.types.float64, 2, "A")


def pin_state_buffer(model: pin.Model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A buffer for :func:`pin_state_into` and its two views: ``(state, q, v)``, with ``q``
    the first nq entries of row 0 and ``v`` the first nv of row 1 (contiguous, for
    Pinocchio)."""
    state = np.zeros((2, max(model.nq, model.nv)))
    return state, state[0, : model.nq], state[1, : model.nv]


@numba.njit(
    numba.types.void(_READ, _READ, _READ, _READ, _READ, _READ, _INDEX, _WRITE),
    cache=True,
)
def pin_state_into(
    base_pos: np.ndarray,
    base_quat: np.ndarray,
    base_linvel: np.ndarray,
    base_angvel: np.ndarray,
    joint_pos: np.ndarray,
    joint_vel: np.ndarray,
    joint_index: np.ndarray,
    state: np.ndarray,
) -> None:
    """Pinocchio's (q, v) written into ``state`` (see :meth:`Robot.pin_state`).

    Compiled because whole-body controllers call it every tick at 1-2 kHz (5 µs in numpy and
    Pinocchio's Python bindings, 1 µs here). The base's linear velocity moves from world to
    base axes (Rᵀ v) with R the normalised quaternion's rotation, in the operations (and
    the order) of Eigen's ``Quaternion::normalized().toRotationMatrix()``; tests compare the
    result with Pinocchio's to 1e-12.

    Args:
        base_pos: pelvis position in the world [m]; base_quat: world-from-pelvis (w, x, y, z).
        base_linvel: pelvis velocity, world axes [m/s]; base_angvel: pelvis axes [rad/s].
        joint_pos, joint_vel: link-side joints, actuator order [rad, rad/s].
        joint_index: each actuated joint's index in q (row 0) and in v (row 1), shape (2, n)
            (:attr:`Robot.pin_joint_index`).
        state: out: q in row 0, v in row 1 (:func:`pin_state_buffer`); entries of joints not
            in ``joint_index`` are left alone.
    """
    q, v = state[0], state[1]
    w, x, y, z = base_quat[0], base_quat[1], base_quat[2], base_quat[3]
    q[0], q[1], q[2] = base_pos[0], base_pos[1], base_pos[2]
    q[3], q[4], q[5], q[6] = x, y, z, w
    norm = np.sqrt((x * x + z * z) + (y * y + w * w))  # Eigen's (SIMD) summation order
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    tx, ty, tz = 2 * x, 2 * y, 2 * z
    twx, twy, twz = tx * w, ty * w, tz * w
    txx, txy, txz = tx * x, ty * x, tz * x
    tyy, tyz, tzz = ty * y, tz * y, tz * z
    rot = np.empty((3, 3))
    rot[0, 0], rot[0, 1], rot[0, 2] = 1 - (tyy + tzz), txy - twz, txz + twy
    rot[1, 0], rot[1, 1], rot[1, 2] = txy + twz, 1 - (txx + tzz), tyz - twx
    rot[2, 0], rot[2, 1], rot[2, 2] = txz - twy, tyz + twx, 1 - (txx + tyy)
    for j in range(3):
        v[j] = base_linvel[0] * rot[0, j] + base_linvel[1] * rot[1, j] + base_linvel[2] * rot[2, j]
        v[3 + j] = base_angvel[j]
    for i in range(joint_index.shape[1]):
        q[joint_index[0, i]] = joint_pos[i]
        v[joint_index[1, i]] = joint_vel[i]


@numba.njit(cache=True)
def frame_jacobian(
    joint_jacobians: np.ndarray, chain: np.ndarray, position: np.ndarray, out: np.ndarray
) -> None:
    """A frame's Jacobian in LOCAL_WORLD_ALIGNED axes, as Pinocchio's ``getFrameJacobian``,
    for the whole-body controllers' compiled ticks (one call per foot at 1-2 kHz).

    Column j of the world-axes joint Jacobian (``data.J``, velocities of the point at the
    world origin) moves to the frame origin p: linear part v − p × ω. Columns off the frame's
    kinematic chain are zero.

    numba's cache does not notice edits here in the compiled callers that inline this
    (``lee2021/kernels.py``, ``jo_oh/tasks.py``): after changing it, delete their
    ``__pycache__``.

    Args:
        joint_jacobians: ``data.J`` after ``computeAllTerms``, shape (6, nv).
        chain: whether each velocity moves the frame's parent joint, shape (nv,) bool.
        position: frame origin in the world [m], shape (3,).
        out: the Jacobian, shape (6, nv).
    """
    p0, p1, p2 = position[0], position[1], position[2]
    for j in range(joint_jacobians.shape[1]):
        if not chain[j]:
            for i in range(6):
                out[i, j] = 0.0
            continue
        w0, w1, w2 = joint_jacobians[3, j], joint_jacobians[4, j], joint_jacobians[5, j]
        out[0, j] = joint_jacobians[0, j] - (p1 * w2 - p2 * w1)  # v − p × ω
        out[1, j] = joint_jacobians[1, j] - (p2 * w0 - p0 * w2)
        out[2, j] = joint_jacobians[2, j] - (p0 * w1 - p1 * w0)
        out[3, j], out[4, j], out[5, j] = w0, w1, w2


@numba.njit(cache=True)
def eigen_rotate(rot: np.ndarray, x0: float, x1: float, x2: float) -> tuple[float, float, float]:
    """rot · x summed as Eigen's 3 × 3 product in Pinocchio: rows 0 and 1 as one two-lane
    packet, (r₀x₀ + r₁x₁) + r₂x₂; row 2 alone as a tree, r₀x₀ + (r₁x₁ + r₂x₂). Summing in
    The compiled controllers' references were made with this order, so it stays.

    Like :func:`frame_jacobian`, inlined into compiled callers whose numba cache does not
    notice edits here: after changing it, delete their ``__pycache__``.
    """
    return (
        (rot[0, 0] * x0 + rot[0, 1] * x1) + rot[0, 2] * x2,
        (rot[1, 0] * x0 + rot[1, 1] * x1) + rot[1, 2] * x2,
        rot[2, 0] * x0 + (rot[2, 1] * x1 + rot[2, 2] * x2),
    )


@numba.njit(cache=True)
def frame_classical_acceleration(
    joint_rot: np.ndarray,
    joint_vel: np.ndarray,
    joint_acc: np.ndarray,
    offset: np.ndarray,
    out: np.ndarray,
) -> None:
    """J̇ q̇ of a frame fixed to a joint's body, world axes at the frame origin, as Pinocchio's
    ``getFrameClassicalAcceleration(..., LOCAL_WORLD_ALIGNED)`` after ``computeAllTerms``,
    in its operations (tested against it to 1e-12), for the whole-body controllers' ticks.

    The joint's spatial velocity (v, ω) and bias acceleration (a, α) (q̈ = 0), in joint axes,
    move to the frame origin (v + ω × o, a + α × o), turn to world axes, and the classical
    acceleration adds ω × v. Inlined like :func:`frame_jacobian` (same cache caveat).

    Args:
        joint_rot: world-from-joint rotation (``data.oMi[j].rotation``).
        joint_vel, joint_acc: ``data.v[j].vector`` and ``data.a[j].vector`` (linear first).
        offset: the frame origin in joint axes (the frame placement's translation) [m].
        out: (linear, angular) [m/s², rad/s²], shape (6,).
    """
    ox, oy, oz = offset[0], offset[1], offset[2]
    w0, w1, w2 = joint_vel[3], joint_vel[4], joint_vel[5]
    v0, v1, v2 = eigen_rotate(
        joint_rot,
        joint_vel[0] + (w1 * oz - w2 * oy),
        joint_vel[1] + (w2 * ox - w0 * oz),
        joint_vel[2] + (w0 * oy - w1 * ox),
    )
    w0, w1, w2 = eigen_rotate(joint_rot, w0, w1, w2)
    al0, al1, al2 = joint_acc[3], joint_acc[4], joint_acc[5]
    a0, a1, a2 = eigen_rotate(
        joint_rot,
        joint_acc[0] + (al1 * oz - al2 * oy),
        joint_acc[1] + (al2 * ox - al0 * oz),
        joint_acc[2] + (al0 * oy - al1 * ox),
    )
    out[0] = a0 + (w1 * v2 - w2 * v1)  # + ω × v
    out[1] = a1 + (w2 * v0 - w0 * v2)
    out[2] = a2 + (w0 * v1 - w1 * v0)
    out[3], out[4], out[5] = eigen_rotate(joint_rot, al0, al1, al2)


_EPS = float(np.finfo(np.float64).eps)


@numba.njit(cache=True)
def log3_theta_axis(val: float, m: np.ndarray, i0: int) -> tuple[float, float, float, float]:
    """θ and the unit axis of a rotation by ≈ π, from its i0-th diagonal term ``val`` =
    2 m[i0, i0] − tr m + 1 (the largest): Pinocchio's ``internal::compute_theta_axis<i0>``,
    its operations in its order, for the whole-body controllers' compiled log₃.

    Inlined like :func:`frame_jacobian` (same cache caveat).
    """
    i1, i2 = (i0 + 1) % 3, (i0 + 2) % 3
    sign = 1.0 if m[i2, i1] >= m[i1, i2] else -1.0
    s = math.sqrt(val + _EPS + _EPS * _EPS) * sign  # ≥ 0 under the root, s ≠ 0
    axis = np.empty(3)
    axis[i0] = s / 2.0
    axis[i1] = 1.0 / (2.0 * s) * (m[i1, i0] + m[i0, i1])
    axis[i2] = 1.0 / (2.0 * s) * (m[i2, i0] + m[i0, i2])
    w = 1.0 / (2.0 * s) * (m[i2, i1] - m[i1, i2])
    norm = math.sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2])
    return 2.0 * math.atan2(norm, w), axis[0] / norm, axis[1] / norm, axis[2] / norm


#: Pinocchio's Taylor-expansion threshold of log₃, ``TaylorSeriesExpansion<double>::precision<2>``.
_LOG3_PREC = math.pow(_EPS, 1.0 / 3.0)


@numba.njit(cache=True)
def log3_entries(r: tuple[float, ...]) -> tuple[float, float, float]:
    """log₃ R, the rotation vector θ u [rad] of R given as its nine entries row by row
    (r₀₀, r₀₁, …, r₂₂): walkrepro's one log₃, compiled into the whole-body ticks (a tuple of
    floats stays in registers, where 3-vectors would cost more in allocations than in
    arithmetic).

    Pinocchio's ``log3`` method: re-orthonormalise R (columns 0 and 1 normalised, c₂ = c₀ × c₁,
    c₀ = c₁ × c₂), θ from the trace (acos; its series near 0; near π the axis from the
    largest 2 R_kk − tr + 1, :func:`log3_theta_axis`), then θ / sin θ (its Taylor series
    below θ = ε^(1/3)) times the skew part. Sums run left to right: the result agrees with
    ``pin.log3`` to 1e-12 (tests/test_robot.py), not to the last bit.
    """
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = r
    n0 = math.sqrt(r00 * r00 + r10 * r10 + r20 * r20)
    n1 = math.sqrt(r01 * r01 + r11 * r11 + r21 * r21)
    x0, x1, x2 = r00 / n0, r10 / n0, r20 / n0  # column 0
    y0, y1, y2 = r01 / n1, r11 / n1, r21 / n1  # column 1
    z0, z1, z2 = x1 * y2 - x2 * y1, x2 * y0 - x0 * y2, x0 * y1 - x1 * y0  # column 2 = x × y
    x0, x1, x2 = y1 * z2 - y2 * z1, y2 * z0 - y0 * z2, y0 * z1 - y1 * z0  # column 0 = y × z
    tr = x0 + y1 + z2
    cos_value = (tr - 1.0) / 2.0
    prec = _LOG3_PREC
    if cos_value < -1.0 + prec:  # θ ≈ π
        m = np.empty((3, 3))
        m[0, 0], m[1, 0], m[2, 0] = x0, x1, x2
        m[0, 1], m[1, 1], m[2, 1] = y0, y1, y2
        m[0, 2], m[1, 2], m[2, 2] = z0, z1, z2
        val0, val1, val2 = 2.0 * x0 - tr + 1.0, 2.0 * y1 - tr + 1.0, 2.0 * z2 - tr + 1.0
        if val0 >= val1:
            k, val = (0, val0) if val0 >= val2 else (2, val2)
        else:
            k, val = (1, val1) if val1 >= val2 else (2, val2)
        theta, u0, u1, u2 = log3_theta_axis(val, m, k)
        return theta * u0, theta * u1, theta * u2
    acos_expansion = math.sqrt(2.0 * (1.0 - cos_value) + _EPS * _EPS)
    if tr <= 3.0 - prec:
        theta = math.acos(cos_value) if tr >= -1.0 + prec else math.pi - acos_expansion
    else:
        theta = acos_expansion
    w0, w1, w2 = 0.5 * (y2 - z1), 0.5 * (z0 - x2), 0.5 * (x1 - y0)  # the antisymmetric part
    if theta >= prec:
        t = theta / math.sin(theta)
    else:
        sq = w0 * w0 + w1 * w1 + w2 * w2
        t = 1.0 + sq / 6.0 + sq * sq * 3.0 / 40.0
    return t * w0, t * w1, t * w2


@numba.njit(cache=True)
def log3(rotation: np.ndarray, out: np.ndarray) -> None:
    """log₃ of a 3 × 3 rotation written into ``out`` (3,) [rad]: :func:`log3_entries`."""
    r = rotation
    out[0], out[1], out[2] = log3_entries(
        (r[0, 0], r[0, 1], r[0, 2], r[1, 0], r[1, 1], r[1, 2], r[2, 0], r[2, 1], r[2, 2])
    )


@dataclass(frozen=True, eq=False)  # eq=False: compare by identity, arrays have no ==
class Robot:
    """One robot, loaded from ``robots/<name>/robot.xml`` into MuJoCo and Pinocchio.

    Instances are shared by :func:`load_robot`'s cache: treat the models and arrays as
    read-only (the arrays are flagged so) and make a copy to change anything.

    Attributes:
        name: folder name under ``robots/``.
        xml_path: the MJCF file.
        mj_model: MuJoCo model of the robot alone (no floor, no options set).
        pin_model: Pinocchio model with a free-flyer root (COMAN: the rigid twin).
        joint_names: actuated link-side joints, in actuator order, shape (n,).
        control_mode: ``"torque"`` (ctrl = joint torques [Nm]) or ``"position"`` (ctrl =
            motor-side position targets [rad]).
        home_qpos: MuJoCo ``qpos`` of the ``home`` keyframe, shape (nq,): knees bent, feet
            flat with the sole bottoms on z = 0, the midpoint of the sole centres at the
            world origin and the CoM above it.
        home_ctrl: MuJoCo ``ctrl`` of the ``home`` keyframe, shape (nu,) (zeros for torque
            robots, the servo targets that hold home for position robots).
        home_joint_pos: link-side joint angles at home, actuator order, shape (n,) [rad].
        total_mass: mass of the whole robot [kg].
        nominal_pelvis_height: pelvis origin height at home (soles on z = 0) [m].
        nominal_com_height: whole-body centre of mass height at home [m].
        sole_size: sole length along x and width along y [m].
        spring_stiffness: spring constant of each series-elastic joint, shape (n,)
            [Nm/rad]; None for a rigid robot.
        pin_q_idx: index in Pinocchio's ``q`` of each actuated joint, shape (n,).
        pin_v_idx: index in Pinocchio's ``v`` of each actuated joint, shape (n,).
        pin_joint_index: ``pin_q_idx`` and ``pin_v_idx`` as the two rows of one array, shape
            (2, n) (for :func:`pin_state_into`).
        encoders_motor_side: the joint encoders sit before the gear and read the motor DoF
            of each series-elastic joint (``dyros_red_actuated``, Lee et al. §V-A); otherwise
            they read the link angle (motor + spring).
    """

    name: str
    xml_path: Path
    mj_model: mujoco.MjModel
    pin_model: pin.Model
    joint_names: tuple[str, ...]
    control_mode: ControlMode
    home_qpos: np.ndarray
    home_ctrl: np.ndarray
    home_joint_pos: np.ndarray
    total_mass: float
    nominal_pelvis_height: float
    nominal_com_height: float
    sole_size: tuple[float, float]
    spring_stiffness: np.ndarray | None
    pin_q_idx: np.ndarray
    pin_v_idx: np.ndarray
    pin_joint_index: np.ndarray
    encoders_motor_side: bool
    _qpos_adr: LinkAddresses = field(repr=False)
    _qvel_adr: LinkAddresses = field(repr=False)

    @property
    def n_joints(self) -> int:
        """Number of actuated link-side joints."""
        return len(self.joint_names)

    @property
    def is_series_elastic(self) -> bool:
        """True when every actuated joint is a motor DoF + spring DoF pair (COMAN)."""
        return self.spring_stiffness is not None

    # ---- MuJoCo side ------------------------------------------------------------------

    def link_joint_qpos_adr(self, model: mujoco.MjModel | None = None) -> LinkAddresses:
        """``qpos`` addresses of each link joint's components, actuator order.

        Args:
            model: a model that contains this robot (e.g. a compiled scene), looked up by
                joint name; defaults to :attr:`mj_model`.
        """
        if model is None or model is self.mj_model:
            return self._qpos_adr
        return _link_addresses(model, self.joint_names, "qposadr")

    def link_joint_qvel_adr(self, model: mujoco.MjModel | None = None) -> LinkAddresses:
        """``qvel`` addresses of each link joint's components, actuator order (see above)."""
        if model is None or model is self.mj_model:
            return self._qvel_adr
        return _link_addresses(model, self.joint_names, "dofadr")

    def encoder_qpos_adr(self, model: mujoco.MjModel | None = None) -> LinkAddresses:
        """``qpos`` addresses the joint encoders read: the link joint's components, or only
        the motor DoF when :attr:`encoders_motor_side`."""
        adr = self.link_joint_qpos_adr(model)
        return _motor_only(adr) if self.encoders_motor_side else adr

    def encoder_qvel_adr(self, model: mujoco.MjModel | None = None) -> LinkAddresses:
        """``qvel`` addresses the joint encoders read (see :meth:`encoder_qpos_adr`)."""
        adr = self.link_joint_qvel_adr(model)
        return _motor_only(adr) if self.encoders_motor_side else adr

    def link_joint_pos(self, qpos: np.ndarray) -> np.ndarray:
        """Link-side joint angles from this robot's MuJoCo ``qpos``, shape (n,) [rad]."""
        return self._qpos_adr.link_values(qpos)

    def link_joint_vel(self, qvel: np.ndarray) -> np.ndarray:
        """Link-side joint velocities from this robot's MuJoCo ``qvel``, shape (n,) [rad/s]."""
        return self._qvel_adr.link_values(qvel)

    def body_names(self) -> tuple[str, ...]:
        """Names of the robot's MuJoCo bodies (world excluded), tree order."""
        return tuple(self.mj_model.body(i).name for i in range(1, self.mj_model.nbody))

    # ---- Pinocchio side ---------------------------------------------------------------

    def pin_state(
        self,
        base_pos: np.ndarray,
        base_quat_wxyz: np.ndarray,
        base_linvel_world: np.ndarray,
        base_angvel_local: np.ndarray,
        joint_pos: np.ndarray,
        joint_vel: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Pinocchio ``(q, v)`` from a base state in MuJoCo's conventions and link joints.

        Args:
            base_pos: pelvis origin in the world, shape (3,) [m].
            base_quat_wxyz: world-from-pelvis orientation (w, x, y, z), as in MuJoCo.
            base_linvel_world: velocity of the pelvis origin in the WORLD frame, shape (3,)
                [m/s] (MuJoCo's ``qvel[0:3]``).
            base_angvel_local: pelvis angular velocity in the PELVIS frame, shape (3,)
                [rad/s] (MuJoCo's ``qvel[3:6]``).
            joint_pos: link-side joint angles in actuator order, shape (n,) [rad].
            joint_vel: link-side joint velocities in actuator order, shape (n,) [rad/s].

        Returns:
            ``q`` (nq,) with the quaternion as (x, y, z, w), and ``v`` (nv,) with the base
            linear and angular velocity both in the pelvis frame.
        """
        state, q, v = pin_state_buffer(self.pin_model)
        pin_state_into(
            np.asarray(base_pos, dtype=np.float64),
            np.asarray(base_quat_wxyz, dtype=np.float64),
            np.asarray(base_linvel_world, dtype=np.float64),
            np.asarray(base_angvel_local, dtype=np.float64),
            np.asarray(joint_pos, dtype=np.float64),
            np.asarray(joint_vel, dtype=np.float64),
            self.pin_joint_index,
            state,
        )
        return q, v

    def pin_configuration(
        self, base_pos: np.ndarray, base_quat_wxyz: np.ndarray, joint_pos: np.ndarray
    ) -> np.ndarray:
        """Pinocchio ``q`` (nq,) alone, quaternion as (x, y, z, w): for controllers that need
        no velocities (see :meth:`pin_state` for the arguments)."""
        quat = np.asarray(base_quat_wxyz, dtype=float)
        q = np.zeros(self.pin_model.nq)
        q[0:3] = base_pos
        q[3:6] = quat[1:4]
        q[6] = quat[0]
        q[self.pin_q_idx] = joint_pos
        return q

    def pin_state_from_mujoco(
        self, qpos: np.ndarray, qvel: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Pinocchio ``(q, v)`` of this robot's MuJoCo state (link joint = sum of components)."""
        return self.pin_state(
            qpos[0:3],
            qpos[3:7],
            qvel[0:3],
            qvel[3:6],
            self.link_joint_pos(qpos),
            self.link_joint_vel(qvel),
        )

    def pin_frame_id(self, name: str) -> int:
        """Pinocchio frame id of a body or site (e.g. ``"left_sole"``; see FRAME_NAMES)."""
        if not self.pin_model.existFrame(name):
            raise UnknownNameError("frame", name, [f.name for f in self.pin_model.frames])
        return int(self.pin_model.getFrameId(name))

    def pin_joint_id(self, name: str) -> int:
        """Pinocchio joint id of an actuated link-side joint (``"l_knee"``)."""
        if name not in self.joint_names:
            raise UnknownNameError("joint", name, self.joint_names)
        return int(self.pin_model.getJointId(name))


def leg_actuators(model: mujoco.MjModel, foot: str) -> np.ndarray:
    """Indices of the actuators of one leg: those driving a joint between the pelvis and the
    foot body, in actuator order (dyros_red: 0–5 for ``"left_foot"``).

    Read from the model's kinematic tree, so it holds for any scene (a log's recompiled
    ``scene.xml`` too) and for series-elastic joints (the motor DoF sits in the link body).

    Args:
        model: a model holding the robot (robot alone or a scene).
        foot: a foot body, ``"left_foot"`` or ``"right_foot"``.
    """
    if foot not in FOOT_BODIES:
        raise UnknownNameError("foot", foot, FOOT_BODIES)
    chain, body = set(), model.body(foot).id
    while body > 0:  # up to the world body (0); the pelvis's free joint drives no actuator
        chain.add(body)
        body = int(model.body_parentid[body])
    joints = model.actuator_trnid[:, 0]
    return np.array([i for i, j in enumerate(joints) if model.jnt_bodyid[j] in chain], dtype=int)


def list_robots() -> list[str]:
    """Names of the robots: the folders of ``robots/`` that hold a ``robot.xml``."""
    if not ROBOTS_DIR.is_dir():
        return []
    return sorted(p.parent.name for p in ROBOTS_DIR.glob("*/robot.xml"))


@functools.cache
def load_robot(name: str) -> Robot:
    """Load ``robots/<name>/robot.xml`` into MuJoCo and Pinocchio (cached per name).

    Raises:
        UnknownNameError: ``name`` is not a robot; the message lists the valid ones.
        ValueError: the MJCF breaks a convention other modules rely on.
    """
    robots = list_robots()
    if name not in robots:
        raise UnknownNameError("robot", name, robots)
    xml_path = ROBOTS_DIR / name / "robot.xml"
    mj_model = mujoco.MjModel.from_xml_path(str(xml_path))
    joint_names = tuple(mj_model.actuator(i).name for i in range(mj_model.nu))
    _check_conventions(mj_model, joint_names, xml_path)

    series_elastic = _joint_id(mj_model, joint_names[0] + MOTOR_SUFFIX) >= 0
    # A series-elastic robot is position controlled when its actuators are servos (COMAN),
    # torque controlled when they apply a torque to the motor DoF (dyros_red_actuated).
    servo = int(mj_model.actuator_biastype[0]) == int(mujoco.mjtBias.mjBIAS_AFFINE)
    text_id = mujoco.mj_name2id(mj_model, mujoco.mjtObj.mjOBJ_TEXT, ENCODERS_TEXT)
    motor_encoders = series_elastic and text_id >= 0 and _text(mj_model, text_id) == "motor"
    pin_model = _build_pin_model(xml_path, rigid_twin=series_elastic)
    pin_q_idx = np.array(
        [pin_model.joints[pin_model.getJointId(j)].idx_q for j in joint_names], dtype=np.int64
    )
    pin_v_idx = np.array(
        [pin_model.joints[pin_model.getJointId(j)].idx_v for j in joint_names], dtype=np.int64
    )

    data = mujoco.MjData(mj_model)
    mujoco.mj_resetDataKeyframe(mj_model, data, mj_model.key(HOME_KEY).id)
    mujoco.mj_forward(mj_model, data)
    qpos_adr = _link_addresses(mj_model, joint_names, "qposadr")
    qvel_adr = _link_addresses(mj_model, joint_names, "dofadr")
    sole = mj_model.geom("left_foot_sole").size
    stiffness = None
    if series_elastic:
        stiffness = np.array([spring_law(mj_model, j)[0] for j in joint_names])

    return Robot(
        name=name,
        xml_path=xml_path,
        mj_model=mj_model,
        pin_model=pin_model,
        joint_names=joint_names,
        control_mode="position" if series_elastic and servo else "torque",
        home_qpos=_frozen(data.qpos),
        home_ctrl=_frozen(data.ctrl),
        home_joint_pos=_frozen(qpos_adr.link_values(data.qpos)),
        total_mass=float(np.sum(mj_model.body_mass)),
        nominal_pelvis_height=float(data.qpos[2]),
        nominal_com_height=float(data.subtree_com[mj_model.body("pelvis").id][2]),
        sole_size=(2.0 * float(sole[0]), 2.0 * float(sole[1])),
        spring_stiffness=None if stiffness is None else _frozen(stiffness),
        pin_q_idx=_frozen(pin_q_idx),
        pin_v_idx=_frozen(pin_v_idx),
        pin_joint_index=_frozen(np.stack((pin_q_idx, pin_v_idx))),
        encoders_motor_side=motor_encoders,
        _qpos_adr=LinkAddresses(_frozen(qpos_adr.adr), _frozen(qpos_adr.starts)),
        _qvel_adr=LinkAddresses(_frozen(qvel_adr.adr), _frozen(qvel_adr.starts)),
    )


def with_servo_gains(robot: Robot, scene_model: mujoco.MjModel) -> Robot:
    """``robot`` with the position servos' gains that run in ``scene_model``.

    A spec's ``actuators.position_gain`` sets the servos of the scene (`walkrepro.sim.world`),
    not of the shared :func:`load_robot` model; a controller that reasons about its own
    servos (e.g. a spring compensation that includes the servo's yield) must see the gains
    it runs. Returns a copy whose ``mj_model`` carries the scene's ``gainprm`` and
    ``biasprm`` for every actuator; the cached robot is not touched. A torque-controlled
    robot is returned as it is.
    """
    if robot.control_mode != "position":
        return robot
    model = copy.copy(robot.mj_model)  # MjModel copies its arrays
    for name in robot.joint_names:
        model.actuator(name).gainprm[:] = scene_model.actuator(name).gainprm
        model.actuator(name).biasprm[:] = scene_model.actuator(name).biasprm
    return dataclasses.replace(robot, mj_model=model)


def with_scene_springs(robot: Robot, scene_model: mujoco.MjModel) -> Robot:
    """``robot`` with the springs that run in ``scene_model`` and its home re-solved for them.

    A spec's ``actuators.spring`` / ``actuators.backlash`` set the scene's springs
    (:func:`walkrepro.sim.springs.set_springs`), not the shared :func:`load_robot` model's. At
    home the link posture and each spring's torque τ on its link stay the robot's (the load
    does not depend on the springs); the spring DoF takes the deflection that holds τ with
    the scene's K and b (:func:`walkrepro.sim.springs.preload_deflection`), the motor DoF
    q_m = q_link − q_s, and the servo target moves with q_m (its torque stays τ). Returns a
    copy whose ``mj_model`` carries the scene's springs, ``spring_stiffness`` their K, and
    ``home_qpos`` / ``home_ctrl`` the new pre-load; ``robot`` itself when nothing differs.
    """
    if robot.spring_stiffness is None:
        return robot
    own = robot.mj_model
    names = robot.joint_names
    laws = [spring_law(own, j) for j in names]
    scene = [spring_law(scene_model, j) for j in names]
    if laws == scene:
        return robot
    model = copy.copy(own)  # MjModel copies its arrays
    data = mujoco.MjData(own)
    data.qpos[:] = robot.home_qpos
    mujoco.mj_forward(own, data)
    qpos, ctrl = np.array(robot.home_qpos), np.array(robot.home_ctrl)
    for i, name in enumerate(names):
        tendon, spring = spring_tendon(own, name), own.joint(name)
        if tendon >= 0:
            model.tendon_stiffness[tendon] = scene_model.tendon_stiffness[tendon]
            model.tendon_lengthspring[tendon] = scene_model.tendon_lengthspring[tendon]
        else:
            model.jnt_stiffness[spring.id] = scene_model.jnt_stiffness[spring.id]
        torque = float(data.qfrc_spring[spring.dofadr[0]])  # the spring's torque on the link
        q_s = preload_deflection(torque, *scene[i])
        shift = q_s - qpos[spring.qposadr[0]]
        qpos[spring.qposadr[0]] = q_s
        qpos[own.joint(name + MOTOR_SUFFIX).qposadr[0]] -= shift  # the link angle stays
        if robot.control_mode == "position":
            ctrl[i] -= shift  # the servo's target moves with its motor
    return dataclasses.replace(
        robot,
        mj_model=model,
        spring_stiffness=_frozen(np.array([k for k, _ in scene])),
        home_qpos=_frozen(qpos),
        home_ctrl=_frozen(ctrl),
    )


# ---- helpers ----------------------------------------------------------------------------


def _text(model: mujoco.MjModel, text_id: int) -> str:
    """The data of an MJCF ``<custom><text>`` element."""
    start = int(model.text_adr[text_id])
    return bytes(model.text_data[start : start + int(model.text_size[text_id]) - 1]).decode()


def _motor_only(adr: LinkAddresses) -> LinkAddresses:
    """The first component (the motor DoF) of each joint's addresses."""
    first = np.asarray(adr.adr)[np.asarray(adr.starts)]
    return LinkAddresses(np.array(first, dtype=int), np.arange(len(first), dtype=int))


def _frozen(x: np.ndarray) -> np.ndarray:
    """A read-only copy: cached robots are shared between callers."""
    out = np.array(x, copy=True)
    out.flags.writeable = False
    return out


def _joint_id(model: mujoco.MjModel, name: str) -> int:
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)


def _link_addresses(
    model: mujoco.MjModel, joint_names: tuple[str, ...], attr: str
) -> LinkAddresses:
    """Addresses (``qposadr`` or ``dofadr``) of each joint's motor (if any) then link DoF."""
    adr: list[int] = []
    starts: list[int] = []
    for name in joint_names:
        starts.append(len(adr))
        for jname in (name + MOTOR_SUFFIX, name):
            jid = _joint_id(model, jname)
            if jid >= 0:
                adr.append(int(getattr(model, f"jnt_{attr}")[jid]))
    return LinkAddresses(np.array(adr, dtype=int), np.array(starts, dtype=int))


def _check_conventions(model: mujoco.MjModel, joint_names: tuple[str, ...], xml_path: Path) -> None:
    """Fail early, naming the file, when the MJCF lacks what other modules rely on."""
    problems = []
    if (
        model.nbody < 2
        or model.body(1).name != "pelvis"
        or model.jnt_type[0] != mujoco.mjtJoint.mjJNT_FREE
    ):
        problems.append("the first body must be 'pelvis' with a free joint")
    for body in FOOT_BODIES:
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body) < 0:
            problems.append(f"no body {body!r}")
    for site in (*SOLE_SITES, *FT_SITES, IMU_SITE):
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site) < 0:
            problems.append(f"no site {site!r}")
    sensors = tuple(model.sensor(i).name for i in range(model.nsensor))
    if sorted(sensors) != sorted(SENSOR_NAMES):
        problems.append(f"sensors must be exactly {SENSOR_NAMES}, got {sensors}")
    for i, name in enumerate(joint_names):
        if _joint_id(model, name) < 0:
            problems.append(f"actuator {name!r} is not named after a link-side joint")
        target = model.actuator_trnid[i, 0]
        if model.joint(target).name not in (name, name + MOTOR_SUFFIX):
            problems.append(f"actuator {name!r} drives joint {model.joint(target).name!r}")
    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, HOME_KEY) < 0:
        problems.append(f"no keyframe {HOME_KEY!r}")
    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "left_foot_sole") < 0:
        problems.append("no sole geom 'left_foot_sole'")
    if problems:
        raise ValueError(f"{xml_path}: " + "; ".join(problems))


def _build_pin_model(xml_path: Path, rigid_twin: bool) -> pin.Model:
    """Pinocchio model of the MJCF; for series-elastic robots, of its rigid twin.

    Pinocchio (checked with 4.1) turns the MJCF free joint into a ``JointModelFreeFlyer`` named ``root``
    (no root joint must be passed), bodies into BODY frames and sites into OP_FRAMEs, and
    reads joint ``armature`` into ``model.armature`` (which ``crba`` adds to M) and
    ``damping`` into ``model.damping``. Two hinges in one body would become one composite
    joint, hence the rigid twin.
    """
    if not rigid_twin:
        return pin.buildModelFromMJCF(str(xml_path))
    tree = ET.parse(xml_path)
    root = tree.getroot()
    # Only kinematics and inertia matter to Pinocchio; the keyframe has MuJoCo's nq.
    for tag in ("actuator", "sensor", "keyframe"):
        for el in root.findall(tag):
            root.remove(el)
    for body in root.iter("body"):
        for motor in [j for j in body.findall("joint") if j.get("name", "").endswith(MOTOR_SUFFIX)]:
            link = next(
                j
                for j in body.findall("joint")
                if j.get("name") == motor.get("name")[: -len(MOTOR_SUFFIX)]
            )
            # Rigid spring: the link moves with the motor, so it gets the motor's range and
            # both DoFs' inertia and damping; the spring's stiffness disappears.
            link.set("range", motor.get("range", ""))
            for attr in ("armature", "damping"):
                link.set(attr, repr(float(motor.get(attr, 0)) + float(link.get(attr, 0))))
            link.attrib.pop("stiffness", None)
            body.remove(motor)
    # Pinocchio's MJCF parser reads files, not strings: go through a temporary file.
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"{xml_path.parent.name}_rigid_twin.xml"
        tree.write(path, encoding="unicode")
        return pin.buildModelFromMJCF(str(path))
