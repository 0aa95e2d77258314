"""The bundled recordings aligned serially, with `-j 2`, and on a Dask cluster of 2 single-threaded workers.

Every run is `feedlog.align.batch.align_many` (what `feedlog align` calls: read MCAP, align, write the
per-recording folder and the dataset partitions) into a fresh folder; the outputs of all runs are
compared byte for byte (Parquet) at the end. Printed per run: wall time, speed-up over serial, the
summed time inside the tasks, how much the tasks were slowed (their summed time over the least serial
one: near 1.0x the workers had their cores, 2x they had one core between them: other jobs on a shared
machine, told apart from the backend's cost), and the per-task overhead

    overhead = (wall x workers - sum of task times) / tasks

which holds everything that is not a task's own work: pool or cluster start, pickling, scheduling,
imports on fresh workers, and workers idle at the end of the job. The Dask cluster is a
`LocalCluster` (2 worker processes, 1 thread each, TCP between them and the scheduler), started
before the timed runs; its first job (cold: workers import feedlog on their first task) and a second
job (warm) are timed separately. The machine is shared: the load average is printed with each run.

    .venv/bin/python benchmarks/bench_scaleout.py [--repeat 3] [--limit N]

With --repeat the three configurations alternate, and the best and median wall time of each are printed:
another job on the machine slows whichever run it overlaps.
"""

from __future__ import annotations

import argparse
import logging
import os
import tempfile
import time
from pathlib import Path

from feedlog.align.batch import align_many
from feedlog.manifest import read_manifest

ROOT = Path(__file__).resolve().parents[1]


def bundled(limit: int | None) -> list[Path]:
    files = [e.path for e in read_manifest(ROOT / "recordings" / "manifest.toml")]
    return files[:limit] if limit else files


def load() -> str:
    return "/".join(f"{x:.2f}" for x in os.getloadavg())


def timed(name: str, recordings: list[Path], out: Path, workers: int, **kw) -> dict:
    before = load()
    start = time.perf_counter()
    items = align_many(recordings, out, progress=False, **kw)
    wall = time.perf_counter() - start
    ok = [i for i in items if i.ok]
    task_s = sum(i.task_s for i in ok)
    return {"name": name, "wall": wall, "task_s": task_s, "ok": len(ok), "failed": [i.recording for i in items if not i.ok],
            "overhead_ms": 1000 * (wall * workers - task_s) / len(items), "load": f"{before} -> {load()}", "out": out}


def identical(a: Path, b: Path) -> bool:
    files = sorted(p.relative_to(a) for p in a.rglob("*.parquet"))
    return bool(files) and files == sorted(p.relative_to(b) for p in b.rglob("*.parquet")) and all(
        (a / f).read_bytes() == (b / f).read_bytes() for f in files)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=1, help="runs of each configuration")
    parser.add_argument("--limit", type=int, default=None, help="only the first N recordings of the manifest")
    args = parser.parse_args()
    from distributed import LocalCluster

    recordings = bundled(args.limit)
    print(f"{len(recordings)} recordings, {sum(p.stat().st_size for p in recordings) / 1e6:.1f} MB; "
          f"{os.cpu_count()} cores; load average (1/5/15 min) {load()}")
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-scaleout-") as tmp:
        t0 = time.perf_counter()
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                               silence_logs=logging.ERROR)
        print(f"LocalCluster of 2 single-threaded workers started in {time.perf_counter() - t0:.1f} s")
        try:
            for r in range(args.repeat):
                rows.append(timed("serial", recordings, Path(tmp, f"serial{r}"), 1, jobs=1))
                rows.append(timed("-j 2", recordings, Path(tmp, f"j2_{r}"), 2, jobs=2))
                label = "dask, cold workers" if r == 0 else "dask"
                rows.append(timed(label, recordings, Path(tmp, f"dask{r}"), 2, scheduler=cluster.scheduler_address))
                if r == 0:
                    rows.append(timed("dask, warm workers", recordings, Path(tmp, "dask_warm"), 2,
                                      scheduler=cluster.scheduler_address))
        finally:
            cluster.close()
        serial = min(r["wall"] for r in rows if r["name"] == "serial")
        j2 = min(r["wall"] for r in rows if r["name"] == "-j 2")
        work = min(r["task_s"] for r in rows if r["name"] == "serial")
        print(f"\n{'run':<20} {'wall s':>7} {'speed-up':>8} {'vs -j 2':>8} {'tasks s':>8} {'slowed':>6} "
              f"{'overhead ms/task':>16}  aligned  load before -> after")
        for r in rows:  # slowed: task time / the least serial task time (> 1: the tasks shared their cores)
            print(f"{r['name']:<20} {r['wall']:7.2f} {serial / r['wall']:7.2f}x {r['wall'] / j2 - 1:+7.1%} "
                  f"{r['task_s']:8.2f} {r['task_s'] / work:5.2f}x {r['overhead_ms']:16.1f}  {r['ok']:>7}  {r['load']}")
        if args.repeat > 1:
            print(f"\n{'best of ' + str(args.repeat):<20} {'wall s':>7} {'speed-up':>8} {'vs -j 2':>8}   (median wall s)")
            for name in ("serial", "-j 2", "dask"):
                walls = sorted(r["wall"] for r in rows if r["name"].startswith(name))
                print(f"{name:<20} {walls[0]:7.2f} {serial / walls[0]:7.2f}x {walls[0] / j2 - 1:+7.1%}   "
                      f"({walls[len(walls) // 2]:.2f})")
        failed = sorted({f for r in rows for f in r["failed"]})
        print(f"\nnot aligned (our error, the same in every run): {', '.join(Path(f).stem for f in failed) or 'none'}")
        same = all(identical(rows[0]["out"], r["out"]) for r in rows[1:])
        print(f"outputs of all runs identical byte for byte (Parquet): {'yes' if same else 'NO'}")


if __name__ == "__main__":
    main()
