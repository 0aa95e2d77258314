"""How long `feedlog diagnose` takes: two 25 s recordings at 1 kHz (target < 60 s on 2 cores, aim 20 s).

The recordings are two bundled 25 s programs (rcl_f3000_p001, rcl_f3000_p01 by default) simulated on
the shipped LinuxCNC profile with a hidden change (`--hidden KEY=VALUE`, default axes.x.acc_max=300),
measured at 1 kHz with 2 um noise and 1 um quantisation, written to MCAP files; `--bundled` diagnoses
the bundled LinuxCNC recordings of those programs instead (the reference machine: nothing to find).
Prints the wall time per phase, the simulations run and what was found, best of `--repeat`.

    .venv/bin/python benchmarks/bench_diagnose.py [--programs A,B] [--hidden KEY=VALUE ...] [--bundled]
        [--repeat 3] [--learned] [-j N] [--scheduler local] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def make_recordings(programs: list[str], hidden: dict[str, float], folder: Path) -> list[str]:
    from feedlog.diagnose.keys import with_values
    from feedlog.ingest import write_recording
    from feedlog.ingest.recording import PROFILE_ATTACHMENT
    from feedlog.profile import load_profile
    from feedlog.sim import MeasurementModel, measure, simulate
    from feedlog.toolpath import parse_program

    base = load_profile("linuxcnc-xyz")
    truth = with_values(base, hidden) if hidden else base
    paths = []
    for i, name in enumerate(programs):
        text = (ROOT / "recordings" / "programs" / f"{name}.ngc").read_text()
        rec = measure(simulate(parse_program(text, name=name), truth),
                      MeasurementModel(rate_hz=1000, noise_mm=0.002, quantum_mm=0.001, rest_s=0.5, seed=i),
                      program_text=text)
        rec.attachments[PROFILE_ATTACHMENT] = base.to_toml().encode()
        path = folder / f"{name}.mcap"
        write_recording(path, rec)
        paths.append(str(path))
    return paths


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--programs", default="rcl_f3000_p001,rcl_f3000_p01")
    ap.add_argument("--hidden", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--bundled", action="store_true", help="the bundled LinuxCNC recordings of the programs")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--learned", action="store_true", help="also fit the learned correction when something is unexplained")
    ap.add_argument("--jobs", "-j", type=int, default=1, help="worker processes (feedlog.execution)")
    ap.add_argument("--scheduler", help="a Dask scheduler, or 'local' for a LocalCluster of --jobs workers")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    from feedlog.diagnose.engine import DiagnoseConfig, diagnose

    programs = args.programs.split(",")
    hidden = dict((k, float(v)) for k, v in (h.split("=") for h in args.hidden)) if args.hidden else (
        {} if args.bundled else {"axes.x.acc_max": 300.0})
    with tempfile.TemporaryDirectory() as tmp:
        paths = ([str(ROOT / "recordings" / f"{p}.mcap") for p in programs] if args.bundled
                 else make_recordings(programs, hidden, Path(tmp)))
        runs = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            dx = diagnose(paths, "linuxcnc-xyz", config=DiagnoseConfig(learned=args.learned, jobs=args.jobs,
                                                                       scheduler=args.scheduler))
            wall = time.perf_counter() - t0
            sims = sum(getattr(s, "simulations", 0) for s in dx.scorers.values())
            runs.append({"wall_s": round(wall, 2), "phases_s": dx.timings_s, "simulations": sims,
                         "motion_s": round(sum(c.cycle_s for c in dx.cases), 2),
                         "findings": {f.parameter: round(float(f.fitted_value), 5) for f in dx.findings},
                         "error_pct": [round(dx.levels["cycle"]["error_before_pct"], 3),
                                       round(dx.levels["cycle"]["error_after_pct"], 3)]})
    best = min(runs, key=lambda r: r["wall_s"])
    load = os.getloadavg()[0]
    if args.json:
        print(json.dumps({"hidden": hidden, "programs": programs, "runs": runs, "best": best, "load": load}))
        return
    where = f"scheduler {args.scheduler}" if args.scheduler else f"{args.jobs} job(s)"
    print(f"diagnose {len(programs)} recordings ({best['motion_s']} s of motion at 1 kHz), hidden {hidden or 'nothing'}, "
          f"{where}, load {load:.1f}")
    for r in runs:
        print(f"  wall {r['wall_s']:6.2f} s  phases {r['phases_s']}  simulations {r['simulations']}")
    print(f"best {best['wall_s']:.2f} s; found {best['findings'] or 'nothing'}; cycle error "
          f"{best['error_pct'][0]:+.2f} % -> {best['error_pct'][1]:+.2f} %")


if __name__ == "__main__":
    main()
