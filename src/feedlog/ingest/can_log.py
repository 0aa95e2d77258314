"""CAN log files (python-can LogReader: BLF, ASC, TRC, CSV, canutils .log; MF4 with asammdf) + a DBC.

python-can yields one `Message` per frame; they are gathered block by block into `CanFrames` arrays
and decoded in bulk (`can_dbc`). Error and remote frames are counted and skipped; frames longer than
8 bytes (CAN FD) are counted and skipped too; ids the DBC does not know are counted per id and
reported; frames shorter than their DBC message are counted and not decoded. A frame no bus can carry
(an id beyond 29 bits, a timestamp that is NaN or beyond int64 nanoseconds) is damage: strict imports
stop there naming the frame, lenient ones skip and count it. A file that python-can cannot parse
raises `IngestError` with the number of frames read before it.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from feedlog.errors import IngestError
from feedlog.ingest.bounded import BoundedReader
from feedlog.ingest.can_dbc import seconds_to_us_ns
from feedlog.ingest.can_dbc import CanFrames, DbcLayout, frame_problem
from feedlog.ingest.can_streams import assemble_streams, decode_frames, lost_counts
from feedlog.recording import Recording

BLOCK = 65536


def _block(ts: list[float], ids: list[int], payload: list[bytes], lengths: list[int]) -> CanFrames:
    t_ns = seconds_to_us_ns(ts)
    data = np.frombuffer(b"".join(payload), dtype=np.uint8).reshape(-1, 8)
    return CanFrames(t_ns, np.asarray(ids, dtype=np.uint32), data, np.asarray(lengths, dtype=np.uint8))


class _Warnings(logging.Handler):
    """python-can's warnings while a log is read (a line it could not parse, a DLC that disagrees
    with the data): kept with the number of frames read by then, instead of printed."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.frames = 0
        self.seen: list[tuple[int, str]] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.seen.append((self.frames, record.getMessage()))


def _open(path: Path):
    """python-can's reader for the file's suffix; BLF (binary, with length fields) through BoundedReader."""
    import can

    try:
        if path.suffix.lower() == ".blf":
            source = BoundedReader(path)
            try:
                return can.BLFReader(source)
            except BaseException:
                source.close()
                raise
        return can.LogReader(str(path))
    except ValueError as exc:
        raise IngestError(f"python-can has no reader for this file: {exc}", file=str(path)) from None
    except ImportError as exc:
        raise IngestError(f"this log format needs an extra package ({exc}); for MF4: pip install "
                          "'python-can[mf4]'", file=str(path)) from None
    except Exception as exc:  # a header python-can cannot parse
        raise IngestError(f"cannot open CAN log: {type(exc).__name__}: {exc}", file=str(path),
                          position="byte 0") from None


def read_can_log(path: str | Path, *, strict: bool = True) -> tuple[CanFrames, dict[str, int]]:
    """All data frames of a python-can log as arrays, and counts of what was skipped."""
    path = Path(path)
    if path.stat().st_size == 0:
        raise IngestError("the log is empty (no CAN frames)", file=str(path), position="byte 0")
    skipped = {"error_frames": 0, "remote_frames": 0, "fd_frames_over_8_bytes": 0, "bad_frames": 0,
               "unreadable_lines": 0}
    blocks: list[CanFrames] = []
    ts: list[float] = []
    ids: list[int] = []
    payload: list[bytes] = []
    lengths: list[int] = []
    count = 0
    warnings = _Warnings()
    can_logger = logging.getLogger("can")
    can_logger.addHandler(warnings)
    try:
        reader = _open(path)
        _check_complete(path, reader)
        with reader:
            for msg in reader:
                count += 1
                warnings.frames = count
                if msg.is_error_frame:
                    skipped["error_frames"] += 1
                    continue
                if msg.is_remote_frame:
                    skipped["remote_frames"] += 1
                    continue
                problem = frame_problem(msg)
                if problem:
                    if strict:
                        raise IngestError(f"{problem} (skip such frames with --lenient)", file=str(path),
                                          position=f"frame {count}")
                    skipped["bad_frames"] += 1
                    continue
                data = bytes(msg.data)
                if len(data) > 8:
                    skipped["fd_frames_over_8_bytes"] += 1
                    continue
                ts.append(msg.timestamp)
                ids.append(msg.arbitration_id)
                payload.append(data.ljust(8, b"\0"))
                lengths.append(len(data))
                if len(ts) >= BLOCK:
                    blocks.append(_block(ts, ids, payload, lengths))
                    ts, ids, payload, lengths = [], [], [], []
    except IngestError:
        raise
    except Exception as exc:  # python-can raises format-specific errors (BLFParseError, struct.error, ...)
        raise IngestError(f"cannot parse CAN log after {count} frames: {type(exc).__name__}: {exc}",
                          file=str(path), position=f"frame {count + 1}") from None
    finally:
        can_logger.removeHandler(warnings)
    if warnings.seen:
        if strict:
            frames, message = warnings.seen[0]
            raise IngestError(f"python-can could not read all of it: {message} ({len(warnings.seen)} such places; "
                              "skip them with --lenient)", file=str(path), position=f"after frame {frames}")
        skipped["unreadable_lines"] = len(warnings.seen)
    if ts:
        blocks.append(_block(ts, ids, payload, lengths))
    return CanFrames.concat(blocks), skipped


def _check_complete(path: Path, reader) -> None:
    """Refuse a log that was cut short (python-can would read its prefix silently)."""
    size = path.stat().st_size
    expected = getattr(reader, "file_size", None)  # BLF: the writer stores the final size in the header
    if expected is not None and 0 < size < expected:
        reader.stop()
        raise IngestError(f"BLF file is truncated: the header says {expected} bytes", file=str(path),
                          position=f"byte {size}")
    if path.suffix.lower() in (".asc", ".trc", ".csv", ".log") and size:
        with open(path, "rb") as f:
            f.seek(max(size - 200, 0))
            tail = f.read()
        if not tail.endswith(b"\n"):
            reader.stop()
            raise IngestError("log ends in the middle of a line (truncated)", file=str(path), position=f"byte {size}")
        last = tail.rstrip().splitlines()[-1:] or [b""]
        if path.suffix.lower() == ".asc" and not last[0].startswith(b"End TriggerBlock"):
            reader.stop()
            raise IngestError("ASC log has no 'End TriggerBlock' line (truncated)", file=str(path),
                              position=f"byte {size}")


def frames_to_recording(frames: CanFrames, layout: DbcLayout, *, source: str = "",
                        skipped: dict[str, int] | None = None) -> Recording:
    """Decode frames with the DBC into standard streams; unknown ids and lost samples in the metadata.

    `dropped_frames` counts, as the live logger does, the frames skipped while reading (`skipped`:
    error, remote, CAN FD, damaged) and the frames missing from the seq counters (all message ids;
    frames too short to decode are among them)."""
    skipped = {k: v for k, v in (skipped or {}).items() if v}
    decoded = decode_frames(frames, layout)
    streams, lost = assemble_streams(decoded, layout)
    metadata = {"source": Path(source).name if source else "", "dbc": layout.path.name,
                "frames": str(len(frames) + sum(skipped.values())), **{k: str(v) for k, v in skipped.items()}}
    if decoded.unknown:
        metadata["unknown_ids"] = decoded.unknown_report()
    if decoded.short:
        metadata["short_frames"] = decoded.short_report()
    if decoded.incomplete:
        metadata["incomplete_samples"] = ", ".join(f"{k} {v}" for k, v in decoded.incomplete.items())
    missing = sum(lost_counts(decoded).values())
    if lost:
        metadata["lost_samples"] = str(lost)
    return Recording(streams=streams, metadata=metadata, attachments={layout.path.name: layout.source_text()},
                     dropped_frames=missing + sum(skipped.values()), source=source)


def read_can_source(path: Path, options) -> Recording:
    """Registry entry (`.blf`, `.asc`, `.trc`, `.mf4`, `.log`, `can:`): `options` is an `ImportOptions`."""
    layout = DbcLayout(options.dbc)
    frames, skipped = read_can_log(path, strict=options.strict)
    if not len(frames):
        raise IngestError(f"no CAN data frames in the log ({sum(skipped.values())} frames skipped)", file=str(path),
                          position="end of file")
    recording = frames_to_recording(frames, layout, source=str(path), skipped=skipped)
    if not recording.streams or not any(len(t) for t in recording.streams.values()):
        raise IngestError(f"no frame in the log decodes with {layout.path.name} ({len(frames)} frames read; "
                          f"{recording.metadata.get('unknown_ids', 'none with a known id')})", file=str(path),
                          position="end of file")
    return recording
