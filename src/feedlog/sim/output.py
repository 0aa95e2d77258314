"""A windowed simulation written to Parquet window by window: memory bounded by the window, not the program.

    result = write_windowed(WindowedSimulation("part.ngc", "linuxcnc-xyz", series=True),
                            series="series.parquet", blocks="blocks.parquet")

Each output is written to a temporary name beside it and renamed when the run has ended (both files
or neither: `feedlog.atomic`). The files read back as the tables `simulate` gives for the whole
program (`SimResult.series`, `SimResult.blocks`): same columns, same dtypes, same rows.

`in_memory_bytes` estimates what simulating a program at once would hold, so that the CLI can refuse a
run that would not fit instead of being killed by the kernel.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import pandas as pd

from feedlog.atomic import atomic_outputs
from feedlog.parquet_sink import ParquetSink
from feedlog.sim.window import WindowedResult, WindowedSimulation

BYTES_PER_BLOCK = 2600     # program table (~1.0 kB) + simulation (~1.5 kB) per block, measured (issue #22)
BYTES_PER_SAMPLE_VALUE = 16  # a float64 series column, and the copy pandas makes building the frame


def write_windowed(run: WindowedSimulation, *, series: str | os.PathLike | None = None,
                   blocks: str | os.PathLike | None = None,
                   progress: Callable[[WindowedSimulation], None] | None = None) -> WindowedResult:
    """Run `run` (built with `series=True` when `series` is given) and write its windows to the
    Parquet files `series` and `blocks`. `progress(run)` is called after each window."""
    targets = {name: Path(p) for name, p in (("series", series), ("blocks", blocks)) if p is not None}
    if "series" in targets and not run.series:
        raise ValueError("a series output needs WindowedSimulation(series=True)")
    with atomic_outputs(*targets.values()) as temporaries:
        sinks = {name: ParquetSink(t) for name, t in zip(targets, temporaries)}
        last = None
        try:
            for window in run:
                if "blocks" in sinks:
                    sinks["blocks"].write(window.blocks)
                if "series" in sinks and window.series is not None:
                    sinks["series"].write(window.series)
                last = window
                if progress is not None:
                    progress(run)
        finally:
            for name, sink in sinks.items():
                sink.close(_empty(last, name))
    return run.result


def _empty(window, name: str) -> pd.DataFrame | None:
    """The table's columns without rows (written when no window had rows)."""
    frame = getattr(window, name, None) if window is not None else None
    return None if frame is None else frame.iloc[:0]


def in_memory_bytes(*, rows: int, series_s: float | None, dt_s: float, axes: int) -> int:
    """About what `simulate` holds for `rows` program rows, and with `series_s` seconds of samples at
    `dt_s` the series too (axes + t_ns, feed, block, line columns)."""
    need = rows * BYTES_PER_BLOCK
    if series_s is not None:
        need += int(series_s / dt_s) * (axes + 4) * BYTES_PER_SAMPLE_VALUE
    return need


def available_bytes() -> int:
    """Memory the system can give without swapping (psutil's `available`)."""
    import psutil

    return int(psutil.virtual_memory().available)
