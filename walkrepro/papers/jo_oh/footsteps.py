"""Footstep plan and ZMP reference for flat-ground walking (§IV).

The plan assumes a flat floor, as the paper's walking pattern does ("the given x-direction
walking pattern assumed with the plane ground"): the controller knows nothing of obstacles.
Each step is a double-support phase (the ZMP moves from the old to the new support foot)
followed by a single-support phase (the other foot swings). The first and last steps are
half strides, so the feet start and end side by side.
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass

import numpy as np

LEFT, RIGHT = 0, 1
SIDES = ("left", "right")


@dataclass(frozen=True)
class Phase:
    """One phase of the walk.

    Attributes:
        t0: start time [s].
        t1: end time [s].
        swing: swinging foot (LEFT/RIGHT), or -1 in double support.
        target: the swing foot's landing sole centre in the world (x, y, 0) [m] (swing only).
    """

    t0: float
    t1: float
    swing: int
    target: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class FootstepPlan:
    """Timed phases and the ZMP reference of a straight walk.

    Attributes:
        phases: phases in time order, covering [0, end].
        zmp_t: sample times of the ZMP reference [s], shape (N,).
        zmp_xy: ZMP reference (x, y) [m], shape (N, 2).
        end: time the last phase ends [s] (the plan then holds the final stance).
    """

    phases: tuple[Phase, ...]
    zmp_t: np.ndarray
    zmp_xy: np.ndarray
    end: float

    def phase_at(self, t: float) -> Phase:
        """The phase that contains time ``t`` [s] (the final stance after the plan ends)."""
        for phase in self.phases:
            if t < phase.t1:
                return phase
        return self.phases[-1]

    def zmp_at(self, t: float) -> tuple[float, float]:
        """Reference ZMP (x, y) at time ``t`` [s]: ``np.interp`` of the samples, per axis.

        Written out on Python floats (with ``np.interp``'s formula and end values): two
        ``np.interp`` calls cost a few µs, which matters at 1 kHz.
        """
        times = self._times
        j = bisect_right(times, t) - 1
        if j < 0:
            return self._xy[0]
        if j >= len(times) - 1:
            return self._xy[-1]
        (x0, y0), (x1, y1) = self._xy[j], self._xy[j + 1]
        if t == times[j]:
            return x0, y0
        dt = times[j + 1] - times[j]
        return (x1 - x0) / dt * (t - times[j]) + x0, (y1 - y0) / dt * (t - times[j]) + y0

    def __post_init__(self) -> None:
        # Python-float copies of the samples for zmp_at (the dataclass is frozen).
        object.__setattr__(self, "_times", self.zmp_t.tolist())
        object.__setattr__(self, "_xy", [tuple(p) for p in self.zmp_xy.tolist()])


@dataclass(frozen=True)
class WalkPattern:
    """A straight walk along +x: where the feet go and when (§IV: 0.35 m stride, 0.56 s + 0.14 s).

    Attributes:
        foot_y: lateral offset of each sole centre from the midline [m] (left +, right −).
        stride: distance a swing foot travels per full step [m]; the first and the last
            step travel half of it.
        n_steps: number of steps (≥ 2).
        first_swing: LEFT or RIGHT.
        t_start: initial double support before the first step [s].
        t_single: single-support (swing) time [s].
        t_double: double-support time of every step [s].
        t_end_hold: double support after the last step, in the plan (the ZMP comes to the
            middle of the feet) [s].
    """

    foot_y: float
    stride: float
    n_steps: int
    first_swing: int
    t_start: float
    t_single: float
    t_double: float
    t_end_hold: float


def plan_walk(pattern: WalkPattern, dt: float) -> FootstepPlan:
    """Plan ``pattern.n_steps`` steps straight ahead along +x, with the ZMP reference.

    Args:
        pattern: the feet's offsets, the stride, the number of steps and the phase times.
        dt: sample time of the ZMP reference [s].
    """
    foot_y, stride, n_steps, first_swing = (
        pattern.foot_y, pattern.stride, pattern.n_steps, pattern.first_swing
    )  # fmt: skip
    t_start, t_single, t_double, t_end_hold = (
        pattern.t_start, pattern.t_single, pattern.t_double, pattern.t_end_hold
    )  # fmt: skip
    if n_steps < 2:
        raise ValueError(f"n_steps must be at least 2, got {n_steps}")
    feet = np.array([[0.0, foot_y], [0.0, -foot_y]])  # sole centres (x, y) [m]
    phases: list[Phase] = [Phase(0.0, t_start, -1)]
    # ZMP knots: (time, x, y); linear between knots.
    knots: list[tuple[float, float, float]] = [(0.0, 0.0, 0.0), (t_start - t_double, 0.0, 0.0)]
    t = t_start - t_double
    swing = first_swing
    for k in range(n_steps):
        support = 1 - swing
        # Double support of this step: the ZMP shifts onto the support foot. The first
        # one is the last t_double of the initial stance.
        if k > 0:
            phases.append(Phase(t, t + t_double, -1))
        t += t_double
        knots.append((t, *feet[support]))
        travel = stride / 2 if k in (0, n_steps - 1) else stride
        target = feet[swing] + np.array([travel, 0.0])
        phases.append(Phase(t, t + t_single, swing, (float(target[0]), float(target[1]), 0.0)))
        t += t_single
        knots.append((t, *feet[support]))
        feet[swing] = target
        swing = support
    phases.append(Phase(t, t + t_double + t_end_hold, -1))
    mid = feet.mean(axis=0)
    knots.append((t + t_double, *mid))
    end = t + t_double + t_end_hold
    knots.append((end, *mid))
    kt = np.array([k[0] for k in knots])
    zmp_t = np.arange(0.0, end + dt / 2, dt)
    zmp_xy = np.stack(
        [np.interp(zmp_t, kt, [k[1] for k in knots]), np.interp(zmp_t, kt, [k[2] for k in knots])],
        axis=1,
    )
    return FootstepPlan(tuple(phases), zmp_t, zmp_xy, end)
