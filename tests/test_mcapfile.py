"""Tests of walkrepro.log.mcapfile's writer: batches queued in a chunk, and its background thread."""

from __future__ import annotations

import io

import numpy as np
import pytest
from mcap.reader import make_reader

from walkrepro.log.mcapfile import McapFile, read_mcap

CHUNK_SIZE = 1 << 20  # [bytes]: chunks close where the tests close them


def _file(stream: io.BytesIO) -> tuple[McapFile, int, int]:
    """A file with two channels (a batched one and one of single messages)."""
    file = McapFile(stream, CHUNK_SIZE, library="test")
    schema = file.add_schema("s", "jsonschema", b"{}")
    return file, file.add_channel("/rows", "json", schema), file.add_channel("/one", "json", schema)


def _messages(n: int, size: int) -> tuple[np.ndarray, np.ndarray, list[bytes]]:
    """Stamps [ns], payloads (uint8, (n, size)) and extra bytes of differing lengths."""
    rng = np.random.default_rng(0)
    stamps = 1_000_000 + 500_000 * np.arange(n, dtype=np.int64)
    payloads = rng.integers(0, 256, size=(n, size), dtype=np.uint8)
    extras = [bytes(i % 3) for i in range(n)]
    return stamps, payloads, extras


@pytest.mark.parametrize("with_extras", [False, True])
def test_queued_rows_write_the_bytes_of_single_messages(with_extras: bool) -> None:
    """A batch queued with append_rows (encoded on the thread when its chunk closes) gives
    the file that one append per message gives, single messages of another channel between
    batches included."""
    stamps, payloads, extras = _messages(300, 40)
    files = []
    for batched in (False, True):
        stream = io.BytesIO()
        file, rows_id, one_id = _file(stream)
        rows, one = file.channel_writer(rows_id), file.channel_writer(one_id)
        for start in range(0, len(stamps), 50):
            part = slice(start, start + 50)
            part_extras = extras[part] if with_extras else None
            if batched:
                queued = payloads[part].copy()
                rows.append_rows(stamps[part], payloads.shape[1], lambda q=queued: q, part_extras)
            else:
                for i in range(start, start + 50):
                    rows.append(
                        int(stamps[i]), payloads[i].tobytes() + (extras[i] if with_extras else b"")
                    )
            one.append(int(stamps[start]), b"single")
            if start % 100 == 50:
                file.flush_chunk()
        file.add_metadata("m", {"k": "v"})
        file.finish()
        files.append(stream.getvalue())
    assert files[0] == files[1]
    contents = read_mcap(files[1], check_indexes=True)
    assert contents.closed and contents.stopped_at is None
    assert len(contents.messages[1]) == len(stamps)
    read = list(make_reader(io.BytesIO(files[1])).iter_messages())
    assert [m.sequence for _, c, m in read if c.topic == "/rows"] == list(range(len(stamps)))


class _FailingStream(io.BytesIO):
    """A stream whose writes fail once ``fail`` is set (a full disk)."""

    fail = False

    def write(self, data: bytes) -> int:  # type: ignore[override]
        if self.fail:
            raise OSError(28, "No space left on device")
        return super().write(data)


def test_an_error_of_the_background_thread_is_raised_by_the_writer() -> None:
    """A chunk the background thread cannot write makes the writer's next call raise that
    error, in the calling thread."""
    stream = _FailingStream()
    file, rows_id, _ = _file(stream)
    rows = file.channel_writer(rows_id)
    stamps, payloads, _ = _messages(10, 8)
    rows.append_rows(stamps, 8, lambda: payloads)
    stream.fail = True
    file.flush_chunk()  # queued: the thread fails
    with pytest.raises(OSError, match="No space left"):
        file.wait()
    file.wait()  # raised once
    file.shutdown()


def test_the_thread_stops_when_the_file_is_finished() -> None:
    """finish() writes the last chunk and stops the background thread."""
    stream = io.BytesIO()
    file, rows_id, _ = _file(stream)
    stamps, payloads, _ = _messages(10, 8)
    file.channel_writer(rows_id).append_rows(stamps, 8, lambda: payloads)
    file.finish()
    assert file._worker._shutdown  # noqa: SLF001 - the executor's own flag
    assert read_mcap(stream.getvalue()).closed
