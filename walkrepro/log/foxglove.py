"""Foxglove well-known messages of a run: the robot's body frames and its geoms as primitives.

- ``/frames`` (``foxglove.FrameTransforms``) at least every :data:`FRAME_PERIOD` of simulated time:
  the pose of every body in the ``world`` frame (MuJoCo's ``xpos``, ``xquat``).
- ``/scene`` (``foxglove.SceneUpdate``), once at the start: one entity per body, on the
  body's frame (``frame_locked``, so it moves with the body), holding its geoms as cubes,
  spheres and cylinders (a capsule is a cylinder with a sphere at each end; the floor plane a
  thin 20 m × 20 m slab). Obstacles are bodies like any other.

Schemas come from Foxglove's published package ``foxglove-schemas-protobuf``. The scene is
built with its classes; ``FrameTransforms``, written 50 times a simulated second, is put
together in protobuf's wire format from a precomputed template (≈ 30x cheaper than building
the protobuf objects for 30 bodies), and ``tests/test_foxglove.py`` decodes it with the
published classes.
"""

from __future__ import annotations

import struct
from typing import NamedTuple

import mujoco
import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CubePrimitive_pb2 import CubePrimitive
from foxglove_schemas_protobuf.CylinderPrimitive_pb2 import CylinderPrimitive
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.SpherePrimitive_pb2 import SpherePrimitive
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.timestamp_pb2 import Timestamp

from walkrepro.log.protolog import descriptor_set_of, length_delimited, tag, varint

#: Longest simulated time between two ``/frames`` messages [s]: 30 Hz, what a viewer needs.
#: They go out on control ticks, every ``frame_every(control_period)`` of them (≥ 30 Hz); a
#: message costs tens of µs in the loop, where its code and data are no longer in the CPU's
#: caches, so not more often.
FRAME_PERIOD = 1 / 30
#: Side of the slab that draws the infinite floor plane [m].
FLOOR_SIZE = 20.0
#: Thickness of that slab [m] (its top face is the plane).
FLOOR_THICKNESS = 0.01
WORLD_FRAME = "world"

FRAME_TRANSFORMS_SCHEMA = ("foxglove.FrameTransforms", FrameTransforms.DESCRIPTOR.file)
SCENE_UPDATE_SCHEMA = ("foxglove.SceneUpdate", SceneUpdate.DESCRIPTOR.file)


def schema_data(file_descriptor) -> bytes:  # noqa: ANN001 - a protobuf FileDescriptor
    """A published schema's ``FileDescriptorSet`` for the log."""
    return descriptor_set_of(file_descriptor)


def frame_every(control_period: float) -> int:
    """Control ticks between two ``/frames`` messages: as many as fit in :data:`FRAME_PERIOD`
    (at least one)."""
    return max(1, int(FRAME_PERIOD / control_period + 1e-9))


def body_names(model: mujoco.MjModel) -> list[str]:
    """Frame id of each body: its name, ``world`` for body 0, ``body<i>`` if unnamed."""
    names = []
    for i in range(model.nbody):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i)
        names.append(WORLD_FRAME if i == 0 else name or f"body{i}")
    return names


def timestamp(stamp_ns: int) -> Timestamp:
    """A protobuf timestamp of ``stamp_ns`` [ns since 1970, UTC]."""
    return Timestamp(seconds=stamp_ns // 1_000_000_000, nanos=stamp_ns % 1_000_000_000)


# FrameTransform fields: 1 timestamp, 2 parent_frame_id, 3 child_frame_id, 4 translation
# (Vector3: 1 x, 2 y, 3 z), 5 rotation (Quaternion: 1 x, 2 y, 3 z, 4 w), all doubles.
_POSE = struct.Struct("<BBBdBdBdBBBdBdBdBd")
_VECTOR3_LEN, _QUATERNION_LEN = 27, 36
#: Where the pose's seven doubles (x, y, z, qx, qy, qz, qw) start in a packed pose.
_POSE_DOUBLES = (3, 12, 21, 32, 41, 50, 59)
_POSE_BYTES = (np.array(_POSE_DOUBLES)[:, None] + np.arange(8)).ravel()


class FrameEncoder:
    """``foxglove.FrameTransforms`` messages of every body but the world, parent ``world``.

    All of a message but its numbers is the same for every message of a run with the same
    length of timestamp: that template is built once per length, with the places of the
    timestamp's and the poses' bytes, and a message is the template with those bytes put
    in (four numpy calls, whatever the number of bodies).
    """

    def __init__(self, model: mujoco.MjModel) -> None:
        names = body_names(model)
        self.bodies = np.arange(1, model.nbody)
        self._names = [
            length_delimited(2, WORLD_FRAME.encode()) + length_delimited(3, names[i].encode())
            for i in self.bodies
        ]
        # Pose columns in the order they are packed: x, y, z, then the quaternion's x, y, z, w.
        self._quat_order = np.array([1, 2, 3, 0])
        self._templates: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def encode(self, stamp_ns: int, xpos: np.ndarray, xquat: np.ndarray) -> bytes:
        """The message at ``stamp_ns`` [ns, UTC] from MuJoCo's ``xpos`` and ``xquat`` (w, x,
        y, z) of all bodies."""
        seconds, nanos = divmod(stamp_ns, 1_000_000_000)
        stamp = tag(1, 0) + varint(seconds) + (tag(2, 0) + varint(nanos) if nanos else b"")
        stamp_field = np.frombuffer(length_delimited(1, stamp), np.uint8)
        template = self._templates.get(stamp_field.size)
        if template is None:
            template = self._templates[stamp_field.size] = self._template(stamp_field.size)
        out, pose_at, stamp_at = template
        out = out.copy()
        bodies = self.bodies
        poses = np.concatenate((xpos[bodies], xquat[bodies][:, self._quat_order]), axis=1)
        out[pose_at] = poses.view(np.uint8).ravel()
        out[stamp_at] = np.tile(stamp_field, bodies.size)
        return out.tobytes()

    def _template(self, stamp_size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The message's bytes with zero numbers, and the places of the poses' doubles (body
        by body, 7 x 8 bytes each) and of each body's timestamp field."""
        zero_pose = _POSE.pack(
            0x22, _VECTOR3_LEN, 0x09, 0.0, 0x11, 0.0, 0x19, 0.0,
            0x2A, _QUATERNION_LEN, 0x09, 0.0, 0x11, 0.0, 0x19, 0.0, 0x21, 0.0,
        )  # fmt: skip
        out = bytearray()
        pose_starts, stamp_starts = [], []
        for names in self._names:
            body = stamp_size + len(names) + len(zero_pose)
            out += b"\x0a" + varint(body)
            stamp_starts.append(len(out))
            out += bytes(stamp_size) + names
            pose_starts.append(len(out))
            out += zero_pose
        pose_at = (np.array(pose_starts)[:, None] + _POSE_BYTES).ravel()
        stamp_at = (np.array(stamp_starts)[:, None] + np.arange(stamp_size)).ravel()
        return np.frombuffer(bytes(out), np.uint8), pose_at, stamp_at


def scene_update(model: mujoco.MjModel, stamp_ns: int) -> bytes:
    """The ``foxglove.SceneUpdate`` of the model's geoms (see the module docstring)."""
    names = body_names(model)
    entities = {}
    stamp = timestamp(stamp_ns)
    for g in range(model.ngeom):
        body = int(model.geom_bodyid[g])
        entity = entities.get(body)
        if entity is None:
            entity = entities[body] = SceneEntity(
                timestamp=stamp, frame_id=names[body], id=names[body], frame_locked=True
            )
        _add_geom(entity, model, g)
    return SceneUpdate(entities=list(entities.values())).SerializeToString()


class GeomShape(NamedTuple):
    """A geom as a primitive in its body's frame, for viewers that draw primitives (this
    module's ``/scene``, :mod:`walkrepro.present.rerun_export`).

    Attributes:
        kind: ``box``, ``ellipsoid`` (a sphere too), ``cylinder`` or ``capsule``; a plane
            is a ``box``: a :data:`FLOOR_SIZE` slab :data:`FLOOR_THICKNESS` thick whose top
            face is the plane.
        pos: centre in the body's frame [m], shape (3,).
        quat: orientation in the body's frame (w, x, y, z), shape (4,).
        size: full extents along the geom's axes [m], shape (3,); a cylinder or a capsule:
            (2 r, 2 r, length of its cylindrical part), its axis along z.
        rgba: colour, each in [0, 1], shape (4,).
    """

    kind: str
    pos: np.ndarray
    quat: np.ndarray
    size: np.ndarray
    rgba: np.ndarray


def geom_shape(model: mujoco.MjModel, g: int) -> GeomShape | None:
    """Geom ``g`` as a :class:`GeomShape`; None for meshes, height fields and SDFs, which
    have no primitive (walkrepro's robots use none)."""
    kind = mujoco.mjtGeom(int(model.geom_type[g]))  # numpy ints do not match enums in `in`
    size = model.geom_size[g]
    pos, quat = model.geom_pos[g].astype(float), model.geom_quat[g].astype(float)
    rgba = model.geom_rgba[g].astype(float)
    geom = mujoco.mjtGeom
    if kind == geom.mjGEOM_PLANE:
        offset = np.zeros(3)
        mujoco.mju_rotVecQuat(offset, np.array([0.0, 0.0, -FLOOR_THICKNESS / 2]), quat)
        extents = np.array([FLOOR_SIZE, FLOOR_SIZE, FLOOR_THICKNESS])
        return GeomShape("box", pos + offset, quat, extents, rgba)
    if kind == geom.mjGEOM_BOX:
        return GeomShape("box", pos, quat, 2 * size.astype(float), rgba)
    if kind in (geom.mjGEOM_SPHERE, geom.mjGEOM_ELLIPSOID):
        radii = size if kind == geom.mjGEOM_ELLIPSOID else np.repeat(size[0], 3)
        return GeomShape("ellipsoid", pos, quat, 2 * radii.astype(float), rgba)
    if kind in (geom.mjGEOM_CYLINDER, geom.mjGEOM_CAPSULE):
        radius, half = float(size[0]), float(size[1])
        name = "cylinder" if kind == geom.mjGEOM_CYLINDER else "capsule"
        return GeomShape(name, pos, quat, np.array([2 * radius, 2 * radius, 2 * half]), rgba)
    return None


def _pose(pos: np.ndarray, quat: np.ndarray) -> Pose:
    return Pose(
        position=Vector3(x=pos[0], y=pos[1], z=pos[2]),
        orientation=Quaternion(w=quat[0], x=quat[1], y=quat[2], z=quat[3]),
    )


def _vector3(v: np.ndarray) -> Vector3:
    return Vector3(x=v[0], y=v[1], z=v[2])


def _add_geom(entity: SceneEntity, model: mujoco.MjModel, g: int) -> None:
    """Appends geom ``g`` to ``entity`` as primitives in its body's frame (a capsule as a
    cylinder and a sphere at each end)."""
    shape = geom_shape(model, g)
    if shape is None:
        return
    r, gr, b, a = (float(c) for c in shape.rgba)
    color = Color(r=r, g=gr, b=b, a=a)
    pose = _pose(shape.pos, shape.quat)
    if shape.kind == "box":
        entity.cubes.append(CubePrimitive(pose=pose, size=_vector3(shape.size), color=color))
    elif shape.kind == "ellipsoid":
        entity.spheres.append(SpherePrimitive(pose=pose, size=_vector3(shape.size), color=color))
    else:
        entity.cylinders.append(
            CylinderPrimitive(
                pose=pose, size=_vector3(shape.size), bottom_scale=1.0, top_scale=1.0, color=color
            )
        )
    if shape.kind == "capsule":
        diameter, half = shape.size[0], shape.size[2] / 2
        for end in (-half, half):
            centre = np.zeros(3)
            mujoco.mju_rotVecQuat(centre, np.array([0.0, 0.0, end]), shape.quat)
            entity.spheres.append(
                SpherePrimitive(
                    pose=_pose(shape.pos + centre, shape.quat),
                    size=Vector3(x=diameter, y=diameter, z=diameter),
                    color=color,
                )
            )
