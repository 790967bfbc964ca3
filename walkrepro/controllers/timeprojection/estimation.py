"""State estimation of Paper II's closed loop: kinematics, IIR filter, moving-average
derivative and smooth dead-zone (section "Closed-Loop Control", Eqs. 26-27).

Only the link encoders and the pelvis IMU are used (Paper II: "we solely rely on the pelvis
IMU for state estimation"): the IMU orientation places the kinematic chain in a
gravity-aligned, heading-aligned frame, and forward kinematics gives the relative
horizontal pelvis-feet vectors s₁ = p − f and s₂ = p − s of Fig. 1.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from walkrepro.robot import Robot

FOOT_FRAMES = ("left_sole", "right_sole")


def smooth_dead_zone(x: np.ndarray | float, a: np.ndarray | float) -> np.ndarray:
    """Smooth dead-zone y = x − arctan(π x / (2a)) · 2a / π (Eq. 27).

    At the threshold x = a it keeps a (1 − 2 arctan(π/2)/π) ≈ 0.36 a, an attenuation of
    ≈ 64 % (Fig. 10); far from it, it is a shift by a. A zero threshold passes the signal
    through.

    Args:
        x: signal.
        a: threshold(s) a > 0, broadcast against x (a ≤ 0 disables the dead-zone).
    """
    x = np.asarray(x, dtype=float)
    a = np.asarray(a, dtype=float)
    safe = np.where(a > 0, a, 1.0)
    y = x - np.arctan(np.pi * x / (2.0 * safe)) * 2.0 * safe / np.pi
    return np.where(a > 0, y, x)


class IirFilter:
    """First-order IIR s(t) = (1 − ζ) s(t − δt) + ζ ŝ(t) (Eq. 26, ζ = 0.1).

    Args:
        zeta: ζ in (0, 1].
        size: signal dimension.
    """

    def __init__(self, zeta: float, size: int) -> None:
        self.zeta = zeta
        self.value = np.zeros(size)
        self._started = False

    def reset(self, value: np.ndarray) -> None:
        """Start from ``value`` (no transient from zero)."""
        self.value = np.array(value, dtype=float)
        self._started = True

    def update(self, observed: np.ndarray) -> np.ndarray:
        """Filter one sample and return the filtered value."""
        if not self._started:
            self.reset(observed)
        else:
            self.value = (1.0 - self.zeta) * self.value + self.zeta * np.asarray(observed)
        return self.value


class MovingAverageDerivative:
    """Backward difference of a signal followed by a moving average (Paper II: "time
    differentiation ... and another averaging filter afterward with a window of 30 samples").

    Args:
        window: number of samples averaged.
        size: signal dimension.
        dt: sample period [s].
    """

    def __init__(self, window: int, size: int, dt: float) -> None:
        self._buf = np.zeros((window, size))
        self._dt = dt
        self._i = 0
        self._n = 0
        self._sum = np.zeros(size)
        self._last: np.ndarray | None = None

    def update(self, x: np.ndarray) -> np.ndarray:
        """Add a sample of x; return the averaged derivative [unit/s]."""
        d = np.zeros_like(self._sum) if self._last is None else (x - self._last) / self._dt
        self._last = np.array(x, dtype=float)
        self._sum += d - self._buf[self._i]
        self._buf[self._i] = d
        self._i = (self._i + 1) % len(self._buf)
        self._n = min(self._n + 1, len(self._buf))
        return self._sum / self._n


class KinematicState:
    """Horizontal sole positions relative to the pelvis from encoders and the IMU (Fig. 3 D).

    The chain is built from the pelvis with the IMU orientation (yaw removed), so the
    vectors are in a gravity-aligned frame that turns with the robot's heading.

    Args:
        robot: the robot (rigid-twin Pinocchio model; the springs are seen by the encoders).
    """

    def __init__(self, robot: Robot) -> None:
        self._robot = robot
        self._model = robot.pin_model
        self._data = self._model.createData()
        self._q = pin.neutral(self._model)
        self._frames = [self._model.getFrameId(f) for f in FOOT_FRAMES]
        imu = self._model.frames[self._model.getFrameId("imu")]
        self._imu_in_pelvis = imu.placement.rotation.copy()

    def feet(
        self, imu_quat_wxyz: np.ndarray, joint_pos: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, float, float]:
        """Left and right sole points relative to the pelvis, heading frame.

        Returns:
            left (3,), right (3,) [m], pelvis roll [rad] and pitch [rad] in that frame.
        """
        w, x, y, z = imu_quat_wxyz
        r_imu = pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()
        r_pelvis = r_imu @ self._imu_in_pelvis.T
        yaw = np.arctan2(r_pelvis[1, 0], r_pelvis[0, 0])
        c, s = np.cos(yaw), np.sin(yaw)
        r_heading = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ r_pelvis
        q = self._q
        q[3:7] = pin.Quaternion(r_heading).coeffs()
        q[self._robot.pin_q_idx] = joint_pos
        pin.forwardKinematics(self._model, self._data, q)
        left = pin.updateFramePlacement(self._model, self._data, self._frames[0]).translation
        right = pin.updateFramePlacement(self._model, self._data, self._frames[1]).translation
        pitch = float(np.arcsin(np.clip(-r_heading[2, 0], -1.0, 1.0)))
        roll = float(np.arctan2(r_heading[2, 1], r_heading[2, 2]))
        return left.copy(), right.copy(), roll, pitch
