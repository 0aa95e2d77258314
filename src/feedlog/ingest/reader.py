"""Reading feedlog recordings (MCAP, format v1) into a `Recording`.

The file is read front to back (`mcap_scan.RecordScan`), one top-level record at a time, so a file
that ends early (a logger killed with SIGKILL, a full disk) is detected at a byte position. Strict
by default: a truncated or corrupt file raises `IngestError` naming the file and the byte offset of
the first bad record; so does a batch that Arrow cannot validate or that holds empty (null) values.
With `recover=True` everything in complete records before that point is returned and
`metadata["recovered"]` says where the file was cut.
"""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd
import pyarrow as pa
from mcap.records import Attachment, Channel, Message, Metadata, Schema

from feedlog.errors import IngestError
from feedlog.ingest import mcap_format as fmt
from feedlog.ingest.mcap_scan import RecordScan
from feedlog.recording import Recording


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
        self.dropped = 0

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
            topic = self.channels[record.channel_id].topic
            try:
                batch = fmt.read_batch(record.data, schema)
            except (pa.ArrowException, ValueError, OSError, EOFError) as exc:
                raise IngestError(f"stream {topic!r}: undecodable batch: {exc}", file=self.source,
                                  position=f"chunk at byte {position}") from None
            empty = [name for name, column in zip(batch.schema.names, batch.columns) if column.null_count]
            if empty:
                raise IngestError(f"stream {topic!r}: column {empty[0]!r} has empty (null) values", file=self.source,
                                  position=f"chunk at byte {position}")
            self.batches[record.channel_id].append(batch)
        elif isinstance(record, Metadata):
            self.metadata[record.name] = dict(record.metadata)
            where = f"metadata record {record.name!r} at byte {position}"
            if record.name == fmt.META_FORMAT:
                check_version(record.metadata, self.source, where)
            if record.name == fmt.META_STATS:
                self.dropped = _count(record.metadata.get("dropped_frames", "0"), "dropped_frames", self.source, where)
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

    def recording(self, end: int) -> Recording:
        """The recording read from the file's first `end` bytes."""
        if fmt.META_FORMAT not in self.metadata:
            raise IngestError("not a feedlog recording (no 'feedlog' metadata record with format_version)",
                              file=self.source, position=f"bytes 0-{end}")
        streams: dict[str, pd.DataFrame] = {}
        for cid, channel in self.channels.items():
            streams[channel.topic] = fmt.batch_to_frame(self.batches[cid], self.arrow[cid])
        stats = self.metadata.get(fmt.META_STATS, {})
        session = dict(self.metadata.get(fmt.META_SESSION, {}))
        if stats.get("closed") == "false" and "ended" in stats:
            session["incomplete"] = stats["ended"]
        return Recording(streams=streams, metadata=session,
                         attachments=self.attachments, dropped_frames=self.dropped, source=self.source)


def _count(raw: str, key: str, source: str, where: str) -> int:
    """A non-negative decimal count from a metadata value."""
    if not (raw.isascii() and raw.isdigit() and len(raw) <= 18):  # below 10**18: an int64 with room to add
        raise IngestError(f"bad {key} {raw[:40]!r} (a count of frames below 10**18)", file=source, position=where)
    return int(raw)


def check_version(meta: dict[str, str], source: str, where: str | None = None) -> None:
    raw = meta.get("format_version", "")
    try:
        version = int(raw)
    except ValueError:
        raise IngestError(f"bad format_version {raw!r}", file=source, position=where) from None
    if version > fmt.FORMAT_VERSION or version < 1:
        raise IngestError(f"recording format_version {version} is not supported by this feedlog "
                          f"(it reads versions 1..{fmt.FORMAT_VERSION}); upgrade feedlog", file=source, position=where)


def read_recording(path: str | os.PathLike, *, recover: bool = False) -> Recording:
    """Read a feedlog recording. Strict unless `recover`: then a cut-off file yields what it holds."""
    source = str(path)
    if Path(path).is_dir():
        raise IngestError("is a folder, not a recording file (give the .mcap files in it, e.g. FOLDER/*.mcap)",
                          file=source)
    if not Path(path).is_file():
        raise IngestError("no such recording file", file=source)
    collector = _Collector(source)
    scan = RecordScan(path, recover=recover)
    for position, record in scan:
        collector.add(record, position)
    if scan.recovered:
        collector.metadata.setdefault(fmt.META_SESSION, {})["recovered"] = scan.recovered
    return collector.recording(scan.end)
