"""`feedlog record --source sim PROGRAM --profile P`: a simulated machine on a virtual CAN bus.

The part program runs through `feedlog.sim.simulate` sampled at `--rate-hz`; every sample becomes the
frames of feedlog_axes.dbc (XY, ZA, BC for five-axis profiles, PATH; one shared 8-bit `seq`). A
player thread sends them on an in-process python-can `virtual` bus at real time times `--speedup`,
stamping each frame with its machine time (like an interface with hardware timestamps, via
`preserve_timestamps`), and the logger records that bus exactly as it records a real one. Machine
time starts at the wall-clock time the recording starts, so the recording's clock does not depend on
the speedup. The player gives up on a frame the bus cannot take within 50 ms (bus overrun); such
frames show up as dropped through the seq counters.
"""

from __future__ import annotations

import argparse
import os
import queue
import sys
import threading
import time
from collections.abc import Iterable, Iterator
from typing import Any

import can
import numpy as np
import pandas as pd
from can.interfaces.virtual import VirtualBus

from feedlog.errors import FeedlogError, IngestError
from feedlog.ingest.can_dbc import CanFrames, DbcLayout
from feedlog.ingest.live import record_bus

MAX_BUS_QUEUE = 200_000  # frames waiting on the virtual bus before the player counts an overrun


STOPS_ON_EVENT = True  # cli_record: SIGINT/SIGTERM set args.stop_event


def add_arguments(group: argparse._ArgumentGroup) -> None:
    group.add_argument("--rate-hz", type=float, default=1000.0, help="samples per second on the bus (default 1000)")
    group.add_argument("--speedup", type=float, default=1.0, help="play K times faster than real time (default 1)")


def sim_frames(series: pd.DataFrame, layout: DbcLayout, *, t0_ns: int = 0, first_seq: int = 0) -> CanFrames:
    """All frames of a simulated series, sample by sample (XY, ZA, [BC], PATH), at t0_ns + t_ns."""
    n = len(series)
    seq = (np.arange(n) + first_seq) % 256
    zeros = np.zeros(n)

    def col(name: str) -> np.ndarray:
        return series[name].to_numpy(np.float64) if name in series else zeros

    feed = np.clip(col("feed_mm_min"), 0.0, None)
    parts = [("FEEDLOG_AXES_XY", {"x_mm": col("x_mm"), "y_mm": col("y_mm")}),
             ("FEEDLOG_AXES_ZA", {"z_mm": col("z_mm"), "a_deg": col("a_deg")})]
    if "b_deg" in series or "c_deg" in series:
        parts.append(("FEEDLOG_AXES_BC", {"b_deg": col("b_deg"), "c_deg": col("c_deg")}))
    parts.append(("FEEDLOG_PATH", {"feed_mm_min": feed, "line": np.clip(col("line"), 0, None),
                                   "in_position": (feed <= 0).astype(np.float64),
                                   "motion_type": np.where(feed > 0, 2.0, 0.0)}))
    data = np.stack([layout.by_name(name).encode({**values, "seq": seq}) for name, values in parts], axis=1)
    ids = np.tile(np.array([layout.by_name(name).frame_id for name, _ in parts], dtype=np.uint32), (n, 1))
    t = np.repeat(series["t_ns"].to_numpy(np.int64) + t0_ns, len(parts))
    return CanFrames(t, ids.ravel(), data.reshape(-1, 8))


class _PlayerBus(VirtualBus):
    """The player's virtual bus: hands each (freshly built) message to the receivers without the deep
    copy `VirtualBus.send` makes, which alone caps sending near 45 k frames/s here."""

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self._check_if_open()
        msg.channel = self.channel_id
        msg.is_rx = True
        full = False
        for bus_queue in self.channel:
            if bus_queue is not self.queue:
                try:
                    bus_queue.put(msg, block=True, timeout=timeout)
                except queue.Full:
                    full = True
        if full:
            raise can.CanOperationError("bus overrun: a receiver's queue is full")


def frame_blocks(series: pd.DataFrame, layout: DbcLayout, *, t0_ns: int = 0,
                 block: int = 10_000) -> Iterator[CanFrames]:
    """`sim_frames` block by block, so a long session never holds all its frames at once."""
    for start in range(0, len(series), block):
        yield sim_frames(series.iloc[start:start + block], layout, t0_ns=t0_ns, first_seq=start)


class Player(threading.Thread):
    """Sends frames on a virtual bus when their machine time is due (real time x speedup)."""

    def __init__(self, blocks: Iterable[CanFrames], channel: str, *, speedup: float, stop: threading.Event) -> None:
        super().__init__(name="feedlog-sim-player", daemon=True)
        self.blocks = blocks
        self.channel = channel
        self.speedup = speedup
        self.stop_event = stop
        self.sent = 0
        self.overruns = 0
        self.done = threading.Event()

    def run(self) -> None:
        bus = _PlayerBus(channel=self.channel, preserve_timestamps=True)
        try:
            start = time.monotonic()
            first_ns = None
            for frames in self.blocks:
                if first_ns is None and len(frames):
                    first_ns = int(frames.t_ns[0])
                if self.stop_event.is_set():
                    break
                self._play(bus, frames, start, first_ns or 0)
        finally:
            bus.shutdown()
            self.done.set()

    def _play(self, bus, f: CanFrames, start: float, first_ns: int) -> None:
        due_s = (f.t_ns - first_ns) / 1e9
        stamp = f.t_ns / 1e9
        k = 0
        while k < len(f) and not self.stop_event.is_set():
            end = int(np.searchsorted(due_s, (time.monotonic() - start) * self.speedup, side="right"))
            end = min(end, k + 20_000)
            if end <= k:
                time.sleep(0.001)
                continue
            block = f.data[k:end].tobytes()
            for j, (ts, can_id) in enumerate(zip(stamp[k:end].tolist(), f.can_id[k:end].tolist())):
                msg = can.Message(timestamp=ts, arbitration_id=can_id, data=block[8 * j: 8 * j + 8],
                                  is_extended_id=False)
                try:
                    bus.send(msg, timeout=0.05)
                    self.sent += 1
                except can.CanError:
                    self.overruns += 1
            k = end


def record(args: argparse.Namespace) -> dict[str, Any]:
    from feedlog.ingest.cli_record import session_attachments

    if not args.program:
        raise FeedlogError("--source sim needs a PROGRAM to play")
    if not args.profile:
        raise FeedlogError("--source sim needs --profile (name or TOML path)")
    if args.rate_hz <= 0 or args.speedup <= 0:
        raise FeedlogError(f"--rate-hz {args.rate_hz} and --speedup {args.speedup} must be > 0")
    from feedlog.sim import simulate
    from feedlog.toolpath import load_program

    series = simulate(load_program(args.program), args.profile, dt_s=1.0 / args.rate_hz).series
    # the DBC pairs axes in frames (ZA, BC): keep only the axes the simulated machine has
    unused = frozenset(f"{axis}_deg" for axis in "abc" if f"{axis}_deg" not in series)
    if series.empty:
        raise IngestError("the simulation produced no samples", file=args.program)
    layout = DbcLayout(args.dbc)
    t0_ns = time.time_ns() // 1_000_000 * 1_000_000  # whole ms, so frame times stay exact after the us rounding
    n_frames = len(series) * (4 if ("b_deg" in series or "c_deg" in series) else 3)
    channel = f"feedlog-sim-{os.getpid()}-{t0_ns}"
    metadata, attachments = session_attachments(args)
    metadata.update({"source": "sim", "controller": "feedlog sim", "nominal_rate_hz": f"{args.rate_hz:g}",
                     "speedup": f"{args.speedup:g}",
                     "start_time": pd.Timestamp(t0_ns, tz="UTC").isoformat()})
    stop = getattr(args, "stop_event", None) or threading.Event()
    rx = can.Bus(interface="virtual", channel=channel, rx_queue_size=MAX_BUS_QUEUE)
    player = Player(frame_blocks(series, layout, t0_ns=t0_ns), channel, speedup=args.speedup, stop=stop)
    try:
        player.start()
        summary = record_bus(rx, args.out, dbc=args.dbc, metadata=metadata, attachments=attachments,
                             overwrite=args.overwrite, stop=stop, finished=_drained(player, rx), drop_columns=unused,
                             duration_s=args.duration_s, progress=None if args.quiet else sys.stderr)
    finally:
        stop.set()
        player.join(timeout=5)
        rx.shutdown()
    summary.update({"frames_sent": player.sent, "bus_overruns": player.overruns, "frames_planned": n_frames,
                    "sim_samples": len(series)})
    return summary


def _drained(player: Player, rx) -> callable:
    """The source is done once the player has sent everything and the bus queue is empty."""
    def finished() -> bool:
        return player.done.is_set() and rx.queue.empty()
    return finished
