"""Synthetic motion with known truth for align/ tests: a polyline moved with exact stops at every
vertex and a trapezoidal feed on every segment, sampled on any timestamps."""

from __future__ import annotations

import numpy as np
import pandas as pd


def segment_times(lengths: np.ndarray, feed_mm_s: float, acc_mm_s2: float) -> np.ndarray:
    """Duration of each exact-stop segment under a trapezoid (triangle when too short)."""
    lengths = np.asarray(lengths, dtype=np.float64)
    full = lengths >= feed_mm_s**2 / acc_mm_s2
    return np.where(full, lengths / feed_mm_s + feed_mm_s / acc_mm_s2, 2 * np.sqrt(lengths / acc_mm_s2))


def distance_in_segment(tau: np.ndarray, length: np.ndarray, feed: float, acc: float) -> np.ndarray:
    """Distance travelled after tau seconds into a segment of `length` (trapezoid / triangle)."""
    vpk = np.minimum(feed, np.sqrt(length * acc))
    ta = vpk / acc
    total = np.where(vpk >= feed, length / feed + feed / acc, 2 * ta)
    tc = total - 2 * ta
    d_acc = 0.5 * acc * np.minimum(tau, ta) ** 2
    d_cru = vpk * np.clip(tau - ta, 0, tc)
    td = np.clip(tau - ta - tc, 0, ta)
    d_dec = vpk * td - 0.5 * acc * td**2
    return np.minimum(d_acc + d_cru + d_dec, length)


class Motion:
    """Exact-stop motion along `vertices` (k, 3) starting after `lead_s` of standstill."""

    def __init__(self, vertices, *, feed_mm_min=3000.0, acc_mm_s2=1000.0, lead_s=0.5, tail_s=0.5,
                 t0_ns=1_000_000_000):
        self.v = np.asarray(vertices, dtype=np.float64)
        self.feed = feed_mm_min / 60.0
        self.acc = acc_mm_s2
        d = np.diff(self.v, axis=0)
        self.lengths = np.sqrt((d * d).sum(axis=1))
        self.durations = segment_times(self.lengths, self.feed, self.acc)
        self.t0_ns = t0_ns
        self.lead_s = lead_s
        self.tail_s = tail_s
        # arrival time of each vertex (s since t0)
        self.arrival_s = lead_s + np.concatenate([[0.0], np.cumsum(self.durations)])
        self.motion_s = float(self.durations.sum())
        self.end_s = self.arrival_s[-1] + tail_s

    @property
    def arrival_ns(self) -> np.ndarray:
        return self.t0_ns + np.rint(self.arrival_s * 1e9).astype(np.int64)

    def positions(self, t_ns: np.ndarray) -> np.ndarray:
        ts = (np.asarray(t_ns, dtype=np.int64) - self.t0_ns) / 1e9
        k = np.clip(np.searchsorted(self.arrival_s, ts, side="right") - 1, 0, len(self.lengths) - 1)
        tau = np.clip(ts - self.arrival_s[k], 0, None)
        dist = distance_in_segment(tau, self.lengths[k], self.feed, self.acc)
        frac = np.where(self.lengths[k] > 0, dist / np.where(self.lengths[k] > 0, self.lengths[k], 1), 0)
        return self.v[k] + frac[:, None] * (self.v[k + 1] - self.v[k])

    def speed(self, t_ns: np.ndarray) -> np.ndarray:
        """True path speed in mm/min (numerical, 1 us)."""
        t = np.asarray(t_ns, dtype=np.int64)
        a, b = self.positions(t - 500), self.positions(t + 500)
        return np.sqrt(((b - a) ** 2).sum(axis=1)) / 1e-6 * 60

    def timestamps(self, rate_hz: float, *, jitter_ns: int = 0, phase_ns: int = 0, seed: int = 0) -> np.ndarray:
        period = int(round(1e9 / rate_hz))
        n = int(self.end_s * 1e9 // period) + 1
        t = self.t0_ns + phase_ns + np.arange(n, dtype=np.int64) * period
        if jitter_ns:
            t = t + np.random.default_rng(seed).integers(-jitter_ns, jitter_ns + 1, n)
            t = np.sort(t)
        return t

    def axes(self, rate_hz: float, **kw) -> pd.DataFrame:
        t = self.timestamps(rate_hz, **kw)
        p = self.positions(t)
        return pd.DataFrame({"t_ns": t, "x_mm": p[:, 0], "y_mm": p[:, 1], "z_mm": p[:, 2]})


def zigzag(passes: int = 4, length: float = 40.0, step: float = 4.0, z: float = -1.0) -> np.ndarray:
    pts = []
    for i in range(passes):
        y = i * step
        xs = (0.0, length) if i % 2 == 0 else (length, 0.0)
        pts += [(xs[0], y, z), (xs[1], y, z)]
    return np.array(pts)


def repeated_zigzag(times: int = 2, **kw) -> np.ndarray:
    """The same zig-zag traced `times` times (back to the start in between): every pass repeats."""
    one = zigzag(**kw)
    out = [one]
    for _ in range(times - 1):
        out.append(one[::-1][1:])  # trace back over the same lines
        out.append(one[1:])
    return np.vstack(out)
