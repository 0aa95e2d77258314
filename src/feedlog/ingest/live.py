"""The live CAN logger: a python-can bus -> bounded frame buffer -> bulk DBC decode -> RecordingWriter.

A `Notifier` thread hands every received frame to `FrameBuffer` (a python-can `Listener`), which keeps
at most `max_frames`; beyond that frames are counted as dropped, so memory stays bounded however slow
the disk is. The main loop wakes every `tick_s`, takes the buffered frames as arrays, decodes them in
bulk, appends the streams to the recording and lets the writer flush a chunk at least every second.
It stops on request (SIGINT/SIGTERM set `stop`), when `finished()` says the source is done, after
`duration_s`, or when the disk refuses a write; in every case what was written stays readable.

`dropped_frames` counts frames the logger lost (buffer overflow, frames arriving too late for their
stream, error and remote frames, frames no bus can carry: an id beyond 29 bits, a time that is not a
number) plus frames missing in the DBC's `seq` counters (lost before they reached the logger, or too
short to decode). A sample that misses one of its frames is left out of its stream and counted in
`incomplete_samples`, so a stream never holds a value that did not arrive.
"""

from __future__ import annotations

import sys
import threading
import time
from dataclasses import dataclass, field
from collections.abc import Callable
from typing import TextIO

import can
import numpy as np

from feedlog.errors import OutputError
from feedlog.ingest.can_dbc import seconds_to_us_ns
from feedlog.ingest.can_dbc import SEQ_SIGNAL, CanFrames, DbcLayout, frame_problem
from feedlog.ingest.can_streams import assemble_streams, decode_frames, lost_samples
from feedlog.ingest.writer import RecordingWriter


class FrameBuffer(can.Listener):
    """Bounded, thread-safe buffer of received frames (filled by python-can's Notifier thread)."""

    def __init__(self, max_frames: int = 500_000) -> None:
        self.max_frames = max_frames
        self.dropped = 0
        self.error_frames = 0
        self.bad_frames = 0
        self.received = 0
        self._lock = threading.Lock()
        self._ts: list[float] = []
        self._ids: list[int] = []
        self._data: list[bytes] = []
        self._dlc: list[int] = []

    def on_message_received(self, msg: can.Message) -> None:
        self.received += 1  # every frame delivered, so the logger's own drops never exceed it
        if msg.is_error_frame or msg.is_remote_frame:
            self.error_frames += 1
            return
        if frame_problem(msg):
            self.bad_frames += 1
            return
        with self._lock:
            if len(self._ts) >= self.max_frames:
                self.dropped += 1
                return
            self._ts.append(msg.timestamp)
            self._ids.append(msg.arbitration_id)
            self._data.append(bytes(msg.data[:8]).ljust(8, b"\0"))
            self._dlc.append(min(len(msg.data), 8))

    def take(self) -> CanFrames:
        with self._lock:
            ts, ids, data, dlc = self._ts, self._ids, self._data, self._dlc
            self._ts, self._ids, self._data, self._dlc = [], [], [], []
        t_ns = seconds_to_us_ns(ts)
        return CanFrames(t_ns, np.asarray(ids, dtype=np.uint32),
                         np.frombuffer(b"".join(data), dtype=np.uint8).reshape(-1, 8), np.asarray(dlc, dtype=np.uint8))

    def __len__(self) -> int:
        return len(self._ts)

    def stop(self) -> None:  # Listener API
        pass


@dataclass
class CaptureStats:
    frames: int = 0
    samples: int = 0
    dropped_frames: int = 0
    late_frames: int = 0
    lost_frames: int = 0
    unknown_frames: int = 0
    short_frames: int = 0
    bad_frames: int = 0
    incomplete_samples: int = 0
    wall_s: float = 0.0
    stopped_by: str = ""
    error: str = ""
    streams: dict[str, int] = field(default_factory=dict)

    def as_dict(self) -> dict:
        rate = self.frames / self.wall_s if self.wall_s > 0 else 0.0
        return {**self.__dict__, "wall_s": round(self.wall_s, 3), "frames_per_s": round(rate, 1)}


class Progress:
    """One refreshing status line: frames, rate, drops."""

    def __init__(self, stream: TextIO | None, interval_s: float = 0.5) -> None:
        self.stream = stream
        self.interval_s = interval_s
        self._last = 0.0

    def show(self, stats: CaptureStats, elapsed: float, *, final: bool = False) -> None:
        if self.stream is None or (not final and elapsed - self._last < self.interval_s):
            return
        self._last = elapsed
        rate = stats.frames / elapsed if elapsed > 0 else 0.0
        self.stream.write(f"\r{elapsed:7.1f} s  {stats.frames:>10} frames  {rate:>9.0f} frames/s  "
                          f"{stats.samples:>10} samples  {stats.dropped_frames} dropped" + ("\n" if final else ""))
        self.stream.flush()


class _Decoder:
    """Decodes frame batches, keeping the last few ms back so one sample's frames stay together."""

    def __init__(self, layout: DbcLayout, hold_ns: int, drop_columns: frozenset[str] = frozenset()) -> None:
        self.layout = layout
        self.drop_columns = drop_columns
        self.hold_ns = hold_ns
        self.pending = CanFrames.concat([])
        self.last_seq: dict[int, int] = {}
        self.last_t: dict[str, int] = {}
        self.columns: dict[str, list[str]] = {}

    def feed(self, frames: CanFrames, stats: CaptureStats, *, final: bool) -> dict:
        frames = CanFrames.concat([self.pending, frames])
        if not len(frames):
            return {}
        if not final:
            cut = frames.t_ns.max() - self.hold_ns
            hold = frames.t_ns > cut
            self.pending = _select(frames, hold)
            frames = _select(frames, ~hold)
        else:
            self.pending = CanFrames.concat([])
        decoded = decode_frames(frames, self.layout)
        stats.unknown_frames += decoded.unknown_frames
        stats.short_frames += decoded.short_frames
        for frame_id, values in decoded.values.items():  # frames missing in each message's seq counter
            if SEQ_SIGNAL in values and len(values[SEQ_SIGNAL]):
                seq = values[SEQ_SIGNAL][np.argsort(decoded.times[frame_id], kind="stable")]
                previous = self.last_seq.get(frame_id)
                stats.lost_frames += lost_samples(seq if previous is None else np.concatenate(([previous], seq)))
                self.last_seq[frame_id] = int(seq[-1])
        streams, _ = assemble_streams(decoded, self.layout)
        stats.incomplete_samples += sum(decoded.incomplete.values())
        out = {}
        for name, table in streams.items():
            if self.drop_columns & set(table.columns):
                table = table.drop(columns=sorted(self.drop_columns & set(table.columns)))
            known = self.columns.setdefault(name, list(table.columns))
            if list(table.columns) != known:  # a member message missing in this batch: its samples are incomplete
                missing = [c for c in known if c not in table.columns]
                if missing:
                    stats.incomplete_samples += len(table)
                    continue
                table = table[known]
            last = self.last_t.get(name)
            if last is not None:
                late = table["t_ns"].to_numpy() < last
                if late.any():
                    stats.late_frames += int(late.sum())
                    table = table[~late]
            if len(table):
                self.last_t[name] = int(table["t_ns"].iloc[-1])
                out[name] = table
        return out


def _select(frames: CanFrames, mask: np.ndarray) -> CanFrames:
    return CanFrames(frames.t_ns[mask], frames.can_id[mask], frames.data[mask], frames.dlc[mask])


def capture(bus: can.BusABC, layout: DbcLayout, writer: RecordingWriter, *, stop: threading.Event,
            finished: Callable[[], bool] | None = None, duration_s: float | None = None,
            max_buffer_frames: int = 500_000, tick_s: float = 0.1, hold_ns: int = 5_000_000,
            drop_columns: frozenset[str] = frozenset(), progress: TextIO | None = sys.stderr) -> CaptureStats:
    """Record `bus` into `writer` until stopped; returns the statistics (the writer stays open).

    `drop_columns` are decoded but not stored (e.g. the A and B angles of an XYZC machine)."""
    buffer = FrameBuffer(max_buffer_frames)
    notifier = can.Notifier(bus, [buffer], timeout=0.05)
    decoder = _Decoder(layout, hold_ns, frozenset(drop_columns))
    stats = CaptureStats()
    show = Progress(progress)
    start = time.monotonic()
    stopped = False
    try:
        while True:
            elapsed = time.monotonic() - start
            if stop.is_set():
                stats.stopped_by = stats.stopped_by or "signal"
            elif duration_s is not None and elapsed >= duration_s:
                stats.stopped_by = "duration"
            elif finished is not None and finished() and len(buffer) == 0:
                stats.stopped_by = "source finished"
            if stats.stopped_by:
                break
            time.sleep(tick_s)
            _write(decoder.feed(buffer.take(), stats, final=False), writer, stats, buffer)
            writer.flush_if_due()
            show.show(stats, time.monotonic() - start)
        notifier.stop()
        stopped = True
        _write(decoder.feed(buffer.take(), stats, final=True), writer, stats, buffer)
    except OutputError as exc:  # the disk refused a write: the file keeps what was flushed before
        stats.error = str(exc)
        stats.stopped_by = "write error"
    finally:
        if not stopped:
            notifier.stop()
        stats.wall_s = time.monotonic() - start
        stats.frames = buffer.received
        _update_drops(stats, buffer)
        if not stats.error:
            writer.dropped_frames = stats.dropped_frames
        show.show(stats, stats.wall_s, final=True)
    return stats


def _update_drops(stats: CaptureStats, buffer: FrameBuffer) -> None:
    stats.bad_frames = buffer.bad_frames
    stats.dropped_frames = (buffer.dropped + buffer.error_frames + buffer.bad_frames + stats.late_frames
                            + stats.lost_frames)



def _write(streams: dict, writer: RecordingWriter, stats: CaptureStats, buffer: FrameBuffer) -> None:
    for name, table in streams.items():
        writer.write(name, table)
        stats.samples += len(table)
        stats.streams[name] = stats.streams.get(name, 0) + len(table)
    stats.frames = buffer.received
    _update_drops(stats, buffer)
    writer.dropped_frames = stats.dropped_frames


def record_bus(bus: can.BusABC, out, *, dbc: str | None = None, metadata: dict[str, str] | None = None,
               attachments: dict[str, bytes] | None = None, overwrite: bool = False,
               stop: threading.Event | None = None, finished: Callable[[], bool] | None = None,
               duration_s: float | None = None, flush_interval_s: float = 1.0,
               max_buffer_frames: int = 500_000, drop_columns: frozenset[str] = frozenset(),
               progress: TextIO | None = sys.stderr) -> dict:
    """Record a live bus into a new recording `out`; returns a summary (frames, samples, drops, ...)."""
    layout = DbcLayout(dbc)
    attachments = {**(attachments or {}), layout.path.name: layout.source_text()}
    metadata = {"dbc": layout.path.name, **(metadata or {})}
    metadata.setdefault("start_time", time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()))
    # lz4: live batches are small and repetitive (line, status), so they shrink well at no cost that matters
    writer = RecordingWriter(out, metadata=metadata, attachments=attachments, overwrite=overwrite,
                             flush_interval_s=flush_interval_s, compression="lz4")
    try:
        stats = capture(bus, layout, writer, stop=stop or threading.Event(), finished=finished,
                        duration_s=duration_s, max_buffer_frames=max_buffer_frames, drop_columns=drop_columns,
                        progress=progress)
    finally:
        try:
            writer.close()
        except OutputError as exc:  # the final flush hit a full disk: the earlier chunks are intact
            stats_error = str(exc)
        else:
            stats_error = ""
    summary = {"out": str(out), **stats.as_dict()}
    if stats_error and not summary["error"]:
        summary["error"] = stats_error
        summary["stopped_by"] = "write error"
    return summary
