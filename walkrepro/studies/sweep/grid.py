"""Sweep grids: ``--grid FIELD=VALUES`` parsed into axes, and every cell's resolved spec.

``FIELD`` is any path ``--set`` accepts (``controller.params.kp``, ``disturbances.0.force.0``)
or a sweep parameter the spec declares (``sweep_parameters:``, which sets several fields
each as ``scale · x + offset``). ``VALUES`` is a comma list (``20,40,60``, ``true,false``; each
item parsed as YAML) or an inclusive range ``start:stop:count``. The grid is the Cartesian
product of its axes, the first axis varying slowest.

:func:`plan_cells` resolves every cell's spec before anything runs, so a bad field, value or
range fails at once with a one-paragraph error.
"""

from __future__ import annotations

import itertools
import json
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from walkrepro.errors import SpecError, UnknownNameError, WalkreproError
from walkrepro.specs import yamlload

_NUMBER = r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?"
_RANGE = re.compile(rf"^\s*({_NUMBER})\s*:\s*({_NUMBER})\s*:\s*(\S+)\s*$")


@dataclass(frozen=True)
class Axis:
    """One grid axis.

    Attributes:
        field: a spec path (``a.b.0.c``) or a declared sweep parameter's name.
        values: the values the axis takes, in order (numbers, booleans or strings).
    """

    field: str
    values: tuple[Any, ...]


@dataclass(frozen=True)
class Cell:
    """One point of the grid and its resolved spec.

    Attributes:
        index: position in the grid (row-major over the axes, first axis slowest).
        values: ``(field, value)`` per axis, in grid order.
        overrides: the ``--set`` strings that make this cell's spec from the experiment.
        spec: the resolved ``ExperimentSpec``, sweep sections cleared.
    """

    index: int
    values: tuple[tuple[str, Any], ...]
    overrides: tuple[str, ...]
    spec: Any  # ExperimentSpec (kept loose: this module is imported by the CLI early)

    @property
    def label(self) -> str:
        """``field=value, ...`` for messages."""
        return ", ".join(f"{f}={value_text(v)}" for f, v in self.values)


def value_text(value: Any) -> str:
    """A grid value as it is written in ``cells.csv`` and in overrides (JSON, which is YAML)."""
    return json.dumps(value)


def parse_grid_item(item: str) -> Axis:
    """``FIELD=VALUES`` → :class:`Axis`.

    Raises:
        WalkreproError: malformed item, empty values or a bad range.
    """
    if "=" not in item:
        raise WalkreproError(
            f"--grid {item!r}: expected FIELD=VALUES, e.g. controller.params.kp=300,400 "
            "or sim.duration=0.5:2:4 (start:stop:count)."
        )
    field, _, text = item.partition("=")
    field = field.strip()
    if not field or any(not p for p in field.split(".")):
        raise WalkreproError(f"--grid {item!r}: empty field name.")
    return Axis(field, parse_values(text, f"--grid {item!r}"))


def parse_values(text: Any, where: str) -> tuple[Any, ...]:
    """A comma list or ``start:stop:count`` range (a list or scalar from YAML is taken as is)."""
    if isinstance(text, list):
        values = tuple(text)
    elif not isinstance(text, str):
        values = (text,)
    elif text.strip().startswith(("[", "{")):
        raise WalkreproError(
            f"{where}: {text!r} is not a single number, boolean or name per value; give a comma "
            "list (20,40,60) and sweep one element of a vector with its index, e.g. "
            "disturbances.0.force.0=20,40."
        )
    elif ":" in text and "," not in text:
        values = _parse_range(text, where)
    else:
        items = [t.strip() for t in text.split(",")]
        if not items or any(not t for t in items):
            raise WalkreproError(
                f"{where}: empty value in {text!r}; give a comma list such as 20,40,60."
            )
        values = tuple(_scalar(t, where) for t in items)
    if not values:
        raise WalkreproError(f"{where}: no values.")
    if len(set(map(value_text, values))) != len(values):
        raise WalkreproError(f"{where}: a value is repeated in {text!r}.")
    return values


def _parse_range(text: str, where: str) -> tuple[float, ...]:
    """``start:stop:count``, inclusive and evenly spaced (12 significant digits)."""
    m = _RANGE.match(text)
    if not m:
        raise WalkreproError(
            f"{where}: bad range {text!r}; a range is start:stop:count with numbers start and "
            "stop and a whole count >= 2, e.g. 0.02:0.06:3."
        )
    start, stop, count_text = float(m.group(1)), float(m.group(4)), m.group(7)
    if not count_text.isdigit() or int(count_text) < 2:
        raise WalkreproError(
            f"{where}: bad range {text!r}: the count {count_text!r} must be a whole number >= 2."
        )
    if start == stop:
        raise WalkreproError(f"{where}: bad range {text!r}: start and stop are equal.")
    n = int(count_text)
    return tuple(float(f"{start + (stop - start) * k / (n - 1):.12g}") for k in range(n))


def _scalar(text: str, where: str) -> Any:
    try:
        value = yamlload.load(text)
    except yaml.YAMLError:
        value = text
    if isinstance(value, dict | list) or value is None:
        raise WalkreproError(
            f"{where}: value {text!r} is not a single number, boolean or name; sweep one "
            "element of a vector with its index, e.g. disturbances.0.force.0=20,40."
        )
    return value


def plan_cells(
    experiment: str | Path, axes: Sequence[Axis], overrides: Sequence[str] = ()
) -> list[Cell]:
    """Every cell of the grid with its resolved spec, validated before anything runs.

    Args:
        experiment: experiment name or spec path.
        axes: the grid.
        overrides: ``--set`` strings applied to every cell before the grid's own.

    Raises:
        WalkreproError: naming the grid item or the cell, with the spec's own message.
    """
    from walkrepro.runs.resolve import resolve_spec
    from walkrepro.specs.files import load_spec
    from walkrepro.specs.models import ExperimentSpec

    base = load_spec(experiment, overrides).spec
    fields = [a.field for a in axes]
    dup = sorted({f for f in fields if fields.count(f) > 1})
    if dup:
        raise WalkreproError(f"--grid: field {dup[0]!r} is given twice; merge its values.")
    parameters = base.sweep_parameters
    for axis in axes:
        top = axis.field.split(".")[0]
        if axis.field not in parameters and top not in ExperimentSpec.model_fields:
            raise UnknownNameError(
                "sweep field",
                axis.field,
                [*parameters, *(f"{f}.…" for f in ExperimentSpec.model_fields)],
                f"--grid {axis.field}",
            )
        if axis.field in parameters:
            bad = [v for v in axis.values if isinstance(v, bool) or not isinstance(v, int | float)]
            if bad:
                raise WalkreproError(
                    f"--grid {axis.field}: sweep parameter values must be numbers "
                    f"(got {value_text(bad[0])})."
                )
    cells = []
    for index, combo in enumerate(itertools.product(*(a.values for a in axes))):
        values = tuple(zip(fields, combo, strict=True))
        cell_overrides = [*overrides]
        for field, value in values:
            if field in parameters:
                param = parameters[field]
                for path in param.sets:
                    cell_overrides.append(f"{path}={value_text(param.affine(path).apply(value))}")
            else:
                cell_overrides.append(f"{field}={value_text(value)}")
        label = ", ".join(f"{f}={value_text(v)}" for f, v in values)
        try:
            loaded = resolve_spec(load_spec(experiment, cell_overrides))
        except WalkreproError as exc:
            text = str(exc).replace("(set with --set)", "(set by --grid or --set)")
            raise SpecError(f"sweep cell {index} ({label}): {text}") from None
        spec = loaded.spec.model_copy(update={"sweeps": [], "sweep_parameters": {}})
        cells.append(Cell(index, values, tuple(cell_overrides), spec))
    return cells


def unit_of(field: str, parameters: dict | None = None) -> str:
    """The unit of a grid field, for axis labels: declared for sweep parameters, else from the
    field's name (the spec's conventions: SI units, angles in degrees where named ``_deg``)."""
    if parameters and field in parameters:
        return parameters[field].unit
    last = field.split(".")
    names = [p for p in last if not p.isdigit()]
    name = names[-1] if names else ""
    for key, unit in _UNITS:
        if re.fullmatch(key, name):
            return unit
    return ""


_UNITS = [
    (r".*_deg", "deg"),
    (r"force", "N"),
    (r"torque", "N·m"),
    (r"start|duration|ramp_time|timestep|control_period|delay|fall_time", "s"),
    (r"size|position|step_length|step_width|zeta", "m"),
    (r"stiffness", "N/m"),
    (r"damping", "N·s/m"),
    (r"mass", "kg"),
]

__all__ = ["Axis", "Cell", "SpecError", "parse_grid_item", "parse_values", "plan_cells"]
