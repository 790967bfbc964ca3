"""The compiled control tick of the E-FSM controller (Lee et al. 2021).

:func:`tick` is everything a control period does after Pinocchio's ``computeAllTerms``: the
feet's frames, the walking frame O_w (§III-A1), the E-FSM (:mod:`.fsm`, Table I), the
footstep planner, A⁻¹ and J̇_c q̇, Γ (:mod:`.wbc`, Eq. 7) and the expected and measured
CoPs, then the logged signals. It is one numba call because the Python around it cost
more than the algebra: numba's dispatcher types each argument in Python at every call
(≈ 50 ns an array, µs a named tuple or a structured array; hence :class:`TickRecords`, one
StructRef of the views of Pinocchio's ``Data``, :func:`tick_state` and the signal record,
made once at reset), a Pinocchio call ≈ 1 µs, a line of Python ≈ 0.1 µs. Records passed between compiled
functions (:class:`.wbc.WbcDynamics`, :class:`.fsm.FsmInput`, …) are named tuples built in
compiled code, where they cost nothing. ``cache=True`` keeps the machine code on disk, so
only the first process compiles; the controller's reset compiles or loads it with two
throwaway ticks.

The signals the tick writes are declared once, :data:`SIGNALS`; :func:`signal_dtype` makes
the record the tick writes them into by name, :func:`signal_layout` the log's layout of the
same values.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
from numba import types
from numba.experimental import structref

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
from walkrepro.papers.lee2021.wbc import (
    WbcDynamics,
    WbcFrames,
    WbcParams,
    WbcTargets,
    whole_body_torques,
)
from walkrepro.sim.robot import eigen_rotate, frame_classical_acceleration

#: Compiled, cached on disk; float division by zero gives inf/NaN as in numpy.
_jit = numba.njit(cache=True, error_model="numpy")

# Phases of fsm.Phase, as plain ints for the compiled code.
_SSD, _DS = int(Phase.SSD), int(Phase.DS)


# ---- Pinocchio's last steps, in the tick ----------------------------------------------------
# After computeAllTerms a tick also called Pinocchio's cholesky.decompose, computeMinv and
# getFrameClassicalAcceleration: about 1 µs of Python binding each, and a fresh 18 × 18 array.
# These kernels (and robot.frame_classical_acceleration, shared with Paper III's controller)
# compute what those calls return inside the tick, in Pinocchio's operations;
# tests/test_efsm_kernels.py checks them against Pinocchio to 1e-12, and
# benchmarks/pinocchio_ports.py measures what calling Pinocchio instead would cost.


@_jit
def mass_matrix_inverse(
    mass: np.ndarray, parent: np.ndarray, subtree: np.ndarray, out: np.ndarray
) -> None:
    """A⁻¹ from A's upper triangle, as Pinocchio's ``cholesky.decompose`` + ``computeMinv``.

    A = U D Uᵀ along the kinematic tree (U unit upper triangular, non-zero only between a
    velocity coordinate and its ancestors); then column c of A⁻¹ is U⁻ᵀ D⁻¹ U⁻¹ e_c, of which
    the upper triangle is kept and mirrored. Every entry gets the terms of Pinocchio's sums
    in Pinocchio's order (left to right: its dot products run along strided rows, which
    Eigen does not vectorize). Only the loops are turned, so that independent sums
    (ancestors; columns) run side by side rather than one after the other: a direct port
    of Pinocchio's column-by-column loops cost as much as the two Python calls it replaces.

    Args:
        mass: A (``data.M`` after computeAllTerms; only its upper triangle is read), (n, n).
        parent: ``data.parents_fromRow``, (n,); subtree: ``data.nvSubtree_fromRow``, (n,).
        out: A⁻¹, both triangles, (n, n).
    """
    n = mass.shape[0]
    u = np.zeros((n, n))  # U's strict upper triangle
    d, d_inv, du, acc = np.empty((4, n))  # D, D⁻¹ and two work vectors: one allocation
    rows = np.empty(n, dtype=np.int64)
    # cholesky.decompose, last coordinate first: D_j = A_jj − Σ_k U_jk D_k U_jk and
    # U_ij = (A_ij − Σ_k U_ik D_k U_jk) / D_j for each ancestor i, k over j's subtree.
    for j in range(n - 1, -1, -1):
        below = subtree[j] - 1  # the coordinates j + 1 … j + below move with j
        for k in range(below):
            du[k] = u[j, j + 1 + k] * d[j + 1 + k]
        n_rows, i = 0, j  # j, then its ancestors
        while i >= 0:
            rows[n_rows] = i
            n_rows += 1
            i = parent[i]
        for r in range(n_rows):  # Eigen's sums: the first term, then + each next one
            acc[r] = u[rows[r], j + 1] * du[0] if below else 0.0
        for k in range(1, below):
            for r in range(n_rows):
                acc[r] = acc[r] + u[rows[r], j + 1 + k] * du[k]
        d[j] = mass[j, j] - acc[0]
        d_inv[j] = 1.0 / d[j]
        for r in range(1, n_rows):
            u[rows[r], j] = (mass[rows[r], j] - acc[r]) * d_inv[j]
    # computeMinv: column c is e_c, then U⁻¹ (back substitution), D⁻¹ on rows ≤ c, and U⁻ᵀ
    # (forward substitution); all columns at once, the rows > c left out (Pinocchio
    # computes them, then overwrites them with the mirror image).
    # In U⁻¹ e_c only the ancestors of c (and c) are non-zero: the other terms of
    # Pinocchio's sums are ±0, which change no non-zero sum, so they are skipped; the
    # non-zero ones are added in its order, from +0.0 (its first term may be ±0: the same).
    for i in range(n):
        for c in range(n):
            out[i, c] = 1.0 if i == c else 0.0
    for k in range(n - 2, -1, -1):
        end = k + subtree[k]  # the columns below k: k + 1 … end − 1
        acc[k + 1 : end] = 0.0
        for i in range(k + 1, end):
            u_ki = u[k, i]
            for c in range(i, i + subtree[i]):  # the columns with row i non-zero
                acc[c] = acc[c] + u_ki * out[i, c]
        for c in range(k + 1, end):
            out[k, c] = -acc[c]
    for k in range(n):
        for c in range(k, n):
            out[k, c] *= d_inv[k]
    for k in range(n):
        for i in range(k + 1, k + subtree[k]):
            u_ki = u[k, i]
            for c in range(i, n):
                out[i, c] -= u_ki * out[k, c]
    for i in range(n):
        for c in range(i):
            out[i, c] = out[c, i]


@_jit
def frame_placement(
    joint_rot: np.ndarray,
    joint_pos: np.ndarray,
    local_rot: np.ndarray,
    local_pos: np.ndarray,
    rot: np.ndarray,
    pos: np.ndarray,
) -> None:
    """A frame's world placement, as Pinocchio's ``updateFramePlacements`` (oMf = oMi · iMf).

    Args:
        joint_rot, joint_pos: ``data.oMi[j]`` of the frame's joint.
        local_rot, local_pos: the frame's placement in the joint (``model.frames[f]``).
        rot, pos: out: the frame's world rotation (3, 3) and position (3,) [m].
    """
    for col in range(3):
        rot[0, col], rot[1, col], rot[2, col] = eigen_rotate(
            joint_rot, local_rot[0, col], local_rot[1, col], local_rot[2, col]
        )
    x0, x1, x2 = eigen_rotate(joint_rot, local_pos[0], local_pos[1], local_pos[2])
    pos[0], pos[1], pos[2] = joint_pos[0] + x0, joint_pos[1] + x1, joint_pos[2] + x2


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
    yaw = math.atan2(p_sw[1] - p_sup[1], p_sw[0] - p_sup[0])
    c, s = math.cos(yaw), math.sin(yaw)
    rot_w[:] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    w_from_world = np.ascontiguousarray(rot_w.T)
    return WalkingFrame(
        yaw, w_from_world @ (com - p_sup), w_from_world @ vcom, (w_from_world @ (p_sw - p_sup))[0]
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
    for foot in range(2):
        wrench = wrench_left if foot == 0 else wrench_right
        rot, pos = ft_rot[foot], ft_pos[foot]
        force = rot @ wrench[:3]  # [N], world axes
        weight = np.array([0.0, 0.0, foot_weight[foot]])  # [N], along +z
        if force[2] + weight[2] <= 0.0:
            continue
        com = pos + rot @ foot_com[foot]  # [m], world
        force_z += force[2] + weight[2]
        moment += rot @ wrench[3:] + np.cross(pos, force) + np.cross(com, weight)
    if force_z <= 1e-6:
        return math.nan, math.nan
    return -moment[1] / force_z, moment[0] / force_z


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


def tick_state(nq: int, nv: int, n_actuators: int) -> np.ndarray:
    """A zeroed state of :func:`tick`: one numpy record (a structured array of length 1).

    The controller's own arrays and numbers, as one argument: numba unboxes a record in one
    step, where two dozen separate arrays and numbers cost ≈ 50 ns each. The controller
    keeps views of the fields it writes or reads (``state["tau"][0]`` is a view). A field
    with a leading axis of 2 holds one entry per foot, indexed as ``controller.FEET``
    (0 left, 1 right).

    Fields:
        kp, kv, fs_max_force, fs_max_moment, fs_saturation (wbc.CLIP, …), balance (1/0),
            cop_margin, torque_limit, half_sole: :class:`.wbc.WbcParams`.
        zeta, r, dxp, d_thr, v_stop, use_epsilon: :class:`.fsm.FsmParams`;
            ds_onset_ramp: ε's ramp at DS onset (1/0, ``EfsmParams.ds_onset_ramp``).
        step_length, n_steps (−1: no limit), width, heading, lateral: the footstep planner.
        z_m0, raise_height, land_height: CoM height (Eq. 2) and swing heights (Table II) [m].
        rot_des_pelvis, rot_des_swing: orientation targets (Table II), world-from-target.
        actuator_rows: the joint-torque row of each actuator.
        parents_from_row, nv_subtree_from_row: Pinocchio's tree (:func:`mass_matrix_inverse`).
        sole_chain: per foot, whether each velocity coordinate moves the sole (1/0).
        sole_local_rot/pos, ft_local_rot/pos: per foot, the sole and F/T frame in its joint.
        foot_com, foot_weight: per foot, as :func:`measured_cop`.
        support (0 left, 1 right), phase (fsm.Phase), xp_des [m], ds_start_xp (x_p^des when
            DS started; NaN out of DS) [m], steps_done, swing_target [m]: the E-FSM's state.
        shift_ticks, shift_tick, control_period [s]: the first DS's weight shift
            (``EfsmParams.first_ds_shift``: its length in ticks, the ticks done);
            first_step_scale: the first footstep's fraction of step_length.
        rot_w: world-from-O_w, rewritten every tick.
        pin_state: Pinocchio's q (row 0, first nq entries) and v (row 1, first nv entries)
            of the tick, written by the controller (:func:`walkrepro.sim.robot.pin_state_into`).
        ft_wrench: per foot, the F/T reading of the tick (see :func:`measured_cop`), written
            by the controller.
        tau: out: actuator torques [Nm].
    """
    f8, i8 = np.float64, np.int64
    fields = [
        ("kp", f8),
        ("kv", f8),
        ("fs_max_force", f8),
        ("fs_max_moment", f8),
        ("fs_saturation", i8),
        ("balance", i8),
        ("cop_margin", f8),
        ("torque_limit", f8),
        ("half_sole", f8, (2,)),
        ("zeta", f8),
        ("r", f8),
        ("dxp", f8),
        ("d_thr", f8),
        ("v_stop", f8),
        ("use_epsilon", i8),
        ("ds_onset_ramp", i8),
        ("step_length", f8),
        ("n_steps", i8),
        ("width", f8),
        ("heading", f8, (3,)),
        ("lateral", f8, (3,)),
        ("z_m0", f8),
        ("raise_height", f8),
        ("land_height", f8),
        ("rot_des_pelvis", f8, (3, 3)),
        ("rot_des_swing", f8, (3, 3)),
        ("actuator_rows", i8, (n_actuators,)),
        ("parents_from_row", i8, (nv,)),
        ("nv_subtree_from_row", i8, (nv,)),
        ("sole_chain", i8, (2, nv)),
        ("sole_local_rot", f8, (2, 3, 3)),
        ("sole_local_pos", f8, (2, 3)),
        ("ft_local_rot", f8, (2, 3, 3)),
        ("ft_local_pos", f8, (2, 3)),
        ("foot_com", f8, (2, 3)),
        ("foot_weight", f8, (2,)),
        ("support", i8),
        ("phase", i8),
        ("xp_des", f8),
        ("ds_start_xp", f8),
        ("steps_done", i8),
        ("swing_target", f8, (3,)),
        ("shift_ticks", i8),
        ("shift_tick", i8),
        ("control_period", f8),
        ("first_step_scale", f8),
        ("rot_w", f8, (3, 3)),
        ("pin_state", f8, (2, max(nq, nv))),
        ("ft_wrench", f8, (2, 6)),
        ("tau", f8, (n_actuators,)),
    ]
    return np.zeros(1, dtype=np.dtype(fields, align=True))


class PinocchioTerms(NamedTuple):
    """What a tick reads of Pinocchio's ``computeAllTerms`` (views of ``Data``), world axes.

    Attributes:
        mass: A, ``data.M`` (only its upper triangle is read), shape (n, n).
        nle: b + g, ``data.nle``, shape (n,).
        j_world: the joint Jacobians ``data.J``, shape (6, n).
        j_com: the CoM Jacobian ``data.Jcom``, shape (3, n).
        com: the CoM ``data.com[0]`` [m]; vcom: its velocity ``data.vcom[0]`` [m/s].
        pelvis_rot: world-from-pelvis rotation, ``data.oMi[1].rotation``.
    """

    mass: np.ndarray
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


@structref.register
class TickRecordsType(types.StructRef):
    """numba's type of :class:`TickRecords` (its fields typed as given, not literal)."""

    def preprocess_fields(self, fields: tuple) -> tuple:
        """The fields' types without literal values."""
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class TickRecords(structref.StructRefProxy):
    """Everything :func:`tick` reads and writes, as one argument; make it with
    :func:`tick_records` once at reset (its arrays are views, filled in place every tick).

    Fields: ``terms`` (:class:`PinocchioTerms`) and ``feet`` (:class:`FootJoint` of the
    left, then the right foot), views of Pinocchio's ``Data``; ``state`` (:func:`tick_state`)
    and ``signals`` (a record of :func:`signal_dtype`). Why not separate arguments or a named
    tuple: numba's dispatcher finds the type of every argument in Python at every call,
    ≈ 2 µs for the fifteen arrays of ``terms`` and ``feet`` and ≈ 15–20 µs for the two
    structured arrays (more than a tenth of the tick); a StructRef carries its type, and its
    arrays were unboxed once, when it was made.
    """


structref.define_proxy(TickRecords, TickRecordsType, ["terms", "feet", "state", "signals"])


@_jit
def tick_records(
    terms: PinocchioTerms,
    feet: tuple[FootJoint, FootJoint],
    state: np.ndarray,
    signals: np.ndarray,
) -> TickRecords:
    """The :class:`TickRecords` of these views and records (``feet``: left, right); compiled
    and cached, unlike the proxy's own constructor."""
    return TickRecords(terms, feet, state, signals)


# ---- the control tick: O_w, E-FSM, footsteps, OS-WBC ----------------------------------------


@_jit
def tick(records: TickRecords) -> int:
    """``EfsmController.step`` after computeAllTerms: O_w, the E-FSM, the footstep planner,
    Γ (Eq. 7) and the expected and measured CoP.

    Args:
        records: (:class:`TickRecords`) ``terms`` and ``feet``: views of ``Data`` after
            computeAllTerms, the dynamics, CoM and pelvis (:class:`PinocchioTerms`) and the
            joint carrying each foot's sole and F/T frame (:class:`FootJoint`, left and
            right); ``state``: :func:`tick_state`, read and updated (``ft_wrench``: the
            tick's F/T readings, written by the controller; ``tau`` is written);
            ``signals``: out: a record of :func:`signal_dtype` (length 1), every field
            written.

    Returns:
        The E-FSM transitions of the tick as bits (:data:`.fsm.DS_TO_SSD`: the feet swapped
        roles).
    """
    terms, feet = records.terms, records.feet
    st = records.state[0]
    n = terms.mass.shape[0]
    # The soles and the F/T frames (left, right), as updateFramePlacements.
    sole_rot, sole_pos = np.empty((2, 3, 3)), np.empty((2, 3))
    ft_rot, ft_pos = np.empty((2, 3, 3)), np.empty((2, 3))
    for f in range(2):
        rot, pos = feet[f].rot, feet[f].pos
        frame_placement(
            rot, pos, st.sole_local_rot[f], st.sole_local_pos[f], sole_rot[f], sole_pos[f]
        )
        frame_placement(rot, pos, st.ft_local_rot[f], st.ft_local_pos[f], ft_rot[f], ft_pos[f])

    # O_w and the E-FSM inputs (§III-A1, Eq. 2); the E-FSM (Table I).
    sup = st.support
    sw = 1 - sup
    rot_w = st.rot_w
    com, vcom = terms.com, terms.vcom
    ow = ow_frame(sole_pos[sup], sole_pos[sw], com, vcom, rot_w)
    x_cp = capture_point(ow.com_w[0], ow.vcom_w[0], st.z_m0)
    fsm_params = FsmParams(st.zeta, st.r, st.dxp, st.d_thr, st.v_stop, st.use_epsilon != 0)
    fsm_input = FsmInput(ow.com_w[0], ow.vcom_w[0], x_cp, ow.x_s)
    if st.phase == _DS and st.steps_done == 0 and st.shift_tick < st.shift_ticks:
        # The first DS's weight shift (EfsmParams.first_ds_shift): the lab's capture-point
        # law puts x_p^des until the shift's time is up; ε and d as in every DS (§IV-B).
        st.shift_tick += 1
        remaining = (st.shift_ticks - st.shift_tick) * st.control_period
        xp_shift = weight_shift_cop(x_cp, ow.x_s, remaining, st.z_m0)
        d_shift = transition_distance(_DS, ow.x_s, xp_shift, x_cp, st.r)
        eps_shift = epsilon(d_shift, st.d_thr) if st.use_epsilon != 0 else 1.0
        fsm = FsmOutput(_DS, xp_shift, eps_shift, d_shift, 0)
    else:
        fsm = fsm_step(st.phase, st.xp_des, fsm_input, fsm_params)
    phase, xp_des = fsm.phase, fsm.xp_des
    if fsm.transitions & DS_TO_SSD:
        # DS ends: the swing foot becomes the support foot; next footstep target; O_w moves
        # (x_p^des, the new support centre, is 0 in it).
        sup, sw = sw, sup
        st.support = sup
        st.steps_done += 1
        st.swing_target[:] = next_swing_target(
            sole_pos[sup], sw, st.steps_done, st.step_length, st.n_steps, st.width,
            st.heading, st.lateral, st.first_step_scale,
        )  # fmt: skip
        ow = ow_frame(sole_pos[sup], sole_pos[sw], com, vcom, rot_w)
        x_cp = capture_point(ow.com_w[0], ow.vcom_w[0], st.z_m0)
        xp_des = 0.0
    st.phase, st.xp_des = phase, xp_des
    double = phase == _DS
    p_sup, p_sw = sole_pos[sup], sole_pos[sw]

    # The swing-foot reference (Table II): the planned xy, raised in SSD, lowered otherwise.
    swing_ref = st.swing_target.copy()
    swing_ref[2] = p_sup[2] + (st.raise_height if phase == _SSD else st.land_height)

    # ε's ramp at DS onset (EfsmParams.ds_onset_ramp): the landing foot's wrench grows
    # from 0 over the first d^thr of the x_p^des ramp.
    eps_onset = 1.0
    if double:
        if math.isnan(st.ds_start_xp):
            st.ds_start_xp = xp_des
        # Not in the first DS's weight shift: both feet stand from the start, none lands.
        standing = st.steps_done == 0 and st.shift_ticks > 0
        if st.use_epsilon != 0 and st.ds_onset_ramp != 0 and not standing:
            eps_onset = epsilon(abs(xp_des - st.ds_start_xp), st.d_thr)
    else:
        st.ds_start_xp = math.nan  # Γ_c = 0

    # A⁻¹ and J̇_c q̇ (support foot first, the swing foot's rows in DS), as Pinocchio.
    a_inv = np.empty((n, n))
    mass_matrix_inverse(terms.mass, st.parents_from_row, st.nv_subtree_from_row, a_inv)
    jc_dot_v = np.empty(12 if double else 6)
    for i in range(2 if double else 1):
        f = sup if i == 0 else sw
        frame_classical_acceleration(
            feet[f].rot, feet[f].vel, feet[f].acc, st.sole_local_pos[f], jc_dot_v[6 * i : 6 * i + 6]
        )

    # Γ = Γ_t + Γ_c + Γ_gc (Eqs. 7 and 11, Appendices A–D), saturated, actuator order.
    wbc = whole_body_torques(
        WbcDynamics(a_inv, terms.nle, jc_dot_v, terms.j_world, terms.j_com, st.pin_state[1, :n]),
        WbcFrames(
            rot_w, p_sup, p_sw, sole_rot[sup], sole_rot[sw], terms.pelvis_rot,
            st.sole_chain[sup], st.sole_chain[sw],
        ),
        WbcTargets(
            st.rot_des_pelvis, st.rot_des_swing,
            np.array([0.0 - ow.com_w[1], st.z_m0 - ow.com_w[2]]),  # CoM y, z targets (Table II)
            ow.vcom_w[1:], swing_ref, phase, fsm.epsilon, eps_onset, xp_des, ow.x_s,
        ),
        WbcParams(
            st.kp, st.kv, st.fs_max_force, st.fs_max_moment, st.fs_saturation, st.balance != 0,
            st.cop_margin, st.torque_limit, st.half_sole,
        ),
        st.actuator_rows,
        st.tau,
    )  # fmt: skip
    meas_x, meas_y = measured_cop(
        ft_rot, ft_pos, st.ft_wrench[0], st.ft_wrench[1], st.foot_com, st.foot_weight
    )
    meas_valid = math.isfinite(meas_x) and math.isfinite(meas_y)
    if not meas_valid:  # no foot loaded: logs hold finite numbers only
        meas_x, meas_y = 0.0, 0.0

    # The signals (SIGNALS), by name.
    out = records.signals[0]
    out.fsm_state = 0.0 if double else (1.0 if sup == 0 else -1.0)
    out.efsm_phase = phase
    out.epsilon, out.epsilon_onset = fsm.epsilon, eps_onset
    out.d = fsm.d if math.isfinite(fsm.d) else 1.0
    out.com_w[:] = ow.com_w
    out.com_vel_w[:] = ow.vcom_w
    out.com_world[:] = com
    out.com_vel_world[:] = vcom
    out.cp_w, out.cp_ref_w, out.x_s_w, out.xp_des_w = x_cp, ow.x_s - st.r, ow.x_s, xp_des
    rot_w_xy = rot_w[:2, :2]  # (c, −s; s, c)
    out.xp_des_world[:] = p_sup[:2] + rot_w_xy[:, 0] * xp_des
    out.cop_exp_w[0], out.cop_exp_w[1] = wbc.cop_exp_x, wbc.cop_exp_y
    out.cop_exp_world[:] = p_sup[:2] + rot_w_xy @ out.cop_exp_w
    out.cop_meas_world[0], out.cop_meas_world[1] = meas_x, meas_y
    out.cop_meas_valid = meas_valid
    out.swing_pos_world[:] = p_sw
    out.swing_ref_world[:] = swing_ref
    out.swing_foot = 0.0 if double else (1.0 if sw == 1 else -1.0)
    out.support_pos_world[:] = p_sup
    out.ow_yaw = ow.yaw
    out.com_force_x, out.balancing, out.steps_done = wbc.com_force_x, wbc.balancing, st.steps_done
    out.tau_ref[:] = st.tau
    return fsm.transitions
