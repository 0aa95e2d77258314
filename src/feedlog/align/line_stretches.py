"""Per-stretch line offsets between a first mismatch and the next anchor.

Where the recorded lines stop being the published program's (`line_map`: the first mismatch) and where
the data ties them again (an anchor: the tool change's spindle restart), the file that ran had lines
inserted or removed somewhere in between: the offset (recorded line - program line) is constant over
stretches and changes where lines were inserted (it grows) or removed (it shrinks).

The line stream gives the time from one recorded line change to the next; at offset `o` it covers
program lines [L_k - o, L_{k+1} - o), whose simulated time is known. Each interval costs
|log((measured + E) / (expected + E))| (capped at CAP; E, one line sample, keeps the sampling's
quantisation from ruling) plus NO_BLOCK where the recorded line would be a program line with no block
(the controller reports executed lines); an offset change costs CHANGE. The cheapest sequence of offsets
from the offset before the mismatch to the anchor's (dynamic programming over the runs) is the estimate.

A change of offset is placed only as well as the line times tell: the runs where moving the change keeps
the cost within AMBIGUOUS of its best are where either offset fits (a stretch of equal short lines looks
the same a line on), and those runs, with the ones within as many recorded lines as the change inserts
or removes (those lines have no counterpart), stay unplaced. A stretch is *established* when its offset costs at
least ESTABLISHED less than the best other offset over it; only established stretches are placed (then
timed block by block). What is left is said: the stretches with their recorded and program lines, the
runs left out, and per change how many recorded lines have no counterpart in the program (an offset
that grows by n: n lines inserted in the file that ran, between the stretches) or the other way round.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

E_S = 0.15           # seconds added to both sides of an interval's ratio (one line sample of a 5-7 Hz stream)
CAP = 3.0            # an interval's cost at most this (a wait no line explains is not evidence against all)
NO_BLOCK = 0.5       # a recorded line that would be a program line without a block
CHANGE = 1.0         # cost of one offset change
AMBIGUOUS = 0.3      # change points within this of the best cost fit as well
ESTABLISHED = 1.0    # a stretch's offset beats every other offset over it by at least this
MARGIN = 8           # offsets considered: between the two known ones, widened by this many lines


def _costs(lines: np.ndarray, measured: np.ndarray, expected: pd.Series, offsets: np.ndarray) -> np.ndarray:
    """(intervals, offsets) cost of interval k (run k to run k+1) at each offset."""
    top = int(max(lines.max(), expected.index.max())) + int(np.abs(offsets).max()) + 2
    per = np.zeros(top + 1)
    known = expected.index.to_numpy(np.int64)
    known = known[(known >= 0) & (known <= top)]
    per[known] = expected.reindex(known).to_numpy(np.float64)
    has = np.zeros(top + 1, dtype=bool)
    has[known] = True
    cum = np.r_[0.0, np.cumsum(per)]                          # cum[l]: lines before l
    lo = lines[:-1, None] - offsets[None, :]
    hi = lines[1:, None] - offsets[None, :]
    ok = (lo >= 1) & (hi >= 1) & (lo <= top) & (hi <= top)
    lo_c, hi_c = np.clip(lo, 0, top), np.clip(hi, 0, top)
    x = np.where(hi_c > lo_c, cum[hi_c] - cum[lo_c], 0.0)
    cost = np.minimum(np.abs(np.log((measured[:, None] + E_S) / (x + E_S))), CAP) + np.where(has[lo_c], 0.0, NO_BLOCK)
    return np.where(ok, cost, CAP + NO_BLOCK)


def _viterbi(cost: np.ndarray, offsets: np.ndarray, start: int, end: int) -> np.ndarray:
    """Cheapest offset index per interval, entering from `start` and leaving into `end` (offsets)."""
    n, m = cost.shape
    change = CHANGE * (offsets[:, None] != offsets[None, :])
    total = cost[0] + CHANGE * (offsets != start)
    back = np.zeros((n, m), dtype=np.int64)
    for k in range(1, n):
        step = total[None, :] + change                    # [to, from]
        back[k] = step.argmin(axis=1)
        total = cost[k] + step.min(axis=1)
    path = [int(np.argmin(total + CHANGE * (offsets != end)))]
    for k in range(n - 1, 0, -1):
        path.append(int(back[k][path[-1]]))
    return np.asarray(path[::-1])


def _change(o1: int, o2: int, between: list[int]) -> dict:
    """An offset change from o1 to o2 somewhere between two recorded lines: o2 - o1 recorded lines (when
    positive) that the program does not have, or o1 - o2 program lines that did not run."""
    return {"from_offset": o1, "to_offset": o2, "between_recorded_lines": between,
            "recorded_without_counterpart": max(o2 - o1, 0), "program_without_counterpart": max(o1 - o2, 0)}


def stretch_offsets(lines: np.ndarray, t_start_s: np.ndarray, still_s: np.ndarray, expected: pd.Series,
                    first: int, last: int, before: int, after: int) -> tuple[list[int | None], list[dict], list[dict]]:
    """Offsets of runs first .. last-1 (None where not established), the stretches and the changes.

    `lines`, `t_start_s`, `still_s`: every run's recorded line, start and standstill seconds (events);
    `before`: the offset of the runs before `first` (the first mismatch); `after`: the anchor's, the
    offset of run `last` on."""
    lines = np.asarray(lines, dtype=np.int64)
    n = last - first
    if n < 2 or last >= len(lines):
        return [None] * max(n, 0), [], []
    lo, hi = min(before, after) - MARGIN, max(before, after) + MARGIN
    offsets = np.arange(lo, hi + 1, dtype=np.int64)
    k = np.arange(first, last)                                            # interval k: run k -> k + 1
    measured = np.maximum(t_start_s[k + 1] - t_start_s[k] - still_s[k], 0.0)
    cost = _costs(lines[first:last + 1], measured, expected, offsets)
    path = _viterbi(cost, offsets, before, after)
    cum = np.vstack([np.zeros((1, len(offsets))), np.cumsum(cost, axis=0)])   # cum[a]: intervals before a
    bounds = [0] + [a for a in range(1, n) if path[a] != path[a - 1]] + [n]
    # how far each change may move: between the stretches either side, the change points within AMBIGUOUS
    unsure = np.zeros(n, dtype=bool)
    for q in range(1, len(bounds) - 1):
        a0, a, a1 = bounds[q - 1], bounds[q], bounds[q + 1]
        j1, j2 = path[a - 1], path[a]
        p = np.arange(a0 + 1, a1)
        c = (cum[p, j1] - cum[a0, j1]) + (cum[a1, j2] - cum[p, j2])
        fits = p[c <= c.min() + AMBIGUOUS]
        # the lines inserted (or the ones whose counterparts were removed) lie next to the change: the
        # runs within that many recorded lines of where it may be are no one's either
        d = abs(int(offsets[j2]) - int(offsets[j1]))
        near = lines[first:last]
        unsure |= (near >= lines[first + fits.min()] - d) & (near <= lines[first + fits.max()] + d)
        unsure[fits.min():fits.max()] = True
    out: list[int | None] = [None] * n
    stretches = []
    for a0, a1 in zip(bounds[:-1], bounds[1:]):
        j = path[a0]
        sure = np.flatnonzero(~unsure[a0:a1]) + a0
        if not len(sure):
            continue
        own = cost[sure, j].sum()
        other = np.delete(cost[sure], j, axis=1).sum(axis=0).min() if len(offsets) > 1 else np.inf
        established = bool(other - own >= ESTABLISHED)
        o = int(offsets[j])
        if established:
            for a in sure:
                out[a] = o
        runs = first + sure
        stretches.append({"offset": o, "established": established, "runs": int(len(sure)),
                          "recorded_lines": [int(lines[runs[0]]), int(lines[runs[-1]])],
                          "program_lines": [int(lines[runs[0]] - o), int(lines[runs[-1]] - o)],
                          "seconds": float(t_start_s[runs[-1] + 1] - t_start_s[runs[0]]),
                          "margin": float(other - own)})
    # the changes: between consecutive established stretches (and the offsets either side of the region)
    # whose offsets differ, somewhere between the last run placed before and the first placed after
    known = [(before, first - 1)] + [(o, first + a) for a, o in enumerate(out) if o is not None] + [(after, last)]
    changes = [_change(o1, o2, [int(lines[r1]), int(lines[r2])])
               for (o1, r1), (o2, r2) in zip(known[:-1], known[1:]) if o1 != o2]
    return out, stretches, changes


__all__ = ["stretch_offsets"]
