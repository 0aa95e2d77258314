"""Cycle-time accuracy against LinuxCNC: program, measured, simulated, CAM, errors.

Measured cycle times (first motion to end of motion) come from ../shared/LINUXCNC.md for the shared
programs and from recordings/manifest.toml for the recorded sessions (when present). For recordings
the last column is the mean absolute error of the time spent on each program line (LinuxCNC's
motion.program-line against the simulated block table), in ms.

    .venv/bin/python benchmarks/bench_sim_accuracy.py [--json]
"""

from __future__ import annotations

import argparse
import json
import time
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd

from feedlog.sim import simulate
from feedlog.toolpath import parse_program

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "linuxcnc"
SHARED_MEASURED = {  # ../shared/LINUXCNC.md
    "test_p001.ngc": ("linuxcnc-xyz", 10.065),
    "test_p01.ngc": ("linuxcnc-xyz", 9.651),
    "test_g61.ngc": ("linuxcnc-xyz", 13.788),
    "dense002q0.ngc": ("linuxcnc-xyz", 5.466),
    "5ax_p001.ngc": ("linuxcnc-xyzac", 13.951),
    "5ax_g61.ngc": ("linuxcnc-xyzac", 13.044),
}


def cases() -> list[dict]:
    out = [{"name": name, "source": "shared", "split": "-", "path": SHARED / name, "profile": prof, "measured_s": t}
           for name, (prof, t) in SHARED_MEASURED.items() if (SHARED / name).is_file()]
    manifest = ROOT / "recordings" / "manifest.toml"
    if manifest.is_file():
        for rec in tomllib.loads(manifest.read_text())["recording"]:
            out.append({"name": rec["name"], "source": "recording", "split": rec.get("split", "-"),
                        "path": manifest.parent / rec["program"], "profile": rec["profile"],
                        "measured_s": float(rec["cycle_time_s"]), "recording": manifest.parent / rec["file"]})
    return out


def line_time_error_ms(recording_path: Path, res) -> float:
    """Mean absolute difference (ms) of the time spent on each program line: LinuxCNC's
    motion.program-line stream (within motion) against the simulated block table."""
    from feedlog.ingest import read_recording  # noqa: PLC0415

    rec = read_recording(recording_path)
    ln = rec.stream("line")
    t = ln["t_ns"].to_numpy()
    lines = ln["line"].to_numpy()
    t0 = int(rec.metadata.get("motion_start_ns", t[0]))
    t1 = int(rec.metadata.get("motion_end_ns", t[-1]))
    inside = (t >= t0) & (t <= t1)
    t, lines = t[inside], lines[inside]
    change = np.flatnonzero(np.diff(lines)) + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change, [len(t) - 1]])
    measured = pd.Series((t[ends] - t[starts]) / 1e6, index=lines[starts]).groupby(level=0).sum()
    simulated = res.blocks.groupby("line")["duration_s"].sum() * 1e3
    both = measured.index.intersection(simulated.index)
    return float(np.mean(np.abs(measured[both] - simulated[both]))) if len(both) else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    rows = []
    for case in cases():
        t0 = time.perf_counter()
        res = simulate(parse_program(case["path"], lenient=True), case["profile"])
        wall = time.perf_counter() - t0
        m = case["measured_s"]
        rows.append({"program": case["name"], "source": case["source"], "split": case["split"],
                     "profile": case["profile"], "measured_s": m, "simulated_s": round(res.cycle_time_s, 4),
                     "cam_s": round(res.cam_time_s, 4), "sim_error_pct": round(100 * (res.cycle_time_s - m) / m, 2),
                     "cam_error_pct": round(100 * (res.cam_time_s - m) / m, 2), "wall_s": round(wall, 3),
                     "line_time_mae_ms": round(line_time_error_ms(case["recording"], res), 2)
                     if "recording" in case else None})
    if args.json:
        print(json.dumps(rows, indent=1))
        return
    head = f"{'program':30s} {'source':9s} {'split':5s} {'profile':15s} {'measured':>9s} {'simulated':>9s} " \
           f"{'CAM':>8s} {'sim err':>8s} {'CAM err':>8s} {'line MAE':>9s}"
    print(head)
    print("-" * len(head))
    for r in rows:
        print(f"{r['program']:30s} {r['source']:9s} {r['split']:5s} {r['profile']:15s} {r['measured_s']:9.3f} "
              f"{r['simulated_s']:9.3f} {r['cam_s']:8.3f} {r['sim_error_pct']:+7.2f}% {r['cam_error_pct']:+7.1f}%"
              + (f" {r['line_time_mae_ms']:6.2f} ms" if r["line_time_mae_ms"] is not None else f" {'-':>9s}"))
    errs = sorted(abs(r["sim_error_pct"]) for r in rows)
    cam = sorted(abs(r["cam_error_pct"]) for r in rows)
    if errs:
        print("-" * len(head))
        print(f"{len(rows)} programs: |sim error| median {errs[len(errs) // 2]:.2f} %, max {errs[-1]:.2f} %, "
              f"within 2 %: {sum(e <= 2 for e in errs)}/{len(errs)}; |CAM error| median {cam[len(cam) // 2]:.1f} %, "
              f"max {cam[-1]:.1f} %")


if __name__ == "__main__":
    main()
