"""MCAP sources: feedlog recordings as they are, and generic MCAP files with JSON messages.

Generic files need a mapping `TARGET=TOPIC:FIELD` (dots walk into objects, numbers into lists), e.g.
`--map x=/machine/axes:pos.x,y=/machine/axes:pos.y,feed=/machine/feed:value`. Each stream's columns
must come from one topic; a stream's time is the message `log_time` unless `t=TOPIC:FIELD` (in the
declared time unit) names a field. Messages missing a mapped field are counted; strict mode stops at
the first with the topic and message number.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from mcap.records import Channel, Message

from feedlog.errors import IngestError
from feedlog.ingest import mcap_format as fmt
from feedlog.ingest.mapping import ColumnMap, build_streams, parse_map, resolve_target, time_to_ns
from feedlog.ingest.mcap_scan import RecordScan, read_header
from feedlog.ingest.reader import read_recording
from feedlog.ingest.readers import ImportOptions
from feedlog.recording import Recording
from feedlog.units import MAX_ABS_T_NS, time_factor


def is_feedlog_recording(path: Path) -> bool:
    """True when the MCAP header names the feedlog profile (the reader still checks format_version)."""
    return read_header(path).profile == fmt.PROFILE


def read_mcap_source(path: Path, options) -> Recording:
    """Registry entry (`.mcap`, `mcap:`): `options` is an `ImportOptions`."""
    if is_feedlog_recording(path) and not options.mapping:
        return read_recording(path, recover=options.recover)
    if not options.mapping:
        raise IngestError("generic MCAP needs --map TARGET=TOPIC:FIELD,... (e.g. x=/axes:pos.x)", file=str(path))
    return read_json_mcap(path, parse_map(options.mapping), strict=options.strict, options=options)


def _field_path(spec: str, target: str) -> tuple[str, list[str | int]]:
    topic, sep, field = spec.rpartition(":")
    if not sep or not topic or not field:
        raise IngestError(f"--map {target}={spec!r}: generic MCAP fields are TOPIC:FIELD (e.g. /axes:pos.x)")
    return topic, [int(p) if p.lstrip("-").isdigit() else p for p in field.split(".")]


def _get(obj, path: list[str | int]):
    for key in path:
        obj = obj[key]
    return obj


def read_json_mcap(path: Path, mapping: dict[str, str], *, strict: bool = True,
                   options: ImportOptions | None = None) -> Recording:
    """Pick mapped fields from JSON messages of a generic MCAP file."""
    fields = {target: _field_path(spec, target) for target, spec in mapping.items() if spec not in ("log_time",)}
    time_field = fields.pop("t", None)
    by_stream: dict[str, str] = {}
    for target, (topic, _) in fields.items():
        stream = resolve_target(target)[0]
        if by_stream.setdefault(stream, topic) != topic:
            raise IngestError(f"stream {stream!r} maps fields from two topics ({by_stream[stream]}, {topic}); "
                              "one stream must come from one topic", file=str(path))
    if not fields:
        raise IngestError("--map names no value fields", file=str(path))
    topics = sorted(set(by_stream.values()))
    options = options or ImportOptions()
    cmap = ColumnMap(mapping={"t": "log_time", **{k: v for k, v in mapping.items() if k != "t"}},
                     time_unit=options.time_unit or "s", length_unit=options.length_unit or "mm",
                     angle_unit=options.angle_unit or "deg", feed_unit=options.feed_unit or "mm/min", name="--map")
    times: dict[str, list[int]] = {t: [] for t in topics}
    values: dict[str, list[float]] = {target: [] for target in fields}
    bad = 0
    first_bad = ""
    count: dict[str, int] = {t: 0 for t in topics}
    channels: dict[int, Channel] = {}
    scan = RecordScan(path, recover=options.recover)
    for _, record in scan:
        if isinstance(record, Channel):
            channels[record.id] = record
            continue
        if not isinstance(record, Message) or record.channel_id not in channels:
            continue
        channel = channels[record.channel_id]
        topic = channel.topic
        if topic not in count:
            continue
        count[topic] += 1
        if channel.message_encoding != "json":
            raise IngestError(f"topic {topic!r} is {channel.message_encoding!r}, not json; this reader takes "
                              "JSON messages", file=str(path), position=f"{topic} message {count[topic]}")
        try:
            obj = json.loads(record.data)
            row = {target: float(_get(obj, fpath)) for target, (t2, fpath) in fields.items() if t2 == topic}
            stamp = float(_get(obj, time_field[1])) if time_field and time_field[0] == topic else record.log_time
            if not all(math.isfinite(v) for v in row.values()):
                raise ValueError("a mapped value is not a finite number")
            if not abs(stamp) * (time_factor(cmap.time_unit) * 1e9 if isinstance(stamp, float) else 1) <= MAX_ABS_T_NS:
                raise ValueError(f"time {stamp} is not a time (NaN, infinite or beyond +-2**62 ns)")
        except (ValueError, KeyError, IndexError, TypeError, RecursionError) as exc:
            bad += 1
            where = f"{topic} message {count[topic]} (log_time {record.log_time})"
            if strict:
                raise IngestError(f"cannot read mapped fields: {type(exc).__name__}: {exc}", file=str(path),
                                  position=where) from None
            first_bad = first_bad or where
            continue
        times[topic].append(stamp)
        for target, value in row.items():
            values[target].append(value)
    streams = {}
    for stream, topic in by_stream.items():
        if time_field and time_field[0] == topic:  # a time field in the declared unit (default s)
            t_ns = time_to_ns(np.asarray(times[topic], dtype=np.float64), cmap)
        else:  # the message log_time, already ns
            t_ns = np.asarray(times[topic], dtype=np.int64)
        order = np.argsort(t_ns, kind="stable")
        cols = {target: np.asarray(values[target], dtype=np.float64)[order] for target, (tp, _) in fields.items()
                if tp == topic and resolve_target(target)[0] == stream}
        streams.update(build_streams(t_ns[order], cols, cmap))
    metadata = {"source": path.name, "mapping": ",".join(f"{k}={v}" for k, v in mapping.items())}
    if scan.recovered:
        metadata["recovered"] = scan.recovered
    if bad:
        metadata["bad_records"] = f"{bad} messages without the mapped fields; first: {first_bad}"
    return Recording(streams=streams, metadata=metadata, source=str(path))
