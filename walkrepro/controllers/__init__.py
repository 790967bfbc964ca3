"""Registry of controllers, by the ``controller.type`` name a spec uses.

Entries are imported lazily so that listing experiments does not import every paper's
controller (and its dependencies).
"""

from __future__ import annotations

from importlib import import_module

from walkrepro.controllers.base import Command, Controller, ControllerParams
from walkrepro.errors import UnknownNameError

_REGISTRY: dict[str, str] = {
    "posture": "walkrepro.controllers.posture:PostureController",
    "qpimpedance": "walkrepro.controllers.qpimpedance.controller:QPImpedanceController",
    "timeprojection": "walkrepro.controllers.timeprojection.controller:TimeProjectionController",
    "efsm": "walkrepro.controllers.efsm.controller:EfsmController",
}


def controller_names() -> list[str]:
    """Every controller type a spec may name."""
    return sorted(_REGISTRY)


def controller_class(name: str) -> type[Controller]:
    """The controller class registered as ``name``."""
    if name not in _REGISTRY:
        raise UnknownNameError("controller", name, controller_names())
    module, _, attr = _REGISTRY[name].partition(":")
    return getattr(import_module(module), attr)


__all__ = ["Command", "Controller", "ControllerParams", "controller_class", "controller_names"]
