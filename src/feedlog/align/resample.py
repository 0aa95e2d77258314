"""Resampling a stream onto other timestamps: continuous columns interpolate, discrete ones hold.

Rules (named, so that callers know what they get):
- **Continuous** columns (floating point: positions, feeds) are linearly interpolated in time. When the
  target is coarser than the source (target period > 1.5 x source period) they are first low-pass
  filtered with a zero-phase 4th-order Butterworth (`scipy.signal.sosfiltfilt`) whose cutoff is
  `cutoff_ratio` x the target Nyquist frequency, so that what is faster than the new rate does not
  alias into it. The filter runs separately on every gap-free run of samples.
- **Discrete** columns (integers, booleans, categories: program line, mode, tool) hold the last value
  at or before each target time (zero-order hold); they are never interpolated or filtered.
- **Gaps** (source intervals longer than `gap_factor` nominal periods) are never bridged: continuous
  values at target times inside a gap, or outside the source's time range, are NaN; discrete values
  there hold the neighbouring value and are counted in the result so that the caller can refuse them.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from feedlog.align.timing import StreamTiming, gap_intervals, stream_timing
from feedlog.errors import AlignmentError

BUTTER_ORDER = 4


@dataclass
class Resampled:
    """A resampled stream and what resampling had to say about it."""

    table: pd.DataFrame        # t_ns + the resampled columns
    timing: StreamTiming       # the source's sampling
    filtered: bool             # anti-alias filter applied
    in_gap: int                # target samples inside a source gap
    outside: int               # target samples outside the source's time range

    @property
    def report(self) -> dict:
        return {"source": self.timing.as_dict(), "anti_alias": self.filtered,
                "target_samples": len(self.table), "in_gap": self.in_gap, "outside": self.outside}


def is_discrete(series: pd.Series) -> bool:
    """Integers, booleans, categories and strings hold; floating point interpolates."""
    return not pd.api.types.is_float_dtype(series.dtype)


def uniform_timebase(t_start_ns: int, t_end_ns: int, period_ns: int) -> np.ndarray:
    """Uniform int64 timestamps from t_start_ns up to and including t_end_ns (when it falls on the grid)."""
    if period_ns <= 0:
        raise AlignmentError(f"resampling period must be > 0 ns, got {period_ns}")
    if t_end_ns < t_start_ns:
        raise AlignmentError(f"empty time range [{t_start_ns}, {t_end_ns}] ns")
    n = (t_end_ns - t_start_ns) // period_ns + 1
    return t_start_ns + np.arange(n, dtype=np.int64) * period_ns


def common_timebase(streams: Sequence[pd.DataFrame], *, period_ns: int | None = None) -> np.ndarray:
    """A uniform timebase over the time range all streams share, at `period_ns` (default: the finest
    median period among the streams)."""
    if not streams:
        raise AlignmentError("common_timebase needs at least one stream")
    starts = [int(s["t_ns"].iloc[0]) for s in streams if len(s)]
    ends = [int(s["t_ns"].iloc[-1]) for s in streams if len(s)]
    if len(starts) != len(streams):
        raise AlignmentError("common_timebase: a stream is empty")
    t0, t1 = max(starts), min(ends)
    if t1 < t0:
        raise AlignmentError(f"streams do not overlap in time (latest start {t0} ns > earliest end {t1} ns)")
    if period_ns is None:
        period_ns = min(stream_timing(s["t_ns"].to_numpy()).period_ns for s in streams)
    return uniform_timebase(t0, t1, int(period_ns))


def lowpass(t_ns: np.ndarray, values: np.ndarray, *, cutoff_hz: float, period_ns: int,
            gap_factor: float = 3.0) -> np.ndarray:
    """Zero-phase Butterworth low-pass of `values` (n, ...) along axis 0, run per gap-free segment.
    Segments too short for the filter's padding are left as they are."""
    fs = 1e9 / period_ns
    wn = cutoff_hz / (fs / 2)
    out = np.array(values, dtype=np.float64, copy=True)
    if not 0 < wn < 1:
        return out
    from scipy import signal  # scipy.signal costs ~0.7 s to import; most alignments never filter
    sos = signal.butter(BUTTER_ORDER, wn, output="sos")
    pad = 3 * (2 * len(sos) + 1)
    cuts = np.flatnonzero(np.diff(t_ns) > gap_factor * period_ns) + 1
    bounds = np.concatenate([[0], cuts, [len(t_ns)]])
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        if hi - lo > pad:
            seg = out[lo:hi]
            finite = np.isfinite(seg).all(axis=tuple(range(1, seg.ndim))) if seg.ndim > 1 else np.isfinite(seg)
            if finite.all():
                out[lo:hi] = signal.sosfiltfilt(sos, seg, axis=0)
    return out


def resample(stream: pd.DataFrame, t_ns: np.ndarray, *, columns: Iterable[str] | None = None,
             discrete: Iterable[str] | None = None, anti_alias: bool = True, cutoff_ratio: float = 0.8,
             gap_factor: float = 3.0, name: str = "stream") -> Resampled:
    """Resample `stream` (t_ns + columns) at the int64 timestamps `t_ns`.

    `discrete` overrides which columns hold (default: every non-float column); `columns` picks a subset.
    """
    if "t_ns" not in stream.columns:
        raise AlignmentError(f"{name}: stream has no t_ns column")
    if not 0 < cutoff_ratio <= 1:
        raise AlignmentError(f"cutoff_ratio must be in (0, 1], got {cutoff_ratio}")
    src_t = stream["t_ns"].to_numpy(dtype=np.int64)
    target = np.asarray(t_ns, dtype=np.int64)
    timing = stream_timing(src_t, gap_factor=gap_factor, name=name)
    cols = [c for c in (columns if columns is not None else stream.columns) if c != "t_ns"]
    missing = [c for c in cols if c not in stream.columns]
    if missing:
        raise AlignmentError(f"{name}: no column(s) {', '.join(missing)}; it has {', '.join(stream.columns)}")
    held = set(discrete) if discrete is not None else {c for c in cols if is_discrete(stream[c])}
    smooth = [c for c in cols if c not in held]

    target_period = int(np.median(np.diff(target))) if len(target) > 1 else timing.period_ns
    filtered = bool(anti_alias and smooth and target_period > 1.5 * timing.period_ns)
    out: dict[str, np.ndarray] = {"t_ns": target}

    # relative float times keep ns precision over long recordings
    rel_src = (src_t - src_t[0]).astype(np.float64)
    rel_tgt = (target - src_t[0]).astype(np.float64)
    outside = (target < src_t[0]) | (target > src_t[-1])
    gaps = gap_intervals(src_t, period_ns=timing.period_ns, gap_factor=gap_factor)
    in_gap = np.zeros(len(target), dtype=bool)
    if len(gaps):
        k = np.searchsorted(gaps[:, 0], target, side="right") - 1
        ok = k >= 0
        in_gap[ok] = (target[ok] > gaps[k[ok], 0]) & (target[ok] < gaps[k[ok], 1])

    if smooth:
        values = stream[smooth].to_numpy(dtype=np.float64)
        if filtered:
            cutoff = cutoff_ratio * (1e9 / target_period) / 2
            values = lowpass(src_t, values, cutoff_hz=cutoff, period_ns=timing.period_ns, gap_factor=gap_factor)
        bad = outside | in_gap
        for j, c in enumerate(smooth):
            v = np.interp(rel_tgt, rel_src, values[:, j])
            v[bad] = np.nan
            out[c] = v
    if held:
        idx = np.clip(np.searchsorted(src_t, target, side="right") - 1, 0, len(src_t) - 1)
        for c in cols:
            if c in held:
                out[c] = stream[c].to_numpy()[idx]
    table = pd.DataFrame({k: out[k] for k in ["t_ns", *cols]})
    return Resampled(table=table, timing=timing, filtered=filtered, in_gap=int(in_gap.sum()),
                     outside=int(outside.sum()))
