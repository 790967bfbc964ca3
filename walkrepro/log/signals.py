"""A controller's named internal signals as one float64 vector with a fixed layout.

A controller logs its internal signals (FSM state, CoM, CP, references, ...) every control
tick. It declares their names, sizes and kinds once (:class:`SignalLayout`) and returns each
tick's values as one vector (:class:`Signals`); the log writer copies that vector into its
batch of ``/controller/signals`` rows without touching each signal (see
:mod:`walkrepro.log.record`). :class:`Signals` is also a read-only mapping from name to value, so
tests and callers read ``command.signals["cp_w"]`` as from a dict.

A signal set to NaN (a scalar, or every value of an array) is not defined at that tick (e.g.
the QP's contact force of a foot the QP did not solve for): the mapping leaves it out, and so
do readers of the log's message.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence

import numpy as np


class SignalLayout:
    """Names, sizes and kinds of a controller's signals, in vector order; fixed for a run.

    Args:
        fields: ``(name, size, integer)`` per signal: ``size`` 0 for a scalar (read back as
            a float, or an int if ``integer``), else the length of an array (read back as a
            list of floats).

    Raises:
        ValueError: a repeated name, a negative size, an integer array, or a name ``t``
            (the log's own time field).
    """

    __slots__ = ("fields", "slots", "width")

    def __init__(self, fields: Sequence[tuple[str, int, bool]]) -> None:
        self.fields = tuple((str(name), int(size), bool(integer)) for name, size, integer in fields)
        self.slots: dict[str, tuple[int, int, bool]] = {}
        at = 0
        for name, size, integer in self.fields:
            if name in self.slots or name == "t":
                raise ValueError(f"signal name {name!r} is repeated or reserved")
            if size < 0 or (integer and size):
                raise ValueError(f"signal {name!r}: size {size} (integers are scalars)")
            self.slots[name] = (at, size, integer)
            at += max(size, 1)
        #: Length of the value vector.
        self.width = at

    @classmethod
    def of_record(cls, dtype: np.dtype) -> SignalLayout:
        """The layout of a structured record of float64 signals, in field order.

        A controller that writes its signals in compiled code declares them once as a numpy
        structured dtype and fills a record of it by name (``record.com_x = …``); the
        record's memory, viewed as float64 (``record.view(np.float64)``), is then the
        :class:`Signals` vector of this layout. A float field is a scalar signal, a 1-D
        float subarray an array signal, and a nested record's fields are signals named
        ``<record>_<field>`` (``left`` with ``fz``: ``left_fz``).

        Raises:
            ValueError: a field of another type, or a dtype with gaps (not packed in field
                order), so that its float64 view would not match the layout.
        """
        fields: list[tuple[str, int, bool]] = []
        offsets: list[int] = []

        def add(record: np.dtype, prefix: str, base: int) -> None:
            for name in record.names:
                field, offset = record.fields[name][:2]
                if field.names is not None:
                    add(field, f"{prefix}{name}_", base + offset)
                    continue
                sub, shape = field.subdtype or (field, ())
                if sub != np.float64 or len(shape) > 1:
                    raise ValueError(
                        f"signal {prefix}{name!r} is {field}, not float64 or a 1-D array of it"
                    )
                fields.append((prefix + name, shape[0] if shape else 0, False))
                offsets.append(base + offset)

        add(np.dtype(dtype), "", 0)
        layout = cls(fields)
        packed = [8 * at for at, _, _ in layout.slots.values()]
        if offsets != packed or np.dtype(dtype).itemsize != 8 * layout.width:
            raise ValueError("a signal record must be packed in field order (no gaps)")
        return layout

    def __repr__(self) -> str:
        return f"SignalLayout({len(self.fields)} signals, {self.width} values)"


class Signals(Mapping):
    """One tick's signals: ``vector`` (float64, shape (layout.width,)) laid out by ``layout``.

    The vector is the controller's to fill and must not change after the tick (return a new
    one, or a copy, each tick).
    """

    __slots__ = ("layout", "vector")

    def __init__(self, layout: SignalLayout, vector: np.ndarray) -> None:
        if vector.shape != (layout.width,) or vector.dtype != np.float64:
            raise ValueError(
                f"signal values must be float64 of shape ({layout.width},); got "
                f"{vector.dtype} {vector.shape}"
            )
        self.layout = layout
        self.vector = vector

    @classmethod
    def of(cls, layout: SignalLayout, signals: Mapping[str, object]) -> Signals:
        """The signals of a mapping in ``layout``; a float signal left out is NaN (not
        defined at this tick).

        Raises:
            ValueError: a name not in ``layout``, a value of another shape, or an integer
                signal left out.
        """
        extra = [name for name in signals if name not in layout.slots]
        if extra:
            raise ValueError(
                f"signal(s) {', '.join(map(repr, extra))} are not in the layout "
                f"({', '.join(layout.slots)}); a run logs one set of signals"
            )
        values = np.full(layout.width, np.nan)
        for name, value in signals.items():
            at, size, _ = layout.slots[name]
            if size:
                array = np.asarray(value, dtype=np.float64)
                if array.shape != (size,):
                    raise ValueError(f"signal {name!r} has shape {array.shape}, not ({size},)")
                values[at : at + size] = array
            elif np.ndim(value) != 0:
                raise ValueError(f"signal {name!r} is an array; its layout makes it a number")
            else:
                values[at] = value
        missing = [
            name
            for name, (_, _, integer) in layout.slots.items()
            if integer and name not in signals
        ]
        if missing:
            raise ValueError(f"integer signal(s) {', '.join(missing)} left out")
        return cls(layout, values)

    def __getitem__(self, name: str) -> float | int | list[float]:
        at, size, integer = self.layout.slots[name]
        if size:
            values = self.vector[at : at + size]
            if np.isnan(values).all():
                raise KeyError(name)  # not defined at this tick
            return values.tolist()
        value = self.vector[at]
        if value != value:  # NaN: not defined at this tick
            raise KeyError(name)
        return int(value) if integer else float(value)

    def __iter__(self) -> Iterator[str]:
        """The names of the signals defined at this tick (as the log's message holds them)."""
        values = self.vector
        for name, (at, size, _) in self.layout.slots.items():
            if not np.isnan(values[at : at + max(size, 1)]).all():
                yield name

    def __len__(self) -> int:
        return sum(1 for _ in self)

    def __repr__(self) -> str:
        return f"Signals({dict(self)!r})"


def dict_layout(signals: Mapping[str, object]) -> SignalLayout:
    """The layout of a plain dict of signals: ints and bools are integers, other numbers
    scalars, 1-D sequences arrays.

    Raises:
        ValueError: a value of another kind (a string, a 2-D array, ...).
    """
    fields = []
    for name, value in signals.items():
        if isinstance(value, (bool, int, np.integer, np.bool_)):
            fields.append((name, 0, True))
        elif isinstance(value, (float, np.floating)):
            fields.append((name, 0, False))
        elif isinstance(value, (list, tuple, np.ndarray)) and np.ndim(value) == 1 and len(value):
            fields.append((name, len(value), False))
        else:
            raise ValueError(
                f"signal {name!r} is a {type(value).__name__}; a signal is a number or a 1-D "
                "array of numbers (not empty)"
            )
    return SignalLayout(fields)
