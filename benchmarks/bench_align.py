"""Measured samples per second through feedlog align, end to end, per recording class.

Two classes, each printed with the load average (the machine is shared; run it twice):

1. The bundled LinuxCNC recordings (recordings/manifest.toml, 1 kHz, ~14 k samples each): read MCAP ->
   align -> write Parquet for every recording in one process (wall and CPU time), then the same through
   `align_many` over `--jobs` worker processes (wall time including the pool). Short recordings are
   dominated by per-recording costs (program parsing, CL points, tables), not by samples. Recordings
   align rejects (one of our errors) are named and left out of the figures; ms per recording by step
   (read, each step of the report's timings_s, write) are printed for the best one-process run.
2. A long synthetic air cut (pocket rings and zig-zags repeated at several depths, arcs between passes,
   G64 P0.01) simulated with feedlog.sim at a fine period so that one run holds `--samples` samples
   (several sizes may be given, e.g. 4 M at 13.7 kHz and 0.3 M at 1 kHz); the result becomes a
   recording with axes, feed and line streams. Timed: align_recording on the in-memory recording, then
   the same from the MCAP file on disk to the Parquet tables (read_recording + align + write).

    .venv/bin/python benchmarks/bench_align.py [--samples 4000000 300000] [--repeat 3] [--jobs 2]
        [--recordings FILE.mcap ...] [--no-bundled]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from feedlog.align import align_recording
from feedlog.align.batch import align_many
from feedlog.align.tables import write_alignment
from feedlog.errors import FeedlogError
from feedlog.ingest import Recording, read_recording, write_recording
from feedlog.manifest import read_manifest
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


RECORDINGS = Path(__file__).resolve().parents[1] / "recordings"


def load() -> str:
    return "load average " + " / ".join(f"{x:.2f}" for x in os.getloadavg()) + " (1/5/15 min)"


def bundled_files() -> list[Path]:
    return [e.path for e in read_manifest(RECORDINGS / "manifest.toml") if e.path.exists()]


def bench_bundled(repeat: int, jobs: int, files: list[Path]) -> None:
    if not files:
        print("bundled recordings: none found")
        return
    where = sorted({str(f.parent) for f in files})
    print(f"bundled recordings: {len(files)} files in {', '.join(where)} ({load()})")
    best_wall = best_cpu = np.inf
    n = 0
    steps: dict[str, float] = {}
    failed: dict[str, str] = {}
    with tempfile.TemporaryDirectory() as tmp:
        runs = k = 0
        while runs < repeat:
            k += 1
            w0, c0 = time.perf_counter(), time.process_time()
            n = 0
            laps: dict[str, float] = {}
            new_failures = False
            for f in files:
                t0 = time.perf_counter()
                r = read_recording(f)
                t1 = time.perf_counter()
                try:
                    a = align_recording(r)
                except FeedlogError as exc:  # a recording align rejects: left out of every figure
                    failed[f.name] = str(exc)
                    new_failures = True
                    continue
                t2 = time.perf_counter()
                write_alignment(Path(tmp) / f"seq{k}" / f.stem, a)
                laps["read"] = laps.get("read", 0.0) + t1 - t0
                laps["write"] = laps.get("write", 0.0) + time.perf_counter() - t2
                for name, v in a.report["timings_s"].items():
                    laps[name] = laps.get(name, 0.0) + v
                n += len(r.streams["axes"])
            if new_failures:  # this run's time includes the rejected ones: run again without them
                files = [f for f in files if f.name not in failed]
                continue
            runs += 1
            wall = time.perf_counter() - w0
            if wall < best_wall:
                best_wall, steps = wall, laps
            best_cpu = min(best_cpu, time.process_time() - c0)
        if failed:
            print(f"  {len(failed)} recording(s) rejected by align, left out: " + "; ".join(
                f"{name} ({msg[:70]}...)" for name, msg in sorted(failed.items())))
        if not files:
            return
        print(f"  one process, read MCAP + align + write Parquet: {len(files)} recordings, {n:,} samples, "
              f"{best_wall:.2f} s wall ({best_cpu:.2f} s CPU) -> {n / best_wall / 1e6:.2f} M samples/s "
              f"({n / best_cpu / 1e6:.2f} per CPU second), {best_wall / len(files) * 1e3:.1f} ms per recording")
        print("    ms per recording, by step (wall): " + ", ".join(
            f"{name} {v / len(files) * 1e3:.1f}" for name, v in steps.items()))
        best = np.inf
        for k in range(repeat):
            t0 = time.perf_counter()
            items = align_many(files, Path(tmp) / f"many{k}", jobs=jobs, progress=False)
            best = min(best, time.perf_counter() - t0)
            failed = [i.recording for i in items if not i.ok]
            if failed:
                raise SystemExit(f"align_many failed on {failed}")
        print(f"  align_many, {jobs} worker processes: {best:.2f} s wall -> {n / best / 1e6:.2f} M samples/s ({load()})")


def bench_long(samples: int, repeat: int) -> None:
    rec, text, sim_s = make_recording(samples)
    n = len(rec.streams["axes"])
    prog = parse_program(text, name="bench.ngc")
    print(f"long recording: {n:,} samples, {rec.duration_s:.1f} s at {rec.metadata['nominal_rate_hz']} Hz, "
          f"{len(prog.motion):,} motion blocks (simulated in {sim_s:.1f} s; {load()})")
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        a = align_recording(rec)
        best = min(best, time.perf_counter() - t0)
    print(f"  align_recording (in memory): {best:.2f} s -> {n / best / 1e6:.2f} M samples/s "
          f"(cycle {a.cycle_time_s:.3f} s, {len(a.points):,} CL points, {len(a.blocks):,} blocks, "
          f"geometry vs line median {a.report['line_stream']['geometry_vs_line']['duration_err_median_s'] * 1e3:.2f} ms)")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.mcap"
        write_recording(path, rec)
        best = np.inf
        for k in range(repeat):
            t0 = time.perf_counter()
            r = read_recording(path)
            a = align_recording(r)
            write_alignment(Path(tmp) / f"out{k}", a)
            best = min(best, time.perf_counter() - t0)
        print(f"  read MCAP + align + write Parquet: {best:.2f} s -> {n / best / 1e6:.2f} M samples/s ({load()})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, nargs="*", default=[4_000_000, 300_000],
                    help="sizes of the long synthetic recording (none: skip it)")
    ap.add_argument("--repeat", type=int, default=3, help="runs per figure; the best is printed")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes for align_many over the bundled recordings")
    ap.add_argument("--no-bundled", action="store_true", help="skip the bundled recordings")
    ap.add_argument("--recordings", type=Path, nargs="*", default=None,
                    help="MCAP files for the first class instead of those in recordings/manifest.toml")
    args = ap.parse_args()
    if not args.no_bundled:
        bench_bundled(args.repeat, args.jobs, args.recordings if args.recordings is not None else bundled_files())
    for samples in args.samples:
        bench_long(samples, args.repeat)


if __name__ == "__main__":
    main()
