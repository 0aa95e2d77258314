"""How a stream was sampled: nominal period, jitter and gaps, measured from its own timestamps.

Alignment never invents timestamps (`index / rate`): it works on the recorded `t_ns`. This module
says how regular those timestamps are so that gaps and jitter are reported, never papered over.
A gap is an interval longer than `gap_factor` nominal periods; jitter is the spread of the
intervals that are not gaps.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from feedlog.errors import AlignmentError

MEDIAN_SAMPLES = 100_000


@dataclass(frozen=True)
class StreamTiming:
    """Sampling summary of one stream (all times in ns unless named otherwise)."""

    samples: int
    period_ns: int            # median interval: the nominal sampling period
    jitter_ns: float          # standard deviation of the non-gap intervals
    max_jitter_ns: int        # largest |interval - period| among non-gap intervals
    gaps: int                 # intervals longer than gap_factor * period
    gap_total_ns: int         # time lost in gaps beyond one nominal period each
    largest_gap_ns: int
    first_gap_index: int      # sample index before the first gap, -1 when none
    duplicates: int           # zero-length intervals (repeated timestamps)

    @property
    def rate_hz(self) -> float:
        return 1e9 / self.period_ns if self.period_ns > 0 else float("nan")

    def as_dict(self) -> dict:
        d = asdict(self)
        d["rate_hz"] = self.rate_hz
        return d


def stream_timing(t_ns: np.ndarray, *, gap_factor: float = 3.0, name: str = "stream") -> StreamTiming:
    """Measure the sampling of a stream from its int64 nanosecond timestamps."""
    t = np.asarray(t_ns, dtype=np.int64)
    if len(t) < 2:
        raise AlignmentError(f"{name}: needs at least 2 samples to measure its timing, got {len(t)}")
    dt = np.diff(t)
    # the nominal period: median of the positive intervals (of an evenly strided subset of at most
    # MEDIAN_SAMPLES intervals on long streams: a period does not need a million of them)
    step = max(1, len(dt) // MEDIAN_SAMPLES)
    some = dt[::step]
    positive = some[some > 0]
    if len(positive) == 0:
        positive = dt[dt > 0]
        if len(positive) == 0:
            raise AlignmentError(f"{name}: all {len(t)} samples carry the same timestamp")
    period = int(np.median(positive))
    lo, hi = int(dt.min()), int(dt.max())
    if lo > 0 and hi <= gap_factor * period:  # the usual case: no gaps, no duplicates; no masks needed
        return StreamTiming(samples=len(t), period_ns=period, jitter_ns=float(np.std(dt)),
                            max_jitter_ns=max(hi - period, period - lo), gaps=0, gap_total_ns=0,
                            largest_gap_ns=0, first_gap_index=-1, duplicates=0)
    gap_mask = dt > gap_factor * period
    regular = dt[(dt > 0) & ~gap_mask]
    dev = regular - period
    gap_idx = np.flatnonzero(gap_mask)
    return StreamTiming(
        samples=len(t),
        period_ns=period,
        jitter_ns=float(np.std(regular)) if len(regular) else 0.0,
        max_jitter_ns=int(np.max(np.abs(dev))) if len(dev) else 0,
        gaps=int(len(gap_idx)),
        gap_total_ns=int(np.sum(dt[gap_mask] - period)),
        largest_gap_ns=hi if len(gap_idx) else 0,
        first_gap_index=int(gap_idx[0]) if len(gap_idx) else -1,
        duplicates=int(np.sum(dt == 0)),
    )


def gap_intervals(t_ns: np.ndarray, *, period_ns: int, gap_factor: float = 3.0) -> np.ndarray:
    """(k, 2) int64 array of [start, end) times of the gaps of a stream."""
    t = np.asarray(t_ns, dtype=np.int64)
    dt = np.diff(t)
    idx = np.flatnonzero(dt > gap_factor * period_ns)
    return np.column_stack([t[idx], t[idx + 1]]) if len(idx) else np.empty((0, 2), dtype=np.int64)
