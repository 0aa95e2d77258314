"""Where the controller waits for motion to finish before it goes on: queue synchronisation points.

Some program words are not motion the interpolator can blend through: LinuxCNC's task executes them only
once the motion queue is empty and the machine at rest (emctaskmain.cc `emcTaskCheckPreconditions`
answers WAITING_FOR_MOTION or WAITING_FOR_MOTION_AND_IO). Until then it queues no further move, so the
move before such a word is planned with no successor: it ends at rest and, in G64, keeps its parabolic
end condition and with it half its acceleration (tc.c `tcGetOverallMaxAccel`). On plasmatest
(LinuxCNC's example, 31 M3/M5 between its cuts) this costs each rapid between an M5 and an M3 about
95 ms, 1.3 s in all (docs/sim.md).

The words found here, per row of the block table:
- M codes: M0 M1 M60 (pause, optional stop), M3 M4 M5 M19 (spindle), M6 (tool change), M7 M8 M9
  (coolant), M64 M65 M68 (outputs set "now"), M66 (wait for an input), M100-M199 (user M codes, run as
  system commands). Not M62/M63/M67 (synchronised with motion), M48-M53 (override switches, I/O only),
  M2/M30 (the program's end stops anyway);
- a spindle speed that changes (an S word: SET_SPINDLE_SPEED; an S equal to the one in force is not
  seen in the block table and not counted);
- a work offset that changes (G54-G59.3, G92, G10 on the active system: SET_G5X / SET_G92);
- an operator message comment `(MSG, ...)` or `(DEBUG, ...)` (OPERATOR_DISPLAY).
A tool length offset (G43/G49, SET_OFFSET) is not in the block table and so not counted.
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

from feedlog.toolpath import schema

# M codes LinuxCNC's task runs only with the motion queue empty (see the module text)
SYNC_M_CODES = frozenset({0, 1, 3, 4, 5, 6, 7, 8, 9, 19, 60, 64, 65, 66, 68, *range(100, 200)})
_M_WORD = re.compile(r"(?i)\bM0*(\d+)")
_MESSAGE = re.compile(r"(?i)^\s*(?:MSG|DEBUG)\s*,")


def sync_rows(table: pd.DataFrame) -> np.ndarray:
    """Row positions of the block table whose words make the controller wait for motion to finish
    before it executes them (sorted, unique)."""
    n = len(table)
    sync = np.zeros(n, dtype=bool)
    sync[m_code_rows(table, SYNC_M_CODES)] = True
    if n > 1 and "spindle_rpm" in table.columns:
        rpm = table["spindle_rpm"].to_numpy(np.float64, na_value=np.nan)
        sync[1:] |= _changed(rpm)
    for name in schema.OFFSET_COLUMNS:
        if n > 1 and name in table.columns:
            sync[1:] |= _changed(table[name].to_numpy(np.float64, na_value=np.nan))
    if "comment" in table.columns:
        text = table["comment"].fillna("").astype(str)
        some = np.flatnonzero(text.str.len().to_numpy() > 0)
        if len(some):
            sync[some] |= text.iloc[some].str.contains(_MESSAGE).to_numpy(bool)
    return np.flatnonzero(sync)


def m_code_rows(table: pd.DataFrame, codes) -> np.ndarray:
    """Row positions of the block table holding any of the M `codes` (numbers) among their M words."""
    if "mcodes" not in table.columns:
        return np.zeros(0, dtype=np.int64)
    column = table["mcodes"]
    # most rows carry no M code: look at the others only (a regex over a million empty strings costs 25 ms)
    some = np.flatnonzero(np.asarray(pc.greater(pc.binary_length(pa.array(column, type=pa.string(), from_pandas=True)),
                                                0).fill_null(False), dtype=bool))
    hit = [i for i in some if any(int(m) in codes for m in _M_WORD.findall(str(column.iloc[i])))]
    return np.asarray(hit, dtype=np.int64)


def syncs_after(table: pd.DataFrame, sel: np.ndarray) -> np.ndarray:
    """Per motion/dwell row `sel` (row positions, sorted): how many synchronisation points lie between
    it and the next such row. A word on a motion row itself runs before that row's motion, so it counts
    for the row before; points before the first motion are not counted (nothing to stop)."""
    out = np.zeros(len(sel))
    if not len(sel):
        return out
    row = np.searchsorted(sel, sync_rows(table), side="left") - 1
    np.add.at(out, row[row >= 0], 1.0)
    return out


def _changed(values: np.ndarray) -> np.ndarray:
    """Per row from the second on: the value differs from the row before (NaN to NaN is no change)."""
    prev, cur = values[:-1], values[1:]
    both_nan = np.isnan(prev) & np.isnan(cur)
    return (prev != cur) & ~both_nan
