"""A machine that warms up: seeded simulated sessions whose feed dial drifts, diagnosed with the shipped
profile. Prints, per session, the true drift, what diagnose found (a drift, a step or nothing), both
values, the times (an approach: its start, time constant and 95 % time) and the timing error with one
value and with the change.

Sessions (seeded): linear drifts from 1.0 to 0.70-0.92 starting 0.5-4 s after motion start and lasting
2-9 s; an exponential warm-up (the dial from 1.0 towards 0.75-0.9 with a time constant of 2-6 s, the
shape thermal growth takes, which a linear drift only approximates); a quick turn (0.05 s, a step); and
one session unchanged. Programs: corners_f1000_p01 (16.4 s) and corners_f3000_p001 (6.9 s).
The dial is applied per block (`tests/diagnose/test_drift.py`, `dial_by_line`), measured at 1 kHz with
2 um noise.

    .venv/bin/python benchmarks/bench_diagnose_drift.py [--sessions 8] [--seed 1]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def sessions(n: int, seed: int):
    from tests.diagnose.test_drift import linear

    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        program = ("corners_f1000_p01", "corners_f3000_p001")[k % 2]
        kind = ("linear", "linear", "exponential", "linear", "step", "linear", "unchanged", "exponential")[k % 8]
        end = 16.0 if program == "corners_f1000_p01" else 6.5
        if kind == "linear":
            t0 = float(rng.uniform(0.5, min(4.0, end - 3.0)))
            t1 = float(min(t0 + rng.uniform(2.0, 9.0), end))
            b = float(rng.uniform(0.70, 0.92))
            out.append((program, f"linear 1 at {t0:.2f} s -> {b:.3f} at {t1:.2f} s", linear(t0, t1, 1.0, b)))
        elif kind == "exponential":
            b, tau = float(rng.uniform(0.75, 0.9)), float(rng.uniform(2.0, 6.0))
            out.append((program, f"exponential 1 -> {b:.3f}, tau {tau:.1f} s",
                        lambda t, b=b, tau=tau: b + (1.0 - b) * np.exp(-np.asarray(t) / tau)))
        elif kind == "step":
            t0, b = float(rng.uniform(2.0, end - 2.0)), float(rng.uniform(0.7, 0.9))
            out.append((program, f"step 1 -> {b:.3f} at {t0:.2f} s (0.05 s)", linear(t0, t0 + 0.05, 1.0, b)))
        else:
            out.append((program, "unchanged", lambda t: np.ones_like(np.asarray(t, float))))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sessions", type=int, default=8)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    from tests.diagnose.test_drift import drifted

    from feedlog.diagnose.engine import DiagnoseConfig, diagnose

    print("| program | true dial | found | before -> after | from -> to (s) | one value | timing error one value -> change | wall |")
    print("|---|---|---|---|---|---|---|---|")
    for k, (program, truth, dial) in enumerate(sessions(args.sessions, args.seed)):
        recs = drifted(f"bench{k}", program, dial=dial, seed=args.seed * 100 + k)
        t = time.perf_counter()
        dx = diagnose(recs, "linuxcnc-xyz", config=DiagnoseConfig(learned=False))
        wall = time.perf_counter() - t
        named = ", ".join(f.parameter for f in dx.findings)
        if not dx.changes:
            print(f"| {program} | {truth} | nothing{' (named: ' + named + ')' if named else ''} | - | - | - | - | {wall:.1f} s |")
        for c in dx.changes:
            span = f"{c.at_s:.2f}"
            if c.shape == "drift":
                span = f"{c.at_s:.2f} -> {c.until_s:.2f}"
            elif c.shape == "approach":
                span = f"{c.at_s:.2f}, tau {c.tau_s:.2f} (95 % at {c.until_s:.2f})"
            found = c.shape + (" (not levelled off)" if c.open_end else "")
            print(f"| {program} | {truth} | {found} | {c.before:.4f} -> {c.after:.4f} | {span} | {c.single_value:.4f} | "
                  f"{c.error_single_pct:.2f} % -> {c.error_change_pct:.2f} % | {wall:.1f} s |", flush=True)


if __name__ == "__main__":
    main()
