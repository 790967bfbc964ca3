"""The compiled control tick of the E-FSM controller (Lee et al. 2021).

:func:`tick` is everything a control period does after Pinocchio's ``computeAllTerms``: the
feet's frames, the walking frame O_w (§III-A1), the E-FSM (:mod:`.fsm`, Table I), the
footstep planner, A⁻¹ and J̇_c q̇, Γ (:mod:`.wbc`, Eq. 7) and the expected and measured
CoPs, then the logged signals. It is one numba call because the Python around it cost
more than the algebra: numba's dispatcher types each argument in Python at every call
(≈ 50 ns an array, µs a named tuple or a structured array), a Pinocchio call ≈ 1 µs, a line
of Python ≈ 0.1 µs. So the tick takes one argument, :class:`TickRecords` (a record of
:mod:`walkrepro.runtime.records`, made once at reset and again on the first tick), which
holds the views of Pinocchio's ``Data``, the parameters (:class:`TickParams`, made at reset),
the targets the first tick records (:class:`WalkTargets`, Table II), the state
(:func:`tick_state`) and the signal record. Records passed between compiled functions
(:class:`.wbc.WbcDynamics`, :class:`.fsm.FsmInput`, …) are named tuples built in compiled
code, where they cost nothing. ``cache=True`` keeps the machine code on disk, so only the
first process compiles; the controller's reset compiles or loads it with two throwaway
ticks.

The signals the tick writes are declared once, :data:`SIGNALS`; :func:`signal_dtype` makes
the record the tick writes them into by name, :func:`signal_layout` the log's layout of the
same values.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from walkrepro.log.signals import SignalLayout
from walkrepro.papers.lee2021.fsm import (
    DS_TO_SSD,
    FsmInput,
    FsmOutput,
    FsmParams,
    Phase,
    capture_point,
    epsilon,
    fsm_step,
    transition_distance,
    weight_shift_cop,
)
from walkrepro.papers.lee2021.tasks import ANGULAR, LINEAR, SPATIAL
from walkrepro.papers.lee2021.wbc import (
    WbcDynamics,
    WbcFrames,
    WbcOutput,
    WbcParams,
    WbcTargets,
    whole_body_torques,
)
from walkrepro.runtime.records import define_record
from walkrepro.sim.robot import frame_classical_acceleration

#: Compiled, cached on disk; float division by zero gives inf/NaN as in numpy.
_jit = numba.njit(cache=True, error_model="numpy")

#: The same, inlined into its caller in numba's IR (the same operations, so the same
#: results): for the functions that take the tick's large records, which a compiled call
#: would otherwise pass by value, each array's reference count raised and dropped per call.
_inline = numba.njit(cache=True, error_model="numpy", inline="always")

#: Axes of a point or vector; its x and y; a wrench's force and moment.
X, Y, Z = 0, 1, 2
XY = slice(X, Z)
FORCE, MOMENT = LINEAR, ANGULAR
#: The feet, indexed as ``controller.FEET``: 0 left, 1 right (1 − i the other one).
LEFT, RIGHT = 0, 1
#: The rows of :func:`tick_state`'s ``pin_state``: Pinocchio's q, then v.
Q_ROW, V_ROW = 0, 1


# ---- Pinocchio's last steps, in the tick ----------------------------------------------------
# After computeAllTerms (and computeMinverse, for A⁻¹) a tick also needs the soles' and F/T
# frames' placements and the soles' classical accelerations. Calling Pinocchio for them from
# Python costs about 1 µs of binding per call and a fresh array; computing them in the tick
# costs well under a µs. The placements are the matrix expressions (tests/test_efsm_kernels.py
# checks them against Pinocchio at a tolerance); the classical acceleration is
# robot.frame_classical_acceleration, shared with Paper III's controller.


@_jit
def symmetric_from_upper(upper: np.ndarray) -> np.ndarray:
    """The symmetric matrix whose upper triangle is ``upper``'s (Pinocchio fills only the
    upper triangle of ``data.M`` and ``data.Minv``): the upper triangle mirrored (a copy
    loop: ``np.triu(m) + np.triu(m, 1).T`` gives the same values for 1 µs more)."""
    out = upper.copy()
    for i in range(out.shape[0]):
        for j in range(i):
            out[i, j] = out[j, i]
    return out


@_jit
def frame_placement(
    joint_rot: np.ndarray, joint_pos: np.ndarray, local_rot: np.ndarray, local_pos: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A frame's world placement oMf = oMi · iMf (Pinocchio's ``updateFramePlacements``).

    Args:
        joint_rot, joint_pos: ``data.oMi[j]`` of the frame's joint.
        local_rot, local_pos: the frame's placement in the joint (``model.frames[f]``).

    Returns:
        The frame's world rotation (3, 3) and position (3,) [m].
    """
    return joint_rot @ local_rot, joint_pos + joint_rot @ local_pos


class WalkingFrame(NamedTuple):
    """The walking frame O_w of a tick (§III-A1) and what the E-FSM reads in it.

    Attributes:
        yaw: O_w's yaw in the world [rad].
        com_w: the CoM in O_w [m], shape (3,).
        vcom_w: the CoM velocity in O_w axes [m/s], shape (3,).
        x_s: the swing sole centre along x of O_w [m].
    """

    yaw: float
    com_w: np.ndarray
    vcom_w: np.ndarray
    x_s: float


@_jit
def ow_frame(
    p_sup: np.ndarray, p_sw: np.ndarray, com: np.ndarray, vcom: np.ndarray, rot_w: np.ndarray
) -> WalkingFrame:
    """O_w (§III-A1): origin at the support sole centre, z up, x toward the swing sole's
    ground projection; and the CoM and swing foot in it.

    Args:
        p_sup: support sole centre [m]; p_sw: swing sole centre [m].
        com, vcom: CoM position [m] and velocity [m/s] in the world.
        rot_w: out: the world-from-O_w rotation, (3, 3).
    """
    yaw = math.atan2(p_sw[Y] - p_sup[Y], p_sw[X] - p_sup[X])
    c, s = math.cos(yaw), math.sin(yaw)
    rot_w[:] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    w_from_world = np.ascontiguousarray(rot_w.T)
    return WalkingFrame(
        yaw, w_from_world @ (com - p_sup), w_from_world @ vcom, (w_from_world @ (p_sw - p_sup))[X]
    )


@_jit
def measured_cop(
    ft_rot: np.ndarray,
    ft_pos: np.ndarray,
    wrench_left: np.ndarray,
    wrench_right: np.ndarray,
    foot_com: np.ndarray,
    foot_weight: np.ndarray,
) -> tuple[float, float]:
    """The CoP (x, y) in the world from the two F/T sensors (§VI-D2) [m]; NaN if unloaded.

    Each sensor reads the wrench the foot applies to the leg; adding back the static weight
    of the part below the sensor (the ankle-roll link, i.e. the foot) gives the ground
    reaction. Feet carrying no vertical load are left out. The CoP is the point on z = 0
    about which the summed moment has no x/y part.

    Args:
        ft_rot: world-from-sensor rotation of each F/T frame (left, right), shape (2, 3, 3).
        ft_pos: position of each F/T frame in the world (left, right) [m], shape (2, 3).
        wrench_left, wrench_right: each sensor's (f, τ) in its frame [N, Nm].
        foot_com: centre of mass of the part below each sensor, sensor frame [m], (2, 3).
        foot_weight: weight of that part (left, right) [N], shape (2,).
    """
    force_z = 0.0
    moment = np.zeros(3)  # about the world origin [Nm]
    for foot in (LEFT, RIGHT):
        wrench = wrench_left if foot == LEFT else wrench_right
        rot, pos = ft_rot[foot], ft_pos[foot]
        force = rot @ wrench[FORCE]  # [N], world axes
        weight = np.array([0.0, 0.0, foot_weight[foot]])  # [N], along +z
        if force[Z] + weight[Z] <= 0.0:
            continue
        com = pos + rot @ foot_com[foot]  # [m], world
        force_z += force[Z] + weight[Z]
        moment += rot @ wrench[MOMENT] + np.cross(pos, force) + np.cross(com, weight)
    if force_z <= 1e-6:
        return math.nan, math.nan
    return -moment[Y] / force_z, moment[X] / force_z


@_jit
def next_swing_target(
    p_sup: np.ndarray,
    swing: int,
    steps_done: int,
    step_length: float,
    n_steps: int,
    width: float,
    heading: np.ndarray,
    lateral: np.ndarray,
    first_scale: float = 1.0,
) -> np.ndarray:
    """Footstep planner: the next swing-foot target, step_length ahead of the support [m].

    After ``n_steps`` footsteps (``n_steps`` ≥ 0) the targets are beside the support foot
    (stepping in place), so the E-FSM keeps its cycle without a separate stopping state.

    Args:
        p_sup: the new support sole centre [m]; swing: the new swing foot (0 left, 1 right).
        steps_done: footsteps so far, this one included.
        step_length: [m]; n_steps: footsteps of step_length (−1: no limit).
        width: lateral foot spacing [m].
        heading, lateral: the walking direction and the left-pointing lateral axis.
        first_scale: the first footstep's length as a fraction of step_length
            (``EfsmParams.first_step_scale``; the lab's half step: 0.5).
    """
    side = 1.0 if swing == 0 else -1.0
    length = step_length if n_steps < 0 or steps_done <= n_steps else 0.0
    if steps_done == 1:
        length *= first_scale
    return p_sup + length * heading + (side * width) * lateral


# ---- the tick's records --------------------------------------------------------------------

#: The signals :func:`tick` logs, declared once: (name, size: 0 a scalar, else the length
#: of an array, integer). The last, ``tau_ref`` [Nm] (Γ, actuator order), has one entry per
#: actuator (size -1 here: :func:`signal_layout` and :func:`signal_dtype` fill it in).
SIGNALS: tuple[tuple[str, int, bool], ...] = (
    ("fsm_state", 0, True),  # 0 in DS, else +1 left support, −1 right
    ("efsm_phase", 0, True),  # fsm.Phase
    ("epsilon", 0, False),  # ε (§IV-B)
    ("epsilon_onset", 0, False),  # ε's DS-onset ramp
    ("d", 0, False),  # distance to the termination criterion [m] (1 when infinite)
    ("com_w", 3, False),  # CoM in O_w [m]
    ("com_vel_w", 3, False),  # [m/s]
    ("com_world", 3, False),
    ("com_vel_world", 3, False),
    ("cp_w", 0, False),  # capture point along x of O_w, Eq. (2) [m]
    ("cp_ref_w", 0, False),  # x_s − r, law L2 [m]
    ("x_s_w", 0, False),  # swing-foot centre along x of O_w [m]
    ("xp_des_w", 0, False),  # x_p^des along x of O_w [m]
    ("xp_des_world", 2, False),
    ("cop_exp_w", 2, False),  # expected CoP in O_w [m]
    ("cop_exp_world", 2, False),
    ("cop_meas_world", 2, False),  # measured CoP [m] (0 when no foot is loaded)
    ("cop_meas_valid", 0, True),
    ("swing_pos_world", 3, False),
    ("swing_ref_world", 3, False),
    ("swing_foot", 0, True),  # 0 in DS, else +1 right swinging, −1 left
    ("support_pos_world", 3, False),
    ("ow_yaw", 0, False),  # [rad]
    ("com_force_x", 0, False),  # F_1 [N]
    ("balancing", 0, True),  # F_3^bal acted
    ("steps_done", 0, True),
    ("tau_ref", -1, False),
)


def _sized(n_actuators: int) -> list[tuple[str, int, bool]]:
    """:data:`SIGNALS` with ``tau_ref``'s size."""
    return [(name, n_actuators if size < 0 else size, integer) for name, size, integer in SIGNALS]


def signal_layout(n_actuators: int) -> SignalLayout:
    """The log's layout of :data:`SIGNALS` for ``n_actuators`` joints."""
    return SignalLayout(_sized(n_actuators))


def signal_dtype(n_actuators: int) -> np.dtype:
    """The record :func:`tick` writes :data:`SIGNALS` into, by name: float64 fields packed
    in declaration order, so that a record's bytes, viewed as float64, are the values in
    :func:`signal_layout`'s order."""
    return np.dtype(
        [
            (name, np.float64, (size,)) if size else (name, np.float64)
            for name, size, _ in _sized(n_actuators)
        ]
    )


class FootFrames(NamedTuple):
    """Each foot's constant frames in the kinematic tree (left, right; from the model).

    Attributes:
        sole_chain: whether each velocity coordinate moves the sole (1/0), shape (2, n).
        sole_local_rot, sole_local_pos: the sole frame in its joint (ankle roll), (2, 3, 3)
            and (2, 3) [m].
        ft_local_rot, ft_local_pos: the F/T sensor frame in the same joint.
        foot_com: the CoM of the part below the F/T sensor, sensor frame [m], (2, 3).
        foot_weight: that part's weight [N], shape (2,) (:func:`measured_cop`).
    """

    sole_chain: np.ndarray
    sole_local_rot: np.ndarray
    sole_local_pos: np.ndarray
    ft_local_rot: np.ndarray
    ft_local_pos: np.ndarray
    foot_com: np.ndarray
    foot_weight: np.ndarray


class TickParams(NamedTuple):
    """The controller's parameters as the tick reads them, made once at reset
    (``EfsmParams``; :meth:`.controller.EfsmController.reset`).

    Attributes:
        fsm: the E-FSM's (:class:`.fsm.FsmParams`). wbc: the OS-WBC's, with its task
            hierarchy (:class:`.wbc.WbcParams`).
        ds_onset_ramp: ε's ramp at DS onset (``EfsmParams.ds_onset_ramp``).
        raise_height, land_height: swing heights in SSD and otherwise (Table II) [m].
        step_length [m], n_steps (−1: no limit), first_step_scale: the footstep planner.
        shift_ticks: the first DS's weight shift in ticks (``EfsmParams.first_ds_shift``).
        control_period: [s].
        feet: :class:`FootFrames`.
    """

    fsm: FsmParams
    wbc: WbcParams
    ds_onset_ramp: bool
    raise_height: float
    land_height: float
    step_length: float
    n_steps: int
    first_step_scale: float
    shift_ticks: int
    control_period: float
    feet: FootFrames


class WalkTargets(NamedTuple):
    """The walk's targets, recorded on the first tick from the standing robot (Table II).

    Attributes:
        z_m0: the CoM height above the soles (Eq. 2) [m].
        width: the lateral foot spacing [m].
        heading, lateral: the walking direction and the left-pointing axis, world (3,).
        rot_des_pelvis, rot_des_swing: orientation targets, world-from-target (level, the
            initial heading).
    """

    z_m0: float
    width: float
    heading: np.ndarray
    lateral: np.ndarray
    rot_des_pelvis: np.ndarray
    rot_des_swing: np.ndarray


def tick_state(nq: int, nv: int, n_actuators: int) -> np.ndarray:
    """A zeroed state of :func:`tick`: one numpy record (a structured array of length 1),
    what the tick reads and writes and nothing it only reads (:class:`TickParams`).

    The controller keeps views of the fields it writes or reads (``state["tau"][0]`` is a
    view).

    Fields:
        support (0 left, 1 right), phase (:class:`.fsm.Phase`), xp_des [m], ds_start_xp
            (x_p^des when DS started; NaN out of DS) [m], steps_done, swing_target [m]: the
            E-FSM's and the planner's state.
        shift_tick: the ticks done of the first DS's weight shift.
        rot_w: world-from-O_w, rewritten every tick.
        pin_state: Pinocchio's q (row :data:`Q_ROW`, first nq entries) and v (row
            :data:`V_ROW`, first nv entries) of the tick, written by the controller
            (:func:`walkrepro.sim.robot.pin_state_into`).
        ft_wrench: per foot, the F/T reading of the tick (see :func:`measured_cop`), written
            by the controller.
        tau: out: actuator torques [Nm].
    """
    f8, i8 = np.float64, np.int64
    fields = [
        ("support", i8),
        ("phase", i8),
        ("xp_des", f8),
        ("ds_start_xp", f8),
        ("steps_done", i8),
        ("swing_target", f8, (3,)),
        ("shift_tick", i8),
        ("rot_w", f8, (3, 3)),
        ("pin_state", f8, (2, max(nq, nv))),
        ("ft_wrench", f8, (2, SPATIAL)),
        ("tau", f8, (n_actuators,)),
    ]
    return np.zeros(1, dtype=np.dtype(fields, align=True))


class PinocchioTerms(NamedTuple):
    """What a tick reads of Pinocchio's ``computeAllTerms`` (views of ``Data``), world axes.

    Attributes:
        mass_inv: A⁻¹, ``data.Minv`` after ``computeMinverse`` (only its upper triangle is
            read), shape (n, n).
        nle: b + g, ``data.nle``, shape (n,).
        j_world: the joint Jacobians ``data.J``, shape (6, n).
        j_com: the CoM Jacobian ``data.Jcom``, shape (3, n).
        com: the CoM ``data.com[0]`` [m]; vcom: its velocity ``data.vcom[0]`` [m/s].
        pelvis_rot: world-from-pelvis rotation, ``data.oMi[1].rotation``.
    """

    mass_inv: np.ndarray
    nle: np.ndarray
    j_world: np.ndarray
    j_com: np.ndarray
    com: np.ndarray
    vcom: np.ndarray
    pelvis_rot: np.ndarray


class FootJoint(NamedTuple):
    """The joint j carrying one foot's sole and F/T frame, after ``computeAllTerms`` (views).

    Attributes:
        rot, pos: its placement ``data.oMi[j]``: world-from-joint rotation, position [m].
        vel: its spatial velocity ``data.v[j].vector`` (v [m/s], ω [rad/s]), joint axes.
        acc: its bias acceleration ``data.a[j].vector`` (q̈ = 0), joint axes.
    """

    rot: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray


#: Everything :func:`tick` reads and writes, as one argument (:mod:`walkrepro.runtime.records`):
#: ``terms`` (:class:`PinocchioTerms`) and ``feet`` (:class:`FootJoint` of the left, then the
#: right foot), views of Pinocchio's ``Data``; ``params`` (:class:`TickParams`); ``targets``
#: (:class:`WalkTargets`); ``state`` (:func:`tick_state`) and ``signals`` (a record of
#: :func:`signal_dtype`). Make it with :func:`tick_records`.
TickRecordsType, TickRecords = define_record(
    "TickRecords", ("terms", "feet", "params", "targets", "state", "signals"), __name__
)


@_jit
def tick_records(
    terms: PinocchioTerms,
    feet: tuple[FootJoint, FootJoint],
    params: TickParams,
    targets: WalkTargets,
    state: np.ndarray,
    signals: np.ndarray,
) -> TickRecords:
    """The :class:`TickRecords` of these views and records (``feet``: left, right); compiled
    and cached, unlike the proxy's own constructor."""
    return TickRecords(terms, feet, params, targets, state, signals)


# ---- the control tick: O_w, E-FSM, footsteps, OS-WBC ----------------------------------------


class FootPlacements(NamedTuple):
    """The soles' and F/T frames' world placements of a tick (left, right).

    Attributes:
        sole_rot, sole_pos: world-from-sole rotations (2, 3, 3), sole centres [m] (2, 3).
        ft_rot, ft_pos: the same of the F/T sensor frames.
    """

    sole_rot: np.ndarray
    sole_pos: np.ndarray
    ft_rot: np.ndarray
    ft_pos: np.ndarray


@_inline
def place_feet(feet: tuple[FootJoint, FootJoint], frames: FootFrames) -> FootPlacements:
    """The soles and the F/T frames (left, right), as ``updateFramePlacements``."""
    out = FootPlacements(
        np.empty((2, 3, 3)), np.empty((2, 3)), np.empty((2, 3, 3)), np.empty((2, 3))
    )
    for f in (LEFT, RIGHT):
        rot, pos = feet[f].rot, feet[f].pos
        out.sole_rot[f], out.sole_pos[f] = frame_placement(
            rot, pos, frames.sole_local_rot[f], frames.sole_local_pos[f]
        )
        out.ft_rot[f], out.ft_pos[f] = frame_placement(
            rot, pos, frames.ft_local_rot[f], frames.ft_local_pos[f]
        )
    return out


class EfsmTick(NamedTuple):
    """The E-FSM's part of a tick (:func:`efsm_tick`).

    Attributes:
        fsm: :class:`.fsm.FsmOutput` (its ``xp_des`` in the old O_w when DS ended).
        ow: :class:`WalkingFrame` of the tick's support foot.
        x_cp: the capture point along x of O_w, Eq. (2) [m].
        xp_des: x_p^des in that O_w [m].
    """

    fsm: FsmOutput
    ow: WalkingFrame
    x_cp: float
    xp_des: float


@_inline
def efsm_tick(
    params: TickParams,
    targets: WalkTargets,
    st: np.ndarray,
    sole_pos: np.ndarray,
    com: np.ndarray,
    vcom: np.ndarray,
) -> EfsmTick:
    """O_w and the E-FSM inputs (§III-A1, Eq. 2), the E-FSM (Table I), and when DS ends the
    feet's new roles and the next footstep; ``st`` (:func:`tick_state`) updated."""
    sup, rot_w, z_m0 = st.support, st.rot_w, targets.z_m0
    sw = 1 - sup
    ow = ow_frame(sole_pos[sup], sole_pos[sw], com, vcom, rot_w)
    x_cp = capture_point(ow.com_w[X], ow.vcom_w[X], z_m0)
    fsm_input = FsmInput(ow.com_w[X], ow.vcom_w[X], x_cp, ow.x_s)
    fp = params.fsm
    if st.phase == Phase.DS and st.steps_done == 0 and st.shift_tick < params.shift_ticks:
        # The first DS's weight shift (EfsmParams.first_ds_shift): the lab's capture-point
        # law puts x_p^des until the shift's time is up; ε and d as in every DS (§IV-B).
        st.shift_tick += 1
        remaining = (params.shift_ticks - st.shift_tick) * params.control_period
        xp_shift = weight_shift_cop(x_cp, ow.x_s, remaining, z_m0)
        d_shift = transition_distance(Phase.DS, ow.x_s, xp_shift, x_cp, fp.r)
        eps_shift = epsilon(d_shift, fp.d_thr) if fp.use_epsilon else 1.0
        fsm = FsmOutput(Phase.DS.value, xp_shift, eps_shift, d_shift, 0)
    else:
        fsm = fsm_step(st.phase, st.xp_des, fsm_input, fp)
    xp_des = fsm.xp_des
    if fsm.transitions & DS_TO_SSD:
        # DS ends: the swing foot becomes the support foot; next footstep target; O_w moves
        # (x_p^des, the new support centre, is 0 in it).
        sup, sw = sw, sup
        st.support = sup
        st.steps_done += 1
        st.swing_target[:] = next_swing_target(
            sole_pos[sup], sw, st.steps_done, params.step_length, params.n_steps,
            targets.width, targets.heading, targets.lateral, params.first_step_scale,
        )  # fmt: skip
        ow = ow_frame(sole_pos[sup], sole_pos[sw], com, vcom, rot_w)
        x_cp = capture_point(ow.com_w[X], ow.vcom_w[X], z_m0)
        xp_des = 0.0
    st.phase, st.xp_des = fsm.phase, xp_des
    return EfsmTick(fsm, ow, x_cp, xp_des)


@_inline
def ds_onset(params: TickParams, st: np.ndarray, xp_des: float) -> float:
    """ε's ramp at DS onset (``EfsmParams.ds_onset_ramp``): the landing foot's wrench grows
    from 0 over the first d^thr of the x_p^des ramp; 1 out of DS (``st`` updated)."""
    if st.phase != Phase.DS:
        st.ds_start_xp = math.nan  # Γ_c = 0
        return 1.0
    if math.isnan(st.ds_start_xp):
        st.ds_start_xp = xp_des
    # Not in the first DS's weight shift: both feet stand from the start, none lands.
    standing = st.steps_done == 0 and params.shift_ticks > 0
    if params.fsm.use_epsilon and params.ds_onset_ramp and not standing:
        return epsilon(abs(xp_des - st.ds_start_xp), params.fsm.d_thr)
    return 1.0


@_inline
def contact_bias(
    feet: tuple[FootJoint, FootJoint], frames: FootFrames, sup: int, double: bool
) -> np.ndarray:
    """J̇_c q̇ of the contacts, as Pinocchio's classical accelerations: the support sole,
    then the swing sole in DS, shape (6 or 12,)."""
    contacts = (sup, 1 - sup) if double else (sup, sup)
    bias = np.empty((2, SPATIAL))
    for i, f in enumerate(contacts):
        frame_classical_acceleration(
            feet[f].rot, feet[f].vel, feet[f].acc, frames.sole_local_pos[f], bias[i]
        )
    return bias.ravel() if double else bias[LEFT].copy()


@_inline
def write_signals(
    out: np.ndarray,
    st: np.ndarray,
    terms: PinocchioTerms,
    efsm: EfsmTick,
    eps_onset: float,
    sole_pos: np.ndarray,
    swing_ref: np.ndarray,
    wbc: WbcOutput,
    cop_meas: tuple[float, float],
    r: float,
) -> None:
    """The signals (:data:`SIGNALS`) of a tick into ``out``, by name."""
    ow, fsm, sup = efsm.ow, efsm.fsm, st.support
    sw = 1 - sup
    double = st.phase == Phase.DS
    p_sup, p_sw, rot_w = sole_pos[sup], sole_pos[sw], st.rot_w
    out.fsm_state = 0.0 if double else (1.0 if sup == LEFT else -1.0)
    out.efsm_phase = st.phase
    out.epsilon, out.epsilon_onset = fsm.epsilon, eps_onset
    out.d = fsm.d if math.isfinite(fsm.d) else 1.0
    out.com_w[:] = ow.com_w
    out.com_vel_w[:] = ow.vcom_w
    out.com_world[:] = terms.com
    out.com_vel_world[:] = terms.vcom
    out.cp_w, out.cp_ref_w, out.x_s_w, out.xp_des_w = efsm.x_cp, ow.x_s - r, ow.x_s, efsm.xp_des
    rot_w_xy = rot_w[XY, XY]  # (c, −s; s, c)
    out.xp_des_world[:] = p_sup[XY] + rot_w_xy[:, X] * efsm.xp_des
    out.cop_exp_w[X], out.cop_exp_w[Y] = wbc.cop_exp_x, wbc.cop_exp_y
    out.cop_exp_world[:] = p_sup[XY] + rot_w_xy @ out.cop_exp_w
    meas_valid = math.isfinite(cop_meas[X]) and math.isfinite(cop_meas[Y])
    if meas_valid:
        out.cop_meas_world[X], out.cop_meas_world[Y] = cop_meas
    else:  # no foot loaded: logs hold finite numbers only
        out.cop_meas_world[:] = 0.0
    out.cop_meas_valid = meas_valid
    out.swing_pos_world[:] = p_sw
    out.swing_ref_world[:] = swing_ref
    out.swing_foot = 0.0 if double else (1.0 if sup == LEFT else -1.0)
    out.support_pos_world[:] = p_sup
    out.ow_yaw = ow.yaw
    out.com_force_x, out.balancing, out.steps_done = wbc.com_force_x, wbc.balancing, st.steps_done
    out.tau_ref[:] = st.tau


@_jit
def tick(records: TickRecords) -> int:
    """``EfsmController.step`` after computeAllTerms: O_w, the E-FSM, the footstep planner,
    Γ (Eq. 7) and the expected and measured CoP.

    Args:
        records: (:class:`TickRecords`) ``terms`` and ``feet``: views of ``Data`` after
            computeAllTerms; ``params``, ``targets``: read; ``state``: :func:`tick_state`,
            read and updated (``ft_wrench``: the tick's F/T readings, written by the
            controller; ``tau`` is written); ``signals``: out: a record of
            :func:`signal_dtype` (length 1), every field written.

    Returns:
        The E-FSM transitions of the tick as bits (:data:`.fsm.DS_TO_SSD`: the feet swapped
        roles).
    """
    terms, feet, params, targets = records.terms, records.feet, records.params, records.targets
    st = records.state[0]
    placed = place_feet(feet, params.feet)
    efsm = efsm_tick(params, targets, st, placed.sole_pos, terms.com, terms.vcom)
    phase, sup, rot_w = st.phase, st.support, st.rot_w
    sw = 1 - sup
    double = phase == Phase.DS
    p_sup, p_sw = placed.sole_pos[sup], placed.sole_pos[sw]
    # The swing-foot reference (Table II): the planned xy, raised in SSD, lowered otherwise.
    swing_ref = st.swing_target.copy()
    swing_ref[Z] = p_sup[Z] + (params.raise_height if phase == Phase.SSD else params.land_height)
    eps_onset = ds_onset(params, st, efsm.xp_des)
    # The CoM target (Table II): y 0 and z z_m0 in O_w; along x task 1 follows x_p^des.
    com_ref = p_sup + rot_w @ np.array([efsm.ow.com_w[X], 0.0, targets.z_m0])
    n = terms.mass_inv.shape[0]
    # Γ = Γ_t + Γ_c + Γ_gc (Eqs. 7 and 11, Appendices A–D), saturated, actuator order.
    wbc = whole_body_torques(
        WbcDynamics(
            symmetric_from_upper(terms.mass_inv), terms.nle, contact_bias(feet, params.feet, sup, double),
            terms.j_world, terms.j_com, terms.com, terms.vcom, st.pin_state[V_ROW, :n],
        ),
        WbcFrames(
            rot_w, p_sup, p_sw, placed.sole_rot[sup], placed.sole_rot[sw], terms.pelvis_rot,
            params.feet.sole_chain[sup], params.feet.sole_chain[sw],
        ),
        WbcTargets(
            targets.rot_des_pelvis, targets.rot_des_swing, com_ref, swing_ref, phase,
            efsm.fsm.epsilon, eps_onset, efsm.xp_des, efsm.ow.x_s,
        ),
        params.wbc,
        st.tau,
    )  # fmt: skip
    cop_meas = measured_cop(
        placed.ft_rot, placed.ft_pos, st.ft_wrench[LEFT], st.ft_wrench[RIGHT],
        params.feet.foot_com, params.feet.foot_weight,
    )  # fmt: skip
    write_signals(
        records.signals[0], st, terms, efsm, eps_onset, placed.sole_pos, swing_ref, wbc, cop_meas,
        params.fsm.r,
    )  # fmt: skip
    return efsm.fsm.transitions
