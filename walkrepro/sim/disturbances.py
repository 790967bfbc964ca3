"""Pushes, drags and holds: time-windowed external wrenches on named bodies.

These are the only external forces in a run besides contacts. The runner writes them to
``xfrc_applied`` (force at the body's centre of mass and torque, both in the world frame)
and logs every one of them on every physics step.

A push is a force of time only. A hold is a human's hand (:class:`HandHold`): a
spring-damper between the body's centre of mass and where it was at the grab, so its force
is an outcome of the robot's motion, measured from the log like any other.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from walkrepro.specs.models import DisturbanceSpec

#: Looks up a controller frame (world-from-frame rotation) by name, or None if unknown.
FrameLookup = Callable[[str], "np.ndarray | None"]

#: A body's centre-of-mass position [m] and linear velocity [m/s], both in the world frame,
#: by body name: what a hand that holds the body feels (the simulator's state, read by the
#: disturbance model only, never by the controller).
BodyState = Callable[[str], "tuple[np.ndarray, np.ndarray]"]

_AXIS_INDEX = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class HandHold:
    """A human's hand that holds a point where it grabbed it (Lee et al. §VI-C, Figs. 11–13).

    Force law, in the hold's frame F (world-from-frame rotation ``rotation``, frozen at the
    grab), on the held axes only (mask S), scaled by the grab/let-go ramp s(t) ∈ [0, 1]:

        f_F = −s(t) · S (k · Rᵀ(p − p₀) + b · Rᵀ ṗ),   f_W = R f_F,   |f_W| ≤ f_max

    with p, ṗ the body's centre of mass and its velocity in the world, p₀ where the hand
    holds: the centre of mass at the grab plus the spec's ``hold_offset`` o_F along the held
    axes of F, p₀ = p_grab + R o_F. The cap is applied to the norm (the direction is kept).

    Attributes:
        stiffness: k [N/m].
        damping: b [N s/m].
        max_force: f_max [N].
        axes: held axes of F, a subset of (0, 1, 2).
        rotation: R, world-from-frame (3, 3).
        anchor: p₀ in the world (3,) [m].
    """

    stiffness: float
    damping: float
    max_force: float
    axes: tuple[int, ...]
    rotation: np.ndarray
    anchor: np.ndarray

    def force(self, scale: float, position: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """The hand's force on the body in the world frame (3,) [N] at ramp ``scale``."""
        r = self.rotation
        err = r.T @ (np.asarray(position, dtype=float) - self.anchor)  # in F [m]
        vel = r.T @ np.asarray(velocity, dtype=float)  # in F [m/s]
        f_frame = np.zeros(3)
        for i in self.axes:
            f_frame[i] = -scale * (self.stiffness * err[i] + self.damping * vel[i])
        f_world = r @ f_frame
        norm = float(np.linalg.norm(f_world))
        if norm > self.max_force:
            f_world *= self.max_force / norm
        return f_world


#: What a body's wrench starts from before the disturbances on it are added (0.0 + x, as the
#: sum onto an array of zeros gave: a lone -0.0 component is written as 0.0).
_ZERO_WRENCH = (0.0,) * 6


#: Two times closer than this are the same instant [s]. Spec times are decimals that binary
#: floats round, so ``start + duration`` (0.2 + 0.1 = 0.30000000000000004) and the step time
#: ``step * timestep`` (600 * 0.0005 = 0.3) can differ in the last bit; a window is
#: [start, end) up to this resolution, far below any timestep.
TIME_RESOLUTION = 1e-9


def in_window(s: DisturbanceSpec, t: float) -> bool:
    """Whether ``t`` [s] lies in the disturbance's window [start, start + duration)."""
    return s.start - TIME_RESOLUTION <= t < s.start + s.duration - TIME_RESOLUTION


@dataclass
class _Active:
    spec: DisturbanceSpec
    rotation: np.ndarray | None = None  # world-from-frame, frozen at onset
    wrench: np.ndarray | None = None  # the world-frame wrench at scale 1 (a push)
    hold: HandHold | None = None  # the hand, from its grab on (a hold)
    on: bool = False


class DisturbanceSchedule:
    """Evaluates the spec's disturbances at a given time."""

    def __init__(self, specs: Sequence[DisturbanceSpec]) -> None:
        self._items = [_Active(spec=s) for s in specs]

    def active_at(self, t: float) -> bool:
        """Whether :meth:`wrenches` can give a wrench or an event at ``t`` [s]: a window is
        open, or a disturbance is still on. Lets the runner skip the quiet steps cheaply."""
        for item in self._items:  # a loop, not any(generator): this runs every physics step
            if item.on or in_window(item.spec, t):
                return True
        return False

    def wrenches(
        self, t: float, frame_lookup: FrameLookup, body_state: BodyState | None = None
    ) -> tuple[dict[str, np.ndarray], list[dict]]:
        """World-frame wrenches per body at time ``t`` [s], and on/off events.

        A push is a function of time only (the profile times the spec's wrench, in its
        frame frozen at onset). A hold reads its body's state through ``body_state``
        (required when the spec has a hold): the hand's spring-damper (:class:`HandHold`).

        Runs at every physics step while a disturbance is on, so the six components are
        Python floats until the end (the same IEEE operations, in the same order, as the
        array arithmetic they replace; about half the cost).

        Returns:
            ``({body: (fx, fy, fz, tx, ty, tz)}, events)`` with only non-zero bodies listed;
            several disturbances on one body add up.
        """
        out: dict[str, list[float]] = {}
        events: list[dict] = []
        for item in self._items:
            s = item.spec
            scale = profile_scale(s, t)
            if scale > 0 and not item.on:
                item.on = True
                item.rotation = rot = self._frame_rotation(s, frame_lookup)
                # The frame is frozen at onset, so is the wrench's direction.
                item.wrench = np.concatenate(
                    [rot @ np.asarray(s.force), rot @ np.asarray(s.torque)]
                )
                event = {"kind": "disturbance_on", "name": s.name, "body": s.body}
                if s.kind == "hold":
                    item.hold = self._grab(s, rot, body_state)
                    event["anchor"] = item.hold.anchor.tolist()  # where the hand holds [m], world
                events.append(event)
            elif scale == 0 and item.on:
                item.on = False
                item.hold = None  # the hand let go
                events.append({"kind": "disturbance_off", "name": s.name, "body": s.body})
            if scale == 0:
                continue
            assert item.wrench is not None
            if item.hold is not None:
                assert body_state is not None  # checked at the grab
                force = item.hold.force(scale, *body_state(s.body))
                wrench = [*force.tolist(), 0.0, 0.0, 0.0]
            else:
                wrench = [scale * w for w in item.wrench.tolist()]
            total = out.get(s.body, _ZERO_WRENCH)
            out[s.body] = [a + b for a, b in zip(total, wrench, strict=True)]
        return {b: np.array(w) for b, w in out.items() if any(w)}, events

    @staticmethod
    def _grab(s: DisturbanceSpec, rotation: np.ndarray, body_state: BodyState | None) -> HandHold:
        """The hand at the grab: it holds the body's centre of mass where it is now, moved by
        the spec's ``hold_offset`` (in the hold's frame, frozen now)."""
        if body_state is None:
            raise RuntimeError(f"disturbance {s.name!r}: a hold needs the body's state")
        grabbed, _ = body_state(s.body)
        anchor = np.array(grabbed, dtype=float)
        if any(s.hold_offset):  # p₀ = p_grab + R o_F; no arithmetic when there is no offset
            anchor = anchor + rotation @ np.asarray(s.hold_offset, dtype=float)
        return HandHold(
            stiffness=s.stiffness,
            damping=s.damping,
            max_force=s.max_force,
            axes=tuple(_AXIS_INDEX[a] for a in s.axes),
            rotation=rotation,
            anchor=anchor,
        )

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
    if not in_window(s, t):
        return 0.0
    if s.profile == "constant":
        return 1.0
    return float(min(1.0, (t - s.start) / s.ramp_time, (end - t) / s.ramp_time))
