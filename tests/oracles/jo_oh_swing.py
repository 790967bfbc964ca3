"""Readable numpy reference of Paper III's swing-foot trajectory (§IV), a test oracle.

The controller's tick evaluates the trajectory compiled, ``walkrepro.papers.jo_oh.tasks``
(:func:`quintic`, :func:`swing_reference`); ``tests/test_qpimpedance_tasks.py`` checks that
it equals this one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def quintic(s: float, duration: float) -> tuple[float, float, float]:
    """Minimum-jerk blend b(s) from 0 to 1 and its time derivatives, s ∈ [0, duration] [s].

    Returns:
        (b, ḃ [1/s], b̈ [1/s²]), with zero velocity and acceleration at both ends.
    """
    if duration <= 0:
        return 1.0, 0.0, 0.0
    u = min(max(s / duration, 0.0), 1.0)
    b = u**3 * (10 - 15 * u + 6 * u**2)
    db = 30 * u**2 * (1 - u) ** 2 / duration
    ddb = 60 * u * (1 - u) * (1 - 2 * u) / duration**2
    return b, db, ddb


@dataclass(frozen=True)
class SwingTrajectory:
    """Swing-foot sole-centre trajectory from lift-off to the planned landing.

    x, y and the roll/pitch angles blend by minimum jerk over the whole swing; z rises
    from the lift-off height to ``apex`` over the first ``rise_fraction`` of the swing, then
    descends to the landing height (the flat floor, z = 0) by the end. The controller's tick
    evaluates it with the compiled copy :func:`.tasks.swing_reference` (tested equal).

    Attributes:
        t0: lift-off time [s].
        duration: swing time [s].
        start: lift-off sole centre (x, y, z) [m] and roll, pitch [rad], shape (5,).
        target: landing sole centre (x, y, z) [m] and roll, pitch [rad], shape (5,).
        apex: swing height above the higher of start and target [m].
        rise_fraction: share of the swing spent rising [-].
    """

    t0: float
    duration: float
    start: np.ndarray
    target: np.ndarray
    apex: float
    rise_fraction: float

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Desired (x, y, z, roll, pitch), velocities and accelerations at ``t`` [s, rad]."""
        s = t - self.t0
        b, db, ddb = quintic(s, self.duration)
        delta = self.target - self.start
        pos = self.start + b * delta
        vel = db * delta
        acc = ddb * delta
        top = max(self.start[2], self.target[2]) + self.apex
        t_rise = self.rise_fraction * self.duration
        if s < t_rise:
            bz, dbz, ddbz = quintic(s, t_rise)
            z0, z1 = self.start[2], top
        else:
            bz, dbz, ddbz = quintic(s - t_rise, self.duration - t_rise)
            z0, z1 = top, self.target[2]
        pos[2] = z0 + bz * (z1 - z0)
        vel[2] = dbz * (z1 - z0)
        acc[2] = ddbz * (z1 - z0)
        return pos, vel, acc
