"""Absolute positions of every row of a part program, vectorised: a forward fill of absolute axis
words, a cumulative sum of incremental ones, and the work offsets (G10 L2/L20, G54..G59.3, G92) that turn
machine positions into program coordinates (toolpath.offsets resolves the offset events)."""

from __future__ import annotations

import numpy as np

from feedlog.toolpath.offsets import SYSTEM_OF, AxisWords, Event, resolve_offsets

AXIS_LETTERS = "XYZABC"

def ffill(values: np.ndarray, present: np.ndarray, initial) -> np.ndarray:
    """Forward-fill `values` from rows where `present`; `initial` before the first one."""
    at = np.flatnonzero(present)
    held = np.r_[np.asarray(initial, dtype=np.result_type(values, np.asarray(initial))), values[at]]
    return np.repeat(held, np.diff(np.r_[0, at, len(values)]))


def positions(W: np.ndarray, has: np.ndarray, S: dict, unit: np.ndarray, is_motion: np.ndarray,
               incremental: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (6, n) of every row, absolute program coordinates, all offsets 0: a forward fill
    of absolute words, plus a cumulative sum of incremental ones."""
    n = W.shape[1]
    any_incremental = bool(incremental.any())
    end = np.zeros((6, n))  # axis-major while computing: contiguous rows
    for j, ch in enumerate(AXIS_LETTERS):
        if not has[S[ch]].any():
            continue
        v = W[S[ch]] * unit if j < 3 else W[S[ch]]
        set_here = has[S[ch]] & is_motion
        if not any_incremental:
            end[j] = ffill(v, set_here, 0.0)
            continue
        delta = np.where(set_here & incremental, v, 0.0)
        cs = np.cumsum(delta)
        absolute = set_here & ~incremental
        end[j] = cs + ffill(np.where(absolute, v - cs, 0.0), absolute, 0.0)
    start = np.zeros((6, n))
    start[:, 1:] = end[:, :-1]
    return start, end


SYSTEM_LUT = np.zeros(1000, dtype=np.int8)
for _g, _s in SYSTEM_OF.items():
    SYSTEM_LUT[_g] = _s


def offset_positions(W: np.ndarray, has: np.ndarray, S: dict, unit: np.ndarray, is_motion: np.ndarray,
                      incremental: np.ndarray, coords: np.ndarray, nonmodal: np.ndarray,
                      offset_row: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Start, end (program coordinates), work offset (6, n) and coordinate system per row, for programs
    with G10/G92: machine position = forward fill of (absolute word + the row's offset) plus the
    incremental moves; program position = machine - offset (toolpath.offsets)."""
    n = W.shape[1]
    values = np.full((6, n), np.nan)
    absolute = np.zeros((6, n), dtype=bool)
    cs = np.zeros((6, n))
    scale = np.vstack([np.broadcast_to(unit, (3, n)), np.ones((3, n))])
    for j, ch in enumerate(AXIS_LETTERS):
        if not has[S[ch]].any():
            continue
        v = W[S[ch]] * scale[j]
        set_here = has[S[ch]] & is_motion
        absolute[j] = set_here & ~incremental
        values[j] = np.where(absolute[j], v, np.nan)
        cs[j] = np.cumsum(np.where(set_here & incremental, v, 0.0))
    selected = ffill(coords, coords >= 0, 540)
    switch = (coords >= 0) & (selected != np.r_[540, selected[:-1]])  # re-selecting the active one is no event
    ev_rows = np.flatnonzero(switch | offset_row)
    given = W[[S[c] for c in AXIS_LETTERS]][:, ev_rows] * scale[:, ev_rows]
    lw, pw = W[S["L"], ev_rows], W[S["P"], ev_rows]
    events = [Event(row=int(r), system=int(SYSTEM_LUT[coords[r]]) if switch[r] else 0,
                    code=int(nonmodal[r]) if offset_row[r] else -1,
                    l_word=int(lw[i]) if not np.isnan(lw[i]) else 0,
                    p_word=int(pw[i]) if not np.isnan(pw[i]) else 0,
                    values=given[:, i])
              for i, r in enumerate(ev_rows.tolist())]
    work, system = resolve_offsets(n, AxisWords(values=values, absolute=absolute, cumsum=cs), events)
    machine = cs.copy()
    for j in range(6):
        if absolute[j].any():
            machine[j] += ffill(np.where(absolute[j], values[j] + work[j] - cs[j], 0.0), absolute[j], 0.0)
    end = machine - work
    start = np.zeros((6, n))
    start[:, 1:] = machine[:, :-1]
    start -= work
    return start, end, work, system
