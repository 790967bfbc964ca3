"""Plots of a run's key signals, declared as data: what to draw, with its unit.

A controller declares its paper's plots (``Plugin.plots``, e.g.
``walkrepro/papers/lee2021/plots.py``): each :class:`Plot` a titled set of lines in one
unit, each :class:`Series` a value of the log named by its path, as Foxglove's plots name
it (``/controller/signals.cp_w``, ``/controller/signals.com_w[0]``, ``/sim/state.qvel[0]``).
A viewer that reads the log (``walkrepro export --rerun``) draws them; the declarations
import nothing heavy, and the core finds them through the plugin registry.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from walkrepro.errors import WalkreproError
from walkrepro.log.record import TOPIC_SIGNALS, Log

#: ``/topic.field`` or ``/topic.field[i]``.
_PATH = re.compile(r"^(?P<topic>/[\w/]+)\.(?P<field>\w+)(?:\[(?P<index>\d+)\])?$")


@dataclass(frozen=True)
class Series:
    """One line of a plot.

    Attributes:
        path: the value in the log: ``/<topic>.<field>``, or ``/<topic>.<field>[i]`` for an
            entry of an array (a topic with a time ``t``: ``/controller/signals``,
            ``/sim/state``, ``/sensors``).
        label: the line's name in the legend, e.g. ``x_CP``.
    """

    path: str
    label: str

    def __post_init__(self) -> None:
        if _PATH.match(self.path) is None:
            raise ValueError(f"series path {self.path!r} is not /topic.field or /topic.field[i]")

    @property
    def topic(self) -> str:
        """The path's topic, e.g. ``/controller/signals``."""
        return _PATH.match(self.path)["topic"]  # type: ignore[index]

    @property
    def field(self) -> str:
        """The path's field, e.g. ``com_w``."""
        return _PATH.match(self.path)["field"]  # type: ignore[index]

    @property
    def index(self) -> int | None:
        """The entry of an array field, or None for a scalar."""
        index = _PATH.match(self.path)["index"]  # type: ignore[index]
        return None if index is None else int(index)


@dataclass(frozen=True)
class Plot:
    """Lines of one unit drawn together.

    Attributes:
        key: a short name for paths (an entity in Rerun), e.g. ``capture_point``.
        title: what the plot shows, e.g. ``capture point and CoM along x of O_w``.
        unit: the unit of every line, e.g. ``m``, ``N``, ``m/s``; ``1`` for a count or a
            state number.
        series: the lines.
    """

    key: str
    title: str
    unit: str
    series: tuple[Series, ...]

    @property
    def name(self) -> str:
        """The title with its unit, e.g. ``pelvis height [m]``."""
        return f"{self.title} [{self.unit}]"


def signal_plots(scalars: list[str]) -> tuple[Plot, ...]:
    """The plot of a controller that declares none: its scalar signals ``scalars`` (their
    unit unknown: ``?``)."""
    if not scalars:
        return ()
    series = tuple(Series(f"{TOPIC_SIGNALS}.{name}", name) for name in scalars)
    return (Plot("signals", "controller signals", "?", series),)


def read_series(log: Log, series: Series, cache: dict[str, dict[str, np.ndarray]]) -> tuple:
    """Times [s] and values of ``series`` in ``log``, without the ticks where it is not
    defined (NaN); ``cache`` keeps each topic's arrays between calls.

    Returns:
        ``(t, values)``, both shape (N,).

    Raises:
        WalkreproError: the log has no such field, or an index past the array's end.
    """
    arrays = cache.get(series.topic)
    if arrays is None:
        arrays = cache[series.topic] = log.arrays(series.topic)
    if not arrays:
        return np.zeros(0), np.zeros(0)
    values = arrays.get(series.field)
    if values is None or "t" not in arrays:
        raise WalkreproError(
            f"{log.path}: {series.path}: {series.topic} has no field {series.field!r} with a "
            f"time t (fields: {', '.join(arrays)})."
        )
    index = series.index
    if index is not None:
        if values.ndim != 2 or index >= values.shape[1]:
            raise WalkreproError(
                f"{log.path}: {series.path}: {series.field} has no entry {index} "
                f"(shape {values.shape[1:]})."
            )
        values = values[:, index]
    elif values.ndim != 1:
        raise WalkreproError(
            f"{log.path}: {series.path}: {series.field} is an array; name an entry, e.g. "
            f"{series.path}[0]."
        )
    values = np.asarray(values, dtype=float)
    keep = np.isfinite(values)
    return np.asarray(arrays["t"], dtype=float)[keep], values[keep]
