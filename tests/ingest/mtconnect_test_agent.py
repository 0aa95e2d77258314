"""A small MTConnect agent for tests: the standard library's HTTP server on 127.0.0.1, replaying a bundled
feedlog recording at its own pace.

It speaks the part of the agent protocol a client uses: `/probe`, `/current`, `/sample?from=&count=`
(one document) and `/sample?from=&count=&interval=&heartbeat=` (a `multipart/x-mixed-replace` stream,
HTTP/1.1 chunked), each also under `/DEVICE/...`. Observations go into a ring buffer of `buffer_size`
sequence numbers as their time comes (only values that change, as an agent reports them). A request
or a stream asking for a sequence the buffer no longer holds gets an `OUT_OF_RANGE` error.

Faults the tests inject: `stall_at_seq` (the stream stops sending for `stall_s` once, so a small buffer
overruns under it: the agent then sends `OUT_OF_RANGE` and ends the stream), `drop_at_seq` (the stream
sends half a part and the connection is cut, once), `probe_body` (serve these bytes as the probe).
`corrupt_at_seq` with `corrupt_times` (that many parts from there on are malformed XML).
`/current?at=SEQ` answers the state at a sequence the buffer still holds.
Run as a script (`python -m tests.ingest.mtconnect_test_agent REC.mcap PORT`) it serves until killed.
"""

from __future__ import annotations

import collections
import socket
import sys
import threading
import time
import urllib.parse
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np

from feedlog.ingest import read_recording

BOUNDARY = "c0ffee5eed0f7e57b0unda4y"
NS = 'xmlns="urn:mtconnect.org:MTConnectStreams:1.3"'


def iso(t_ns: int) -> str:
    s, ns = divmod(t_ns, 1_000_000_000)
    return time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(s)) + f".{ns // 1000:06d}Z"


# data item id -> (component element, component name, category, type, subType, units)
ITEMS = {
    "Xact": ("Linear", "X", "SAMPLE", "POSITION", "ACTUAL", "MILLIMETER"),
    "Xcmd": ("Linear", "X", "SAMPLE", "POSITION", "COMMANDED", "MILLIMETER"),
    "Yact": ("Linear", "Y", "SAMPLE", "POSITION", "ACTUAL", "MILLIMETER"),
    "Ycmd": ("Linear", "Y", "SAMPLE", "POSITION", "COMMANDED", "MILLIMETER"),
    "Zact": ("Linear", "Z", "SAMPLE", "POSITION", "ACTUAL", "MILLIMETER"),
    "Zcmd": ("Linear", "Z", "SAMPLE", "POSITION", "COMMANDED", "MILLIMETER"),
    "pf": ("Path", "path", "SAMPLE", "PATH_FEEDRATE", "ACTUAL", "MILLIMETER/SECOND"),
    "pfo": ("Path", "path", "SAMPLE", "PATH_FEEDRATE", "OVERRIDE", "PERCENT"),
    "ln": ("Path", "path", "EVENT", "LINE_NUMBER", "ABSOLUTE", ""),
    "exec": ("Path", "path", "EVENT", "EXECUTION", "", ""),
    "pgm": ("Path", "path", "EVENT", "PROGRAM", "", ""),
    "tool": ("Path", "path", "EVENT", "TOOL_NUMBER", "", ""),
    "avail": ("Device", "", "EVENT", "AVAILABILITY", "", ""),
}
ROTARY_ITEMS = {f"{a}act": ("Rotary", a, "SAMPLE", "ANGLE", "ACTUAL", "DEGREE") for a in "ABC"}


def synthetic_table(seconds: float, rate_hz: float = 100.0) -> dict[str, np.ndarray]:
    """Six axes that all move every sample, a feed and a line that changes every second (benchmarks)."""
    t = np.arange(int(seconds * rate_hz)) / rate_hz
    return {"t_ns": np.round(t * 1e9).astype(np.int64), "x": 50 * np.sin(t), "y": 40 * np.cos(0.7 * t),
            "z": -5 + np.sin(3 * t), "a": 30 * np.sin(0.2 * t), "b": 20 * np.cos(0.3 * t), "c": 10.0 * t,
            "feed": 1000 + 500 * np.sin(t), "line": (10 + t).astype(np.int64)}


def probe_xml(device: str = "LinuxCNC", items: dict = ITEMS, extra_devices: tuple[str, ...] = ()) -> bytes:
    def one(name: str, ident: str) -> str:
        comps: dict[tuple[str, str], list[str]] = {}
        top = []
        for item_id, (comp, cname, cat, typ, sub, units) in items.items():
            attrs = f'category="{cat}" id="{ident}{item_id}" type="{typ}"'
            attrs += f' subType="{sub}"' if sub else ""
            attrs += f' units="{units}"' if units else ""
            (top if comp == "Device" else comps.setdefault((comp, cname), [])).append(f"<DataItem {attrs}/>")
        body = "".join(f'<{comp} id="{ident}{comp}{cname}" name="{cname}"><DataItems>{"".join(ds)}</DataItems></{comp}>'
                       for (comp, cname), ds in comps.items())
        return (f'<Device id="{ident}d" name="{name}" uuid="{name}-uuid"><DataItems>{"".join(top)}</DataItems>'
                f'<Components><Axes id="{ident}ax" name="base"><Components>{body}</Components></Axes></Components>'
                "</Device>")

    devices = one(device, "") + "".join(one(name, f"{name}_") for name in extra_devices)
    return ('<?xml version="1.0" encoding="UTF-8"?>\n<MTConnectDevices xmlns="urn:mtconnect.org:MTConnectDevices:1.3">'
            '<Header creationTime="2026-01-01T00:00:00Z" sender="test" instanceId="1" version="1.3.0" '
            f'bufferSize="4096" assetBufferSize="0" assetCount="0"/><Devices>{devices}</Devices>'
            "</MTConnectDevices>").encode()


def replay_table(path: Path, rate_hz: float) -> dict[str, np.ndarray]:
    """The recording's axes, feed and line at `rate_hz` (every k-th 1 kHz sample), times from 0."""
    rec = read_recording(path)
    axes, feed, line = rec.streams["axes"], rec.streams["feed"], rec.streams["line"]
    t = axes["t_ns"].to_numpy()
    step = max(1, int(round(1e9 / rate_hz / np.median(np.diff(t)))))
    pick = np.arange(0, len(t), step)
    at = lambda table: np.searchsorted(table["t_ns"].to_numpy(), t[pick], side="right") - 1  # noqa: E731
    return {"t_ns": t[pick] - t[0], "x": axes["x_mm"].to_numpy()[pick], "y": axes["y_mm"].to_numpy()[pick],
            "z": axes["z_mm"].to_numpy()[pick], "feed": feed["feed_mm_min"].to_numpy()[at(feed)],
            "line": line["line"].to_numpy()[at(line)]}


class ReplayAgent:
    def __init__(self, recording: Path | None, *, rate_hz: float = 100.0, buffer_size: int = 8192,
                 device: str = "LinuxCNC", start_delay_s: float = 0.8, port: int = 0,
                 table: dict[str, np.ndarray] | None = None) -> None:
        self.table = table if table is not None else replay_table(recording, rate_hz)
        self.items = {**ITEMS, **{k: v for k, v in ROTARY_ITEMS.items() if k[0].lower() in self.table}}
        self.device = device
        self._init_agent(buffer_size=buffer_size, start_delay_s=start_delay_s, port=port)
        self.observations = self._observations()

    def _init_agent(self, *, buffer_size: int, start_delay_s: float, port: int, initial_ns: int | None = None) -> None:
        """The agent's buffer, fault switches and HTTP server (shared with agents replaying other data)."""
        self.buffer_size = buffer_size
        self.start_delay_s = start_delay_s
        self.instance = str(int(time.time()))
        self.lock = threading.RLock()
        self.produced = 0       # observations replayed so far (the producer and a restart share it)
        self.buffer: collections.deque = collections.deque(maxlen=buffer_size)   # (seq, item, t_ns, text)
        self.latest: dict[str, tuple[int, str, int, str]] = {}
        self.history: list[tuple[int, str, int, str]] = []    # every observation (for current?at=)
        self.next_seq = 1
        self.stall_at_seq: int | None = None
        self.stall_s = 0.0
        self.drop_at_seq: int | None = None
        self.probe_body: bytes | None = None
        self.corrupt_at_seq: int | None = None
        self.corrupt_times = 0
        self.generation = 0     # restarts so far (a stream of an earlier generation ends)
        self.events: list[tuple] = []      # ("stall"|"drop"|"out_of_range", seq, first_seq)
        self.finished = threading.Event()
        self.closed = threading.Event()
        self.t0_ns = (time.time_ns() // 1_000_000 + int(start_delay_s * 1000)) * 1_000_000
        now = time.time_ns() // 1000 * 1000 if initial_ns is None else initial_ns
        for item in self.items:
            self._add(item, now, "UNAVAILABLE" if item != "avail" else "AVAILABLE")
        self.server = ThreadingHTTPServer(("127.0.0.1", port), self._handler())
        self.server.daemon_threads = True
        self.port = self.server.server_address[1]
        self.url = f"http://127.0.0.1:{self.port}"

    # -- the replayed data ----------------------------------------------------------------------------
    def _observations(self) -> list[tuple[int, str, str]]:
        """(t_ns from the start, item, text) of every change, in order."""
        out, last = [], {}
        tab = self.table
        for i in range(len(tab["t_ns"])):
            t = int(tab["t_ns"][i])
            values = {"Xact": tab["x"][i], "Xcmd": tab["x"][i], "Yact": tab["y"][i], "Ycmd": tab["y"][i],
                      "Zact": tab["z"][i], "Zcmd": tab["z"][i], "pf": tab["feed"][i] / 60.0, "pfo": 100.0,
                      "ln": int(tab["line"][i]), "exec": "ACTIVE", "pgm": "replay.ngc", "tool": 1,
                      **{f"{a}act": tab[a.lower()][i] for a in "ABC" if a.lower() in tab}}
            for item, value in values.items():
                text = repr(float(value)) if isinstance(value, (float, np.floating)) else str(value)
                if last.get(item) != text:
                    out.append((t, item, text))
                    last[item] = text
        out.append((int(tab["t_ns"][-1]) + 10_000_000, "exec", "READY"))
        return out

    def _add(self, item: str, t_ns: int, text: str) -> None:
        with self.lock:
            entry = (self.next_seq, item, t_ns, text)
            self.buffer.append(entry)
            self.history.append(entry)
            self.latest[item] = entry
            self.next_seq += 1

    def _produce(self) -> None:
        while time.time_ns() < self.t0_ns and not self.closed.is_set():
            time.sleep(0.005)
        while not self.closed.is_set():
            with self.lock:     # (an agent replaying a log keeps its times)
                due = self._add_due(time.time_ns())
            if due is None:
                self.finished.set()
                return
            time.sleep(min(0.002, max(0.0, (due - time.time_ns()) / 1e9)))

    def _add_due(self, now: int) -> int | None:
        """Add every observation due by `now` (the lock held); the next one's due time, None at the end."""
        while self.produced < len(self.observations):
            t_rel, item, text, *stamp = self.observations[self.produced]
            due = self.t0_ns + t_rel
            if due > now:
                return due
            self._add(item, stamp[0] if stamp else due, text)
            self.produced += 1
        return None

    def restart(self) -> None:
        """As if the agent process restarted: a new instanceId, sequences from 1, an empty buffer
        that starts with the values the adapter sends on connecting (its whole state); open streams end."""
        with self.lock:
            # what the replay was due to send by now is sent first: a replayed observation stamped before
            # the restart must not arrive after the state stamped at it (a flake under load)
            now = time.time_ns() // 1000 * 1000
            self._add_due(now)
            state = {item: entry[3] for item, entry in self.latest.items()}
            self.instance = str(int(self.instance) + 1)
            self.buffer.clear()
            self.history.clear()
            self.latest.clear()
            self.next_seq = 1
            self.generation += 1
            for item, text in state.items():
                self._add(item, now, text)
        self.events.append(("restart", 1, 1))

    def first_seq(self) -> int:
        return self.buffer[0][0] if self.buffer else self.next_seq

    def values_at(self, t_ns: np.ndarray) -> dict[str, np.ndarray]:
        """The replayed values held at absolute times `t_ns` (forward filled), for comparisons."""
        tab = self.table
        k = np.searchsorted(tab["t_ns"] + self.t0_ns, t_ns, side="right") - 1
        return {name: tab[name][k] for name in ("x", "y", "z", "feed", "line")}

    # -- documents ----------------------------------------------------------------------------------------
    def _header(self, *, next_seq: int | None = None, last: int | None = None) -> str:
        return (f'<Header creationTime="{iso(time.time_ns())}" sender="test" instanceId="{self.instance}" '
                f'version="1.3.0" bufferSize="{self.buffer_size}" firstSequence="{self.first_seq()}" '
                f'lastSequence="{self.next_seq - 1 if last is None else last}" '
                f'nextSequence="{self.next_seq if next_seq is None else next_seq}"/>')

    def _streams(self, entries, *, next_seq: int | None = None) -> bytes:
        by_comp: dict[tuple[str, str], list[str]] = {}
        for seq, item, t_ns, text in entries:
            comp, cname, cat, typ, sub, _ = self.items[item]
            element = "".join(part.capitalize() for part in typ.split("_"))
            category = "Samples" if cat == "SAMPLE" else "Events"
            sub_attr = f' subType="{sub}"' if sub else ""
            by_comp.setdefault((comp, cname), []).append(
                (category, f'<{element} dataItemId="{item}" timestamp="{iso(t_ns)}" sequence="{seq}"{sub_attr}>'
                           f"{text}</{element}>"))
        comps = []
        for (comp, cname), elems in by_comp.items():
            cats = "".join(f"<{cat}>{''.join(e for c, e in elems if c == cat)}</{cat}>"
                           for cat in ("Samples", "Events") if any(c == cat for c, _ in elems))
            comps.append(f'<ComponentStream component="{comp}" name="{cname}" componentId="{comp}{cname}">{cats}'
                         "</ComponentStream>")
        return (f'<?xml version="1.0" encoding="UTF-8"?>\n<MTConnectStreams {NS}>{self._header(next_seq=next_seq)}'
                f'<Streams><DeviceStream name="{self.device}" uuid="{self.device}-uuid">{"".join(comps)}'
                "</DeviceStream></Streams></MTConnectStreams>").encode()

    def _error(self, code: str, text: str) -> bytes:
        return (f'<?xml version="1.0" encoding="UTF-8"?>\n<MTConnectError xmlns="urn:mtconnect.org:MTConnectError:1.3">'
                f'<Header creationTime="{iso(time.time_ns())}" sender="test" instanceId="{self.instance}" '
                f'version="1.3.0" bufferSize="{self.buffer_size}"/><Errors><Error errorCode="{code}">{text}</Error>'
                "</Errors></MTConnectError>").encode()

    def _range(self, start: int, count: int, device: str | None = None) -> tuple[list, int]:
        """The entries of sequences start .. start+count-1 (of `device` only, when given) and the next
        sequence to ask for (the scan's end, whatever the device filter kept)."""
        with self.lock:
            entries = [e for e in self.buffer if start <= e[0] < start + count]
            nxt = entries[-1][0] + 1 if entries else self.next_seq
        return self._of_device(entries, device), nxt

    def serves(self, device: str) -> bool:
        return device == self.device

    def _of_device(self, entries: list, device: str | None) -> list:
        return entries     # one device: everything is its

    # -- HTTP -------------------------------------------------------------------------------------------
    def _handler(self):
        agent = self

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.1"

            def log_message(self, *args) -> None:
                pass

            def _send(self, status: int, body: bytes) -> None:
                self.send_response(status)
                self.send_header("Content-Type", "text/xml")
                self.send_header("Content-Length", str(len(body)))
                self.send_header("Connection", "close")
                self.end_headers()
                self.wfile.write(body)
                self.close_connection = True

            def do_GET(self) -> None:
                url = urllib.parse.urlsplit(self.path)
                parts = [p for p in url.path.split("/") if p]
                device = None
                if len(parts) == 2 and agent.serves(parts[0]):
                    device, parts = parts[0], parts[1:]
                elif len(parts) == 2:
                    return self._send(404, agent._error("NO_DEVICE", f"no device {parts[0]}"))
                query = dict(urllib.parse.parse_qsl(url.query))
                what = parts[0] if parts else "probe"
                if what == "probe":
                    return self._send(200, agent.probe_body if agent.probe_body is not None else
                                      probe_xml(agent.device, agent.items))
                if what == "current":
                    with agent.lock:
                        entries = sorted(agent.latest.values())
                        if "at" in query:  # the state at a sequence the buffer holds
                            at = int(query["at"])
                            if not agent.first_seq() <= at < agent.next_seq:
                                return self._send(400, agent._error("OUT_OF_RANGE", "'at' outside the buffer"))
                            state = {e[1]: e for e in agent.history[:at]}   # sequences start at 1
                            entries = sorted(state.values())
                    return self._send(200, agent._streams(agent._of_device(entries, device)))
                if what != "sample":
                    return self._send(400, agent._error("UNSUPPORTED", f"{what}"))
                try:
                    start = int(query.get("from", agent.first_seq()))
                    count = int(query.get("count", 100))
                except ValueError:
                    return self._send(400, agent._error("INVALID_REQUEST", "from and count are integers"))
                if "interval" not in query and agent.stall_at_seq is not None and start > agent.stall_at_seq:
                    agent.stall_at_seq = None      # a slow answer to a poll: the buffer moves on meanwhile
                    agent.events.append(("stall", start, agent.first_seq()))
                    time.sleep(agent.stall_s)
                    return self._send(400, agent._error("OUT_OF_RANGE", f"'from' must be >= {agent.first_seq()}"))
                with agent.lock:
                    out_of_range = start < agent.first_seq() or start > agent.next_seq
                if out_of_range:
                    agent.events.append(("out_of_range", start, agent.first_seq()))
                    return self._send(400, agent._error("OUT_OF_RANGE", f"'from' must be >= {agent.first_seq()}"))
                if "interval" not in query:
                    entries, nxt = agent._range(start, count, device)
                    return self._send(200, agent._streams(entries, next_seq=nxt))
                self._stream(start, count, int(query["interval"]), int(query.get("heartbeat", 10000)), device)

            def _chunk(self, body: bytes) -> None:
                part = (f"--{BOUNDARY}\r\nContent-type: text/xml\r\nContent-length: {len(body)}\r\n\r\n").encode()
                part += body + b"\r\n"
                self.wfile.write(f"{len(part):X}\r\n".encode() + part + b"\r\n")
                self.wfile.flush()

            def _stream(self, pos: int, count: int, interval_ms: int, heartbeat_ms: int,
                        device: str | None = None) -> None:
                self.send_response(200)
                self.send_header("Content-Type", f"multipart/x-mixed-replace;boundary={BOUNDARY}")
                self.send_header("Transfer-Encoding", "chunked")
                self.end_headers()
                last_sent = time.monotonic()
                generation = agent.generation
                try:
                    while not agent.closed.is_set() and generation == agent.generation:
                        with agent.lock:
                            overrun = pos < agent.first_seq()
                        if overrun:
                            agent.events.append(("out_of_range", pos, agent.first_seq()))
                            self._chunk(agent._error("OUT_OF_RANGE", "Client can't keep up with event stream"))
                            break
                        entries, nxt = agent._range(pos, count, device)
                        if agent.drop_at_seq is not None and entries and entries[-1][0] >= agent.drop_at_seq:
                            agent.drop_at_seq = None
                            agent.events.append(("drop", pos, agent.first_seq()))
                            body = agent._streams(entries, next_seq=nxt)
                            self.wfile.write(f"{len(body) + 200:X}\r\n".encode() + body[: len(body) // 2])
                            self.wfile.flush()
                            self.connection.shutdown(socket.SHUT_RDWR)
                            self.close_connection = True
                            return
                        if agent.corrupt_times and entries and entries[-1][0] >= (agent.corrupt_at_seq or 0):
                            agent.corrupt_times -= 1
                            agent.events.append(("corrupt", pos, agent.first_seq()))
                            body = agent._streams(entries, next_seq=nxt)
                            self._chunk(body[: len(body) // 2] + b"<</Streams>")
                            time.sleep(interval_ms / 1000)
                            continue
                        if entries or time.monotonic() - last_sent >= heartbeat_ms / 1000:
                            self._chunk(agent._streams(entries, next_seq=nxt))
                            last_sent = time.monotonic()
                        pos = nxt      # (sequences of other devices are passed over)
                        if agent.stall_at_seq is not None and pos > agent.stall_at_seq:
                            agent.stall_at_seq = None
                            agent.events.append(("stall", pos, agent.first_seq()))
                            time.sleep(agent.stall_s)
                            continue
                        time.sleep(interval_ms / 1000)
                    self.wfile.write(b"0\r\n\r\n")
                except OSError:
                    pass
                self.close_connection = True

        return Handler

    def start(self) -> ReplayAgent:
        threading.Thread(target=self.server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True).start()
        threading.Thread(target=self._produce, daemon=True).start()
        return self

    def close(self) -> None:
        self.closed.set()
        self.server.shutdown()
        self.server.server_close()

    def __enter__(self) -> ReplayAgent:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()


if __name__ == "__main__":
    # REC.mcap PORT [START_DELAY_S], or synthetic:SECONDS PORT [START_DELAY_S] (six axes at 100 Hz, benchmarks)
    source = sys.argv[1]
    table = synthetic_table(float(source.split(":", 1)[1])) if source.startswith("synthetic:") else None
    agent = ReplayAgent(None if table is not None else Path(source), port=int(sys.argv[2]) if len(sys.argv) > 2 else 0,
                        start_delay_s=float(sys.argv[3]) if len(sys.argv) > 3 else 0.5, table=table,
                        buffer_size=131072)
    agent.start()
    print(agent.url, agent.t0_ns, flush=True)
    agent.finished.wait()
    while True:
        time.sleep(1)
