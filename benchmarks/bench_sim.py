"""Simulation speed: simulated seconds per wall-clock second for 100k-block programs.

Programs are generated here (deterministic): a 3-axis freeform-like polyline with 0.3-1.2 mm
segments at F3000 and a five-axis XYZAC polyline turning A and C. Parsing is timed separately;
the figure of merit is simulate() alone (target >= 10,000x real time).

    .venv/bin/python benchmarks/bench_sim.py [--blocks 100000]
"""

from __future__ import annotations

import argparse
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
    best = best_series = np.inf
    res = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        res = simulate(prog, profile)
        t1 = time.perf_counter()
        series = res.series  # the 1 kHz series is sampled on first access
        best = min(best, t1 - t0)
        best_series = min(best_series, time.perf_counter() - t1)
    n = int((prog.blocks["kind"].astype(str) != "none").sum())
    print(f"{name:7s} {profile:15s} {n:7d} blocks | parse {t_parse:5.2f} s | simulate (plan, block times, cycle "
          f"time) {best:6.3f} s = {res.cycle_time_s / best:8.0f}x real time | + {len(series):8d}-sample series "
          f"{best_series:6.3f} s = {res.cycle_time_s / (best + best_series):7.0f}x | simulated {res.cycle_time_s:7.1f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    bench("3-axis", three_axis(args.blocks), "linuxcnc-xyz", args.repeat)
    bench("5-axis", five_axis(args.blocks), "linuxcnc-xyzac", args.repeat)
    bench("5-axis", five_axis(args.blocks), "chien-ac", args.repeat)


if __name__ == "__main__":
    main()
