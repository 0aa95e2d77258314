"""Live network sources: six axes, feed and line at 100 Hz for N minutes from an MTConnect agent and an OPC UA
server, recorded by `feedlog record` in its own process; lost samples and the recorder's CPU cost.

    python benchmarks/bench_live_sources.py [--minutes 10] [--source mtconnect|opcua|both]

The servers are the tests' (`tests/ingest/mtconnect_test_agent.py` on the standard library's HTTP server,
`tests/ingest/opcua_test_server.py` on asyncua), each in its own process on 127.0.0.1, publishing a
synthetic session in which all six axes move every sample (so every sample is a row: 100 rows/s per
axes stream), the feed every sample and the line every second. The recorder runs as `feedlog record
--source ... --json` with `--duration-s` covering the session. Afterwards the recording is read back
strictly and compared with the published table: rows expected in the session's span, rows found with
the published values at the published times (expected: what was published after the recorder
attached, its metadata `start_time`), lost (expected - found), gaps, and the recorder's CPU
time (its own summary, `cpu_s`) as a share of one core. Figures, not a test.
"""

from __future__ import annotations

import argparse
import json
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from feedlog.ingest import read_recording  # noqa: E402
from tests.ingest.mtconnect_test_agent import synthetic_table  # noqa: E402


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_source(kind: str, seconds: float) -> tuple[subprocess.Popen, str, int]:
    port = free_port()
    if kind == "mtconnect":
        cmd = [sys.executable, "-m", "tests.ingest.mtconnect_test_agent", f"synthetic:{seconds}", str(port), "8"]
    else:
        cmd = [sys.executable, "-m", "tests.ingest.opcua_test_server", f"synthetic:{seconds}", str(port), "+8"]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    words = proc.stdout.readline().split()
    if kind == "opcua":
        words = words[1:]  # READY URL T0
    if len(words) != 2:
        proc.kill()
        raise SystemExit(f"{kind} server did not start: {proc.stderr.read()[-2000:]}")
    return proc, words[0], int(words[1])


def run(kind: str, minutes: float, out_dir: Path) -> dict:
    seconds = minutes * 60
    table = synthetic_table(seconds)
    server, url, t0 = start_source(kind, seconds)
    out = out_dir / f"{kind}.mcap"
    interval = "100" if kind == "mtconnect" else "10"
    wait = (t0 - time.time_ns()) / 1e9
    cmd = [sys.executable, "-m", "feedlog.cli", "record", "--source", kind, "--url", url, "--interval-ms", interval,
           "--duration-s", f"{seconds + wait + 3:.1f}", "-o", str(out), "--json", "--quiet"]
    try:
        done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=seconds + 120)
    finally:
        server.kill()
    if done.returncode != 0:
        raise SystemExit(f"{kind} recorder failed: {done.stderr[-2000:]}")
    summary = json.loads(done.stdout)
    rec = read_recording(out)
    axes = rec.streams["axes"]
    t = axes["t_ns"].to_numpy()
    # expected: what was published after the recorder attached (its session start_time; the recorder's
    # own start-up, importing and connecting, is not a loss)
    attached = int(pd.Timestamp(rec.metadata["start_time"]).value)
    want_t = table["t_ns"] + t0
    before = int((want_t <= attached).sum())
    want_t = want_t[want_t > attached]
    found = np.isin(want_t, t)
    k = np.searchsorted(want_t, t[t >= t0], side="right") - 1
    mine = axes[t >= t0]
    exact = all(np.array_equal(mine[f"{a}_{'mm' if a in 'xyz' else 'deg'}"].to_numpy(), table[a][k]) for a in "xyzabc")
    lost_at = (want_t[~found] - t0) / 1e9
    return {"source": kind, "minutes": minutes, "published_before_attach": before,
            "rows_expected": len(want_t), "rows_found": int(found.sum()),
            "lost": int((~found).sum()), "lost_between_s": [round(float(lost_at.min()), 2), round(float(lost_at.max()), 2)]
            if len(lost_at) else [], "values_exact": bool(exact), "gaps": len(summary["gaps"]),
            "wall_s": summary["wall_s"], "cpu_s": summary["cpu_s"],
            "cpu_share_of_one_core": round(summary["cpu_s"] / summary["wall_s"], 3),
            "file_mb": round(out.stat().st_size / 1e6, 2), "streams": summary["streams"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--source", choices=("mtconnect", "opcua", "both"), default="both")
    args = parser.parse_args()
    kinds = ("mtconnect", "opcua") if args.source == "both" else (args.source,)
    with tempfile.TemporaryDirectory() as tmp:
        for kind in kinds:
            print(json.dumps(run(kind, args.minutes, Path(tmp))), flush=True)


if __name__ == "__main__":
    main()
