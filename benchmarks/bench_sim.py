"""Simulation speed: simulated seconds per wall-clock second for 100k-block programs.

Programs are generated here (deterministic): a 3-axis freeform-like polyline with 0.3-1.2 mm
segments at F3000 and a five-axis XYZAC polyline turning A and C. Parsing is timed separately;
the figure of merit is simulate() alone (target >= 10,000x real time), in CPU seconds of this
process (time.process_time: on a shared machine wall time also counts waiting for a core).

    .venv/bin/python benchmarks/bench_sim.py [--blocks 100000]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from feedlog.sim import simulate
from feedlog.toolpath import parse_program


def three_axis(n: int, seed: int = 0) -> str:
    rng = np.random.default_rng(seed)
    step = rng.uniform(0.3, 1.2, n)
    heading = np.cumsum(rng.normal(0.0, 0.25, n))
    x = np.cumsum(step * np.cos(heading))
    y = np.cumsum(step * np.sin(heading))
    z = -0.5 + 0.3 * np.sin(np.arange(n) / 50.0)
    body = "\n".join(f"G1 X{a:.4f} Y{b:.4f} Z{c:.4f}" for a, b, c in zip(x, y, z))
    return f"G21 G90 G17 G64 P0.01\nF3000\nG0 X0 Y0 Z1\n{body}\nG0 Z5\nM2\n"


def five_axis(n: int, seed: int = 1) -> str:
    rng = np.random.default_rng(seed)
    i = np.arange(n)
    r = 30 + 5 * np.sin(i / 300.0)
    ang = i * 0.02
    x, y = r * np.cos(ang), r * np.sin(ang)
    z = 5 + np.cumsum(rng.normal(0, 0.01, n))
    a = -20 + 15 * np.sin(i / 400.0)
    c = np.degrees(ang)
    body = "\n".join(f"G1 X{p:.4f} Y{q:.4f} Z{s:.4f} A{u:.4f} C{v:.4f}" for p, q, s, u, v in zip(x, y, z, a, c))
    return f"G21 G90 G17 G64 P0.01\nF3000\nG0 X30 Y0 Z20 A0 C0\n{body}\nG0 Z30\nM2\n"


def bench(name: str, text: str, profile: str, repeat: int) -> None:
    t0 = time.perf_counter()
    prog = parse_program(text, name=f"{name}.ngc")
    t_parse = time.perf_counter() - t0
    best = best_series = best_wall = np.inf
    res = None
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        res = simulate(prog, profile)
        w1, c1 = time.perf_counter(), time.process_time()
        series = res.series  # the 1 kHz series is sampled on first access
        best = min(best, c1 - c0)
        best_wall = min(best_wall, w1 - w0)
        best_series = min(best_series, time.process_time() - c1)
    n = int((prog.blocks["kind"].astype(str) != "none").sum())
    print(f"{name:7s} {profile:15s} {n:7d} blocks | parse {t_parse:5.2f} s | simulate (plan, block times, cycle "
          f"time) {best:6.3f} s CPU ({best_wall:6.3f} s wall) = {res.cycle_time_s / best:7.0f}x real time | "
          f"+ {len(series):8d}-sample series {best_series:6.3f} s CPU = {res.cycle_time_s / (best + best_series):6.0f}x "
          f"| simulated {res.cycle_time_s:7.1f} s")


def machine_speed_ms() -> float:
    """A reference figure for the machine's current speed: one 1M-element numpy multiply-add (ms).
    An idle modern core takes ~1-2 ms; on a shared, loaded machine it is several times more."""
    a = np.random.default_rng(0).random(1_000_000)
    best = np.inf
    for _ in range(20):
        t0 = time.perf_counter()
        _ = a * a + a
        best = min(best, time.perf_counter() - t0)
    return best * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"machine: {os.cpu_count()} cores, load average {load:.1f}, numpy 1M multiply-add "
          f"{machine_speed_ms():.1f} ms (idle core: ~1-2 ms)")
    bench("3-axis", three_axis(args.blocks), "linuxcnc-xyz", args.repeat)
    bench("5-axis", five_axis(args.blocks), "linuxcnc-xyzac", args.repeat)
    bench("5-axis", five_axis(args.blocks), "chien-ac", args.repeat)


if __name__ == "__main__":
    main()
