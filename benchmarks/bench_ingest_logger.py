"""Live logger load: frames/s recorded from a virtual CAN bus, and drops, at a target frame rate.

    python benchmarks/bench_ingest_logger.py [--frames-per-s 30000] [--seconds 600]

A player thread sends feedlog_axes.dbc frames (XY, ZA, PATH per sample, so 3 frames per sample) at
real time; the logger (the same code as `feedlog record`) records them into an MCAP file. Prints the
achieved send and record rates, dropped frames, bus overruns and the process's peak memory. On a
shared machine the player and the logger share the same Python process and CPU.
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import threading
import time
from pathlib import Path

import can
import numpy as np
import pandas as pd

from feedlog.ingest import read_recording
from feedlog.ingest.can_dbc import DbcLayout
from feedlog.ingest.live import record_bus
from feedlog.ingest.source_sim import MAX_BUS_QUEUE, Player, sim_frames


def synthetic_blocks(layout: DbcLayout, *, rate_hz: float, seconds: float, t0_ns: int, block: int = 10_000):
    """Samples of a circular motion, generated block by block (bounded memory for long runs)."""
    total = int(rate_hz * seconds)
    period_ns = int(round(1e9 / rate_hz))
    for start in range(0, total, block):
        i = np.arange(start, min(start + block, total))
        t = i * period_ns
        series = pd.DataFrame({"t_ns": t, "x_mm": 50 * np.cos(t / 2e9), "y_mm": 50 * np.sin(t / 2e9),
                               "z_mm": np.zeros(len(i)), "feed_mm_min": np.full(len(i), 3000.0),
                               "line": 10 + i // int(rate_hz)})
        yield sim_frames(series, layout, t0_ns=t0_ns, first_seq=start)


def virtual_bus(frames_per_s: float, seconds: float, channel: str):
    """A virtual CAN bus fed by a player of synthetic frames at `frames_per_s` (three frames per
    sample) for `seconds`: (receiving bus, player, its stop event, DBC layout, frames it will send)."""
    layout = DbcLayout()
    t0_ns = time.time_ns() // 1_000_000 * 1_000_000
    stop = threading.Event()
    rx = can.Bus(interface="virtual", channel=channel, rx_queue_size=MAX_BUS_QUEUE)
    player = Player(synthetic_blocks(layout, rate_hz=frames_per_s / 3, seconds=seconds, t0_ns=t0_ns), channel,
                    speedup=1.0, stop=stop)
    return rx, player, stop, layout, int(frames_per_s / 3 * seconds) * 3


def record_played(rx, player, stop: threading.Event, out: Path, *, progress=None) -> tuple[dict, float]:
    """Start the player, log the bus to `out` until the player is done and the bus drained, shut down:
    (the logger's summary, CPU seconds of this process meanwhile)."""
    cpu0 = time.process_time()
    player.start()
    try:
        summary = record_bus(rx, out, stop=stop, progress=progress,
                             finished=lambda: player.done.is_set() and rx.queue.empty())
    finally:
        stop.set()
        player.join(timeout=10)
        rx.shutdown()
    return summary, time.process_time() - cpu0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames-per-s", type=float, default=30_000)
    parser.add_argument("--seconds", type=float, default=600)
    args = parser.parse_args()
    rx, player, stop, layout, planned = virtual_bus(args.frames_per_s, args.seconds, f"bench-{time.time_ns()}")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "load.mcap"
        summary, cpu_s = record_played(rx, player, stop, out)
        rec = read_recording(out)
        samples = len(rec.streams["axes"])
        size_mb = out.stat().st_size / 1e6
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"logger load: target {args.frames_per_s:.0f} frames/s for {args.seconds:g} s ({planned} frames)")
    print(f"  sent {player.sent} frames, recorded {summary['frames']} frames in {summary['wall_s']:.1f} s "
          f"= {summary['frames_per_s']:.0f} frames/s (target {args.frames_per_s:.0f})")
    print(f"  CPU {cpu_s:.1f} s for player + logger = {cpu_s / max(summary['frames'], 1) * 1e6:.1f} us per frame "
          f"(at 30000 frames/s that is {cpu_s / max(summary['frames'], 1) * 3e4 * 100:.0f} % of one core)")
    print(f"  dropped_frames {summary['dropped_frames']}, bus overruns {player.overruns}, "
          f"axes samples in file {samples}, file {size_mb:.1f} MB, peak RSS {peak_mb:.0f} MB")


if __name__ == "__main__":
    main()
