"""Clock offsets between streams recorded by different devices.

Convention: `offset_ns` is how far the *other* stream's clock runs ahead of the reference clock: an
event at reference time t carries the timestamp t + offset_ns in the other stream. Removing it means
`other_t_ns - offset_ns` (`shift_stream(other, -offset_ns)`).

Two estimators:
- `estimate_offset`: cross-correlation of one continuous signal both streams see (e.g. path speed from a
  CAN position stream and the controller's feed export). Both signals are resampled onto one uniform grid
  at the finer of the two periods (anti-aliased), normalised, correlated by FFT, and the peak is refined to
  sub-sample precision by a parabola through its three highest points. Confidence is the Pearson
  correlation of the two signals at the estimated lag over their overlap (1 = identical shape).
- `event_offset`: matched events seen by both streams (e.g. block changes from a line-number export and
  from geometry): the offset is the median time difference, its spread the median absolute deviation.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd

from feedlog.align.resample import resample, uniform_timebase
from feedlog.align.timing import stream_timing
from feedlog.errors import AlignmentError


@dataclass(frozen=True)
class ClockOffset:
    offset_ns: int          # other clock minus reference clock
    confidence: float       # 0..1 (Pearson r at the lag for xcorr; share of consistent events for events)
    resolution_ns: int      # grid period (xcorr) or spread (events) of the estimate
    method: str
    samples: int            # grid samples or matched events used

    def as_dict(self) -> dict:
        return asdict(self)


def _on_grid(t_ns: np.ndarray, values: np.ndarray, grid: np.ndarray, name: str) -> np.ndarray:
    table = pd.DataFrame({"t_ns": np.asarray(t_ns, dtype=np.int64), "v": np.asarray(values, dtype=np.float64)})
    v = resample(table, grid, name=name).table["v"].to_numpy()
    finite = np.isfinite(v)
    if finite.sum() < 3:
        raise AlignmentError(f"{name}: fewer than 3 samples overlap the correlation grid")
    mean, std = v[finite].mean(), v[finite].std()
    if std == 0:
        raise AlignmentError(f"{name}: the signal is constant; a clock offset cannot be estimated from it")
    return np.where(finite, (v - mean) / std, 0.0)


def estimate_offset(ref_t_ns: np.ndarray, ref_values: np.ndarray, other_t_ns: np.ndarray,
                    other_values: np.ndarray, *, max_offset_ns: int | None = None,
                    period_ns: int | None = None) -> ClockOffset:
    """Clock offset of `other` relative to `ref` by cross-correlating one continuous signal."""
    ref_t = np.asarray(ref_t_ns, dtype=np.int64)
    oth_t = np.asarray(other_t_ns, dtype=np.int64)
    if period_ns is None:
        period_ns = min(stream_timing(ref_t, name="reference").period_ns,
                        stream_timing(oth_t, name="other").period_ns)
    t0 = min(ref_t[0], oth_t[0])
    t1 = max(ref_t[-1], oth_t[-1])
    grid = uniform_timebase(int(t0), int(t1), int(period_ns))
    a = _on_grid(ref_t, ref_values, grid, "reference")
    b = _on_grid(oth_t, other_values, grid, "other")
    from scipy import signal  # scipy.signal costs ~0.7 s to import; only the cross-correlation needs it
    corr = signal.correlate(b, a, mode="full", method="fft")
    lags = signal.correlation_lags(len(b), len(a), mode="full")
    if max_offset_ns is not None:
        keep = np.abs(lags) * period_ns <= max_offset_ns
        corr, lags = corr[keep], lags[keep]
    if len(corr) == 0:
        raise AlignmentError("no lag within max_offset_ns to test")
    k = int(np.argmax(corr))
    frac = 0.0
    if 0 < k < len(corr) - 1:
        y0, y1, y2 = corr[k - 1], corr[k], corr[k + 1]
        denom = y0 - 2 * y1 + y2
        if denom < 0:
            frac = float(np.clip(0.5 * (y0 - y2) / denom, -0.5, 0.5))
    lag = int(lags[k])
    # Pearson r of the overlapping, truly sampled parts at the integer lag
    if lag >= 0:
        aa, bb = a[: len(a) - lag], b[lag:]
    else:
        aa, bb = a[-lag:], b[: len(b) + lag]
    both = (aa != 0) | (bb != 0)
    r = float(np.corrcoef(aa[both], bb[both])[0, 1]) if both.sum() > 2 else 0.0
    return ClockOffset(offset_ns=int(round((lag + frac) * period_ns)), confidence=max(0.0, r),
                       resolution_ns=int(period_ns), method="xcorr", samples=len(grid))


def event_offset(ref_events_ns: np.ndarray, other_events_ns: np.ndarray, *,
                 consistent_ns: int | None = None) -> ClockOffset:
    """Clock offset from pairs of the same events timed by both clocks (NaN-free int64 arrays of equal
    length). Confidence is the share of events within `consistent_ns` (default 3 x spread, at least 1 ms)
    of the median."""
    ref = np.asarray(ref_events_ns, dtype=np.int64)
    oth = np.asarray(other_events_ns, dtype=np.int64)
    if ref.shape != oth.shape:
        raise AlignmentError(f"event_offset needs paired events, got {ref.shape} and {oth.shape}")
    if len(ref) == 0:
        raise AlignmentError("event_offset: no events seen by both streams")
    d = oth - ref
    med = int(np.median(d))
    mad = int(np.median(np.abs(d - med)))
    window = consistent_ns if consistent_ns is not None else max(3 * mad, 1_000_000)
    share = float(np.mean(np.abs(d - med) <= window))
    return ClockOffset(offset_ns=med, confidence=share, resolution_ns=mad, method="events", samples=len(d))


def shift_stream(stream: pd.DataFrame, delta_ns: int) -> pd.DataFrame:
    """A copy of `stream` with `delta_ns` added to its timestamps."""
    out = stream.copy()
    out["t_ns"] = out["t_ns"].to_numpy(dtype=np.int64) + np.int64(delta_ns)
    return out
