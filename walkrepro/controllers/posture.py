"""Standing posture controller: joint PD plus gravity compensation through the feet.

The sanity controller of the ``stand_*`` experiments. For torque-controlled robots it
returns

    τ = S (g(q) − J_cᵀ λ) + K_p (q_home − q) − K_d q̇,

where λ (both feet's wrenches) is the minimum-norm solution of the floating-base rows
J_c,baseᵀ λ = g_base: the feet carry the weight and the joints only hold the posture.
For position-controlled robots (series-elastic COMAN) it returns the motor targets of the
``home`` keyframe, i.e. the servos hold the posture.

It runs at up to 2 kHz; after Pinocchio's gravity and sole Jacobians, the algebra on
6 × 6 and 12 × n matrices is one compiled numba call rather than ten numpy calls.
"""

from __future__ import annotations

import numba
import numpy as np
import pinocchio as pin
from pydantic import Field

from walkrepro.controllers.base import Command, Controller, ControllerParams
from walkrepro.controllers.ranges import MAX_JOINT_DAMPING, MAX_JOINT_STIFFNESS
from walkrepro.sim.robot import Robot
from walkrepro.sim.sensors import SensorSnapshot
from walkrepro.specs.origin import assumed

SOLE_FRAMES = ("left_sole", "right_sole")


class PostureParams(ControllerParams):
    """Posture gains (torque robots only)."""

    kp: float = Field(
        300.0,
        ge=0.0,
        le=MAX_JOINT_STIFFNESS,
        description="joint stiffness K_p [Nm/rad]",
        json_schema_extra=assumed("walkrepro's standing check, not a paper's: 300 Nm/rad"),
    )
    kd: float = Field(
        20.0,
        ge=0.0,
        le=MAX_JOINT_DAMPING,
        description="joint damping K_d [Nms/rad]",
        json_schema_extra=assumed("walkrepro's standing check: 20 Nms/rad"),
    )
    gravity_compensation: bool = Field(
        True,
        description="add S(g − J_cᵀλ)",
        json_schema_extra=assumed("walkrepro's standing check: gravity compensated"),
    )


@numba.njit("f8[:](f8[:,:], f8[:])", cache=True)
def feet_gravity_torque(jc: np.ndarray, g: np.ndarray) -> np.ndarray:
    """S (g − J_cᵀ λ) for the soles' Jacobians ``jc`` (rows: both feet's wrenches, columns:
    Pinocchio's v with the 6 base columns first) and the gravity vector ``g``.

    λ is the minimum-norm solution of the base rows A λ = g_base, A = J_c,baseᵀ (6 × 12, full
    row rank with both feet down): λ = Aᵀ (A Aᵀ)⁻¹ g_base, a 6 × 6 solve.
    """
    base = np.ascontiguousarray(jc[:, :6])
    lam = base @ np.linalg.solve(np.ascontiguousarray(base.T) @ base, g[:6])
    return g[6:] - lam @ np.ascontiguousarray(jc[:, 6:])


class PostureController(Controller):
    """Holds the robot's ``home`` posture."""

    Params = PostureParams

    def reset(self, robot: Robot, params: ControllerParams, control_period: float) -> None:
        """Cache the home posture and Pinocchio workspace."""
        assert isinstance(params, PostureParams)
        self._robot = robot
        self._params = params
        self._q_home = robot.home_joint_pos.copy()
        self._data = robot.pin_model.createData()
        self._soles = [robot.pin_model.getFrameId(f) for f in SOLE_FRAMES]
        self._jc = np.zeros((6 * len(SOLE_FRAMES), robot.pin_model.nv))  # both soles' Jacobians

    def step(self, t: float, sensors: SensorSnapshot) -> Command:
        """PD + gravity compensation, or the home motor targets for position servos."""
        robot, p = self._robot, self._params
        if robot.control_mode == "position":
            return Command(ctrl=robot.home_ctrl.copy(), signals={"posture_error": 0.0})
        error = self._q_home - sensors.joint_pos
        tau = p.kp * error - p.kd * sensors.joint_vel
        if p.gravity_compensation:
            tau += self._gravity_torque(sensors)
        return Command(ctrl=tau, signals={"posture_error": float(np.abs(error).max())})

    def _gravity_torque(self, sensors: SensorSnapshot) -> np.ndarray:
        """S (g − J_cᵀ λ) with λ carrying the floating base's gravity load."""
        model, data, jc = self._robot.pin_model, self._data, self._jc
        q = sensors.pinocchio_configuration(self._robot, "the posture controller")
        g = pin.computeGeneralizedGravity(model, data, q)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        for rows, frame in zip((slice(0, 6), slice(6, 12)), self._soles, strict=True):
            jc[rows] = pin.getFrameJacobian(
                model, data, frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
            )
        return feet_gravity_torque(jc, g)
