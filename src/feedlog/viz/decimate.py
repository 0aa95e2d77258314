"""Decimation of a time series to what a screen can show.

A time-series view `columns` pixels wide draws every sample that falls into one pixel column as one
vertical stroke from the column's lowest to its highest value. Keeping, per column, the first and
last sample (the line joins to the neighbours) and the lowest and highest (the stroke) draws the
same picture with at most four samples per column: every peak and valley a person sees survives
(`minmax_keep`). Where the samples of several columns lie on a straight line (a held feed, an
acceleration ramp, a smooth axis velocity) within one `rows`-th of the series' range, `linear_keep`
keeps only the line's two ends: the line drawn through what is left stays within that fraction of
every dropped sample.
"""

from __future__ import annotations

import numpy as np

SCREEN_COLUMNS = 800   # the width of the demo blueprint's series views on a 1920-px screen (3/5 of what the side panels leave)
SPATIAL_COLUMNS = SCREEN_COLUMNS * 2 // 3   # its 3D view beside them (2 shares to their 3): 533 px
FRAME_RATE_HZ = 30     # a video frame rate: positions a moving marker shows per second of playback
SCREEN_ROWS = 1000     # a series' range in 1000 steps: finer than a pixel of the demo's series panels


def minmax_keep(t: np.ndarray, values: np.ndarray, columns: int = SCREEN_COLUMNS) -> np.ndarray:
    """Boolean mask over the samples: first, last, lowest and highest sample of each of `columns`
    equal time spans between the first and the last `t`. Series of at most 4 x `columns` samples,
    or with no time span, keep everything. `values` must be finite (non-finite samples are left out
    before: Rerun draws a gap)."""
    t = np.asarray(t, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    if columns < 1:
        raise ValueError(f"columns must be at least 1, got {columns}")
    if t.shape != values.shape or t.ndim != 1:
        raise ValueError(f"time and values must be 1-D of one length, got {t.shape} and {values.shape}")
    n = len(t)
    keep = np.ones(n, dtype=bool)
    span = t[-1] - t[0] if n else 0.0
    if n <= 4 * columns or not span > 0:
        return keep
    col = np.minimum(((t - t[0]) * (columns / span)).astype(np.int64), columns - 1)
    # runs of consecutive samples in one column (time may step back: then a column is just split in two runs)
    starts = np.flatnonzero(np.r_[True, col[1:] != col[:-1]])
    ends = np.r_[starts[1:], n] - 1
    run = np.cumsum(np.r_[True, col[1:] != col[:-1]]) - 1
    keep[:] = False
    keep[starts] = True
    keep[ends] = True
    for reduce in (np.minimum, np.maximum):
        extreme = reduce.reduceat(values, starts)
        hit = np.flatnonzero(values == extreme[run])
        first = np.r_[True, run[hit][1:] != run[hit][:-1]]  # one sample per run: the first that reaches it
        keep[hit[first]] = True
    return keep


def rate_keep(t_ns: np.ndarray, hz: float = FRAME_RATE_HZ) -> np.ndarray:
    """Boolean mask keeping the first sample of every 1/`hz` second (and the last): a moving marker
    played back in real time on a `hz` display shows no more positions than that."""
    t_ns = np.asarray(t_ns, dtype=np.int64)
    keep = np.ones(len(t_ns), dtype=bool)
    if len(t_ns) < 3:
        return keep
    frame = (t_ns - t_ns[0]) // int(1e9 / hz)
    keep[:] = np.r_[True, frame[1:] != frame[:-1]]
    keep[-1] = True
    return keep


def linear_keep(t: np.ndarray, values: np.ndarray, columns: int = SCREEN_COLUMNS,
                rows: int = SCREEN_ROWS) -> np.ndarray:
    """`minmax_keep`, except where a straight line draws the samples: the columns are grouped in
    aligned runs of 2, 4, 8, ... columns, and a group whose every sample lies within one `rows`-th
    of the series' range of the chord from its first to its last sample keeps only those two (the
    widest such group wins). The drawn line stays within that tolerance of every sample."""
    t = np.asarray(t, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    keep = minmax_keep(t, values, columns)
    n = len(t)
    if keep.all():
        return keep
    span = t[-1] - t[0]
    col = np.minimum(((t - t[0]) * (columns / span)).astype(np.int64), columns - 1)
    if np.any(np.diff(col) < 0):  # time steps back: keep the plain per-column extremes
        return keep
    tol = float(values.max() - values.min()) / rows
    covered = np.zeros(n, dtype=bool)
    level = int(np.ceil(np.log2(columns)))
    while level >= 0:
        group = col >> level
        starts = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
        ends = np.r_[starts[1:], n] - 1
        gid = np.cumsum(np.r_[True, group[1:] != group[:-1]]) - 1
        ta, tb, va, vb = t[starts][gid], t[ends][gid], values[starts][gid], values[ends][gid]
        dt = np.where(tb > ta, tb - ta, 1.0)
        chord = va + (vb - va) * (t - ta) / dt
        worst = np.maximum.reduceat(np.abs(values - chord), starts)
        free = ~np.logical_or.reduceat(covered, starts)
        straight = (worst <= tol) & free & (ends - starts >= 2)
        if straight.any():
            inside = straight[gid]
            covered |= inside
            keep[inside] = False
            keep[starts[straight]] = True
            keep[ends[straight]] = True
        level -= 1
    return keep


def spacing_keep(xyz: np.ndarray, columns: int = SPATIAL_COLUMNS, min_step: float = 0.0) -> np.ndarray:
    """Boolean mask over path points keeping the first point of every step along the path of
    1/`columns` of the path's largest extent (a point per pixel of a view `columns` wide that shows
    the whole path) or `min_step`, the larger (points drawn as spheres of radius r spaced at most a
    diameter 2r apart touch: a continuous band at any zoom); the first and last point always.
    A standstill keeps one point."""
    xyz = np.asarray(xyz, dtype=np.float64)
    n = len(xyz)
    keep = np.ones(n, dtype=bool)
    if n < 3 or not np.isfinite(xyz).all():
        return keep
    extent = float(np.ptp(xyz, axis=0).max())
    if not extent > 0:
        keep[1:-1] = False
        return keep
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(xyz, axis=0), axis=1))]
    pixel = np.floor(s / max(extent / columns, min_step)).astype(np.int64)
    keep[:] = False
    keep[np.flatnonzero(np.r_[True, pixel[1:] != pixel[:-1]])] = True
    keep[-1] = True
    return keep
