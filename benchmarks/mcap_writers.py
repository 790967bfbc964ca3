"""Per-tick cost of writing a walkrepro log with walkrepro's MCAP writer and with the Foxglove
SDK's, measured in one process, with the writers taking turns.

Each log given is read back (schemas, channels, attachments, metadata, and every message with
its channel, log time and encoded bytes, chunk by chunk, with the ``mcap`` package's stream
reader). Then the same messages are written to a new file by each writer:

- ``mcapfile``: :class:`walkrepro.log.mcapfile.McapFile` used the way ``LogWriter`` uses it: a
  batched topic's consecutive messages in one ``ChannelWriter.append_rows`` call (a uint8
  array, one row per message, with any extra bytes of a row; copied into the chunk on the
  file's background thread when the chunk closes, with the compression and the writes),
  the other topics one
  ``ChannelWriter.append`` per message, the chunk closed where the log's chunk closes
  (zstd level -3 with its frame checksum, no chunk CRC);
- ``mcapfile zstd 1``: the same at zstd level 1 (the SDK accepts no negative level);
- ``sdk``: ``foxglove.open_mcap`` with one ``foxglove.Channel`` per channel (same topic,
  schema name, encoding and data, same message encoding) and one ``Channel.log(data,
  log_time=...)`` per message; zstd level 1 on the calling thread, no chunk or data-section
  CRC, the chunk closed (``MCAPWriter.flush``) where the log's chunk closes;
- ``sdk base.log``: the same through ``Channel.base.log`` (the Rust channel's ``log``),
  skipping ``Channel.log``'s Python checks of each message: the SDK's floor per message;
- ``sdk + split``: the same, fed from ``mcapfile``'s batch arrays, each row turned into a
  ``bytes`` object first (``Channel.log`` takes ``bytes``, one message per call): what
  ``LogWriter`` would pay with the SDK in place of ``mcapfile``;
- ``sdk defaults``: ``open_mcap`` with its default options (zstd at the library's default
  level, compression on the SDK's worker threads, 1 MiB chunks, chunk and data-section CRCs).

Each timed write runs from opening the file to closing it (attachments, schemas, channels,
messages, metadata, summary). The writers take turns (one round: each writer once), after
one untimed round; per writer, the median and the minimum over the rounds are reported, as
wall time and as process CPU time (all threads) per control tick (a control tick: one
``/controller/signals`` message). Each writer's file is checked once: ``read_log`` reads it
whole and every topic holds the same messages (log time and bytes, in order) as the log.

Usage::

    python benchmarks/mcap_writers.py LOG.mcap [LOG.mcap ...] [--rounds 7]
        [--bench BENCH.json]

``--bench`` takes a ``walkrepro bench --json`` file and sets each writer's extra cost
against the logging stage of the same experiment.
"""

from __future__ import annotations

import argparse
import gc
import importlib.metadata
import json
import statistics
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from foxglove.mcap import MCAPCompression, MCAPWriteOptions
from mcap.reader import make_reader
from mcap.records import Attachment, Channel, Message, MessageIndex, Metadata, Schema
from mcap.stream_reader import StreamReader

import foxglove
import walkrepro
from walkrepro.log import mcapfile
from walkrepro.log.mcapfile import McapFile
from walkrepro.log.record import (
    DEFAULT_CHUNK_SIZE,
    TOPIC_CONTACTS,
    TOPIC_INPUTS,
    TOPIC_SENSORS,
    TOPIC_SIGNALS,
    TOPIC_STATE,
    read_log,
)

#: Topics that ``LogWriter`` gathers as rows and writes a batch at a time.
BATCHED = frozenset({TOPIC_STATE, TOPIC_INPUTS, TOPIC_CONTACTS, TOPIC_SENSORS, TOPIC_SIGNALS})
#: zstd level of the SDK's matched configuration: its nearest to mcapfile's -3 (the SDK's
#: ``compression_level`` is unsigned, and 0 means the library's default, 3).
SDK_ZSTD_LEVEL = 1


@dataclass(frozen=True)
class Recording:
    """A log's records, as a writer needs them.

    Attributes:
        path: the log.
        experiment: the ``experiment`` key of its ``walkrepro`` metadata.
        ticks: control ticks (``/controller/signals`` messages).
        schemas: schema records, in file order.
        channels: channel records, in file order.
        attachments: attachment records, in file order.
        metadata: metadata records, in file order.
        chunks: each chunk's messages, in file order.
    """

    path: Path
    experiment: str
    ticks: int
    schemas: list[Schema]
    channels: list[Channel]
    attachments: list[Attachment]
    metadata: list[Metadata]
    chunks: list[list[Message]]

    @property
    def messages(self) -> int:
        return sum(map(len, self.chunks))


def read_recording(path: Path) -> Recording:
    """Reads a log's records; a message index after a message ends that message's chunk."""
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    attachments: list[Attachment] = []
    metadata: list[Metadata] = []
    chunks: list[list[Message]] = []
    current: list[Message] = []
    with open(path, "rb") as stream:
        for record in StreamReader(stream).records:
            if isinstance(record, Message):
                current.append(record)
            elif isinstance(record, MessageIndex):
                if current:
                    chunks.append(current)
                    current = []
            elif isinstance(record, Schema):
                schemas.setdefault(record.id, record)
            elif isinstance(record, Channel):
                channels.setdefault(record.id, record)
            elif isinstance(record, Attachment):
                attachments.append(record)
            elif isinstance(record, Metadata):
                metadata.append(record)
    if current:
        chunks.append(current)
    topic_of = {c.id: c.topic for c in channels.values()}
    ticks = sum(topic_of[m.channel_id] == TOPIC_SIGNALS for chunk in chunks for m in chunk)
    experiment = next(
        (m.metadata.get("experiment", "") for m in metadata if m.name == "walkrepro"), ""
    )
    return Recording(
        path=path,
        experiment=experiment,
        ticks=ticks,
        schemas=[schemas[i] for i in sorted(schemas)],
        channels=[channels[i] for i in sorted(channels)],
        attachments=attachments,
        metadata=metadata,
        chunks=chunks,
    )


# --------------------------------------------------------------------------- write plans
# A writer's input is built before the clock starts: the batch arrays are what LogWriter's
# encoders hand mcapfile in a run; the per-message bytes are what the SDK's Channel.log takes
# (``sdk + split`` times making them from the batch arrays).


@dataclass(frozen=True)
class Rows:
    """One ``append_rows`` call: channel index, stamps (int64, (n,)), payloads (uint8,
    (n, size)) and the bytes after each row (None: none)."""

    channel: int
    stamps: np.ndarray
    payloads: np.ndarray
    extras: list[bytes] | None


@dataclass(frozen=True)
class One:
    """One ``append`` call: channel index, stamp [ns], data."""

    channel: int
    stamp: int
    data: bytes


def batch_plan(recording: Recording) -> list[list[Rows | One]]:
    """Each chunk's writer calls as ``LogWriter`` makes them: a batched topic's consecutive
    messages in one :class:`Rows` (the extras path where their lengths differ, split at the
    shortest), every other message one :class:`One`."""
    index = {c.id: i for i, c in enumerate(recording.channels)}
    batched = {c.id for c in recording.channels if c.topic in BATCHED}
    plan: list[list[Rows | One]] = []
    for chunk in recording.chunks:
        calls: list[Rows | One] = []
        run: list[Message] = []
        for message in [*chunk, None]:
            if run and (message is None or message.channel_id != run[0].channel_id):
                calls.append(_rows(index[run[0].channel_id], run))
                run = []
            if message is None:
                break
            if message.channel_id in batched:
                run.append(message)
            else:
                calls.append(One(index[message.channel_id], message.log_time, message.data))
        plan.append(calls)
    return plan


def _rows(channel: int, run: list[Message]) -> Rows:
    stamps = np.array([m.log_time for m in run], dtype=np.int64)
    size = min(len(m.data) for m in run)
    payloads = np.frombuffer(b"".join(m.data[:size] for m in run), np.uint8).reshape(len(run), -1)
    extras = [m.data[size:] for m in run]
    return Rows(channel, stamps, payloads, extras if any(extras) else None)


def message_plan(recording: Recording) -> list[list[tuple[int, bytes, int]]]:
    """Each chunk's messages as (channel index, data, log time)."""
    index = {c.id: i for i, c in enumerate(recording.channels)}
    return [
        [(index[m.channel_id], m.data, m.log_time) for m in chunk] for chunk in recording.chunks
    ]


# --------------------------------------------------------------------------- the writers


def write_mcapfile(recording: Recording, plan: list[list[Rows | One]], path: Path) -> None:
    """``McapFile`` as ``LogWriter`` drives it: attachments, schemas and channels, then each
    chunk's calls and the chunk closed, then the metadata and the summary."""
    with open(path, "wb") as stream:
        writer = McapFile(stream, DEFAULT_CHUNK_SIZE, library=f"walkrepro/{walkrepro.__version__}")
        for a in recording.attachments:
            writer.add_attachment(a.create_time, a.log_time, a.name, a.media_type, a.data)
        schema_ids = {
            s.id: writer.add_schema(s.name, s.encoding, s.data) for s in recording.schemas
        }
        channels = [
            writer.channel_writer(
                writer.add_channel(c.topic, c.message_encoding, schema_ids[c.schema_id])
            )
            for c in recording.channels
        ]
        for calls in plan:
            for call in calls:
                if type(call) is Rows:
                    payloads = call.payloads
                    channels[call.channel].append_rows(
                        call.stamps, payloads.shape[1], lambda p=payloads: p, call.extras
                    )
                else:
                    channels[call.channel].append(call.stamp, call.data)
            writer.flush_chunk()
        for m in recording.metadata:
            writer.add_metadata(m.name, m.metadata)
        writer.finish()


def write_mcapfile_zstd1(recording: Recording, plan: list[list[Rows | One]], path: Path) -> None:
    """:func:`write_mcapfile` with the chunks at zstd level 1 (set for this call only)."""
    level = mcapfile.ZSTD_LEVEL
    mcapfile.ZSTD_LEVEL = SDK_ZSTD_LEVEL  # read once, by McapFile.__init__
    try:
        write_mcapfile(recording, plan, path)
    finally:
        mcapfile.ZSTD_LEVEL = level


def sdk_matched_options() -> MCAPWriteOptions:
    """The SDK's options closest to ``mcapfile``'s file: zstd on the calling thread at
    :data:`SDK_ZSTD_LEVEL`, no automatic chunk closing (the caller closes each chunk), no
    chunk or data-section CRC."""
    return MCAPWriteOptions(
        compression=MCAPCompression.Zstd,
        compression_level=SDK_ZSTD_LEVEL,
        compression_threads=0,
        chunk_size=None,
        calculate_chunk_crcs=False,
        calculate_data_section_crc=False,
    )


class _SdkFile:
    """An SDK MCAP writer on its own context, with one channel per recording channel."""

    def __init__(self, recording: Recording, path: Path, options: MCAPWriteOptions) -> None:
        self.context = foxglove.Context()
        self.writer = foxglove.open_mcap(
            path, allow_overwrite=True, context=self.context, writer_options=options
        )
        for a in recording.attachments:
            self.writer.attach(
                log_time=a.log_time,
                create_time=a.create_time,
                name=a.name,
                media_type=a.media_type,
                data=a.data,
            )
        schemas = {s.id: s for s in recording.schemas}
        self.channels = []
        for c in recording.channels:
            s = schemas[c.schema_id]
            schema = foxglove.Schema(name=s.name, encoding=s.encoding, data=s.data)
            self.channels.append(
                foxglove.Channel(
                    c.topic,
                    schema=schema,
                    message_encoding=c.message_encoding,
                    context=self.context,
                )
            )
        self.logs = [channel.log for channel in self.channels]
        #: The Rust channels' own ``log(data, log_time, sink_id)``, under ``Channel.log``.
        self.base_logs = [channel.base.log for channel in self.channels]

    def close(self, recording: Recording) -> None:
        for m in recording.metadata:
            self.writer.write_metadata(m.name, m.metadata)
        self.writer.close()
        for channel in self.channels:
            channel.close()


def write_sdk(
    recording: Recording,
    plan: list[list[tuple[int, bytes, int]]],
    path: Path,
    options: MCAPWriteOptions | None = None,
) -> None:
    """The SDK writer, one ``Channel.log`` per message; with the matched options, each chunk
    closed where the log's closes."""
    matched = options is None
    sdk = _SdkFile(recording, path, sdk_matched_options() if matched else options)
    logs = sdk.logs
    for messages in plan:
        for channel, data, stamp in messages:
            logs[channel](data, log_time=stamp)
        if matched:
            sdk.writer.flush()
    sdk.close(recording)


def write_sdk_base(
    recording: Recording, plan: list[list[tuple[int, bytes, int]]], path: Path
) -> None:
    """:func:`write_sdk` (matched options) through the Rust channel's ``log`` directly,
    without ``Channel.log``'s Python checks: the SDK's own cost per message."""
    sdk = _SdkFile(recording, path, sdk_matched_options())
    logs = sdk.base_logs
    for messages in plan:
        for channel, data, stamp in messages:
            logs[channel](data, stamp, None)
        sdk.writer.flush()
    sdk.close(recording)


def write_sdk_split(recording: Recording, plan: list[list[Rows | One]], path: Path) -> None:
    """The SDK writer (matched options) fed ``LogWriter``'s batch arrays: each row becomes
    one ``bytes`` message (with its extra bytes) before it is logged."""
    sdk = _SdkFile(recording, path, sdk_matched_options())
    logs = sdk.logs
    for calls in plan:
        for call in calls:
            if type(call) is Rows:
                log = logs[call.channel]
                stamps = call.stamps.tolist()
                if call.extras is None:
                    for row, stamp in zip(call.payloads, stamps, strict=True):
                        log(row.tobytes(), log_time=stamp)
                else:
                    for row, extra, stamp in zip(call.payloads, call.extras, stamps, strict=True):
                        log(row.tobytes() + extra, log_time=stamp)
            else:
                logs[call.channel](call.data, log_time=call.stamp)
        sdk.writer.flush()
    sdk.close(recording)


def write_sdk_defaults(
    recording: Recording, plan: list[list[tuple[int, bytes, int]]], path: Path
) -> None:
    """The SDK writer with its default options (it closes chunks itself, at 1 MiB); ``plan``
    holds every message as one list."""
    write_sdk(recording, plan, path, MCAPWriteOptions())


# --------------------------------------------------------------------------- measuring


@dataclass
class Writer:
    """A writer under test and its times per round [s]."""

    name: str
    write: Callable[[Path], None]
    wall: list[float]
    cpu: list[float]
    size: int = 0


def check(recording: Recording, path: Path) -> str:
    """Reads a written file back; returns what differs from the recording ("" if nothing).

    ``read_log`` must read it whole, with every topic's message count, and the ``mcap``
    package's reader every topic's messages (log time and bytes, in file order).
    """
    problems = []
    log = read_log(path, check_indexes=True)
    if log.damage:
        problems.append(f"read_log: {log.damage}")
    topic_of = {c.id: c.topic for c in recording.channels}
    expected: dict[str, list[tuple[int, bytes]]] = {}
    for chunk in recording.chunks:
        for m in chunk:
            expected.setdefault(topic_of[m.channel_id], []).append((m.log_time, m.data))
    for topic, messages in expected.items():
        if log.count(topic) != len(messages):
            problems.append(f"read_log: {topic} has {log.count(topic)}, not {len(messages)}")
    got: dict[str, list[tuple[int, bytes]]] = {}
    with open(path, "rb") as stream:
        for _, channel, message in make_reader(stream).iter_messages(log_time_order=False):
            got.setdefault(channel.topic, []).append((message.log_time, message.data))
    for topic in expected.keys() | got.keys():
        if got.get(topic) != expected.get(topic):
            problems.append(f"mcap reader: {topic} messages differ")
    return "; ".join(problems)


def sequence_start(path: Path) -> int:
    """The sequence number of a file's first message."""
    with open(path, "rb") as stream:
        for _, _, message in make_reader(stream).iter_messages(log_time_order=False):
            return message.sequence
    return -1


def measure(recording: Recording, rounds: int, folder: Path) -> list[Writer]:
    """Times every writer ``rounds`` times, taking turns, after one untimed round."""
    batches = batch_plan(recording)
    messages = message_plan(recording)
    flat = [[m for chunk in messages for m in chunk]]
    writers = [
        Writer("mcapfile", lambda p: write_mcapfile(recording, batches, p), [], []),
        Writer("mcapfile zstd 1", lambda p: write_mcapfile_zstd1(recording, batches, p), [], []),
        Writer("sdk", lambda p: write_sdk(recording, messages, p), [], []),
        Writer("sdk base.log", lambda p: write_sdk_base(recording, messages, p), [], []),
        Writer("sdk + split", lambda p: write_sdk_split(recording, batches, p), [], []),
        Writer("sdk defaults", lambda p: write_sdk_defaults(recording, flat, p), [], []),
    ]
    for i, writer in enumerate(writers):
        path = folder / f"{i}.mcap"
        writer.write(path)  # the untimed round; its file is the one checked
        problems = check(recording, path)
        if problems:
            raise SystemExit(f"{recording.path}: {writer.name}'s file: {problems}")
        writer.size = path.stat().st_size
        print(
            f"  {writer.name}: read back whole, same messages per topic "
            f"(first sequence number {sequence_start(path)}), {writer.size / 1e6:.1f} MB"
        )
        path.unlink()
    for _ in range(rounds):
        for i, writer in enumerate(writers):
            path = folder / f"{i}.mcap"
            gc.collect()
            wall, cpu = time.perf_counter(), time.process_time()
            writer.write(path)
            writer.wall.append(time.perf_counter() - wall)
            writer.cpu.append(time.process_time() - cpu)
            path.unlink()
    return writers


def logging_stage(bench: Path | None, experiment: str) -> float | None:
    """The logging stage of ``experiment`` in a ``walkrepro bench --json`` file [µs/tick]."""
    if bench is None:
        return None
    for result in json.loads(bench.read_text())["results"]:
        if result["experiment"] == experiment:
            return result["per_tick"]["logging"] * 1e6
    return None


def report(recording: Recording, writers: list[Writer], logging: float | None) -> None:
    us = 1e6 / recording.ticks
    base = writers[0]
    base_median = statistics.median(base.wall) * us
    print(
        f"\n{recording.experiment} ({recording.path}): {recording.ticks} control ticks, "
        f"{recording.messages} messages, {len(recording.chunks)} chunks"
    )
    head = "writer", "median", "min", "ratio median", "ratio min", "cpu median", "MB"
    print("{:<16} {:>8} {:>8} {:>12} {:>10} {:>10} {:>6}".format(*head))
    for writer in writers:
        median = statistics.median(writer.wall) * us
        low = min(writer.wall) * us
        print(
            f"{writer.name:<16} {median:8.2f} {low:8.2f} "
            f"{median / base_median:12.2f} {low / (min(base.wall) * us):10.2f} "
            f"{statistics.median(writer.cpu) * us:10.2f} {writer.size / 1e6:6.1f}"
        )
    print("(µs per control tick, wall time, over the rounds; ratios to mcapfile)")
    if logging is None:
        return
    print(f"logging stage (walkrepro bench): {logging:.1f} µs/tick; 10 % of it: {logging / 10:.2f}")
    for writer in writers[2:]:
        extra = statistics.median(writer.wall) * us - base_median
        verdict = "within" if extra <= logging / 10 else "over"
        print(
            f"  {writer.name}: {extra:+.2f} µs/tick against mcapfile (medians) = "
            f"{100 * extra / logging:+.0f} % of the logging stage: {verdict} 10 %"
        )


def foxglove_version() -> str:
    """The installed ``foxglove-sdk`` version."""
    return importlib.metadata.version("foxglove-sdk")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("logs", nargs="+", type=Path, help="walkrepro logs (log.mcap)")
    parser.add_argument("--rounds", type=int, default=7, help="timed rounds (default 7)")
    parser.add_argument("--bench", type=Path, help="a `walkrepro bench --json` file")
    args = parser.parse_args()
    print(f"foxglove-sdk {foxglove_version()}, walkrepro {walkrepro.__version__}")
    for path in args.logs:
        recording = read_recording(path)
        print(f"{recording.experiment}: writing {path} {args.rounds} + 1 times per writer")
        with tempfile.TemporaryDirectory(prefix="mcap-writers-") as folder:
            writers = measure(recording, args.rounds, Path(folder))
        report(recording, writers, logging_stage(args.bench, recording.experiment))


if __name__ == "__main__":
    main()
