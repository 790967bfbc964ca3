"""The task hierarchy of Lee et al. 2021 (Eq. 11), declared by name, and the routine that
stacks it.

:data:`HIERARCHY` is the list a researcher edits: each :class:`TaskSpec` names a quantity
(the CoM, the upper body, the swing foot), the frame its axes are read in (the world or the
walking frame O_w of §III-A1), the axes it controls, its gains, its priority (1 the highest;
tasks of one priority are stacked into one level of Eq. 11), the force law that turns its
reference acceleration into a task force, and the paper's equation. :func:`task_rows` turns
the list, once at reset, into a row table; :func:`stack_tasks`, every tick, stacks the rows
into the task Jacobian, the reference accelerations ẍ* = k_p e − k_v ẋ (Eq. 6) and the
bounds of the priority levels. No row offset is written anywhere: removing the upper-body
task, or moving the CoM height to its own priority, is one edit of :data:`HIERARCHY`.
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import IntEnum
from typing import NamedTuple

import numba
import numpy as np

#: Compiled, cached on disk, as the rest of the tick.
_jit = numba.njit(cache=True, error_model="numpy")

#: The same, inlined into its caller in numba's IR (the same operations, so the same
#: results): for the functions that take the tick's large records, which a compiled call
#: would otherwise pass by value, each array's reference count raised and dropped per call.
_inline = numba.njit(cache=True, error_model="numpy", inline="always")

#: The axes of a quantity's spatial vector (linear, then angular), world or O_w axes.
X, Y, Z, ROLL, PITCH, YAW = range(6)
#: The linear and the angular part of a spatial vector (force, moment; velocity, ω).
LINEAR, ANGULAR = slice(X, ROLL), slice(ROLL, YAW + 1)
#: Length of a spatial vector.
SPATIAL = YAW + 1


class Quantity(IntEnum):
    """What a task controls; each has a Jacobian, an error and a velocity in world axes
    (:func:`.wbc.task_quantities`)."""

    COM = 0  #: the CoM position (linear axes only); target in O_w (Table II)
    UPPER_BODY = 1  #: the pelvis, the rigid upper body (angular axes; no position target)
    SWING_FOOT = 2  #: the swing sole centre (6-D); a contact in DS, so no task there


#: Number of :class:`Quantity` members.
N_QUANTITIES = len(Quantity)


class Frame(IntEnum):
    """The axes a task's rows are read in."""

    WORLD = 0  #: world axes
    WALKING = 1  #: the walking frame O_w (§III-A1): x toward the swing foot, z up


class Law(IntEnum):
    """How a task's rows get their force (Eq. 11: Γ_t = Σ_i J̃_iᵀ F_i)."""

    PD = 0  #: F = Λ ẍ*, ẍ* = k_p e − k_v ẋ (Eq. 6)
    COP = 1  #: the CoM force that realises x_p^des (Appendix D-1, Eqs. 17–21)
    SWING = 2  #: Eq. 6 with F_s saturated (§V-B) and scaled by ε in SSA (§IV-C)
    BALANCE = 3  #: Eq. 6, replaced by F_3 + F_3^bal when the expected CoP leaves the
    #: shrunk support polygon (Appendix D-3, Eqs. 23–29); two rows, the moments about x, y


class TaskSpec(NamedTuple):
    """One task of the hierarchy, as a researcher declares it.

    Attributes:
        name: the task's name (unique).
        quantity: what it controls (:class:`Quantity`).
        frame: the axes of its rows (:class:`Frame`).
        axes: the controlled axes of the quantity's spatial vector (:data:`X` … :data:`YAW`).
        priority: 1 the highest; equal priorities share one level of Eq. (11).
        law: how its force is made (:class:`Law`).
        kp, kv: its stiffness k_p [1/s²] and damping k_v [1/s] of Eq. (6); None takes the
            controller's (``EfsmParams.kp``, ``kv``: §V-B gives one pair for every task).
        equation: where the paper states it.
    """

    name: str
    quantity: Quantity
    frame: Frame
    axes: tuple[int, ...]
    priority: int
    law: Law = Law.PD
    kp: float | None = None
    kv: float | None = None
    equation: str = ""


#: Paper I's hierarchy (§IV, Eq. 11): task 1 the CoM x-force for x_p^des, task 2 the CoM
#: y/z, the upper body's yaw and (out of DS) the 6-D swing foot, task 3 the upper body's
#: roll and pitch with the balancing force. Targets: Table II.
HIERARCHY: tuple[TaskSpec, ...] = (
    TaskSpec(
        "com_x", Quantity.COM, Frame.WALKING, (X,), 1, Law.COP,
        equation="task 1: Appendix D-1, Eqs. 17–21",
    ),
    TaskSpec(
        "com_yz", Quantity.COM, Frame.WALKING, (Y, Z), 2,
        equation="task 2: Eq. 6; Table II (y = 0, z = z_m0 in O_w)",
    ),
    TaskSpec(
        "upper_body_yaw", Quantity.UPPER_BODY, Frame.WORLD, (YAW,), 2,
        equation="task 2: Eq. 6; Table II (the initial heading)",
    ),
    TaskSpec(
        "swing_foot", Quantity.SWING_FOOT, Frame.WORLD, (X, Y, Z, ROLL, PITCH, YAW), 2,
        Law.SWING, equation="task 2: Eq. 6, F_s saturated (§V-B), × ε in SSA (§IV-C); Table II",
    ),
    TaskSpec(
        "upper_body_roll_pitch", Quantity.UPPER_BODY, Frame.WALKING, (ROLL, PITCH), 3,
        Law.BALANCE, equation="task 3: Eq. 6; F_3^bal, Appendix D-3, Eqs. 23–29; Table II",
    ),
)  # fmt: skip


class TaskRows(NamedTuple):
    """The hierarchy as rows, highest priority first (:func:`task_rows`); one entry per row.

    Attributes:
        quantity: :class:`Quantity` of the row. axis: the spatial axis (:data:`X` …).
        frame: :class:`Frame`. law: :class:`Law`.
        level: the row's priority level, 0 the highest, consecutive.
        kp, kv: the row's gains [1/s²], [1/s].
    """

    quantity: np.ndarray
    axis: np.ndarray
    frame: np.ndarray
    law: np.ndarray
    level: np.ndarray
    kp: np.ndarray
    kv: np.ndarray


def task_rows(tasks: Sequence[TaskSpec], kp: float, kv: float) -> TaskRows:
    """The row table of ``tasks``, sorted by priority (stable), with the default gains.

    Raises:
        ValueError: a repeated name, an axis outside a spatial vector or not one of the
            quantity's, an empty task, a CoP law on anything but one CoM row, or balance rows
            other than two angular ones.
    """
    names = [t.name for t in tasks]
    if len(set(names)) != len(names):
        raise ValueError(f"task names repeat: {names}")
    rows = []
    for task in sorted(tasks, key=lambda t: t.priority):
        if not task.axes:
            raise ValueError(f"task {task.name!r}: no axes")
        for axis in task.axes:
            _check_axis(task, axis)
            rows.append((task, axis))
    levels = sorted({t.priority for t, _ in rows})
    laws = [t.law for t, _ in rows]
    if laws.count(Law.COP) > 1:
        raise ValueError("one CoM row at most takes the CoP law (Appendix D-1)")
    if laws.count(Law.BALANCE) not in (0, 2):
        raise ValueError("the balance law takes two rows, the moments about x and y")
    ints = np.int64
    return TaskRows(
        quantity=np.array([int(t.quantity) for t, _ in rows], dtype=ints),
        axis=np.array([a for _, a in rows], dtype=ints),
        frame=np.array([int(t.frame) for t, _ in rows], dtype=ints),
        law=np.array([int(t.law) for t, _ in rows], dtype=ints),
        level=np.array([levels.index(t.priority) for t, _ in rows], dtype=ints),
        kp=np.array([kp if t.kp is None else t.kp for t, _ in rows], dtype=float),
        kv=np.array([kv if t.kv is None else t.kv for t, _ in rows], dtype=float),
    )


def _check_axis(task: TaskSpec, axis: int) -> None:
    """Raise ValueError unless ``axis`` is one the task's quantity and law can take."""
    if axis not in range(SPATIAL):
        raise ValueError(f"task {task.name!r}: axis {axis} is not one of X … YAW (0 … 5)")
    angular = axis >= ROLL
    if task.quantity == Quantity.COM and angular:
        raise ValueError(f"task {task.name!r}: the CoM has no angular axes")
    if task.law == Law.COP and (task.quantity != Quantity.COM or axis != X):
        raise ValueError(f"task {task.name!r}: the CoP law is the CoM's x row (Appendix D-1)")
    if task.law == Law.BALANCE and axis not in (ROLL, PITCH):
        raise ValueError(f"task {task.name!r}: the balance law takes the roll and pitch rows")
    if task.law == Law.SWING and task.quantity != Quantity.SWING_FOOT:
        raise ValueError(f"task {task.name!r}: the swing law is the swing foot's")


class TaskLayout(NamedTuple):
    """The stacked rows of one support mode (single or double support), computed once at
    reset (:func:`task_set`): the offsets no one types.

    Attributes:
        rows: the :class:`TaskRows` index of each stacked row, highest priority first
            (in DS without the swing foot's), shape (m,).
        first, end: each priority level's first row and the row after its last, (levels,).
        swing_level: the level of the swing foot's rows (:data:`Law.SWING`), −1 if none.
        swing_first: the first of them (stacked row), −1 if none; they are consecutive.
        swing_lin, swing_ang: the stacked rows of F_s's force and moment components.
        cop: the stacked row of the CoP law (Appendix D-1), none or one.
        balance: the stacked rows of the balance law (Appendix D-3), none or two.
    """

    rows: np.ndarray
    first: np.ndarray
    end: np.ndarray
    swing_level: int
    swing_first: int
    swing_lin: np.ndarray
    swing_ang: np.ndarray
    cop: np.ndarray
    balance: np.ndarray


class TaskSet(NamedTuple):
    """A hierarchy as the tick reads it (:func:`task_set`).

    Attributes:
        rows: the row table (:class:`TaskRows`).
        single, double: the :class:`TaskLayout` out of DS and in DS.
    """

    rows: TaskRows
    single: TaskLayout
    double: TaskLayout


def task_layout(rows: TaskRows, double: bool) -> TaskLayout:
    """The stacked rows of ``rows`` in DS (``double``: the swing foot's left out) or out."""
    active = np.flatnonzero(~(double & (rows.quantity == Quantity.SWING_FOOT)))
    level = rows.level[active]
    first = np.flatnonzero(np.diff(level, prepend=-1) != 0)  # the rows opening a level
    end = np.flatnonzero(np.diff(level, append=-1) != 0) + 1  # after the rows closing one
    law, angular = rows.law[active], rows.axis[active] >= ROLL
    swing = np.flatnonzero(law == Law.SWING)
    swing_level = int(np.searchsorted(first, swing[0], side="right") - 1) if swing.size else -1
    return TaskLayout(
        rows=active.astype(np.int64),
        first=first.astype(np.int64),
        end=end.astype(np.int64),
        swing_level=swing_level,
        swing_first=int(swing[0]) if swing.size else -1,
        swing_lin=np.flatnonzero((law == Law.SWING) & ~angular).astype(np.int64),
        swing_ang=np.flatnonzero((law == Law.SWING) & angular).astype(np.int64),
        cop=np.flatnonzero(law == Law.COP).astype(np.int64),
        balance=np.flatnonzero(law == Law.BALANCE).astype(np.int64),
    )


def task_set(tasks: Sequence[TaskSpec], kp: float, kv: float) -> TaskSet:
    """The row table of ``tasks`` (:func:`task_rows`) and its layouts out of and in DS."""
    rows = task_rows(tasks, kp, kv)
    single = task_layout(rows, False)
    swing = np.r_[single.swing_lin, single.swing_ang]
    if swing.size and not np.array_equal(swing, np.arange(swing.size) + single.swing_first):
        raise ValueError("the swing foot's rows are one task: force axes, then moment axes")
    return TaskSet(rows, single, task_layout(rows, True))


@_inline
def stack_tasks(
    rows: TaskRows,
    layout: TaskLayout,
    jac: np.ndarray,
    err: np.ndarray,
    vel: np.ndarray,
    rot_w: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The task rows of a tick: the task Jacobian J of Eq. (11), shape (m, n), and the
    reference accelerations ẍ* = k_p e − k_v ẋ of Eq. (6), shape (m,).

    A row on axis a of O_w reads the world-axes part (linear or angular) p of its quantity
    along O_w's axis a, the column a of ``rot_w``: r_aᵀ p.

    Args:
        rows: the hierarchy (:func:`task_rows`); layout: its rows this tick (:func:`task_layout`).
        jac: each quantity's Jacobian, world axes, shape (quantities, 6, n).
        err: each quantity's error (target − actual), world axes, shape (quantities, 6).
        vel: each quantity's velocity, world axes, shape (quantities, 6).
        rot_w: world-from-O_w rotation.
    """
    m, n = layout.rows.size, jac.shape[2]
    jacobian, acc = np.empty((m, n)), np.empty(m)
    for i, r in enumerate(layout.rows):
        q, axis = rows.quantity[r], rows.axis[r]
        if rows.frame[r] == Frame.WALKING:
            angular = axis >= ROLL
            part = ANGULAR if angular else LINEAR
            r_a = np.ascontiguousarray(rot_w[:, axis - ROLL if angular else axis])
            jacobian[i] = r_a @ jac[q, part]
            e, v = r_a @ err[q, part], r_a @ vel[q, part]
        else:
            jacobian[i] = jac[q, axis]
            e, v = err[q, axis], vel[q, axis]
        acc[i] = rows.kp[r] * e - rows.kv[r] * v  # Eq. (6)
    return jacobian, acc
