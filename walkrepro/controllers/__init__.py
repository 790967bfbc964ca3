"""Controllers by the ``controller.type`` name a spec uses, from the installed plugins
(:mod:`walkrepro.plugins`).

A controller's module is imported when a spec names it, so that listing experiments does not
import every paper's controller (and its dependencies).
"""

from __future__ import annotations

import functools
import json
from typing import TYPE_CHECKING

from walkrepro import plugins
from walkrepro.controllers.base import Command, Controller, ControllerParams
from walkrepro.errors import UnknownNameError, WalkreproError

if TYPE_CHECKING:
    from walkrepro.specs.models import ControllerSpec


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


def controller_params(controller: ControllerSpec) -> ControllerParams:
    """The typed parameters of a spec's controller: its ``params`` validated by the
    controller's own model (``Params``), the one place a spec's dict becomes that record.

    :func:`walkrepro.runs.resolve.resolve_spec` calls it at load, turning a
    ``pydantic.ValidationError`` into file:line errors; the runner and the metrics that need
    the parameters get the same record from it (the models are frozen: one validated record
    per controller and parameter set, per process).

    Raises:
        UnknownNameError, WalkreproError: see :func:`controller_class`.
        pydantic.ValidationError: the parameters do not fit the model.
    """
    try:
        key = json.dumps(controller.params, sort_keys=True)
    except (TypeError, ValueError):  # not plain data (e.g. a YAML date): the model says why
        return controller_class(controller.type).Params.model_validate(controller.params)
    return _validated(controller.type, key)


@functools.lru_cache(maxsize=64)
def _validated(name: str, params_json: str) -> ControllerParams:
    return controller_class(name).Params.model_validate(json.loads(params_json))


__all__ = [
    "Command",
    "Controller",
    "ControllerParams",
    "controller_class",
    "controller_names",
    "controller_params",
]
