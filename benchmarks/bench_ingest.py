"""Ingest throughput: CSV import rows/s (and with `feedlog import`'s data checks), recording write/read
samples/s, CAN bulk decode frames/s.

    python benchmarks/bench_ingest.py [--rows 2000000] [--frames 10000000] [--csv-only]

A "sample" is one row of a stream (t_ns plus its columns); the write/read test uses an `axes` stream
with five float64 positions. Figures vary with machine load; each is the best of `--repeat` runs. Each
figure is given per wall second and per CPU-second (all threads of the process: user + system), and the
load average is printed before and after: on a shared machine the wall rate says how busy it was, the
CPU rate what the code costs.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.csv as pacsv

from feedlog.ingest import Recording, read_recording, write_recording
from feedlog.ingest.can_dbc import CanFrames, DbcLayout
from feedlog.ingest.can_streams import decode_frames
from feedlog.ingest.csv_reader import read_csv
from feedlog.ingest.data_checks import run_checks
from feedlog.ingest.mapping import load_preset


class Timing:
    """Best wall time and best CPU time (all threads) of `repeat` runs."""

    def __init__(self, fn, repeat: int) -> None:
        walls, cpus = [], []
        for _ in range(repeat):
            w0, c0 = time.perf_counter(), time.process_time()
            fn()
            walls.append(time.perf_counter() - w0)
            cpus.append(time.process_time() - c0)
        self.wall, self.cpu = min(walls), min(cpus)

    def rate(self, n: int) -> str:
        return f"{n / self.wall / 1e6:.2f} M/s wall ({n / self.cpu / 1e6:.2f} M per CPU-second)"


def load() -> str:
    return "load average " + " ".join(f"{v:.2f}" for v in os.getloadavg())


def servo_trace(path: Path, rows: int) -> None:
    t = np.arange(rows) * 1.0  # ms
    table = pa.table({"time": t, "X1_ActualPosition": np.round(np.sin(t / 500) * 50, 4),
                      "Y1_ActualPosition": np.round(np.cos(t / 500) * 50, 4),
                      "Z1_ActualPosition": np.round(t * 1e-4, 4), "PathVelocity": np.full(rows, 3000.0)})
    pacsv.write_csv(table, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=2_000_000, help="CSV rows and recording samples")
    parser.add_argument("--frames", type=int, default=10_000_000, help="CAN frames to decode")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--csv-only", action="store_true", help="only the CSV import and its checks")
    args = parser.parse_args()
    print(f"before: {load()} ({os.cpu_count()} cores)")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        csv_path = tmp / "trace.csv"
        servo_trace(csv_path, args.rows)
        cmap = load_preset("servo-trace-1khz")
        timing = Timing(lambda: read_csv(csv_path, cmap), args.repeat)
        print(f"csv import (servo-trace-1khz, {args.rows} rows, {csv_path.stat().st_size / 1e6:.0f} MB): "
              f"rows {timing.rate(args.rows)}")
        trace = read_csv(csv_path, cmap)
        checks = Timing(lambda: run_checks(trace), args.repeat)
        print(f"import data checks (units, jumps, rounding, program lines) on those rows: rows "
              f"{checks.rate(args.rows)}")
        both = Timing(lambda: run_checks(read_csv(csv_path, cmap)), args.repeat)
        print(f"csv import with the checks (as `feedlog import` runs them): rows {both.rate(args.rows)}; "
              f"{both.wall:.3f} s wall, {both.cpu:.3f} CPU-s")
        if args.csv_only:
            print(f"after: {load()}")
            return

        n = args.rows
        t = np.arange(n, dtype=np.int64) * 1_000_000
        rng = np.random.default_rng(0)
        axes = pd.DataFrame({"t_ns": t, **{c: np.cumsum(rng.normal(size=n)) * 1e-3
                                           for c in ("x_mm", "y_mm", "z_mm", "a_deg", "c_deg")}})
        rec = Recording(streams={"axes": axes})
        for compression in ("lz4", "none", "zstd"):
            out = tmp / f"rec-{compression}.mcap"
            w = Timing(lambda: write_recording(out, rec, overwrite=True, compression=compression), args.repeat)
            r = Timing(lambda: read_recording(out), args.repeat)
            print(f"recording {compression:>4} ({n} samples x 5 float64, {out.stat().st_size / 1e6:.0f} MB): "
                  f"write samples {w.rate(n)}, read samples {r.rate(n)}")

    layout = DbcLayout()
    m = args.frames
    ids = np.array([0x100, 0x101, 0x110, 0x7FF], dtype=np.uint32)[np.arange(m) % 4]
    frames = CanFrames(np.arange(m, dtype=np.int64) * 25_000, ids,
                       np.random.default_rng(1).integers(0, 256, (m, 8), dtype=np.uint8))
    timing = Timing(lambda: decode_frames(frames, layout), args.repeat)
    print(f"CAN bulk decode (feedlog_axes.dbc, {m} frames, 1/4 unknown ids): frames {timing.rate(m)}")
    print(f"after: {load()}")


if __name__ == "__main__":
    main()
