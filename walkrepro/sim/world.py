"""Builds the MuJoCo scene: robot MJCF + floor + obstacles + the spec's physics options.

The floor and every obstacle take the contact of :mod:`walkrepro.sim.contact_model` (docs/contact.md).

The scene is returned as one self-contained XML string. The runner compiles its model from
that very string, and the log stores it as ``scene.xml``; replaying a log therefore uses
the identical model, bit for bit.
"""

from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from walkrepro.errors import SpecError
from walkrepro.sim.contact_model import ContactModel, contact_model
from walkrepro.sim.robot import Robot
from walkrepro.sim.springs import set_springs
from walkrepro.specs.models import ExperimentSpec, ObstacleSpec

#: Collision filtering: robot geoms use contype=2/conaffinity=1 (no self-collision); world
#: geoms use contype=1/conaffinity=3 so they touch the robot and each other.
WORLD_CONTYPE = 1
WORLD_CONAFFINITY = 3
FLOOR_NAME = "floor"
#: Contact priority of the floor: above the robots' geoms (0), so that the floor's friction
#: acts on the soles; obstacles get one more.
FLOOR_PRIORITY = 1
#: Penetration [m] of a robot geom into an obstacle at the home pose beyond which the
#: obstacle overlaps the robot (a touch, e.g. a sole resting on a step, stays below it).
OVERLAP_TOLERANCE = 1e-3
#: The robot's root body (sim/robot.py's conventions); its subtree is the robot.
ROBOT_ROOT = "pelvis"
#: Scene options are the robot's: ``robots/<robot>/parameters.yaml`` sets them (entries
#: ``option_<attribute>``, written into the robot's MJCF ``<option>`` by
#: ``robots/build_models.py``) with their class, and the scene keeps them; every other option
#: is MuJoCo's default (:mod:`walkrepro.publish.ledger` lists both). A spec's ``world.cone`` and
#: ``world.condim`` override them for a sensitivity map.
CONE_KEYWORDS: dict[str, int] = {
    "pyramidal": int(mujoco.mjtCone.mjCONE_PYRAMIDAL),
    "elliptic": int(mujoco.mjtCone.mjCONE_ELLIPTIC),
}


@dataclass(frozen=True)
class Scene:
    """A compiled scene.

    Attributes:
        xml: self-contained MJCF of robot, floor and obstacles.
        model: the model compiled from ``xml``.
    """

    xml: str
    model: mujoco.MjModel


def build_scene(robot: Robot, spec: ExperimentSpec) -> Scene:
    """Compose the robot with the spec's world and physics timestep."""
    mjspec = mujoco.MjSpec.from_file(str(robot.xml_path))
    mjspec.modelname = f"{spec.name}-{robot.name}"
    mjspec.option.timestep = spec.sim.timestep
    # The friction cone and the solver are the robot's MJCF <option> (its ledger), unless a
    # sensitivity map sets the cone.
    if spec.world.cone is not None:
        mjspec.option.cone = CONE_KEYWORDS[spec.world.cone]
    _add_visuals(mjspec)
    floor = mjspec.worldbody.add_geom()
    floor.name = FLOOR_NAME
    floor.type = mujoco.mjtGeom.mjGEOM_PLANE
    floor.size = [0.0, 0.0, 1.0]  # infinite plane, grid spacing 1 m
    floor.friction = [spec.world.floor_friction, 0.005, 0.0001]
    # MuJoCo mixes two geoms' friction by taking the larger, so against the robot's soles
    # (friction 1) a lower floor friction would not act; the higher priority makes the
    # floor's own friction, solref and solimp the ones of every robot-floor contact.
    floor.priority = FLOOR_PRIORITY
    contact = contact_model(robot, spec.world.contact, spec.sim.timestep)
    floor.solref = list(contact.solref)
    floor.solimp = list(contact.solimp)
    if spec.world.condim is not None:
        # With its higher priority the floor's condim is the one of every robot-floor contact.
        floor.condim = spec.world.condim
    floor.contype = WORLD_CONTYPE
    floor.conaffinity = WORLD_CONAFFINITY
    floor.material = "grid"
    for obstacle in spec.world.obstacles:
        _add_obstacle(mjspec, obstacle, spec.world.floor_friction, contact, spec.world.condim)
    _set_position_gains(mjspec, spec.actuators.position_gain)
    _set_drives(mjspec, spec.actuators.friction_loss, spec.actuators.torque_lag)
    set_springs(mjspec, spec.actuators.spring, spec.actuators.backlash)
    mjspec.compile()  # to_xml() writes the compiled spec
    xml = mjspec.to_xml()
    # Compile again from the text: the logged XML is the single source of truth.
    return Scene(xml=xml, model=mujoco.MjModel.from_xml_string(xml))


def home_overlaps(
    robot: Robot, model: mujoco.MjModel, spec: ExperimentSpec
) -> dict[str, dict[str, float]]:
    """Robot collision geoms each obstacle penetrates when the robot stands at ``home``.

    ``model`` is the scene's (:func:`build_scene` of ``robot`` and ``spec``), set to the
    robot's home keyframe and MuJoCo's collision detection run (``mj_forward``) on fresh
    data; a contact between an obstacle and a robot geom deeper than
    :data:`OVERLAP_TOLERANCE` is an overlap.

    Returns:
        obstacle name -> {robot geom (``body/geom``) -> penetration depth [m]}; obstacles
        that overlap nothing are absent.
    """
    data = mujoco.MjData(model)
    data.qpos[: robot.home_qpos.size] = robot.home_qpos  # as the runner starts a run
    mujoco.mj_forward(model, data)
    obstacles = {o.name for o in spec.world.obstacles}
    robot_root = model.body_rootid[model.body(ROBOT_ROOT).id]
    out: dict[str, dict[str, float]] = {}
    for contact in data.contact[: data.ncon]:
        names = [model.geom(int(g)).name for g in contact.geom]
        for mine, other in ((0, 1), (1, 0)):
            other_body = int(model.geom_bodyid[contact.geom[other]])
            is_robot = model.body_rootid[other_body] == robot_root
            if names[mine] in obstacles and is_robot and -contact.dist > OVERLAP_TOLERANCE:
                label = f"{model.body(other_body).name}/{names[other] or int(contact.geom[other])}"
                hits = out.setdefault(names[mine], {})
                hits[label] = max(hits.get(label, 0.0), -float(contact.dist))
    return out


def _add_obstacle(
    mjspec: mujoco.MjSpec,
    obstacle: ObstacleSpec,
    floor_friction: float,
    contact: ContactModel,
    condim: int | None = None,
) -> None:
    """A box with its centre (or, ``anchor: top``, its top face's centre) at ``position``,
    tilted about that point, about x then y (degrees)."""
    numbers = (*obstacle.size, *obstacle.position, obstacle.tilt_x_deg, obstacle.tilt_y_deg)
    if not all(math.isfinite(x) for x in numbers):
        # The spec's validation refuses these; a spec built in code must not reach MuJoCo,
        # which would place a NaN box at the origin or fail with an opaque error.
        raise SpecError(f"obstacle {obstacle.name!r}: size, position and tilt must be finite.")
    body = mjspec.worldbody.add_body()
    body.name = obstacle.name
    body.pos = list(obstacle.position)
    body.quat = _quat_xy(math.radians(obstacle.tilt_x_deg), math.radians(obstacle.tilt_y_deg))
    if not obstacle.fixed:
        body.add_freejoint()
    geom = body.add_geom()
    geom.name = obstacle.name
    geom.type = mujoco.mjtGeom.mjGEOM_BOX
    geom.size = [s / 2 for s in obstacle.size]  # MuJoCo box sizes are half-extents
    if obstacle.anchor == "top":
        geom.pos = [0.0, 0.0, -obstacle.size[2] / 2]  # the body's origin is the top face's centre
    friction = obstacle.friction if obstacle.friction is not None else floor_friction
    geom.friction = [friction, 0.005, 0.0001]
    # MuJoCo otherwise mixes two geoms' friction by taking the larger; the priority (above
    # the floor's) makes the obstacle's own friction the one that acts on the foot, and on
    # the floor under a free obstacle.
    geom.priority = FLOOR_PRIORITY + 1
    # With the higher priority, the obstacle's solref/solimp are the ones its contacts use:
    # the floor's material (docs/contact.md) unless the spec departs, with its reason.
    geom.solref = list(obstacle.solref if obstacle.solref is not None else contact.solref)
    geom.solimp = list(contact.solimp)
    if condim is not None:
        geom.condim = condim
    geom.contype = WORLD_CONTYPE
    geom.conaffinity = WORLD_CONAFFINITY
    geom.rgba = [0.85, 0.45, 0.2, 1.0]
    if obstacle.mass is not None:
        geom.mass = obstacle.mass


def _set_position_gains(mjspec: mujoco.MjSpec, gains: dict[str, float]) -> None:
    """Set the stiffness kp [Nm/rad] of position servos whose names match the globs."""
    for pattern, kp in gains.items():
        for actuator in mjspec.actuators:
            if fnmatch.fnmatchcase(actuator.name, pattern):
                # A MuJoCo position servo is force = kp * ctrl - kp * q.
                actuator.gainprm[0] = kp
                actuator.biasprm[1] = -kp


def _set_drives(
    mjspec: mujoco.MjSpec, friction_loss: float | None, torque_lag: float | None
) -> None:
    """Set the Coulomb friction [Nm] of the DoF each actuator drives and the time constant
    [s] of first-order actuator dynamics; None leaves the robot's own value."""
    for actuator in mjspec.actuators:
        if friction_loss is not None:
            mjspec.joint(actuator.target).frictionloss = friction_loss
        if torque_lag is not None:
            actuator.dynprm[0] = torque_lag


def _quat_xy(rx: float, ry: float) -> list[float]:
    """Quaternion (w, x, y, z) of a rotation about x by ``rx`` then about the new y by ``ry``."""
    qx = np.array([math.cos(rx / 2), math.sin(rx / 2), 0.0, 0.0])
    qy = np.array([math.cos(ry / 2), 0.0, math.sin(ry / 2), 0.0])
    out = np.zeros(4)
    mujoco.mju_mulQuat(out, qx, qy)
    return out.tolist()


def _add_visuals(mjspec: mujoco.MjSpec) -> None:
    """Checkered floor, sky and lights for snapshot rendering (no effect on physics)."""
    tex = mjspec.add_texture()
    tex.name = "grid"
    tex.type = mujoco.mjtTexture.mjTEXTURE_2D
    tex.builtin = mujoco.mjtBuiltin.mjBUILTIN_CHECKER
    tex.rgb1 = [0.82, 0.85, 0.88]
    tex.rgb2 = [0.72, 0.75, 0.78]
    tex.width = 300
    tex.height = 300
    sky = mjspec.add_texture()
    sky.name = "sky"
    sky.type = mujoco.mjtTexture.mjTEXTURE_SKYBOX
    sky.builtin = mujoco.mjtBuiltin.mjBUILTIN_GRADIENT
    sky.rgb1 = [0.55, 0.7, 0.85]
    sky.rgb2 = [0.95, 0.97, 1.0]
    sky.width = 64
    sky.height = 384
    mat = mjspec.add_material()
    mat.name = "grid"
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "grid"
    mat.texrepeat = [8, 8]
    mat.reflectance = 0.1
    light = mjspec.worldbody.add_light()
    light.name = "sun"
    light.pos = [0.0, -1.0, 4.0]
    light.dir = [0.0, 0.3, -1.0]
    light.castshadow = True
    mjspec.visual.headlight.ambient = [0.35, 0.35, 0.35]
    mjspec.visual.headlight.diffuse = [0.5, 0.5, 0.5]
    mjspec.visual.global_.offwidth = 1280
    mjspec.visual.global_.offheight = 960
