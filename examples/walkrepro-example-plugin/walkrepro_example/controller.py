"""A joint-space PD controller that holds the robot's home posture, without a model.

    τ = K_p (q_home − q) − K_d q̇        [N·m], joint order of the robot's actuators

It reads only the joint encoders of the sensor snapshot, as every walkrepro controller reads
only what the robot senses. On a position-controlled robot it sends the home motor targets.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from walkrepro.controllers import Command, Controller, ControllerParams
from walkrepro.controllers.ranges import MAX_JOINT_DAMPING, MAX_JOINT_STIFFNESS
from walkrepro.sim.robot import Robot
from walkrepro.sim.sensors import SensorSnapshot


class JointPdParams(ControllerParams):
    """The spec's ``controller.params`` block, validated once when the spec loads."""

    # Every number has a physical range (walkrepro.controllers.ranges): out of it, the spec
    # is refused with the field and the range.
    kp: float = Field(
        600.0, ge=0.0, le=MAX_JOINT_STIFFNESS, description="joint stiffness K_p [N·m/rad]"
    )
    kd: float = Field(
        30.0, ge=0.0, le=MAX_JOINT_DAMPING, description="joint damping K_d [N·m·s/rad]"
    )


class JointPdController(Controller):
    """Holds the ``home`` keyframe's joint angles with a PD law."""

    Params = JointPdParams

    def reset(self, robot: Robot, params: ControllerParams, control_period: float) -> None:
        assert isinstance(params, JointPdParams)
        self._robot, self._params = robot, params
        self._q_home = robot.home_joint_pos.copy()

    def step(self, t: float, sensors: SensorSnapshot) -> Command:
        if self._robot.control_mode == "position":
            return Command(ctrl=self._robot.home_ctrl.copy())
        error = self._q_home - sensors.joint_pos
        tau = self._params.kp * error - self._params.kd * sensors.joint_vel
        return Command(ctrl=tau, signals={"pd_error": float(np.abs(error).max())})
