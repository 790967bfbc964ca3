"""The open-loop layer of Paper II (Fig. 3, A → C): 3LP gait → Cartesian targets → joints.

- the 3LP model's parameters derived from the robot model (note ``3lp.md`` §8);
- the Cartesian targets of the pelvis and both soles in a level frame attached to the
  pelvis, with the fixed lift of Eqs. (22)-(23) and the adaptive lift of Eqs. (28)-(30);
- analytic leg IK (:mod:`.ik`) to link-side joint angles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from walkrepro.papers.faraji.ik import (
    SOLE_FRAMES,
    LegConstants,
    LegGeometry,
    leg_ik,
    leg_ik_scalar,
    rot_rpy,
)
from walkrepro.papers.faraji.projection import TimeProjection
from walkrepro.papers.faraji.threelp import (
    HIP,
    PELVIS,
    SWING,
    Q,
    ThreeLP,
    ThreeLPParams,
    U,
    reconstruction,
)
from walkrepro.sim.robot import Robot


def threelp_params_from_robot(robot: Robot, leg_inertia: bool = True) -> ThreeLPParams:
    """3LP parameters of a robot at its ``home`` posture (note ``3lp.md`` §8).

    - m1: everything but the legs (pelvis, trunk, head, arms) [kg];
    - m2: one leg, the subtree of the pelvis's child that carries the left sole (coman:
      ``l_hip_yaw_link``; coman_lab: ``l_hip_pitch_link``) [kg];
    - h1: pelvis (hip-midpoint) height (:attr:`Robot.nominal_pelvis_height`) [m];
    - h2: depth of the leg's CoM below the pelvis origin [m];
    - h3: height of the m1 CoM above the pelvis origin [m];
    - pw: half the hip spacing: the hip centre's lateral offset (where the three hip axes
      meet, :class:`.ik.LegGeometry`) [m];
    - I2 = I3: the leg's pitch inertia about its own CoM [kg m²] (Paper II, 3LP Model: "each
      pendulum approximates the entire corresponding limb in the robot with a mass in the
      middle and inertia in the sagittal and lateral planes"); 0 with ``leg_inertia=False``
      (point-mass legs). On coman it is 0.265 kg m², close to the point mass's own
      m2 h2² = 0.309 kg m² about the hip, so leaving it out halves the swing leg's inertia.

    Which set (decided before any run on coman_lab): the robot's, so on coman_lab the lab's
    Robotran bodies (class source, robots/coman_lab/parameters.yaml) at the paper's home
    posture (knee 0.4 rad): m1 15.51 kg, m2 6.424 kg, h1 0.5165 m, h2 0.221 m, h3 0.231 m,
    pw 0.0726 m, I2 0.171 kg m². The paper's first author's own 3LP set for COMAN
    (salmanfaraji/Walking3LP @ 63d55a6, anatomy/coman_ratios.m and tools/model_geom.m) gives
    the masses (M 28.5 kg, m2 6.39 kg per leg; its m1, 14.17 kg, leaves the pelvis out) and
    every length as a fraction of a body length L, which the same file sets to r.L = 1 m (the
    GUI's anatomy selector loads it, Walking3LP.m): h1 0.524 m, h2 0.232 m, h3 0.190 m,
    pw 0.0636 m (r.pelvis; 0.0761 in the earlier commit 592f691), I2 0.207 kg m²; its masses
    agree with the lab's within 0.6 %, its hips are 12.7 cm apart against the lab's 14.5 cm
    and Paper II's "about 14 cm". The time projection is a model of the robot it runs on,
    and the lab's model gives every quantity at the posture the controller holds.
    """
    model = robot.mj_model
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    pelvis, leg = model.body("pelvis").id, leg_root_body(robot, "l")
    total, m2 = float(model.body_subtreemass[pelvis]), float(model.body_subtreemass[leg])
    m1 = total - 2.0 * m2
    z_pelvis = float(data.xpos[pelvis, 2])
    z_leg = float(data.subtree_com[leg, 2])
    z_upper = (total * float(data.subtree_com[pelvis, 2]) - 2.0 * m2 * z_leg) / m1
    hip_y = float(abs(LegGeometry.from_robot(robot, "l").hip[1]))
    inertia = _subtree_pitch_inertia(model, data, leg) if leg_inertia else 0.0
    return ThreeLPParams(
        m1=m1,
        m2=m2,
        h1=robot.nominal_pelvis_height,
        h2=z_pelvis - z_leg,
        h3=z_upper - z_pelvis,
        pw=hip_y,
        I2=inertia,
        I3=inertia,
    )


def leg_root_body(robot: Robot, side: str) -> int:
    """MuJoCo id of the leg's root: the pelvis's child body whose subtree holds the sole."""
    model = robot.mj_model
    pelvis = model.body("pelvis").id
    body = int(model.site_bodyid[model.site(SOLE_FRAMES[side]).id])
    while int(model.body_parentid[body]) != pelvis:
        if body == 0:
            raise ValueError(f"{robot.name}: {SOLE_FRAMES[side]} is not below the pelvis")
        body = int(model.body_parentid[body])
    return body


def series_stiffness(robot: Robot, joint: str) -> float:
    """A joint's motor-side position servo in series with its spring [Nm/rad], 0 if the
    robot has no springs.

    Paper II, Effective Ankle Stiffness: the servo's ≈ 1100 Nm/rad acts "in series" with
    the spring: k_eff = 1 / (1/k + 1/kp), kp = k_d/β of the motor model (Eqs. 19-20). kp
    is ``robot.mj_model``'s: the gain that runs when the runner passed the robot through
    :func:`walkrepro.sim.robot.with_servo_gains` (a spec's ``actuators`` override included).
    """
    if robot.spring_stiffness is None:
        return 0.0
    k_spring = float(robot.spring_stiffness[robot.joint_names.index(joint)])
    k_servo = float(robot.mj_model.actuator(joint).gainprm[0])
    return 1.0 / (1.0 / k_spring + 1.0 / k_servo)


def ankle_series_stiffness(robot: Robot, side: str = "l") -> float:
    """:func:`series_stiffness` of the ``side`` leg's ankle pitch [Nm/rad]."""
    return series_stiffness(robot, f"{side}_ankle_pitch")


def _subtree_pitch_inertia(model: mujoco.MjModel, data: mujoco.MjData, root: int) -> float:
    """Pitch (world y-y) inertia of the subtree at ``root`` about its own CoM [kg m²].

    Parallel-axis sum of the bodies' inertias, at the posture in ``data`` (kinematics done).
    """
    com = data.subtree_com[root]
    total = 0.0
    for b in range(model.nbody):
        a = b
        while a > root:
            a = int(model.body_parentid[a])
        if a != root:
            continue
        rot = data.ximat[b].reshape(3, 3)
        inertia = rot @ np.diag(model.body_inertia[b]) @ rot.T
        r = data.xipos[b] - com
        total += float(inertia[1, 1]) + float(model.body_mass[b]) * float(r[0] ** 2 + r[2] ** 2)
    return total


def relative_footstep_gains(model: ThreeLP, tp: TimeProjection) -> np.ndarray:
    """Gains of the touchdown change of the swing foot *relative to the pelvis*, Δ(f − p)(T).

    Paper II simulates the current error to the end of the phase under the time-projecting
    controller (posture F of Fig. 3) and takes the attack-angle change with respect to the
    nominal gait. A position-controlled swing hip sets f − p, so the adjustment that matters
    is the swing foot's change minus the pelvis's: this table, shape (n, 2, 8), on the same
    phase grid as ``tp``.
    """
    out = np.zeros((len(tp.phases), 2, 8))
    for i, t in enumerate(tp.phases):
        phi = model.propagator(float(t), tp.step_time - float(t))
        end = phi[Q, Q] @ reconstruction() - phi[Q, U][:, HIP] @ tp.torque_gains[i]
        out[i] = end[SWING] - end[PELVIS]
    return out


@dataclass(frozen=True)
class LegTargets:
    """Cartesian targets of one step instant in the level frame at the pelvis origin.

    Attributes:
        pelvis_roll: pelvis roll about x [rad] (Eq. 22), positive lifts the left hip.
        left: left sole point, shape (3,) [m]; right: the right one.
        left_pitch / right_pitch: foot pitch about y in the world [rad].
    """

    pelvis_roll: float
    left: np.ndarray
    right: np.ndarray
    left_pitch: float
    right_pitch: float


class LegIk:
    """Both legs' IK from :class:`LegTargets` (feet flat in the world unless pitched)."""

    def __init__(self, robot: Robot) -> None:
        self.left = LegGeometry.from_robot(robot, "l")
        self.right = LegGeometry.from_robot(robot, "r")
        self._left = LegConstants.from_geometry(self.left)
        self._right = LegConstants.from_geometry(self.right)

    def solve_level(
        self,
        pelvis_roll: float,
        left: tuple[float, float, float],
        right: tuple[float, float, float],
        left_pitch: float,
        right_pitch: float,
    ) -> list[float]:
        """:meth:`solve` for a level pelvis (pitch 0), on plain floats: the per-tick path.

        Args:
            pelvis_roll: pelvis roll about x [rad].
            left: left sole target (x, y, z) in the level frame [m]; right: the right one.
            left_pitch / right_pitch: foot pitch about y in the world [rad].

        Returns:
            Joint angles [left leg (6), right leg (6)] [rad].
        """
        # Level frame → pelvis: R_x(roll)ᵀ; foot orientation R_x(roll)ᵀ R_y(foot pitch).
        c, s = math.cos(pelvis_roll), math.sin(pelvis_roll)
        out: list[float] = []
        for leg, (x, y, z), foot_pitch in (
            (self._left, left, left_pitch),
            (self._right, right, right_pitch),
        ):
            cp, sp = math.cos(foot_pitch), math.sin(foot_pitch)
            rot = (cp, 0.0, sp, -s * sp, c, s * cp, -c * sp, -s, c * cp)
            out.extend(leg_ik_scalar(leg, x, c * y + s * z, c * z - s * y, rot))
        return out

    def solve(self, targets: LegTargets, pitch: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
        """Joint angles [left leg (6), right leg (6)] [rad].

        Args:
            targets: Cartesian targets in the level frame.
            pitch: pelvis pitch [rad] assumed for the (left, right) leg's IK: 0 for the
                commanded (level) posture, or the IMU's pitch to place a swing foot in the
                level frame whatever the torso lean.
        """
        legs = []
        for geom, pos, foot_pitch, pel_pitch in (
            (self.left, targets.left, targets.left_pitch, pitch[0]),
            (self.right, targets.right, targets.right_pitch, pitch[1]),
        ):
            r_t = rot_rpy(targets.pelvis_roll, pel_pitch).T
            legs.append(leg_ik(geom, r_t @ pos, r_t @ rot_rpy(0.0, foot_pitch)))
        return np.concatenate(legs)
