"""MCAP log writing and reading: the log contract (format version 2).

A run's log is one MCAP file that holds everything needed to re-check, re-plot and
re-simulate the run, with no other file:

- attachment ``scene.xml`` (``application/xml``): the compiled scene; it loads alone with
  ``mujoco.MjModel.from_xml_string``;
- attachment ``spec.yaml`` (``application/yaml``): the resolved experiment spec;
- metadata record ``walkrepro`` (string → string): ``log_format`` (:data:`LOG_FORMAT`),
  ``version``, ``git_commit``, ``mujoco_version``, ``pinocchio_version``, ``seed``,
  ``experiment``, ``start_time`` (UTC ISO 8601), ``log_time_origin`` (see below),
  ``outcome`` (one of :data:`OUTCOMES`) and any extra keys given to :meth:`LogWriter.close`
  (e.g. ``fall_time``, ``error``). It is written last, by ``close()``, because the outcome is
  only known then;
- the numeric topics ``/sim/state``, ``/sim/inputs``, ``/sim/contacts``, ``/sensors`` and
  ``/controller/signals`` as protobuf messages (schemas ``walkrepro.*``, see
  :mod:`walkrepro.log.protolog`), the Foxglove topics ``/frames`` and ``/scene`` as protobuf
  messages of Foxglove's published schemas (:mod:`walkrepro.log.foxglove`), ``/events`` as JSON
  (schema encoding ``jsonschema``); each schema is stored in the file. Messages go into
  zstd-compressed chunks. The per-tick topics are gathered as float64 rows and written a batch
  at a time (:class:`_RowBatch`), so a chunk holds one stretch of time with each channel's
  messages in order.

``log_time`` and ``publish_time`` of a message are wall-clock UTC in [ns]: the run's start
(``log_time_origin``, ns since 1970) plus the simulated time; the simulated time ``t`` [s]
itself is in the payload. ``sequence`` counts the messages of each channel from 0.

Floats round-trip bit for bit: protobuf's ``double`` is the IEEE float64 itself, and the JSON
topic holds the shortest repr that parses back to the same double (orjson, or Python's
``json``). The binary topics hold any float64; the runner stops on a non-finite state or
command before it is logged, and a NaN signal means "not defined at this tick"
(:mod:`walkrepro.log.signals`). JSON rejects NaN and infinity, so ``/events`` is always valid.

A log whose writer was killed has no summary and no ``walkrepro`` metadata; :func:`read_log`
still reads every complete chunk before the damage. :func:`read_log` also reads format 1
logs (JSON on every topic, simulated time in the MCAP stamps): each channel is decoded by its
own message encoding.
"""

from __future__ import annotations

import functools
import json
import math
import re
import time
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field
from datetime import datetime, timezone
from importlib import metadata as importlib_metadata
from pathlib import Path
from types import NoneType, TracebackType
from typing import Any, NamedTuple, NoReturn

import mujoco
import numpy as np

from walkrepro._version import __version__
from walkrepro.errors import UnknownNameError, WalkreproError
from walkrepro.log import foxglove, protolog
from walkrepro.log.mcapfile import ChannelWriter, McapFile, McapSummary, read_mcap, read_summary
from walkrepro.log.signals import SignalLayout, Signals, dict_layout

try:
    import orjson
except ImportError:  # optional speed-up: pip install orjson
    orjson = None

#: The log format version, in the metadata's ``log_format`` (logs without it are format 1).
LOG_FORMAT = "2"

TOPIC_STATE = "/sim/state"
TOPIC_INPUTS = "/sim/inputs"
TOPIC_CONTACTS = "/sim/contacts"
TOPIC_SENSORS = "/sensors"
TOPIC_SIGNALS = "/controller/signals"
TOPIC_EVENTS = "/events"
TOPIC_FRAMES = "/frames"
TOPIC_SCENE = "/scene"
#: Every topic a log may hold, in channel order.
TOPICS = (
    TOPIC_STATE,
    TOPIC_INPUTS,
    TOPIC_CONTACTS,
    TOPIC_SENSORS,
    TOPIC_SIGNALS,
    TOPIC_EVENTS,
    TOPIC_FRAMES,
    TOPIC_SCENE,
)

#: How a run ended, as written to the ``outcome`` metadata key.
OUTCOMES = ("complete", "fell", "interrupted", "error")
#: ``outcome`` of a log read back without its metadata record (the writer never closed).
OUTCOME_NOT_CLOSED = "unknown (log not closed)"

METADATA_NAME = "walkrepro"
SCENE_ATTACHMENT = "scene.xml"
SPEC_ATTACHMENT = "spec.yaml"
#: Metadata keys the caller must give; the writer fills ``version``, ``mujoco_version``,
#: ``pinocchio_version`` and ``start_time`` itself unless given.
REQUIRED_METADATA = ("git_commit", "seed", "experiment")
#: Default chunk size in [bytes] (uncompressed); a killed writer loses at most two chunks (the
#: open one, and the closed one the background thread may still be writing).
DEFAULT_CHUNK_SIZE = 1 << 20

# Keys each message must have; checked on write so a bad runner fails at once, not at verify.
_REQUIRED_KEYS: dict[str, frozenset[str]] = {
    TOPIC_STATE: frozenset({"step", "t", "qpos", "qvel", "act"}),
    TOPIC_INPUTS: frozenset({"step", "ctrl", "xfrc"}),
    TOPIC_CONTACTS: frozenset({"step", "t", "pairs"}),
    TOPIC_SENSORS: frozenset(),
    TOPIC_SIGNALS: frozenset({"t"}),
    TOPIC_EVENTS: frozenset({"t", "kind"}),
}
#: The protobuf message of each walkrepro binary topic.
_PROTO_MESSAGES = {
    TOPIC_STATE: "walkrepro.SimState",
    TOPIC_INPUTS: "walkrepro.SimInputs",
    TOPIC_CONTACTS: "walkrepro.SimContacts",
    TOPIC_SENSORS: "walkrepro.Sensors",
    TOPIC_SIGNALS: "walkrepro.Signals",
}
#: Most messages gathered per fixed-layout channel before the batches are written and the
#: chunk closed; fewer where four state records per message would exceed the chunk size
#: (≈ 400 at 1 MB for Paper I's robot). A killed writer loses at most two batches of ticks.
BATCH_ROWS = 512
#: Types of signal values :meth:`LogWriter._signal_vector` copies as they are.
_PLAIN_NUMBERS = frozenset({float, int, bool, np.float64})
_FILE_ATTRIBUTE = re.compile(r"<(\w+)\b[^>]*?\sfile\s*=", re.DOTALL)


def _json_default(obj: Any) -> Any:
    """Turns numpy values into plain Python ones (lists of Python floats, ints, bools)."""
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, Mapping):
        return dict(obj)
    if isinstance(obj, (tuple, set, frozenset)):
        return list(obj)
    raise TypeError(f"cannot write a {type(obj).__name__} to a JSON log message")


# One shared encoder: json.dumps() with options builds a new encoder per call, which is slower.
_ENCODER = json.JSONEncoder(allow_nan=False, separators=(",", ":"), default=_json_default)


def _encode_stdlib(message: Mapping[str, Any]) -> bytes:
    """Compact JSON; raises ValueError on NaN/infinity."""
    return _ENCODER.encode(message).encode()


# orjson writes NaN and infinity as null. A compiled regex finds "null" faster than `in`,
# find() or rfind() do in real messages (≈ 0.5 µs for 1.4 kB).
_find_null = re.compile(rb"null").search


def _encode_orjson(message: Mapping[str, Any]) -> bytes:
    """Compact JSON, ~8x faster than the stdlib; raises ValueError on NaN/infinity."""
    data = orjson.dumps(message, default=_json_default)
    if _find_null(data) is not None:
        _reject_nonfinite(message, data)
    return data


def _reject_nonfinite(message: Any, data: bytes) -> None:
    """Raise ValueError if a null in orjson's ``data`` stands for NaN or infinity.

    A null is rare except from top-level ``None`` fields (e.g. the base state a spec does not
    provide), so only a null those do not account for costs a walk through the message.
    """
    # Counting types, not values: == on an array is elementwise.
    nones = [*map(type, message.values())].count(NoneType) if isinstance(message, Mapping) else 0
    if data.count(b"null") != nones and _find_nonfinite(message, "") is not None:
        raise ValueError("Out of range float values are not JSON compliant")


# orjson is optional: both spell every double as its shortest exact repr, so logs read back
# bit for bit either way. With the stdlib, a 37-dof state costs ~35 us to encode, with orjson ~5.
if orjson is None:
    _encode = _encode_stdlib
    _decode_json: Callable[[bytes], Any] = json.loads
else:
    _encode = _encode_orjson
    _decode_json = orjson.loads


def _raise_nonfinite(topic: str, message: Any, t: float, exc: ValueError) -> NoReturn:
    """Raise for a message the encoder refused (``exc``), naming its first non-finite number
    if that was the reason."""
    where = _find_nonfinite(message, "")
    if where is None:
        raise exc
    raise ValueError(
        f"{topic} message at t={t} [s] holds a non-finite number: {where}. "
        "Logs must be valid JSON; check the simulation for divergence."
    ) from exc


def _find_nonfinite(obj: Any, where: str) -> str | None:
    """Path (e.g. ``qpos[3]``) of the first NaN or infinity inside ``obj``, or None."""
    if isinstance(obj, np.ndarray) and obj.dtype.kind == "f":
        bad = np.flatnonzero(~np.isfinite(obj))
        if bad.size == 0:
            return None
        index = np.unravel_index(int(bad[0]), obj.shape)
        return f"{where}{''.join(f'[{i}]' for i in index)} = {obj[index]}"
    if isinstance(obj, Mapping):
        for key, value in obj.items():
            found = _find_nonfinite(value, f"{where}.{key}" if where else str(key))
            if found is not None:
                return found
    elif isinstance(obj, (list, tuple, np.ndarray)):
        for i, value in enumerate(obj):
            found = _find_nonfinite(value, f"{where}[{i}]")
            if found is not None:
                return found
    elif isinstance(obj, (float, np.floating)) and not math.isfinite(obj):
        return f"{where} = {obj}"
    return None


def _compile_scene(scene_xml: str) -> mujoco.MjModel:
    """Compiles ``scene_xml`` alone, proving the log's scene is self-contained."""
    match = _FILE_ATTRIBUTE.search(scene_xml)
    if match is not None:
        raise WalkreproError(
            f"scene.xml is not self-contained: a <{match.group(1)}> element reads a file. "
            "Inline the data (e.g. mesh vertex/face) or drop the element, so the log's scene "
            "loads alone with mujoco.MjModel.from_xml_string."
        )
    try:
        return mujoco.MjModel.from_xml_string(scene_xml)
    except ValueError as exc:
        raise WalkreproError(f"scene.xml does not load alone: {exc}") from exc


def _ns(t: float) -> int:
    """Simulated time ``t`` in [s] as a duration in [ns]."""
    return round(float(t) * 1e9)


def _json_schemas() -> dict[str, tuple[str, dict[str, Any]]]:
    """JSON schemas (draft 2020-12) of the JSON topics: topic -> (name, schema)."""
    dialect = "https://json-schema.org/draft/2020-12/schema"
    t = {"type": "number", "description": "simulated time [s]"}
    return {
        TOPIC_EVENTS: (
            "walkrepro.Event",
            {
                "$schema": dialect,
                "title": "walkrepro.Event",
                "description": "A discrete event (fall, push start, FSM transition, ...).",
                "type": "object",
                "properties": {
                    "t": t,
                    "kind": {"type": "string", "description": "event kind"},
                },
                "required": ["t", "kind"],
            },
        ),
    }


class SimState(NamedTuple):
    """The simulation's state at a physics step, as a ``/sim/state`` row holds it.

    Attributes:
        step: physics steps since the start; t: simulated time [s].
        qpos, qvel, act: MjData's arrays (views are fine: the row copies them).
    """

    step: int
    t: float
    qpos: np.ndarray
    qvel: np.ndarray
    act: np.ndarray


class _Channel:
    """A topic's MCAP channel writer, and its ``append`` bound once (called per message)."""

    __slots__ = ("append", "writer")

    def __init__(self, writer: ChannelWriter) -> None:
        self.writer = writer
        self.append = writer.append


class _RowBatch:
    """A fixed-layout channel's next messages as float64 rows (see
    :class:`protolog.RowEncoder`), with their stamps and any bytes that follow a row's
    message (an ``/sim/inputs`` row's disturbance wrenches)."""

    __slots__ = ("encoder", "extras", "n", "rows", "stamps", "writer")

    def __init__(self, encoder: protolog.RowEncoder, writer: ChannelWriter, capacity: int) -> None:
        self.encoder = encoder
        self.writer = writer
        self.rows = np.zeros((capacity, encoder.width))
        self.stamps = np.zeros(capacity, dtype=np.int64)
        self.extras: list[bytes] | None = None
        self.n = 0

    def flush(self) -> None:
        """Queues the rows gathered so far in the open chunk; they are encoded when it
        closes, on the file's background thread, so the batch gathers in new arrays."""
        n = self.n
        if n:
            extras = None if self.extras is None else self.extras[:n]
            rows, stamps = self.rows, self.stamps
            encode = functools.partial(self.encoder.encode, rows[:n])
            self.writer.append_rows(stamps[:n], self.encoder.size, encode, extras)
            self.rows, self.stamps = np.empty_like(rows), np.empty_like(stamps)
            self.n, self.extras = 0, None


class LogWriter:
    """Writes one run's MCAP log per the log contract (see the module docstring).

    Use as a context manager: leaving the block by an exception closes the log with outcome
    ``error`` (``interrupted`` for Ctrl-C) and the exception text in the ``error`` key; leaving
    it normally without :meth:`close` records ``complete``.

    Args:
        path: file to create (overwritten if it exists).
        scene_xml: the compiled scene; must load alone with ``MjModel.from_xml_string``.
        spec_yaml: the resolved experiment spec.
        metadata: string → string run metadata; must hold :data:`REQUIRED_METADATA`.
        chunk_size: uncompressed chunk size in [bytes]; a killed writer loses at most two
            chunks (see :data:`DEFAULT_CHUNK_SIZE`).
        log_time_origin: wall-clock UTC of simulated time 0 in [ns since 1970]; default now.

    Raises:
        WalkreproError: the scene does not load alone, or ``path`` cannot be written.
        ValueError: missing metadata keys or a reserved ``outcome`` key.
        TypeError: non-string metadata keys or values.
    """

    def __init__(
        self,
        path: Path,
        *,
        scene_xml: str,
        spec_yaml: str,
        metadata: Mapping[str, str],
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        log_time_origin: int | None = None,
    ) -> None:
        self.path = Path(path)
        model = _compile_scene(scene_xml)
        self._dims = {"qpos": model.nq, "qvel": model.nv, "act": model.na, "ctrl": model.nu}
        self._state_dims = (model.nq, model.nv, model.na)
        self._bodies = frozenset(
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i) for i in range(model.nbody)
        )
        now_ns = time.time_ns()
        #: Wall-clock UTC of simulated time 0 [ns]: every message's stamp is this plus ``t``.
        self.log_time_origin = now_ns if log_time_origin is None else int(log_time_origin)
        self._metadata = {
            **_base_metadata(metadata),
            "log_format": LOG_FORMAT,
            "log_time_origin": str(self.log_time_origin),
        }
        try:
            self._file = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        except OSError as exc:
            raise WalkreproError(f"cannot write log {self.path}: {exc.strerror}") from exc
        self._writer = McapFile(self._file, chunk_size, library=f"walkrepro/{__version__}")
        # Attachments first: they then survive any truncation of the file.
        for name, media_type, text in (
            (SCENE_ATTACHMENT, "application/xml", scene_xml),
            (SPEC_ATTACHMENT, "application/yaml", spec_yaml),
        ):
            self._writer.add_attachment(now_ns, 0, name, media_type, text.encode())
        self._channels: dict[str, _Channel] = {}
        core = protolog.file_descriptor_set()
        for topic in (TOPIC_STATE, TOPIC_INPUTS, TOPIC_CONTACTS):
            self._add_channel(topic, _PROTO_MESSAGES[topic], "protobuf", core)
        # /sensors' schema follows the first snapshot's layout; its channel is added then.
        for topic, (name, schema) in _json_schemas().items():
            self._add_channel(topic, name, "jsonschema", json.dumps(schema).encode())
        for topic, (name, file) in (
            (TOPIC_FRAMES, foxglove.FRAME_TRANSFORMS_SCHEMA),
            (TOPIC_SCENE, foxglove.SCENE_UPDATE_SCHEMA),
        ):
            self._add_channel(topic, name, "protobuf", foxglove.schema_data(file))
        nq, nv, na = self._state_dims
        self._state_split = (2 + nq, 2 + nq + nv)  # row: step, t, qpos, qvel, act
        state = protolog.RowEncoder(
            [(1, protolog.COUNT, 1), (2, protolog.SCALAR, 1), (3, protolog.ARRAY, nq),
             (4, protolog.ARRAY, nv), (5, protolog.ARRAY, na)]
        )  # fmt: skip
        inputs = protolog.RowEncoder([(1, protolog.COUNT, 1), (2, protolog.ARRAY, model.nu)])
        self._batch_rows = max(1, min(BATCH_ROWS, chunk_size // (4 * (31 + state.size))))
        self._state_rows = _RowBatch(state, self._channels[TOPIC_STATE].writer, self._batch_rows)
        self._input_rows = _RowBatch(inputs, self._channels[TOPIC_INPUTS].writer, self._batch_rows)
        self._xfrc = protolog.WrenchEncoder(3)
        self._contacts = protolog.ContactsEncoder()
        # /sensors and /controller/signals are laid out from their first message.
        self._sensor_rows: _RowBatch | None = None
        self._sensor_fields: list[tuple[str, str, int]] = []  # (key, kind, size), row order
        self._sensor_reading = False  # rows straight from SensorSnapshot.reading
        self._signal_rows: _RowBatch | None = None
        self._signal_layout: SignalLayout | None = None
        self._signal_scalars: tuple[str, ...] | None = None  # names, when all are scalars
        self._batches = [self._state_rows, self._input_rows]
        self._frames = foxglove.FrameEncoder(model)
        # /sim/contacts: one batch per set of pairs, the current one gathering.
        self._contact_batches: dict[tuple[str, ...], _RowBatch] = {}
        self._contact_rows: _RowBatch | None = None
        self._contact_names: tuple[str, ...] | None = None
        self._last_t, self._last_stamp = math.nan, 0
        self._closed = False
        self._channels[TOPIC_SCENE].append(
            self.log_time_origin, foxglove.scene_update(model, self.log_time_origin)
        )

    def _add_channel(self, topic: str, name: str, encoding: str, schema: bytes) -> None:
        schema_id = self._writer.add_schema(name, encoding, schema)
        message_encoding = "protobuf" if encoding == "protobuf" else "json"
        channel_id = self._writer.add_channel(topic, message_encoding, schema_id)
        self._channels[topic] = _Channel(self._writer.channel_writer(channel_id))

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` has finished the file."""
        return self._closed

    def write(self, topic: str, message: Mapping[str, Any], t: float) -> None:
        """Appends one message.

        Args:
            topic: one of :data:`TOPICS` but ``/frames`` and ``/scene`` (see
                :meth:`write_frames`).
            message: mapping with str keys in the topic's shape (see the README's log
                contract); numpy arrays and scalars are written exactly (float32 as the
                float64 of the same value).
            t: simulated time of the message in [s], ``>= 0``.

        Raises:
            ValueError: unknown topic, missing keys, wrong vector sizes, NaN/infinity on a
                JSON topic, a ``/sensors`` message unlike the run's first, negative or
                non-finite ``t``, or the log is closed.
            UnknownNameError: an ``xfrc`` body that is not in the scene.
        """
        channel = self._channels.get(topic)
        lazy = topic in (TOPIC_SENSORS, TOPIC_SIGNALS)  # channels added at their first message
        if channel is None and not lazy or topic in (TOPIC_FRAMES, TOPIC_SCENE):
            raise ValueError(f"unknown topic {topic!r}. Valid topics: {', '.join(TOPICS[:6])}.")
        required = _REQUIRED_KEYS[topic]
        if not required <= message.keys():
            missing = required - message.keys()
            raise ValueError(f"{topic} message lacks key(s) {', '.join(sorted(missing))}")
        if topic == TOPIC_STATE:
            arrays = [np.asarray(message[k], dtype=np.float64) for k in ("qpos", "qvel", "act")]
            self.write_state(int(message["step"]), float(message["t"]), *arrays)
        elif topic == TOPIC_INPUTS:
            self._check_sizes(topic, message)
            ctrl = self.encode_ctrl(np.asarray(message["ctrl"], dtype=np.float64))
            self.write_inputs(int(message["step"]), ctrl, message["xfrc"], t)
        elif topic == TOPIC_CONTACTS:
            self.write_contacts(message["step"], message["t"], message["pairs"])
        elif topic == TOPIC_SENSORS:
            self._write_sensors(message, None, t)
        elif topic == TOPIC_SIGNALS:
            self.write_signals(t, {key: value for key, value in message.items() if key != "t"})
        else:
            data = self._encode_checked(topic, message, _encode, t)
            if t != self._last_t:
                self._set_time(topic, t)
            channel.append(self._last_stamp, data)

    def write_contacts(self, step: int, t: float, pairs: Mapping[str, Any]) -> None:
        """One ``/sim/contacts`` message: ``{"<robot body>/<world geom>": 6-vector}``."""
        names = tuple(pairs)
        wrenches = np.array([np.asarray(w, dtype=np.float64) for w in pairs.values()])
        if names and wrenches.shape != (len(names), 6):
            raise ValueError(f"{TOPIC_CONTACTS} pair wrenches must have 6 entries each")
        self.write_contact_pairs(step, t, names, wrenches.reshape(len(names), 6))

    def write_contact_pairs(
        self, step: int, t: float, names: tuple[str, ...], wrenches: np.ndarray
    ) -> None:
        """One ``/sim/contacts`` message from the pairs' names and wrenches (float64, shape
        (pairs, 6)), as :meth:`walkrepro.sim.contact_reader.ContactReader.read_pairs` gives them.

        Messages with the same pairs are gathered as rows; the batch is written when the set
        of pairs changes (a few times per step) or with the other batches.
        """
        batch = self._contact_rows
        if names is not self._contact_names:
            if batch is None or names != self._contact_names:
                if batch is not None:
                    batch.flush()
                batch = self._contact_batch(names)
            self._contact_names = names
        if t != self._last_t:
            self._set_time(TOPIC_CONTACTS, t)
        i = batch.n
        row = batch.rows[i]
        row[0] = step
        row[1] = t
        row[2:] = wrenches.ravel()
        batch.stamps[i] = self._last_stamp
        batch.n = i + 1
        if i + 1 == self._batch_rows:
            self._flush_batches()

    def _contact_batch(self, names: tuple[str, ...]) -> _RowBatch:
        """The (empty) batch of the messages with these pairs, made once per set."""
        batch = self._contact_batches.get(names)
        if batch is None:
            encoder = protolog.RowEncoder(self._contacts.row_fields(names))
            writer = self._channels[TOPIC_CONTACTS].writer
            batch = self._contact_batches[names] = _RowBatch(encoder, writer, self._batch_rows)
        self._contact_rows = batch
        return batch

    def write_sensors(self, snapshot: Any) -> None:
        """One ``/sensors`` message from a :class:`walkrepro.sim.sensors.SensorSnapshot` (its
        ``t`` is the message time)."""
        if self._sensor_reading and snapshot.reading is not None:
            t = snapshot.t
            if t != self._last_t:
                self._set_time(TOPIC_SENSORS, t)
            batch = self._sensor_rows
            i = batch.n
            row = batch.rows[i]
            row[0] = t
            row[1:] = snapshot.reading
            batch.stamps[i] = self._last_stamp
            batch.n = i + 1
            if i + 1 == self._batch_rows:
                self._flush_batches()
            return
        self._write_sensors(snapshot.as_message(), snapshot, snapshot.t)

    def _write_sensors(self, message: Mapping[str, Any], snapshot: Any, t: float) -> None:
        """One ``/sensors`` message from its dict (a snapshot's, or a caller's)."""
        if self._sensor_rows is None:
            self._start_sensors(message, snapshot)
        if tuple(message) != self._sensor_keys:
            raise ValueError(
                f"/sensors message keys {tuple(message)} differ from the run's first "
                f"snapshot's {self._sensor_keys}"
            )
        for key in self._sensor_nulls:
            if message[key] is not None:
                raise ValueError(f"/sensors field {key!r} changed kind within the run (first null)")
        row = protolog.message_row(message, self._sensor_fields)
        if t != self._last_t:
            self._set_time(TOPIC_SENSORS, t)
        batch = self._sensor_rows
        i = batch.n
        batch.rows[i] = row
        batch.stamps[i] = self._last_stamp
        batch.n = i + 1
        if i + 1 == self._batch_rows:
            self._flush_batches()

    def _start_sensors(self, message: Mapping[str, Any], snapshot: Any) -> None:
        """Lays out ``/sensors`` from its first message and adds its channel. A snapshot
        whose fields view its ``reading`` in :data:`SensorSnapshot.READING` order is logged
        from then on as ``[t, *reading]``."""
        if self._closed:
            raise ValueError(f"cannot write to {TOPIC_SENSORS!r}: log {self.path} is closed")
        layout = protolog.sensors_layout(message)
        sizes = {key: len(message[key]) for key, kind in layout if kind == protolog.ARRAY}
        reading = getattr(snapshot, "reading", None)
        order = [key for key in getattr(snapshot, "READING", ()) if message.get(key) is not None]
        self._sensor_reading = False
        if reading is not None and order:
            fields = ["t", *order]
            kinds = dict(layout)
            as_fields = protolog.message_row(
                message, [(key, kinds[key], sizes.get(key, 1)) for key in fields]
            )
            self._sensor_reading = (
                as_fields[1:].view(np.int64).tolist()
                == np.asarray(reading, dtype=np.float64).view(np.int64).tolist()
            )
        if not self._sensor_reading:
            fields = [key for key, kind in layout if kind != protolog.NULL]
        self._add_channel(
            TOPIC_SENSORS,
            _PROTO_MESSAGES[TOPIC_SENSORS],
            "protobuf",
            protolog.file_descriptor_set(sensors=layout),
        )
        kinds = dict(layout)
        self._sensor_keys = tuple(message)
        self._sensor_nulls = [key for key, kind in layout if kind == protolog.NULL]
        self._sensor_fields = [(key, kinds[key], sizes.get(key, 1)) for key in fields]
        encoder = protolog.RowEncoder(protolog.row_fields(layout, sizes, fields))
        self._sensor_rows = _RowBatch(
            encoder, self._channels[TOPIC_SENSORS].writer, self._batch_rows
        )
        self._batches.append(self._sensor_rows)

    def write_signals(self, t: float, signals: Signals | Mapping[str, Any]) -> None:
        """One ``/controller/signals`` message, ``{"t": t, **signals}``.

        :class:`walkrepro.log.signals.Signals` of the run's layout are copied as one vector. A
        plain dict is laid out by the run's first one (:func:`walkrepro.log.signals.dict_layout`);
        a later dict may leave out scalars (logged as NaN: not defined at that tick) but not
        add signals.

        Raises:
            ValueError: a signal that is not a number or a 1-D array, a signal not in the
                run's layout, or a bad ``t``.
        """
        if self._signal_rows is None:
            self._start_signals(signals)
        values = self._signal_vector(signals)
        if t != self._last_t:
            self._set_time(TOPIC_SIGNALS, t)
        batch = self._signal_rows
        i = batch.n
        row = batch.rows[i]
        row[0] = t
        row[1:] = values
        batch.stamps[i] = self._last_stamp
        batch.n = i + 1
        if i + 1 == self._batch_rows:
            self._flush_batches()

    def _start_signals(self, signals: Signals | Mapping[str, Any]) -> None:
        """Lays out ``/controller/signals`` from the first signals and adds its channel."""
        if self._closed:
            raise ValueError(f"cannot write to {TOPIC_SIGNALS!r}: log {self.path} is closed")
        if not isinstance(signals, Mapping):
            raise TypeError(f"signals must be a mapping or Signals, not {type(signals).__name__}")
        layout = signals.layout if isinstance(signals, Signals) else dict_layout(signals)
        kinds = [
            (name, protolog.ARRAY if size else protolog.INTEGER if integer else protolog.SCALAR)
            for name, size, integer in layout.fields
        ]
        proto_layout = protolog.signals_layout(kinds)
        sizes = {name: size for name, size, _ in layout.fields if size}
        self._add_channel(
            TOPIC_SIGNALS,
            _PROTO_MESSAGES[TOPIC_SIGNALS],
            "protobuf",
            protolog.file_descriptor_set(signals=proto_layout),
        )
        encoder = protolog.RowEncoder(protolog.row_fields(proto_layout, sizes))
        self._signal_layout = layout
        scalars = all(size == 0 for _, size, _ in layout.fields)
        self._signal_scalars = tuple(layout.slots) if scalars else None
        self._signal_rows = _RowBatch(
            encoder, self._channels[TOPIC_SIGNALS].writer, self._batch_rows
        )
        self._batches.append(self._signal_rows)

    def _signal_values(self, signals: Mapping[str, Any]) -> np.ndarray:
        """The value vector of signals given as a mapping, in the run's layout."""
        try:
            return Signals.of(self._signal_layout, signals).vector
        except ValueError as exc:
            raise ValueError(f"{TOPIC_SIGNALS}: {exc}") from None

    def _signal_vector(self, signals: Signals | Mapping[str, Any]) -> Any:
        """A tick's signal values in the run's layout, to copy into a row (None before the
        first signals laid it out): the vector of :class:`Signals` of the layout; the values
        of a dict of plain numbers with the layout's names in its order (a controller's few
        scalars, e.g. the posture controller's, without building a vector); else
        :meth:`_signal_values`, which checks each signal.

        Raises:
            ValueError: as :meth:`_signal_values`.
        """
        if type(signals) is Signals and signals.layout is self._signal_layout:
            return signals.vector
        if self._signal_layout is None:
            return None
        if type(signals) is dict and tuple(signals) == self._signal_scalars:
            values = tuple(signals.values())
            for value in values:
                if type(value) not in _PLAIN_NUMBERS:
                    break
            else:
                return values  # a float64 row takes them as Signals.of's vector does
        return self._signal_values(signals)

    def write_state(
        self, step: int, t: float, qpos: np.ndarray, qvel: np.ndarray, act: np.ndarray
    ) -> None:
        """One ``/sim/state`` message from MjData's float64 arrays (written at every control
        tick, up to 2 kHz).

        Raises:
            ValueError: wrong vector sizes, or a bad ``t``.
        """
        if (len(qpos), len(qvel), len(act)) != self._state_dims:
            message = {"qpos": qpos, "qvel": qvel, "act": act}
            self._check_sizes(TOPIC_STATE, message)
        if t != self._last_t:
            self._set_time(TOPIC_STATE, t)
        batch = self._state_rows
        i = batch.n
        self._fill_state_row(batch.rows[i], step, t, qpos, qvel, act)
        batch.stamps[i] = self._last_stamp
        batch.n = i + 1
        if i + 1 == self._batch_rows:
            self._flush_batches()

    def _fill_state_row(
        self,
        row: np.ndarray,
        step: int,
        t: float,
        qpos: np.ndarray,
        qvel: np.ndarray,
        act: np.ndarray,
    ) -> None:
        """A ``/sim/state`` row: ``[step, t, *qpos, *qvel, *act]``."""
        a, b = self._state_split
        row[0] = step
        row[1] = t
        row[2:a] = qpos
        row[a:b] = qvel
        row[b:] = act

    def write_tick(
        self,
        sim: SimState,
        snapshot: Any,
        signals: Signals | Mapping[str, Any],
        ctrl: np.ndarray,
        xfrc: Mapping[str, np.ndarray],
    ) -> None:
        """A control tick's ``/sim/state``, ``/sensors``, ``/controller/signals`` and
        ``/sim/inputs``: what :meth:`write_state`, :meth:`write_sensors`,
        :meth:`write_signals` and :meth:`write_inputs` write, in one call with one time
        check. Anything but the simulation loop's steady case (a snapshot read at ``t``, the
        run's Signals layout, no disturbance) goes through those four methods.
        """
        step, t, qpos, qvel, act = sim
        state, sensors, logged = self._state_rows, self._sensor_rows, self._signal_rows
        i = state.n
        values = self._signal_vector(signals)
        if not (
            self._sensor_reading  # then /sensors is laid out
            and values is not None
            and snapshot.t == t
            and not xfrc
            and sensors.n == i == logged.n
            and (len(qpos), len(qvel), len(act)) == self._state_dims
            and snapshot.reading is not None
        ):
            self.write_state(step, t, qpos, qvel, act)
            self.write_sensors(snapshot)
            self.write_signals(t, signals)
            self.write_inputs(step, ctrl, xfrc, t)
            return
        if t != self._last_t:
            self._set_time(TOPIC_STATE, t)
        # The rows filled in line: this runs at up to 2 kHz.
        a, b = self._state_split
        row = state.rows[i]
        row[0] = step
        row[1] = t
        row[2:a] = qpos
        row[a:b] = qvel
        if len(act):
            row[b:] = act
        row = sensors.rows[i]
        row[0] = t
        row[1:] = snapshot.reading
        row = logged.rows[i]
        row[0] = t
        if type(values) is tuple:  # a few plain numbers: one by one is faster than a slice
            for k, value in enumerate(values, 1):
                row[k] = value
        else:
            row[1:] = values
        inputs = self._input_rows
        j = inputs.n
        row = inputs.rows[j]
        row[0] = step
        row[1:] = ctrl
        stamp = self._last_stamp
        state.stamps[i] = sensors.stamps[i] = logged.stamps[i] = inputs.stamps[j] = stamp
        state.n = sensors.n = logged.n = i + 1
        inputs.n = j + 1
        if i + 1 == self._batch_rows or j + 1 == self._batch_rows:
            self._flush_batches()

    def encode_ctrl(self, ctrl: np.ndarray) -> np.ndarray:
        """A float64 ``ctrl`` vector checked once per control tick, to pass to
        :meth:`write_inputs` for every physics step it is held.

        Raises:
            ValueError: wrong size, or NaN/infinity (or a magnitude above 1e154).
        """
        if len(ctrl) != self._dims["ctrl"]:
            raise ValueError(
                f"{TOPIC_INPUTS} ctrl has {len(ctrl)} entries, the scene has {self._dims['ctrl']}"
            )
        # One BLAS call: any NaN or infinity (or |x| > 1e154, never a command) makes it so.
        if not math.isfinite(ctrl.dot(ctrl)):
            _raise_nonfinite(TOPIC_INPUTS, {"ctrl": ctrl}, 0.0, ValueError("non-finite ctrl"))
        return ctrl

    def write_inputs(
        self, step: int, ctrl: np.ndarray, xfrc: Mapping[str, np.ndarray], t: float
    ) -> None:
        """One ``/sim/inputs`` message; ``ctrl`` comes from :meth:`encode_ctrl`."""
        if t != self._last_t:
            self._set_time(TOPIC_INPUTS, t)
        batch = self._input_rows
        i = batch.n
        row = batch.rows[i]
        row[0] = step
        row[1:] = ctrl
        batch.stamps[i] = self._last_stamp
        if xfrc:
            self._check_xfrc(xfrc)
            if batch.extras is None:
                batch.extras = [b""] * self._batch_rows
            batch.extras[i] = self._xfrc.encode(xfrc)
        batch.n = i + 1
        if i + 1 == self._batch_rows:
            self._flush_batches()

    def _flush_batches(self) -> None:
        """Writes every channel's gathered rows and closes the chunk: a chunk holds the
        messages of one stretch of time, each channel's in order."""
        for batch in self._batches:
            batch.flush()
        if self._contact_rows is not None:
            self._contact_rows.flush()
        self._writer.flush_chunk()

    def write_frames(self, t: float, xpos: np.ndarray, xquat: np.ndarray) -> None:
        """One ``/frames`` message: every body's pose from MuJoCo's ``xpos`` and ``xquat``."""
        if t != self._last_t:
            self._set_time(TOPIC_FRAMES, t)
        stamp = self._last_stamp
        self._channels[TOPIC_FRAMES].append(stamp, self._frames.encode(stamp, xpos, xquat))

    @staticmethod
    def _encode_checked(
        topic: str, message: Any, encode: Callable[[Any], bytes], t: float
    ) -> bytes:
        """``encode(message)``, naming the first non-finite number if there is one."""
        try:
            return encode(message)
        except ValueError as exc:
            _raise_nonfinite(topic, message, t, exc)

    def _set_time(self, topic: str, t: float) -> None:
        """Makes ``t`` the time of the messages that follow; a tick's messages share one time,
        so this runs once per tick. Also refuses a closed log (``close()`` resets the time)."""
        if self._closed:
            raise ValueError(f"cannot write to {topic!r}: log {self.path} is closed")
        if not 0.0 <= t < math.inf:  # also false for NaN
            raise ValueError(f"{topic} message time t={t!r} must be finite and >= 0 [s]")
        self._last_t, self._last_stamp = t, self.log_time_origin + _ns(t)

    def _check_sizes(self, topic: str, message: Mapping[str, Any]) -> None:
        """Vector sizes and body names of the replay-critical topics, so ``verify`` can work."""
        for key in ("qpos", "qvel", "act") if topic == TOPIC_STATE else ("ctrl",):
            if len(message[key]) != self._dims[key]:
                raise ValueError(
                    f"{topic} {key} has {len(message[key])} entries, the scene has "
                    f"{self._dims[key]}"
                )
        if topic == TOPIC_INPUTS:
            self._check_xfrc(message["xfrc"])

    def _check_xfrc(self, xfrc: Mapping[str, Any]) -> None:
        """``xfrc`` names bodies of the scene, with a 6-vector each."""
        for body, wrench in xfrc.items():
            if body not in self._bodies:
                raise UnknownNameError("body", body, filter(None, self._bodies), TOPIC_INPUTS)
            if len(wrench) != 6:
                raise ValueError(f"{TOPIC_INPUTS} xfrc[{body!r}] must have 6 entries")

    def close(self, outcome: str, extra: Mapping[str, str] | None = None) -> None:
        """Writes the ``walkrepro`` metadata record and finishes the file. Idempotent.

        Args:
            outcome: one of :data:`OUTCOMES`.
            extra: further string → string metadata (e.g. ``fall_time``, ``error``).

        Raises:
            ValueError: unknown outcome, or an ``outcome`` key in ``extra``.
            TypeError: non-string keys or values in ``extra``.
        """
        if self._closed:
            return
        if outcome not in OUTCOMES:
            raise ValueError(f"unknown outcome {outcome!r}. Valid outcomes: {', '.join(OUTCOMES)}.")
        extra = dict(extra or {})
        if "outcome" in extra:
            raise ValueError("give the outcome as close()'s first argument, not in extra")
        _check_strings(extra, "extra metadata")
        record = {**self._metadata, **extra, "outcome": outcome}
        self._closed = True
        self._last_t = math.nan  # the next write goes through _set_time, which refuses it
        try:
            self._flush_batches()
            self._writer.add_metadata(METADATA_NAME, record)
            self._writer.finish()
        finally:
            try:
                self._writer.shutdown()  # the background thread's last chunk, if still writing
            finally:
                self._file.close()

    def __enter__(self) -> LogWriter:  # noqa: PYI034 - Self needs Python 3.11
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._closed:
            return
        if exc is None:
            self.close("complete")
        else:
            outcome = "interrupted" if isinstance(exc, KeyboardInterrupt) else "error"
            self.close(outcome, {"error": f"{type(exc).__name__}: {exc}"})


def _check_strings(values: Mapping[str, Any], what: str) -> None:
    for key, value in values.items():
        if not isinstance(key, str) or not isinstance(value, str):
            raise TypeError(f"{what} must map str to str; got {key!r}: {value!r}")


def _package_version(name: str) -> str:
    try:
        return importlib_metadata.version(name)
    except importlib_metadata.PackageNotFoundError:
        return "not installed"


def _base_metadata(given: Mapping[str, str]) -> dict[str, str]:
    """The caller's metadata, with versions and start time filled in where not given."""
    given = dict(given)
    _check_strings(given, "metadata")
    if "outcome" in given:
        raise ValueError("metadata must not hold 'outcome': LogWriter.close() writes it")
    missing = [key for key in REQUIRED_METADATA if key not in given]
    if missing:
        raise ValueError(f"metadata lacks key(s): {', '.join(missing)}")
    defaults = {
        "version": __version__,
        "mujoco_version": mujoco.__version__,
        "pinocchio_version": _package_version("pin"),
        "start_time": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
    return {**defaults, **given}


#: A topic's messages as read: (decoder, raw messages) per channel, in channel order.
_Segments = list[tuple[Callable[[bytes], Any], list[bytes]]]


@dataclass(frozen=True)
class Log:
    """A log read back from disk.

    Attributes:
        path: the MCAP file.
        scene_xml: the ``scene.xml`` attachment.
        spec_yaml: the ``spec.yaml`` attachment.
        metadata: the ``walkrepro`` metadata record; for a log whose writer never closed it,
            only ``{"outcome": OUTCOME_NOT_CLOSED}``.
        truncated: whether the file ended (or was damaged) before its MCAP footer.
        damage: why the log is not whole, one sentence (``""`` when it is): cut short
            (``truncated`` and no summary), or damaged (a record that fails its checksum or
            does not parse, before the footer or in the summary).
        summary: the MCAP summary from the end of the file, when whole (it survives damage
            before it, and says how many messages the file held).
    """

    path: Path
    scene_xml: str
    spec_yaml: str
    metadata: dict[str, str]
    truncated: bool = False
    damage: str = ""
    summary: McapSummary | None = None
    _raw: Mapping[str, _Segments] = field(default_factory=dict, repr=False, compare=False)

    @property
    def log_format(self) -> str:
        """The log format version (``"1"`` for logs that do not say)."""
        return self.metadata.get("log_format", "1")

    def messages(self, topic: str) -> list[dict[str, Any]]:
        """The decoded messages of ``topic`` in file order (decoded anew on each call), in
        the shapes of the README's log contract.

        Raises:
            UnknownNameError: ``topic`` is neither a contract topic nor in this log.
        """
        segments = self._raw.get(topic)
        if segments is None:
            if topic in TOPICS:
                return []
            raise UnknownNameError("topic", topic, set(TOPICS) | set(self._raw), str(self.path))
        out: list[dict[str, Any]] = []
        for decode, raw in segments:
            descriptor = getattr(decode, "descriptor", None)
            rows = protolog.flat_messages(raw, descriptor) if descriptor is not None else None
            out += rows if rows is not None else [decode(data) for data in raw]
        return out

    def arrays(self, topic: str, fields: Collection[str] | None = None) -> dict[str, np.ndarray]:
        """The messages of a topic of numbers and fixed-size float vectors (``/sim/state``,
        ``/sensors``) as arrays, one row per message in file order: e.g. ``t`` (N,),
        ``qpos`` (N, nq). A protobuf topic is read at numpy speed (≈ 10x faster than
        :meth:`messages`); other topics are stacked from :meth:`messages`. Fields that are
        not provided (None) are left out; an empty topic gives ``{}``.

        Args:
            topic: the topic.
            fields: only these fields (None: all), e.g. ``("step", "ctrl")`` of
                ``/sim/inputs``, whose ``xfrc`` is a map.

        Raises:
            UnknownNameError: as :meth:`messages`.
            ValueError: a field asked for is not a number or a fixed-size vector.
        """
        segments = self._raw.get(topic)
        if segments is None:
            self.messages(topic)  # raises for an unknown topic
            return {}
        parts = []
        for decode, raw in segments:
            if not raw:
                continue
            descriptor = getattr(decode, "descriptor", None)
            got = protolog.flat_arrays(raw, descriptor) if descriptor is not None else None
            parts.append(got if got is not None else _stack([decode(d) for d in raw], fields))
        if not parts:
            return {}
        keys = [k for k in parts[0] if fields is None or k in fields]
        return {key: np.concatenate([part[key] for part in parts]) for key in keys}

    def count(self, topic: str) -> int:
        """Number of messages of ``topic`` (0 if none)."""
        return sum(len(raw) for _, raw in self._raw.get(topic, ()))

    def logged_count(self, topic: str) -> int | None:
        """Messages of ``topic`` that the file's summary says were written; None when the
        summary is gone (a truncated file) or lists no such topic."""
        return self.summary.count(topic) if self.summary is not None else None

    def topics(self) -> list[str]:
        """Topics with at least one message, in channel order."""
        return [topic for topic, segments in self._raw.items() if any(r for _, r in segments)]


def _stack(
    messages: list[dict[str, Any]], fields: Collection[str] | None = None
) -> dict[str, np.ndarray]:
    """Messages' numbers and vectors as arrays (only ``fields`` if given), None fields left
    out."""
    out = {}
    for key, value in messages[0].items():
        if value is None or (fields is not None and key not in fields):
            continue
        try:
            values = np.array([message[key] for message in messages])
        except (ValueError, TypeError):
            values = None
        if values is None or values.dtype.kind not in "biuf":
            raise ValueError(f"field {key!r} is not a number or a fixed-size vector")
        out[key] = values.astype(float) if values.dtype.kind == "f" else values
    return out


def read_log(path: Path, check_indexes: bool = False) -> Log:
    """Reads a log (format 2 or 1), including one truncated by a killed writer.

    Whatever keeps the file from being whole is in :attr:`Log.damage`: a cut, a chunk or an
    attachment that fails its checksum, a summary that fails its CRC, schema or channel
    records that differ from their copies in the summary (the summary's are then used).

    Args:
        path: the MCAP file.
        check_indexes: also check the message index records (see
            :func:`walkrepro.log.mcapfile.read_mcap`); ``walkrepro verify`` does.

    Returns:
        The log; every complete chunk before any damage is kept.

    Raises:
        WalkreproError: the file is missing, not an MCAP file, or lacks the attachments.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise WalkreproError(f"cannot read log {path}: {exc.strerror}") from exc
    try:
        contents = read_mcap(data, check_indexes)
    except ValueError:
        raise WalkreproError(f"{path} is not an MCAP log (it lacks the MCAP magic bytes)") from None
    summary = read_summary(data)
    damage, schemas, channels = _records(contents, summary)
    raw = _segments(path, contents, schemas, channels, damage)
    try:
        attachments = {a.name: a.data.decode() for a in contents.attachments}
    except UnicodeDecodeError:
        raise WalkreproError(
            f"{path} is {damage or 'damaged'}: an attachment is not UTF-8 text"
        ) from None
    metadata = next((dict(m.metadata) for m in contents.metadata if m.name == METADATA_NAME), None)
    closed = contents.closed
    missing = [name for name in (SCENE_ATTACHMENT, SPEC_ATTACHMENT) if name not in attachments]
    if missing:
        raise WalkreproError(
            f"{path} is {damage}; without its {' and '.join(missing)} attachment(s), "
            "nothing in it can be replayed or measured"
            if damage
            else f"{path} is not a walkrepro log: it has no {' or '.join(missing)} attachment"
        )
    return Log(
        path=path,
        scene_xml=attachments[SCENE_ATTACHMENT],
        spec_yaml=attachments[SPEC_ATTACHMENT],
        metadata=metadata if metadata is not None else {"outcome": OUTCOME_NOT_CLOSED},
        truncated=not closed,
        damage=damage,
        summary=summary,
        _raw=raw,
    )


def _records(contents: Any, summary: McapSummary | None) -> tuple[str, dict, dict]:
    """The log's damage (see :attr:`Log.damage`), its schemas and its channels by id: the
    summary's copies where it has them (they are under its CRC; those at the start of the
    file are not), a difference between the two being damage."""
    damage = _damage(contents, summary)
    schemas, channels = contents.schemas, contents.channels
    if summary is not None and summary.channels:
        differ = [
            f"schema {i}" for i, x in summary.schemas.items() if schemas.get(i) not in (None, x)
        ] + [
            f"channel {x.topic}"
            for i, x in summary.channels.items()
            if channels.get(i) not in (None, x)
        ]
        if differ and not damage:
            damage = (
                f"damaged: its {', '.join(differ)} record(s) differ from the copies in its summary"
            )
        schemas, channels = {**schemas, **summary.schemas}, {**channels, **summary.channels}
    return damage, schemas, channels


def _segments(
    path: Path, contents: Any, schemas: dict, channels: dict, damage: str
) -> dict[str, _Segments]:
    """Each topic's messages with their decoder (JSON, or protobuf from the channel's
    schema), channel by channel in id order.

    Raises:
        WalkreproError: a channel's schema does not parse, or its encoding is neither.
    """
    raw: dict[str, _Segments] = {}
    decoders: dict[int, Callable[[bytes], Any]] = {}
    for channel_id, channel in sorted(channels.items()):
        messages = contents.messages.get(channel_id, [])
        schema = schemas.get(channel.schema_id)
        if channel.message_encoding == "json":
            decode = _decode_json
        elif channel.message_encoding == "protobuf" and schema is not None:
            if schema.id not in decoders:
                try:
                    decoders[schema.id] = protolog.dict_decoder(schema.data, schema.name)
                except Exception as exc:  # noqa: BLE001 - protobuf raises several kinds
                    raise WalkreproError(
                        f"{path} is {damage or 'damaged'}: the schema {schema.name!r} of "
                        f"channel {channel.topic} does not parse ({type(exc).__name__})"
                    ) from None
            decode = decoders[schema.id]
        else:
            raise WalkreproError(
                f"{path}: channel {channel.topic} has message encoding "
                f"{channel.message_encoding!r} (schema {schema.name if schema else 'none'}); "
                "walkrepro reads json and protobuf"
            )
        raw.setdefault(channel.topic, []).append((decode, messages))
    return raw


def _damage(contents: Any, summary: McapSummary | None) -> str:
    """Why a read MCAP file is not whole (``""`` if it is); see :attr:`Log.damage`."""
    size, stopped = contents.size, contents.stopped_at
    if contents.closed:
        if summary is None:
            return "damaged: its summary section or footer fails its CRC or does not parse"
        return ""
    if summary is None:
        return (
            f"truncated: it ends at byte {size} without its summary and footer (whole "
            f"records up to byte {stopped})"
        )
    return (
        f"damaged at byte {stopped} of {size}: the record there fails its checksum or does "
        "not parse, and nothing after it could be read"
    )
