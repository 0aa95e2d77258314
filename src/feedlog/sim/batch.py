"""Simulating many part programs: one task per program on `feedlog.execution`'s backend.

Each task parses one program (absolute path or fsspec URL), simulates it on the profile (read once on
the client and sent as data) and publishes, each whole (`feedlog.storage`):
- OUTDIR/<program stem>/ with series.parquet (the interpolated series), blocks.parquet (per block) and
  summary.json (what `feedlog sim --json` prints);
- its partitions of OUTDIR/dataset/blocks/ and OUTDIR/dataset/series/ (`program=<stem>/part-0.parquet`).
The summary travels back. A program that fails with one of our errors is reported per program.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from feedlog import storage
from feedlog.dataset import run_per_input, write_partition

FILES = ("series.parquet", "blocks.parquet", "summary.json")
DATASET_TABLES = ("blocks", "series")
PARTITION_KEY = "program"


@dataclass(frozen=True)
class SimTask:
    program: str                 # absolute path or URL, read by the worker
    label: str                   # as given: the name in messages and summaries
    outdir: str                  # OUTDIR, absolute path or URL
    profile: Any                 # MachineProfile
    mechanisms: Any = None
    dt_s: float | None = None
    token: str = ""
    lenient: bool = False        # unsupported program codes skipped (listed in the summary) instead of failing
    dialect: str = "auto"        # G-code dialect (feedlog.toolpath.dialects)
    interp: Any = None           # InterpOptions: subroutine folders, tool table, parameter file


@dataclass
class SimItem:
    program: str
    outdir: str
    ok: bool
    summary: dict[str, Any] | None = None
    error: str | None = None
    exit_code: int = 0  # of the error: 2 bad input, 1 an output that could not be written


def simulate_one(task: SimTask) -> dict[str, Any]:
    """Runs on a worker: parse, simulate, publish the folder and the dataset partitions; the summary."""
    from feedlog.sim.simulate import simulate
    from feedlog.toolpath import load_program

    name = storage.stem(task.label)
    with storage.local_input(task.program) as local:
        program = load_program(Path(local), name=task.label, lenient=task.lenient, dialect=task.dialect,
                               interp=task.interp)
    result = simulate(program, task.profile, mechanisms=task.mechanisms, dt_s=task.dt_s)
    summary = {"program": task.label, **result.summary(), **program_notes(program)}
    with storage.publish_dir(storage.join(task.outdir, name), token=task.token) as staging:
        result.series.to_parquet(staging / FILES[0], index=False)
        result.blocks.to_parquet(staging / FILES[1], index=False)
        (staging / FILES[2]).write_text(json.dumps(summary, indent=1) + "\n")
    for table, frame in (("blocks", result.blocks), ("series", result.series)):
        write_partition(task.outdir, table, PARTITION_KEY, name, frame, token=task.token)
    return summary


def program_notes(program: Any) -> dict[str, Any]:
    """What a summary says about reading the program: its dialect, the codes skipped (lenient), warnings."""
    out: dict[str, Any] = {"dialect": program.metadata.get("dialect", "rs274ngc")}
    if program.unsupported:
        out["skipped"] = [{"line": u.line, "code": u.code, "reason": u.reason} for u in program.unsupported]
    if program.warnings:
        out["warnings"] = list(program.warnings)
    return out


def simulate_many(programs: list[str | Path], outdir: str | Path, *, profile: Any, mechanisms: Any = None,
                  dt_s: float | None = None, jobs: int | None = None, scheduler: str | None = None,
                  overwrite: bool = False, progress: bool = True, log=None, lenient: bool = False,
                  dialect: str = "auto", interp: Any = None) -> list[SimItem]:
    """Simulate every program into OUTDIR/<stem>/ and OUTDIR/dataset/; results in the input order.

    `profile` is a MachineProfile, a shipped name or a TOML path (read here once).
    """
    from feedlog.profile import MachineProfile, load_profile

    prof = profile if isinstance(profile, MachineProfile) else load_profile(profile)
    labels, outcome = run_per_input(
        programs, outdir,
        lambda label, root, token: SimTask(program=storage.absolute(label), label=label, outdir=root, profile=prof,
                                           mechanisms=mechanisms, dt_s=dt_s, token=token, lenient=lenient,
                                           dialect=dialect, interp=interp),
        simulate_one, what="programs", files=FILES, tables=DATASET_TABLES, key=PARTITION_KEY, overwrite=overwrite,
        desc="sim", jobs=jobs, scheduler=scheduler, progress=progress, log=log)
    items = []
    for label in labels:
        shown, result = storage.join(str(outdir), storage.stem(label)), outcome[label]
        if isinstance(result, str):
            items.append(SimItem(label, shown, False, error=f"{result} exists; pass --overwrite to replace it",
                                 exit_code=2))
        else:
            items.append(SimItem(label, shown, result.ok, summary=result.value, error=result.error,
                                 exit_code=result.exit_code))
    return items
