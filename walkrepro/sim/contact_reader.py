"""What the simulator's contacts say about the robot: the net wrench of each robot-world
pair (logged on ``/sim/contacts``) and whether a non-foot body touched the floor (a fall).

Both run every control tick on MuJoCo's contact list, and the same few contact sets recur
tick after tick: everything that depends only on *which* geoms touch is worked out once per
set and cached. The per-tick arithmetic (a force per contact from its constraint force and
frame, a torque about the world origin, a sum per pair) is one compiled numba call, not a
dozen numpy calls on arrays of eight rows, because it runs at up to 2 kHz.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numba
import numpy as np

from walkrepro.sim import contact_law
from walkrepro.sim.robot import Robot
from walkrepro.sim.world import FLOOR_NAME
from walkrepro.specs.models import ExperimentSpec

FOOT_BODIES = ("left_foot", "right_foot")

#: Contact sets remembered per cache; a walk sees tens. A full cache is emptied, so memory
#: stays bounded however long the run.
MAX_CACHED_SETS = 4096


@numba.njit(
    "f8[:,:](f8[:], i4[:], f8[:,:], f8[:,:], i8[:], f8[:], i8[:], i8)", cache=True, nogil=True
)
def _pair_wrenches(
    force_source: np.ndarray,
    force_address: np.ndarray,
    frame: np.ndarray,
    pos: np.ndarray,
    rows: np.ndarray,
    sign: np.ndarray,
    pair: np.ndarray,
    n_pairs: int,
) -> np.ndarray:
    """Net wrench on the robot geom of each pair, world frame, torque about the origin.

    Contact ``rows[k]`` has its local force (normal, tangent, tangent; geom1 on geom2) at
    ``force_source[force_address[rows[k]]:+3]`` (none when the address is negative) and its frame (rows = axes in world
    coordinates) in ``frame``; ``sign[k]`` flips it to the force on the robot geom, and it
    adds to pair ``pair[k]``, in row order. The first row of a pair is copied, not added to
    zero, so a single contact's ``-0.0`` stays ``-0.0``.
    """
    out = np.empty((n_pairs, 6))
    seen = np.zeros(n_pairs, dtype=np.bool_)
    wrench = np.empty(6)
    for k in range(rows.size):
        i = rows[k]
        a = force_address[i]
        if a >= 0:
            f0, f1, f2 = force_source[a], force_source[a + 1], force_source[a + 2]
        else:  # a contact the solver excluded carries no force
            f0 = f1 = f2 = 0.0
        s = sign[k]
        for j in range(3):  # world force = frameᵀ · local
            wrench[j] = (f0 * frame[i, j] + f1 * frame[i, 3 + j] + f2 * frame[i, 6 + j]) * s
        px, py, pz = pos[i, 0], pos[i, 1], pos[i, 2]
        wrench[3] = py * wrench[2] - pz * wrench[1]
        wrench[4] = pz * wrench[0] - px * wrench[2]
        wrench[5] = px * wrench[1] - py * wrench[0]
        p = pair[k]
        if seen[p]:
            for j in range(6):
                out[p, j] += wrench[j]
        else:
            seen[p] = True
            for j in range(6):
                out[p, j] = wrench[j]
    return out


_NO_WRENCHES = np.zeros((0, 6))
_NO_WRENCHES.flags.writeable = False


@dataclass(frozen=True)
class _PairPlan:
    """How one contact set (a tuple of geom pairs) maps onto pair wrenches.

    Attributes:
        rows: indices of the robot-world contacts among all.
        sign: +1 where the world geom is geom1 (MuJoCo's force is then the one on the robot
            geom), -1 where it is geom2.
        pair: index into ``keys`` of each row.
        keys: ``"<robot body>/<world geom>"`` of each pair, in order of first appearance.
        in_efc_force: whether every contact's local force is the first three rows of its
            constraint force (elliptic cones, condim >= 3), so it is read from ``efc_force``
            in place; else from ``mj_contactForce``.
    """

    rows: np.ndarray
    sign: np.ndarray
    pair: np.ndarray
    keys: tuple[str, ...]
    in_efc_force: bool


class ContactReader:
    """Net contact wrench on each robot body from each world geom (floor, obstacles)."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self._model = model
        self._world_geom = np.array(
            [
                (model.geom(i).name == FLOOR_NAME or model.geom(i).name.startswith("obstacle"))
                for i in range(model.ngeom)
            ]
        )
        self._geom_name = [model.geom(i).name for i in range(model.ngeom)]
        self._body_name = [model.body(model.geom_bodyid[i]).name for i in range(model.ngeom)]
        self._elliptic = model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
        self._plans: dict[bytes, _PairPlan | None] = {}
        self._force = np.zeros(6)
        # A ground law computed by walkrepro (contact_law.py) is no MuJoCo contact: its soles'
        # wrenches join the pairs as "<sole body>/floor".
        self._ground = contact_law.from_model(model)
        self._ground_keys: dict[tuple[tuple[str, ...], tuple[int, ...]], tuple[str, ...]] = {}

    def read(self, data: mujoco.MjData) -> dict[str, np.ndarray]:
        """``{"<robot body>/<world geom>": [fx, fy, fz, tx, ty, tz]}`` in the world frame.

        The torque is about the world origin, so a pair's centre of pressure on a
        horizontal surface is ``(-ty / fz, tx / fz)``.
        """
        keys, wrenches = self.read_pairs(data)
        return dict(zip(keys, wrenches, strict=True))

    def read_pairs(self, data: mujoco.MjData) -> tuple[tuple[str, ...], np.ndarray]:
        """:meth:`read` as the pairs' names (one tuple object per contact set, so a caller
        can tell a set it has seen by identity) and their wrenches, shape (pairs, 6)."""
        keys, wrenches = self._mujoco_pairs(data)
        if self._ground is None:
            return keys, wrenches
        law = [(b, self._ground.wrench(data, b)) for b in self._ground.bodies]
        law = [(b, w) for b, w in law if w[2] != 0.0]  # soles on the ground
        if not law:
            return keys, wrenches
        bodies = tuple(b for b, _ in law)
        combined = self._ground_keys.get((keys, bodies))
        if combined is None:
            names = tuple(f"{self._model.body(b).name}/{FLOOR_NAME}" for b in bodies)
            combined = self._ground_keys[(keys, bodies)] = keys + names
        return combined, np.vstack([wrenches.reshape(-1, 6), np.array([w for _, w in law])])

    def _mujoco_pairs(self, data: mujoco.MjData) -> tuple[tuple[str, ...], np.ndarray]:
        """The robot-world pairs of MuJoCo's own contacts."""
        n = data.ncon
        if n == 0:
            return (), _NO_WRENCHES
        contact = data.contact  # each field access builds a view: read each once
        geom = contact.geom[:n]
        signature = geom.tobytes()
        plan = self._plans.get(signature, False)
        if plan is False:
            if len(self._plans) >= MAX_CACHED_SETS:
                self._plans.clear()
            plan = self._plans[signature] = self._plan(geom, contact.dim[:n])
        if plan is None:
            return (), _NO_WRENCHES
        if plan.in_efc_force:
            source, address = data.efc_force, contact.efc_address[:n]
        else:
            source, address = self._local_forces(data, n)
        wrenches = _pair_wrenches(
            source,
            address,
            contact.frame[:n],
            contact.pos[:n],
            plan.rows,
            plan.sign,
            plan.pair,
            len(plan.keys),
        )
        return plan.keys, wrenches

    def _plan(self, geom: np.ndarray, dim: np.ndarray) -> _PairPlan | None:
        """The plan for this contact set, or None when no contact is robot-world.

        A contact's dimension is set by its two geoms, so it is part of the set."""
        world = self._world_geom[geom]
        rows = np.flatnonzero(world[:, 0] != world[:, 1])
        if rows.size == 0:
            return None
        world_first = world[rows, 0]
        geom = geom[rows]
        robot_geom = np.where(world_first, geom[:, 1], geom[:, 0]).tolist()
        world_geom = np.where(world_first, geom[:, 0], geom[:, 1]).tolist()
        labels = [
            f"{self._body_name[r]}/{self._geom_name[w]}"
            for r, w in zip(robot_geom, world_geom, strict=True)
        ]
        keys = tuple(dict.fromkeys(labels))
        rank = {key: i for i, key in enumerate(keys)}
        return _PairPlan(
            rows=rows.astype(np.int64),
            sign=np.where(world_first, 1.0, -1.0),
            pair=np.array([rank[label] for label in labels], dtype=np.int64),
            keys=keys,
            # With elliptic cones and condim >= 3 the first three rows of a contact's
            # constraint force are its local force, all that mj_contactForce would copy.
            in_efc_force=bool(self._elliptic and dim[rows].min() >= 3),
        )

    def _local_forces(self, data: mujoco.MjData, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Every contact's local force from ``mj_contactForce`` (pyramidal cones, condim 1),
        laid out as the kernel reads ``efc_force``: contact i at ``3 i``."""
        local = np.empty(3 * n)
        for i in range(n):
            mujoco.mj_contactForce(self._model, data, i, self._force)
            local[3 * i : 3 * i + 3] = self._force[:3]
        return local, np.arange(0, 3 * n, 3, dtype=np.int32)


class FallDetector:
    """TARGETS.md: pelvis below a fraction of nominal height, or a non-foot body on the floor."""

    def __init__(self, robot: Robot, model: mujoco.MjModel, spec: ExperimentSpec) -> None:
        self._ratio = spec.sim.fall.pelvis_height_ratio
        self._nominal_z = float(robot.home_qpos[2])  # standing pelvis height [m]
        self._min_z = self._ratio * self._nominal_z
        self._check_contact = spec.sim.fall.non_foot_ground_contact
        self._pelvis = model.body("pelvis").id
        self._floor = floor = model.geom(FLOOR_NAME).id
        feet = {model.body(name).id for name in FOOT_BODIES}
        # Geoms of the robot's tree other than the feet (obstacles may rest on the floor).
        non_foot = np.array(
            [
                model.body_rootid[model.geom_bodyid[g]] == self._pelvis
                and model.geom_bodyid[g] not in feet
                for g in range(model.ngeom)
            ]
        )
        # falls[g1, g2]: a contact between these two geoms is a non-foot body on the floor.
        self._falls = np.zeros((model.ngeom, model.ngeom), dtype=bool)
        self._falls[floor, non_foot] = self._falls[non_foot, floor] = True
        self._geom_body = [model.body(model.geom_bodyid[g]).name for g in range(model.ngeom)]
        self._suspects: dict[bytes, np.ndarray] = {}

    def check(self, data: mujoco.MjData) -> str:
        """Reason for a fall, or an empty string."""
        z = data.xpos[self._pelvis, 2]
        if z < self._min_z:
            return (
                f"the pelvis dropped to {z:.2f} m, under {self._ratio:.0%} of its standing "
                f"height of {self._nominal_z:.2f} m"
            )
        n = data.ncon
        if not (self._check_contact and n):
            return ""
        contact = data.contact
        geom = contact.geom[:n]
        # Which contacts pair the floor with a non-foot geom depends only on the contact set,
        # which recurs tick after tick: look it up once per set (usually: none).
        signature = geom.tobytes()
        rows = self._suspects.get(signature)
        if rows is None:
            if len(self._suspects) >= MAX_CACHED_SETS:
                self._suspects.clear()
            rows = self._suspects[signature] = np.flatnonzero(self._falls[geom[:, 0], geom[:, 1]])
        if rows.size:
            touching = rows[contact.dist[rows] < 0]
            if touching.size:
                g1, g2 = geom[touching[0]]
                robot_geom = g2 if g1 == self._floor else g1
                return f"{self._geom_body[robot_geom]} touched the floor"
        return ""
