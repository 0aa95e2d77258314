"""Align accuracy on sparse data: the bundled 1 kHz recordings downsampled (default 5 Hz, six phases).

Each manifest recording is padded with 0.5 s of standstill at both ends (a logger keeps logging), every
`--step`-th sample kept from each phase offset, and aligned. Printed per run: cycle time error against
the recording's measured cycle time, and how far each feed CL point's matched time lies from its match
on the full 1 kHz recording (median / p95 / max, ms). Refused runs are counted and named.

    .venv/bin/python benchmarks/bench_align_sparse.py [--step 200] [--phases 0,37,74,111,148,185] [-j 2] [--json]
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd

from feedlog.align import align_recording
from feedlog.errors import FeedlogError
from feedlog.ingest import Recording, read_recording
from feedlog.manifest import read_manifest

ROOT = Path(__file__).resolve().parents[1] / "recordings"
PAD_S = 0.5


def padded(axes: pd.DataFrame, period_ns: int) -> pd.DataFrame:
    """`axes` with its first and last pose held for PAD_S at the recording's own period."""
    n = int(PAD_S * 1e9 / period_ns)
    t = axes["t_ns"].to_numpy()
    head = axes.iloc[[0] * n].copy()
    head["t_ns"] = t[0] - np.arange(n, 0, -1) * period_ns
    tail = axes.iloc[[-1] * n].copy()
    tail["t_ns"] = t[-1] + np.arange(1, n + 1) * period_ns
    return pd.concat([head, axes, tail], ignore_index=True)


def run_one(args: tuple[str, int, tuple[int, ...]]) -> dict:
    name, step, phases = args
    rec = read_recording(ROOT / f"{name}.mcap")
    measured = float(rec.metadata["cycle_time_s"])
    t = rec.stream("axes")["t_ns"].to_numpy()
    axes = padded(rec.stream("axes"), int(np.median(np.diff(t))))
    out = {"name": name, "runs": []}
    try:
        full = align_recording(Recording(streams={"axes": axes}, metadata=rec.metadata, attachments=rec.attachments,
                                         source=rec.source)).points.set_index("point")
        feed = (full["kind"] != "rapid") & (full.index > full.index[0])  # not the start pose the tool rests at
    except FeedlogError as exc:  # refused at full rate (mix5ax_022): cycle times only
        full, out["full_rate_refused"] = None, str(exc)[:300]
    for phase in phases:
        sub = axes.iloc[phase % step::step].reset_index(drop=True)
        sparse = Recording(streams={"axes": sub}, metadata=rec.metadata, attachments=rec.attachments,
                           source=f"{rec.source}@every{step}+{phase}")
        try:
            a = align_recording(sparse)
        except FeedlogError as exc:
            out["runs"].append({"phase": phase, "refused": str(exc)[:300]})
            continue
        row = {"phase": phase, "cycle_error_pct": 100 * (a.cycle_time_s / measured - 1)}
        if full is not None:
            late = ((a.points.set_index("point")["t_ns"] - full["t_ns"]).abs()[feed] / 1e6).dropna()
            row.update(point_ms_median=float(late.median()), point_ms_p95=float(late.quantile(0.95)),
                       point_ms_max=float(late.max()))
        out["runs"].append(row)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--step", type=int, default=200, help="keep every step-th sample (200: 1 kHz -> 5 Hz)")
    ap.add_argument("--phases", default="0,37,74,111,148,185", help="sample offsets (ms at 1 kHz)")
    ap.add_argument("-j", "--jobs", type=int, default=2)
    ap.add_argument("--names", default="", help="only these recordings (comma-separated)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    phases = tuple(int(p) for p in args.phases.split(","))
    names = [e.name for e in read_manifest(ROOT / "manifest.toml")]
    if args.names:
        names = [n for n in names if n in args.names.split(",")]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.jobs) as pool:
        results = list(pool.map(run_one, [(n, args.step, phases) for n in names]))
    wall = time.perf_counter() - t0
    if args.json:
        print(json.dumps(results, indent=1))
        return
    ok = [r for res in results for r in res["runs"] if "cycle_error_pct" in r]
    refused = [(res["name"], r["phase"], r["refused"]) for res in results for r in res["runs"] if "refused" in r]
    err = np.abs([r["cycle_error_pct"] for r in ok])
    timed = [r for r in ok if "point_ms_p95" in r]
    print(f"{len(names)} recordings x {len(phases)} phases, every {args.step}th sample, {wall:.1f} s wall")
    print(f"aligned {len(ok)} / {len(ok) + len(refused)}; |cycle time error| median {np.median(err):.3f} %, "
          f"max {err.max():.3f} %, above 0.5 %: {(err > 0.5).sum()}")
    print(f"matched point time vs full rate (ms, {len(timed)} runs): median of run medians "
          f"{np.median([r['point_ms_median'] for r in timed]):.1f}, median p95 "
          f"{np.median([r['point_ms_p95'] for r in timed]):.1f}, worst p95 {max(r['point_ms_p95'] for r in timed):.1f}, "
          f"worst {max(r['point_ms_max'] for r in timed):.1f}")
    for name, phase, msg in refused:
        print(f"refused {name} phase {phase}: {msg}")


if __name__ == "__main__":
    main()
