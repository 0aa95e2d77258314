"""`feedlog demo` end to end: wall time, peak memory, and the size of what it writes.

Runs the demo as a child process (`python -m feedlog demo -o OUT`, exactly README's first command)
and prints: wall time, the demo's own run time (the figure its report and console quote), peak
resident memory of the demo process and of its largest worker (getrusage of the children; Linux
reports kilobytes), the CPU seconds of both (a figure the other jobs on the machine change less), and the bytes written per output (`rerun/*.rrd`, `plots/`, `models/`,
`diagnose/`, `report.md`) against the recordings it read. Options pass through (`--no-rrd`, `-j`,
`--no-train`). Run: .venv/bin/python benchmarks/bench_demo.py [--out DIR] [-- demo options]
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PARTS = ("rerun", "plots", "models", "diagnose", "report.md", "cycle_times.json")

# the parent records its own peak and its largest worker's: a wrapper that runs the demo in-process
CHILD = """
import resource, sys
from feedlog.cli import main
rc = main(sys.argv[1:])
self, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
print(f"@@rss {self.ru_maxrss} {kids.ru_maxrss}", file=sys.stderr)
print(f"@@cpu {self.ru_utime + self.ru_stime} {kids.ru_utime + kids.ru_stime}", file=sys.stderr)
sys.exit(rc)
"""


def size(path: Path) -> int:
    if path.is_file():
        return path.stat().st_size
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file()) if path.is_dir() else 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="demo output folder (default: a temporary one)")
    parser.add_argument("--recordings", type=Path, default=ROOT / "recordings")
    parser.add_argument("demo_args", nargs=argparse.REMAINDER, help="after --: options for feedlog demo")
    args = parser.parse_args()
    extra = [a for a in args.demo_args if a != "--"]
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp) / "demo"
        cmd = [sys.executable, "-c", CHILD, "demo", "-o", str(out), "--recordings", str(args.recordings), *extra]
        start = time.perf_counter()
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env={**os.environ})
        wall = time.perf_counter() - start
        if proc.returncode != 0:
            print(proc.stderr[-2000:], file=sys.stderr)
            return proc.returncode
        rss = re.search(r"@@rss (\d+) (\d+)", proc.stderr)
        demo_s = re.search(r"feedlog demo finished in ([\d.]+) s", proc.stdout)
        recordings = sum(p.stat().st_size for p in args.recordings.glob("*.mcap"))
        load = " / ".join(f"{x:.2f}" for x in os.getloadavg())
        print(f"feedlog demo on {args.recordings} ({recordings / 1e6:.1f} MB of .mcap), {os.cpu_count()} cores, "
              f"load average {load}")
        print(f"wall time {wall:.1f} s; the demo's own run time {demo_s.group(1) if demo_s else 'n/a'} s")
        cpu = re.search(r"@@cpu ([\d.]+) ([\d.]+)", proc.stderr)
        if cpu:  # what the load does not change much: CPU seconds used (2 cores: wall >= this / 2)
            print(f"CPU time: demo process {float(cpu.group(1)):.1f} s, its workers and children "
                  f"{float(cpu.group(2)):.1f} s (user + system)")
        if rss:
            print(f"peak memory: demo process {int(rss.group(1)) / 1024:.0f} MB, largest worker "
                  f"{int(rss.group(2)) / 1024:.0f} MB")
        for part in PARTS:
            n = size(out / part)
            count = len(list((out / part).glob("*"))) if (out / part).is_dir() else 1
            print(f"  {part:18s} {n / 1e6:8.1f} MB  ({count} file(s))"
                  + (f"  {n / recordings:.1f} x the recordings" if part == "rerun" and recordings else ""))
        print(f"  {'total':18s} {size(out) / 1e6:8.1f} MB")
    print(f"own peak (this benchmark) {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
