"""Controllers by the ``controller.type`` name a spec uses, from the installed plugins
(:mod:`walkrepro.plugins`).

A controller's module is imported when a spec names it, so that listing experiments does not
import every paper's controller (and its dependencies).
"""

from __future__ import annotations

from walkrepro import plugins
from walkrepro.controllers.base import Command, Controller, ControllerParams
from walkrepro.errors import UnknownNameError, WalkreproError


def controller_names() -> list[str]:
    """Every controller type a spec may name: those of every installed plugin."""
    return sorted(plugins.controllers())


def controller_class(name: str) -> type[Controller]:
    """The controller class registered as ``name``, imported now.

    Raises:
        UnknownNameError: no plugin declares ``name``.
        WalkreproError: the declared class does not import or is not a :class:`Controller`.
    """
    registry = plugins.controllers()
    if name not in registry:
        raise UnknownNameError("controller", name, controller_names())
    try:
        cls = plugins.load(registry[name])
    except (ImportError, AttributeError) as exc:
        raise WalkreproError(
            f"controller {name!r} ({registry[name]}) does not import: {type(exc).__name__}: {exc}"
        ) from None
    if not (isinstance(cls, type) and issubclass(cls, Controller)):
        raise WalkreproError(
            f"controller {name!r} ({registry[name]}) is not a walkrepro.controllers.Controller."
        )
    return cls


__all__ = ["Command", "Controller", "ControllerParams", "controller_class", "controller_names"]
