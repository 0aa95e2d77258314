"""`feedlog record --source mtconnect --url http://AGENT:5000 [--device NAME] -o REC.mcap`: a live agent.

1. `/probe`: the data items are chosen by type, subType and component, never by name (`plan_items`):
   `POSITION` of the Linear components X/Y/Z and `ANGLE` of the Rotary components A/B/C (ACTUAL into
   `axes`, COMMANDED into `axes_commanded` where both exist; an axis with only COMMANDED positions
   gives those to `axes`), `PATH_FEEDRATE` (ACTUAL -> `feed.feed_mm_min`, COMMANDED or PROGRAMMED ->
   `feed.requested_feed_mm_min`), `LINE_NUMBER` (absolute; else the older `LINE`) -> `line.line`, and
   `EXECUTION`, `PROGRAM`, `TOOL_NUMBER`, `BLOCK` as text into `events` (name, value). Units come from
   each data item's `units` (MILLIMETER, INCH, DEGREE, RADIAN, MILLIMETER/SECOND, ...), converted to
   mm, deg and mm/min.
2. `/current`: the state the agent holds when the recording starts, stamped at its `creationTime`,
   and the sequence number to continue from.
3. `/sample?from=SEQ&interval=MS&count=N&heartbeat=MS`: a multipart stream of Streams documents
   (`--poll`: plain requests `/sample?from=SEQ&count=N` every `--interval-ms` instead).

Sequence numbers are tracked: observations already received are never taken twice, a dropped or
silent connection, or a damaged document (malformed XML; three in a row at the same sequence end the
recording with one error line), is reopened from the next sequence (nothing the agent still holds
is lost), and a
gap (the agent's buffer overran: `OUT_OF_RANGE`, or a `firstSequence` beyond the next one wanted; an
agent restart: a new `instanceId`) is written to the `gaps` stream (t_ns = last observation before,
end_t_ns = first one after, lost = sequences lost or -1 when unknown, reason) and counted in
`dropped_frames`. Observations become rows as `feedlog import` does with saved responses: one row per
distinct time at which a member of the stream changed, every column holding its last value; a stream
with an `UNAVAILABLE` member has no rows until it has a value again (counted, never filled).
The HTTP reading runs in a thread; the main loop writes through `RecordingWriter` (a chunk flushed
at least every second, so kill -9 loses at most about a second) and stops on SIGINT/SIGTERM.
"""

from __future__ import annotations

import argparse
import queue
import re
import sys
import threading
import time
from typing import Any, TextIO

import numpy as np

from feedlog.errors import IngestError, OutputError
from feedlog.ingest.mtconnect_agent import (AgentClient, AgentUnreachable, DataItem, Device, Observation,
                                            StreamsDocument, parse_probe, parse_streams)
from feedlog.ingest.live_rows import Column, Gap, Plan, Progress, RowSession, Stats, iso, record_from_args, stop_reason
from feedlog.ingest.mtconnect_obs import parse_times
from feedlog.ingest.writer import RecordingWriter

STOPS_ON_EVENT = True  # cli_record: SIGINT/SIGTERM set args.stop_event

LENGTH_UNITS = {"MILLIMETER": 1.0, "INCH": 25.4, "": 1.0}           # MTConnect's standard is MILLIMETER
ANGLE_UNITS = {"DEGREE": 1.0, "RADIAN": 180.0 / np.pi, "": 1.0}      # ... and DEGREE
FEED_UNITS = {"MILLIMETER/SECOND": 60.0, "": 60.0, "MILLIMETER/MINUTE": 1.0, "INCH/MINUTE": 25.4,
              "INCH/SECOND": 25.4 * 60.0, "FOOT/MINUTE": 304.8}
EVENT_TYPES = {"EXECUTION": "execution", "PROGRAM": "program", "TOOL_NUMBER": "tool_number", "BLOCK": "block",
               "TOOL_ASSET_ID": "tool_asset_id"}
_LINEAR = re.compile(r"^([XYZ])\d*$", re.IGNORECASE)
_ROTARY = re.compile(r"^([ABC])\d*$", re.IGNORECASE)
MAX_BAD_DOCUMENTS = 3   # damaged documents in a row for the same sequence before the recording stops


def add_arguments(group: argparse._ArgumentGroup) -> None:
    group.add_argument("--device", help="MTConnect: the agent's device (name or uuid) when it has several")
    group.add_argument("--poll", action="store_true",
                       help="MTConnect: request /sample every --interval-ms instead of streaming (multipart)")


# -- which data items ----------------------------------------------------------------------------------
def _factor(item: DataItem, table: dict[str, float], what: str) -> float:
    if item.units not in table:
        raise IngestError(f"data item {item.id!r} ({item.type}) has units {item.units!r}; feedlog converts "
                          f"{what} from {', '.join(u for u in table if u)}")
    return table[item.units]


def choose_device(devices: list[Device], name: str | None, where: str) -> Device:
    if not devices:
        raise IngestError("the probe lists no devices", file=where)
    if name:
        for device in devices:
            if name in (device.name, device.uuid):
                return device
        raise IngestError(f"no device {name!r} at the agent (devices: {', '.join(d.name for d in devices)})",
                          file=where)
    real = [d for d in devices if any(i.type in ("POSITION", "PATH_FEEDRATE", "LINE_NUMBER", "LINE")
                                      for i in d.items)]
    if len(real) > 1:
        raise IngestError(f"the agent has several devices ({', '.join(d.name for d in real)}): choose one "
                          "with --device", file=where)
    return (real or devices)[0]


def plan_items(device: Device, where: str = "probe") -> Plan:
    """The data items to record and where they go: see the module docstring."""
    plan = Plan(device.name, labels={i.id: " ".join(filter(None, (i.type, i.sub_type or "-", i.units or "-",
                                                                  i.coordinate_system))) for i in device.items})
    axes: dict[str, dict[str, DataItem]] = {}      # axis letter -> subType -> item
    feed: dict[str, DataItem] = {}
    line: dict[str, DataItem] = {}
    for item in device.items:
        sub = item.sub_type
        if item.category == "CONDITION":   # a travel-limit or load condition is a state, not a value
            continue
        if item.type == "POSITION" and item.component == "Linear" and _LINEAR.match(item.component_name):
            axes.setdefault(_LINEAR.match(item.component_name).group(1).lower(), {}).setdefault(sub, item)
        elif item.component == "Rotary" and _ROTARY.match(item.component_name) and (
                item.type == "ANGLE" or (item.type == "POSITION" and item.units in ("DEGREE", "RADIAN"))):
            axes.setdefault(_ROTARY.match(item.component_name).group(1).lower(), {}).setdefault(sub, item)
        elif item.type == "PATH_FEEDRATE" and sub in ("", "ACTUAL", "COMMANDED", "PROGRAMMED"):
            feed.setdefault("ACTUAL" if sub in ("", "ACTUAL") else "COMMANDED", item)
        elif item.type == "LINE_NUMBER" and sub in ("", "ABSOLUTE"):
            line.setdefault("LINE_NUMBER", item)
        elif item.type == "LINE":
            line.setdefault("LINE", item)
        elif item.type in EVENT_TYPES and item.category == "EVENT":
            plan.events.setdefault(item.id, event_name(item))
    for axis in "xyzabc":
        subs = axes.get(axis)
        if not subs:
            continue
        linear = axis in "xyz"
        unit, table = ("mm", LENGTH_UNITS) if linear else ("deg", ANGLE_UNITS)
        primary = subs.get("ACTUAL") or subs.get("") or subs.get("COMMANDED") or next(iter(subs.values()))
        plan.columns[primary.id] = Column("axes", f"{axis}_{unit}", _factor(primary, table, "positions"))
        commanded = subs.get("COMMANDED")
        if commanded is not None and commanded is not primary:
            plan.columns[commanded.id] = Column("axes_commanded", f"{axis}_{unit}",
                                                _factor(commanded, table, "positions"))
    if "ACTUAL" in feed:
        plan.columns[feed["ACTUAL"].id] = Column("feed", "feed_mm_min", _factor(feed["ACTUAL"], FEED_UNITS, "feeds"))
    if "COMMANDED" in feed:
        plan.columns[feed["COMMANDED"].id] = Column("feed", "requested_feed_mm_min",
                                                    _factor(feed["COMMANDED"], FEED_UNITS, "feeds"))
    chosen_line = line.get("LINE_NUMBER") or line.get("LINE")
    if chosen_line is not None:
        plan.columns[chosen_line.id] = Column("line", "line", 0.0)
    if not plan.columns:
        kinds = sorted({f"{i.component}/{i.type}" for i in device.items})[:20]
        raise IngestError(f"device {device.name!r} has no axis positions, path feed or line number (found: "
                          f"{', '.join(kinds) or 'no data items'})", file=where)
    if not any(c.stream == "axes" for c in plan.columns.values()):
        plan.notes.append("no axis positions: align and diagnose use the line stream")
    by_id = {i.id: i for i in device.items}
    for item_id in plan.columns:
        item = by_id[item_id]
        if item.native_units and item.units and item.native_units != item.units:
            plan.notes.append(f"{item_id} ({item.type}): the agent converts the adapter's {item.native_units} "
                              f"to {item.units}; a wrong nativeUnits scales every value")
    return plan


def event_name(item: DataItem) -> str:
    """The `events` name of an event data item: its type's name, with its subType where it has one
    (a Mazak lists PROGRAM and PROGRAM subType x:SUB: `program` and `program_sub`)."""
    sub = item.sub_type.rsplit(":", 1)[-1].lower()
    return EVENT_TYPES[item.type] + (f"_{sub}" if sub else "")


# -- observations -> rows --------------------------------------------------------------------------------
def observation_times(observations: list[Observation], default_ns: int) -> np.ndarray:
    """int64 ns of each observation's timestamp; one without a usable time takes `default_ns`."""
    if not observations:
        return np.zeros(0, dtype=np.int64)
    t, ok = parse_times(np.array([o.timestamp for o in observations], dtype=object))
    return np.where(ok, t, default_ns)


# -- the HTTP side ----------------------------------------------------------------------------------------
class _Resync(Exception):
    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


class AgentReader(threading.Thread):
    """Reads the agent from sequence `next_seq` on and puts ("doc", StreamsDocument), ("gap", Gap),
    ("reconnect", reason) and ("fatal", exception) on `out`; stops when `stop` is set."""

    def __init__(self, client: AgentClient, device: str, *, next_seq: int, instance: str, interval_ms: int,
                 poll: bool, out: queue.Queue, stop: threading.Event, count: int = 10_000,
                 heartbeat_ms: int = 1000) -> None:
        super().__init__(name="feedlog-mtconnect", daemon=True)
        self.client = client
        self.device = device
        self.next_seq = next_seq
        self.instance = instance
        self.interval_ms = interval_ms
        self.poll = poll
        self.out = out
        self.stop_event = stop
        self.count = count
        self.heartbeat_ms = heartbeat_ms
        self.reconnects = 0
        self.bad_documents = 0      # damaged documents in a row at the same sequence
        self.bad_at = -1

    def _put(self, item) -> None:
        while not self.stop_event.is_set():
            try:
                self.out.put(item, timeout=0.2)   # a full queue holds the reader back: the agent keeps the data
                return
            except queue.Full:
                continue
        self.out.put(item)  # stopping: the main loop drains the queue

    def run(self) -> None:
        backoff = 0.1
        resync: str | None = None
        try:
            while not self.stop_event.is_set():
                try:
                    if resync is not None:
                        self._resync(resync)
                        resync = None
                    self._poll() if self.poll else self._stream()
                    backoff = 0.1
                except AgentUnreachable as exc:
                    if self.stop_event.is_set():
                        break
                    self.reconnects += 1
                    self._put(("reconnect", str(exc)))
                    self.stop_event.wait(backoff)
                    backoff = min(backoff * 2, 5.0)
                except _Resync as exc:
                    resync = exc.reason
                    self.stop_event.wait(0.05)   # an agent that keeps refusing must not make this spin
        except Exception as exc:  # noqa: BLE001 - handed to the main loop, which ends the recording
            if not self.stop_event.is_set():  # (closing the connection to stop breaks reads in any way)
                self._put(("fatal", exc))

    def _path(self, what: str) -> str:
        return f"/{self.device}/{what}" if self.device else f"/{what}"

    def _stream(self) -> None:
        path = self._path(f"sample?from={self.next_seq}&interval={self.interval_ms}&count={self.count}"
                          f"&heartbeat={self.heartbeat_ms}")
        for response in self.client.stream(path):
            self._accept(response.status, response.body, path)
            if self.stop_event.is_set():
                return
        raise AgentUnreachable("the agent ended the stream")

    def _poll(self) -> None:
        while not self.stop_event.is_set():
            started = time.monotonic()
            path = self._path(f"sample?from={self.next_seq}&count={self.count}")
            response = self.client.get(path)
            got = self._accept(response.status, response.body, path)
            if got < self.count:
                self.stop_event.wait(max(0.0, self.interval_ms / 1000 - (time.monotonic() - started)))

    def _accept(self, status: int, body: bytes, path: str) -> int:
        try:
            doc = parse_streams(body, where=self.client.url + path)
        except IngestError as exc:  # a damaged document: ask for the same sequences again, a few times
            self.bad_documents = self.bad_documents + 1 if self.bad_at == self.next_seq else 1
            self.bad_at = self.next_seq
            if self.bad_documents >= MAX_BAD_DOCUMENTS:
                raise IngestError(f"{exc.message} ({self.bad_documents} times in a row from sequence "
                                  f"{self.next_seq})", file=exc.file, line=exc.line) from None
            raise AgentUnreachable(f"a damaged document ({exc.message})") from None
        if doc.errors:
            codes = [code for code, _ in doc.errors]
            if "OUT_OF_RANGE" in codes:
                raise _Resync("buffer overrun (OUT_OF_RANGE)")
            raise IngestError(f"the agent answered with an error: "
                              f"{'; '.join(f'{c}: {t}' for c, t in doc.errors)}", file=self.client.url + path)
        if status != 200:
            raise IngestError(f"the agent answered HTTP {status}", file=self.client.url + path)
        instance = doc.header.get("instanceId", "")
        if instance and self.instance and instance != self.instance:
            raise _Resync("the agent restarted (new instanceId)")
        first = doc.header_int("firstSequence")
        if first is not None and first > self.next_seq:
            raise _Resync("buffer overrun (firstSequence beyond the next sequence wanted)")
        fresh = [o for o in doc.observations if o.sequence >= self.next_seq]
        doc.observations = fresh
        nxt = doc.header_int("nextSequence")
        top = max((o.sequence for o in fresh), default=self.next_seq - 1) + 1
        self.next_seq = max(self.next_seq, top, nxt or 0)
        self._put(("doc", doc))
        return len(fresh)

    def _resync(self, reason: str) -> None:
        """After an overrun or a restart: continue from the oldest sequence the agent still holds,
        starting from the state the agent had there (`current?at=SEQ`): values that changed inside
        the gap must not be carried over from before it."""
        response = self.client.get(self._path("current"))  # AgentUnreachable: run() retries
        doc = parse_streams(response.body, where=self.client.url + self._path("current"))
        if doc.errors:
            raise IngestError(f"the agent answered /current with an error: {doc.errors[0][0]}: {doc.errors[0][1]}",
                              file=self.client.url)
        instance = doc.header.get("instanceId", "")
        first = doc.header_int("firstSequence") or 1
        agent_next = doc.header_int("nextSequence")
        if instance and instance != self.instance:
            lost, reason = -1, "the agent restarted (new instanceId): what it saw before is unknown"
            self.instance = instance
        elif agent_next is not None and self.next_seq > agent_next:
            lost, reason = -1, "the agent's sequence numbers went back: what it saw before is unknown"
        elif first > self.next_seq:
            lost = first - self.next_seq
        else:
            return                      # nothing was lost after all: resume where we were
        self._put(("gap", Gap(lost, reason)))
        self.next_seq = first
        path = self._path(f"current?at={first}")
        state = None
        try:
            at = self.client.get(path)
            if at.status == 200:
                state = parse_streams(at.body, where=self.client.url + path)
                state = None if state.errors else state
        except IngestError:
            state = None                # an agent without `at`: the state is unknown until values arrive
        self._put(("state", state))


# -- the recorder --------------------------------------------------------------------------------------
class _Session(RowSession):
    """`begin(current)`: the agent's state when the recording starts. It is applied at the time of the
    first new observation: the observations carry the adapter's clock, which need not be the agent's
    (the header's creationTime); stamped by the agent's clock, a state could lie after everything
    that follows and push it all to one time. With no new observation at all it is applied at the
    header's time when the recording ends."""

    start_state: list[Observation] | None = None
    start_ns: int = 0

    def begin(self, doc: StreamsDocument, stamp_ns: int) -> None:
        self.start_state, self.start_ns = list(doc.observations), stamp_ns

    def _apply_start(self, t_ns: int) -> None:
        state, self.start_state = self.start_state, None
        if state:
            self.observations(state, np.full(len(state), t_ns, dtype=np.int64), counted=False)

    def document(self, doc: StreamsDocument) -> None:
        """A streams document's observations -> rows."""
        times = observation_times(doc.observations, _header_time(doc) or time.time_ns())
        if self.start_state is not None and len(times):
            self._apply_start(int(times.min()))
        self.observations(doc.observations, times)

    def gap(self, gap: Gap) -> None:
        self.start_state = None      # what held at the start no longer does; the resume state follows
        super().gap(gap)

    def finish(self) -> None:
        if self.start_state is not None:
            self._apply_start(self.start_ns)
        super().finish()


def _header_time(doc: StreamsDocument) -> int | None:
    text = doc.header.get("creationTime", "")
    if not text:
        return None
    t, ok = parse_times(np.array([text], dtype=object))
    return int(t[0]) if ok[0] else None


def _get(client: AgentClient, path: str) -> bytes:
    try:
        response = client.get(path)
    except AgentUnreachable as exc:
        raise IngestError(f"cannot reach the MTConnect agent at {client.url}: {exc}") from None
    if response.status != 200:
        try:
            doc = parse_streams(response.body, where=client.url + path)
        except IngestError:
            doc = StreamsDocument()
        detail = "; ".join(f"{c}: {t}" for c, t in doc.errors) or response.body[:80].decode("latin-1", "replace")
        raise IngestError(f"the agent answered HTTP {response.status} ({detail})", file=client.url + path)
    return response.body


def record_agent(url: str, out, *, device: str | None = None, interval_ms: int = 100, poll: bool = False,
                 metadata: dict[str, str] | None = None, attachments: dict[str, bytes] | None = None,
                 overwrite: bool = False, stop: threading.Event | None = None, duration_s: float | None = None,
                 flush_interval_s: float = 1.0, max_queue: int = 10_000,
                 progress: TextIO | None = sys.stderr) -> dict[str, Any]:
    """Record an MTConnect agent into a new recording `out`; returns a summary."""
    if not 1 <= interval_ms <= 600_000:
        raise IngestError(f"--interval-ms {interval_ms} must be from 1 to 600000")
    client = AgentClient(url, timeout_s=max(10.0, 3 * interval_ms / 1000))
    probe_path = "/probe"   # every device: a wrong --device is answered with the list of the right ones
    devices = parse_probe(_get(client, probe_path), where=client.url + probe_path)
    dev = choose_device(devices, device, client.url + probe_path)
    plan = plan_items(dev, client.url + probe_path)
    name = dev.name
    current_path = f"/{name}/current"
    current = parse_streams(_get(client, current_path), where=client.url + current_path)
    if current.errors:
        raise IngestError(f"the agent answered /current with an error: {current.errors[0][0]}", file=client.url)
    next_seq = current.header_int("nextSequence")
    if next_seq is None:
        raise IngestError("the /current response has no nextSequence in its header", file=client.url + current_path)
    start_ns = _header_time(current) or time.time_ns()
    meta = {"controller": "mtconnect", "units": "mm, deg, mm/min", **{k: v for k, v in (metadata or {}).items() if v},
            "source": "mtconnect", "agent": client.url, "device": name, "device_uuid": dev.uuid,
            "interval_ms": str(interval_ms), "mode": "poll" if poll else "stream",
            "mtconnect_instance": current.header.get("instanceId", ""),
            "mtconnect_version": current.header.get("version", ""), "data_items": plan.describe(),
            "start_time": iso(start_ns)}
    if plan.notes:
        meta["notes"] = "; ".join(filter(None, [meta.get("notes", ""), *plan.notes]))
    writer = RecordingWriter(out, metadata=meta, attachments=attachments or {}, overwrite=overwrite,
                             flush_interval_s=flush_interval_s, compression="lz4")
    stats = Stats()
    show = Progress(progress)
    stop = stop or threading.Event()
    halt = threading.Event()
    items: queue.Queue = queue.Queue(maxsize=max_queue)
    reader = AgentReader(client, name, next_seq=next_seq, instance=current.header.get("instanceId", ""),
                         interval_ms=interval_ms, poll=poll, out=items, stop=halt)
    session = _Session(plan, writer, stats)
    start, cpu0 = time.monotonic(), time.process_time()
    fatal: BaseException | None = None
    try:
        session.begin(current, start_ns)
        reader.start()
        while True:
            stats.stopped_by = stop_reason(stop, duration_s, time.monotonic() - start)
            if stats.stopped_by or fatal is not None:
                break
            try:
                fatal = _handle(items.get(timeout=0.1), session, stats)
            except queue.Empty:
                pass
            session.release_due()
            writer.flush_if_due()
            show.show(stats, time.monotonic() - start)
        halt.set()
        client.close()
        reader.join(timeout=15)
        while True:  # whatever the reader had received is written too
            try:
                fatal = _handle(items.get_nowait(), session, stats) or fatal
            except queue.Empty:
                break
        session.finish()
    except OutputError as exc:
        stats.error = str(exc)
        stats.stopped_by = "write error"
    finally:
        halt.set()
        client.close()
        stats.reconnects = reader.reconnects
        stats.wall_s = time.monotonic() - start
        stats.cpu_s = round(time.process_time() - cpu0, 3)
        try:
            writer.close()
        except OutputError as exc:
            stats.error = stats.error or str(exc)
            stats.stopped_by = "write error"
        show.show(stats, stats.wall_s, final=True)
    if fatal is not None:
        if isinstance(fatal, IngestError):
            raise IngestError(f"{fatal} (the recording keeps what arrived before: {out})") from None
        raise fatal
    return {"out": str(out), "agent": client.url, "device": name, **stats.as_dict()}


def _handle(item, session: _Session, stats: Stats) -> BaseException | None:
    kind, value = item
    if kind == "doc":
        session.document(value)
    elif kind == "gap":
        session.gap(value)
    elif kind == "state":
        session.state(value.observations if value is not None else None)
    elif kind == "reconnect":
        stats.reconnects += 1
    elif kind == "fatal":
        return value
    return None


def record(args: argparse.Namespace) -> dict[str, Any]:
    return record_from_args(args, record_agent, "mtconnect", "http://AGENT:PORT", device=args.device, poll=args.poll)
