"""The MCAP file under a run's log, written with messages packed in batches.

mcap's Python ``Writer`` spends about fifty interpreted calls on each message (record
builder, statistics, per-message index entries), and a run writes 5-8 messages per control
tick at 0.5-2 kHz. On forward_walk's format 2 messages (protobuf, ≈ 300 B each), with the
chunks' zstd included, mcap's ``Writer`` costs 4.0x this writer per message (9.4 vs 2.3 µs on
the shared 2-core VM; ≈ 35 µs more per 2 kHz control tick). This writer produces the same
kind of file (header, schemas, channels, attachments, zstd chunks each followed by its
message indexes, metadata, and a summary with schemas, channels, statistics and
chunk/attachment/metadata indexes, summary offsets and footer), using mcap's own record
classes for every record except the three that repeat: a message is one call of its
channel's :class:`ChannelWriter` (one ``struct.pack`` and two appends to the open chunk), or
one row of a batch of a channel's messages (:meth:`ChannelWriter.append_rows`), and a chunk
and its message indexes are packed when the chunk closes. Compression and its checksum
(zstd, XXH64, in place of MCAP's optional chunk CRC) run in C. mcap's readers read the
result; tests check that.

A closed chunk is encoded (its batches of rows made into message records), compressed and
written on one background thread, so the caller only fills the next chunk meanwhile: numpy's
large copies, zstd and the file writes release the GIL. A batch's size in bytes is known
before it is encoded, so its offsets and message index entries are computed when it is
queued. Every write to the file goes through that thread in order, or waits for it, so the
file's bytes are those of writing in line; an error there is raised by the writer's next
call. At most one closed chunk waits for the thread: a killed writer loses at most that
chunk and the open one.

Schemas and channels are written before the first message of their channel (all but one
before any chunk), so a log cut short still names its topics.

:func:`read_mcap` reads such a file back the same way: the few records that are not messages
with mcap's record classes, the messages of each chunk with one ``struct`` call each.
"""

from __future__ import annotations

import io
import struct
import zlib
from collections import defaultdict
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any, BinaryIO, NamedTuple

import numpy as np
import zstandard
from mcap.data_stream import ReadDataStream, RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

MAGIC = b"\x89MCAP0\r\n"
# Message record: opcode, record length, channel id, sequence, log time, publish time.
_MESSAGE = struct.Struct("<BQHIQQ")
_MESSAGE_FIXED = _MESSAGE.size - 9  # record length counts what follows opcode and length
_MESSAGE_OPCODE = int(Opcode.MESSAGE)
#: The same header as a numpy record (packed: 31 bytes), for batches of messages.
_MESSAGE_HEADS = np.dtype(
    [("opcode", "u1"), ("length", "<u8"), ("channel", "<u2"), ("sequence", "<u4"),
     ("log_time", "<u8"), ("publish_time", "<u8")]
)  # fmt: skip
_RECORD_HEAD = struct.Struct("<BQ")  # opcode, length of what follows
# Message index record up to its entries: opcode, length, channel id, length of the entries.
_INDEX_HEAD = struct.Struct("<BQHI")
_CHANNEL_ID = struct.Struct("<H")
_LOG_TIME = struct.Struct("<Q")
_LOG_TIME_AT = 6  # a message record's body: channel id (2 bytes), sequence (4), log time (8)
# Chunk record up to its records: opcode, length, start and end time, uncompressed size and
# CRC, compression (a 4-byte string: "zstd"), length of the records.
_CHUNK_HEAD = struct.Struct("<BQQQQII4sQ")
#: zstd level of the chunks: one of zstd's fast (negative) levels. The chunks hold float64
#: payloads, which barely compress at any level. Measured on a forward_walk chunk (0.88 MB of
#: format 2 records, signals binary): level 1 compresses 1.34x in 2.1 ms, -3 1.27x in 0.9 ms,
#: -7 1.20x; -3 keeps most of the gain at under half the cost (≈ 1.8 µs per 2 kHz tick, on
#: the background thread).
ZSTD_LEVEL = -3
#: Whether each chunk's zstd frame ends with a checksum of its records (XXH64, verified by
#: every zstd decompressor). It stands in for the chunk's CRC32, which MCAP makes optional
#: (0 = none): it costs ≈ 0.03 ms per MB of records where CRC32 costs 0.17-0.22.
ZSTD_CHECKSUM = True


class McapFile:
    """Writes one MCAP file; messages go into zstd chunks of about ``chunk_size`` bytes.

    Args:
        stream: binary output, positioned at its start.
        chunk_size: uncompressed bytes after which the open chunk is closed and written.
        library: the header's ``library`` string.
    """

    def __init__(self, stream: BinaryIO, chunk_size: int, library: str) -> None:
        self._out = stream
        self._chunk_size = chunk_size
        self._schemas: list[Schema] = []
        self._channels: list[Channel] = []
        self._attachment_indexes: list[AttachmentIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._chunk_indexes: list[ChunkIndex] = []
        self._stats = Statistics(
            attachment_count=0,
            channel_count=0,
            channel_message_counts=defaultdict(int),
            chunk_count=0,
            message_count=0,
            message_end_time=0,
            message_start_time=0,
            metadata_count=0,
            schema_count=0,
        )
        # The open chunk: its parts in order (records as bytes, and batches of rows still to
        # encode), its length [bytes], and each channel's message index entries in order
        # ((time, offset) pairs, and an (n, 2) array per batch).
        self._parts: list[bytearray | _Rows] = []
        self._chunk_length = 0
        self._index: dict[int, list[Any]] = {}
        self._compressor = zstandard.ZstdCompressor(
            compression_params=zstandard.ZstdCompressionParameters.from_level(
                ZSTD_LEVEL, write_checksum=ZSTD_CHECKSUM
            )
        )
        # The thread that compresses and writes closed chunks, and its last job (None: idle).
        self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="mcap-chunks")
        self._pending: Future[None] | None = None
        self._out.write(MAGIC)
        self._write(Header(profile="", library=library))

    def add_schema(self, name: str, encoding: str, data: bytes) -> int:
        """Registers a schema; returns its id."""
        schema = Schema(id=len(self._schemas) + 1, name=name, encoding=encoding, data=data)
        self._schemas.append(schema)
        self._stats.schema_count += 1
        self._write(schema)
        return schema.id

    def add_channel(self, topic: str, message_encoding: str, schema_id: int) -> int:
        """Registers a channel; returns its id."""
        channel = Channel(
            id=len(self._channels) + 1,
            topic=topic,
            message_encoding=message_encoding,
            schema_id=schema_id,
            metadata={},
        )
        self._channels.append(channel)
        self._index[channel.id] = []
        self._stats.channel_count += 1
        self._write(channel)
        return channel.id

    def channel_writer(self, channel_id: int) -> ChannelWriter:
        """The writer of the messages of channel ``channel_id`` (from :meth:`add_channel`)."""
        return ChannelWriter(self, channel_id)

    def add_attachment(
        self, create_time: int, log_time: int, name: str, media_type: str, data: bytes
    ) -> None:
        """Writes an attachment record (outside chunks) and indexes it; times in [ns]."""
        self.wait()
        offset = self._out.tell()
        length = self._write(
            Attachment(
                create_time=create_time,
                log_time=log_time,
                name=name,
                media_type=media_type,
                data=data,
            )
        )
        self._attachment_indexes.append(
            AttachmentIndex(
                offset=offset,
                length=length,
                log_time=log_time,
                create_time=create_time,
                data_size=len(data),
                name=name,
                media_type=media_type,
            )
        )
        self._stats.attachment_count += 1

    def add_metadata(self, name: str, metadata: dict[str, str]) -> None:
        """Writes a metadata record (after closing the open chunk) and indexes it."""
        self.flush_chunk()
        self.wait()
        offset = self._out.tell()
        length = self._write(Metadata(name=name, metadata=metadata))
        self._metadata_indexes.append(MetadataIndex(offset=offset, length=length, name=name))
        self._stats.metadata_count += 1

    def flush_chunk(self) -> None:
        """Closes the open chunk, if it has messages: it is encoded, compressed and written
        with its message indexes on the background thread (after the chunk before it)."""
        if not self._parts:
            return
        self.wait()  # one chunk at a time: the file's order, and bounded memory
        parts, self._parts = self._parts, []
        index, self._index = self._index, {channel_id: [] for channel_id in self._index}
        length, self._chunk_length = self._chunk_length, 0
        self._pending = self._worker.submit(self._write_chunk, parts, index, length)

    def wait(self) -> None:
        """Waits until the background thread has written every closed chunk; raises what
        it raised."""
        pending = self._pending
        if pending is None:
            return
        try:
            pending.result()
        finally:
            # Raised by the thread: once. Interrupted here (Ctrl-C): the job still runs, and
            # the next call waits for it again.
            if pending.done():
                self._pending = None

    def _write_chunk(
        self, parts: list[bytearray | _Rows], index: dict[int, list[Any]], length: int
    ) -> None:
        """Encodes, compresses and writes one chunk and its message indexes, indexes the
        chunk and counts its messages (on the background thread)."""
        raw = bytearray()
        for part in parts:
            raw += part if type(part) is bytearray else part.records()
        if len(raw) != length:  # the offsets in the indexes were computed for ``length``
            raise AssertionError(f"a chunk of {len(raw)} bytes, {length} expected")
        entries = {
            channel_id: np.concatenate([np.asarray(e, "<u8").reshape(-1, 2) for e in pieces])
            for channel_id, pieces in index.items()
            if pieces
        }
        start = min(int(pairs[:, 0].min()) for pairs in entries.values())
        end = max(int(pairs[:, 0].max()) for pairs in entries.values())
        compressed = self._compressor.compress(raw)
        out = self._out
        chunk_offset = out.tell()
        # The record as mcap's Chunk.write() lays it out, without copying the data twice.
        out.write(
            _CHUNK_HEAD.pack(
                Opcode.CHUNK,
                _CHUNK_HEAD.size - _RECORD_HEAD.size + len(compressed),
                start,
                end,
                len(raw),
                0,  # no CRC: the zstd frame's checksum guards the records (see ZSTD_CHECKSUM)
                len(b"zstd"),
                b"zstd",
                len(compressed),
            )
        )
        out.write(compressed)
        chunk_length = out.tell() - chunk_offset
        index_offsets: dict[int, int] = {}
        for channel_id, pairs in entries.items():
            index_offsets[channel_id] = out.tell()
            n = len(pairs)
            out.write(_INDEX_HEAD.pack(Opcode.MESSAGE_INDEX, 6 + 16 * n, channel_id, 16 * n))
            out.write(pairs.tobytes())
        self._chunk_indexes.append(
            ChunkIndex(
                message_start_time=start,
                message_end_time=end,
                chunk_start_offset=chunk_offset,
                chunk_length=chunk_length,
                message_index_offsets=index_offsets,
                message_index_length=out.tell() - chunk_offset - chunk_length,
                compression="zstd",
                compressed_size=len(compressed),
                uncompressed_size=len(raw),
            )
        )
        self._count(entries, start, end)

    def _count(self, entries: dict[int, np.ndarray], start: int, end: int) -> None:
        """Adds a chunk's messages and time span [ns] to the statistics."""
        stats = self._stats
        for channel_id, pairs in entries.items():
            stats.channel_message_counts[channel_id] += len(pairs)
            stats.message_count += len(pairs)
        if stats.chunk_count == 0:
            stats.message_start_time = start
        stats.message_start_time = min(stats.message_start_time, start)
        stats.message_end_time = max(stats.message_end_time, end)
        stats.chunk_count += 1

    def finish(self) -> None:
        """Closes the open chunk and writes the summary, footer and closing magic; stops the
        background thread."""
        try:
            self.flush_chunk()
            self.wait()
        finally:
            self.shutdown()
        self._write(DataEnd(data_section_crc=0))
        summary_start = self._out.tell()
        summary = RecordBuilder()
        offsets: list[SummaryOffset] = []
        groups: list[tuple[Opcode, list]] = [
            (Opcode.SCHEMA, self._schemas),
            (Opcode.CHANNEL, self._channels),
            (Opcode.STATISTICS, [self._stats]),
            (Opcode.CHUNK_INDEX, self._chunk_indexes),
            (Opcode.ATTACHMENT_INDEX, self._attachment_indexes),
            (Opcode.METADATA_INDEX, self._metadata_indexes),
        ]
        for opcode, records in groups:
            start = summary.count
            for record in records:
                record.write(summary)
            offsets.append(SummaryOffset(opcode, summary_start + start, summary.count - start))
        summary_offset_start = summary_start + summary.count
        for offset in offsets:
            offset.write(summary)
        data = summary.end()
        crc = zlib.crc32(data)
        crc = zlib.crc32(
            struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, summary_offset_start), crc
        )
        self._out.write(data)
        self._write(Footer(summary_start, summary_offset_start, crc))
        self._out.write(MAGIC)

    def shutdown(self) -> None:
        """Lets the background thread finish its chunk, then stops it (idempotent). A file
        left unfinished (an error while writing) keeps the chunks written so far."""
        try:
            self.wait()
        finally:
            self._worker.shutdown(wait=True)

    def _write(self, record: object) -> int:
        """Writes one record with mcap's own encoder (after the background thread's chunks);
        returns its length in bytes."""
        self.wait()
        builder = RecordBuilder()
        record.write(builder)  # type: ignore[attr-defined]
        data = builder.end()
        self._out.write(data)
        return len(data)


class ChannelWriter:
    """Appends one channel's messages to its file's open chunk, numbering them from 0.

    The per-message work of a log, in one call: the channel's message index entry, the record
    (a header packed with one ``struct`` call, then the data), and closing the chunk when full.
    """

    __slots__ = ("_chunk_size", "_file", "id", "sequence")

    def __init__(self, file: McapFile, channel_id: int) -> None:
        self.id = channel_id
        self.sequence = 0  #: the next message's sequence number
        self._file = file
        self._chunk_size = file._chunk_size

    def append(self, stamp: int, data: bytes) -> None:
        """Appends one message (log time = publish time = ``stamp`` [ns])."""
        file = self._file
        parts = file._parts
        if not parts or type(parts[-1]) is not bytearray:
            parts.append(bytearray())
        offset = file._chunk_length
        file._index[self.id].append((stamp, offset))
        sequence = self.sequence
        self.sequence = sequence + 1
        part = parts[-1]
        part += _MESSAGE.pack(
            _MESSAGE_OPCODE, _MESSAGE_FIXED + len(data), self.id, sequence, stamp, stamp
        )
        part += data
        file._chunk_length = offset + _MESSAGE.size + len(data)
        if file._chunk_length >= self._chunk_size:
            file.flush_chunk()

    def append_rows(
        self,
        stamps: np.ndarray,
        size: int,
        payloads: Callable[[], np.ndarray],
        extras: list[bytes] | None = None,
    ) -> None:
        """Appends a batch of ``n = len(stamps)`` messages stamped ``stamps`` (int64, (n,))
        [ns]: ``payloads()`` (uint8, shape (n, size)) row by row, each followed by its
        ``extras`` bytes if given.

        The same records as ``n`` calls of :meth:`append`. ``payloads`` is called, and
        ``stamps`` read, on the background thread when the chunk closes: until then neither
        may change. The chunk is not closed here: the caller closes it after the batches
        that belong together.
        """
        n = len(stamps)
        if n == 0:
            return
        file = self._file
        if extras is None or not any(extras):
            extras = None
            records = np.full(n, _MESSAGE.size + size, dtype=np.int64)
        else:
            records = _MESSAGE.size + size + np.fromiter(map(len, extras), np.int64, count=n)
        ends = file._chunk_length + np.cumsum(records)
        pairs = np.empty((n, 2), "<u8")
        pairs[:, 0] = stamps
        pairs[:, 1] = ends - records
        file._index[self.id].append(pairs)
        file._parts.append(_Rows(self.id, self.sequence, stamps, size, payloads, extras))
        file._chunk_length = int(ends[-1])
        self.sequence += n


class _Rows(NamedTuple):
    """A batch of one channel's messages queued in the open chunk, encoded when the chunk
    closes (see :meth:`ChannelWriter.append_rows`)."""

    channel_id: int
    sequence: int  #: the first message's sequence number
    stamps: np.ndarray
    size: int
    payloads: Callable[[], np.ndarray]
    extras: list[bytes] | None

    def records(self) -> bytes:
        """The batch's message records, as ``n`` calls of :meth:`ChannelWriter.append`
        write them: a header and a payload each (then its extra bytes)."""
        n, size, extras = len(self.stamps), self.size, self.extras
        head = _MESSAGE_HEADS.itemsize
        rows = np.empty((n, head + size), np.uint8)
        heads = np.ndarray(n, _MESSAGE_HEADS, rows, strides=(head + size,))  # views `rows`
        heads["opcode"] = _MESSAGE_OPCODE
        heads["channel"] = self.channel_id
        heads["sequence"] = np.arange(self.sequence, self.sequence + n)
        heads["log_time"] = self.stamps
        heads["publish_time"] = self.stamps
        rows[:, head:] = self.payloads()
        if extras is None:
            heads["length"] = _MESSAGE_FIXED + size
            return rows.tobytes()
        heads["length"] = _MESSAGE_FIXED + size + np.fromiter(map(len, extras), np.int64, count=n)
        return b"".join(
            part for row, extra in zip(rows, extras, strict=True) for part in (row, extra)
        )


@dataclass
class McapContents:
    """What :func:`read_mcap` found, in file order.

    Attributes:
        schemas: schema id → schema, from the records seen (in or outside chunks).
        channels: channel id → channel, from the records seen (in or outside chunks).
        messages: channel id → the data of each of its messages, in file order.
        attachments: every attachment record.
        metadata: every metadata record.
        closed: whether the footer was reached (the writer finished the file).
        stopped_at: byte offset of the record where reading stopped because the file ends
            or is damaged there (None when the footer was reached).
        size: the file's size [bytes].
    """

    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    messages: dict[int, list[bytes]] = field(default_factory=lambda: defaultdict(list))
    attachments: list[Attachment] = field(default_factory=list)
    metadata: list[Metadata] = field(default_factory=list)
    closed: bool = False
    stopped_at: int | None = None
    size: int = 0


class _Damaged(Exception):
    """The file ends or is damaged here; what was read before stands."""


def read_mcap(data: bytes, check_indexes: bool = False) -> McapContents:
    """Reads an MCAP file's records, stopping quietly at the first damaged or missing byte.

    Only the opening magic must be whole: a file cut short (no summary, footer or closing
    magic) keeps every record, and every chunk that passes its CRC, before the cut. A chunk
    is checked by its CRC or its zstd frame's checksum, an attachment by its CRC.

    Args:
        data: the file's bytes.
        check_indexes: also check that the message index records after each chunk are
            exactly what the chunk's messages give (they carry no checksum of their own;
            walkrepro's reader does not use them, other MCAP readers do).

    Raises:
        ValueError: ``data`` does not start with the MCAP magic.
    """
    if not data.startswith(MAGIC):
        raise ValueError("not an MCAP file (it lacks the MCAP magic bytes)")
    out = McapContents(size=len(data))
    pos, end = len(MAGIC), len(data)
    start = pos
    # The message index records still expected after the last chunk, by channel, and
    # whether any came (MCAP allows a file without them: then none comes).
    expected: dict[int, bytes] | None = None
    indexed = False
    try:
        while pos < end and not out.closed:
            start = pos
            opcode, body, pos = _record_at(data, pos, end)
            if opcode == Opcode.MESSAGE_INDEX and expected is not None:
                (channel_id,) = _CHANNEL_ID.unpack_from(data, body)
                if expected.pop(channel_id, None) != data[body:pos]:
                    raise _Damaged
                indexed = True
                continue
            if expected and indexed:  # an index of the last chunk is missing
                raise _Damaged
            expected, indexed = None, False
            if opcode == Opcode.CHUNK:
                expected = _read_chunk(data[body:pos], out, check_indexes)
            else:
                _read_other(opcode, data[body:pos], out)
    except _Damaged:
        out.stopped_at = start
        return out
    if not out.closed:
        out.stopped_at = pos
    return out


@dataclass(frozen=True)
class McapSummary:
    """The summary section of a finished file, read from its end.

    Attributes:
        schemas: schema id → schema, as the summary lists them.
        channels: channel id → channel, as the summary lists them.
        message_counts: channel id → messages the file holds on that channel (None when
            the summary has no statistics record).
        chunk_count: chunks in the file (None when the summary has no statistics record).
    """

    schemas: dict[int, Schema]
    channels: dict[int, Channel]
    message_counts: dict[int, int] | None
    chunk_count: int | None

    def count(self, topic: str) -> int | None:
        """Messages on ``topic`` (summed over its channels); None if unknown."""
        ids = [i for i, c in self.channels.items() if c.topic == topic]
        if not ids or self.message_counts is None:
            return None
        return sum(self.message_counts.get(i, 0) for i in ids)


_FOOTER = struct.Struct("<BQQQI")  # opcode, length (20), summary start, offsets start, CRC


def read_summary(data: bytes) -> McapSummary | None:
    """The summary of an MCAP file, found from its footer at the end of ``data``.

    The footer's CRC covers the whole summary section, so a summary that is returned is
    whole. It survives damage to the data section before it (a flipped byte in a chunk),
    so it still says what the file held.

    Returns:
        The summary (empty when the footer says there is none); None when ``data`` does not
        end with a footer and the closing magic (a truncated file), or the summary fails
        its CRC or does not parse.
    """
    footer_at = len(data) - len(MAGIC) - _FOOTER.size
    if footer_at < len(MAGIC) or not data.endswith(MAGIC):
        return None
    opcode, length, summary_start, offsets_start, crc = _FOOTER.unpack_from(data, footer_at)
    if opcode != Opcode.FOOTER or length != _FOOTER.size - _RECORD_HEAD.size:
        return None
    if summary_start == 0:  # MCAP: a file written without a summary section
        return McapSummary({}, {}, None, None)
    if not len(MAGIC) <= summary_start < footer_at:
        return None
    covered = memoryview(data)[summary_start : footer_at + _FOOTER.size - 4]
    if crc != 0 and zlib.crc32(covered) != crc:
        return None
    end = offsets_start if summary_start < offsets_start <= footer_at else footer_at
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    stats: Statistics | None = None
    pos = summary_start
    try:
        while pos < end:
            opcode, body, pos = _record_at(data, pos, end)
            if opcode == Opcode.CHANNEL:
                channel = Channel.read(ReadDataStream(io.BytesIO(data[body:pos])))
                channels[channel.id] = channel
            elif opcode == Opcode.SCHEMA:
                schema = Schema.read(ReadDataStream(io.BytesIO(data[body:pos])))
                schemas[schema.id] = schema
            elif opcode == Opcode.STATISTICS:
                stats = Statistics.read(ReadDataStream(io.BytesIO(data[body:pos])))
    except Exception:  # noqa: BLE001 - a summary that does not parse is no summary
        return None
    if stats is None:
        return McapSummary(schemas, channels, None, None)
    return McapSummary(schemas, channels, dict(stats.channel_message_counts), stats.chunk_count)


def _record_at(data: bytes, pos: int, end: int) -> tuple[int, int, int]:
    """Opcode, start of the body, and end of the record at ``pos``."""
    if pos + _RECORD_HEAD.size > end:
        raise _Damaged
    opcode, length = _RECORD_HEAD.unpack_from(data, pos)
    body = pos + _RECORD_HEAD.size
    if body + length > end:
        raise _Damaged
    return opcode, body, body + length


def _read_other(opcode: int, body: bytes, out: McapContents) -> None:
    """A record outside the chunks; the ones walkrepro does not use are skipped."""
    reader = {
        Opcode.SCHEMA: Schema.read,
        Opcode.CHANNEL: Channel.read,
        Opcode.ATTACHMENT: Attachment.read,
        Opcode.METADATA: Metadata.read,
    }.get(opcode)
    if opcode == Opcode.FOOTER:
        out.closed = True
    if reader is None:
        return
    if opcode == Opcode.ATTACHMENT and len(body) >= 4:
        (crc,) = struct.unpack_from("<I", body, len(body) - 4)
        if crc != 0 and zlib.crc32(memoryview(body)[:-4]) != crc:
            raise _Damaged
    try:
        record = reader(ReadDataStream(io.BytesIO(body)))
    except Exception as exc:  # noqa: BLE001 - a malformed record ends the read
        raise _Damaged from exc
    if isinstance(record, Schema):
        out.schemas.setdefault(record.id, record)
    elif isinstance(record, Channel):
        out.channels.setdefault(record.id, record)
    elif isinstance(record, Attachment):
        out.attachments.append(record)
    else:
        out.metadata.append(record)


def _read_chunk(body: bytes, out: McapContents, index: bool = False) -> dict[int, bytes] | None:
    """The messages (and any schema/channel records) of one chunk, if its CRC holds.

    Returns:
        With ``index``, the body of the message index record that each channel with
        messages in the chunk must have (MCAP: log time and offset of each message in the
        uncompressed records); else None.
    """
    try:
        chunk = Chunk.read(ReadDataStream(io.BytesIO(body)))
        if chunk.compression == "zstd":
            raw = zstandard.ZstdDecompressor().decompress(
                chunk.data, max_output_size=chunk.uncompressed_size
            )
        elif chunk.compression == "":
            raw = chunk.data
        else:
            raise _Damaged  # walkrepro writes zstd
    except _Damaged:
        raise
    except Exception as exc:  # noqa: BLE001 - truncated body, zstd error
        raise _Damaged from exc
    # A CRC of 0 means none: then zstd has checked its frame's checksum, if it has one.
    if len(raw) != chunk.uncompressed_size or (
        chunk.uncompressed_crc != 0 and zlib.crc32(raw) != chunk.uncompressed_crc
    ):
        raise _Damaged
    messages = out.messages
    flats: dict[int, list[int]] | None = defaultdict(list) if index else None
    pos, end = 0, len(raw)
    while pos < end:
        record = pos
        opcode, start, pos = _record_at(raw, pos, end)
        if opcode == Opcode.MESSAGE:
            (channel_id,) = _CHANNEL_ID.unpack_from(raw, start)
            messages[channel_id].append(raw[start + _MESSAGE_FIXED : pos])
            if flats is not None:
                (log_time,) = _LOG_TIME.unpack_from(raw, start + _LOG_TIME_AT)
                flats[channel_id] += (log_time, record)
        elif opcode in (Opcode.CHANNEL, Opcode.SCHEMA):
            _read_other(opcode, raw[start:pos], out)
    if flats is None:
        return None
    return {
        channel_id: struct.pack(f"<HI{len(flat)}Q", channel_id, 8 * len(flat), *flat)
        for channel_id, flat in flats.items()
    }
