"""A point-contact ground law computed by walkrepro and applied as forces: the ground
contact of COMAN's lab's simulator (Paper II; NicolasVdN/CoManRobotran @ 0207863b,
``simu_def.h``, ``user_ExtForces.c``, ``init_GCM.c``), usable by any robot whose lab used it.

Each sole carries a grid of contact points (in the sole body's frame). For a point below the
ground plane z = 0, at depth δ = −z > 0 with vertical velocity ż [m/s]:

- **normal force** (Hunt–Crossley type, zero at touchdown):
  F_z = k δ max(0, 1 − ż / v₀)  [N], with k [N/m] and v₀ [m/s];
- **tangential force**: a spring-damper to the point's *anchor* a (where it touched down),
  F_t = −k_t (p_xy − a) − b_t ṗ_xy  [N]; when |F_t| > μ F_z the point slides: F_t is scaled
  to μ F_z and the anchor moves so that the spring alone gives the scaled force
  (a = p_xy + F_t / k_t, the damping part kept out of the anchor's memory).

A point above the ground releases its anchor. The forces of one sole are summed into one
force and one moment about the body's centre of mass and added to ``qfrc_passive`` by
``mj_applyFT`` inside MuJoCo's passive-force callback (``mjcb_passive``): the law runs at the
same point of every physics step in ``mj_step1`` (the runner) and in ``mj_step`` (``walkrepro
verify``), so a log replays bit for bit. Its state, every point's anchor and contact flag,
lives in ``MjData.userdata`` (``3 n`` numbers from :attr:`GroundContact.offset`), which
``mj_resetData`` clears and the physics carries from step to step.

The forces are explicit (computed from the state before the step, like MuJoCo's passive
springs and like the lab's simulator): stiff springs on light bodies are unstable above a
timestep. Measured on a 200-point sole landing from 1 cm (``tests/test_contact_law.py``): a
1 kg body settles at the lab's 0.5 ms and diverges at 1 ms; 6.4 kg (a COMAN leg) and 14 kg
settle at 1 ms and diverge at 2 ms.

Cost: with one law applied, MuJoCo calls the law compiled as a C function
(:func:`native_callback`; no Python in a physics step), which skips a sole whose points are
all above the ground (:func:`lowest_point`, a box around them) and runs the point law on the
others. ``benchmarks/contact_law.py`` (two 200-point soles standing): the law adds ≈ 9 µs
to MuJoCo's ≈ 4 µs step on this machine (≈ 40 µs as a Python callback before).
``robots/coman_lab`` (COMAN rebuilt from its lab's model) stands on the law. MuJoCo's own constraint must be off between those soles and
the ground (the scene gives them ``contype = conaffinity = 0`` against the floor), else the
foot would be held twice.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import mujoco
import numba
import numpy as np
from numba import types


@dataclass(frozen=True)
class PointContactLaw:
    """The law's parameters (each one a ledger entry of the robot that uses it).

    Attributes:
        stiffness: normal stiffness k per point [N/m].
        velocity_scale: v₀ of the Hunt–Crossley damping factor (1 − ż/v₀) [m/s].
        tangential_stiffness: k_t per point [N/m].
        tangential_damping: b_t per point [N s/m].
        friction: Coulomb coefficient μ [-].
    """

    stiffness: float
    velocity_scale: float
    tangential_stiffness: float
    tangential_damping: float
    friction: float

    def __post_init__(self) -> None:
        for name in ("stiffness", "velocity_scale", "tangential_stiffness", "friction"):
            if not getattr(self, name) > 0:
                raise ValueError(f"the contact law's {name} must be > 0")
        if self.tangential_damping < 0:
            raise ValueError("the contact law's tangential_damping must be >= 0")


def sole_grid(
    x_range: tuple[float, float], y_range: tuple[float, float], z: float, spacing: float
) -> np.ndarray:
    """Contact points on a rectangular sole, ``spacing`` apart, inclusive of both edges.

    Args:
        x_range: (back, front) of the sole in its body's frame [m].
        y_range: (right, left) [m].
        z: the sole's bottom in the body's frame [m].
        spacing: grid step [m] (the lab's: 0.01).

    Returns:
        (n, 3) points in the body's frame [m].
    """
    nx = int(round((x_range[1] - x_range[0]) / spacing)) + 1
    ny = int(round((y_range[1] - y_range[0]) / spacing)) + 1
    xs = np.linspace(x_range[0], x_range[1], nx)
    ys = np.linspace(y_range[0], y_range[1], ny)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    return np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, z)])


#: ``userdata`` slots after a sole's points: its wrench of the last step (force, torque).
WRENCH_SLOTS = 6
#: A wrench's parts: force [N], torque [N m].
FORCE, TORQUE = slice(0, 3), slice(3, 6)


@dataclass
class _Sole:
    body: int
    points: np.ndarray  # (n, 3) in the body frame [m]
    offset: int  # first userdata slot of this sole's state


class SoleLayout(NamedTuple):
    """Every sole of a model stacked for one compiled call (:func:`apply_law`).

    Attributes:
        bodies: each sole's body id, (s,).
        points: all soles' contact points in their bodies' frames [m], (n, 3).
        first: sole j's points are ``points[first[j]:first[j + 1]]``, (s + 1,).
        offsets: each sole's first ``userdata`` slot, (s,).
        low, high: each sole's box around its points in its body's frame [m], (s, 3).
    """

    bodies: np.ndarray
    points: np.ndarray
    first: np.ndarray
    offsets: np.ndarray
    low: np.ndarray
    high: np.ndarray

    @classmethod
    def of(cls, soles: list[_Sole]) -> SoleLayout:
        """The layout of ``soles``, in their order."""
        counts = [len(sole.points) for sole in soles]
        return cls(
            bodies=np.array([sole.body for sole in soles], dtype=np.int64),
            points=np.concatenate([sole.points for sole in soles]).reshape(-1, 3),
            first=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
            offsets=np.array([sole.offset for sole in soles], dtype=np.int64),
            low=np.array([sole.points.min(axis=0) for sole in soles]).reshape(-1, 3),
            high=np.array([sole.points.max(axis=0) for sole in soles]).reshape(-1, 3),
        )


@dataclass
class GroundContact:
    """The law bound to a compiled model: which bodies carry which points, where their state
    lives in ``userdata``.

    Args:
        model: the compiled scene (``nuserdata`` ≥ :meth:`userdata_size`).
        law: the law's parameters.
        points: body name -> (n, 3) contact points in that body's frame [m].
        offset: first ``userdata`` slot the law may use.
    """

    model: mujoco.MjModel
    law: PointContactLaw
    points: Mapping[str, np.ndarray]
    offset: int = 0
    soles: list[_Sole] = field(init=False)
    _layout: SoleLayout = field(init=False, repr=False)
    _params: np.ndarray = field(init=False, repr=False)
    _velocities: np.ndarray = field(init=False, repr=False)
    _wrench_rows: np.ndarray = field(init=False, repr=False)
    _velocity_rows: list[np.ndarray] = field(init=False, repr=False)
    _wrenches: list[tuple[np.ndarray, np.ndarray]] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.soles = []
        slot = self.offset
        for name, pts in self.points.items():
            pts = np.asarray(pts, dtype=float).reshape(-1, 3)
            self.soles.append(_Sole(self.model.body(name).id, pts, slot))
            slot += 3 * len(pts) + WRENCH_SLOTS
        if slot > self.model.nuserdata:
            raise ValueError(
                f"the contact law needs {slot} userdata slots; the model has "
                f"{self.model.nuserdata} (set nuserdata when building the scene)"
            )
        self._layout = SoleLayout.of(self.soles)
        law = self.law
        self._params = np.array(
            [
                law.stiffness,
                law.velocity_scale,
                law.tangential_stiffness,
                law.tangential_damping,
                law.friction,
            ]
        )
        # Per sole: its velocity (ω, v) and its wrench (force, moment about its CoM).
        self._velocities = np.zeros((len(self.soles), 6))
        self._wrench_rows = np.zeros((len(self.soles), 6))
        self._velocity_rows = list(self._velocities)
        self._wrenches = [(row[FORCE], row[TORQUE]) for row in self._wrench_rows]

    @staticmethod
    def userdata_size(points: Mapping[str, np.ndarray]) -> int:
        """``userdata`` slots the law's state needs: 3 per point (anchor x, y; contact flag)
        and the sole's last wrench (6)."""
        return sum(3 * len(np.asarray(p).reshape(-1, 3)) + WRENCH_SLOTS for p in points.values())

    @property
    def bodies(self) -> tuple[int, ...]:
        """The ids of the bodies that carry soles."""
        return tuple(sole.body for sole in self.soles)

    def wrench(self, data: mujoco.MjData, body: int) -> np.ndarray:
        """The ground's wrench on ``body`` in the last step: (force [N], torque about the world
        origin [N m]), world frame, as :class:`walkrepro.sim.contact_reader.ContactReader` reports a
        contact pair; zero when the sole is in the air."""
        for sole in self.soles:
            if sole.body == body:
                start = sole.offset + 3 * len(sole.points)
                return np.array(data.userdata[start : start + WRENCH_SLOTS])
        raise KeyError(f"body {body} carries no sole of the ground law")

    def apply(self, data: mujoco.MjData) -> None:
        """Add every sole's contact force to ``data.qfrc_passive`` and advance the anchors.

        Called from MuJoCo's passive stage: positions (``xpos``, ``xmat``, ``xipos``) and
        velocities of this step are current. One compiled call (:func:`apply_law`) runs the
        law on every sole; MuJoCo's own functions give the bodies' velocities before it and
        apply the touching soles' wrenches after it.
        """
        model, wrenches = self.model, self._wrenches
        for sole, velocity in zip(self.soles, self._velocity_rows, strict=True):
            # The body frame's (angular, linear) velocity at its origin, in world axes.
            mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_XBODY, sole.body, velocity, 0)
        touching = apply_law(
            self._layout, data.xpos, data.xmat, data.xipos, self._velocities, data.userdata,
            self._params, self._wrench_rows,
        )  # fmt: skip
        for sole, wrench, touches in zip(self.soles, wrenches, touching, strict=True):
            if touches:
                force, torque = wrench
                com = data.xipos[sole.body]
                mujoco.mj_applyFT(model, data, force, torque, com, sole.body, data.qfrc_passive)


class SoleKinematics(NamedTuple):
    """A sole body's state at this step, in the world frame.

    Attributes:
        origin: the body frame's origin [m], (3,).
        rotation: the body frame's orientation, row-major 3 × 3 as ``xmat``, (9,).
        velocity: (ω [rad/s], v [m/s]) of the body frame at its origin, (6,).
        com: the body's centre of mass [m], (3,): the point the wrench is summed about.
    """

    origin: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    com: np.ndarray


@numba.njit(cache=True)
def sole_wrench(
    body: SoleKinematics,
    points: np.ndarray,
    state: np.ndarray,
    params: np.ndarray,
    wrench: np.ndarray,
) -> bool:
    """The law's net force and moment of one sole; advances each point's anchor.

    Args:
        body: the sole body's kinematics.
        points: (n, 3) contact points in the body frame [m].
        state: (n, 3) per point: anchor x, y [m] in the world, contact flag (1 touching).
            Updated in place: set at touchdown, moved while sliding, cleared above ground.
        params: (k, v₀, k_t, b_t, μ) of :class:`PointContactLaw`.
        wrench: out, (force [N], moment about ``body.com`` [N m]) in the world frame.

    Returns:
        whether any point touches the ground.
    """
    k, v0, kt, bt, mu = params[0], params[1], params[2], params[3], params[4]
    R = body.rotation  # row-major 3 × 3
    o, w, vo, c = body.origin, body.velocity[:3], body.velocity[3:], body.com
    wrench[:] = 0.0
    touching = False
    # Scalar components throughout: a per-point small-array allocation costs more than the
    # law itself (155 µs against 6 µs per 200-point sole, measured).
    for i in range(points.shape[0]):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        # r = R p_body: the point relative to the body origin, world axes [m].
        rx = R[0] * px + R[1] * py + R[2] * pz
        ry = R[3] * px + R[4] * py + R[5] * pz
        rz = R[6] * px + R[7] * py + R[8] * pz
        x, y, z = o[0] + rx, o[1] + ry, o[2] + rz  # the point in the world [m]
        if z >= 0.0:
            state[i, 0] = state[i, 1] = state[i, 2] = 0.0  # above ground: anchor released
            continue
        touching = True
        # v = v_o + ω × r: the point's velocity [m/s].
        vx = vo[0] + w[1] * rz - w[2] * ry
        vy = vo[1] + w[2] * rx - w[0] * rz
        vz = vo[2] + w[0] * ry - w[1] * rx
        fz = k * (-z) * max(0.0, 1.0 - vz / v0)  # Hunt–Crossley normal force [N]
        if state[i, 2] == 0.0:  # touchdown: the anchor is where the point landed
            state[i, 0], state[i, 1], state[i, 2] = x, y, 1.0
        fx = -kt * (x - state[i, 0]) - bt * vx  # anchored tangential spring-damper [N]
        fy = -kt * (y - state[i, 1]) - bt * vy
        norm = np.sqrt(fx * fx + fy * fy)
        limit = mu * fz
        if norm > limit:  # sliding: Coulomb's bound; the anchor follows the spring
            fx *= limit / norm
            fy *= limit / norm
            state[i, 0] = x + fx / kt
            state[i, 1] = y + fy / kt
        # The force and its moment about the centre of mass, (p − c) × f.
        dx, dy, dz = x - c[0], y - c[1], z - c[2]
        wrench[0] += fx
        wrench[1] += fy
        wrench[2] += fz
        wrench[3] += dy * fz - dz * fy
        wrench[4] += dz * fx - dx * fz
        wrench[5] += dx * fy - dy * fx
    return touching


#: A sole whose box is this high above the ground [m] skips the point law: every point is
#: above it, far beyond the rounding of a point's height (≈ 1e-16 m).
AIRBORNE = 1e-9


@numba.njit(cache=True)
def lowest_point(
    origin: np.ndarray, rotation: np.ndarray, low: np.ndarray, high: np.ndarray
) -> float:
    """A lower bound of the height of a sole's points: the lowest corner of their box
    [low, high] (body frame) in the world, z = o_z + Σ_k R_zk p_k [m] (``rotation``
    row-major, as ``xmat``); the broad phase of :func:`apply_law`."""
    z = origin[2]
    for k in range(3):
        r = rotation[6 + k]  # R_zk: the world height of the body's axis k
        z += min(r * low[k], r * high[k])
    return z


@numba.njit(cache=True)
def apply_law(
    layout: SoleLayout,
    xpos: np.ndarray,
    xmat: np.ndarray,
    xipos: np.ndarray,
    velocities: np.ndarray,
    userdata: np.ndarray,
    params: np.ndarray,
    wrenches: np.ndarray,
) -> np.ndarray:
    """The law on every sole of ``layout`` (:func:`sole_wrench`), one physics step.

    Args:
        layout: the soles.
        xpos, xmat, xipos: ``MjData``'s body origins, orientations and centres of mass.
        velocities: each sole body's (ω, v) at its origin, world axes, (s, 6).
        userdata: ``MjData.userdata``: the anchors are advanced in place, and each sole's
            recorded wrench (force, torque about the world origin) is written.
        params: (k, v₀, k_t, b_t, μ).
        wrenches: out, each sole's (force [N], moment about its CoM [N m]), (s, 6).

    Returns:
        Whether each sole touches the ground, (s,).
    """
    n_soles = layout.bodies.shape[0]
    touching = np.zeros(n_soles, dtype=np.bool_)
    for j in range(n_soles):
        body, offset = layout.bodies[j], layout.offsets[j]
        points = layout.points[layout.first[j] : layout.first[j + 1]]
        n = points.shape[0]
        state = userdata[offset : offset + 3 * n].reshape(n, 3)
        com = xipos[body]
        wrench = wrenches[j]
        if lowest_point(xpos[body], xmat[body], layout.low[j], layout.high[j]) > AIRBORNE:
            state[:] = 0.0  # every point above the ground: every anchor released
            wrench[:] = 0.0
        else:
            kinematics = SoleKinematics(xpos[body], xmat[body], velocities[j], com)
            touching[j] = sole_wrench(kinematics, points, state, params, wrench)
        recorded = userdata[offset + 3 * n : offset + 3 * n + WRENCH_SLOTS]
        if touching[j]:
            # The torque about the world origin: τ_o = τ_c + c × f.
            f = wrench[FORCE]
            recorded[FORCE] = f
            recorded[TORQUE] = wrench[TORQUE] + np.cross(com, f)
        else:
            recorded[:] = 0.0
    return touching


# --------------------------------------------------------------------------------------
# MuJoCo's passive callback is one per process. With one law applied it is the law compiled
# as a C function (:func:`native_callback`): MuJoCo calls it directly, no Python runs in a
# physics step. With several laws at once (models stepped side by side in one process), a
# Python function dispatches to each model's :meth:`GroundContact.apply`. Either runs the
# same compiled law (:func:`apply_law`). The callback is set only while a law is applied:
# MuJoCo also calls it while it compiles a model, when the Python bindings cannot hand the
# model over (the compile then fails), so no model may be compiled inside :func:`applied`.

_LAWS: dict[int, GroundContact] = {}


def _passive(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    contact = _LAWS.get(id(model))
    if contact is not None:
        contact.apply(data)


#: How far into ``mjData`` / ``mjModel`` a field is looked for [words]: MuJoCo 4.0's
#: ``mjData`` keeps the law's pointers ≈ 20,000 words in (after its solver statistics).
_STRUCT_WORDS = 1 << 16


class _DataWords(NamedTuple):
    """Where ``mjData`` keeps the pointers of the arrays the law reads and writes: each one's
    index among the struct's 8-byte words (the same for every ``mjData`` of this MuJoCo)."""

    xpos: int
    xmat: int
    xipos: int
    userdata: int
    qfrc_passive: int


@functools.cache
def _data_words() -> _DataWords:
    """Find the pointer fields of ``mjData``: the struct's words, read from its start up to
    each field, hold the address the Python bindings give for that array."""
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><size nuserdata="1"/><worldbody><body><freejoint/><geom size="1"/></body>'
        "</worldbody></mujoco>"
    )
    data = mujoco.MjData(model)
    words = ctypes.cast(data._address, ctypes.POINTER(ctypes.c_uint64))

    def word(array: np.ndarray) -> int:
        address, i = array.ctypes.data, 0
        while words[i] != address:  # a field of the struct: found before its end
            i += 1
            if i == _STRUCT_WORDS:
                raise LookupError("mjData keeps its arrays' pointers elsewhere")
        return i

    return _DataWords(*(word(getattr(data, name)) for name in _DataWords._fields))


class _ModelInts(NamedTuple):
    """Where ``mjModel`` keeps two of its sizes: each one's index among its 4-byte words."""

    nbody: int
    nuserdata: int


@functools.cache
def _model_ints() -> _ModelInts:
    """Find ``mjModel.nbody`` and ``nuserdata``: the word that holds each size in three
    models whose sizes all differ, read from the struct's start (its sizes come first)."""
    probes = [
        mujoco.MjModel.from_xml_string(
            f'<mujoco><size nuserdata="{1000 + 7 * n}"/><worldbody>'
            + "<body><geom size='1'/>" * n
            + "</body>" * n
            + "</worldbody></mujoco>"
        )
        for n in (3, 5, 8)
    ]
    words = [ctypes.cast(m._address, ctypes.POINTER(ctypes.c_int32)) for m in probes]

    def word(name: str) -> int:
        i = 0
        while any(w[i] != getattr(m, name) for w, m in zip(words, probes, strict=True)):
            i += 1
            if i == _STRUCT_WORDS:
                raise LookupError(f"mjModel keeps {name} elsewhere")
        return i

    return _ModelInts(*(word(name) for name in _ModelInts._fields))


@functools.cache
def _mujoco_functions() -> tuple[Callable, Callable]:
    """MuJoCo's ``mj_objectVelocity`` and ``mj_applyFT`` as C functions the law can call."""
    (library,) = Path(mujoco.__file__).parent.glob("libmujoco.so*")
    lib = ctypes.CDLL(str(library))
    vector = ctypes.POINTER(ctypes.c_double)
    model = ctypes.POINTER(ctypes.c_int32)  # mjModel*, read as its words (see `_ModelInts`)
    data = ctypes.POINTER(vector)  # mjData*, read as its words (see `_DataWords`)
    object_velocity = lib.mj_objectVelocity
    object_velocity.argtypes = [model, data, ctypes.c_int, ctypes.c_int, vector, ctypes.c_int]
    object_velocity.restype = None
    apply_ft = lib.mj_applyFT
    apply_ft.argtypes = [model, data, vector, vector, vector, ctypes.c_int, vector]
    apply_ft.restype = None
    return object_velocity, apply_ft


#: The compiled callbacks of this process, by law (its soles, parameters and model sizes).
_NATIVE: dict[bytes, Callable] = {}


def native_callback(contact: GroundContact) -> Callable:
    """``contact``'s law as a C passive-force callback (a ctypes function pointer, which
    MuJoCo's Python bindings install as the C callback itself): :meth:`GroundContact.apply`
    without Python in a physics step.

    Its soles and parameters are constants in it: compiled once per law and process (about a
    second), for any model of the same sizes (a run's and its replay's scene); a model of
    other sizes (one compiled meanwhile) is left alone.
    """
    model = contact.model
    nbody, nuserdata = model.nbody, model.nuserdata
    bodies, points, first, offsets, low, high = contact._layout
    params, n_soles = contact._params, len(contact.soles)
    arrays = (params, *contact._layout, np.array([nbody, nuserdata]))
    key = b"|".join(a.tobytes() for a in arrays)
    if key in _NATIVE:
        return _NATIVE[key]
    words, sizes = _data_words(), _model_ints()
    object_velocity, apply_ft = _mujoco_functions()
    xbody = int(mujoco.mjtObj.mjOBJ_XBODY)

    @numba.cfunc(
        types.void(types.CPointer(types.int32), types.CPointer(types.CPointer(types.float64)))
    )
    def passive(m, d):  # noqa: ANN001, ANN202 (C types)
        if m[sizes.nbody] != nbody or m[sizes.nuserdata] != nuserdata:
            return
        xipos = numba.carray(d[words.xipos], (nbody, 3))
        velocities = np.empty((n_soles, 6))
        for j in range(n_soles):
            object_velocity(m, d, xbody, bodies[j], velocities[j].ctypes, 0)
        wrenches = np.empty((n_soles, 6))
        touching = apply_law(
            SoleLayout(bodies, points, first, offsets, low, high),
            numba.carray(d[words.xpos], (nbody, 3)),
            numba.carray(d[words.xmat], (nbody, 9)),
            xipos,
            velocities,
            numba.carray(d[words.userdata], (nuserdata,)),
            params,
            wrenches,
        )
        for j in range(n_soles):
            if touching[j]:
                wrench, com = wrenches[j], xipos[bodies[j]]
                force, torque = wrench[FORCE], wrench[TORQUE]
                qfrc = d[words.qfrc_passive]
                apply_ft(m, d, force.ctypes, torque.ctypes, com.ctypes, bodies[j], qfrc)

    _NATIVE[key] = passive.ctypes
    return passive.ctypes


def _install() -> None:
    """Set MuJoCo's passive callback for the laws applied now."""
    if not _LAWS:
        mujoco.set_mjcb_passive(None)
    elif len(_LAWS) == 1:
        (contact,) = _LAWS.values()
        try:
            mujoco.set_mjcb_passive(native_callback(contact))
        except LookupError:  # a MuJoCo whose structs the compiled law cannot read: Python
            mujoco.set_mjcb_passive(_passive)
    else:
        mujoco.set_mjcb_passive(_passive)


def _ours(callback: object) -> bool:
    """Whether ``callback`` is one this module installed."""
    return callback is _passive or any(c is callback for c in _NATIVE.values())


#: The MJCF ``<custom><numeric>`` that carries a model's law: (k, v₀, k_t, b_t, μ). A robot
#: whose lab's simulator used this law writes it into its ``robot.xml`` (build_models.py),
#: with one ``SOLE_PREFIX + body`` numeric per sole (its points, x y z each, in the body frame)
#: and ``<size nuserdata>`` for the anchors; the logged scene carries it, so a log replays
#: with its own law.
LAW_NUMERIC = "walkrepro_ground_law"
SOLE_PREFIX = "walkrepro_ground_sole:"


def from_model(model: mujoco.MjModel) -> GroundContact | None:
    """The law a compiled model carries in its custom numerics, or None."""
    names = [model.numeric(i).name for i in range(model.nnumeric)]
    if LAW_NUMERIC not in names:
        return None
    k, v0, kt, bt, mu = (float(x) for x in model.numeric(LAW_NUMERIC).data[:5])
    soles = {
        name[len(SOLE_PREFIX) :]: np.asarray(model.numeric(name).data, dtype=float).reshape(-1, 3)
        for name in names
        if name.startswith(SOLE_PREFIX)
    }
    return GroundContact(model, PointContactLaw(k, v0, kt, bt, mu), soles)


def mjcf(law: PointContactLaw, soles: Mapping[str, np.ndarray]) -> str:
    """The ``<custom>`` element that declares ``law`` on ``soles`` in a model's MJCF (and
    the ``<size nuserdata>`` its anchors need), for a robot's build."""
    numerics = [
        f'<numeric name="{LAW_NUMERIC}" data="{law.stiffness!r} {law.velocity_scale!r} '
        f'{law.tangential_stiffness!r} {law.tangential_damping!r} {law.friction!r}"/>'
    ]
    for body, points in soles.items():
        data = " ".join(repr(float(x)) for x in np.asarray(points, dtype=float).ravel())
        numerics.append(f'<numeric name="{SOLE_PREFIX}{body}" data="{data}"/>')
    size = GroundContact.userdata_size(soles)
    return f'<size nuserdata="{size}"/>\n<custom>\n' + "\n".join(numerics) + "\n</custom>"


def applied_to(model: mujoco.MjModel) -> contextlib.AbstractContextManager[None]:
    """:func:`applied` for the law ``model`` carries, or a context that does nothing."""
    contact = from_model(model)
    return applied(contact) if contact is not None else contextlib.nullcontext()


@contextlib.contextmanager
def applied(contact: GroundContact) -> Iterator[None]:
    """Apply ``contact`` in every MuJoCo step of its model (``mj_step``, ``mj_step1``,
    ``mj_forward``) while the block runs; compile no model inside it.

    The law's passive stage also advances its anchors, so each physics step must run it
    exactly once: a ``mj_forward`` inside the block would advance them a second time (the
    runner and the replay call only ``mj_step1``/``mj_step2`` or ``mj_step`` in it)."""
    key = id(contact.model)
    previous = mujoco.get_mjcb_passive()
    if previous is not None and not _ours(previous):
        raise RuntimeError("another passive-force callback is installed in this process")
    _LAWS[key] = contact
    _install()
    try:
        yield
    finally:
        _LAWS.pop(key, None)
        _install()
