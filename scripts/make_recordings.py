#!/usr/bin/env python3
"""Regenerate recordings/: part programs, LinuxCNC recordings and the manifest.

    .venv/bin/python scripts/make_recordings.py                 # programs + every missing recording
    .venv/bin/python scripts/make_recordings.py --force corners_f3000_p001
    .venv/bin/python scripts/make_recordings.py --programs-only

Programs (recordings/programs/*.ngc) come from scripts/linuxcnc_programs.py; each is run on the
reference machine (recordings/configs/xyz.ini or xyzac.ini, copied from ../shared/linuxcnc/configs)
with feedlog's LinuxCNC recorder. LinuxCNC runs in real time only, so sessions run `--jobs` at a time,
each in its own namespaces (root). recordings/manifest.toml lists program, machine, profile, feed,
tolerance, split (train/test) and the measured cycle time (first motion to end of motion).
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

import tomli_w

from feedlog.manifest import read_manifests

sys.path.insert(0, str(Path(__file__).resolve().parent))
import linuxcnc_programs as progs

ROOT = Path(__file__).resolve().parents[1]
RECORDINGS = ROOT / "recordings"
SHARED_CONFIGS = ROOT.parent / "shared" / "linuxcnc" / "configs"
MACHINES = {"xyz": ("configs/xyz.ini", "linuxcnc-xyz"), "xyzac": ("configs/xyzac.ini", "linuxcnc-xyzac")}
OFFSET_B = (15.0, -10.0, 5.0)
MIX_3AX, MIX_5AX = 40, 24  # random_mix training programs (sized for the recordings/ budget of 30 MB)
MIX_DENSE = 8  # 3-axis random_mix programs weighted to dense runs, G64 with Q0, F2500/F3000 (dense002q0's regime)
# 3-axis random_mix programs whose dense runs are 200-900 segments long, meant to show LinuxCNC's block rate
# over long stretches (as dense002q0's 3142-segment circle does; the mixdense runs have at most 80)
LONG_DENSE = (  # feed, tolerance, CL lines
    (3000.0, "G64 P0.01 Q0", 1400), (2500.0, "G64 P0.05 Q0", 1200), (2000.0, "G64 P0.1 Q0", 1000),
    (3000.0, "G64 P0.05 Q0", 1800), (1500.0, "G64 P0.01 Q0", 900), (2500.0, "G64 P0.01", 1400))
# recorded sessions that feedlog's simulation misses by more than the 2 % of tests/sim/test_linuxcnc_accuracy.py
# (simulated vs recorded cycle time): listed in recordings/held_back.toml instead of manifest.toml until the
# simulation or the test changes. After the simulation changes of 2026-11-22 (docs/sim.md) the seven
# sessions once held back here (mix_000, mix_009, mix_026, mix_033, mix_038 at -2.6 to -16.5 %, mix5ax_011,
# mix5ax_023 at +2.3/+2.4 %) are within 0.4 %. The five long dense runs held back on 2026-11-23 (-3.9 to
# +17.5 % under the fitted block-rate floor) are within 0.93 % since the simulation clamps trimmed line
# pieces and counts queue entries as LinuxCNC does (docs/sim.md). The learners train on held-back sessions too.
HELD_BACK: dict[str, float] = {}
# cycle times measured on the reference machines for ../shared/linuxcnc (LINUXCNC.md)
REFERENCE_CYCLE_S = {"test_p001.ngc": 10.065, "test_p01.ngc": 9.651, "test_g61.ngc": 13.788,
                     "dense002q0.ngc": 5.466, "5ax_p001.ngc": 13.951, "5ax_g61.ngc": 13.044}


@dataclass(frozen=True)
class Entry:
    name: str
    family: str
    machine: str
    feed_mm_min: float
    tolerance: str
    split: str
    text: str
    reference: str = ""  # the ../shared/linuxcnc program this one reproduces

    @property
    def streams(self) -> str:
        """Training sessions keep the compact stream set (axes, line, feed_mm_min; zstd 19), test
        sessions everything the recorder samples."""
        return "compact" if self.split == "train" else "full"

    @property
    def tol_mm(self) -> float:
        """G64 P tolerance in mm; 0 for exact stop (G61)."""
        words = self.tolerance.split()
        return float(words[1][1:]) if words[0] == "G64" else 0.0


def catalogue() -> list[Entry]:
    e: list[Entry] = []

    def add(name, family, machine, feed, tol, split, text, reference=""):
        e.append(Entry(name, family, machine, feed, tol, split, text, reference))

    p001, p01, g61 = "G64 P0.01", "G64 P0.1", "G61"
    # training programs (3-axis)
    add("corners_f3000_p001", "corners", "xyz", 3000, p001, "train", progs.corners(3000, p001))
    add("corners_f1000_p01", "corners", "xyz", 1000, p01, "train", progs.corners(1000, p01))
    add("corners_f3000_g61", "corners", "xyz", 3000, g61, "train", progs.corners(3000, g61))
    add("circle_f3000_p001", "polygon_circle", "xyz", 3000, p001, "train", progs.polygon_circle(3000, p001))
    add("circle_f1000_p01", "polygon_circle", "xyz", 1000, p01, "train", progs.polygon_circle(1000, p01))
    add("pocket_f3000_p001", "pocket", "xyz", 3000, p001, "train", progs.pocket(3000, p001))
    add("pocket_f1000_g61", "pocket", "xyz", 1000, g61, "train", progs.pocket(1000, g61, width_mm=20.0, height_mm=10.0))
    add("freeform_f3000_p001", "freeform", "xyz", 3000, p001, "train", progs.freeform(3000, p001, width_mm=30.0, rows=7))
    add("freeform_f1000_p01", "freeform", "xyz", 1000, p01, "train", progs.freeform(1000, p01, width_mm=20.0, rows=5))
    p005 = "G64 P0.05"
    add("corners_f2000_p005", "corners", "xyz", 2000, p005, "train",
        progs.corners(2000, p005, angles=(20, 70, 110, 140, 170), long_mm=30.0, short_mm=0.5))
    add("circle_r10_f2000_p001", "polygon_circle", "xyz", 2000, p001, "train",
        progs.polygon_circle(2000, p001, radius_mm=10.0, sides=36, laps=3))
    add("pocket_f2000_p01", "pocket", "xyz", 2000, p01, "train",
        progs.pocket(2000, p01, width_mm=25.0, height_mm=15.0, stepover_mm=3.0))
    add("freeform_f2000_p005", "freeform", "xyz", 2000, p005, "train",
        progs.freeform(2000, p005, width_mm=20.0, rows=5, row_step_mm=1.5, amp_mm=1.0, phase=1.9))
    # training programs (five-axis)
    add("5ax_near_f3000_p001", "five_axis_near", "xyzac", 3000, p001, "train", progs.five_axis_near(3000, p001))
    add("5ax_far_f3000_p001", "five_axis_far", "xyzac", 3000, p001, "train", progs.five_axis_far(3000, p001))
    add("5ax_near_f1000_g61_offset", "five_axis_near", "xyzac", 1000, g61, "train",
        progs.five_axis_near(1000, g61, offset=OFFSET_B))
    add("5ax_far_f1000_p01_offset", "five_axis_far", "xyzac", 1000, p01, "train",
        progs.five_axis_far(1000, p01, offset=OFFSET_B))
    add("5ax_near_f2000_p01", "five_axis_near", "xyzac", 2000, p01, "train",
        progs.five_axis_near(2000, p01, radius_mm=25.0))
    add("5ax_far_f2000_g61", "five_axis_far", "xyzac", 2000, g61, "train",
        progs.five_axis_far(2000, g61, radius_mm=25.0))
    # random CL-line training toolpaths (Chien: dedicated training toolpaths at F1000/F3000 and two
    # tolerances), sized for 20-30 s of motion each
    for i, (feed, tol, tag, n3, n5) in enumerate((
            (1000, p001, "p001", 170, 125), (1000, p01, "p01", 250, 170),
            (3000, p001, "p001", 460, 175), (3000, p01, "p01", 600, 240),
            (3000, g61, "g61", 320, 190))):
        add(f"rcl_f{feed}_{tag}", "random_cl", "xyz", feed, tol, "train",
            progs.random_cl(feed, tol, seed=100 + i, blocks=n3))
        add(f"rcl5ax_f{feed}_{tag}", "random_cl_5ax", "xyzac", feed, tol, "train",
            progs.random_cl(feed, tol, seed=200 + i, blocks=n5, five_axis=True))
    # Chien-style short random toolpaths mixing every regime of the held-out tests (long lines, sharp
    # and obtuse corners, runs of 0.1-1 mm and dense 0.02-0.06 mm segments, G61/G64 P0.01-P0.1 with and
    # without Q0, F1000-F3000; five-axis: A -55..0 incl. near A = 0, C turns, G10 L2 work offsets)
    for k in range(MIX_3AX):
        cfg = progs.mix_settings(1000 + k, five_axis=False)
        add(f"mix_{k:03d}", "random_mix", "xyz", cfg["feed"], cfg["tolerance"], "train",
            progs.random_mix(cfg["feed"], cfg["tolerance"], seed=1000 + k, lines=cfg["lines"]))
    for k in range(MIX_5AX):
        cfg = progs.mix_settings(2000 + k, five_axis=True)
        add(f"mix5ax_{k:03d}", "random_mix_5ax", "xyzac", cfg["feed"], cfg["tolerance"], "train",
            progs.random_mix(cfg["feed"], cfg["tolerance"], seed=2000 + k, lines=cfg["lines"], five_axis=True,
                             offset=cfg["offset"]))
    for k in range(MIX_DENSE):
        feed, tol = (3000.0, 2500.0)[k % 2], ("G64 P0.01 Q0", "G64 P0.01 Q0", "G64 P0.05 Q0", "G64 P0.1 Q0")[k % 4]
        add(f"mixdense_{k:03d}", "random_mix_dense", "xyz", feed, tol, "train",
            progs.random_mix(feed, tol, seed=3000 + k, lines=120 + 20 * k, weights=(2, 2, 2, 4)))
    for k, (feed, tol, lines) in enumerate(LONG_DENSE):
        add(f"longdense_{k:03d}", "long_dense", "xyz", feed, tol, "train",
            progs.random_mix(feed, tol, seed=4000 + k, lines=lines, weights=(2, 1, 1, 4), dense_count=(200, 900)))
    # test programs: the shared reference programs, and new geometry of each family
    add("test_p001", "shared_test", "xyz", 3000, p001, "test", progs.shared_test(p001), "test_p001.ngc")
    add("test_p01", "shared_test", "xyz", 3000, p01, "test", progs.shared_test(p01), "test_p01.ngc")
    add("test_g61", "shared_test", "xyz", 3000, g61, "test", progs.shared_test(g61), "test_g61.ngc")
    add("dense002q0", "shared_dense", "xyz", 3000, "G64 P0.01 Q0", "test", progs.shared_dense(), "dense002q0.ngc")
    add("5ax_p001", "shared_5ax", "xyzac", 3000, p001, "test", progs.shared_5ax(p001), "5ax_p001.ngc")
    add("5ax_g61", "shared_5ax", "xyzac", 3000, g61, "test", progs.shared_5ax(g61), "5ax_g61.ngc")
    add("corners_b_f1000_p001", "corners", "xyz", 1000, p001, "test",
        progs.corners(1000, p001, angles=(45, 75, 105, 135, 165), long_mm=15.0, short_mm=1.0))
    add("circle_b_f3000_g61", "polygon_circle", "xyz", 3000, g61, "test",
        progs.polygon_circle(3000, g61, radius_mm=15.0, sides=60, laps=1))
    add("freeform_b_f3000_p01", "freeform", "xyz", 3000, p01, "test",
        progs.freeform(3000, p01, width_mm=24.0, rows=6, row_step_mm=2.5, amp_mm=2.0, phase=0.7))
    add("5ax_near_b_f1000_p01_offset", "five_axis_near", "xyzac", 1000, p01, "test",
        progs.five_axis_near(1000, p01, radius_mm=15.0, offset=(-10.0, 12.0, 0.0)))
    return e


def write_programs(entries: list[Entry]) -> None:
    (RECORDINGS / "programs").mkdir(parents=True, exist_ok=True)
    for entry in entries:
        path = RECORDINGS / "programs" / f"{entry.name}.ngc"
        if not path.exists() or path.read_text() != entry.text:
            path.write_text(entry.text)


def ensure_configs(source: Path) -> None:
    target = RECORDINGS / "configs"
    target.mkdir(parents=True, exist_ok=True)
    for name in ("xyz.ini", "xyzac.ini", "trt.hal"):
        if not (target / name).exists():
            if not (source / name).exists():
                raise SystemExit(f"reference config {name} missing in {target} and {source}")
            shutil.copyfile(source / name, target / name)


def record_one(entry: Entry, *, isolate: bool, force: bool, priority: str = "normal") -> dict:
    from feedlog.ingest.linuxcnc import record_linuxcnc

    ini, profile = MACHINES[entry.machine]
    out = RECORDINGS / f"{entry.name}.mcap"
    summary = record_linuxcnc(RECORDINGS / ini, RECORDINGS / "programs" / f"{entry.name}.ngc", out,
                              profile=profile, isolate=isolate, overwrite=force, timeout_s=120,
                              streams=entry.streams, priority=priority,
                              notes=f"{entry.family}, {entry.split} program; regenerate with "
                                    "scripts/make_recordings.py")
    return summary


def manifest_entry(entry: Entry, summary: dict) -> dict:
    ini, profile = MACHINES[entry.machine]
    row = {
        "name": entry.name,
        "file": f"{entry.name}.mcap",
        "program": f"programs/{entry.name}.ngc",
        "family": entry.family,
        "split": entry.split,
        "machine_ini": ini,
        "profile": profile,
        "feed_mm_min": float(entry.feed_mm_min),
        "tolerance": entry.tolerance,
        "tol_mm": entry.tol_mm,
        "streams": entry.streams,
        "cycle_time_s": round(float(summary["cycle_time_s"]), 6),
        "linuxcnc_motion_time_s": round(float(summary["linuxcnc_motion_time_s"]), 6),
        "samples": int(summary["samples"]),
        "dropped_frames": int(summary["dropped_frames"]),
    }
    if entry.reference:
        row["reference_program"] = f"../shared/linuxcnc/{entry.reference}"
        row["reference_cycle_time_s"] = REFERENCE_CYCLE_S[entry.reference]
    return row


def load_manifest() -> dict[str, dict]:
    """Rows of manifest.toml and held_back.toml by name."""
    entries = read_manifests(RECORDINGS / "manifest.toml", RECORDINGS / "held_back.toml")
    return {name: dict(e.fields) for name, e in entries.items()}


def save_manifest(rows: dict[str, dict], entries: list[Entry]) -> None:
    """manifest.toml: every recorded entry except HELD_BACK ones, which go to held_back.toml with the
    simulation's relative cycle-time error."""
    order = [e.name for e in entries if e.name in rows and e.name not in HELD_BACK]
    held = [e.name for e in entries if e.name in rows and e.name in HELD_BACK]
    (RECORDINGS / "held_back.toml").write_text(tomli_w.dumps({
        "description": "Recorded like manifest.toml's sessions, but feedlog's simulated cycle time misses the "
                       "recorded one by more than 2 % (sim_cycle_time_error = simulated / recorded - 1); kept "
                       "out of manifest.toml until the simulation or tests/sim/test_linuxcnc_accuracy.py changes.",
        "recording": [{**rows[n], "sim_cycle_time_error": HELD_BACK[n]} for n in held],
    }))
    doc = {
        "description": "LinuxCNC 2.9 headless sessions recorded by feedlog (scripts/make_recordings.py). "
                       "cycle_time_s = first motion to end of motion from the recorded axis positions; "
                       "linuxcnc_motion_time_s = servo periods with motion.in-position false, integrated in HAL.",
        "format": "feedlog recording (MCAP, zstd chunks); read with feedlog.ingest.read_recording",
        "recording": [{k: v for k, v in rows[n].items() if k != "sim_cycle_time_error"} for n in order],
    }
    (RECORDINGS / "manifest.toml").write_text(tomli_w.dumps(doc))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", help="only these recordings (default: all)")
    parser.add_argument("--force", action="store_true", help="re-record even if the .mcap exists")
    parser.add_argument("--programs-only", action="store_true", help="write programs and configs, record nothing")
    parser.add_argument("--jobs", type=int, default=2, help="parallel LinuxCNC sessions (default 2)")
    parser.add_argument("--configs", type=Path, default=SHARED_CONFIGS, help="reference configs to copy")
    parser.add_argument("--priority", choices=("normal", "high", "realtime"), default=None,
                        help="scheduling of the LinuxCNC processes (default: high as root, else normal)")
    args = parser.parse_args(argv)

    entries = catalogue()
    known = {e.name for e in entries}
    unknown = [n for n in args.names if n not in known]
    if unknown:
        parser.error(f"unknown recordings {unknown}; known: {', '.join(sorted(known))}")
    ensure_configs(args.configs)
    write_programs(entries)
    if args.programs_only:
        return 0
    chosen = [e for e in entries if (not args.names or e.name in args.names)
              and (args.force or not (RECORDINGS / f"{e.name}.mcap").exists())]
    from feedlog.ingest.linuxcnc_session import isolation_available
    reason = isolation_available()
    isolate = reason is None
    if not isolate and args.jobs > 1:
        print(f"{reason}: running one LinuxCNC session at a time", file=sys.stderr)
        args.jobs = 1
    import os
    priority = args.priority or ("high" if os.geteuid() == 0 else "normal")
    rows = load_manifest()
    failures = 0
    t0 = time.monotonic()
    with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        futures = {pool.submit(record_one, e, isolate=isolate, force=args.force, priority=priority): e
                   for e in chosen}
        for future in as_completed(futures):
            entry = futures[future]
            try:
                summary = future.result()
            except Exception as exc:  # report and go on with the others
                failures += 1
                print(f"FAILED {entry.name}: {exc}", file=sys.stderr)
                continue
            rows[entry.name] = manifest_entry(entry, summary)
            save_manifest(rows, entries)
            print(f"{entry.name:32s} {summary['cycle_time_s']:8.3f} s  (LinuxCNC {summary['linuxcnc_motion_time_s']:.3f} s,"
                  f" {summary['samples']} samples, {summary['dropped_frames']} dropped)", flush=True)
    # entries whose recording exists but which this run did not record keep their manifest rows
    by_name = {e.name: e for e in entries}
    rows = {n: manifest_entry(by_name[n], r) for n, r in rows.items()
            if n in known and (RECORDINGS / r["file"]).exists()}
    save_manifest(rows, entries)
    size = sum(p.stat().st_size for p in RECORDINGS.rglob("*") if p.is_file())
    print(f"{len(chosen) - failures}/{len(chosen)} recorded in {time.monotonic() - t0:.0f} s; "
          f"recordings/ is {size / 1e6:.1f} MB")
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
