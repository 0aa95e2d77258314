"""One table over many inputs: a hive-partitioned Parquet dataset, one partition per recording (or program).

    OUTDIR/dataset/<table>/<key>=<value>/part-0.parquet      e.g. aligned/dataset/blocks/recording=mix_001/

Each task writes its own partition (under a temporary name, then renamed: `feedlog.storage`), so a
cluster job needs no gathering step and a later job can add partitions. The partition key is not a
column inside the files; readers add it from the folder name:

    pandas.read_parquet("aligned/dataset/blocks")                       # pyarrow's hive partitioning
    dask.dataframe.read_parquet("aligned/dataset/points")
    duckdb.sql("SELECT * FROM read_parquet('aligned/dataset/blocks/*/*.parquet', hive_partitioning=true)")

Every partition of a table must have the same columns and types (readers take the schema of one
file): writers conform their frames first (e.g. `feedlog.align.tables.dataset_points`).
"""

from __future__ import annotations

import uuid
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any
from urllib.parse import quote

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from feedlog.errors import FeedlogError
from feedlog.storage import exists, join, publish_file

DATASET = "dataset"
PART = "part-0.parquet"


def partition_dir(outdir: str, table: str, key: str, value: str) -> str:
    """OUTDIR/dataset/<table>/<key>=<value> (the value URI-encoded, as pyarrow's hive partitioning reads it)."""
    return join(outdir, DATASET, table, f"{key}={quote(str(value), safe='')}")


def write_partition(outdir: str, table: str, key: str, value: str, frame: pd.DataFrame, *,
                    metadata: dict[bytes, bytes] | None = None, token: str = "") -> str:
    """Write `frame` as the partition `key=value` of `table` (replacing it); returns the file's location."""
    if key in frame.columns:
        frame = frame.drop(columns=[key])  # the folder name carries it
    arrow = pa.Table.from_pandas(frame, preserve_index=False)
    if metadata:
        arrow = arrow.replace_schema_metadata({**(arrow.schema.metadata or {}), **metadata})
    target = join(partition_dir(outdir, table, key, value), PART)

    def write(path: Path) -> None:
        pq.write_table(arrow, path, compression="zstd")

    publish_file(target, write, token=token)
    return target


def partition_exists(outdir: str, table: str, key: str, value: str) -> bool:
    return exists(join(partition_dir(outdir, table, key, value), PART))


def existing_output(outdir: str, name: str, *, files: tuple[str, ...], tables: tuple[str, ...],
                    key: str) -> str | None:
    """The first of OUTDIR/<name>/<files> or <name>'s dataset partitions that exists (a job refuses to
    replace it unless asked), or None."""
    for file in files:
        if exists(join(outdir, name, file)):
            return join(outdir, name, file)
    for table in tables:
        if partition_exists(outdir, table, key, name):
            return f"{join(outdir, DATASET, table)} partition {key}={name}"
    return None


def read_dataset(outdir: str | Path, table: str, **kw: Any) -> pd.DataFrame:
    """The whole table (all partitions, the key as a column) with pandas."""
    return pd.read_parquet(join(str(outdir), DATASET, table), **kw)


def run_per_input(inputs: Sequence[str | Path], outdir: str | Path, make_task: Callable[[str, str, str], Any],
                  fn: Callable[[Any], Any], *, what: str, files: tuple[str, ...], tables: tuple[str, ...], key: str,
                  overwrite: bool, desc: str, jobs: int | None, scheduler: str | None, progress: bool,
                  log=None) -> tuple[list[str], dict[str, Any]]:
    """One task per input, each writing OUTDIR/<stem>/ and its dataset partitions. Inputs whose file
    names collide are refused at once; an input whose outputs exist is not run unless `overwrite`.
    `make_task(label, root, token)` builds an input's task; `fn` runs one (`execution.run_tasks`).
    Returns the labels in input order and per label the existing output's name (a str: not run) or the
    task's `execution.TaskResult`. The job's partial files are removed whatever happens."""
    from feedlog import storage
    from feedlog.execution import run_tasks

    labels = [str(p) for p in inputs]
    stems = [storage.stem(p) for p in labels]
    dup = sorted({s for s in stems if stems.count(s) > 1})
    if dup:
        raise FeedlogError(f"{what} share the file name {dup[0]!r}: their outputs would collide in {outdir}")
    root = storage.absolute(str(outdir))
    storage.writable_dir(root)  # a file there, a read-only or full disk: one error before any task runs
    token = uuid.uuid4().hex[:8]
    outcome: dict[str, Any] = {}
    tasks, run = [], []
    for label, name in zip(labels, stems):
        there = None if overwrite else existing_output(root, name, files=files, tables=tables, key=key)
        if there is not None:
            outcome[label] = there
            continue
        tasks.append(make_task(label, root, token))
        run.append(label)
    try:
        results = run_tasks(fn, tasks, jobs=jobs, scheduler=scheduler, desc=desc, label=lambda t: t.label,
                            progress=progress, log=log)
    finally:
        storage.remove_partials(root, token)
    outcome.update(zip(run, results))
    return labels, outcome
