"""Geometry, changes during a session, and what nothing explains: seeded LinuxCNC machines, measured.

Three parts, each printed as a table (`--part` runs one):

- `geometry`: five-axis LinuxCNC machines (configs/xyzac.ini) whose trt.hal y/z-offsets are drawn at
  random (seeded; one machine in four unchanged), two five-axis programs recorded on each, diagnosed
  with the shipped profile. Prints the true and fitted offsets (profile sign: minus the HAL value) and
  the joints' RMS before and after.
- `changes`: the xyz machine running a program while the driver turns the feed dial once at a random
  time to a random value (one machine in four: no turn), with a second program at 100 %. Prints the
  true and found turn (time, before, after) and what one value would have been.
- `unexplained`: the simulated pocket whose moves after an arc ran at 70 % of F (no hypothesis covers
  it), diagnosed with the learned correction: the signature, and the correction's held-out error.

    .venv/bin/python benchmarks/bench_diagnose_session.py [--machines 4] [--seed 1] [--part geometry]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PROGRAMS = ROOT / "recordings" / "programs"
sys.path.insert(0, str(ROOT / "scripts"))
sys.path.insert(0, str(ROOT))


def geometry(machines: int, seed: int, folder: Path) -> None:
    from linuxcnc_variants import derive_machine

    from feedlog.diagnose.engine import DiagnoseConfig, diagnose
    from feedlog.ingest.linuxcnc import record_linuxcnc

    rng = np.random.default_rng(seed)
    print("| machine | y-offset true | fitted | z-offset true | fitted | named | joints RMS before -> after | wall |")
    print("|---|---|---|---|---|---|---|---|")
    for k in range(machines):
        control = k % 4 == 3
        dy, dz = (20.0, 10.0) if control else (round(float(rng.uniform(5, 40)), 2), round(float(rng.uniform(0, 25)), 2))
        ini = derive_machine("xyzac", folder / f"geo{k}", hal_params={"xyzac-trt-kins.y-offset": dy,
                                                                      "xyzac-trt-kins.z-offset": dz})
        progs = rng.choice([f"mix5ax_{i:03d}" for i in range(20)], size=2, replace=False)
        paths = []
        for p in progs:
            out = ini.parent / f"{p}.mcap"
            record_linuxcnc(ini, PROGRAMS / f"{p}.ngc", out, timeout_s=120)
            paths.append(out)
        t0 = time.perf_counter()
        dx = diagnose(paths, "linuxcnc-xyzac", config=DiagnoseConfig(learned=False))
        wall = time.perf_counter() - t0
        found = {f.parameter: f.fitted_value for f in dx.findings}
        fy, fz = found.get("kinematics.rotary_offset_mm.1"), found.get("kinematics.rotary_offset_mm.2")
        geo = dx.levels.get("geometry") or {}
        print(f"| {k}{' (unchanged)' if control else ''} {', '.join(progs)} | {dy} | "
              f"{'-' if fy is None else f'{-fy:.3f}'} | {dz} | {'-' if fz is None else f'{-fz:.3f}'} | "
              f"{', '.join(sorted(found)) or 'nothing'} | {geo.get('rms_before_mm', float('nan')):.4f} -> "
              f"{geo.get('rms_after_mm', float('nan')):.6f} mm | {wall:.1f} s |", flush=True)


def changes(machines: int, seed: int, folder: Path) -> None:
    from feedlog.diagnose.engine import DiagnoseConfig, diagnose
    from feedlog.ingest import read_recording
    from feedlog.ingest.linuxcnc import record_linuxcnc

    rng = np.random.default_rng(seed + 100)
    ini = ROOT / "recordings" / "configs" / "xyz.ini"
    print("| session | turned at (s after start:dial) | dial | found at, from motion start (segment) | before | after | one value | timing error one value -> change | named | wall |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    pairs = [("pocket_f3000_p001", "corners_f3000_p001"), ("freeform_f2000_p005", "corners_f2000_p005"),
             ("corners_f1000_p01", "pocket_f3000_p001"), ("circle_f3000_p001", "corners_f3000_p001")]
    for k in range(machines):
        turned, other = pairs[k % len(pairs)]
        control = k % 4 == 3
        at, dial = round(float(rng.uniform(1.5, 4.0)), 2), round(float(rng.uniform(0.5, 0.9)), 2)
        paths = []
        for p, turns in ((turned, () if control else ((at, dial),)), (other, ())):
            out = folder / f"chg{k}_{p}.mcap"
            record_linuxcnc(ini, PROGRAMS / f"{p}.ngc", out, timeout_s=120, feed_override_at=turns)
            paths.append(out)
        meta = read_recording(paths[0]).metadata.get("feed_override_turns", "")
        t0 = time.perf_counter()
        dx = diagnose(paths, "linuxcnc-xyz", config=DiagnoseConfig(learned=False))
        wall = time.perf_counter() - t0
        named = ", ".join(f"{f.parameter}={f.fitted_value:.4g}" for f in dx.findings) or "nothing"
        if not dx.changes:
            print(f"| {k} {turned} | {meta or 'no turn'} | {'-' if control else dial} | no change | | | | | {named} | "
                  f"{wall:.1f} s |", flush=True)
        for c in dx.changes:
            print(f"| {k} {turned} | {meta or 'no turn'} | {'-' if control else dial} | {c.recording} "
                  f"{c.at_s:.3f} s ({c.between_s[0]:.2f}-{c.between_s[1]:.2f}) | {c.before:.4f} | {c.after:.4f} | {c.single_value:.4f} | "
                  f"{c.error_single_pct:.2f} % -> {c.error_change_pct:.2f} % | {named} | {wall:.1f} s |", flush=True)


def unexplained() -> None:
    from tests.diagnose.conftest import make_hidden, slower_after_arcs

    from feedlog.diagnose.engine import DiagnoseConfig, diagnose

    t0 = time.perf_counter()
    dx = diagnose(make_hidden("arcs", edit=slower_after_arcs), "linuxcnc-xyz", config=DiagnoseConfig(learned=True))
    wall = time.perf_counter() - t0
    for u in dx.unexplained:
        print(f"unexplained, cause {u['cause']}: {u['error_pct']:.2f} % misplaced, {u['systematic_share_pct']:.0f} % "
              f"systematic; signature: {u['signature']['text']}")
        lc = u.get("learned_correction") or {}
        for r in lc.get("held_out", []):
            print(f"  learned correction, {r['name']} held out: {r['error_before_pct']:+.2f} % -> {r['error_after_pct']:+.2f} %")
        if lc:
            print(f"  mean |error| held out {lc.get('mean_abs_error_before_pct', float('nan')):.2f} % -> "
                  f"{lc.get('mean_abs_error_after_pct', float('nan')):.2f} % (gain {lc.get('gain_pct', float('nan')):.1f} %)")
    print(f"  {wall:.1f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--machines", type=int, default=4)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--part", choices=("geometry", "changes", "unexplained"), action="append")
    args = ap.parse_args()
    parts = args.part or ["geometry", "changes", "unexplained"]
    with tempfile.TemporaryDirectory() as tmp:
        if "geometry" in parts:
            geometry(args.machines, args.seed, Path(tmp))
        if "changes" in parts:
            changes(args.machines, args.seed, Path(tmp))
        if "unexplained" in parts:
            unexplained()


if __name__ == "__main__":
    main()
