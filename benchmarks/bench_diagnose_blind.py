"""`feedlog diagnose` on LinuxCNC machines drawn at random: how often it names what was changed.

Each machine is one of the shipped LinuxCNC configs (xyz, or xyzac one time in four) with 0, 1 or 2
changes drawn from a seeded generator: an axis's acceleration or velocity limit, the TRAJ velocity
limit, the feed override dial, the blend look-ahead depth, a first-order lag on one joint's feedback.
Two programs are drawn from the bundled ones for that config (cycle time under `--max-cycle-s`). Both
are recorded with LinuxCNC, then diagnosed with the shipped profile, as a user would, with no hint.

A change is *observable* when putting its true value into the shipped profile moves the simulated
cycle time by more than `--observable-pct` over the two programs (a lag always is: the recordings
carry feedback). A finding is *right* when it names a changed key and its value is within 15 % of the
true one. Printed: per machine what was changed and what was found; in all: findings right / named,
changes named only as an equally good alternative to a wrong finding (the data cannot tell them apart),
observable changes found, findings on unchanged machines, cycle-time error before and after.

    .venv/bin/python benchmarks/bench_diagnose_blind.py [--machines 12] [--seed 1] [--rate-hz 5] [--json]
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from feedlog.manifest import read_manifest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))

LINEAR = {"xyz": "xyz", "xyzac": "xyz"}
JOINT = {"x": 0, "y": 1, "z": 2, "a": 3, "c": 4}


def draw_change(rng: random.Random, base: str) -> tuple[str, list, dict | None, float | None, str, float]:
    """One change: (kind, INI edits, feedback lags, feed override, profile key, true value)."""
    kinds = ["acc", "acc", "vel", "traj", "override", "lookahead", "lag"] + (["rot_vel", "rot_acc"] if base == "xyzac" else [])
    kind = rng.choice(kinds)
    if kind in ("acc", "vel"):
        axis = rng.choice(LINEAR[base])
        value = round(rng.uniform(200, 800)) if kind == "acc" else round(rng.uniform(15, 45))
        ini = "MAX_ACCELERATION" if kind == "acc" else "MAX_VELOCITY"
        return (kind, [(f"AXIS_{axis.upper()}", ini, value), (f"JOINT_{JOINT[axis]}", ini, value)], None, None,
                f"axes.{axis}.{'acc_max' if kind == 'acc' else 'vel_max'}", float(value))
    if kind in ("rot_vel", "rot_acc"):
        axis = rng.choice("ac")
        value = round(rng.uniform(10, 40)) if kind == "rot_vel" else round(rng.uniform(100, 450))
        ini = "MAX_VELOCITY" if kind == "rot_vel" else "MAX_ACCELERATION"
        return (kind, [(f"AXIS_{axis.upper()}", ini, value), (f"JOINT_{JOINT[axis]}", ini, value)], None, None,
                f"axes.{axis}.{'vel_max' if kind == 'rot_vel' else 'acc_max'}", float(value))
    if kind == "traj":
        value = round(rng.uniform(15, 45))
        return kind, [("TRAJ", "MAX_LINEAR_VELOCITY", value)], None, None, "interpolator.path_vel_max_mm_s", float(value)
    if kind == "override":
        value = round(rng.uniform(0.5, 0.95), 2)
        return kind, [], None, value, "sim.feed_override.override", value
    if kind == "lookahead":
        value = rng.randint(2, 12)
        return kind, [("TRAJ", "ARC_BLEND_OPTIMIZATION_DEPTH", value)], None, None, "interpolator.lookahead_blocks", value
    axis = rng.choice(LINEAR[base])
    value = round(rng.uniform(0.005, 0.03), 3)
    return kind, [], {JOINT[axis]: value}, None, f"sim.following_lag.lag_s.{axis}", value


def draw_machine(rng: random.Random, programs: dict[str, list[str]]) -> dict:
    base = "xyzac" if rng.random() < 0.25 else "xyz"
    n = rng.choice([0, 1, 1, 1, 2, 2])
    changes, keys = [], set()
    while len(changes) < n:
        c = draw_change(rng, base)
        if c[4] not in keys and not (c[0] == "lag" and any(x[0] == "lag" for x in changes)):
            changes.append(c)
            keys.add(c[4])
    return {"base": base, "changes": changes, "programs": rng.sample(programs[base], 2)}


def bundled_programs(max_cycle_s: float) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {"xyz": [], "xyzac": []}
    for r in read_manifest(ROOT / "recordings" / "manifest.toml"):
        base = Path(r["machine_ini"]).stem
        if base in out and r["cycle_time_s"] <= max_cycle_s:
            out[base].append(r.name)
    return out


def record(machine: dict, folder: Path, isolate: bool) -> list[Path]:
    from feedlog.ingest.linuxcnc import record_linuxcnc
    from linuxcnc_variants import derive_machine

    edits = [e for c in machine["changes"] for e in c[1]]
    lags = {j: tau for c in machine["changes"] if c[2] for j, tau in c[2].items()}
    override = next((c[3] for c in machine["changes"] if c[3] is not None), None)
    ini = derive_machine(machine["base"], folder, changes=edits, feedback_lag=lags or None)
    out = []
    for name in machine["programs"]:
        program = ROOT / "recordings" / "programs" / f"{name}.ngc"
        path = folder / f"{name}.mcap"
        out.append(path)
        if path.exists():  # kept from an earlier run of the same seed (--keep)
            continue
        summary = record_linuxcnc(ini, program, path, isolate=isolate, timeout_s=300, feed_override=override)
        if summary["status"] != "complete":
            raise RuntimeError(f"{folder.name}: {name} did not complete: {summary}")
    return out


def at_rate(path: Path, rate_hz: float):
    from feedlog.ingest import read_recording

    rec = read_recording(path)
    period = int(rec.metadata.get("servo_period_ns", "1000000"))
    step = max(1, round(1e9 / rate_hz / period))
    rec.streams = {k: v.iloc[::step].reset_index(drop=True) for k, v in rec.streams.items()
                   if k in ("axes", "feed", "line")}
    rec.source = str(path.with_name(f"{path.stem}_{rate_hz:g}hz.mcap"))
    return rec


def truth_effect_pct(dx, key: str, value: float) -> float:
    """How much the true value of one change moves the simulated cycle time of these recordings."""
    from feedlog.diagnose.keys import with_values
    from feedlog.diagnose.levels import simulate_all
    from feedlog.diagnose.residuals import sim_span

    def total(profile) -> float:
        return sum(e - s for s, e in (sim_span(c, r) for c, r in zip(dx.cases, simulate_all(dx.cases, profile))))

    return 100 * (total(with_values(dx.profile, {key: value})) / total(dx.profile) - 1)


def score(machine: dict, dx, observable_pct: float) -> dict:
    truth = {c[4]: c[5] for c in machine["changes"]}
    found = {f.parameter: float(f.fitted_value) for f in dx.findings}
    right = {k for k, v in found.items() if k in truth and abs(v / truth[k] - 1) <= 0.15}
    # a changed key listed as an equally good alternative to a wrong finding (the data cannot tell them)
    tied = {a["parameter"] for f in dx.findings if f.parameter not in right for a in f.alternatives
            if a["parameter"] in truth and abs(float(a["fitted_value"]) / truth[a["parameter"]] - 1) <= 0.15}
    observable = {k for k, v in truth.items()
                  if k.startswith("sim.following_lag") or abs(truth_effect_pct(dx, k, v)) > observable_pct}
    cyc = dx.levels["cycle"]
    fb = dx.levels.get("feedback") or {}
    return {"base": machine["base"], "programs": machine["programs"], "truth": truth, "found": found,
            "right": sorted(right), "tied": sorted(tied - right), "observable": sorted(observable), "unexplained": len(dx.unexplained),
            "error_before_pct": cyc["error_before_pct"], "error_after_pct": cyc["error_after_pct"],
            "fb_before_um": 1e3 * fb["rms_before_mm"] if fb.get("rms_before_mm") is not None else None,
            "fb_after_um": 1e3 * fb["rms_after_mm"] if fb.get("rms_after_mm") is not None else None}


def summarise(rows: list[dict]) -> dict:
    named = sum(len(r["found"]) for r in rows)
    right = sum(len(r["right"]) for r in rows)
    obs = sum(len(r["observable"]) for r in rows)
    obs_found = sum(len(set(r["right"]) & set(r["observable"])) for r in rows)
    controls = [r for r in rows if not r["truth"]]
    changed = [r for r in rows if r["truth"]]
    return {"machines": len(rows), "changes": sum(len(r["truth"]) for r in rows), "observable": obs,
            "observable_found": obs_found, "named": named, "named_right": right,
            "tied": sum(len(r["tied"]) for r in rows),
            "controls": len(controls), "controls_with_findings": sum(bool(r["found"]) for r in controls),
            "unexplained_reported": sum(r["unexplained"] > 0 for r in rows),
            "median_abs_error_before_pct": _median([abs(r["error_before_pct"]) for r in changed]),
            "median_abs_error_after_pct": _median([abs(r["error_after_pct"]) for r in changed])}


def _median(v: list[float]) -> float | None:
    v = sorted(v)
    return None if not v else (v[len(v) // 2] if len(v) % 2 else 0.5 * (v[len(v) // 2 - 1] + v[len(v) // 2]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--machines", type=int, default=12)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--rate-hz", type=float, default=None, help="diagnose the recordings resampled to this rate")
    ap.add_argument("--max-cycle-s", type=float, default=20.0)
    ap.add_argument("--observable-pct", type=float, default=0.3)
    ap.add_argument("--keep", type=Path, help="keep the recordings in this folder (and reuse them on the next run)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    from feedlog.diagnose.engine import DiagnoseConfig, diagnose
    from feedlog.ingest.linuxcnc_session import isolation_available

    rng = random.Random(args.seed)
    machines = [draw_machine(rng, bundled_programs(args.max_cycle_s)) for _ in range(args.machines)]
    isolate = isolation_available() is None
    with tempfile.TemporaryDirectory() as tmp:
        root = args.keep or Path(tmp)
        t0 = time.perf_counter()
        with ThreadPoolExecutor(2 if isolate else 1) as pool:
            paths = list(pool.map(lambda im: record(im[1], root / f"m{im[0]:02d}", isolate), enumerate(machines)))
        t_record = time.perf_counter() - t0
        rows = []
        for i, (machine, files) in enumerate(zip(machines, paths)):
            sources = [at_rate(p, args.rate_hz) for p in files] if args.rate_hz else files
            t = time.perf_counter()
            dx = diagnose(sources, f"linuxcnc-{machine['base']}", config=DiagnoseConfig(learned=False))
            row = score(machine, dx, args.observable_pct) | {"machine": f"m{i:02d}", "diagnose_s": time.perf_counter() - t}
            rows.append(row)
            if not args.json:
                truth = ", ".join(f"{k}={v:g}" for k, v in row["truth"].items()) or "(unchanged)"
                found = ", ".join(f"{k}={v:.4g}" for k, v in row["found"].items()) or "nothing"
                hidden = sorted(set(row["truth"]) - set(row["observable"]))
                print(f"{row['machine']} {row['base']:5s} {'+'.join(row['programs'])}\n"
                      f"    changed: {truth}" + (f"  (not observable here: {', '.join(hidden)})" if hidden else "") +
                      f"\n    found:   {found}" + (f"  +{row['unexplained']} unexplained" if row["unexplained"] else "") +
                      (f"  (equally good: {', '.join(row['tied'])})" if row["tied"] else "") +
                      f"\n    cycle error {row['error_before_pct']:+.2f} % -> {row['error_after_pct']:+.2f} %"
                      + (f", feedback RMS {row['fb_before_um']:.1f} -> {row['fb_after_um']:.1f} um"
                         if row["fb_before_um"] is not None else "") + f"  ({row['diagnose_s']:.1f} s)", flush=True)
    total = summarise(rows) | {"record_s": t_record, "rate_hz": args.rate_hz or "recorded", "seed": args.seed}
    if args.json:
        print(json.dumps({"summary": total, "machines": rows}, indent=1, default=str))
        return
    print(f"\n{total['machines']} machines (seed {args.seed}, {total['rate_hz']} Hz), recorded in {t_record:.0f} s")
    print(f"findings right / named:             {total['named_right']} / {total['named']}")
    print(f"changes named only as an equally good alternative: {total['tied']}")
    print(f"observable changes found:           {total['observable_found']} / {total['observable']}"
          f"  ({total['changes']} changes in all)")
    print(f"unchanged machines with a finding:  {total['controls_with_findings']} / {total['controls']}")
    print(f"machines with an unexplained part:  {total['unexplained_reported']}")
    print(f"median |cycle error| on changed machines: {total['median_abs_error_before_pct']:.2f} % -> "
          f"{total['median_abs_error_after_pct']:.2f} %")


if __name__ == "__main__":
    main()
