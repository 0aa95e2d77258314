"""align's on-disk output: `points.parquet`, `blocks.parquet` and `report.json` in one folder per recording.

Both Parquet files carry key `feedlog.align` in their schema metadata: a JSON object with
`format_version`, `table`, `cycle_time_s`, `recording` (as given), `recording_path` (absolute, when it is a file) and `program`. Readers refuse a newer
format_version. Columns (units in names):
- points: point, block, line, kind, x_mm ... c_deg, ori_*, programmed_feed_mm_min, s_mm (program),
  t_ns (matched time), t_rel_s (since motion start), dist_mm, sample (nearest measured sample),
  feed_meas_mm_min, v<axis>_meas_mm_min / _deg_min, then toolpath's per-block features of the block
  the point ends (FEATURE_COLUMNS without line/kind/feed_mm_min).
- blocks: block, line, t_start_ns, t_end_ns, duration_s, seen, source ("line" or "geometry"), then
  toolpath's FEATURE_COLUMNS (kind, length_mm, ..., feed_mm_min = programmed feed).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from feedlog.align.pipeline import Alignment
from feedlog.atomic import atomic_outputs
from feedlog.errors import AlignmentError, FeedlogError, OutputError

FORMAT_VERSION = 1
META_KEY = b"feedlog.align"
FILES = ("points.parquet", "blocks.parquet", "report.json")


def _json_default(value: Any) -> Any:
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return None if not np.isfinite(value) else float(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    return str(value)


def to_json(data: Any, **kw: Any) -> str:
    return json.dumps(data, default=_json_default, **kw)


def _write(path: Path, table: pd.DataFrame, meta: dict[str, Any]) -> None:
    arrow = pa.Table.from_pandas(table, preserve_index=False)
    schema_meta = dict(arrow.schema.metadata or {})
    schema_meta[META_KEY] = to_json(meta).encode()
    pq.write_table(arrow.replace_schema_metadata(schema_meta), path, compression="zstd")


def write_alignment(outdir: str | Path, alignment: Alignment, *, overwrite: bool = False,
                    recording_path: str | None = None) -> list[Path]:
    """Write the three files into `outdir` (created); refuses to replace existing files unless `overwrite`.

    `recording_path` (absolute path or URL) is stored when the recording named in the report is not
    a file here (a worker that read it elsewhere, or a download of a URL)."""
    out = Path(outdir)
    paths = [out / name for name in FILES]
    existing = [p for p in paths if p.exists()]
    if existing and not overwrite:
        raise FeedlogError(f"{existing[0]} exists; use --overwrite to replace it")
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create the output folder: {exc.strerror or exc}", file=str(out)) from None
    base = _base_meta(alignment, recording_path)
    try:
        with atomic_outputs(*paths) as temporaries:  # all three files or none
            _write(temporaries[0], alignment.points, {**base, "table": "points"})
            _write(temporaries[1], alignment.blocks, {**base, "table": "blocks"})
            temporaries[2].write_text(to_json(alignment.report, indent=2) + "\n")
    except OutputError:
        if created:
            out.rmdir()
        raise
    return paths


def _base_meta(alignment: Alignment, recording_path: str | None) -> dict[str, Any]:
    rec = alignment.report.get("recording")
    base = {"format_version": FORMAT_VERSION, "cycle_time_s": alignment.cycle_time_s,
            "recording": rec, "program": alignment.report.get("program")}
    if recording_path is not None:
        base["recording_path"] = recording_path
    elif rec and Path(rec).is_file():  # as given, and absolute: readers elsewhere still find its manifest
        base["recording_path"] = str(Path(rec).resolve())
    return base


def table_metadata(alignment: Alignment, table: str, *, recording_path: str | None = None) -> dict[bytes, bytes]:
    """The `feedlog.align` schema metadata of one table, for files written elsewhere (the dataset)."""
    return {META_KEY: to_json({**_base_meta(alignment, recording_path), "table": table}).encode()}


def dataset_points(points: pd.DataFrame) -> pd.DataFrame:
    """The points table with every axis's measured feed column (NaN where the machine has no such axis), so
    that three- and five-axis recordings are partitions of one dataset with one schema."""
    from feedlog.toolpath.schema import AXES, AXIS_UNITS

    measured = [f"v{a}_meas_{AXIS_UNITS[a]}_min" for a in AXES]
    out = points.assign(**{c: np.nan for c in measured if c not in points.columns})
    cols = [c for c in out.columns if c not in measured]
    cut = cols.index("feed_meas_mm_min") + 1 if "feed_meas_mm_min" in cols else len(cols)
    return out[cols[:cut] + measured + cols[cut:]]


def read_table(path: str | Path) -> tuple[pd.DataFrame, dict[str, Any]]:
    """One of align's Parquet tables and its feedlog metadata."""
    p = Path(path)
    try:
        arrow = pq.read_table(p)
    except (OSError, pa.ArrowException) as exc:
        raise AlignmentError(f"{p}: not a readable Parquet file ({exc})") from None
    raw = (arrow.schema.metadata or {}).get(META_KEY)
    if raw is None:
        raise AlignmentError(f"{p}: not written by feedlog align (no {META_KEY.decode()} metadata)")
    meta = json.loads(raw)
    version = int(meta.get("format_version", 0))
    if version > FORMAT_VERSION:
        raise AlignmentError(f"{p}: align format_version {version} is newer than this feedlog reads "
                             f"({FORMAT_VERSION}); upgrade feedlog")
    return arrow.to_pandas(), meta
