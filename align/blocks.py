"""Block boundaries and cycle time: when each program block started and ended on the machine.

Two sources (Chien et al. 2024 train on per-CL-line "block cycle times"):
- **Line stream** (ground truth when the controller exports it, e.g. LinuxCNC `motion.program-line`):
  a block starts at the first sample showing its line and ends at the first sample showing another
  line after its last run. Times are clipped to the motion span, so that a line shown while the queue
  fills, or held after the end, does not count as motion. Blocks whose line never shows (segments
  shorter than one servo period, merged segments) get zero duration at their neighbour's boundary and
  `seen = False`.
- **Geometry** (when there is no line stream): block k ends when the tool arrives at its end point (the
  constrained CL match of the block's last CL point) and starts when it leaves the previous block's end
  point (departure; differs from arrival at a stop or dwell). The first block starts at motion start,
  the last ends at motion end.

Motion span (cycle time = end - start): from the positions themselves. Motion starts in the first
sampling interval in which any axis moves by more than `still_mm` and ends in the last. At high rates
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


def motion_span(t_ns: np.ndarray, positions: np.ndarray, *, still_mm: float = 1e-6,
                acc_mm_s2: float = np.inf, sparse_ns: int = 5_000_000) -> MotionSpan:
    """First motion to end of motion. `positions` (n, k) in mm (and deg for rotary columns);
    intervals longer than `sparse_ns` get the sub-interval estimate described in the module doc."""
    t = np.asarray(t_ns, dtype=np.int64)
    p = np.asarray(positions, dtype=np.float64)
    if len(t) < 2:
        raise AlignmentError(f"motion span needs at least 2 samples, got {len(t)}")
    step = np.abs(np.diff(p, axis=0)).max(axis=1)
    moving = np.flatnonzero(step > still_mm)
    if len(moving) == 0:
        raise AlignmentError(f"the recording never moves (no axis changes by more than {still_mm} mm)")
    i0, i1 = int(moving[0]), int(moving[-1])
    chord = np.sqrt((np.diff(p[:, :3], axis=0) ** 2).sum(axis=1)) if p.shape[1] >= 3 else step
    t_start, t_end = int(t[i0]), int(t[i1 + 1])
    dt0 = t[i0 + 1] - t[i0]
    if dt0 > sparse_ns and i0 + 1 < len(chord):
        nxt = i0 + 1
        v = chord[nxt] / ((t[nxt + 1] - t[nxt]) / 1e9)
        tau = _time_from_rest(float(chord[i0]), max(v, chord[i0] / (dt0 / 1e9)), acc_mm_s2)
        t_start = int(t[i0 + 1] - min(int(tau * 1e9), int(dt0)))
    dt1 = t[i1 + 1] - t[i1]
    if dt1 > sparse_ns and i1 - 1 >= 0:
        prv = i1 - 1
        v = chord[prv] / ((t[prv + 1] - t[prv]) / 1e9)
        tau = _time_from_rest(float(chord[i1]), max(v, chord[i1] / (dt1 / 1e9)), acc_mm_s2)
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
    first = runs.groupby("line")["t_start_ns"].min()
    last = runs.groupby("line")["t_end_ns"].max()
    start = pd.Series(lines).map(first).to_numpy(dtype=np.float64)
    end = pd.Series(lines).map(last).to_numpy(dtype=np.float64)
    seen = np.isfinite(start)
    if not seen.any():
        raise AlignmentError("the line stream never shows a line of the program's motion blocks "
                             f"(it shows {sorted(set(np.asarray(line).tolist()))[:10]}...); wrong program?")
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


def blocks_from_geometry(motion_blocks: pd.DataFrame, end_arrival_ns: np.ndarray, end_departure_ns: np.ndarray,
                         *, span: MotionSpan) -> pd.DataFrame:
    """Per motion block: ends at the arrival at its end point, starts at the departure from the previous
    block's end point (the first at motion start). Arrays are per motion block, in program order."""
    arr = np.asarray(end_arrival_ns, dtype=np.int64)
    dep = np.asarray(end_departure_ns, dtype=np.int64)
    start = np.concatenate([[span.t_start_ns], dep[:-1]])
    end = arr.copy()
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


def compare_blocks(truth: pd.DataFrame, other: pd.DataFrame, *, servo_period_s: float | None = None) -> dict:
    """Errors of `other` block times against `truth` (same blocks): median/p95/max of |duration|,
    |start| and |end| differences in seconds (only blocks seen in the truth)."""
    m = truth.merge(other, on="block", suffixes=("_true", "_est"))
    m = m[m["seen_true"]] if "seen_true" in m else m
    if len(m) == 0:
        return {"blocks": 0}
    dd = (m["duration_s_est"] - m["duration_s_true"]).abs()
    ds = (m["t_start_ns_est"] - m["t_start_ns_true"]).abs() / 1e9
    de = (m["t_end_ns_est"] - m["t_end_ns_true"]).abs() / 1e9
    out = {"blocks": int(len(m)),
           "duration_err_median_s": float(dd.median()), "duration_err_p95_s": float(dd.quantile(0.95)),
           "duration_err_max_s": float(dd.max()), "start_err_median_s": float(ds.median()),
           "end_err_median_s": float(de.median()),
           "end_bias_s": float(((m["t_end_ns_est"] - m["t_end_ns_true"]) / 1e9).median())}
    if servo_period_s:
        out["duration_err_median_periods"] = out["duration_err_median_s"] / servo_period_s
    return out
