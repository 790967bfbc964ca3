"""Pushes and drags: time-windowed external wrenches on named bodies.

These are the only external forces in a run besides contacts. The runner writes them to
``xfrc_applied`` (force at the body's centre of mass and torque, both in the world frame)
and logs every one of them on every physics step.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from walkrepro.spec import DisturbanceSpec

#: Looks up a controller frame (world-from-frame rotation) by name, or None if unknown.
FrameLookup = Callable[[str], "np.ndarray | None"]


@dataclass
class _Active:
    spec: DisturbanceSpec
    rotation: np.ndarray | None = None  # world-from-frame, frozen at onset
    on: bool = False


class DisturbanceSchedule:
    """Evaluates the spec's disturbances at a given time."""

    def __init__(self, specs: Sequence[DisturbanceSpec]) -> None:
        self._items = [_Active(spec=s) for s in specs]

    def wrenches(
        self, t: float, frame_lookup: FrameLookup
    ) -> tuple[dict[str, np.ndarray], list[dict]]:
        """World-frame wrenches per body at time ``t`` [s], and on/off events.

        Returns:
            ``({body: (fx, fy, fz, tx, ty, tz)}, events)`` with only non-zero bodies listed;
            several disturbances on one body add up.
        """
        out: dict[str, np.ndarray] = {}
        events: list[dict] = []
        for item in self._items:
            s = item.spec
            scale = profile_scale(s, t)
            if scale > 0 and not item.on:
                item.on = True
                item.rotation = self._frame_rotation(s, frame_lookup)
                events.append({"kind": "disturbance_on", "name": s.name, "body": s.body})
            elif scale == 0 and item.on:
                item.on = False
                events.append({"kind": "disturbance_off", "name": s.name, "body": s.body})
            if scale == 0:
                continue
            rot = item.rotation if item.rotation is not None else np.eye(3)
            wrench = scale * np.concatenate([rot @ np.asarray(s.force), rot @ np.asarray(s.torque)])
            out[s.body] = out.get(s.body, np.zeros(6)) + wrench
        return {b: w for b, w in out.items() if np.any(w)}, events

    @staticmethod
    def _frame_rotation(s: DisturbanceSpec, frame_lookup: FrameLookup) -> np.ndarray:
        if s.frame == "world":
            return np.eye(3)
        rot = frame_lookup(s.frame)
        if rot is None:
            raise RuntimeError(f"disturbance {s.name!r}: controller has no frame {s.frame!r}")
        return np.asarray(rot, dtype=float).copy()


def profile_scale(s: DisturbanceSpec, t: float) -> float:
    """Magnitude factor in [0, 1] of a disturbance at time ``t`` [s] (window is [start, end))."""
    end = s.start + s.duration
    if not s.start <= t < end:
        return 0.0
    if s.profile == "constant":
        return 1.0
    return float(min(1.0, (t - s.start) / s.ramp_time, (end - t) / s.ramp_time))
