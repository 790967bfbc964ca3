"""The controller protocol: sensor snapshot in, actuator command out.

A controller never sees MuJoCo's ``MjData``: it gets a frozen :class:`SensorSnapshot`
(what the robot would sense) and returns a :class:`Command`. This keeps every reproduction
honest and lets the same controller run against a log or a real robot.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict

if TYPE_CHECKING:
    from walkrepro.log.signals import Signals
    from walkrepro.sim.robot import Robot
    from walkrepro.sim.sensors import SensorSnapshot


class ControllerParams(BaseModel):
    """Base of every controller's parameter model; unknown fields are errors."""

    model_config = ConfigDict(extra="forbid", frozen=True)


@dataclass(frozen=True)
class Command:
    """What a controller returns each control tick.

    Attributes:
        ctrl: actuator inputs, shape (nu,), in actuator order: joint torques [Nm] for
            torque-controlled robots, motor position targets [rad] for position-controlled ones.
        signals: named internal signals to log on ``/controller/signals``: a
            :class:`walkrepro.log.signals.Signals` (one vector in a fixed layout, the fast path),
            or a dict of numbers and 1-D arrays with one set of names per run.
        events: discrete events to log on ``/events``; each a dict with at least ``kind``.
    """

    ctrl: np.ndarray
    signals: Signals | Mapping[str, Any] = field(default_factory=dict)
    events: tuple[Mapping[str, Any], ...] = ()


class Controller(ABC):
    """A walking or posture controller.

    Subclasses set ``Params`` to a :class:`ControllerParams` model that validates the spec's
    ``controller.params`` block.
    """

    Params: ClassVar[type[ControllerParams]] = ControllerParams
    #: Names of the controller frames a disturbance may be expressed in (see :meth:`frame`).
    FRAMES: ClassVar[tuple[str, ...]] = ()

    @abstractmethod
    def reset(self, robot: Robot, params: ControllerParams, control_period: float) -> None:
        """Prepare for a run.

        Args:
            robot: the robot (MuJoCo + Pinocchio models of the same MJCF).
            params: validated parameters of this controller.
            control_period: time between two ``step`` calls [s].
        """

    @abstractmethod
    def step(self, t: float, sensors: SensorSnapshot) -> Command:
        """Compute the command for the sensor snapshot taken at time ``t`` [s]."""

    def frame(self, name: str) -> np.ndarray | None:
        """World-from-frame rotation (3x3) of a named controller frame, e.g. ``"O_w"``.

        Disturbances may be expressed in such a frame; ``None`` means the controller has no
        frame of that name. The default controller has none.
        """
        return None

    def timing(self) -> dict[str, float]:
        """Optional split of the controller's wall time [s] accumulated over the run.

        E.g. ``{"dynamics": ..., "wbc": ..., "qp": ...}``; ``walkrepro bench`` reports it.
        """
        return {}
