"""Aligning many recordings: one worker process per core, a progress bar, one output folder each.

Each recording is read, aligned and written by a worker (`concurrent.futures.ProcessPoolExecutor`),
so only small summaries travel back. A recording that fails with one of our errors is reported with
its message and does not stop the others; a bug (any other exception) propagates.
"""

from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tqdm import tqdm

from feedlog.align.pipeline import AlignConfig, align_recording
from feedlog.align.tables import write_alignment
from feedlog.errors import FeedlogError


@dataclass
class BatchItem:
    recording: str
    outdir: str
    ok: bool
    cycle_time_s: float | None = None
    blocks: list[dict[str, Any]] | None = None
    error: str | None = None
    samples: int = 0
    exit_code: int = 0  # of the error: 2 bad input, 1 an output that could not be written


def output_dir(outdir: str | Path, recording: str | Path) -> Path:
    """Where one recording's tables go: OUTDIR/<recording file stem>/."""
    return Path(outdir) / Path(recording).stem


def align_one(recording: str, program: str | None, profile: str | None, outdir: str, config: AlignConfig,
              overwrite: bool, with_blocks: bool) -> BatchItem:
    from feedlog.ingest import read_recording  # noqa: PLC0415 - keep worker start-up light

    target = output_dir(outdir, recording)
    try:
        rec = read_recording(recording)
        alignment = align_recording(rec, program, profile=profile, config=config)
        write_alignment(target, alignment, overwrite=overwrite)
    except FeedlogError as exc:
        return BatchItem(recording=recording, outdir=str(target), ok=False, error=str(exc), exit_code=exc.exit_code)
    blocks = None
    if with_blocks:
        cols = ["block", "line", "t_start_ns", "t_end_ns", "duration_s"]
        blocks = alignment.blocks[cols].to_dict(orient="records")
    return BatchItem(recording=recording, outdir=str(target), ok=True, cycle_time_s=alignment.cycle_time_s,
                     blocks=blocks, samples=int(alignment.report["match"]["measured_samples"]))


def align_many(recordings: list[str | Path], outdir: str | Path, *, program: str | Path | None = None,
               profile: str | Path | None = None, config: AlignConfig | None = None, jobs: int | None = None,
               overwrite: bool = False, progress: bool = True, with_blocks: bool = False) -> list[BatchItem]:
    """Align every recording into OUTDIR/<stem>/; results in the input order."""
    cfg = config or AlignConfig()
    names = [str(r) for r in recordings]
    stems = [Path(r).stem for r in names]
    dup = sorted({s for s in stems if stems.count(s) > 1})
    if dup:
        raise FeedlogError(f"recordings share the file name {dup[0]!r}: their outputs would collide in {outdir}")
    args = (None if program is None else str(program), None if profile is None else str(profile), str(outdir),
            cfg, overwrite, with_blocks)
    jobs = max(1, min(jobs or os.cpu_count() or 1, len(names)))
    results: dict[str, BatchItem] = {}
    bar = tqdm(total=len(names), desc="align", unit="rec", disable=None if progress else True)  # None: off when not a terminal
    try:
        if jobs == 1:
            for name in names:
                results[name] = align_one(name, *args)
                bar.update()
        else:
            with ProcessPoolExecutor(max_workers=jobs) as pool:
                futures = {pool.submit(align_one, name, *args): name for name in names}
                for fut in as_completed(futures):
                    results[futures[fut]] = fut.result()
                    bar.update()
    finally:
        bar.close()
    return [results[n] for n in names]
