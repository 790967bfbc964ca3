"""The protobuf messages of the log's numeric topics: schemas, encoders and a decoder.

The schemas (package ``walkrepro``, file ``walkrepro/log.proto``) are built here as protobuf
descriptors and stored in the log as a ``FileDescriptorSet`` (MCAP schema encoding
``protobuf``), so any protobuf decoder (Foxglove, ``mcap-protobuf-support``) reads the log
without walkrepro::

    syntax = "proto3";
    package walkrepro;
    message SimState    { fixed64 step = 1; double t = 2; repeated double qpos = 3;
                          repeated double qvel = 4; repeated double act = 5; }
    message Wrench      { string name = 1; repeated double wrench = 2; }  // fx fy fz tx ty tz
    message SimInputs   { fixed64 step = 1; repeated double ctrl = 2; repeated Wrench xfrc = 3; }
    message SimContacts { fixed64 step = 1; double t = 2; repeated Wrench pairs = 3; }
    message Sensors     { double t = 1; repeated double <array field> = 2; ...;
                          google.protobuf.NullValue <field not provided> = n; }
    message Signals     { double t = 1; double <scalar> = 2; sfixed64 <integer> = 3;
                          repeated double <array> = 4; ... }

``Sensors`` is laid out from the first snapshot of a run (its field order, which fields are
arrays and which are not provided); a run's snapshots all share that layout. ``Signals`` is
laid out from the controller's signal layout (:class:`walkrepro.controllers.base.SignalLayout`).

Every scalar is a fixed-width field (``double``, ``fixed64``, ``sfixed64``: 8 bytes), so a
message of a fixed layout puts every value at the same byte offset: :class:`RowEncoder` writes
a batch of messages from a float64 array, one row per message, with a few numpy operations.

The encoders write protobuf's wire format directly: a message of these schemas is a few
tags and lengths around float64 buffers (``ndarray.tobytes()``, IEEE little-endian, which is
protobuf's ``double``), so a state costs one ``bytes.join`` instead of building a protobuf
object (≈ 13x slower: 34.5 vs 2.6 µs for a 37-dof state). Scalars are always written, zeros
too (the wire format allows it and every parser reads them). ``tests/test_protolog.py`` checks every encoder against protobuf's
own parser, so the schema stays the one definition of the format.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory, struct_pb2
from google.protobuf.descriptor import Descriptor, FieldDescriptor, FileDescriptor
from google.protobuf.json_format import MessageToDict

PACKAGE = "walkrepro"
PROTO_FILE = "walkrepro/log.proto"
_NULL = ".google.protobuf.NullValue"

_F = descriptor_pb2.FieldDescriptorProto
_DOUBLE = struct.Struct("<d")


def _field(name: str, number: int, kind: int, repeated: bool = False, type_name: str = ""):
    field = _F(name=name, number=number, type=kind)
    field.label = _F.LABEL_REPEATED if repeated else _F.LABEL_OPTIONAL
    if type_name:
        field.type_name = type_name
    return field


def _message(name: str, *fields: _F) -> descriptor_pb2.DescriptorProto:
    return descriptor_pb2.DescriptorProto(name=name, field=list(fields))


def _core_messages() -> list[descriptor_pb2.DescriptorProto]:
    wrench = f".{PACKAGE}.Wrench"
    return [
        _message(
            "SimState",
            _field("step", 1, _F.TYPE_FIXED64),
            _field("t", 2, _F.TYPE_DOUBLE),
            _field("qpos", 3, _F.TYPE_DOUBLE, True),
            _field("qvel", 4, _F.TYPE_DOUBLE, True),
            _field("act", 5, _F.TYPE_DOUBLE, True),
        ),
        _message(
            "Wrench", _field("name", 1, _F.TYPE_STRING), _field("wrench", 2, _F.TYPE_DOUBLE, True)
        ),
        _message(
            "SimInputs",
            _field("step", 1, _F.TYPE_FIXED64),
            _field("ctrl", 2, _F.TYPE_DOUBLE, True),
            _field("xfrc", 3, _F.TYPE_MESSAGE, True, wrench),
        ),
        _message(
            "SimContacts",
            _field("step", 1, _F.TYPE_FIXED64),
            _field("t", 2, _F.TYPE_DOUBLE),
            _field("pairs", 3, _F.TYPE_MESSAGE, True, wrench),
        ),
    ]


#: Kinds of a ``Sensors`` or ``Signals`` field: a double, an integer (``sfixed64``), an array
#: of doubles, or a field not provided.
SCALAR, INTEGER, ARRAY, NULL = "scalar", "integer", "array", "null"
#: A row column that holds a message's ``step`` (``fixed64``).
COUNT = "count"
#: A run of doubles after bytes given as the field's ``number`` (e.g. a ``Wrench``
#: sub-message's key, length, name and packed-field head, :meth:`WrenchEncoder.head`).
RAW = "raw"


def sensors_layout(message: Mapping[str, Any]) -> tuple[tuple[str, str], ...]:
    """``((key, kind), ...)`` of a sensor snapshot message, in its key order.

    Raises:
        ValueError: a value that is neither a number, an array of numbers nor None.
    """
    layout = []
    for key, value in message.items():
        if value is None:
            kind = NULL
        elif isinstance(value, (float, int, np.floating, np.integer)) and not isinstance(
            value, bool
        ):
            kind = SCALAR
        elif isinstance(value, (np.ndarray, list, tuple)) and np.ndim(value) == 1:
            kind = ARRAY
        else:
            raise ValueError(
                f"/sensors field {key!r} is a {type(value).__name__}; "
                "a sensor field is a number, a 1-D array of numbers or None"
            )
        layout.append((key, kind))
    return tuple(layout)


def signals_layout(names_kinds: Sequence[tuple[str, str]]) -> tuple[tuple[str, str], ...]:
    """``(("t", SCALAR), *names_kinds)``: the ``Signals`` layout of a controller's signals."""
    return (("t", SCALAR), *((name, kind) for name, kind in names_kinds))


_KINDS = {
    SCALAR: (_F.TYPE_DOUBLE, False, ""),
    INTEGER: (_F.TYPE_SFIXED64, False, ""),
    ARRAY: (_F.TYPE_DOUBLE, True, ""),
    NULL: (_F.TYPE_ENUM, False, _NULL),
}


def file_descriptor_set(
    sensors: Sequence[tuple[str, str]] = (), signals: Sequence[tuple[str, str]] = ()
) -> bytes:
    """The serialized ``FileDescriptorSet`` of ``walkrepro/log.proto`` (with ``Sensors`` laid
    out as ``sensors``, see :func:`sensors_layout`, and ``Signals`` as ``signals``, see
    :func:`signals_layout`) and the file it imports."""
    proto = descriptor_pb2.FileDescriptorProto(
        name=PROTO_FILE, package=PACKAGE, syntax="proto3", message_type=_core_messages()
    )
    for name, layout in (("Sensors", sensors), ("Signals", signals)):
        fields = [_field(key, i, *_KINDS[kind]) for i, (key, kind) in enumerate(layout, start=1)]
        proto.message_type.append(_message(name, *fields))
    proto.dependency.append(struct_pb2.DESCRIPTOR.name)
    struct_file = descriptor_pb2.FileDescriptorProto()
    struct_pb2.DESCRIPTOR.CopyToProto(struct_file)
    return descriptor_pb2.FileDescriptorSet(file=[struct_file, proto]).SerializeToString()


def descriptor_set_of(descriptor: FileDescriptor) -> bytes:
    """The serialized ``FileDescriptorSet`` of a compiled protobuf file and everything it
    imports, dependencies first (how Foxglove's published schemas go into a log)."""
    files: list[descriptor_pb2.FileDescriptorProto] = []
    seen: set[str] = set()

    def add(file: FileDescriptor) -> None:
        if file.name in seen:
            return
        seen.add(file.name)
        for dependency in file.dependencies:
            add(dependency)
        proto = descriptor_pb2.FileDescriptorProto()
        file.CopyToProto(proto)
        files.append(proto)

    add(descriptor)
    return descriptor_pb2.FileDescriptorSet(file=files).SerializeToString()


# ---------------------------------------------------------------------------- wire format


def varint(n: int) -> bytes:
    """Protobuf's base-128 varint of ``n >= 0``."""
    out = bytearray()
    while n > 0x7F:
        out.append((n & 0x7F) | 0x80)
        n >>= 7
    out.append(n)
    return bytes(out)


def tag(number: int, wire_type: int) -> bytes:
    """A field's key: number and wire type (0 varint, 1 fixed64, 2 length-delimited)."""
    return varint(number << 3 | wire_type)


def packed_head(number: int, n_doubles: int) -> bytes:
    """Key and length of a packed ``repeated double`` field of ``n_doubles`` values; empty
    for none (an empty repeated field is not written)."""
    return tag(number, 2) + varint(8 * n_doubles) if n_doubles else b""


def length_delimited(number: int, payload: bytes) -> bytes:
    """A string, bytes or sub-message field."""
    return tag(number, 2) + varint(len(payload)) + payload


_STEP = b"\x09"  # field 1, fixed64
_T = b"\x11"  # field 2, fixed64
_U64 = struct.Struct("<Q")


class RowEncoder:
    """Messages of a fixed layout from float64 rows: one row per message, a batch at a time.

    ``fields`` are ``(field number, kind, size)`` in row order (which is also the wire order;
    protobuf allows any): a ``SCALAR`` (``double``), ``INTEGER`` (``sfixed64``) or ``COUNT``
    (``fixed64``) takes one column, an ``ARRAY`` (packed ``repeated double``) ``size`` columns,
    and a ``RAW`` run ``size`` columns after the bytes given in place of its number.
    Every value is 8 bytes, so each sits at a fixed byte offset of the message: a batch is
    the message template repeated, with the rows' bytes put in place (integers converted
    first). The row holds integers as float64, exact up to 2**53.
    """

    def __init__(self, fields: Sequence[tuple[int, str, int]]) -> None:
        template = bytearray()
        # (first column, byte offset, columns) of each run of values; the integer columns.
        runs: list[tuple[int, int, int]] = []
        integer_columns: list[tuple[int, int]] = []  # (column, byte offset)
        width = 0
        for number, kind, size in fields:
            if kind == RAW:
                template += number
            elif kind == ARRAY:
                if size == 0:
                    continue  # an empty repeated field is not on the wire
                template += packed_head(number, size)
            else:
                if size != 1:
                    raise ValueError(f"a {kind} field takes one column, not {size}")
                template += tag(number, 1)
                if kind in (INTEGER, COUNT):
                    integer_columns.append((width, len(template)))
            runs.append((width, len(template), size))
            template += bytes(8 * size)
            width += size
        #: Columns of a row.
        self.width = width
        #: Bytes of each message.
        self.size = len(template)
        self._template = np.frombuffer(bytes(template), np.uint8)
        self._runs = runs
        self._integer_columns = integer_columns

    def encode(self, rows: np.ndarray) -> np.ndarray:
        """The messages of ``rows`` (float64, shape (n, width)) as a (n, size) uint8 array."""
        rows = np.ascontiguousarray(rows, dtype=np.float64)
        n = len(rows)
        out = np.empty((n, self.size), np.uint8)
        out[:] = self._template
        values = rows.view(np.uint8)  # (n, 8 * width)
        for column, at, size in self._runs:
            out[:, at : at + 8 * size] = values[:, 8 * column : 8 * (column + size)]
        for column, at in self._integer_columns:
            integers = rows[:, column].astype("<i8")
            out[:, at : at + 8] = integers.view(np.uint8).reshape(n, 8)
        return out

    def encode_one(self, row: np.ndarray) -> bytes:
        """One message."""
        return self.encode(np.asarray(row, dtype=np.float64)[None, :]).tobytes()


class WrenchEncoder:
    """Repeated ``Wrench`` fields ``{name: 6-vector}`` of field ``number``; the key and
    name bytes of each name are built once."""

    def __init__(self, number: int) -> None:
        self._number = number
        self._heads: dict[str, bytes] = {}

    def encode(self, wrenches: Mapping[str, Any]) -> bytes:
        heads = self._heads
        parts = []
        for name, wrench in wrenches.items():
            head = heads.get(name)
            if head is None:
                head = heads[name] = self._head(name)
            parts.append(head)
            if (
                type(wrench) is not np.ndarray
                or wrench.dtype != np.float64
                or not wrench.flags.c_contiguous
            ):
                wrench = np.ascontiguousarray(wrench, dtype=np.float64)
            parts.append(wrench)  # its buffer: join copies the 48 bytes
        return b"".join(parts)

    def head(self, name: str) -> bytes:
        """The bytes of the entry ``name`` before its six doubles."""
        head = self._heads.get(name)
        if head is None:
            head = self._heads[name] = self._head(name)
        return head

    def _head(self, name: str) -> bytes:
        name_field = length_delimited(1, name.encode())
        body = len(name_field) + 2 + 48
        return tag(self._number, 2) + varint(body) + name_field + packed_head(2, 6)


def row_fields(
    layout: Sequence[tuple[str, str]], sizes: Mapping[str, int], order: Sequence[str] = ()
) -> list[tuple[int, str, int]]:
    """:class:`RowEncoder` fields of a ``Sensors`` or ``Signals`` layout: each field's number
    is its place in ``layout``, ``sizes`` gives each array's length, and ``order`` (default:
    the layout's) the order of the row's columns; not-provided fields take none."""
    numbers = {key: i for i, (key, _) in enumerate(layout, start=1)}
    kinds = dict(layout)
    provided = [key for key, kind in layout if kind != NULL]
    keys = list(order) if order else provided
    if sorted(keys) != sorted(provided):
        raise ValueError(f"row order {tuple(keys)} is not the layout's fields {tuple(provided)}")
    return [(numbers[key], kinds[key], sizes[key] if kinds[key] == ARRAY else 1) for key in keys]


def message_row(message: Mapping[str, Any], fields: Sequence[tuple[str, str, int]]) -> np.ndarray:
    """The row of a dict message for fields ``(key, kind, size)`` in row order.

    Raises:
        ValueError: the message's keys differ, or a value's kind or size is not the field's.
    """
    parts = []
    for key, kind, size in fields:
        value = message[key]
        if kind == ARRAY:
            array = np.asarray(value, dtype=np.float64)
            if value is None or array.shape != (size,):
                raise ValueError(
                    f"field {key!r} changed kind or size within the run (first {size} values)"
                )
            parts.append(array)
        else:
            if value is None or np.ndim(value) != 0:
                raise ValueError(f"field {key!r} changed kind within the run (first {kind})")
            parts.append(np.array([value], dtype=np.float64))
    return np.concatenate(parts) if parts else np.zeros(0)


class ContactsEncoder:
    """``SimContacts`` messages."""

    def __init__(self) -> None:
        self._pairs = WrenchEncoder(3)

    def row_fields(self, names: Sequence[str]) -> list[tuple[Any, str, int]]:
        """:class:`RowEncoder` fields of the messages with these pairs: rows ``[step, t,
        *wrenches.ravel()]``."""
        return [(1, COUNT, 1), (2, SCALAR, 1)] + [
            (self._pairs.head(name), RAW, 6) for name in names
        ]

    def encode(self, step: int, t: float, pairs: Mapping[str, Any]) -> bytes:
        return b"".join((_STEP, _U64.pack(step), _T, _DOUBLE.pack(t), self._pairs.encode(pairs)))


# ---------------------------------------------------------------------------- decoding


def message_classes(descriptor_set: bytes) -> dict[str, type]:
    """Message classes by full name from a serialized ``FileDescriptorSet``."""
    files = descriptor_pb2.FileDescriptorSet.FromString(descriptor_set).file
    pool = descriptor_pool.DescriptorPool()
    by_name = {file.name: file for file in files}

    def add(file: descriptor_pb2.FileDescriptorProto) -> None:
        for dependency in file.dependency:
            if dependency in by_name:
                add(by_name.pop(dependency))
        pool.Add(file)

    while by_name:
        add(by_name.popitem()[1])
    classes = {}
    for file in files:
        for name in file.message_type:
            full = f"{file.package}.{name.name}" if file.package else name.name
            classes[full] = message_factory.GetMessageClass(pool.FindMessageTypeByName(full))
    return classes


def dict_decoder(descriptor_set: bytes, name: str) -> Callable[[bytes], dict[str, Any]]:
    """A function from a message's bytes to the log's dict shape.

    For ``walkrepro.*`` messages: scalars as Python numbers, repeated doubles as lists of
    floats, repeated ``Wrench`` as ``{name: [6 floats]}`` in message order, a ``NullValue``
    field as None. Other messages (Foxglove's) as protobuf's JSON mapping with field names.
    """
    cls = message_classes(descriptor_set)[name]
    if not name.startswith(PACKAGE + "."):
        return lambda data: MessageToDict(cls.FromString(data), preserving_proto_field_name=True)
    readers = [_field_reader(field) for field in cls.DESCRIPTOR.fields]
    parse = cls.FromString

    def decode(data: bytes) -> dict[str, Any]:
        message = parse(data)
        return {key: read(message) for key, read in readers}

    decode.descriptor = cls.DESCRIPTOR  # type: ignore[attr-defined] - for flat_arrays
    return decode


def _field_reader(field: FieldDescriptor) -> tuple[str, Callable[[Any], Any]]:
    name = field.name
    if field.enum_type is not None and field.enum_type.full_name == _NULL[1:]:
        return name, lambda message: None
    if _is_repeated(field):
        if field.message_type is not None:
            return name, lambda message: {w.name: list(w.wrench) for w in getattr(message, name)}
        return name, lambda message: list(getattr(message, name))
    return name, lambda message: getattr(message, name)


def flat_arrays(raw: Sequence[bytes], descriptor: Descriptor) -> dict[str, np.ndarray] | None:
    """Every message of a flat schema at once: field name -> array over the messages
    (``uint64``, ``fixed64``, ``sfixed64`` -> int64 (N,), ``double`` -> float64 (N,), ``repeated double`` -> float64
    (N, n)); None if the messages do not fit that (a sub-message or string field on the wire,
    ragged arrays, an unexpected byte).

    Messages of equal length are read as one numpy array of bytes. The first of them is
    parsed field by field, and every other must have the same key and length bytes at the
    same places (and varints of the same length), so each parses the same way: its values
    are then columns of the array. ``NullValue`` fields (never on the wire) are left out.
    """
    fields = {f.number: f for f in descriptor.fields}
    groups: dict[int, list[int]] = {}
    for i, data in enumerate(raw):
        groups.setdefault(len(data), []).append(i)
    columns: dict[str, list[tuple[list[int], np.ndarray]]] = {}
    for length, index in groups.items():
        layout = _flat_layout(raw[index[0]], fields)
        if layout is None:
            return None
        rows = np.frombuffer(b"".join([raw[i] for i in index]), np.uint8)
        rows = rows.reshape(len(index), length)
        structure = np.ones(length, dtype=bool)
        for _, _, start, size in layout:
            structure[start : start + size] = False
        if not (rows[:, structure] == rows[0, structure]).all():
            return None
        for name, wire_type, start, size in layout:
            cells = rows[:, start : start + size]
            if wire_type == 0:
                if (cells[:, :-1] < 0x80).any() or (cells[:, -1] >= 0x80).any():
                    return None  # a varint of another length here: not this layout
                weights = np.left_shift(np.uint64(1), 7 * np.arange(size, dtype=np.uint64))
                value = ((cells & 0x7F).astype(np.uint64) * weights).sum(axis=1).astype(np.int64)
            elif wire_type == 9:  # fixed64 or sfixed64: int64 (steps stay below 2**63)
                value = np.ascontiguousarray(cells).view("<i8")[:, 0]
            else:
                value = np.ascontiguousarray(cells).view("<f8")
                if wire_type == 1:
                    value = value[:, 0]
            columns.setdefault(name, []).append((index, value))
    n = len(raw)
    out: dict[str, np.ndarray] = {}
    for field in descriptor.fields:
        parts = columns.get(field.name)
        if field.enum_type is not None:
            continue  # NullValue: not provided
        if parts is None and field.message_type is not None:
            continue  # sub-messages, none on the wire: not numbers
        if parts is None:  # never on the wire: zero, or no values
            repeated = field.type == FieldDescriptor.TYPE_DOUBLE and _is_repeated(field)
            out[field.name] = np.zeros((n, 0) if repeated else n)
            continue
        if len(parts) < len(groups) or len({p[1].shape[1:] for p in parts}) != 1:
            return None  # absent from some messages, or arrays of different sizes
        first = parts[0][1]
        values = np.empty((n, *first.shape[1:]), dtype=first.dtype)
        for index, value in parts:
            values[index] = value
        out[field.name] = values
    return out


_FIXED_WIDTH = (
    FieldDescriptor.TYPE_DOUBLE,
    FieldDescriptor.TYPE_FIXED64,
    FieldDescriptor.TYPE_SFIXED64,
)


def flat_messages(raw: Sequence[bytes], descriptor: Descriptor) -> list[dict[str, Any]] | None:
    """The messages of a flat schema as :func:`dict_decoder` gives them, read at numpy speed
    through :func:`flat_arrays`; None where that does not apply. In ``walkrepro.Signals``, a
    NaN scalar or all-NaN array (a signal not defined at that tick) is left out of its
    message."""
    arrays = flat_arrays(raw, descriptor)
    if arrays is None or not raw:
        return None
    names = [field.name for field in descriptor.fields]
    # Not in ``arrays``: NullValue fields (None) and repeated Wrench fields with no entries.
    wrenches = {f.name for f in descriptor.fields if f.message_type is not None}
    columns = [
        arrays[name].tolist()
        if name in arrays
        else [{} for _ in raw]
        if name in wrenches
        else [None] * len(raw)
        for name in names
    ]
    rows = [dict(zip(names, values, strict=True)) for values in zip(*columns, strict=True)]
    if descriptor.full_name == f"{PACKAGE}.Signals":
        for name in names:
            values = arrays[name]
            if values.dtype.kind != "f" or values.size == 0:
                continue
            undefined = np.isnan(values) if values.ndim == 1 else np.isnan(values).all(axis=1)
            for i in np.flatnonzero(undefined).tolist():
                del rows[i][name]
    return rows


def _is_repeated(field: FieldDescriptor) -> bool:
    repeated = getattr(field, "is_repeated", None)  # protobuf >= 5.29; `label` before
    return field.label == FieldDescriptor.LABEL_REPEATED if repeated is None else repeated


def _read_varint(data: bytes, pos: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        byte = data[pos]
        pos += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if byte < 0x80:
            return value, pos


def _flat_layout(
    data: bytes, fields: Mapping[int, FieldDescriptor]
) -> list[tuple[str, int, int, int]] | None:
    """(field name, wire type, start, size) of each value of one message, or None if a field
    is not a varint, a double or a packed repeated double, or comes twice."""
    layout = []
    seen = set()
    pos = 0
    try:
        while pos < len(data):
            key, pos = _read_varint(data, pos)
            number, wire_type = key >> 3, key & 7
            field = fields.get(number)
            if field is None or number in seen:
                return None
            seen.add(number)
            if wire_type == 0:
                _, end = _read_varint(data, pos)
                layout.append((field.name, 0, pos, end - pos))
            elif wire_type == 1 and field.type in _FIXED_WIDTH:
                layout.append((field.name, 1 if field.type == FieldDescriptor.TYPE_DOUBLE else 9,
                               pos, 8))  # fmt: skip
                end = pos + 8
            elif wire_type == 2 and field.type == FieldDescriptor.TYPE_DOUBLE:
                size, pos = _read_varint(data, pos)
                if size % 8:
                    return None
                layout.append((field.name, 2, pos, size))
                end = pos + size
            else:
                return None
            pos = end
    except IndexError:
        return None
    return layout if pos == len(data) else None
