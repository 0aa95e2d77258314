"""Motion start and end between sparse samples, from a model of the motion (e.g. feedlog.sim).

At 5 Hz the first sample after motion start may lie up to 200 ms after it: counting whole intervals
would miss the cycle time by up to two periods. The measured positions say *where* the tool was at the
first sample after the start (and at the last sample before the end); a model trajectory of the same
program (an NC interpolator simulation on the machine's profile) says how long the tool needs from
the program start to that place (and from there to the end). Only this local time is taken from the
model; everything else stays measured. The model sample matching a measured position is the nearest
one among the model's first (last) `search_s` of motion, so that a later pass over the same place is
never taken for the start. Positions are compared on every recorded axis, rotary ones included (mm and
deg as they are): a five-axis program may start with a rotary-only move (G0 A-20), during which x/y/z
stand still and only the rotary axes say how far the move has come.
"""

from __future__ import annotations

import numpy as np

from feedlog.align.blocks import MotionSpan


def _moving_range(pos: np.ndarray, still_mm: float) -> tuple[int, int]:
    step = np.abs(np.diff(pos, axis=0)).max(axis=1)
    moving = np.flatnonzero(step > still_mm)
    return int(moving[0]), int(moving[-1]) + 1


def refine_span(span: MotionSpan, t_ns: np.ndarray, positions: np.ndarray, model_t_ns: np.ndarray,
                model_positions: np.ndarray, *, still_mm: float = 1e-6, search_s: float | None = None) -> MotionSpan:
    """`span` with start and end moved inside their sampling intervals by the model's local timing.

    `positions` and `model_positions` are (n, k) with the same k axes in the same frame and order (x/y/z,
    then any rotary axes); `search_s` defaults to twice the sampling interval at each end.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    p = np.asarray(positions, dtype=np.float64)
    mt = np.asarray(model_t_ns, dtype=np.int64)
    mp = np.asarray(model_positions, dtype=np.float64)
    if p.ndim != 2 or mp.ndim != 2 or p.shape[1] != mp.shape[1]:
        raise ValueError(f"positions {p.shape} and model positions {mp.shape} need the same axes")
    if len(mt) < 2 or len(t) < 3:
        return span
    m0, m1 = _moving_range(mp, still_mm)
    i0, i1 = span.first_index, span.last_index  # last at rest before, first at rest after
    start, end = span.t_start_ns, span.t_end_ns
    # start: the first sample after motion began
    j = i0 + 1
    if j < len(t):
        dt = t[j] - t[i0]
        window = int((search_s * 1e9) if search_s else 2 * dt)
        cand = np.flatnonzero((mt >= mt[m0]) & (mt <= mt[m0] + window))
        if len(cand):
            k = cand[np.argmin(np.linalg.norm(mp[cand] - p[j], axis=1))]
            tau = int(mt[k] - mt[m0])
            start = int(t[j] - min(max(tau, 0), dt))
    # end: the last sample before motion ended
    j = i1 - 1
    if j >= 0 and i1 < len(t):
        dt = t[i1] - t[j]
        window = int((search_s * 1e9) if search_s else 2 * dt)
        cand = np.flatnonzero((mt <= mt[m1]) & (mt >= mt[m1] - window))
        if len(cand):
            k = cand[np.argmin(np.linalg.norm(mp[cand] - p[j], axis=1))]
            tau = int(mt[m1] - mt[k])
            end = int(t[j] + min(max(tau, 0), dt))
    return MotionSpan(t_start_ns=start, t_end_ns=end, first_index=i0, last_index=i1)
