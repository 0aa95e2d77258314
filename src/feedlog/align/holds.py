"""Feed holds in a recording with positions: where the tool stood still and the program did not ask it to.

A *still stretch* is a run of position samples whose position a window `window_s` later is within
`still_mm` (align's rest threshold: the noise at rest) of its own, lasting at least MIN_STILL_S
(`session_events`): the run of window starts plus the window is the stretch, so its bounds are good to a
sampling period, not to a speed window. Only stretches inside the motion span count.

Each stretch is placed on the program by the measured block times (`Alignment.blocks`): the blocks whose
measured time overlaps it, and the blocks the alignment gave no time between the last one ending before
it and the first one starting after it. When one of those asks the machine to wait (a dwell `G4`, a tool
change `M6`, a program or optional stop `M0`/`M1`, spindle or coolant M codes `M3`-`M9`) the stretch is
that event (`session_events.KINDS`, named as there) and stays in the comparison: the simulation models
dwells and tool changes, and a wait on M codes is the machine's own time. Otherwise the machine stood
where the program asks for motion: a `feed hold` (an operator's pause, an unprogrammed wait), which a
comparison of measured with simulated time takes out (`hold_free`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from feedlog.align.session_events import KINDS, MIN_STILL_S, WAIT_CODES, line_codes
from feedlog.toolpath import Program

WINDOW_S = 0.05          # the position a window this long later is compared (motion shows as a step)
HOLD = "feed hold"
COLUMNS = ["kind", "block", "line", "t_start_ns", "t_end_ns", "duration_s", "removed"]


def still_stretches(t_ns: np.ndarray, pos: np.ndarray, still_mm: float, *, min_s: float = MIN_STILL_S,
                    window_s: float = WINDOW_S) -> list[tuple[int, int]]:
    """(start, end) sample indices (end inclusive) of the runs where the positions stay within `still_mm`
    over every `window_s` and that last at least `min_s`."""
    n = len(t_ns)
    if n < 3:
        return []
    later = np.minimum(np.searchsorted(t_ns, t_ns + int(window_s * 1e9), side="left"), n - 1)
    ok = np.isfinite(pos).all(axis=1)
    step = np.linalg.norm(pos[later] - pos, axis=1)
    still = ok & ok[later] & (later > np.arange(n)) & (step <= still_mm)
    edges = np.flatnonzero(np.diff(np.r_[0, still.astype(np.int8), 0]))
    out = []
    for a, b in zip(edges[::2], edges[1::2]):           # window starts a .. b-1 are still
        end = int(later[b - 1])
        if (t_ns[end] - t_ns[a]) >= min_s * 1e9:
            out.append((int(a), end))
    return out


def _kind(program_rows: pd.DataFrame, info: pd.DataFrame) -> str:
    """What the program asks on these rows that makes the machine wait, else a feed hold."""
    codes: set[int] = set()
    dwell = False
    for ln in program_rows["line"].to_numpy(np.int64):
        if int(ln) in info.index:
            codes |= set(info.at[int(ln), "codes"])
            dwell |= bool(info.at[int(ln), "dwell"])
    kind = next((KINDS[c] for c in (6, 0, 1) if c in codes), None)
    if kind is not None:
        return kind
    if dwell:
        return "dwell"
    return "wait on M codes" if codes & WAIT_CODES else HOLD


def find_holds(axes: pd.DataFrame, blocks: pd.DataFrame, program: Program, *, span_ns: tuple[int, int],
               still_mm: float, min_s: float = MIN_STILL_S) -> pd.DataFrame:
    """Still stretches inside `span_ns`, each with its kind, the block and program line it stood on, its
    bounds and duration, and `removed` (a feed hold: out of the motion comparison). `axes`: t_ns and
    x_mm/y_mm/z_mm; `blocks`: align's block table (block, line, t_start_ns, t_end_ns)."""
    cols = [c for c in ("x_mm", "y_mm", "z_mm") if c in axes.columns]
    t = axes["t_ns"].to_numpy(np.int64)
    inside = (t >= span_ns[0]) & (t <= span_ns[1])
    t, pos = t[inside], axes[cols].to_numpy(np.float64)[inside]
    runs = still_stretches(t, pos, max(float(still_mm), 1e-6), min_s=min_s)
    if not runs or not len(blocks):
        return pd.DataFrame([], columns=COLUMNS)
    info = line_codes(program)
    rows_of = program.blocks.set_index("block") if "block" in program.blocks.columns else program.blocks
    b_id = blocks["block"].to_numpy(np.int64)
    b_start, b_end = blocks["t_start_ns"].to_numpy(np.int64), blocks["t_end_ns"].to_numpy(np.int64)
    out = []
    for a, e in runs:
        t0, t1 = int(t[a]), int(t[e])
        mid = (t0 + t1) // 2
        over = np.flatnonzero((b_start < t1) & (b_end > t0))
        before = np.flatnonzero(b_end <= t0 + (t1 - t0) // 4)
        after = np.flatnonzero(b_start >= t1 - (t1 - t0) // 4)
        lo = int(b_id[before[-1]]) if len(before) else int(b_id.min())
        hi = int(b_id[after[0]]) if len(after) else int(b_id.max())
        ids = set(range(lo, hi + 1)) | set(b_id[over].tolist())
        here = rows_of.loc[rows_of.index.intersection(sorted(ids))]
        kind = _kind(here, info)
        at = np.flatnonzero((b_start <= mid) & (b_end > mid))
        k = int(at[0]) if len(at) else (int(over[0]) if len(over) else (int(before[-1]) if len(before) else 0))
        out.append({"kind": kind, "block": int(b_id[k]), "line": int(blocks["line"].iloc[k]), "t_start_ns": t0,
                    "t_end_ns": t1, "duration_s": (t1 - t0) / 1e9, "removed": kind == HOLD})
    return pd.DataFrame(out, columns=COLUMNS)


def hold_free(t_s: np.ndarray | float, removed_s: list[tuple[float, float]]) -> np.ndarray:
    """Times (s from motion start) with the removed stretches (start, end; same clock) taken out: a time
    inside one maps to its start, a time after it moves earlier by its duration."""
    t = np.asarray(t_s, dtype=np.float64)
    out = t.copy()
    for a, b in removed_s:
        out = out - np.clip(t - a, 0.0, b - a)
    return out


__all__ = ["HOLD", "find_holds", "hold_free", "still_stretches"]
