"""Wall time of the LinuxCNC recordings the integration tests make, the old way against sessions.record_all.

    python benchmarks/bench_test_recordings.py [--only before|after] [--sessions N]

For each fixture that records on a derived LinuxCNC machine (tests/linuxcnc: calibrate, changes,
diagnose, geometry, many, in pytest's order), the same jobs are recorded twice: "before" as the tests
did until now (diagnose two sessions at a time, every other fixture one at a time, nothing shared) and
"after" with `tests.linuxcnc.sessions.record_all` (up to N sessions at once, a recording made earlier in
the run served again). Prints the seconds of each fixture and the total, and the largest difference of
any recording's cycle time between the two ways (it should be a servo period or less). Needs LinuxCNC
and root (isolated sessions). Figures, not a test.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))

from feedlog.ingest import read_recording  # noqa: E402
from feedlog.ingest.linuxcnc import record_linuxcnc  # noqa: E402
from linuxcnc_variants import derive_machine  # noqa: E402
from tests.linuxcnc import sessions  # noqa: E402
from tests.linuxcnc import test_linuxcnc_calibrate as cal  # noqa: E402
from tests.linuxcnc import test_linuxcnc_changes as chg  # noqa: E402
from tests.linuxcnc import test_linuxcnc_diagnose as dia  # noqa: E402
from tests.linuxcnc import test_linuxcnc_geometry as geo  # noqa: E402
from tests.linuxcnc import test_linuxcnc_many as many  # noqa: E402

Job = sessions.Job


def fixtures(root: Path) -> dict[str, tuple[list[Job], int, float]]:
    """name -> (jobs, sessions at once before, timeout) as each test module builds them."""
    out = {}
    ini = derive_machine("xyz", root / "cal" / "far", changes=cal.CHANGES)
    out["calibrate"] = ([Job(ini, cal.PROGRAMS / f"{n}.ngc", ini.parent / f"far_{n}.mcap")
                         for n in (*cal.FIT_ON, *cal.JUDGE)], 1, 180.0)
    xyz = chg.CONFIGS / "xyz.ini"
    out["changes"] = ([Job(xyz, chg.PROGRAMS / "pocket_f3000_p001.ngc", root / "chg" / "pocket.mcap",
                           {"feed_override_at": (chg.TURN,)}),
                       Job(xyz, chg.PROGRAMS / "corners_f3000_p001.ngc", root / "chg" / "corners.mcap")], 1, 120.0)
    jobs = []
    for name, (base, changes, lags, override, programs, _) in dia.MACHINES.items():
        ini = derive_machine(base, root / "dia" / name, changes=changes, feedback_lag=lags)
        options = {"feed_override": override} if override is not None else {}
        jobs += [Job(ini, dia.PROGRAMS / f"{p}.ngc", ini.parent / f"{name}_{p}.mcap", options) for p in programs]
    out["diagnose"] = (jobs, 2, 120.0)
    jobs = []
    for name, params in geo.MACHINES.items():
        ini = derive_machine("xyzac", root / "geo" / name, hal_params=params)
        jobs += [Job(ini, geo.PROGRAMS / f"{p}.ngc", ini.parent / f"{name}_{p}.mcap") for p in geo.P5]
    out["geometry"] = (jobs, 1, 120.0)
    ini = derive_machine("xyz", root / "many" / "four", changes=many.CHANGES)
    out["many"] = ([Job(ini, many.PROGRAMS / f"{n}.ngc", ini.parent / f"four_{n}.mcap", {"feed_override": 0.85})
                    for n in many.PROGRAMS_USED], 1, 120.0)
    return out


def moved(job: Job, folder: str) -> Job:
    return Job(job.ini, job.program, job.out.parent / folder / job.out.name, job.options)


def before(jobs: list[Job], at_once: int, timeout_s: float) -> None:
    def run(job: Job) -> None:
        job.out.parent.mkdir(parents=True, exist_ok=True)
        summary = record_linuxcnc(job.ini, job.program, job.out, isolate=sessions.isolated(), timeout_s=timeout_s,
                                  **job.options)
        assert summary["status"] == "complete", summary
    with ThreadPoolExecutor(at_once) as pool:
        list(pool.map(run, jobs))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=("before", "after"))
    parser.add_argument("--sessions", type=int, default=sessions.SESSIONS)
    args = parser.parse_args()
    sessions.SESSIONS = args.sessions
    ways = [args.only] if args.only else ["before", "after"]
    figures: dict[str, dict[str, float]] = {way: {} for way in ways}
    with tempfile.TemporaryDirectory(prefix="bench-test-rec-") as tmp:
        sets = fixtures(Path(tmp))
        for way in ways:
            for name, (jobs, at_once, timeout_s) in sets.items():
                mine = [moved(job, way) for job in jobs]
                t0 = time.monotonic()
                if way == "before":
                    before(mine, at_once, timeout_s)
                else:
                    sessions.record_all(mine, timeout_s=timeout_s)
                figures[way][name] = round(time.monotonic() - t0, 1)
                print(f"{way:6} {name:9} {len(jobs):2} recordings {figures[way][name]:6.1f} s", flush=True)
            print(f"{way:6} total {sum(figures[way].values()):6.1f} s", flush=True)
        if len(ways) == 2:
            worst = 0.0
            for jobs, _, _ in sets.values():
                for job in jobs:
                    a, b = (float(read_recording(moved(job, w).out).metadata["cycle_time_s"]) for w in ways)
                    worst = max(worst, abs(a - b))
            figures["largest_cycle_time_difference_ms"] = {"all": round(worst * 1000, 3)}
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
