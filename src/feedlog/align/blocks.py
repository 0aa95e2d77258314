"""Block boundaries and cycle time: when each program block started and ended on the machine.

Two sources (Chien et al. 2024 train on per-CL-line "block cycle times"):
- **Line stream** (ground truth when the controller exports it, e.g. LinuxCNC `motion.program-line`):
  a block starts at the first sample showing its line and ends at the first sample showing another
  line after its last run. Times are clipped to the motion span, so that a line shown while the queue
  fills, or held after the end, does not count as motion; the first seen block starts at motion start
  and the last ends at motion end, so block times add up to the cycle time. Blocks whose line never shows (segments
  shorter than one servo period, merged segments) get zero duration at their neighbour's boundary and
  `seen = False`.
- **Geometry** (when there is no line stream): block k ends when the tool arrives at its end point (the
  constrained CL match of the block's last CL point) and starts when it leaves the previous block's end
  point (departure; differs from arrival at a stop or dwell). The first block starts at motion start,
  the last ends at motion end.

Motion span (cycle time = end - start): from the positions themselves. Motion starts in the first
sampling interval at whose end an axis is more than `still_mm` away from its starting rest position,
and ends in the last interval before every axis settles within `still_mm` of its final rest position
(noise-free data: the first and last sample-to-sample change; noisy data: `still_mm` from `rest_noise`). At high rates
the interval edges are used (motion starts at the last sample at rest, ends at the first sample at
rest); when samples are sparse (5 Hz) the moment inside the interval is estimated from the distance
moved in it, the mean speed of the neighbouring interval and the acceleration limit (from rest with
acceleration `acc_mm_s2` up to that speed; `acc_mm_s2 = inf` assumes constant speed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from feedlog.errors import AlignmentError
from feedlog.align.line_sequence import blocks_from_line_sequence, repeats_lines, shares_next_run


@dataclass(frozen=True)
class MotionSpan:
    t_start_ns: int
    t_end_ns: int
    first_index: int   # last sample at rest before motion
    last_index: int    # first sample at rest after motion

    @property
    def duration_s(self) -> float:
        return (self.t_end_ns - self.t_start_ns) / 1e9


def _time_from_rest(d: float, v: float, acc: float) -> float:
    """Seconds to travel d from rest, accelerating at acc up to speed v."""
    if v <= 0:
        return 0.0
    if not np.isfinite(acc) or acc <= 0:
        return d / v
    if d <= v * v / (2 * acc):
        return float(np.sqrt(2 * d / acc))
    return d / v + v / (2 * acc)


def rest_noise(t_ns: np.ndarray, positions: np.ndarray, *, probe_s: float = 0.1, bound_mm: float = 0.1) -> float:
    """Robust standard deviation of the position noise (worst axis): 1.4826 x MAD of the second
    differences / sqrt(6), over the samples of the first (last) `probe_s` that stay within `bound_mm` of
    the first (last) sample, where a logger normally sees the machine standing. 0 for clean positions."""
    t = np.asarray(t_ns, dtype=np.int64)
    p = np.asarray(positions, dtype=np.float64)
    head = max(int(np.searchsorted(t, t[0] + int(probe_s * 1e9))), 1)
    tail = min(int(np.searchsorted(t, t[-1] - int(probe_s * 1e9))), len(t) - 1)
    spread = []
    for part in (p[:head], p[tail:][::-1]):
        near = np.abs(part - part[0]).max(axis=1) <= bound_mm
        run = part[: int(np.argmin(near)) if not near.all() else len(part)]
        if len(run) >= 5:
            # second differences: white noise of std s gives std s*sqrt(6); a smooth start (constant
            # acceleration) gives a constant that the median removes, so motion is not taken for noise
            d2 = np.diff(run, n=2, axis=0)
            dev = np.abs(d2 - np.median(d2, axis=0))
            spread.append(1.4826 * np.median(dev, axis=0).max() / np.sqrt(6.0))
        elif len(run) >= 2:  # sparse data: a few samples at rest, far from any moving one
            spread.append(1.4826 * np.median(np.abs(run - np.median(run, axis=0)), axis=0).max())
    return float(min(spread)) if spread else 0.0


def motion_span(t_ns: np.ndarray, positions: np.ndarray, *, still_mm: float = 1e-6,
                acc_mm_s2: float = np.inf, sparse_ns: int = 5_000_000) -> MotionSpan:
    """First motion to end of motion. `positions` (n, k) in mm (and deg for rotary columns); the tool
    moves once any axis is more than `still_mm` away from where it rested at the start (with
    still_mm > 1e-6: the median of the leading samples within 2 still_mm of the first), and has stopped
    once every axis stays within
    `still_mm` of where it rests at the end; for noise-free data that is the first and last
    sample-to-sample change. Intervals longer than `sparse_ns` get the sub-interval estimate described
    in the module doc."""
    t = np.asarray(t_ns, dtype=np.int64)
    p = np.asarray(positions, dtype=np.float64)
    if len(t) < 2:
        raise AlignmentError(f"motion span needs at least 2 samples, got {len(t)}")
    # rest positions: the first and last sample; with noise, the median of the leading (trailing) run
    # of samples within 2 x still_mm of the first (last) one
    ref0, ref1 = p[0], p[-1]
    if still_mm > 1e-6:
        near0 = np.abs(p - p[0]).max(axis=1) <= 2 * still_mm
        near1 = np.abs(p - p[-1]).max(axis=1) <= 2 * still_mm
        run0 = int(np.argmin(near0)) if not near0.all() else len(p)
        run1 = int(np.argmin(near1[::-1])) if not near1.all() else len(p)
        ref0 = np.median(p[:max(run0, 1)], axis=0)
        ref1 = np.median(p[len(p) - max(run1, 1):], axis=0)
    away0 = np.flatnonzero(np.abs(p - ref0).max(axis=1) > still_mm)
    away1 = np.flatnonzero(np.abs(p - ref1).max(axis=1) > still_mm)
    if len(away0) == 0 or len(away1) == 0:
        raise AlignmentError(f"the recording never moves (no axis changes by more than {still_mm} mm)")
    i0 = max(int(away0[0]) - 1, 0)                  # last sample at rest before motion
    i1 = min(int(away1[-1]), len(t) - 2)            # last sample before the final rest

    def chord(i: int) -> float:  # straight distance moved in interval i
        return float(np.linalg.norm(p[i + 1, :3] - p[i, :3]))

    t_start, t_end = int(t[i0]), int(t[i1 + 1])
    if still_mm > 1e-6 and np.isfinite(acc_mm_s2) and acc_mm_s2 > 0:
        # with a noise threshold the tool is seen moving only once it is still_mm away: it started
        # (stopped) sqrt(2 still_mm / acc) before (after) that, accelerating from rest
        tau = int(np.sqrt(2 * still_mm / acc_mm_s2) * 1e9)
        t_start = max(int(t[i0 + 1]) - tau, int(t[0]))
        t_end = min(int(t[i1]) + tau, int(t[-1]))
    dt0 = t[i0 + 1] - t[i0]
    if dt0 > sparse_ns and i0 + 2 < len(t):
        nxt = i0 + 1
        v = chord(nxt) / ((t[nxt + 1] - t[nxt]) / 1e9)
        tau = _time_from_rest(chord(i0), max(v, chord(i0) / (dt0 / 1e9)), acc_mm_s2)
        t_start = int(t[i0 + 1] - min(int(tau * 1e9), int(dt0)))
    dt1 = t[i1 + 1] - t[i1]
    if dt1 > sparse_ns and i1 - 1 >= 0:
        prv = i1 - 1
        v = chord(prv) / ((t[prv + 1] - t[prv]) / 1e9)
        tau = _time_from_rest(chord(i1), max(v, chord(i1) / (dt1 / 1e9)), acc_mm_s2)
        t_end = int(t[i1] + min(int(tau * 1e9), int(dt1)))
    return MotionSpan(t_start_ns=t_start, t_end_ns=t_end, first_index=i0, last_index=i1 + 1)


def line_runs(t_ns: np.ndarray, line: np.ndarray) -> pd.DataFrame:
    """Runs of a constant program line: line, t_start_ns (first sample), t_end_ns (first sample of the
    next run; the last sample's time for the final run)."""
    t = np.asarray(t_ns, dtype=np.int64)
    ln = np.asarray(line, dtype=np.int64)
    if len(t) == 0:
        return pd.DataFrame({"line": np.empty(0, np.int64), "t_start_ns": np.empty(0, np.int64),
                             "t_end_ns": np.empty(0, np.int64)})
    starts = np.concatenate([[0], np.flatnonzero(ln[1:] != ln[:-1]) + 1])
    ends_t = np.concatenate([t[starts[1:]], [t[-1]]])
    return pd.DataFrame({"line": ln[starts], "t_start_ns": t[starts], "t_end_ns": ends_t})


def blocks_from_lines(t_ns: np.ndarray, line: np.ndarray, motion_blocks: pd.DataFrame, *,
                      span: MotionSpan | None = None) -> pd.DataFrame:
    """Per motion block (`block`, `line` columns of `motion_blocks`, in program order): t_start_ns,
    t_end_ns, duration_s and `seen` from a program-line stream."""
    runs = line_runs(t_ns, line)
    lines = motion_blocks["line"].to_numpy(dtype=np.int64)
    if span is not None:
        runs["t_start_ns"] = runs["t_start_ns"].clip(span.t_start_ns, span.t_end_ns)
        runs["t_end_ns"] = runs["t_end_ns"].clip(span.t_start_ns, span.t_end_ns)
    runs = runs[runs["line"].isin(lines)]
    if repeats_lines(motion_blocks):  # loops, subroutines, sub files: a line number names several blocks
        start, end = blocks_from_line_sequence(runs.reset_index(drop=True), motion_blocks)
    else:
        first = runs.groupby("line")["t_start_ns"].min()
        last = runs.groupby("line")["t_end_ns"].max()
        start = pd.Series(lines).map(first).to_numpy(dtype=np.float64, copy=True)
        end = pd.Series(lines).map(last).to_numpy(dtype=np.float64, copy=True)
    seen = np.isfinite(start)
    if not seen.any():
        raise AlignmentError("the line stream never shows a line of the program's motion blocks "
                             f"(it shows {sorted(set(np.asarray(line).tolist()))[:10]}...); wrong program?")
    # a line that makes several moves (a canned cycle, G28) shows as one run: it times the last of them,
    # the others are split off by geometry (split_merged), as blocks the planner merged
    seen &= ~shares_next_run(motion_blocks)
    if span is not None:
        # motion before the first line shows (or after the last one ends) can only be theirs
        first, last = np.flatnonzero(seen)[[0, -1]]
        start[first] = span.t_start_ns
        end[last] = span.t_end_ns
    # unseen blocks: zero length at the next seen block's start (or the previous end at the tail)
    nxt = pd.Series(np.where(seen, start, np.nan)).bfill().to_numpy()
    prv = pd.Series(np.where(seen, end, np.nan)).ffill().to_numpy()
    fill = np.where(np.isfinite(nxt), nxt, prv)
    start = np.where(seen, start, fill)
    end = np.where(seen, end, fill)
    out = motion_blocks[["block", "line"]].reset_index(drop=True).copy()
    out["t_start_ns"] = start.astype(np.int64)
    out["t_end_ns"] = end.astype(np.int64)
    out["duration_s"] = (out["t_end_ns"] - out["t_start_ns"]) / 1e9
    out["seen"] = seen
    return out


NO_TIME = np.iinfo(np.int64).min
SHORT_LEAVE_SAMPLES = 64


def _last_on(t, p, rows, start, hi, a, d, on_path_mm, *, off=False):
    """Per row: the index of the last sample in [start, hi[row]] within on_path_mm of the segment
    a[i] + u d[i] (u in [0, 1]) (with `off`: farther than on_path_mm), -1 when none."""
    n = len(t)
    out = np.full(len(rows), -1, dtype=np.int64)
    if not len(rows):
        return out
    widths = hi[rows] - start + 1
    # rows of similar window width together, so a few long windows do not pad every row to their width
    order = np.argsort(widths, kind="stable")
    chunks, first = [], 0
    while first < len(order):  # up to 1024 rows and 2 M samples x rows per chunk
        widest = max(1, int(widths[order[min(first + 1024, len(order)) - 1]]))
        size = max(1, min(1024, 2_000_000 // widest))
        chunks.append(order[first:first + size])
        first += size
    for sel in chunks:
        width = max(1, int(widths[sel].max()))
        part, st = rows[sel], start[sel]
        idx = st[:, None] + np.arange(width)[None, :]
        valid = idx <= hi[part, None]
        idx = np.minimum(idx, n - 1)
        w = p[idx] - a[sel, None, :]
        dv = d[sel, None, :]
        dd = (dv * dv).sum(axis=2)
        u = np.clip(np.where(dd > 0, (w * dv).sum(axis=2) / np.where(dd > 0, dd, 1.0), 0.0), 0.0, 1.0)
        dist = np.sqrt(((w - u[..., None] * dv) ** 2).sum(axis=2))
        hit = (dist > on_path_mm) if off else (dist <= on_path_mm)
        out[sel] = np.where(valid & hit, idx, -1).max(axis=1)
    return out


def leave_times(t_ns: np.ndarray, positions: np.ndarray, seg_start: np.ndarray, seg_end: np.ndarray,
                end_index: np.ndarray, *, on_path_mm: float = 1e-4, search_s: float = 0.5,
                merge_back: int = 32) -> np.ndarray:
    """Per straight block k (segment seg_start[k] -> seg_end[k], NaN rows skipped): the time of the
    first sample off the segment (farther than `on_path_mm`) after the last sample on it, among the
    samples after the previous block's end match and up to this block's end match `end_index[k]`
    (fractional sample index, non-decreasing), at most `search_s` before it. This is where a corner
    blend begins. A block with no sample on its own segment may have been merged with up to
    `merge_back` straight blocks before it into one move (LinuxCNC G64 Q: the planner runs a straight
    line from the first block's start to the last block's end): the chords seg_start[k - m] -> seg_end[k]
    are tried in turn. NO_TIME where neither finds a sample on the path."""
    t = np.asarray(t_ns, dtype=np.int64)
    p = np.asarray(positions, dtype=np.float64)[:, :3]
    a = np.asarray(seg_start, dtype=np.float64)
    b = np.asarray(seg_end, dtype=np.float64)
    n, k = len(t), len(a)
    out = np.full(k, NO_TIME, dtype=np.int64)
    ok = np.isfinite(end_index) & np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    if not ok.any() or n < 2:
        return out
    hi = np.maximum.accumulate(np.where(np.isfinite(end_index), np.ceil(np.nan_to_num(end_index, nan=0.0)), 0))
    hi = np.minimum(hi.astype(np.int64), n - 1)
    dt = np.diff(t)
    period = float(np.median(dt[dt > 0])) if (dt > 0).any() else 1.0
    lo = np.concatenate([[0], hi[:-1] + 1])
    lo = np.maximum(lo, hi - int(np.ceil(search_s * 1e9 / period)) + 1)
    rows = np.flatnonzero(ok & (hi >= lo))
    # own segment: first the last few samples before each end (a blend is short), then the whole window
    short = np.maximum(lo[rows], hi[rows] - SHORT_LEAVE_SAMPLES + 1)
    last = _last_on(t, p, rows, short, hi, a[rows], b[rows] - a[rows], on_path_mm)
    retry = (last < 0) & (short > lo[rows])
    if retry.any():
        r = rows[retry]
        last[retry] = _last_on(t, p, r, lo[r], hi, a[r], b[r] - a[r], on_path_mm)
    found = last >= 0
    out[rows[found]] = t[np.minimum(last[found] + 1, n - 1)]
    # merged moves: chords from an earlier straight block's start to this block's end
    todo = rows[~found]
    bad_before = np.cumsum(~ok)  # straight blocks k-m..k <=> no non-straight block in between
    for m in range(1, merge_back + 1):
        todo = todo[todo - m >= 0]
        todo = todo[bad_before[todo] - bad_before[todo - m] == 0] if len(todo) else todo
        if not len(todo):
            break
        ca = a[todo - m]
        last = _last_on(t, p, todo, lo[todo], hi, ca, b[todo] - ca, on_path_mm)
        hit = last >= 0
        out[todo[hit]] = t[np.minimum(last[hit] + 1, n - 1)]
        todo = todo[~hit]
    return out


def blocks_from_geometry(motion_blocks: pd.DataFrame, end_arrival_ns: np.ndarray, end_departure_ns: np.ndarray,
                         *, span: MotionSpan, end_leave_ns: np.ndarray | None = None) -> pd.DataFrame:
    """Per motion block: ends at the arrival at its end point (or, with `end_leave_ns`, where the tool
    leaves the block's path into a corner blend, when that is earlier); the next block starts there, or
    at the departure when the tool stopped at the point (a stop or a dwell is not motion of the next
    block). The first block starts at motion start. Arrays are per motion block, in program order."""
    arr = np.asarray(end_arrival_ns, dtype=np.int64)
    dep = np.asarray(end_departure_ns, dtype=np.int64)
    end = arr.copy()
    if end_leave_ns is not None:
        leave = np.asarray(end_leave_ns, dtype=np.int64)
        use = (leave != NO_TIME) & (leave < arr)
        end = np.where(use, leave, arr)
    stopped = dep > arr
    start = np.concatenate([[span.t_start_ns], np.where(stopped, dep, end)[:-1]])
    if len(end):
        end[-1] = span.t_end_ns  # arrival at the final point is the end of motion (sub-sample at low rates)
    # progress is monotone; guard against a departure estimate after the next arrival
    start = np.minimum(start, end)
    out = motion_blocks[["block", "line"]].reset_index(drop=True).copy()
    out["t_start_ns"] = start
    out["t_end_ns"] = end
    out["duration_s"] = (end - start) / 1e9
    out["seen"] = True
    return out


def line_groups(seen: np.ndarray) -> np.ndarray:
    """Group id per block: a controller that merges short collinear segments (LinuxCNC G64 P..Q) runs
    them as one and shows the last line only, so every unseen block belongs with the next seen one
    (trailing unseen blocks with the last seen one). The id is the index of that seen block."""
    seen = np.asarray(seen, dtype=bool)
    n = len(seen)
    idx = np.where(seen, np.arange(n), n)
    nxt = np.minimum.accumulate(idx[::-1])[::-1]
    last = np.flatnonzero(seen)[-1] if seen.any() else 0
    return np.where(nxt < n, nxt, last)


def split_merged(line_blocks: pd.DataFrame, geometry_blocks: pd.DataFrame) -> pd.DataFrame:
    """Line-stream block times where the controller merged several blocks into one: the group's
    measured interval (from the line stream) is split over its blocks in proportion to their geometric
    durations (equal shares when those are all zero). Singleton groups keep their line times exactly.
    `source` becomes "line+geometry" for split blocks."""
    lb = line_blocks.reset_index(drop=True).copy()
    geo = geometry_blocks.set_index("block")["duration_s"].reindex(lb["block"]).to_numpy(dtype=np.float64)
    group = line_groups(lb["seen"].to_numpy())
    sizes = np.bincount(group, minlength=len(lb))[group]
    multi = sizes > 1
    if not multi.any():
        return lb
    g = pd.DataFrame({"group": group, "w": np.nan_to_num(np.maximum(geo, 0.0))})
    total = g.groupby("group")["w"].transform("sum").to_numpy()
    w = np.where(total > 0, g["w"].to_numpy() / np.where(total > 0, total, 1.0), 1.0 / sizes)
    before = pd.Series(w).groupby(group).cumsum().to_numpy() - w
    s0 = lb["t_start_ns"].to_numpy()[group].astype(np.float64)
    e0 = lb["t_end_ns"].to_numpy()[group].astype(np.float64)
    # the group starts where its first block starts on the line stream's clock: the seen block's start
    first_start = pd.Series(np.where(lb["seen"].to_numpy(), s0, np.nan)).groupby(group).transform("first")
    s0 = first_start.to_numpy()
    start = np.rint(s0 + (e0 - s0) * before).astype(np.int64)
    end = np.rint(s0 + (e0 - s0) * (before + w)).astype(np.int64)
    lb.loc[multi, "t_start_ns"] = start[multi]
    lb.loc[multi, "t_end_ns"] = end[multi]
    lb["duration_s"] = (lb["t_end_ns"] - lb["t_start_ns"]) / 1e9
    if "source" in lb:
        lb["source"] = np.where(multi, "line+geometry", lb["source"].to_numpy())
    return lb


def compare_blocks(truth: pd.DataFrame, other: pd.DataFrame, *, servo_period_s: float | None = None,
                   groups: np.ndarray | None = None) -> dict:
    """Errors of `other` block times against `truth` from a line stream: median/p95/max of |duration|,
    |start| and |end| differences in seconds, per group of blocks. `groups` (one id per row of `truth`,
    non-decreasing), e.g. the planner moves of `feedlog.align.moves.planner_moves`: blocks the
    controller really merged into one move are compared as that move, every other block alone (a block
    whose line never shows then counts with its true zero time). Without `groups`, every block unseen in
    `truth` is grouped with the next seen one (`line_groups`)."""
    m = truth.reset_index(drop=True).merge(other, on="block", suffixes=("_true", "_est"), how="left")
    seen = m["seen_true"].to_numpy() if "seen_true" in m else np.ones(len(m), dtype=bool)
    if len(m) == 0 or not seen.any():
        return {"blocks": 0}
    if groups is None:
        group = line_groups(seen)
    else:
        group = np.asarray(groups, dtype=np.int64)
        if len(group) != len(m) or np.any(np.diff(group) < 0):
            raise AlignmentError(f"compare_blocks: need one non-decreasing group id per block ({len(m)} blocks, "
                                 f"{len(group)} ids)")
    agg = m.assign(group=group).groupby("group").agg(
        ts_true=("t_start_ns_true", "min"), te_true=("t_end_ns_true", "max"),
        ts_est=("t_start_ns_est", "min"), te_est=("t_end_ns_est", "max"),
        d_true=("duration_s_true", "sum"), d_est=("duration_s_est", "sum"))
    dd = (agg["d_est"] - agg["d_true"]).abs()
    ds = (agg["ts_est"] - agg["ts_true"]).abs() / 1e9
    de = (agg["te_est"] - agg["te_true"]).abs() / 1e9
    out = {"blocks": int(len(m)), "groups": int(len(agg)), "merged_blocks": int(len(m) - len(agg)),
           "unseen_blocks": int((~seen).sum()),
           "duration_err_median_s": float(dd.median()), "duration_err_p95_s": float(dd.quantile(0.95)),
           "duration_err_max_s": float(dd.max()), "start_err_median_s": float(ds.median()),
           "end_err_median_s": float(de.median()),
           "end_bias_s": float(((agg["te_est"] - agg["te_true"]) / 1e9).median())}
    if servo_period_s:
        out["duration_err_median_periods"] = out["duration_err_median_s"] / servo_period_s
    return out
