"""Logger soak: the live logger for ten minutes at 30 000 CAN frames/s on the python-can virtual bus.

    python benchmarks/bench_logger_soak.py [--duration 600] [--frames-per-s 30000] [--report-every 60]

A player thread sends feedlog_axes.dbc frames (XY, ZA, PATH: three frames per sample) in real time
on an in-process `virtual` bus; the logger (`record_bus`, the code behind `feedlog record`) records
them into an MCAP file as it would from a real bus. Every `--report-every` seconds one line shows
frames sent and recorded, drops so far, the bus backlog (frames waiting for the logger), the file
size and the resident memory, so a slow leak or a logger falling behind shows up over the run. At
the end: dropped frames (target 0), bus overruns, samples in the file against the samples sent, the
largest chunk, CPU per frame. The file is read back strictly. Figures, not a test.
"""

from __future__ import annotations

import argparse
import io
import os
import resource
import tempfile
import threading
import time
from pathlib import Path

from mcap.records import Chunk
from mcap.stream_reader import StreamReader

from bench_ingest_logger import record_played, virtual_bus  # same directory: run as a script
from feedlog.ingest import read_recording
from feedlog.ingest.source_sim import MAX_BUS_QUEUE


class LastLine(io.TextIOBase):
    """Keeps the logger's latest progress line (frames, rate, samples, dropped) instead of printing it."""

    def __init__(self) -> None:
        self.last = ""

    def write(self, text: str) -> int:
        if text.strip():
            self.last = text.strip("\r\n ")
        return len(text)


def rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=600.0, help="seconds of frames to send (default 600)")
    parser.add_argument("--frames-per-s", type=float, default=30_000.0)
    parser.add_argument("--report-every", type=float, default=60.0, help="seconds between progress lines")
    args = parser.parse_args()
    rx, player, stop, _, planned = virtual_bus(args.frames_per_s, args.duration, f"soak-{os.getpid()}")
    progress = LastLine()
    backlog = [0, 0.0]  # largest bus backlog (frames) and when (s)
    rss_peak = [0.0]    # largest resident memory while recording (MB)

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "soak.mcap"

        def report() -> None:
            start, next_at = time.monotonic(), args.report_every
            while not stop.wait(0.5):
                elapsed = time.monotonic() - start
                waiting = rx.queue.qsize()
                if waiting > backlog[0]:
                    backlog[:] = [waiting, elapsed]
                rss_peak[0] = max(rss_peak[0], rss_mb())
                if elapsed >= next_at:
                    next_at += args.report_every
                    size = out.stat().st_size / 1e6 if out.exists() else 0.0
                    print(f"{elapsed:6.0f} s  sent {player.sent:>10}  logger: {progress.last}  backlog "
                          f"{rx.queue.qsize():>6}  file {size:7.1f} MB  RSS {rss_mb():6.0f} MB", flush=True)

        monitor = threading.Thread(target=report, daemon=True)
        print(f"logger soak: {args.frames_per_s:.0f} frames/s for {args.duration:g} s on the virtual bus", flush=True)
        monitor.start()
        try:
            summary, cpu_s = record_played(rx, player, stop, out, progress=progress)
        finally:
            stop.set()            # the monitor stops with the recording, also on an error
            monitor.join(timeout=5)
        rec = read_recording(out)  # strict: the logger finished the file
        samples = len(rec.streams["axes"])
        chunk_mb = max((r.uncompressed_size for r in StreamReader(str(out), emit_chunks=True).records
                        if isinstance(r, Chunk)), default=0) / 2**20
        size_mb = out.stat().st_size / 1e6
    print(f"frames: planned {planned}, sent {player.sent}, recorded {summary['frames']} in {summary['wall_s']:.1f} s "
          f"= {summary['frames_per_s']:.0f} frames/s")
    print(f"dropped_frames {summary['dropped_frames']} (of them late {summary['late_frames']}, missing from the seq "
          f"counters {summary['lost_frames']}), incomplete samples "
          f"{summary['incomplete_samples']}, bus overruns {player.overruns}, largest bus backlog {backlog[0]} frames "
          f"(at {backlog[1]:.0f} s; the bus queue holds {MAX_BUS_QUEUE})")
    print(f"axes samples in the file {samples} of {player.sent // 3} sent; file {size_mb:.1f} MB, largest chunk "
          f"{chunk_mb:.2f} MiB uncompressed")
    print(f"CPU {cpu_s:.0f} s for player + logger = {cpu_s / max(summary['frames'], 1) * 1e6:.1f} us per frame; "
          f"RSS while recording at most {rss_peak[0]:.0f} MB (sampled every 0.5 s), peak with the read-back "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")


if __name__ == "__main__":
    main()
