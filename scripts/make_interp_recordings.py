#!/usr/bin/env python3
"""Record recordings/interp/: programs that need the interpreter, run on the real LinuxCNC kernel.

    .venv/bin/python scripts/make_interp_recordings.py                 # every missing vendored recording
    .venv/bin/python scripts/make_interp_recordings.py --force polar    # re-record some
    .venv/bin/python scripts/make_interp_recordings.py --long /tmp/long # the long examples, not vendored

Each program runs on the bundled 3-axis machine (recordings/configs/xyz.ini: 100 mm/s and 1000 mm/s^2
per axis, travel +-1000 mm, 1 kHz servo) with `feedlog record --source linuxcnc` (record_linuxcnc), in
its own namespaces, `--jobs` at a time (LinuxCNC runs in real time only). The programs are LinuxCNC's
own examples (/usr/share/linuxcnc/ncfiles of the linuxcnc-uspace package, read in place) and three of
ours (recordings/interp/programs/): canned cycles, cutter compensation, subroutines called from loops
with one subroutine in a file of its own found along SUBROUTINE_PATH (`--subroutine-path`, attached
to the recording). recordings/interp/manifest.toml lists what was recorded and the measured cycle times
(first motion to end of motion, whole servo periods).
"""

from __future__ import annotations

import argparse
import os
import sys
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

import tomli_w

from feedlog.manifest import read_manifest

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "recordings" / "interp"
OWN = OUT / "programs"
SUBS = OWN / "subs"
INI = ROOT / "recordings" / "configs" / "xyz.ini"
NCFILES = Path("/usr/share/linuxcnc/ncfiles")

# name -> (program, what it exercises); short enough to vendor (a few MB in all at 1 kHz with the compact
# streams: axes, line, feed_mm_min, zstd 19; what align, sim and train read)
VENDORED = {
    "hole-circle": (NCFILES / "hole-circle.ngc", "ncfiles: G81 in G91 with polar ^ and L6, inch"),
    "polar": (NCFILES / "polar.ngc", "ncfiles: G81 with polar @ ^, G91 L5/L17, inch"),
    "toplevel": (NCFILES / "toplevel.ngc", "ncfiles: M70/M71/M72 modal state save/restore, G91"),
    "3dtest": (NCFILES / "3dtest.ngc", "ncfiles: full circles in G17/G18/G19 (no end point), inch"),
    "3D_Chips": (NCFILES / "3D_Chips.ngc", "ncfiles: parameters, O-word loops, 4684 short moves"),
    "plasmatest": (NCFILES / "plasmatest.ngc", "ncfiles: long plasma profile, M6 T1, arcs"),
    "drill_cycles": (OWN / "drill_cycles.ngc", "ours: G81/G83, R/Z, L4 in G91, G98/G99"),
    "cutter_comp": (OWN / "cutter_comp.ngc", "ours: G41/G42 with T1 (6 mm), lines and an arc"),
    "subs_loops": (OWN / "subs_loops.ngc", "ours: o<square> in the file called from repeat, "
                                           "o<bolt_row> (subs/) from while, with a while inside"),
    "splines_g64_f3000": (OWN / "splines_g64_f3000.ngc", "ours: two G5, two G5.1 (biarcs), G64 P0.01 F3000"),
    "splines_g611_f1200": (OWN / "splines_g611_f1200.ngc", "ours: two G5, two G5.1 (biarcs), exact stop G61.1 "
                                                           "F1200"),
    "blend_corners_p005": (OWN / "blend_corners_p005.ngc", "ours: line-arc, arc-arc, arc-line corners, G64 P0.05 "
                                                           "F3000"),
}
# not recorded: skeleton.ngc and tort.ngc stop at M0/M00 for the operator (the driver does not press
# cycle start: tort waited 12 minutes at its line 4); daisy.ngc and b-index.ngc move A and B, which the
# bundled machine lacks; the others of ncfiles have no motion, use probing, lathe codes, or cutter
# compensation that is refused before it moves (entry too short)
# examples that run for minutes: recorded and measured with --long, not vendored (size)
# the blend corners in G64 without P (programs/blend_corners_g64.ngc, 110 kB): measured once with --only after
# adding it to VENDORED, not vendored (size; docs/sim.md "Blend geometry")
# the same splines in G64 P0.01 F1200 (160 kB): not vendored (size), recorded live by
# tests/linuxcnc/test_linuxcnc_interp_live.py
LONG = {
    "spiral": NCFILES / "spiral.ngc", "arcspiral": NCFILES / "arcspiral.ngc",
    "flowsnake": NCFILES / "flowsnake.ngc", "cds": NCFILES / "cds.ngc",
}


def record_one(name: str, program: Path, out: Path, *, streams: str) -> dict:
    from feedlog.ingest.linuxcnc import record_linuxcnc
    from feedlog.ingest.linuxcnc_session import isolation_available

    return record_linuxcnc(INI, program, out, isolate=isolation_available() is None, timeout_s=1200,
                           overwrite=True, streams=streams, subroutine_path=(SUBS,),
                           notes=f"scripts/make_interp_recordings.py: {name}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--force", nargs="*", default=None, metavar="NAME", help="re-record these (none: all)")
    ap.add_argument("--jobs", type=int, default=2, help="sessions at a time (default 2)")
    ap.add_argument("--long", type=Path, metavar="DIR", help="record the long examples into DIR instead")
    ap.add_argument("--only", nargs="*", metavar="NAME", help="record only these")
    args = ap.parse_args(argv)
    if args.long is not None:
        todo = {n: (p, "long example") for n, p in LONG.items()}
        outdir, streams = args.long, "compact"
    else:
        todo, outdir, streams = dict(VENDORED), OUT, "compact"
    if args.only:
        todo = {n: v for n, v in todo.items() if n in args.only}
    force = set(todo) if args.force == [] else set(args.force or ())
    outdir.mkdir(parents=True, exist_ok=True)
    manifest_path = outdir / "manifest.toml"
    manifest = {"recording": {e.name: dict(e.fields) for e in read_manifest(manifest_path)}
                if manifest_path.exists() else {}}
    pending = {n: v for n, v in todo.items() if n in force or not (outdir / f"{n}.mcap").exists()}
    failed = 0
    with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        futures = {pool.submit(record_one, n, p, outdir / f"{n}.mcap", streams=streams): n
                   for n, (p, _) in pending.items()}
        for fut in as_completed(futures):
            name = futures[fut]
            program, what = todo[name]
            try:
                summary = fut.result()
            except Exception as exc:  # report and go on: the others are still worth having
                print(f"{name}: FAILED: {exc}", file=sys.stderr)
                failed += 1
                continue
            # paths relative to the manifest's folder (feedlog.manifest reads them so); LinuxCNC's own
            # examples stay absolute: they are read in place where LinuxCNC is installed
            rel = Path(os.path.relpath(program, outdir)) if program.is_relative_to(ROOT) else program
            manifest["recording"][name] = {
                "program": str(rel), "what": what, "ini": os.path.relpath(INI, outdir), "streams": streams,
                "cycle_time_s": round(float(summary["cycle_time_s"]), 6),
                "linuxcnc_motion_time_s": round(float(summary["linuxcnc_motion_time_s"]), 6),
                "samples": int(summary["samples"]), "dropped_frames": int(summary["dropped_frames"]),
                "status": summary["status"],
            }
            print(f"{name}: {summary['cycle_time_s']:.3f} s, {summary['samples']} samples, {summary['status']}",
                  flush=True)
    manifest["recording"] = dict(sorted(manifest["recording"].items()))
    manifest_path.write_text(tomli_w.dumps(manifest))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
