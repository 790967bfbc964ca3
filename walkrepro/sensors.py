"""The sensor snapshot a controller receives, and the model that produces it.

A controller sees only what the robot would sense: link-side joint encoders, the IMU, the
6-axis force/torque sensors between ankle and sole, and the floating-base state where the
paper says the simulator provides it. Noise, encoder quantization and delay come from the
spec's ``sensors`` block and are seeded, so a run is deterministic.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from walkrepro.robot import SENSOR_NAMES

if TYPE_CHECKING:
    from walkrepro.robot import Robot
    from walkrepro.spec import SensorsSpec

FOOT_SIDES = ("left", "right")


@dataclass(frozen=True)
class SensorSnapshot:
    """One reading of every sensor, as the controller receives it.

    Attributes:
        t: time the reading was taken [s] (earlier than the control time when delayed).
        joint_pos: link-side joint angles, shape (n,), actuator order [rad].
        joint_vel: link-side joint velocities, shape (n,) [rad/s].
        imu_quat: orientation of the IMU site, world-from-IMU, (w, x, y, z).
        imu_gyro: angular velocity in the IMU frame, shape (3,) [rad/s].
        imu_acc: specific force in the IMU frame, shape (3,) [m/s^2] (reads +g at rest).
        left_ft: left F/T sensor, (fx, fy, fz, tx, ty, tz) in the ``left_foot_ft`` site frame;
            the wrench the foot applies to the leg, so standing gives fz ≈ +supported weight
            [N, Nm].
        right_ft: right F/T sensor, same convention.
        base_pos: pelvis position in the world [m], or None when not provided.
        base_quat: pelvis orientation world-from-pelvis (w, x, y, z), or None.
        base_linvel: pelvis linear velocity in the world frame [m/s], or None.
        base_angvel: pelvis angular velocity in the pelvis frame [rad/s], or None.
    """

    t: float
    joint_pos: np.ndarray
    joint_vel: np.ndarray
    imu_quat: np.ndarray
    imu_gyro: np.ndarray
    imu_acc: np.ndarray
    left_ft: np.ndarray
    right_ft: np.ndarray
    base_pos: np.ndarray | None = None
    base_quat: np.ndarray | None = None
    base_linvel: np.ndarray | None = None
    base_angvel: np.ndarray | None = None

    def pinocchio_state(
        self, robot: Robot, who: str = "this controller"
    ) -> tuple[np.ndarray, np.ndarray]:
        """Pinocchio ``(q, v)`` of the robot from the base state and the joint encoders.

        Raises:
            ValueError: the spec does not provide the base state (``sensors.base_state``).
        """
        if self.base_pos is None or self.base_quat is None:
            raise ValueError(
                f"{who} needs the base state: set sensors.base_state: true in the spec"
            )
        return robot.pin_state(
            self.base_pos,
            self.base_quat,
            self.base_linvel,
            self.base_angvel,
            self.joint_pos,
            self.joint_vel,
        )

    def as_dict(self) -> dict[str, float | list[float] | None]:
        """Plain-JSON view for the log's ``/sensors`` topic."""
        out: dict[str, float | list[float] | None] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            out[f.name] = value.tolist() if isinstance(value, np.ndarray) else value
        return out


class SensorModel:
    """Turns simulator state into :class:`SensorSnapshot` with the spec's imperfections.

    This and the runner are the only code that reads ``MjData``; it only reads.
    """

    def __init__(
        self,
        robot: Robot,
        model: mujoco.MjModel,
        spec: SensorsSpec,
        control_period: float,
        seed: int,
    ) -> None:
        self._spec = spec
        self._rng = np.random.default_rng(seed)
        self._qpos_adr = robot.link_joint_qpos_adr(model)
        self._qvel_adr = robot.link_joint_qvel_adr(model)
        self._sensor = {name: _sensor_slice(model, name) for name in SENSOR_NAMES}
        # A delay of d seconds holds back round(d / control_period) readings.
        self._delay_ticks = int(round(spec.delay / control_period))
        self._buffer: deque[SensorSnapshot] = deque(maxlen=self._delay_ticks + 1)

    def read(self, model: mujoco.MjModel, data: mujoco.MjData) -> SensorSnapshot:
        """Read the sensors now (after ``mj_forward``) and return the delayed snapshot."""
        self._buffer.append(self._measure(data))
        return self._buffer[0]

    def _noisy(self, x: np.ndarray, std: float) -> np.ndarray:
        """``x`` plus seeded white noise of standard deviation ``std`` (a copy either way)."""
        if std == 0:
            return np.array(x, dtype=float)
        return x + std * self._rng.standard_normal(np.shape(x))

    def _measure(self, data: mujoco.MjData) -> SensorSnapshot:
        spec = self._spec
        # Sum the components of each link joint (motor + spring DoF for series-elastic joints).
        joint_pos = self._qpos_adr.link_values(data.qpos)
        joint_vel = self._qvel_adr.link_values(data.qvel)
        noisy = self._noisy
        joint_pos = noisy(joint_pos, spec.joint_position_noise)
        if spec.joint_position_quantization > 0:
            step = spec.joint_position_quantization
            joint_pos = np.round(joint_pos / step) * step
        joint_vel = noisy(joint_vel, spec.joint_velocity_noise)

        s = data.sensordata
        imu_quat = s[self._sensor["imu_quat"]].copy()
        imu_gyro = noisy(s[self._sensor["imu_gyro"]], spec.imu_gyro_noise)
        imu_acc = noisy(s[self._sensor["imu_acc"]], spec.imu_acc_noise)
        ft = {}
        for side in FOOT_SIDES:
            # MuJoCo's force/torque sensors give the wrench the parent applies to the foot
            # subtree; the F/T convention here is the reaction (foot on leg), hence the sign.
            force = noisy(-s[self._sensor[f"{side}_foot_force"]], spec.ft_force_noise)
            torque = noisy(-s[self._sensor[f"{side}_foot_torque"]], spec.ft_torque_noise)
            ft[side] = np.concatenate([force, torque])

        base: dict[str, np.ndarray | None] = dict.fromkeys(
            ("base_pos", "base_quat", "base_linvel", "base_angvel")
        )
        if spec.base_state:
            base = {
                "base_pos": data.qpos[0:3].copy(),
                "base_quat": data.qpos[3:7].copy(),
                "base_linvel": data.qvel[0:3].copy(),
                "base_angvel": data.qvel[3:6].copy(),
            }
        return SensorSnapshot(
            t=float(data.time),
            joint_pos=joint_pos,
            joint_vel=joint_vel,
            imu_quat=imu_quat,
            imu_gyro=np.asarray(imu_gyro),
            imu_acc=np.asarray(imu_acc),
            left_ft=ft["left"],
            right_ft=ft["right"],
            **base,
        )


def _sensor_slice(model: mujoco.MjModel, name: str) -> slice:
    """Slice of ``sensordata`` that holds the named MuJoCo sensor."""
    sensor_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, name)
    if sensor_id < 0:
        raise ValueError(f"robot model has no sensor named {name!r}")
    adr = model.sensor_adr[sensor_id]
    return slice(adr, adr + model.sensor_dim[sensor_id])
