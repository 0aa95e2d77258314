"""Parse + feature throughput of feedlog.toolpath on a generated 100k-block program.

    .venv/bin/python benchmarks/bench_toolpath.py [--blocks 100000] [--repeat 3]

The program mixes what CAM output holds: short G1 XYZ segments with 4 decimals, G2/G3 arcs (I/J and R),
occasional feed changes, comments and N words. Prints blocks/s for parse_program, block_features and
both together (best and median of --repeat runs). Target: >= 200k blocks/s for parse + features.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

from feedlog.toolpath import block_features, cl_points, parse_program


def generate(n_blocks: int, seed: int = 0) -> str:
    rng = np.random.default_rng(seed)
    xy = np.cumsum(rng.normal(0.0, 0.5, size=(n_blocks, 2)), axis=0)
    z = -1.0 - 0.5 * np.sin(np.arange(n_blocks) / 500.0)
    kind = rng.choice(4, size=n_blocks, p=[0.85, 0.06, 0.06, 0.03])
    lines = ["%", "O1234 (benchmark program)", "G21 G90 G17 G94 G64 P0.01", "S12000 M3", "G0 X0 Y0 Z5",
             "G1 Z-1 F2000"]
    prev = np.zeros(2)
    for i in range(n_blocks):
        x, y = xy[i]
        n = f"N{i + 10} " if i % 7 == 0 else ""
        feed = f" F{1000 + 500 * (i % 5)}" if i % 50 == 0 else ""
        note = " (pass)" if i % 200 == 0 else ""
        if kind[i] == 0:
            lines.append(f"{n}G1 X{x:.4f} Y{y:.4f} Z{z[i]:.4f}{feed}{note}")
        elif kind[i] in (1, 2):
            cx, cy = (prev + xy[i]) / 2 + rng.normal(0, 0.3, 2)
            r0 = np.hypot(*(prev - (cx, cy)))
            ang = np.arctan2(y - cy, x - cx)
            ex, ey = cx + r0 * np.cos(ang), cy + r0 * np.sin(ang)
            xy[i] = ex, ey
            lines.append(f"{n}G{kind[i] + 1} X{ex:.4f} Y{ey:.4f} I{cx - prev[0]:.4f} J{cy - prev[1]:.4f}{feed}")
        else:
            chord = np.hypot(*(xy[i] - prev))
            lines.append(f"{n}G2 X{x:.4f} Y{y:.4f} R{max(chord, 0.01):.4f}{feed}")
        prev = xy[i]
    lines += ["G0 Z5", "M5", "M30", "%"]
    return "\n".join(lines) + "\n"


def timed(fn, repeat: int) -> tuple[float, float, float, object]:
    """Best and median wall time, and best CPU time of this process (the machine may be shared)."""
    times, cpu, out = [], [], None
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return min(times), statistics.median(times), min(cpu), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    text = generate(args.blocks)
    parse_program(text)  # warm-up (imports, first allocations)
    p_best, p_med, p_cpu, program = timed(lambda: parse_program(text), args.repeat)
    f_best, f_med, f_cpu, feats = timed(lambda: block_features(program), args.repeat)
    b_best, b_med, b_cpu, _ = timed(lambda: block_features(parse_program(text)), args.repeat)
    c_best, c_med, c_cpu, pts = timed(lambda: cl_points(program, chord_tol_mm=0.001), args.repeat)
    n = len(program.motion)
    print(f"program: {len(text) / 1e6:.1f} MB, {len(program.blocks)} rows, {n} motion blocks, "
          f"{len(feats)} feature rows, {len(pts)} CL points; load average {os.getloadavg()[0]:.1f} "
          f"on {os.cpu_count()} CPUs")
    for label, best, med, cpu in (("parse_program", p_best, p_med, p_cpu),
                                  ("block_features", f_best, f_med, f_cpu),
                                  ("parse + features", b_best, b_med, b_cpu),
                                  ("cl_points (0.001 mm)", c_best, c_med, c_cpu)):
        print(f"{label:<22} wall {n / best / 1e3:6.0f} k blocks/s best ({best * 1e3:5.0f} ms), "
              f"{n / med / 1e3:6.0f} k/s median; CPU {n / cpu / 1e3:6.0f} k blocks/s ({cpu * 1e3:5.0f} ms)")
    verdict = "met" if n / b_best >= 200e3 else "NOT met"
    print(f"target parse + features >= 200 k blocks/s (best wall time): {verdict}")


if __name__ == "__main__":
    main()
