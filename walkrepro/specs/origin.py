"""Where a number comes from: the four provenance classes, attached to model fields.

Every number a run uses beyond its scenario has exactly one class (``../shared/GUIDE.md``,
Models around the controller; ``docs/provenance.md``):

- ``paper``: the paper gives it (section, table or equation);
- ``source``: a public model, datasheet or code of the lab or the maker, cited as
  repository @ commit : path (or the document), the number read from the file;
- ``assumed``: chosen before any run by a stated criterion that uses no result;
- ``calibrated``: pinned by a declared calibration (``experiments/calibration/<paper>.yaml``),
  or chosen by looking at a result, which is then named as its criterion.

A pydantic field carries the class of its *default* in ``json_schema_extra``::

    zeta: float = Field(0.03, gt=0, description="margin ζ [m]", json_schema_extra=paper("§V-B"))

A field whose value a spec sets as the experiment's own setup (a step length, a commanded
speed, an ablation's switch) is also marked :func:`scenario`: a spec's value of it needs no
class of its own. Every other value a spec sets is classed in the spec's ``provenance:``
block or in ``experiments/provenance/<paper>.yaml`` (:mod:`walkrepro.publish.ledger`).

This module is a leaf (no walkrepro import), so the spec and controller models can use it.
"""

from __future__ import annotations

from typing import Any

#: The provenance classes, in the order reports list them.
CLASSES: tuple[str, ...] = ("paper", "source", "assumed", "calibrated")
#: What a value set as the experiment's own setup is listed as (not counted as a class).
SCENARIO = "scenario"


def _origin(klass: str, source: str, scenario: str | None = None) -> dict[str, Any]:
    if klass not in CLASSES:
        raise ValueError(f"unknown provenance class {klass!r}; valid: {', '.join(CLASSES)}")
    if not source.strip():
        raise ValueError("a provenance needs its source: the section, file or criterion")
    extra: dict[str, Any] = {"provenance": {"class": klass, "source": source}}
    if scenario is not None:
        extra["scenario"] = scenario
    return extra


def paper(where: str, *, scenario: str | None = None) -> dict[str, Any]:
    """The paper gives the default: ``where`` is its section, table or equation."""
    return _origin("paper", where, scenario)


def source(citation: str, *, scenario: str | None = None) -> dict[str, Any]:
    """A lab's or maker's public file gives the default: repository @ commit : path."""
    return _origin("source", citation, scenario)


def assumed(criterion: str, *, scenario: str | None = None) -> dict[str, Any]:
    """The default was chosen before any run by ``criterion`` (which uses no result)."""
    return _origin("assumed", criterion, scenario)


def calibrated(criterion: str, *, scenario: str | None = None) -> dict[str, Any]:
    """The default was pinned by a declared calibration, or chosen on the named result."""
    return _origin("calibrated", criterion, scenario)


def scenario(why: str) -> dict[str, Any]:
    """A field with no default of consequence whose spec value is the experiment's setup."""
    return {"scenario": why}


def field_origin(extra: Any) -> tuple[dict[str, str] | None, str | None]:
    """(``{"class", "source"}`` of the default or None, the scenario reason or None) of a
    field's ``json_schema_extra``."""
    if not isinstance(extra, dict):
        return None, None
    return extra.get("provenance"), extra.get("scenario")
