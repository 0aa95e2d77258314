"""Measured samples per second through feedlog align, end to end.

A long synthetic air cut (pocket rings and zig-zags repeated at several depths, arcs between passes,
G64 P0.01) is simulated with feedlog.sim at a fine period so that one run holds millions of samples;
the result becomes a recording with axes, feed and line streams. Timed:
1. align_recording (program parse, CL points, motion span, constrained match, feeds, line and
   geometry block boundaries, features) on the in-memory recording;
2. the same from the MCAP file on disk to the Parquet tables (read_recording + align + write).

    .venv/bin/python benchmarks/bench_align.py [--samples 4000000] [--repeat 3]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from feedlog.align import align_recording
from feedlog.align.tables import write_alignment
from feedlog.ingest import Recording, read_recording, write_recording
from feedlog.profile import load_profile
from feedlog.sim import simulate
from feedlog.toolpath import parse_program


def program_text(depths: int = 6) -> str:
    lines = ["%", "(bench_align: pocket rings + zig-zags at several depths)", "G21 G90 G17 G94", "G64 P0.01",
             "F3000", "G0 X0 Y0 Z5"]
    for d in range(depths):
        z = -0.5 * (d + 1)
        lines.append(f"G1 Z{z:.3f} F600")
        lines.append("F3000")
        for ring in range(8):  # rectangles shrinking by 2 mm, joined by arcs
            a, b = 2.0 * ring, 60.0 - 2.0 * ring
            lines += [f"G1 X{b:.3f} Y{a:.3f}", f"G1 X{b:.3f} Y{b - 40:.3f}", f"G1 X{a:.3f} Y{b - 40:.3f}",
                      f"G1 X{a:.3f} Y{a:.3f}"]
            lines.append(f"G2 X{a + 2:.3f} Y{a + 2:.3f} I1 J1")
        for k in range(30):  # zig-zag over the same area, short segments
            y = 2.0 + 0.6 * k
            lines += [f"G1 X{50.0 if k % 2 == 0 else 10.0:.3f} Y{y:.3f}"]
            lines += [f"G1 X{50.0 if k % 2 == 0 else 10.0:.3f} Y{y + 0.6:.3f}"]
        lines.append("G0 Z5")
        lines.append("G0 X0 Y0")
    lines += ["M2", "%"]
    return "\n".join(lines) + "\n"


def make_recording(samples: int) -> tuple[Recording, str, float]:
    text = program_text()
    prog = parse_program(text, name="bench.ngc")
    profile = load_profile("linuxcnc-xyz")
    t0 = time.perf_counter()
    probe = simulate(prog, profile)
    dt = max(probe.cycle_time_s / samples, 1e-5)
    sim = simulate(prog, profile, dt_s=dt)
    sim_s = time.perf_counter() - t0
    s = sim.series
    t = s["t_ns"].to_numpy() + 1_000_000_000
    axes = s[["x_mm", "y_mm", "z_mm"]].assign(t_ns=t)[["t_ns", "x_mm", "y_mm", "z_mm"]]
    feed = s[["feed_mm_min"]].assign(t_ns=t)[["t_ns", "feed_mm_min"]]
    line = s[["line"]].assign(t_ns=t)[["t_ns", "line"]].astype({"line": np.int64})
    rec = Recording(streams={"axes": axes, "feed": feed, "line": line},
                    metadata={"machine": "linuxcnc-xyz", "controller": "feedlog.sim", "units": "mm, deg, s",
                              "nominal_rate_hz": f"{1 / dt:.0f}", "start_time": "", "notes": "bench_align"},
                    attachments={"program.ngc": text.encode(), "profile.toml": profile.to_toml().encode()},
                    source="bench")
    return rec, text, sim_s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=4_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    rec, text, sim_s = make_recording(args.samples)
    n = len(rec.streams["axes"])
    prog = parse_program(text, name="bench.ngc")
    print(f"recording: {n:,} samples, {rec.duration_s:.1f} s at {rec.metadata['nominal_rate_hz']} Hz, "
          f"{len(prog.motion):,} motion blocks (simulated in {sim_s:.1f} s)")
    best = np.inf
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        a = align_recording(rec)
        best = min(best, time.perf_counter() - t0)
    print(f"align_recording (in memory): {best:.2f} s -> {n / best / 1e6:.2f} M samples/s "
          f"(cycle {a.cycle_time_s:.3f} s, {len(a.points):,} CL points, {len(a.blocks):,} blocks, "
          f"geometry vs line median {a.report['line_stream']['geometry_vs_line']['duration_err_median_s'] * 1e3:.2f} ms)")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.mcap"
        write_recording(path, rec)
        best = np.inf
        for k in range(args.repeat):
            t0 = time.perf_counter()
            r = read_recording(path)
            a = align_recording(r)
            write_alignment(Path(tmp) / f"out{k}", a)
            best = min(best, time.perf_counter() - t0)
        print(f"read MCAP + align + write Parquet: {best:.2f} s -> {n / best / 1e6:.2f} M samples/s")


if __name__ == "__main__":
    main()
