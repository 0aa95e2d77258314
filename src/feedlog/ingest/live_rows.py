"""What the live network sources (MTConnect, OPC UA) share: observations -> rows -> RecordingWriter.

A source turns what it receives into `Observation`s (item id, sequence, timestamp text, value text)
with int64 ns times; `Pivot` makes rows of them as `feedlog import` does with MTConnect files: per
stream, one row per distinct time at which a member changed, each column holding its last value; a
stream with an unavailable member (`UNAVAILABLE`, or no value yet) has no rows until it has one again
(counted, never filled). `RowSession` writes the rows, records gaps (`gaps` stream: t_ns = last
observation before, end_t_ns = first after, lost = items lost or -1 when unknown, reason) and keeps
the statistics the progress line and the summary show.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TextIO

import numpy as np
import pandas as pd

from feedlog.ingest.mtconnect_agent import Observation
from feedlog.ingest.writer import RecordingWriter

UNAVAILABLE = "UNAVAILABLE"


@dataclass(frozen=True)
class Column:
    stream: str
    column: str
    factor: float       # to mm, deg, mm/min; 0 for integers (line)


@dataclass
class Plan:
    """Which source items are recorded where: `columns` (numbers, converted by `factor`) and
    `events` (text into the `events` stream). `labels` describe items for the metadata."""

    name: str = ""
    columns: dict[str, Column] = field(default_factory=dict)     # item id -> column
    events: dict[str, str] = field(default_factory=dict)         # item id -> event name
    labels: dict[str, str] = field(default_factory=dict)         # item id -> what it is (type, unit)
    notes: list[str] = field(default_factory=list)

    def describe(self) -> str:
        parts = [f"{c.stream}.{c.column}={i}" + (f"({self.labels[i]})" if i in self.labels else "")
                 for i, c in self.columns.items()]
        parts += [f"events.{name}={i}" for i, name in self.events.items()]
        return ", ".join(parts)



class Pivot:
    """Turns observations (in sequence order) into rows: per stream, one row per distinct time at
    which one of its members changed, each column holding its last value. The rows of the latest
    time are held back until an observation with a later time arrives (an agent may split the
    observations of one time over two documents) or `release()` is called.

    A stream's columns are fixed by its first row: once every member has a value, or `settle_ns` after
    the first member had one, whichever comes first; members still without a value then are left out
    of the stream for good (`left_out`: a probe may list an axis the machine never reports, which must
    not keep every row of `axes` out)."""

    def __init__(self, plan: Plan, settle_ns: int = 2_000_000_000) -> None:
        self.plan = plan
        self.members: dict[str, list[str]] = {}
        for column in plan.columns.values():
            self.members.setdefault(column.stream, []).append(column.column)
        self.held = {s: {c: np.nan for c in cols} for s, cols in self.members.items()}
        self.last_t: dict[str, int] = {}
        self.pending_t: int | None = None
        self.dirty: set[str] = set()
        self.settle_ns = settle_ns
        self.first_seen: dict[str, int] = {}
        self.fixed: dict[str, list[str]] = {}           # stream -> its columns, once fixed
        self.left_out: list[str] = []                   # stream.column never reported in time
        self.unavailable_rows = 0
        self.bad_values = 0
        self.late = 0

    def feed(self, observations: list[Observation], times: np.ndarray) -> dict[str, pd.DataFrame]:
        rows: dict[str, list[tuple]] = {}
        events: list[tuple[int, str, str]] = []
        order = np.lexsort((np.array([o.sequence for o in observations], dtype=np.int64), times))
        for k in order.tolist():
            obs, t = observations[k], int(times[k])
            if self.pending_t is not None and t != self.pending_t and self.dirty:
                self._emit(self.pending_t, rows)
            self.pending_t = t
            column = self.plan.columns.get(obs.item)
            if column is not None:
                value = self._number(obs.value, column)
                if value is None:
                    continue
                self.held[column.stream][column.column] = value
                self.dirty.add(column.stream)
            elif obs.item in self.plan.events:
                events.append((self._clamp("events", t), self.plan.events[obs.item], obs.value))
        return self._frames(rows, events)

    def forget(self) -> None:
        """After a gap: no value is known until it arrives again."""
        for values in self.held.values():
            for column in values:
                values[column] = np.nan
        self.dirty.clear()

    def release(self) -> dict[str, pd.DataFrame]:
        """The rows held back (the latest time's)."""
        rows: dict[str, list[tuple]] = {}
        if self.dirty and self.pending_t is not None:
            self._emit(self.pending_t, rows)
        return self._frames(rows, [])

    def _frames(self, rows: dict[str, list[tuple]], events: list[tuple[int, str, str]]) -> dict[str, pd.DataFrame]:
        out = {}
        for stream, table in rows.items():
            frame = pd.DataFrame(table, columns=["t_ns", *self.fixed[stream]])
            frame["t_ns"] = frame["t_ns"].astype(np.int64)
            if "line" in frame:
                frame["line"] = frame["line"].astype(np.int64)
            out[stream] = frame
        if events:
            out["events"] = pd.DataFrame({"t_ns": np.array([e[0] for e in events], dtype=np.int64),
                                          "name": [e[1] for e in events], "value": [e[2] for e in events]})
        return out

    def _number(self, text: str, column: Column) -> float | None:
        if text.upper() == UNAVAILABLE:
            return np.nan
        try:
            value = float(text.removeprefix("N").removeprefix("n") if column.factor == 0 else text)
        except ValueError:
            self.bad_values += 1
            return None
        if not np.isfinite(value) or (column.factor == 0 and (value != int(value) or abs(value) > 2**53)):
            self.bad_values += 1
            return None
        return value if column.factor == 0 else value * column.factor

    def _clamp(self, stream: str, t: int) -> int:
        last = self.last_t.get(stream)
        if last is not None and t < last:   # an adapter's own timestamps may step back: keep the order
            self.late += 1
            t = last
        self.last_t[stream] = t
        return t

    def _emit(self, t: int, rows: dict[str, list[tuple]]) -> None:
        for stream in sorted(self.dirty):
            values = self.held[stream]
            columns = self.fixed.get(stream)
            if columns is None:
                known = [c for c, v in values.items() if np.isfinite(v)]
                if known:
                    self.first_seen.setdefault(stream, t)
                if known and (len(known) == len(values) or t - self.first_seen[stream] >= self.settle_ns):
                    columns = self.fixed[stream] = known
                    self.left_out += [f"{stream}.{c}" for c in values if c not in known]
            if columns is not None and all(np.isfinite(values[c]) for c in columns):
                rows.setdefault(stream, []).append((self._clamp(stream, t), *(values[c] for c in columns)))
            else:
                self.unavailable_rows += 1
        self.dirty.clear()



@dataclass
class Gap:
    lost: int            # sequences lost; -1 when unknown (the agent restarted)
    reason: str



@dataclass
class Stats:
    samples: int = 0
    observations: int = 0
    sequences_lost: int = 0
    gaps: list[dict] = field(default_factory=list)
    reconnects: int = 0
    unavailable_rows: int = 0
    bad_values: int = 0
    late_observations: int = 0
    wall_s: float = 0.0
    cpu_s: float = 0.0          # the recorder process's CPU time over the recording (all its threads)
    left_out: list[str] = field(default_factory=list)   # columns the source never reported in time
    stopped_by: str = ""
    error: str = ""
    streams: dict[str, int] = field(default_factory=dict)

    def as_dict(self) -> dict:
        rate = self.samples / self.wall_s if self.wall_s > 0 else 0.0
        return {**self.__dict__, "wall_s": round(self.wall_s, 3), "samples_per_s": round(rate, 1)}


class Progress:
    """One refreshing status line: samples, rate, gaps, reconnects."""

    def __init__(self, stream: TextIO | None, interval_s: float = 0.5) -> None:
        self.stream = stream
        self.interval_s = interval_s
        self._last = 0.0

    def show(self, stats: Stats, elapsed: float, *, final: bool = False) -> None:
        if self.stream is None or (not final and elapsed - self._last < self.interval_s):
            return
        self._last = elapsed
        rate = stats.samples / elapsed if elapsed > 0 else 0.0
        self.stream.write(f"\r{elapsed:7.1f} s  {stats.samples:>9} samples  {rate:>7.0f} samples/s  "
                          f"{len(stats.gaps)} gaps ({stats.sequences_lost} lost)  {stats.reconnects} reconnects"
                          + ("\n" if final else ""))
        self.stream.flush()


def iso(t_ns: int | None) -> str:
    return "" if t_ns is None else pd.Timestamp(t_ns, tz="UTC").isoformat()


class RowSession:
    """A live recorder's state: pivot, writer, gaps waiting for their end time. A gap starts at the
    last observation before it and ends at the first new one after it; the values held before a
    gap are forgotten (they may have changed inside it)."""

    def __init__(self, plan: Plan, writer: RecordingWriter, stats: Stats) -> None:
        self.pivot = Pivot(plan)
        self.writer = writer
        self.stats = stats
        self.last_obs_ns: int | None = None
        self.open_gaps: list[Gap] = []
        self.held_since: float | None = None
        self.resume_state: list[Observation] | None = None

    def observations(self, observations: list[Observation], times: np.ndarray, *, counted: bool = True) -> None:
        """Observations (at int64 ns `times`) -> rows. `counted`: new ones (not a state read back)."""
        if counted:
            self.stats.observations += len(observations)
        if len(times) and self.open_gaps and counted:  # a gap ends with the first new observation
            end = int(times.min())
            self._close_gaps(end)
            if self.resume_state:  # the state where the source resumed: it held at `end`
                state, self.resume_state = self.resume_state, None
                self._feed(state, np.full(len(state), end, dtype=np.int64))
        self._feed(observations, times)
        if len(times):
            self.last_obs_ns = max(int(times.max()), self.last_obs_ns or int(times.max()))

    def _feed(self, observations: list[Observation], times: np.ndarray) -> None:
        self._write(self.pivot.feed(observations, times))
        if self.pivot.dirty and self.held_since is None:
            self.held_since = time.monotonic()
        self.stats.unavailable_rows = self.pivot.unavailable_rows
        self.stats.bad_values = self.pivot.bad_values
        self.stats.late_observations = self.pivot.late
        self.stats.left_out = list(self.pivot.left_out)

    def gap(self, gap: Gap) -> None:
        if gap.lost > 0:
            self.stats.sequences_lost += gap.lost
        if self.open_gaps:  # nothing new arrived since the last gap (a resync that lost the race): one gap
            last = self.open_gaps[-1]
            self.open_gaps[-1] = Gap(-1 if -1 in (last.lost, gap.lost) else last.lost + gap.lost, last.reason)
        else:
            self.open_gaps.append(gap)
        self.writer.dropped_frames = self.stats.sequences_lost
        self._write(self.pivot.release())   # rows before the gap are complete; the held values no longer hold
        self.held_since = None
        self.pivot.forget()

    def state(self, observations: list[Observation] | None) -> None:
        """The source's state where the recording resumes after a gap (None: it could not say):
        applied when the first new observation arrives, at its time."""
        self.resume_state = observations or None

    def _close_gaps(self, end_ns: int) -> None:
        start = self.last_obs_ns if self.last_obs_ns is not None else end_ns
        start = min(start, end_ns)
        for gap in self.open_gaps:
            self.stats.gaps.append({"start": iso(start), "end": iso(end_ns), "span_s": round((end_ns - start) / 1e9, 3),
                                    "lost": gap.lost, "reason": gap.reason})
            self._write({"gaps": pd.DataFrame({"t_ns": np.array([start], dtype=np.int64),
                                               "end_t_ns": np.array([end_ns], dtype=np.int64),
                                               "lost": np.array([gap.lost], dtype=np.int64),
                                               "reason": [gap.reason]})})
        self.open_gaps = []

    def release_due(self, hold_s: float = 0.3) -> None:
        """Write the rows held back once they have waited `hold_s` for a later observation."""
        if self.held_since is not None and time.monotonic() - self.held_since >= hold_s:
            self.held_since = None
            self._write(self.pivot.release())

    def finish(self) -> None:
        self._write(self.pivot.release())
        if self.open_gaps:  # the recording ended before anything arrived after the gap
            self._close_gaps(max(time.time_ns(), self.last_obs_ns or 0))

    def _write(self, streams: dict[str, pd.DataFrame]) -> None:
        for name, table in streams.items():
            self.writer.write(name, table)
            if name != "gaps":
                self.stats.samples += len(table)
                self.stats.streams[name] = self.stats.streams.get(name, 0) + len(table)


def stop_reason(stop, duration_s: float | None, elapsed_s: float) -> str:
    """Why a live recording ends now: "signal" (SIGINT/SIGTERM set `stop`), "duration", or "" (go on)."""
    if stop.is_set():
        return "signal"
    return "duration" if duration_s is not None and elapsed_s >= duration_s else ""


def record_from_args(args, record_fn, source: str, example_url: str, **options):
    """`feedlog record --source SOURCE`: the common arguments (URL, output, program and profile
    attached, interval, duration, stop event, progress) handed to a network source's `record_fn`."""
    import sys

    from feedlog.errors import IngestError
    from feedlog.ingest.cli_record import session_attachments

    if not args.url:
        raise IngestError(f"--source {source} needs --url {example_url}")
    metadata, attachments = session_attachments(args)
    return record_fn(args.url, args.out, interval_ms=args.interval_ms, metadata=metadata, attachments=attachments,
                     overwrite=args.overwrite, stop=getattr(args, "stop_event", None), duration_s=args.duration_s,
                     progress=None if args.quiet else sys.stderr, **options)
