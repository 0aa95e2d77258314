"""Reading feedlog recordings (MCAP, format v1) into a `Recording`.

The file is read front to back with the `mcap` stream reader, one top-level record at a time, so a
file that ends early (a logger killed with SIGKILL, a full disk) is detected at a byte position.
Strict by default: a truncated or corrupt file raises `IngestError` naming the file and the byte
offset of the first bad record. With `recover=True` everything in complete records before that point
is returned and `metadata["recovered"]` says where the file was cut.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path

import pandas as pd
import pyarrow as pa
from mcap.exceptions import McapError
from mcap.records import Attachment, Channel, Chunk, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader, breakup_chunk

from feedlog.errors import IngestError
from feedlog.ingest import mcap_format as fmt
from feedlog.ingest.recording import Recording

# what the mcap library, zstd/lz4 and struct raise on damaged bytes
_DAMAGE = (McapError, struct.error, ValueError, EOFError, UnicodeDecodeError, MemoryError, RuntimeError, KeyError)


class _Collector:
    """Accumulates the records of one file into streams, metadata and attachments."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.arrow: dict[int, pa.Schema] = {}
        self.batches: dict[int, list[pa.RecordBatch]] = {}
        self.metadata: dict[str, dict[str, str]] = {}
        self.attachments: dict[str, bytes] = {}

    def add(self, record, position: int) -> None:
        if isinstance(record, Schema):
            self.schemas[record.id] = record
        elif isinstance(record, Channel):
            self._add_channel(record, position)
        elif isinstance(record, Message):
            schema = self.arrow.get(record.channel_id)
            if schema is None:
                raise IngestError(f"message on unknown channel {record.channel_id}", file=self.source,
                                  position=f"byte {position}")
            try:
                batch = fmt.read_batch(record.data, schema)
            except (pa.ArrowException, ValueError) as exc:
                raise IngestError(f"stream {self.channels[record.channel_id].topic!r}: undecodable batch: {exc}",
                                  file=self.source, position=f"byte {position}") from None
            self.batches[record.channel_id].append(batch)
        elif isinstance(record, Metadata):
            self.metadata[record.name] = dict(record.metadata)
            if record.name == fmt.META_FORMAT:
                check_version(record.metadata, self.source)
        elif isinstance(record, Attachment):
            self.attachments[record.name] = bytes(record.data)

    def _add_channel(self, channel: Channel, position: int) -> None:
        if channel.id in self.channels:
            return
        schema = self.schemas.get(channel.schema_id)
        if schema is None or schema.encoding != fmt.SCHEMA_ENCODING or channel.message_encoding != fmt.MESSAGE_ENCODING:
            raise IngestError(f"channel {channel.topic!r} is not a feedlog stream (schema encoding "
                              f"{getattr(schema, 'encoding', None)!r}, message encoding {channel.message_encoding!r});"
                              " read generic MCAP with `feedlog import --map`", file=self.source,
                              position=f"byte {position}")
        try:
            self.arrow[channel.id] = fmt.read_schema(schema.data)
        except (pa.ArrowException, ValueError) as exc:
            raise IngestError(f"channel {channel.topic!r}: bad Arrow schema: {exc}", file=self.source,
                              position=f"byte {position}") from None
        self.channels[channel.id] = channel
        self.batches[channel.id] = []

    def recording(self) -> Recording:
        if fmt.META_FORMAT not in self.metadata:
            raise IngestError("not a feedlog recording (no 'feedlog' metadata record with format_version)",
                              file=self.source)
        streams: dict[str, pd.DataFrame] = {}
        for cid, channel in self.channels.items():
            streams[channel.topic] = fmt.batch_to_frame(self.batches[cid], self.arrow[cid])
        stats = self.metadata.get(fmt.META_STATS, {})
        session = dict(self.metadata.get(fmt.META_SESSION, {}))
        if stats.get("closed") == "false" and "ended" in stats:
            session["incomplete"] = stats["ended"]
        try:
            dropped = int(stats.get("dropped_frames", 0))
        except ValueError:
            raise IngestError(f"bad dropped_frames {stats.get('dropped_frames')!r}", file=self.source) from None
        return Recording(streams=streams, metadata=session,
                         attachments=self.attachments, dropped_frames=dropped, source=self.source)


def check_version(meta: dict[str, str], source: str) -> None:
    raw = meta.get("format_version", "")
    try:
        version = int(raw)
    except ValueError:
        raise IngestError(f"bad format_version {raw!r}", file=source) from None
    if version > fmt.FORMAT_VERSION or version < 1:
        raise IngestError(f"recording format_version {version} is not supported by this feedlog "
                          f"(it reads versions 1..{fmt.FORMAT_VERSION}); upgrade feedlog", file=source)


class RecordScan:
    """Every record of an MCAP file front to back, chunks opened, each with its chunk's byte offset.

    Strict: damage raises `IngestError` naming the file and byte. With `recover`, iteration stops at the
    damage and `recovered` says what and where.
    """

    def __init__(self, path: str | os.PathLike, *, recover: bool = False) -> None:
        self.path = Path(path)
        self.source = str(path)
        self.recover = recover
        self.recovered: str | None = None
        if not self.path.is_file():
            raise IngestError("no such file", file=self.source)

    def _damaged(self, problem: str, position: int) -> None:
        if position == 0:
            raise IngestError(f"not an MCAP file ({problem})", file=self.source, position="byte 0")
        if not self.recover:
            raise IngestError(f"{problem}; read it with recover=True (feedlog info/import --recover) to keep "
                              "the complete records before this point", file=self.source, position=f"byte {position}")
        self.recovered = f"{problem} at byte {position}"

    def __iter__(self):
        size = self.path.stat().st_size
        with open(self.path, "rb") as f:
            # chunk CRCs are checked in breakup_chunk; the whole-stream CRC would only hash everything twice
            records = StreamReader(f, emit_chunks=True, validate_crcs=False).records
            position = 0
            while True:
                try:
                    record = next(records)
                except StopIteration:
                    return
                except _DAMAGE as exc:
                    self._damaged(_describe(exc, position, size), position)
                    return
                if isinstance(record, Chunk):
                    try:
                        inner = breakup_chunk(record, validate_crc=True)
                    except _DAMAGE as exc:
                        self._damaged(f"corrupt chunk ({exc})", position)
                        return
                    for item in inner:
                        yield position, item
                else:
                    yield position, record
                if isinstance(record, Footer):
                    return
                position = f.tell()


def read_recording(path: str | os.PathLike, *, recover: bool = False) -> Recording:
    """Read a feedlog recording. Strict unless `recover`: then a cut-off file yields what it holds."""
    source = str(path)
    if not Path(path).is_file():
        raise IngestError("no such recording file", file=source)
    collector = _Collector(source)
    scan = RecordScan(path, recover=recover)
    for position, record in scan:
        collector.add(record, position)
    if scan.recovered:
        collector.metadata.setdefault(fmt.META_SESSION, {})["recovered"] = scan.recovered
    return collector.recording()


def _describe(exc: Exception, position: int, size: int) -> str:
    if position >= size or type(exc).__name__ == "EndOfFile" or isinstance(exc, struct.error):
        return f"file is truncated (ends at byte {size}, inside or before the record at byte {position})"
    return f"corrupt record ({type(exc).__name__}: {exc})"
