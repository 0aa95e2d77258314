"""`--calibrate` from `generic-xyzac` on a five-axis machine, and the profile likelihood of its Z pair.

The machine: X/Y/Z at 70/55/40 mm/s and 600/450/350 mm/s^2, A 30 deg/s and 300 deg/s^2, C 45 deg/s and
400 deg/s^2 (the rest generic-xyzac), three mix5ax programs simulated on it and measured like a 1 kHz
logger (2 um noise, 1 um quantisation), as tests/diagnose makes them. Calibrated with
`calibrate.calibrate` (what `feedlog diagnose --calibrate` runs first). Then:

- the **profile likelihood** of the Z velocity limit with the Z acceleration refitted at each point (the
  other limits held at their fitted values): the loss against Z velocity, and the Z acceleration that
  goes with it. A flat valley through the truth and the fit (a ridge) means the recordings do not tell
  the two apart; a valley with its floor at the fit and the truth well above it means the fit is wrong.
- the **calibration air-cut** `feedlog program --calibration` writes for the pair (`toolpath.calibration`),
  simulated on the machine, measured the same way and added to the recordings: the calibration
  repeated on all four, and the Z pair's values and intervals printed again.

    .venv/bin/python benchmarks/bench_calibrate_five.py [--programs mix5ax_002,mix5ax_011,mix5ax_015] [--json]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROGRAMS = ROOT / "recordings" / "programs"
TRUTH = {"axes.x.vel_max": 70.0, "axes.y.vel_max": 55.0, "axes.z.vel_max": 40.0,
         "axes.x.acc_max": 600.0, "axes.y.acc_max": 450.0, "axes.z.acc_max": 350.0,
         "axes.a.vel_max": 30.0, "axes.a.acc_max": 300.0, "axes.c.vel_max": 45.0, "axes.c.acc_max": 400.0}
BASE = "generic-xyzac"
ZV, ZA = "axes.z.vel_max", "axes.z.acc_max"


def measured(name: str, text: str, seed: int):
    from feedlog.diagnose.keys import with_values
    from feedlog.ingest.recording import PROFILE_ATTACHMENT
    from feedlog.profile import load_profile
    from feedlog.sim import MeasurementModel, measure, simulate
    from feedlog.toolpath import parse_program

    truth = with_values(load_profile(BASE), TRUTH)
    rec = measure(simulate(parse_program(text, name=name), truth),
                  MeasurementModel(rate_hz=1000.0, noise_mm=0.002, quantum_mm=0.001, rest_s=0.5, seed=seed),
                  program_text=text)
    rec.attachments[PROFILE_ATTACHMENT] = load_profile(BASE).to_toml().encode()
    rec.source = f"five_{name}.mcap"
    return rec


def calibrated(recs):
    from feedlog.diagnose.calibrate import calibrate
    from feedlog.diagnose.engine import load_cases
    from feedlog.diagnose.evidence import gather

    prof, cases = load_cases(recs, BASE)
    t0 = time.perf_counter()
    cal = calibrate(prof, cases, gather(cases, prof))
    return prof, cases, cal, time.perf_counter() - t0


def ridge(prof, cases, cal, zv_values):
    """(Z velocity, refitted Z acceleration, loss) along the profile likelihood, the rest held."""
    from feedlog.diagnose.fit import Scorer
    from feedlog.diagnose.hypothesis import family
    from feedlog.diagnose.joint import joint_fit, loss

    scorer = Scorer(prof, cases, "timing")
    held = {p.key: p.fitted_value for p in cal.parameters}
    acc = [h for h in family("axis_limits").candidates(prof, cases) if h.key == ZA]
    out = []
    for zv in zv_values:
        model = joint_fit(scorer, {**held, ZV: zv}, acc)
        out.append((zv, float(model[ZA]), loss(scorer, model)))
    truth = {**held, ZV: TRUTH[ZV], ZA: TRUTH[ZA]}
    return out, loss(scorer, held), loss(scorer, truth), float(scorer.floor.sum())


def z_rows(cal) -> dict:
    return {p.key: {"fitted": round(p.fitted_value, 2), "constrained": p.constrained, "pair": p.pair,
                    "interval": [None if x is None else round(x, 2) for x in p.interval]}
            for p in cal.parameters if p.key in (ZV, ZA)}


def main() -> int:
    from feedlog.toolpath.calibration import calibration_program

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--programs", default="mix5ax_002,mix5ax_011,mix5ax_015")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    names = args.programs.split(",")
    recs = [measured(n, (PROGRAMS / f"{n}.ngc").read_text(), seed=i) for i, n in enumerate(names)]
    prof, cases, cal, wall = calibrated(recs)
    report = {"programs": names, "calibrate_s": round(wall, 1), "parameters": {
        p.key: [round(p.fitted_value, 2), p.constrained] for p in cal.parameters}, "z": z_rows(cal),
        "held_out": cal.held_out}
    t0 = time.perf_counter()
    zvs = [30.0, 35.0, 38.0, 40.0, 42.0, 45.0, 47.6, 50.0, 55.0, 65.0]
    rows, fitted_loss, truth_loss, floor = ridge(prof, cases, cal, zvs)
    report["ridge"] = {"rows": [[zv, round(za, 1), lo] for zv, za, lo in rows], "fitted_loss": fitted_loss,
                       "truth_loss": truth_loss, "floor": floor, "s": round(time.perf_counter() - t0, 1)}
    pair = next((r for r in cal.pairs if ZV in r.keys), None)
    report["pairs"] = [r.as_dict() for r in cal.pairs]
    # the air-cut the report names for the pair (both Z limits when it named none)
    for_keys = pair.separated_by["for"] if pair is not None and pair.separated_by else [ZV, ZA]
    report["aircut_for"] = for_keys
    text = calibration_program(cal.profile, keys=for_keys)
    with_cal = [*recs, measured("calibration", text, seed=len(recs))]
    _, _, cal2, wall2 = calibrated(with_cal)
    report["with_calibration_aircut"] = {"calibrate_s": round(wall2, 1), "z": z_rows(cal2),
                                         "held_out": cal2.held_out}
    if args.json:
        print(json.dumps(report, indent=1))
        return 0
    print(f"calibrated on {', '.join(names)} in {wall:.1f} s")
    for k, (v, c) in report["parameters"].items():
        print(f"  {k:18s} {v:9.2f}  true {TRUTH[k]:7.1f}  {'constrained' if c else 'NOT constrained'}")
    print(f"  Z: {report['z']}")
    print(f"  held out: {cal.held_out}")
    print(f"  pairs: {report['pairs']}")
    print(f"profile likelihood over {ZV} ({ZA} refitted, the rest held; floor {floor:.4g}):")
    for zv, za, lo in rows:
        print(f"  {ZV} {zv:6.1f}  {ZA} {za:7.1f}  loss {lo:.5g}")
    print(f"  at the fit {fitted_loss:.5g}; at the truth (40, 350) {truth_loss:.5g}")
    print(f"with the calibration air-cut for {', '.join(for_keys)} ({wall2:.1f} s): {report['with_calibration_aircut']['z']}")
    print(f"  held out: {cal2.held_out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
