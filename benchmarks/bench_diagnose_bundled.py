"""feedlog diagnose on the bundled LinuxCNC recordings: the reference machine as its own control.

Every recording of recordings/manifest.toml is diagnosed on its own (held-out stretches of it) with
the profile it was recorded on; with `--families` the recordings of one program family and machine
are also diagnosed together (leave one recording out). A faithful recording should give no finding:
the script prints, per run, the timing error before, what was found, what stays unexplained, a change
during the session and the wall time, then the counts.

    .venv/bin/python benchmarks/bench_diagnose_bundled.py [-j 2] [--families] [--only NAME,...] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from feedlog.manifest import read_manifest

ROOT = Path(__file__).resolve().parents[1]
RECORDINGS = ROOT / "recordings"


def run_one(item: tuple[str, list[str], str]) -> dict:
    from feedlog.diagnose.engine import DiagnoseConfig, diagnose
    from feedlog.errors import FeedlogError

    label, paths, profile = item
    t0 = time.perf_counter()
    try:
        dx = diagnose(paths, profile, config=DiagnoseConfig(learned=False))
    except FeedlogError as exc:
        return {"run": label, "error": str(exc)[:200], "wall_s": time.perf_counter() - t0}
    cyc = dx.levels["cycle"]
    return {"run": label, "recordings": len(paths), "error_before_pct": cyc["error_before_pct"],
            "error_after_pct": cyc["error_after_pct"],
            "findings": [f"{f.parameter}={f.fitted_value:.4g}" for f in dx.findings],
            "unexplained": [f"{u['level']} {u['error_pct']:.2f} %: {u['where']}" for u in dx.unexplained],
            "changes": [c.text() for c in dx.changes],
            "wall_s": time.perf_counter() - t0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-j", "--jobs", type=int, default=2)
    ap.add_argument("--families", action="store_true", help="also diagnose each family's recordings together")
    ap.add_argument("--only", help="comma-separated recording names")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    entries = read_manifest(RECORDINGS / "manifest.toml")
    if args.only:
        keep = set(args.only.split(","))
        entries = [e for e in entries if e.name in keep]
    items = [(e.name, [str(e.path)], e.profile) for e in entries]
    if args.families:
        groups: dict[tuple[str, str], list[str]] = {}
        for e in entries:
            groups.setdefault((e.family, e.profile), []).append(str(e.path))
        items += [(f"family {fam} ({len(p)})", p, prof) for (fam, prof), p in groups.items() if len(p) > 1]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        rows = list(pool.map(run_one, items))
    wall = time.perf_counter() - t0
    if args.json:
        json.dump(rows, sys.stdout, indent=1)
        return
    for r in rows:
        if "error" in r:
            print(f"{r['run']:40s} refused: {r['error']}")
            continue
        print(f"{r['run']:40s} {r['error_before_pct']:+7.3f} % -> {r['error_after_pct']:+7.3f} %  "
              f"{r['wall_s']:5.1f} s  findings: {', '.join(r['findings']) or '-'}"
              + (f"  unexplained: {'; '.join(r['unexplained'])}" if r["unexplained"] else "")
              + (f"  {'; '.join(r['changes'])}" if r["changes"] else ""))
    done = [r for r in rows if "error" not in r]
    print(f"\n{len(rows)} runs, {wall:.0f} s wall ({args.jobs} workers): {sum(bool(r['findings']) for r in done)} with "
          f"a finding, {sum(bool(r['unexplained']) for r in done)} with an unexplained residual, "
          f"{sum(bool(r['changes']) for r in done)} with a change during the session, "
          f"{len(rows) - len(done)} refused")


if __name__ == "__main__":
    main()
