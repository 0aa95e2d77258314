"""Aligning many recordings: one task per recording on `feedlog.execution`'s backend, one output folder each.

Each task reads one recording (absolute path or fsspec URL), aligns it and publishes, each whole
(written under a temporary name, then renamed, `feedlog.storage`):
- OUTDIR/<recording stem>/ with points.parquet, blocks.parquet and report.json, as `write_alignment`;
- its partitions of the dataset OUTDIR/dataset/blocks/ and OUTDIR/dataset/points/
  (`recording=<stem>/part-0.parquet`, `feedlog.dataset`), which pandas, dask and duckdb read as one table.
Only a small summary travels back. The part program and profile given for all recordings are read
once here and sent to the workers as data, so workers need only reach the recordings.

Existing outputs are checked here before any task runs: without `overwrite` that recording fails with
"exists" and is not aligned. A recording that fails with one of our errors is reported with its
message and does not stop the others; a bug (any other exception) propagates.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from feedlog import storage
from feedlog.align.pipeline import AlignConfig, align_recording
from feedlog.align.tables import FILES, dataset_points, table_metadata, write_alignment
from feedlog.dataset import run_per_input, write_partition

DATASET_TABLES = ("blocks", "points")
PARTITION_KEY = "recording"
BLOCK_COLUMNS = ["block", "line", "t_start_ns", "t_end_ns", "duration_s"]


@dataclass
class BatchItem:
    recording: str
    outdir: str
    ok: bool
    cycle_time_s: float | None = None
    blocks: list[dict[str, Any]] | None = None
    error: str | None = None
    samples: int = 0
    task_s: float = 0.0
    exit_code: int = 0  # of the error: 2 bad input, 1 an output that could not be written
    exists: bool = False  # not run: its outputs exist and --overwrite was not given
    notes: list[str] | None = None  # what align decided by itself (a line range, a work offset, lines only)


@dataclass(frozen=True)
class AlignTask:
    """What one worker needs: where to read and write (absolute or URLs) and the shared inputs as data."""

    recording: str              # absolute path or URL, read by the worker
    label: str                  # as given: the recording's name in report.json and the tables' metadata
    outdir: str                 # OUTDIR, absolute path or URL
    program: Any = None         # a parsed toolpath Program, or None: the recording's attached program
    profile: Any = None         # a MachineProfile, or None: the attached profile
    config: AlignConfig = AlignConfig()
    with_blocks: bool = False
    token: str = ""             # this job's mark on temporary names


def output_dir(outdir: str | Path, recording: str | Path) -> Path:
    """Where one recording's tables go: OUTDIR/<recording file stem>/."""
    return Path(outdir) / Path(recording).stem


def align_one(task: AlignTask) -> BatchItem:
    """Runs on a worker: read, align, publish the folder and the dataset partitions."""
    from feedlog.ingest import read_recording  # keep worker start-up light

    name = storage.stem(task.label)
    with storage.local_input(task.recording) as local:
        rec = read_recording(local)
    rec.source = task.label
    alignment = align_recording(rec, task.program, profile=task.profile, config=task.config)
    where = task.recording if storage.is_url(task.recording) else str(Path(task.recording).resolve())
    with storage.publish_dir(storage.join(task.outdir, name), token=task.token) as staging:
        write_alignment(staging, alignment, overwrite=True, recording_path=where)
    for table, frame in (("blocks", alignment.blocks), ("points", dataset_points(alignment.points))):
        write_partition(task.outdir, table, PARTITION_KEY, name, frame, token=task.token,
                        metadata=table_metadata(alignment, table, recording_path=where))
    blocks = alignment.blocks[BLOCK_COLUMNS].to_dict(orient="records") if task.with_blocks else None
    return BatchItem(recording=task.label, outdir="", ok=True, cycle_time_s=alignment.cycle_time_s, blocks=blocks,
                     samples=int(alignment.report["match"]["measured_samples"]), notes=decisions(alignment.report))


def decisions(report: dict[str, Any]) -> list[str]:
    """What align chose by itself for this recording, in a few words each (for the console)."""
    out = []
    if report.get("lines") and report["lines"]["from"] == "line stream":
        out.append(f"program lines {report['lines']['first']}:{report['lines']['last']} (from the line stream)")
    if report.get("work_offset_estimate"):
        offset = report["work_offset_estimate"]["offset_mm"]
        out.append(f"work offset estimated ({', '.join(f'{v:.3f}' for v in offset)}) mm")
    if report.get("mode") == "line stream only":
        out.append("no positions: block times from the line stream")
        numbering = report.get("numbering") or {}
        if numbering.get("from") == "detected from the data":
            out.append(f"block numbers read as {numbering['numbering']}")
        line_map = report.get("line_map") or {}
        if line_map and not line_map.get("matches", True):
            first = line_map.get("first_mismatch") or {}
            offsets = ", ".join(f"{o:+d}" for o in line_map.get("offsets", []) if o)
            said = ([f"from recorded line {first['recorded_line']}"] if first.get("found_by") == "line time" else []) \
                + ([f"lines mapped {offsets}"] if offsets else []) + ["report.json: line_map"]
            out.append(f"the program is not what ran ({'; '.join(said)})")
    totals: dict[str, list[float]] = {}
    for event in report.get("events") or []:
        totals.setdefault(event["kind"], []).append(event["duration_s"])
    if totals:
        out.append("events: " + ", ".join(f"{k} {len(v)} x {sum(v):.2f} s" for k, v in totals.items()))
    rounding = report.get("unstated_tolerance")
    if rounding and rounding["dist_max_mm"] > report["config"]["tol_mm"]:
        out.append(f"the machine rounds corners the program gives no tolerance for by up to "
                   f"{rounding['dist_max_mm']:.3f} mm (measured, beyond what the sampling cuts off)")
    return out


def _shared_inputs(program: str | Path | None, profile: str | Path | None, config: AlignConfig):
    """The program and profile given for every recording, read here (errors stop the job before it starts)."""
    from feedlog.profile import MachineProfile, load_profile
    from feedlog.toolpath import load_program

    prog = prof = None
    if program is not None:
        text = str(program)
        source = storage.read_text(text) if storage.is_url(text) else Path(program)
        prog = load_program(source, lenient=config.lenient, name=text if storage.is_url(text) else None,
                            dialect=config.dialect)
    if profile is not None:
        text = str(profile)
        prof = MachineProfile.from_toml(storage.read_text(text), source=text) if storage.is_url(text) \
            else load_profile(profile)
    return prog, prof


def align_many(recordings: list[str | Path], outdir: str | Path, *, program: str | Path | None = None,
               profile: str | Path | None = None, config: AlignConfig | None = None, jobs: int | None = None,
               scheduler: str | None = None, overwrite: bool = False, progress: bool = True,
               with_blocks: bool = False, log=None) -> list[BatchItem]:
    """Align every recording into OUTDIR/<stem>/ and OUTDIR/dataset/; results in the input order.

    `jobs`/`scheduler` choose where the tasks run (`feedlog.execution`: serial, local processes, Dask).
    """
    cfg = config or AlignConfig()
    prog, prof = _shared_inputs(program, profile, cfg)
    labels, outcome = run_per_input(
        recordings, outdir,
        lambda label, root, token: AlignTask(recording=storage.absolute(label), label=label, outdir=root,
                                             program=prog, profile=prof, config=cfg, with_blocks=with_blocks,
                                             token=token),
        align_one, what="recordings", files=FILES, tables=DATASET_TABLES, key=PARTITION_KEY, overwrite=overwrite,
        desc="align", jobs=jobs, scheduler=scheduler, progress=progress, log=log)
    items: list[BatchItem] = []
    for label in labels:
        shown, result = storage.join(str(outdir), storage.stem(label)), outcome[label]
        if isinstance(result, str):
            items.append(BatchItem(recording=label, outdir=shown, ok=False, exit_code=2, exists=True,
                                   error=f"{result} exists; use --overwrite to replace it"))
        elif result.ok:
            result.value.outdir, result.value.task_s = shown, result.task_s
            items.append(result.value)
        else:
            items.append(BatchItem(recording=label, outdir=shown, ok=False, error=result.error,
                                   exit_code=result.exit_code))
    return items

