"""CSV import with the checks, before and after: this tree against another git commit, under the same load.

    python benchmarks/bench_ingest_ab.py [--ref 73023f0] [--rows 2000000] [--rounds 4]

On a shared machine one figure taken now and another taken an hour ago compare the load, not the code.
This exports the other commit's `src/` (`git archive`), writes one servo trace (bench_ingest.py's), and
runs both trees in turn in fresh processes, `--rounds` times: each process warms up once, then times
`read_csv`, `run_checks` and the two together three times and keeps its best wall and best CPU time
(user + system, all threads). Prints, per tree and part, the best and the median over the rounds and
the 1-minute load average after each round.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
from io import BytesIO
from pathlib import Path

from bench_ingest import servo_trace   # same directory: run as a script

ROOT = Path(__file__).resolve().parents[1]
CHILD = r'''
import json, sys, time
from feedlog.ingest.csv_reader import read_csv
from feedlog.ingest.data_checks import run_checks
from feedlog.ingest.mapping import load_preset

cmap, path = load_preset("servo-trace-1khz"), sys.argv[1]

def timed(fn):
    w, c = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - w, time.process_time() - c

timed(lambda: run_checks(read_csv(path, cmap)))
rec = read_csv(path, cmap)
parts = {"import": lambda: read_csv(path, cmap), "checks": lambda: run_checks(rec),
         "import+checks": lambda: run_checks(read_csv(path, cmap))}
best = {}
for name, fn in parts.items():
    runs = [timed(fn) for _ in range(3)]
    best[name] = [min(r[0] for r in runs), min(r[1] for r in runs)]
print(json.dumps(best))
'''


def export_src(ref: str, into: Path) -> Path:
    """`ref`'s src/ folder under `into` (git archive), or SystemExit naming the ref."""
    done = subprocess.run(["git", "-C", str(ROOT), "archive", ref, "src"], capture_output=True)
    if done.returncode:
        raise SystemExit(f"bench_ingest_ab: cannot export {ref!r}: {done.stderr.decode().strip()}")
    with tarfile.open(fileobj=BytesIO(done.stdout)) as tar:
        tar.extractall(into, filter="data")
    return into / "src"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ref", default="73023f0", help="the commit to compare with (default: before issue #28's work)")
    parser.add_argument("--rows", type=int, default=2_000_000)
    parser.add_argument("--rounds", type=int, default=4)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        trees = {f"before ({args.ref})": export_src(args.ref, tmp / "before"), "after (this tree)": ROOT / "src"}
        trace = tmp / "trace.csv"
        servo_trace(trace, args.rows)
        results: dict[str, list[dict]] = {name: [] for name in trees}
        loads = [os.getloadavg()[0]]
        for _ in range(args.rounds):
            for name, src in trees.items():
                out = subprocess.run([sys.executable, "-c", CHILD, str(trace)], capture_output=True, text=True,
                                     env={**os.environ, "PYTHONPATH": str(src)}, check=True)
                results[name].append(json.loads(out.stdout))
            loads.append(os.getloadavg()[0])
    n = args.rows
    for name, runs in results.items():
        for part in runs[0]:
            wall, cpu = [r[part][0] for r in runs], [r[part][1] for r in runs]
            print(f"{name:>20} {part:>13}: CPU best {min(cpu):.3f} s ({n / min(cpu) / 1e6:.2f} M rows per CPU-second), "
                  f"median {statistics.median(cpu):.3f} s; wall best {min(wall):.3f} s ({n / min(wall) / 1e6:.2f} M "
                  f"rows/s), median {statistics.median(wall):.3f} s")
    print(f"1-minute load average before and after each round ({os.cpu_count()} cores): "
          + " ".join(f"{v:.1f}" for v in loads))


if __name__ == "__main__":
    main()
