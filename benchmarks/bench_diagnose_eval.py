"""What one step of a diagnose fit costs: re-simulating the recordings for one profile and scoring them.

A fit, a held-out fold, a screen and a joint least-squares step all ask the timing `Scorer` for the loss
of the recordings under one more profile; a many-cause case asks for thousands, so the cost of one is
what a case takes. The recordings are `bench_diagnose_many`'s first *many* machine of the seed (three
bundled programs simulated on `linuxcnc-xyz` with three changed limits and a feed override, measured at
1 kHz). Printed: CPU milliseconds per evaluation of all recordings (`unit_losses`) and of the units of
all recordings but one (`Scorer.loss`, what a leave-one-recording-out fold's fit asks), each over
`--evals` distinct profiles, best of `--repeat` (CPU time, so a loaded machine inflates it less than wall
time; `uptime` printed). Then the wall milliseconds of the same requests (all recordings, and all but
one, alternately) serially and on a `ScorerPool` of `--processes` (diagnose's default on a large case):
what sharing each request's recordings over the cores gives, when the machine has a core free, and the
pool's measured pace (its request time over the serial one; at 0.95 or more it pauses).

    .venv/bin/python benchmarks/bench_diagnose_eval.py [--evals 30] [--repeat 3] [--seed 1] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--evals", type=int, default=30, help="distinct profiles evaluated per round")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--processes", type=int, default=2, help="processes of the pool measured (1: skip it)")
    args = ap.parse_args()
    import numpy as np

    import bench_diagnose_many as many
    from feedlog.diagnose.engine import load_cases
    from feedlog.diagnose.fit import Scorer

    rng = random.Random(args.seed)
    values = many.draw_many(rng)
    programs = rng.sample(many.POOL[:6], 3)
    profile, cases = load_cases(many.record(values, programs, "linuxcnc-xyz", 0), "linuxcnc-xyz")
    key = sorted(values)[0]
    best = {"all_ms": np.inf, "fold_ms": np.inf}
    for r in range(args.repeat):
        scorer = Scorer(profile, cases, "timing")   # a fresh cache each round: every profile is new
        fold = [j for g in scorer.groups[1:] for j in g]
        grid = np.geomspace(0.6, 1.4, args.evals) * float(values[key]) * (1 + 1e-3 * r)
        c0 = time.process_time()
        for v in grid:
            scorer.unit_losses({key: float(v)})
        best["all_ms"] = min(best["all_ms"], 1e3 * (time.process_time() - c0) / args.evals)
        # a fold's loss: `Scorer.loss` simulates only its recordings (before it existed, all of them)
        fold_loss = getattr(scorer, "loss", lambda vals, units: float(scorer.unit_losses(vals)[units].sum()))
        c0 = time.process_time()
        for v in grid * 1.01:
            fold_loss({key: float(v)}, fold)
        best["fold_ms"] = min(best["fold_ms"], 1e3 * (time.process_time() - c0) / args.evals)
    if args.processes > 1:
        best.update(_pool_wall(profile, cases, key, float(values[key]), args))
    out = {"programs": programs, "parameter": key, "recordings": len(cases), "evals": args.evals, **best,
           "load_1min": os.getloadavg()[0]}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{len(cases)} recordings ({', '.join(programs)}), {key} varied over {args.evals} values, "
              f"best of {args.repeat}: {best['all_ms']:.1f} ms CPU per evaluation of all recordings, "
              f"{best['fold_ms']:.1f} ms of all but one (load {out['load_1min']:.1f})")
        if "pool_wall_ms" in best:
            print(f"wall per request (all recordings and all but one, alternately), best of {args.repeat}: "
                  f"{best['serial_wall_ms']:.2f} ms serially, {best['pool_wall_ms']:.2f} ms on {args.processes} "
                  f"processes (pace {best['pool_pace']:.2f}, {best['pool_pauses']} pause(s))")


def _pool_wall(profile, cases, key: str, value: float, args) -> dict:
    import numpy as np

    from feedlog.diagnose.fit import Scorer
    from feedlog.diagnose.scorer_pool import ScorerPool

    out = {"serial_wall_ms": np.inf, "pool_wall_ms": np.inf, "pool_pace": None, "pool_pauses": 0}
    for r in range(args.repeat):
        for mode in ("serial", "pool"):
            scorer = Scorer(profile, cases, "timing")
            fold = [j for g in scorer.groups[1:] for j in g]
            pool = ScorerPool(scorer, args.processes) if mode == "pool" else None
            grid = np.geomspace(0.6, 1.4, args.evals) * value * (1 + 1e-3 * r)
            t0 = time.perf_counter()
            for k, v in enumerate(grid):
                if k % 2:
                    scorer.loss({key: float(v)}, fold)
                else:
                    scorer.unit_losses({key: float(v)})
            ms = 1e3 * (time.perf_counter() - t0) / args.evals
            out[f"{mode}_wall_ms"] = min(out[f"{mode}_wall_ms"], ms)
            if pool is not None:
                out["pool_pace"], out["pool_pauses"] = round(pool.pace, 3), max(out["pool_pauses"], pool.pauses)
                pool.close()
    return out


if __name__ == "__main__":
    main()
