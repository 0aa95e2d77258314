"""Feed from positions: path (TCP) feed and per-axis feeds by smoothed differentiation.

Method (works on the recorded, possibly jittery timestamps; nothing assumes a uniform rate):
1. Pre-smoothing (only when the window spans more than 1.5 sampling periods, i.e. at high rates): each
   position column is replaced by its centred moving average over `window_s`, computed exactly for
   piecewise-linear signals as the difference of the cumulative trapezoid integral at t +- window/2.
   This removes quantisation and noise (a 1 um step becomes 1 um / window of speed, not 1 um / period).
2. Path length: S(t) is the cumulative chord length of the (smoothed) TCP positions x, y, z. Using the
   length along the samples, not the length of a velocity vector, keeps reversals and corners honest
   when samples are sparse (5 Hz: one sample every several mm).
3. Feed at sample i: [S(t_i + h) - S(t_i - h)] / 2h with h = max(window_s, period) / 2, S interpolated
   linearly in time and the span clipped to the recording at its ends. At 5 Hz this is the mean speed of
   the two intervals next to the sample; at 1 kHz with the default 4 ms window, a 4 ms average. Per-axis
   feeds use the same rule on the signed axis position.

For five-axis trunnion machines the TCP is the tool tip in workpiece coordinates; LinuxCNC's `axes`
stream (world coordinates under xyzac-trt-kins) already is that, so TCP feed is the feed of x, y, z.
Rotary axes get angular feeds (`a_deg_min`, ...) by the same rule. Units: mm/min and deg/min.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from feedlog.errors import AlignmentError

LINEAR = ("x_mm", "y_mm", "z_mm")
ROTARY = ("a_deg", "b_deg", "c_deg")


@dataclass(frozen=True)
class FeedSmoothing:
    """Differentiation window. `window_s=None` picks max(period, min_window_s)."""

    window_s: float | None = None
    min_window_s: float = 0.004

    def __post_init__(self) -> None:
        if self.window_s is not None and not self.window_s > 0:
            raise AlignmentError(f"FeedSmoothing.window_s must be > 0 s, got {self.window_s}")
        if not self.min_window_s >= 0:
            raise AlignmentError(f"FeedSmoothing.min_window_s must be >= 0 s, got {self.min_window_s}")

    def window_ns(self, period_ns: int) -> int:
        if self.window_s is not None:
            return int(round(self.window_s * 1e9))
        return max(int(period_ns), int(round(self.min_window_s * 1e9)))


def _integral_at(t: np.ndarray, v: np.ndarray, integral: np.ndarray, tq: np.ndarray) -> np.ndarray:
    """The running integral (n, k) of the piecewise-linear signals v (n, k) at times tq (quadratic
    inside intervals); one interval search serves all columns."""
    k = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, len(t) - 2)
    dt = t[k + 1] - t[k]
    tau = (tq - t[k])[:, None]
    inv = np.where(dt > 0, 1.0 / np.where(dt > 0, dt, 1.0), 0.0)[:, None]
    vk = v[k]
    return integral[k] + vk * tau + 0.5 * (v[k + 1] - vk) * inv * tau * tau


def moving_average(t_ns: np.ndarray, values: np.ndarray, window_ns: int) -> np.ndarray:
    """Centred moving average of `values` (n,) or (n, k) over `window_ns`, exact for piecewise-linear
    signals on any timestamps; the window shrinks (stays centred where possible) at the ends."""
    t = (np.asarray(t_ns, dtype=np.int64) - int(t_ns[0])).astype(np.float64)
    v = np.asarray(values, dtype=np.float64)
    squeeze = v.ndim == 1
    v2 = v[:, None] if squeeze else v
    dt = np.diff(t)
    integral = np.vstack([np.zeros((1, v2.shape[1])), np.cumsum(0.5 * (v2[1:] + v2[:-1]) * dt[:, None], axis=0)])
    lo = np.clip(t - window_ns / 2, t[0], t[-1])
    hi = np.clip(t + window_ns / 2, t[0], t[-1])
    span = (hi - lo)[:, None]
    a = _integral_at(t, v2, integral, lo)
    b = _integral_at(t, v2, integral, hi)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(span > 0, (b - a) / np.where(span > 0, span, 1.0), v2)
    return out[:, 0] if squeeze else out


def _central_rate(t: np.ndarray, s: np.ndarray, h: float) -> np.ndarray:
    lo = np.clip(t - h, t[0], t[-1])
    hi = np.clip(t + h, t[0], t[-1])
    span = hi - lo
    ds = np.interp(hi, t, s) - np.interp(lo, t, s)
    return np.where(span > 0, ds / np.where(span > 0, span, 1.0), 0.0)


def _prepare(t_ns, positions, columns, smoothing):
    smoothing = smoothing or FeedSmoothing()
    t_ns = np.asarray(t_ns, dtype=np.int64)
    if isinstance(positions, np.ndarray):
        if positions.ndim != 2 or positions.shape[1] != 3:
            raise AlignmentError(f"positions array must be (n, 3) x/y/z, got {positions.shape}")
        positions = pd.DataFrame(positions, columns=list(LINEAR))
    cols = list(columns) if columns is not None else [c for c in (*LINEAR, *ROTARY) if c in positions.columns]
    linear = [c for c in cols if c in LINEAR]
    if not linear:
        raise AlignmentError(f"feed from positions needs x_mm/y_mm/z_mm columns, got {list(positions.columns)}")
    n = len(t_ns)
    if n != len(positions):
        raise AlignmentError(f"{n} timestamps but {len(positions)} positions")
    if n < 2:
        raise AlignmentError(f"feed from positions needs at least 2 samples, got {n}")
    dt = np.diff(t_ns)
    if (dt < 0).any():
        raise AlignmentError("timestamps go backwards; cannot differentiate positions")
    period = int(np.median(dt[dt > 0])) if (dt > 0).any() else 0
    if period == 0:
        raise AlignmentError("all position samples carry the same timestamp")
    window = smoothing.window_ns(period)
    p = positions[cols].to_numpy(dtype=np.float64)
    if not np.isfinite(p).all():
        bad = int(np.flatnonzero(~np.isfinite(p).all(axis=1))[0])
        raise AlignmentError(f"position sample {bad} is not finite (NaN/inf); fill or drop it first")
    return t_ns, p, cols, [cols.index(c) for c in linear], period, window


def _rate_names(cols: list[str]) -> list[str]:
    return [f"v{c.split('_', 1)[0]}_{c.split('_', 1)[1]}_min" for c in cols]


def feed_from_positions(t_ns: np.ndarray, positions: pd.DataFrame | np.ndarray, *,
                        columns: Sequence[str] | None = None,
                        smoothing: FeedSmoothing | None = None) -> pd.DataFrame:
    """Path feed (`feed_mm_min`, over x/y/z) and per-axis feeds (`vx_mm_min`, ..., `va_deg_min`, ...).

    `positions` is a table with unit-named columns (x_mm, y_mm, z_mm, a_deg, ...) or an (n, 3) array of
    x, y, z. Returns a table with `t_ns` and the feeds, one row per input sample.
    """
    t_ns, p, cols, li, period, window = _prepare(t_ns, positions, columns, smoothing)
    if window > 1.5 * period:
        p = moving_average(t_ns, p, window)
    t = (t_ns - t_ns[0]).astype(np.float64)
    h = max(window, period) / 2
    chord = np.sqrt((np.diff(p[:, li], axis=0) ** 2).sum(axis=1))
    s = np.concatenate([[0.0], np.cumsum(chord)])
    out = {"t_ns": t_ns, "feed_mm_min": _central_rate(t, s, h) * 60e9}
    for j, name in enumerate(_rate_names(cols)):
        out[name] = _central_rate(t, p[:, j], h) * 60e9
    return pd.DataFrame(out)


def feed_at(t_ns: np.ndarray, positions: pd.DataFrame | np.ndarray, query_ns: np.ndarray, *,
            columns: Sequence[str] | None = None, smoothing: FeedSmoothing | None = None) -> pd.DataFrame:
    """The same feeds as `feed_from_positions`, evaluated only at the times `query_ns` (centred there
    instead of interpolated between samples): O(n) for one running integral plus O(queries x window
    samples), so a long 1 kHz recording costs little when only CL points need a feed."""
    t_ns, p, cols, li, period, window = _prepare(t_ns, positions, columns, smoothing)
    return _feed_at(t_ns, p, cols, li, period, window, query_ns)


def feed_at_checked(t_ns: np.ndarray, values: np.ndarray, cols: list[str], query_ns: np.ndarray, *,
                    period_ns: int, smoothing: FeedSmoothing | None = None) -> pd.DataFrame:
    """`feed_at` for callers that already hold validated arrays (finite float64 positions in `cols`
    order, x/y/z first; non-decreasing int64 times) and their sampling period."""
    window = (smoothing or FeedSmoothing()).window_ns(period_ns)
    li = [cols.index(c) for c in cols if c in LINEAR]
    return _feed_at(np.asarray(t_ns, dtype=np.int64), values, list(cols), li, int(period_ns), window, query_ns)


def _local_moving_average(t: np.ndarray, p: np.ndarray, idx: np.ndarray, a: np.ndarray, b: np.ndarray,
                          window: float) -> np.ndarray:
    """`moving_average` at the samples idx (k, m) (rows spanning samples a..b), from running integrals
    over each row's own neighbourhood only: no pass over the whole recording."""
    n = len(t)
    half = window / 2
    aw = np.clip(np.searchsorted(t, t[a] - half, side="right") - 1, 0, n - 2)
    bw = np.clip(np.searchsorted(t, t[b] + half, side="left"), 1, n - 1)
    width = int((bw - aw).max()) + 1
    widx = np.minimum(aw[:, None] + np.arange(width)[None, :], bw[:, None])  # (k, L)
    tw = t[widx]
    pw = p[widx]
    piece = 0.5 * (pw[:, 1:] + pw[:, :-1]) * (tw[:, 1:] - tw[:, :-1])[..., None]
    local = np.concatenate([np.zeros((len(a), 1, p.shape[1])), np.cumsum(piece, axis=1)], axis=1)
    rows = np.arange(len(a))[:, None]

    def integral_at(tq):  # (k, m) times -> (k, m, c) running integral since t[aw]
        kk = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, n - 2)
        j = np.clip(kk - aw[:, None], 0, width - 1)
        dt = t[kk + 1] - t[kk]
        tau = (tq - t[kk])[..., None]
        inv = np.where(dt > 0, 1.0 / np.where(dt > 0, dt, 1.0), 0.0)[..., None]
        return local[rows, j] + p[kk] * tau + 0.5 * (p[kk + 1] - p[kk]) * inv * tau * tau

    ti = t[idx]
    wlo = np.clip(ti - half, t[0], t[-1])
    whi = np.clip(ti + half, t[0], t[-1])
    span = (whi - wlo)[..., None]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(span > 0, (integral_at(whi) - integral_at(wlo)) / np.where(span > 0, span, 1.0), p[idx])


def _feed_at(t_ns, p, cols, li, period, window, query_ns) -> pd.DataFrame:
    n = len(t_ns)
    t = (t_ns - t_ns[0]).astype(np.float64)
    q = (np.asarray(query_ns, dtype=np.int64) - t_ns[0]).astype(np.float64)
    h = max(window, period) / 2
    lo = np.clip(q - h, t[0], t[-1])
    hi = np.clip(q + h, t[0], t[-1])
    a = np.clip(np.searchsorted(t, lo, side="right") - 1, 0, n - 2)
    b = np.clip(np.searchsorted(t, hi, side="left"), 1, n - 1)
    b = np.maximum(b, a + 1)
    m = int((b - a).max()) + 1 if len(q) else 2
    idx = np.minimum(a[:, None] + np.arange(m)[None, :], b[:, None])  # (k, m): samples a..b, then b repeated
    if window > 1.5 * period:
        ps = _local_moving_average(t, p, idx, a, b, window)
    else:
        ps = p[idx]
    rows = np.arange(len(q))
    last = b - a  # row position of sample b
    f_lo = np.where(t[a + 1] > t[a], (lo - t[a]) / np.where(t[a + 1] > t[a], t[a + 1] - t[a], 1.0), 0.0)
    f_hi = np.where(t[b] > t[b - 1], (hi - t[b - 1]) / np.where(t[b] > t[b - 1], t[b] - t[b - 1], 1.0), 1.0)
    p_lo = ps[:, 0] + f_lo[:, None] * (ps[:, 1] - ps[:, 0])
    p_hi = ps[rows, last - 1] + f_hi[:, None] * (ps[rows, last] - ps[rows, last - 1])
    chord = np.sqrt((np.diff(ps[:, :, li], axis=1) ** 2).sum(axis=2))  # (k, m-1), 0 past b
    s_row = np.concatenate([np.zeros((len(q), 1)), np.cumsum(chord, axis=1)], axis=1)
    s_lo = f_lo * chord[:, 0]
    s_hi = s_row[rows, last - 1] + f_hi * chord[rows, last - 1]
    span = hi - lo
    ok = span > 0
    den = np.where(ok, span, 1.0)
    out = {"t_ns": np.asarray(query_ns, dtype=np.int64),
           "feed_mm_min": np.where(ok, (s_hi - s_lo) / den, 0.0) * 60e9}
    rate = np.where(ok[:, None], (p_hi - p_lo) / den[:, None], 0.0) * 60e9
    for j, name in enumerate(_rate_names(cols)):
        out[name] = rate[:, j]
    return pd.DataFrame(out)


def path_length(positions: np.ndarray) -> np.ndarray:
    """Cumulative chord length (n,) of an (n, 3) polyline, starting at 0."""
    p = np.asarray(positions, dtype=np.float64)
    return np.concatenate([[0.0], np.cumsum(np.sqrt((np.diff(p, axis=0) ** 2).sum(axis=1)))])
