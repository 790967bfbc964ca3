"""State estimation of Paper II's closed loop: kinematics, IIR filter, moving-average
derivative and smooth dead-zone (section "Closed-Loop Control", Eqs. 26-27).

Only the link encoders and the pelvis IMU are used (Paper II: "we solely rely on the pelvis
IMU for state estimation"): the IMU orientation places the kinematic chain in a
gravity-aligned, heading-aligned frame, and forward kinematics gives the relative
horizontal pelvis-feet vectors s₁ = p − f and s₂ = p − s of Fig. 1.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from walkrepro.sim.robot import Robot

FOOT_FRAMES = ("left_sole", "right_sole")

Point = tuple[float, float, float]


class FeetPose(NamedTuple):
    """The soles relative to the pelvis and the pelvis tilt, in the heading frame (gravity
    aligned, x along the pelvis heading).

    Attributes:
        left, right: each sole point (x, y, z) [m] relative to the pelvis.
        roll, pitch: the pelvis roll and pitch [rad].
    """

    left: Point
    right: Point
    roll: float
    pitch: float


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


def dead_zone(x: float, a: float) -> float:
    """:func:`smooth_dead_zone` of one float (the per-tick path).

    Args:
        x: signal.
        a: threshold a > 0 (a ≤ 0 passes the signal through).
    """
    if a > 0:
        return x - math.atan(math.pi * x / (2.0 * a)) * 2.0 * a / math.pi
    return x


class IirFilter:
    """First-order IIR s(t) = (1 − ζ) s(t − δt) + ζ ŝ(t) (Eq. 26, ζ = 0.1).

    The state is a list of floats: the signals are a handful of scalars, for which plain
    float arithmetic is several times cheaper than numpy's per-call overhead.

    Args:
        zeta: ζ in (0, 1].
        size: signal dimension.
    """

    def __init__(self, zeta: float, size: int) -> None:
        self.zeta = zeta
        self.value = [0.0] * size
        self._started = False

    def reset(self, value: Sequence[float]) -> None:
        """Start from ``value`` (no transient from zero)."""
        self.value = [float(v) for v in value]
        self._started = True

    def update(self, observed: Sequence[float]) -> list[float]:
        """Filter one sample and return the filtered value (a new list)."""
        if not self._started:
            self.reset(observed)
        else:
            zeta = self.zeta
            keep = 1.0 - zeta
            self.value = [
                keep * v + zeta * float(o) for v, o in zip(self.value, observed, strict=False)
            ]
        return self.value


class MovingAverageDerivative:
    """Backward difference of a signal followed by a moving average (Paper II: "time
    differentiation ... and another averaging filter afterward with a window of 30 samples").

    A running sum over a ring buffer of plain floats: O(size) per sample.

    Args:
        window: number of samples averaged.
        size: signal dimension.
        dt: sample period [s].
    """

    def __init__(self, window: int, size: int, dt: float) -> None:
        self._buf = [[0.0] * size for _ in range(window)]
        self._dt = dt
        self._i = 0
        self._n = 0
        self._sum = [0.0] * size
        self._last: list[float] | None = None

    def update(self, x: Sequence[float]) -> list[float]:
        """Add a sample of x; return the averaged derivative [unit/s] (a new list)."""
        x = [float(v) for v in x]
        dt = self._dt
        last = self._last
        d = (
            [0.0] * len(x)
            if last is None
            else [(v - w) / dt for v, w in zip(x, last, strict=False)]
        )
        self._last = x
        old = self._buf[self._i]
        s = self._sum = [
            acc + (new - prev) for acc, new, prev in zip(self._sum, d, old, strict=False)
        ]
        self._buf[self._i] = d
        self._i = (self._i + 1) % len(self._buf)
        self._n = n = min(self._n + 1, len(self._buf))
        return [v / n for v in s]

    def swap(self, i: int, j: int) -> None:
        """Exchange the histories of channels i and j (the last sample stays per channel).

        The averaged derivatives then follow roles rather than channels: at a touchdown the
        stance foot's history continues on the foot that now stands (Paper II
        differentiates s₁ = p − f and s₂ = p − s, whose rates stay continuous when the
        feet land at rest, while each foot's own rate jumps).
        """
        for row in self._buf:
            row[i], row[j] = row[j], row[i]
        self._sum[i], self._sum[j] = self._sum[j], self._sum[i]


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
        idx = np.asarray(robot.pin_q_idx)
        contiguous = idx.size > 0 and np.array_equal(idx, np.arange(idx[0], idx[0] + idx.size))
        self._q_idx = slice(int(idx[0]), int(idx[0]) + idx.size) if contiguous else idx
        self._frames = [self._model.getFrameId(f) for f in FOOT_FRAMES]
        imu = self._model.frames[self._model.getFrameId("imu")]
        imu_in_pelvis = imu.placement.rotation
        # Pelvis = IMU · (IMU in pelvis)ᵀ; skipped when the IMU is mounted level.
        self._pelvis_from_imu = (
            None
            if np.array_equal(imu_in_pelvis, np.eye(3))
            else tuple(imu_in_pelvis.ravel().tolist())
        )

    def heading_rotation(self, imu_quat_wxyz: np.ndarray) -> tuple[float, ...]:
        """The pelvis orientation in the heading frame (yaw removed), row-major 9 floats.

        From the IMU quaternion (w, x, y, z), normalised, as Eigen's ``toRotationMatrix``.
        """
        w, x, y, z = imu_quat_wxyz.tolist()
        norm = math.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w / norm, x / norm, y / norm, z / norm
        tx, ty, tz = 2.0 * x, 2.0 * y, 2.0 * z
        twx, twy, twz = tx * w, ty * w, tz * w
        txx, txy, txz = tx * x, ty * x, tz * x
        tyy, tyz, tzz = ty * y, tz * y, tz * z
        r = (
            1.0 - (tyy + tzz), txy - twz, txz + twy,
            txy + twz, 1.0 - (txx + tzz), tyz - twx,
            txz - twy, tyz + twx, 1.0 - (txx + tyy),
        )  # fmt: skip
        m = self._pelvis_from_imu
        if m is not None:  # r · mᵀ
            r = tuple(
                r[3 * i] * m[3 * j] + r[3 * i + 1] * m[3 * j + 1] + r[3 * i + 2] * m[3 * j + 2]
                for i in range(3)
                for j in range(3)
            )
        # R_z(−yaw) · r, with yaw the pelvis heading.
        yaw = math.atan2(r[3], r[0])
        c, s = math.cos(yaw), math.sin(yaw)
        return (
            c * r[0] + s * r[3], c * r[1] + s * r[4], c * r[2] + s * r[5],
            c * r[3] - s * r[0], c * r[4] - s * r[1], c * r[5] - s * r[2],
            r[6], r[7], r[8],
        )  # fmt: skip

    def feet(self, imu_quat_wxyz: np.ndarray, joint_pos: np.ndarray) -> FeetPose:
        """Left and right sole points relative to the pelvis, heading frame, and the pelvis
        roll and pitch in that frame."""
        h = self.heading_rotation(imu_quat_wxyz)
        # Forward kinematics with the pelvis at the identity, then rotate into the heading
        # frame: the same sole points as a floating base at the heading orientation.
        q = self._q
        q[self._q_idx] = joint_pos
        model, data = self._model, self._data
        pin.forwardKinematics(model, data, q)
        soles = []
        for frame in self._frames:
            x, y, z = pin.updateFramePlacement(model, data, frame).translation.tolist()
            soles.append(
                (
                    h[0] * x + h[1] * y + h[2] * z,
                    h[3] * x + h[4] * y + h[5] * z,
                    h[6] * x + h[7] * y + h[8] * z,
                )
            )
        pitch = math.asin(min(max(-h[6], -1.0), 1.0))
        roll = math.atan2(h[7], h[8])
        return FeetPose(soles[0], soles[1], roll, pitch)
