"""LinuxCNC's rapid dial against the simulation: three programs recorded at 100, 50 and 25 % rapid dial.

Records (LinuxCNC, configs/xyz.ini, the dial turned as the program starts) the eight-hole drilling
program of tests/diagnose, and the G0/G1 and rapid-chain programs of tests/linuxcnc/rapid_dial.py,
then simulates each on linuxcnc-xyz at its dial, with the profile's rule (the dial scales the axis
speed before the TRAJ cap, blend arcs sized for the undialed request) and with the generic rule (the
dial times the capped rapid rate). Prints the cycle time error and the per-line time errors.

    .venv/bin/python benchmarks/bench_rapid_dial.py [--out DIR]    (about 3 min of LinuxCNC runs)
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

DIALS = (1.0, 0.5, 0.25)


def main() -> None:
    from tests.diagnose.conftest import drilling
    from tests.linuxcnc.rapid_dial import PROGRAMS, compare
    from tests.linuxcnc.sessions import Job, record_all

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, help="folder for the programs and recordings (kept; re-used when present)")
    args = ap.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="bench_rapid_dial_"))
    out.mkdir(parents=True, exist_ok=True)
    programs = {"drill": drilling(8), **PROGRAMS}
    jobs, keys = [], []
    for name, text in programs.items():
        (out / f"{name}.ngc").write_text(text)
        for dial in DIALS:
            rec = out / f"{name}_{round(dial * 100)}.mcap"
            keys.append((name, dial, rec))
            if not rec.is_file():
                options = {} if dial == 1.0 else {"rapid_override_at": ((0.0, dial),)}
                jobs.append(Job(ROOT / "recordings" / "configs" / "xyz.ini", out / f"{name}.ngc", rec, options))
    t0 = time.perf_counter()
    if jobs:
        record_all(jobs, timeout_s=180.0)
    print(f"recorded {len(jobs)} LinuxCNC sessions in {time.perf_counter() - t0:.0f} s into {out}")
    for rule, flag in (("LinuxCNC rule (profile)", None), ("generic rule", False)):
        print(f"\n{rule}")
        for name, dial, rec in keys:
            cmp = compare(rec, programs[name], dial, scale_axis_speed=flag)
            print(f"  {name:6s} {100 * dial:4.0f} %  {cmp.line()}")


if __name__ == "__main__":
    main()
