"""`feedlog diagnose` without a program (diagnose/no_program.py): how long the measurement takes.

Reads the bundled LinuxCNC recordings given (default: every `recordings/mix_*.mcap`, 1 kHz), strips
nothing (the measurement does not look at the program), and prints samples, CPU seconds of `measure`
and samples per second, with what it found for X.

    .venv/bin/python benchmarks/bench_diagnose_no_program.py [RECORDING ...]
"""

from __future__ import annotations

import glob
import sys
import time
from pathlib import Path

from feedlog.diagnose.no_program import measure
from feedlog.ingest import read_recording

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    paths = sys.argv[1:] or sorted(glob.glob(str(ROOT / "recordings" / "mix_*.mcap")))
    recs = [read_recording(p) for p in paths]
    samples = sum(len(r.streams["axes"]) for r in recs if "axes" in r.streams)
    measure(recs[:1])   # imports (scipy) out of the timing
    cpu = time.process_time()
    dx = measure(recs)
    cpu = time.process_time() - cpu
    x = dx.axes.get("x")
    print(f"{len(recs)} recordings, {samples} position samples, {len(dx.axes)} axes: measure {cpu:.2f} s CPU "
          f"({samples / cpu:,.0f} samples/s)")
    if x is not None:
        print(f"x: peak {x.peak_speed} mm/s, {x.peak_acc} mm/s^2; constrains {dx.profile_values()}")


if __name__ == "__main__":
    main()
