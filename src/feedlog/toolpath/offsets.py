"""Work coordinate systems: G10 L2/L20, G54-G59.3 and G92/G92.1, with LinuxCNC's semantics.

Machine position = program position + work offset, per axis, where the work offset of a row is the
active coordinate system's offset (G54 = P1 ... G59.3 = P9) plus the G92 offset. Offsets never move
the machine: a change shifts the program coordinates of the current point instead (LinuxCNC prints the
next move's unprogrammed axes at `machine - new offset`).

- `G10 L2 Pn X..`: offset n on the axes given = the values (absolute; G91 does not apply; program units).
- `G10 L20 Pn X..`: offset n such that the current point has the given program coordinates:
  offset = machine - G92 offset - value.
- `G92 X..`: the G92 offset such that the current point has the given coordinates:
  G92 = machine - coordinate-system offset - value; `G92.1` zeroes it.
- `P0` means the active system. Start state: every offset 0, G54 active (LinuxCNC would start from the
  offsets in its parameter file; programs that rely on them must set them with G10).

The events are few, so they run in a Python loop over event rows; positions between them stay
vectorised. Programs without G10/G92 never come here.
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass

import numpy as np
import pandas as pd

from feedlog.toolpath.schema import END_COLUMNS, OFFSET_COLUMNS, START_COLUMNS

G10, G92, G92_1 = 100, 920, 921  # G code x 10
# G54 ... G59.3 (x 10) -> coordinate system number 1 ... 9
SYSTEM_OF = {540: 1, 550: 2, 560: 3, 570: 4, 580: 5, 590: 6, 591: 7, 592: 8, 593: 9}
WORK_OFFSET_COLUMNS = tuple(c for c in OFFSET_COLUMNS if c != "coord_system")  # wx_mm ... wc_deg


@dataclass
class AxisWords:
    """Per-axis motion words (axis-major, (6, n)): `values` the program value in mm/deg of absolute
    words (NaN elsewhere), `absolute` where they are, `cumsum` the running sum of G91 deltas (continued
    from earlier chunks); `term` and `machine` the position carry of the rows before (toolpath.carry)."""

    values: np.ndarray       # (6, n)
    absolute: np.ndarray     # (6, n) bool: an absolute motion word for the axis on this row
    cumsum: np.ndarray       # (6, n) cumulative incremental deltas
    term: np.ndarray         # (6,) machine - cumsum at the last absolute word before these rows
    machine: np.ndarray      # (6,) machine position before the first row


@dataclass
class Event:
    """One row that changes offsets: selection (`system`, 0 = none) then `code` (G10/G92/G92.1/-1)."""

    row: int
    system: int
    code: int
    l_word: int
    p_word: int
    values: np.ndarray       # (6,) mm/deg, NaN for absent axis words


def resolve_offsets(n: int, words: AxisWords, events: list[Event], state) -> tuple[np.ndarray, np.ndarray]:
    """Work offset per row (6, n) and active coordinate system per row (int8, 1..9), from the events
    in row order. `state` (toolpath.carry.OffsetCarry: table, G92 offset, active system) is the state
    before the first row; it is updated to the state after the last."""
    table, g92 = state.table, state.g92
    initial = state.total.copy()
    initial_system = state.active
    ev_rows: list[int] = []
    ev_total: list[np.ndarray] = []
    ev_system: list[int] = []
    abs_rows = [np.flatnonzero(words.absolute[j]) for j in range(6)]

    def offset_at(row: int) -> np.ndarray:
        k = bisect_right(ev_rows, row) - 1
        return ev_total[k] if k >= 0 else initial

    def machine_before(row: int) -> np.ndarray:
        """Machine position at the start of `row` (the end of row - 1)."""
        if row == 0:
            return words.machine.copy()
        pos = np.zeros(6)
        r = row - 1
        for j in range(6):
            rows_j = abs_rows[j]
            k = np.searchsorted(rows_j, r, side="right") - 1
            if k >= 0:
                la = int(rows_j[k])
                # the machine position as the rows' own: cumsum + (value + offset - cumsum at the absolute row),
                # so a program read in chunks, which starts a chunk from that position, gets the same floats
                pos[j] = words.cumsum[j, r] + (words.values[j, la] + offset_at(la)[j] - words.cumsum[j, la])
            else:
                pos[j] = words.cumsum[j, r] + words.term[j]
        return pos

    for ev in events:
        if ev.system:
            state.active = ev.system
        given = ~np.isnan(ev.values)
        if ev.code == G10:
            target = state.active if ev.p_word == 0 else ev.p_word
            if ev.l_word == 2:
                table[target, given] = ev.values[given]
            else:  # L20: the current point gets the given program coordinates
                here = machine_before(ev.row)
                table[target, given] = (here - g92 - ev.values)[given]
        elif ev.code == G92:
            here = machine_before(ev.row)
            g92[given] = (here - table[state.active] - ev.values)[given]
        elif ev.code == G92_1:
            g92[:] = 0.0
        total = table[state.active] + g92
        if ev_rows and ev_rows[-1] == ev.row:
            ev_total[-1], ev_system[-1] = total, state.active
        else:
            ev_rows.append(ev.row)
            ev_total.append(total)
            ev_system.append(state.active)

    at = np.asarray(ev_rows, dtype=np.int64)
    reps = np.diff(np.r_[0, at, n])
    held = np.vstack([initial[None, :], np.asarray(ev_total).reshape(-1, 6)])
    offsets = np.repeat(held, reps, axis=0).T.copy()
    system = np.repeat(np.r_[initial_system, ev_system].astype(np.int8), reps)
    return offsets, system


def _offsets_of(blocks: pd.DataFrame) -> np.ndarray | None:
    """(n, 6) work offsets of a block table, None when it has no offset columns or all are 0."""
    if not all(c in blocks.columns for c in WORK_OFFSET_COLUMNS):
        return None
    w = blocks[list(WORK_OFFSET_COLUMNS)].to_numpy(dtype=np.float64)
    return w if w.any() else None


def to_machine(blocks) -> pd.DataFrame:
    """A copy of a block table (or a Program's) with start/end positions and arc centres in machine
    coordinates (program + work offset `wx_mm` ... `wc_deg`). Tables without offset columns come back
    unchanged (as a copy); the offset columns themselves are kept."""
    blocks = getattr(blocks, "blocks", blocks)
    out = blocks.copy()
    w = _offsets_of(blocks)
    if w is None:
        return out
    out[list(START_COLUMNS)] = blocks[list(START_COLUMNS)].to_numpy() + w
    out[list(END_COLUMNS)] = blocks[list(END_COLUMNS)].to_numpy() + w
    out[["cx_mm", "cy_mm", "cz_mm"]] = blocks[["cx_mm", "cy_mm", "cz_mm"]].to_numpy() + w[:, :3]
    return out
