"""Cycle-time accuracy against LinuxCNC: program, measured, simulated, CAM, errors.

Measured cycle times (first motion to end of motion) come from ../shared/LINUXCNC.md for the shared
programs and from recordings/manifest.toml for the recorded sessions (when present).

    .venv/bin/python benchmarks/bench_sim_accuracy.py [--json]
"""

from __future__ import annotations

import argparse
import json
import time
import tomllib
from pathlib import Path

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
                        "measured_s": float(rec["cycle_time_s"])})
    return out


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
                     "cam_error_pct": round(100 * (res.cam_time_s - m) / m, 2), "wall_s": round(wall, 3)})
    if args.json:
        print(json.dumps(rows, indent=1))
        return
    head = f"{'program':30s} {'source':9s} {'split':5s} {'profile':15s} {'measured':>9s} {'simulated':>9s} " \
           f"{'CAM':>8s} {'sim err':>8s} {'CAM err':>8s}"
    print(head)
    print("-" * len(head))
    for r in rows:
        print(f"{r['program']:30s} {r['source']:9s} {r['split']:5s} {r['profile']:15s} {r['measured_s']:9.3f} "
              f"{r['simulated_s']:9.3f} {r['cam_s']:8.3f} {r['sim_error_pct']:+7.2f}% {r['cam_error_pct']:+7.1f}%")
    errs = sorted(abs(r["sim_error_pct"]) for r in rows)
    cam = sorted(abs(r["cam_error_pct"]) for r in rows)
    if errs:
        print("-" * len(head))
        print(f"{len(rows)} programs: |sim error| median {errs[len(errs) // 2]:.2f} %, max {errs[-1]:.2f} %, "
              f"within 2 %: {sum(e <= 2 for e in errs)}/{len(errs)}; |CAM error| median {cam[len(cam) // 2]:.1f} %, "
              f"max {cam[-1]:.1f} %")


if __name__ == "__main__":
    main()
