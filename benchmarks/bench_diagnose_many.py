"""`feedlog diagnose` on machines with many changes at once, and on machines with no profile, drawn blind.

Two kinds of machine, drawn from a seeded generator (simulated recordings: each program simulated on
the drawn machine and measured like a 1 kHz logger with 2 um noise and 1 um quantisation, the shipped
profile attached, as `tests/diagnose` makes them; LinuxCNC cannot make the second kind's far-off
machines from its shipped configs without new INI files per draw):

- **many**: `linuxcnc-xyz` with three axis limits changed (distinct axes or limits; acceleration 200-800
  mm/s^2, velocity 15-45 mm/s) and the feed override dial at 0.70-0.95, recorded on three programs
  drawn from the bundled 3-axis ones. Diagnosed with the shipped profile. A change is *named* when its
  key is found within 5 % of the true value; a finding that is not a change (or is off by more than
  15 %) is *wrong*; a change not found is *missed*. A change is *observable* when taking it out of the
  machine (the others kept) moves the three programs' simulated cycle time by 1 % or more.
- **far**: `generic-xyz` with every axis limit and the rapid rate redrawn (velocity 25-90 mm/s,
  acceleration 150-900 mm/s^2, rapids 3000-9000 mm/min), calibrated from `generic-xyz`
  (`--calibrate`) on three programs and judged on three others it never saw: the cycle time the
  calibrated profile predicts against the machine's own, with and without a coverage warning.

Printed per machine and in all; `--json` prints one object. Each case's time: wall seconds, and CPU
seconds of the diagnose call in this process plus its worker processes (`resource.RUSAGE_CHILDREN`;
by default diagnose re-simulates the recordings of a large case on the machine's cores, `--jobs 1`:
serially), with the load average at its end.

    .venv/bin/python benchmarks/bench_diagnose_many.py [--machines 4] [--seed 1] [--kind many|far|both] [--rows]
        [--jobs N]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import resource
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROGRAMS = ROOT / "recordings" / "programs"
POOL = ("corners_f3000_p001", "pocket_f3000_p001", "mix_010", "mix_020", "mix_035", "longdense_003",
        "corners_f2000_p005", "pocket_f2000_p01", "freeform_f2000_p005", "circle_f3000_p001", "mixdense_003",
        "test_p001", "rcl_f3000_p01")


def record(values: dict, programs, base: str, seed: int):
    from feedlog.diagnose.keys import with_values
    from feedlog.ingest.recording import PROFILE_ATTACHMENT
    from feedlog.profile import load_profile
    from feedlog.sim import MeasurementModel, measure, simulate
    from feedlog.toolpath import parse_program

    truth = with_values(load_profile(base), values)
    out = []
    for i, name in enumerate(programs):
        text = (PROGRAMS / f"{name}.ngc").read_text()
        rec = measure(simulate(parse_program(text, name=name), truth),
                      MeasurementModel(rate_hz=1000.0, noise_mm=0.002, quantum_mm=0.001, rest_s=0.5, seed=seed + i),
                      program_text=text)
        rec.attachments[PROFILE_ATTACHMENT] = load_profile(base).to_toml().encode()
        rec.source = f"m{seed}_{name}.mcap"
        out.append(rec)
    return out


def draw_many(rng: random.Random) -> dict:
    slots = [(a, lim) for a in "xyz" for lim in ("acc_max", "vel_max")]
    rng.shuffle(slots)
    values = {}
    for a, lim in slots[:3]:
        values[f"axes.{a}.{lim}"] = float(round(rng.uniform(200, 800) if lim == "acc_max" else rng.uniform(15, 45)))
    values["sim.feed_override.override"] = round(rng.uniform(0.70, 0.95), 2)
    return values


def draw_far(rng: random.Random) -> dict:
    values = {"rapid_mm_min": float(round(rng.uniform(3000, 9000), -2))}
    for a in "xyz":
        values[f"axes.{a}.vel_max"] = float(round(rng.uniform(25, 90)))
        values[f"axes.{a}.acc_max"] = float(round(rng.uniform(150, 900), -1))
    return values


def observable(values: dict, programs, base: str, pct: float = 1.0) -> list[str]:
    """The changes whose removal (the others kept) moves the programs' total simulated cycle time by
    `pct` or more: what the recordings can show at all."""
    from feedlog.diagnose.keys import with_values
    from feedlog.profile import load_profile
    from feedlog.sim import simulate
    from feedlog.toolpath import parse_program

    progs = [parse_program((PROGRAMS / f"{n}.ngc").read_text(), name=n) for n in programs]

    def total(vals: dict) -> float:
        prof = with_values(load_profile(base), vals)
        return sum(simulate(p, prof).cycle_time_s for p in progs)

    full = total(values)
    return [k for k in values if abs(total({q: v for q, v in values.items() if q != k}) / full - 1) * 100 >= pct]


def _cpu_s() -> float:
    """CPU seconds of this process and of its children that have ended (diagnose's worker processes)."""
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + kids.ru_utime + kids.ru_stime


def run_many(rng: random.Random, i: int, jobs: int | None = None) -> dict:
    from feedlog.diagnose.engine import DiagnoseConfig, diagnose

    values = draw_many(rng)
    programs = rng.sample(POOL[:6], 3)
    recs = record(values, programs, "linuxcnc-xyz", 100 * i)
    t0, c0 = time.perf_counter(), _cpu_s()
    dx = diagnose(recs, "linuxcnc-xyz", config=DiagnoseConfig(learned=False, jobs=jobs))
    seconds, cpu = time.perf_counter() - t0, _cpu_s() - c0
    found = {f.parameter: float(f.fitted_value) for f in dx.findings}
    named = [k for k, v in values.items() if k in found and abs(found[k] / v - 1) <= 0.05]
    wrong = [k for k, v in found.items() if k not in values or abs(v / values[k] - 1) > 0.15]
    cyc = dx.levels["cycle"]
    seen = observable(values, programs, "linuxcnc-xyz")
    return {"kind": "many", "machine": i, "changed": values, "programs": programs, "found": found, "named": named,
            "observable": seen, "missed": [k for k in values if k not in found], "wrong": wrong,
            "error_before_pct": cyc["error_before_pct"], "error_after_pct": cyc["error_after_pct"],
            "seconds": seconds, "cpu_seconds": cpu, "load": os.getloadavg()[0]}


def run_far(rng: random.Random, i: int, jobs: int | None = None) -> dict:
    from feedlog.coverage import program_warnings
    from feedlog.diagnose.engine import DiagnoseConfig, diagnose
    from feedlog.diagnose.keys import with_values
    from feedlog.profile import load_profile
    from feedlog.sim import simulate
    from feedlog.toolpath import parse_program

    values = draw_far(rng)
    programs = rng.sample(POOL, 6)
    fit_on, judge_on = programs[:3], programs[3:]
    recs = record(values, fit_on, "generic-xyz", 100 * i)
    t0, c0 = time.perf_counter(), _cpu_s()
    dx = diagnose(recs, "generic-xyz", config=DiagnoseConfig(learned=False, calibrate=True, jobs=jobs))
    seconds, cpu = time.perf_counter() - t0, _cpu_s() - c0
    truth, generic = with_values(load_profile("generic-xyz"), values), load_profile("generic-xyz")
    judged = []
    for name in judge_on:
        prog = parse_program((PROGRAMS / f"{name}.ngc").read_text(), name=name)
        t_true = simulate(prog, truth).cycle_time_s
        fitted = simulate(prog, dx.extended)
        warned = program_warnings(dx.extended, fitted.series, prog.blocks)
        judged.append({"program": name, "error_pct": 100 * (fitted.cycle_time_s / t_true - 1),
                       "generic_error_pct": 100 * (simulate(prog, generic).cycle_time_s / t_true - 1),
                       "warned": sorted({w.split(":")[0] for w in warned})})
    cal = dx.calibration
    return {"kind": "far", "machine": i, "true": values, "fitted_on": fit_on, "judged": judged,
            "constrained": [p.key for p in cal.parameters if p.constrained],
            "constrained_within_5pct": [p.key for p in cal.parameters if p.constrained
                                        and abs(p.fitted_value / values[p.key] - 1) <= 0.05],
            "own_error_before_pct": dx.levels["cycle"]["error_before_pct"],
            "own_error_after_pct": dx.levels["cycle"]["error_after_pct"], "seconds": seconds, "cpu_seconds": cpu,
            "load": os.getloadavg()[0]}


def _many_lines(r: dict, i: int) -> list[str]:
    return [f"many m{i}: changed {r['changed']} on {', '.join(r['programs'])}",
            f"  found {{{', '.join(f'{k}: {v:.4g}' for k, v in r['found'].items())}}}; named {len(r['named'])}/4 "
            f"({len(r['observable'])} observable), missed {r['missed']}, wrong {r['wrong']}; error "
            f"{r['error_before_pct']:+.2f} % -> {r['error_after_pct']:+.2f} %; {r['seconds']:.0f} s "
            f"({r['cpu_seconds']:.0f} s CPU, load {r['load']:.1f})"]


def _far_lines(r: dict, i: int) -> list[str]:
    return [f"far m{i}: {r['true']} fitted on {', '.join(r['fitted_on'])}: {len(r['constrained'])} "
            f"constrained ({len(r['constrained_within_5pct'])} within 5 %), own error "
            f"{r['own_error_before_pct']:+.2f} % -> {r['own_error_after_pct']:+.2f} %; {r['seconds']:.0f} s "
            f"({r['cpu_seconds']:.0f} s CPU, load {r['load']:.1f})"] + [
        f"  unseen {j['program']}: {j['error_pct']:+.2f} % (generic {j['generic_error_pct']:+.2f} %)"
        f"{' warned: ' + ', '.join(j['warned']) if j['warned'] else ''}" for j in r["judged"]]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--machines", type=int, default=4, help="machines of each kind")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--kind", choices=("many", "far", "both"), default="both")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--rows", action="store_true", help="also print each machine's row as one JSON line when done")
    ap.add_argument("--jobs", "-j", type=int, default=None,
                    help="diagnose's processes (default: its own choice, the cores for a large case; 1: serially)")
    args = ap.parse_args()
    rng = random.Random(args.seed)
    rows = []
    for i in range(args.machines):
        for kind, run, say in (("many", run_many, _many_lines), ("far", run_far, _far_lines)):
            if args.kind not in (kind, "both"):
                continue
            r = run(rng, i, args.jobs)
            rows.append(r)
            if args.rows:
                print(json.dumps(r), flush=True)
            if not args.json:
                print("\n".join(say(r, i)), flush=True)
    many = [r for r in rows if r["kind"] == "many"]
    far = [r for r in rows if r["kind"] == "far"]
    total: dict = {"seed": args.seed}
    if many:
        total["many"] = {"changes": 4 * len(many), "observable": sum(len(r["observable"]) for r in many),
                         "named": sum(len(r["named"]) for r in many),
                         "observable_named": sum(len(set(r["named"]) & set(r["observable"])) for r in many),
                         "missed": sum(len(r["missed"]) for r in many),
                         "observable_missed": sum(len(set(r["missed"]) & set(r["observable"])) for r in many),
                         "wrong": sum(len(r["wrong"]) for r in many),
                         "mean_abs_error_before_pct": sum(abs(r["error_before_pct"]) for r in many) / len(many),
                         "mean_abs_error_after_pct": sum(abs(r["error_after_pct"]) for r in many) / len(many),
                         "max_seconds": max(r["seconds"] for r in many),
                         "max_cpu_seconds": max(r["cpu_seconds"] for r in many)}
    if far:
        judged = [j for r in far for j in r["judged"]]
        quiet = [j for j in judged if not j["warned"]]
        total["far"] = {"unseen_programs": len(judged), "not_warned": len(quiet),
                        "not_warned_within_1pct": sum(abs(j["error_pct"]) < 1.0 for j in quiet),
                        "worst_not_warned_pct": max((abs(j["error_pct"]) for j in quiet), default=None),
                        "warned": len(judged) - len(quiet),
                        "warned_off_by_1pct_or_more": sum(abs(j["error_pct"]) >= 1.0 for j in judged if j["warned"]),
                        "mean_abs_generic_pct": sum(abs(j["generic_error_pct"]) for j in judged) / len(judged),
                        "max_seconds": max(r["seconds"] for r in far),
                        "max_cpu_seconds": max(r["cpu_seconds"] for r in far)}
    if args.json:
        print(json.dumps({"rows": rows, "total": total}))
    else:
        print(json.dumps(total, indent=1))


if __name__ == "__main__":
    main()
