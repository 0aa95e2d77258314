"""halsampler captures -> feedlog Recording: join the samplers on the servo clock, check, name, convert.

Each capture file holds `halsampler -t` lines: the sample tag, the shared HAL clock (seconds of servo
time) and that sampler's columns (linuxcnc_hal.SamplerLayout). Rows are joined on the tag; `t_ns`
is the servo clock rounded to whole servo periods (integer ns). Gaps in the tag or the clock are
missing servo periods: counted as `dropped_frames`, never filled in.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from feedlog.errors import IngestError
from feedlog.ingest.linuxcnc_hal import ROTARY_LETTERS, SamplerLayout
from feedlog.units import length_factor

MM_MIN_PER_UNIT_S = 60.0


@dataclass(frozen=True)
class MotionSpan:
    """First and last servo sample in which any axis position changed, and the time between."""

    first: int
    last: int
    cycle_time_ns: int

    @property
    def cycle_time_s(self) -> float:
        return self.cycle_time_ns / 1e9


def read_capture(path: Path, names: list[str]) -> pd.DataFrame:
    """One halsampler -t file as a table with the given column names (sample tag first)."""
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise IngestError(f"cannot read sampler capture: {exc.strerror}", file=str(path)) from None
    if text and not text.endswith("\n"):
        text = text[:text.rfind("\n") + 1]  # halsampler stopped mid-line: that last sample is incomplete
    if not text.strip():
        return pd.DataFrame({n: pd.Series(dtype="float64") for n in names})
    try:
        table = pd.read_csv(io.StringIO(text), sep=r"\s+", header=None, engine="c")
    except (ValueError, pd.errors.ParserError) as exc:
        raise IngestError(f"malformed sampler capture: {exc}", file=str(path)) from None
    if table.shape[1] != len(names):
        raise IngestError(f"sampler capture has {table.shape[1]} fields per line, expected {len(names)} "
                          f"({', '.join(names)})", file=str(path), line=1)
    table.columns = names
    bad = table.isna().any(axis=1).to_numpy()
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise IngestError("truncated line in sampler capture", file=str(path), line=row + 1)
    return table


def join_captures(tables: list[pd.DataFrame], *, source: str = "", period_ns: int | None = None) -> pd.DataFrame:
    """Join per-sampler tables row by row: on the shared servo clock when there is one, else on the tag.

    The gate opens from user space, so it can open between two samplers' functions in one servo
    period: one sampler then holds a leading sample the others lack, and their tags differ by one
    from there on. The shared clock names the servo period itself, so joining on it drops that
    lone sample instead of pairing rows one period apart. Within the joined rows every sampler's
    tag must keep the same offset from sampler 0's: a sampler that lost a sample mid-run (or a
    clock that disagrees) is out of step and refused.
    """
    clocked = period_ns is not None and "clock_s" in tables[0]
    key = "tick" if clocked else "sample"
    if clocked:
        tables = [t.assign(tick=servo_t_ns(t["clock_s"].to_numpy(), period_ns)) for t in tables]
    joined = tables[0]
    for k, table in enumerate(tables[1:], start=1):
        joined = joined.merge(table, on=key, how="inner", suffixes=("", f"_{k}"))
        if "clock_s" not in joined:
            continue
        clash = np.flatnonzero(np.abs(joined["clock_s"] - joined[f"clock_s_{k}"]) > 1e-6)
        if clocked:
            offset = joined[f"sample_{k}"].to_numpy() - joined["sample"].to_numpy()
            clash = np.flatnonzero(offset != offset[0]) if len(offset) else clash
            if not len(joined) and len(table) and len(tables[0]):
                raise IngestError(f"sampler {k} is out of step with sampler 0: their clocks never "
                                  "meet", file=source or None)
        if len(clash):
            raise IngestError(f"sampler {k} is out of step with sampler 0 at sample "
                              f"{int(joined['sample'].iloc[clash[0]])}", file=source or None)
        joined = joined.drop(columns=[c for c in (f"clock_s_{k}", f"sample_{k}") if c in joined])
    return joined.drop(columns=["tick"], errors="ignore").reset_index(drop=True)


def servo_t_ns(clock_s: np.ndarray, period_ns: int) -> np.ndarray:
    """Servo clock in seconds -> integer ns on the servo grid."""
    ticks = np.rint(np.asarray(clock_s, dtype=np.float64) * 1e9 / period_ns).astype(np.int64)
    return ticks * np.int64(period_ns)


def missing_periods(t_ns: np.ndarray, period_ns: int) -> int:
    """Servo periods absent between the first and last sample."""
    if len(t_ns) < 2:
        return 0
    steps = np.diff(t_ns) // period_ns
    return int(np.sum(steps - 1, where=steps > 1, initial=0))


def motion_span(axes: pd.DataFrame, period_ns: int) -> MotionSpan | None:
    """First motion to end of motion: samples whose axis positions differ from the previous sample.

    The cycle time counts whole servo periods: (last - first + 1) * period. None when nothing moved.
    """
    pos = axes.drop(columns=["t_ns"]).to_numpy(dtype=np.float64)
    if len(pos) < 2:
        return None
    moved = np.flatnonzero(np.any(np.diff(pos, axis=0) != 0.0, axis=1)) + 1
    if not len(moved):
        return None
    first, last = int(moved[0]), int(moved[-1])
    t = axes["t_ns"].to_numpy()
    return MotionSpan(first=first, last=last, cycle_time_ns=int(t[last] - t[first]) + period_ns)


def capture_streams(joined: pd.DataFrame, layout: SamplerLayout, *, period_ns: int,
                    linear_units: str = "mm") -> dict[str, pd.DataFrame]:
    """The standard feedlog streams (axes, joints, feed, line, status) from the joined capture."""
    if len(joined) and joined["sample"].duplicated().any():
        raise IngestError("sampler capture repeats a sample tag")
    scale = length_factor("inch" if linear_units.lower().startswith("in") else "mm")
    if layout.clock:
        t_ns = servo_t_ns(joined["clock_s"].to_numpy(), period_ns)
    else:  # no clock column: the sample tag counts servo periods
        t_ns = joined["sample"].to_numpy().astype(np.int64) * np.int64(period_ns)
    axis_cols = [c.name for group in layout.groups for c in group if c.pin.startswith("axis.")]
    axes = {"t_ns": t_ns}
    for name in axis_cols:
        values = joined[name].to_numpy(dtype=np.float64)
        axes[name] = values if name[0] in ROTARY_LETTERS else values * scale
    joint_cols = [c.name for group in layout.groups for c in group if c.pin.startswith("joint.")]
    joints = {"t_ns": t_ns} | {n: joined[n].to_numpy(dtype=np.float64) for n in joint_cols}
    feed = {
        "t_ns": t_ns,
        "feed_mm_min": joined["current_vel"].to_numpy(dtype=np.float64) * scale * MM_MIN_PER_UNIT_S,
        "requested_feed_mm_min": joined["requested_vel"].to_numpy(dtype=np.float64) * scale * MM_MIN_PER_UNIT_S,
        "programmed_feed_mm_min": joined["feed_upm"].to_numpy(dtype=np.float64) * scale,
        "distance_to_go_mm": joined["distance_to_go"].to_numpy(dtype=np.float64) * scale,
    }
    line = {"t_ns": t_ns, "line": joined["line"].to_numpy().astype(np.int64)}
    status = {
        "t_ns": t_ns,
        "in_position": joined["in_position"].to_numpy().astype(bool),
        "motion_type": joined["motion_type"].to_numpy().astype(np.int8),
        "servo_last_period_ticks": joined["last_period"].to_numpy().astype(np.int64),
    }
    return {name: pd.DataFrame(cols) for name, cols in
            (("axes", axes), ("joints", joints), ("feed", feed), ("line", line), ("status", status))}


def has_samples(files: list[Path]) -> bool:
    """Whether any capture file holds data (a session that failed before sampling leaves none)."""
    return any(Path(f).is_file() and Path(f).stat().st_size > 0 for f in files)


def load_capture(files: list[Path], layout: SamplerLayout, *, period_ns: int, linear_units: str = "mm",
                 source: str = "") -> tuple[dict[str, pd.DataFrame], int]:
    """Streams and the number of missing servo periods from a set of capture files."""
    if len(files) != len(layout.groups):
        raise ValueError(f"{len(files)} capture files for {len(layout.groups)} samplers")
    tables = [read_capture(f, layout.column_names(k)) for k, f in enumerate(files)]
    # joined on the clock, a sampler's lone samples at the gate's edges are outside the session and a
    # sample lost mid-run is refused as out of step; joined on tags, a shorter sampler lost rows
    lost_rows = 0 if layout.clock else max(len(t) for t in tables) - min(len(t) for t in tables)
    joined = join_captures(tables, source=source, period_ns=period_ns)
    streams = capture_streams(joined, layout, period_ns=period_ns, linear_units=linear_units)
    missing = missing_periods(streams["axes"]["t_ns"].to_numpy(), period_ns) + lost_rows
    return streams, missing
