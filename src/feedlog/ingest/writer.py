"""Writing feedlog recordings (MCAP, format v1): `RecordingWriter` for live appends, `write_recording`.

`RecordingWriter` keeps each stream's appended rows in memory only until a message is full
(`rows_per_message`, and at most 1/8 of a chunk in bytes) or `flush_interval_s` has passed; then it
closes the MCAP chunk and flushes the file, so a process killed with SIGKILL loses at most that
interval. Chunks hold at most `chunk_size` uncompressed bytes (1 MiB): a file cut anywhere keeps every
chunk before the cut (`read_recording(recover=True)`). A failed write (disk full, file size limit)
cuts the file back to the last complete flush, ends it there (footer without summary) and raises
`OutputError`: everything written before stays readable, and the file says why it ended.
`write_recording` writes whole recordings under a temporary name, streams interleaved by time,
and renames the file only once it is complete.
"""

from __future__ import annotations

import contextlib
import heapq
import os
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

import mcap.writer
import numpy as np
import pandas as pd
import pyarrow as pa
import zstandard
from mcap.records import DataEnd, Footer, Metadata
from mcap.data_stream import RecordBuilder
from mcap.writer import MCAP0_MAGIC, CompressionType, IndexType, Writer

from feedlog.atomic import atomic_output
from feedlog.errors import IngestError, OutputError
from feedlog.ingest import mcap_format as fmt
from feedlog.recording import Recording, first_bad_value

COMPRESSIONS = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
ZSTD_DEFAULT_LEVEL = 3  # what mcap's writer uses (zstandard.compress's default)
ZSTD_LEVELS = range(1, 23)
CHUNK_SIZE = 1 << 20  # largest chunk, uncompressed: what a cut-off file can lose beyond the last flush
MESSAGE_SHARE = 8     # a message holds at most 1/8 of a chunk, so a chunk never outgrows chunk_size
MESSAGE_SPAN_NS = 1_000_000_000  # write_recording: a message holds at most 1 s of samples


class _LevelledZstd:
    """Stands in for the `zstandard` module inside mcap.writer, whose Writer compresses each chunk
    with `zstandard.compress(data)` at zstd's default level and has no option for another. The level
    is per thread (`zstd_level()`), so concurrent writers do not affect each other; everything else
    is the real module."""

    def __init__(self) -> None:
        self._local = threading.local()

    def __getattr__(self, name: str):
        return getattr(zstandard, name)

    def compress(self, data: bytes) -> bytes:
        level = getattr(self._local, "level", ZSTD_DEFAULT_LEVEL)
        return zstandard.ZstdCompressor(level=level).compress(data)


_ZSTD = _LevelledZstd()
if getattr(mcap.writer, "zstandard", None) is zstandard:
    mcap.writer.zstandard = _ZSTD  # type: ignore[attr-defined]


@contextlib.contextmanager
def zstd_level(level: int) -> Iterator[None]:
    """Chunks that mcap's Writer compresses in this thread inside the block use zstd `level`."""
    before = getattr(_ZSTD._local, "level", ZSTD_DEFAULT_LEVEL)
    _ZSTD._local.level = level
    try:
        yield
    finally:
        _ZSTD._local.level = before


class RecordingWriter:
    """Append batches of samples to a feedlog recording; use as a context manager.

    `write(stream, table)` appends rows (a DataFrame, Arrow table/batch or dict of arrays whose first
    column is `t_ns` int64); the first write of a stream fixes its columns and types. Set
    `dropped_frames` at any time; it is stored with every flush and at close.
    """

    def __init__(self, path: str | os.PathLike, *, metadata: dict[str, str] | None = None,
                 attachments: dict[str, bytes] | None = None, overwrite: bool = False,
                 flush_interval_s: float = 1.0, rows_per_message: int = 16384,
                 chunk_size: int = CHUNK_SIZE, compression: str = "none",
                 level: int | None = None) -> None:
        if flush_interval_s <= 0 or rows_per_message < 1 or chunk_size < 4096:
            raise ValueError(f"flush_interval_s={flush_interval_s}, rows_per_message={rows_per_message} must be "
                             f"positive and chunk_size={chunk_size} at least 4096")
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression {compression!r} is not one of {sorted(COMPRESSIONS)}")
        if level is not None and (compression != "zstd" or level not in ZSTD_LEVELS):
            raise ValueError(f"level={level} needs compression='zstd' and a zstd level from 1 to 22")
        if level is not None and mcap.writer.zstandard is not _ZSTD:  # type: ignore[attr-defined]
            raise ValueError("this mcap version compresses chunks on its own: no zstd level can be set")
        self.level = ZSTD_DEFAULT_LEVEL if level is None else level
        self.path = Path(path)
        if self.path.exists() and not overwrite:
            raise IngestError("output exists; pass --overwrite to replace it", file=str(self.path))
        self.flush_interval_s = flush_interval_s
        self.rows_per_message = rows_per_message
        self.message_bytes = chunk_size // MESSAGE_SHARE
        self._rows: dict[str, int] = {}  # rows per message of each stream (rows_per_message or fewer)
        self.dropped_frames = 0
        self._stored_drops: int | None = None
        try:
            self._file: BinaryIO = open(self.path, "wb")
        except OSError as exc:
            raise OutputError(f"cannot create the recording: {exc.strerror or exc}", file=str(self.path)) from None
        # mcap closes a chunk once it passes its threshold: one message below chunk_size keeps it within
        self._mcap = Writer(self._file, chunk_size=chunk_size - self.message_bytes, compression=COMPRESSIONS[compression],
                            index_types=IndexType.ALL)
        self._channels: dict[str, int] = {}
        self._schemas: dict[str, pa.Schema] = {}
        self._pending: dict[str, list[pa.RecordBatch]] = {}
        self._pending_rows: dict[str, int] = {}
        self._last_t: dict[str, int] = {}
        self._samples = 0
        self._closed = False
        self._failed: OutputError | None = None
        self._good_offset = 0
        self._last_flush = time.monotonic()
        try:
            self._guard(self._start, metadata or {}, attachments or {})
        except OutputError:  # not even the header fits: nothing recorded, no file left
            self._closed = True
            with contextlib.suppress(OSError):  # the buffer that did not fit fails again on close
                self._file.close()
            self.path.unlink(missing_ok=True)
            raise OutputError(f"cannot write the recording ({self._failed.reason}); nothing was written",
                              file=str(self.path)) from None

    # -- public API ----------------------------------------------------------------------------------
    def write(self, stream: str, table: pd.DataFrame | pa.Table | pa.RecordBatch | dict) -> None:
        """Append rows to `stream` (its t_ns must continue where the last batch ended)."""
        self._check_open()
        batch = fmt.table_to_batch(stream, table, self._schemas.get(stream))
        if batch.num_rows:
            t = batch.column(0).to_numpy()
            bad = first_bad_value(t, {name: column.to_numpy(zero_copy_only=False)
                                      for name, column in zip(batch.schema.names[1:], batch.columns[1:])})
            if bad:
                raise IngestError(f"stream {stream!r}: {bad[0]} (sample {bad[1]} of this batch); recordings hold "
                                  "finite values and int64 times only", file=str(self.path))
            first_back = _first_backwards(t, self._last_t.get(stream))
            if first_back is not None:
                raise IngestError(f"stream {stream!r}: time goes backwards at sample {first_back} of this batch",
                                  file=str(self.path))
        if stream not in self._schemas:
            self._guard(self._register, stream, batch.schema)
        if batch.num_rows:
            self.message_rows(stream, batch)
            self._last_t[stream] = int(t[-1])
            self._pending[stream].append(batch)
            self._pending_rows[stream] += batch.num_rows
            self._samples += batch.num_rows
            if self._pending_rows[stream] >= self._rows[stream]:
                self._guard(self._emit, stream, False)
        self.flush_if_due()

    def message_rows(self, stream: str, batch: pa.RecordBatch) -> int:
        """Rows per message of `stream`, fixed by its first rows (`batch`): rows_per_message, or fewer
        when that many would take more than 1/8 of a chunk."""
        if stream not in self._rows:
            row_bytes = max(batch.nbytes / max(batch.num_rows, 1), 1.0)
            self._rows[stream] = max(1, min(self.rows_per_message, int((self.message_bytes - 1024) / row_bytes)))
        return self._rows[stream]

    def end_message(self, stream: str) -> None:
        """Write the rows of `stream` not yet written as one message now (for callers that cut their
        messages themselves, as `write_recording` does by time)."""
        self._check_open()
        if stream in self._pending:
            self._guard(self._emit, stream, True)

    def add_attachment(self, name: str, data: bytes) -> None:
        self._check_open()
        self._guard(self._mcap.add_attachment, time.time_ns(), 0, name, fmt.media_type(name), bytes(data))

    def flush_if_due(self) -> None:
        """Flush when `flush_interval_s` has passed since the last flush (call it from idle loops too)."""
        if not self._closed and time.monotonic() - self._last_flush >= self.flush_interval_s:
            self.flush()

    def flush(self) -> None:
        """Write every pending sample as a complete MCAP chunk and push it to the operating system."""
        self._check_open()
        self._guard(self._flush_all)

    def close(self) -> None:
        """Write what is pending, the statistics and the MCAP summary. Safe to call twice."""
        if self._closed:
            return
        try:
            if self._failed is None:
                self._guard(self._finish)
        finally:
            self._closed = True
            try:
                self._file.close()
            except OSError as exc:  # after a failed write (already sealed) the unwritten buffer fails again
                if self._failed is None:
                    raise OutputError(f"write failed on close ({exc.strerror or exc})", file=str(self.path)) from None

    @property
    def samples_written(self) -> int:
        return self._samples

    @property
    def streams(self) -> list[str]:
        return list(self._channels)

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()

    # -- internals -----------------------------------------------------------------------------------
    def _start(self, metadata: dict[str, str], attachments: dict[str, bytes]) -> None:
        self._mcap.start(profile=fmt.PROFILE, library=fmt.LIBRARY)
        self._mcap.add_metadata(fmt.META_FORMAT, {"format_version": str(fmt.FORMAT_VERSION), "writer": fmt.LIBRARY,
                                                  "message_encoding": fmt.MESSAGE_ENCODING})
        self._mcap.add_metadata(fmt.META_SESSION, {str(k): str(v) for k, v in metadata.items()})
        for name, data in attachments.items():
            self._mcap.add_attachment(time.time_ns(), 0, name, fmt.media_type(name), bytes(data))
        self._sync()

    def _register(self, stream: str, schema: pa.Schema) -> None:
        schema_id = self._mcap.register_schema(fmt.SCHEMA_PREFIX + stream, fmt.SCHEMA_ENCODING,
                                               fmt.schema_bytes(stream, schema))
        self._channels[stream] = self._mcap.register_channel(
            stream, fmt.MESSAGE_ENCODING, schema_id, {"columns": fmt.column_summary(schema)})
        self._schemas[stream] = schema
        self._pending[stream] = []
        self._pending_rows[stream] = 0

    def _emit(self, stream: str, everything: bool) -> None:
        """Turn pending rows of `stream` into messages of `rows_per_message` rows (all rows if asked)."""
        rows = self._pending_rows[stream]
        if rows == 0 or (not everything and rows < self._rows[stream]):
            return
        table = pa.Table.from_batches(self._pending[stream], schema=self._schemas[stream]).combine_chunks()
        step = self._rows[stream]
        end = rows if everything else rows - rows % step
        channel = self._channels[stream]
        for start in range(0, end, step):
            piece = table.slice(start, min(step, end - start)).to_batches()[0]
            t0 = max(int(piece.column(0)[0].as_py()), 0)
            self._mcap.add_message(channel, t0, fmt.batch_bytes(piece), t0)
        rest = table.slice(end)
        self._pending[stream] = rest.to_batches() if rest.num_rows else []
        self._pending_rows[stream] = rest.num_rows

    def _flush_all(self) -> None:
        for stream in self._channels:
            self._emit(stream, True)
        if self._stored_drops != self.dropped_frames:
            self._write_stats(closed=False)
        self._mcap.flush()
        self._sync()

    def _finish(self) -> None:
        for stream in self._channels:
            self._emit(stream, True)
        self._write_stats(closed=True)
        self._mcap.finish()
        self._sync()

    def _write_stats(self, *, closed: bool) -> None:
        self._mcap.add_metadata(fmt.META_STATS, {"dropped_frames": str(int(self.dropped_frames)),
                                                 "closed": "true" if closed else "false"})
        self._stored_drops = self.dropped_frames

    def _sync(self) -> None:
        self._file.flush()
        self._good_offset = self._file.tell()
        self._last_flush = time.monotonic()

    def _guard(self, action, *args) -> None:
        """Run a write; on an OS error keep the file as it was after the last complete flush."""
        try:
            with zstd_level(self.level):
                action(*args)
        except OSError as exc:
            self._failed = OutputError(f"write failed ({exc.strerror or exc}); the recording keeps the data "
                                       f"flushed before byte {self._good_offset}", file=str(self.path),
                                       position=f"byte {self._good_offset}")
            self._failed.reason = exc.strerror or str(exc)
            self._seal(f"write failed: {exc.strerror or exc}")
            raise self._failed from None

    def _seal(self, reason: str) -> None:
        """After a failed write: cut the file back to its last complete flush and end it there (stats,
        data end, footer without summary, magic) so it reads as a complete, shorter recording. If even
        that does not fit, the file stays cut back (readable with recover=True)."""
        try:
            self._file.truncate(self._good_offset)
            self._file.seek(self._good_offset)
            builder = RecordBuilder()
            Metadata(name=fmt.META_STATS, metadata={"dropped_frames": str(int(self.dropped_frames)),
                                                    "closed": "false", "ended": reason}).write(builder)
            DataEnd(0).write(builder)
            Footer(0, 0, 0).write(builder)
            self._file.write(builder.end() + MCAP0_MAGIC)
            self._file.flush()
        except OSError:
            try:
                self._file.truncate(self._good_offset)
            except OSError:
                pass

    def _check_open(self) -> None:
        if self._failed is not None:
            raise self._failed
        if self._closed:
            raise IngestError("recording writer is closed", file=str(self.path))


def _first_backwards(t, previous: int | None) -> int | None:
    if previous is not None and len(t) and t[0] < previous:
        return 0
    back = np.flatnonzero(np.diff(t) < 0)
    return int(back[0]) + 1 if len(back) else None


def write_recording(path: str | os.PathLike, recording: Recording, *, overwrite: bool = False,
                    compression: str = "none", level: int | None = None, chunk_size: int = CHUNK_SIZE) -> None:
    """Write a whole recording. The file appears under `path` only once it is complete.

    Messages of all streams are written in the order of their first sample, so each chunk covers a
    stretch of time in every stream and a file cut short keeps all streams up to the cut. `level` is
    the zstd level (1-22, with compression='zstd'; default 3); `chunk_size` the largest chunk,
    uncompressed (larger chunks let zstd find repeats further back).
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise IngestError("output exists; pass --overwrite to replace it", file=str(path))
    if not path.parent.is_dir():
        raise OutputError("cannot create the recording: its folder does not exist", file=str(path))
    batches = {name: fmt.table_to_batch(name, table) for name, table in recording.streams.items()}
    try:
        with atomic_output(path) as partial:
            with RecordingWriter(partial, metadata=recording.metadata, attachments=recording.attachments,
                                 overwrite=True, compression=compression, level=level, chunk_size=chunk_size) as writer:
                for name, batch in batches.items():  # channels in the recording's stream order
                    writer.write(name, batch.slice(0, 0))
                for name, piece in _pieces_by_time(batches, writer):
                    writer.write(name, piece)
                    writer.end_message(name)
                writer.dropped_frames = recording.dropped_frames
    except OutputError as exc:
        if not hasattr(exc, "reason"):  # already about `path` (atomic_output's own)
            raise
        raise OutputError(f"cannot write the recording ({exc.reason}); nothing was written", file=str(path)) from None


def _pieces_by_time(batches: dict[str, pa.RecordBatch], writer: RecordingWriter):
    """(stream, rows) in messages of at most MESSAGE_SPAN_NS of samples (and the writer's message size),
    all streams merged by each message's first time: chunks then follow time in every stream."""
    def pieces(name: str, batch: pa.RecordBatch):
        if not batch.num_rows:
            return
        rows = writer.message_rows(name, batch)
        t = batch.column(0).to_numpy()
        start = 0
        while start < len(t):
            end = min(start + rows, int(np.searchsorted(t, t[start] + MESSAGE_SPAN_NS, side="left")))
            end = max(end, start + 1)
            yield (int(t[start]), name, batch.slice(start, end - start))
            start = end

    merged = heapq.merge(*(pieces(name, batch) for name, batch in batches.items()), key=lambda item: item[0])
    for _, name, piece in merged:
        yield name, piece
