"""Absolute positions of every row of a part program, vectorised: a forward fill of absolute axis
words, a cumulative sum of incremental ones, and the work offsets (G10 L2/L20, G54..G59.3, G92) that turn
machine positions into program coordinates (toolpath.offsets resolves the offset events).

A program parsed in chunks (toolpath.stream) continues the running sums from the previous chunk
(`PositionCarry`): the cumulative sum starts at the carried value, so every position is the same
float as when the whole program is parsed at once.
"""

from __future__ import annotations

import numpy as np

from feedlog.toolpath.carry import OffsetCarry, PositionCarry
from feedlog.toolpath.offsets import SYSTEM_OF, AxisWords, Event, resolve_offsets

AXIS_LETTERS = "XYZABC"


def ffill(values: np.ndarray, present: np.ndarray, initial) -> np.ndarray:
    """Forward-fill `values` from rows where `present`; `initial` before the first one."""
    at = np.flatnonzero(present)
    held = np.r_[np.asarray(initial, dtype=np.result_type(values, np.asarray(initial))), values[at]]
    return np.repeat(held, np.diff(np.r_[0, at, len(values)]))


def _cumsum(delta: np.ndarray, initial: float) -> np.ndarray:
    """Running sum of `delta` continuing from `initial` (the same additions as one sum over the program)."""
    if initial == 0.0:
        return np.cumsum(delta)
    return np.cumsum(np.r_[initial, delta])[1:]


def _last(values: np.ndarray, initial: float) -> float:
    return float(values[-1]) if len(values) else float(initial)


def positions(W: np.ndarray, has: np.ndarray, S: dict, unit: np.ndarray, is_motion: np.ndarray,
              incremental: np.ndarray, carry: PositionCarry) -> tuple[np.ndarray, np.ndarray, PositionCarry]:
    """Start and end (6, n) of every row, absolute program coordinates, all offsets 0: a forward fill
    of absolute words, plus a cumulative sum of incremental ones; and the carry after the last row."""
    n = W.shape[1]
    any_incremental = carry.incremental or bool(incremental.any())
    end = np.zeros((6, n))  # axis-major while computing: contiguous rows
    out = PositionCarry(cs=carry.cs.copy(), term=carry.term.copy(), incremental=any_incremental)
    for j, ch in enumerate(AXIS_LETTERS):
        if not has[S[ch]].any():
            end[j] = carry.cs[j] + carry.term[j] if any_incremental else carry.term[j]
            continue
        v = W[S[ch]] * unit if j < 3 else W[S[ch]]
        set_here = has[S[ch]] & is_motion
        if not any_incremental:
            end[j] = ffill(v, set_here, carry.term[j])
            out.term[j] = _last(end[j], carry.term[j])
            continue
        delta = np.where(set_here & incremental, v, 0.0)
        cs = _cumsum(delta, carry.cs[j])
        absolute = set_here & ~incremental
        term = ffill(np.where(absolute, v - cs, 0.0), absolute, carry.term[j])
        end[j] = cs + term
        out.cs[j], out.term[j] = _last(cs, carry.cs[j]), _last(term, carry.term[j])
    start = np.empty((6, n))
    if n:
        start[:, 0] = carry.machine
        start[:, 1:] = end[:, :-1]
        out.machine = end[:, -1].copy()
    else:
        out.machine = carry.machine.copy()
    return start, end, out


SYSTEM_LUT = np.zeros(1000, dtype=np.int8)
for _g, _s in SYSTEM_OF.items():
    SYSTEM_LUT[_g] = _s


def offset_positions(W: np.ndarray, has: np.ndarray, S: dict, unit: np.ndarray, is_motion: np.ndarray,
                     incremental: np.ndarray, coords: np.ndarray, nonmodal: np.ndarray,
                     offset_row: np.ndarray, carry: PositionCarry, offsets: OffsetCarry):
    """Start, end (program coordinates), work offset (6, n), coordinate system per row, and the position
    and offset carries, for programs with G10/G92: machine position = forward fill of (absolute word +
    the row's offset) plus the incremental moves; program position = machine - offset."""
    n = W.shape[1]
    values = np.full((6, n), np.nan)
    absolute = np.zeros((6, n), dtype=bool)
    cs = np.empty((6, n))
    scale = np.vstack([np.broadcast_to(unit, (3, n)), np.ones((3, n))])
    for j, ch in enumerate(AXIS_LETTERS):
        if not has[S[ch]].any():
            cs[j] = carry.cs[j]
            continue
        v = W[S[ch]] * scale[j]
        set_here = has[S[ch]] & is_motion
        absolute[j] = set_here & ~incremental
        values[j] = np.where(absolute[j], v, np.nan)
        cs[j] = _cumsum(np.where(set_here & incremental, v, 0.0), carry.cs[j])
    selected = ffill(coords, coords >= 0, offsets.selected)
    before = np.r_[offsets.selected, selected[:-1]]
    switch = (coords >= 0) & (selected != before)  # re-selecting the active one is no event
    ev_rows = np.flatnonzero(switch | offset_row)
    given = W[[S[c] for c in AXIS_LETTERS]][:, ev_rows] * scale[:, ev_rows]
    lw, pw = W[S["L"], ev_rows], W[S["P"], ev_rows]
    events = [Event(row=int(r), system=int(SYSTEM_LUT[coords[r]]) if switch[r] else 0,
                    code=int(nonmodal[r]) if offset_row[r] else -1,
                    l_word=int(lw[i]) if not np.isnan(lw[i]) else 0,
                    p_word=int(pw[i]) if not np.isnan(pw[i]) else 0,
                    values=given[:, i])
              for i, r in enumerate(ev_rows.tolist())]
    offsets_out = OffsetCarry(table=offsets.table.copy(), g92=offsets.g92.copy(), active=offsets.active,
                              selected=int(selected[-1]) if n else offsets.selected, used=True)
    work, system = resolve_offsets(n, AxisWords(values=values, absolute=absolute, cumsum=cs, term=carry.term,
                                                machine=carry.machine), events, offsets_out)
    machine = cs.copy()
    term_out = carry.term.copy()
    for j in range(6):
        term = ffill(np.where(absolute[j], values[j] + work[j] - cs[j], 0.0), absolute[j], carry.term[j])
        machine[j] += term
        term_out[j] = _last(term, carry.term[j])
    end = machine - work
    start = np.empty((6, n))
    if n:
        start[:, 0] = carry.machine
        start[:, 1:] = machine[:, :-1]
    start -= work
    out = PositionCarry(cs=cs[:, -1].copy() if n else carry.cs.copy(), term=term_out,
                        machine=machine[:, -1].copy() if n else carry.machine.copy(),
                        incremental=carry.incremental or bool(incremental.any()))
    return start, end, work, system, out, offsets_out
