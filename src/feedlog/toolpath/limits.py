"""The ranges a part program must stay in: numbers, positions, run time and the machine's axes.

A G-code number is a decimal of any length, so `X` followed by 320 nines overflows float64, `F1e-12`
makes one block last 20 000 years and a G91 move repeated a few times runs past float64. None of
that is a program a machine ran: each is refused with the file, line and word, before it can turn
into inf, NaN or an int64 nanosecond count that wraps. The bounds are far beyond any machine
(1e9 mm is 1000 km; 1e9 s is 31.7 years) and keep every sum of lengths and times finite and every
time exact in int64 nanoseconds.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd

from feedlog.errors import ProgramError
from feedlog.toolpath.schema import AXES, AXIS_UNITS, MOTION_KINDS
from feedlog.units import MAX_TIME_S

MAX_WORD = 1e9           # |value| of any word (mm, inch, deg, s, mm/min, rpm, turns, line number)
MAX_POSITION = 1e9       # |coordinate| in mm or deg, after units, offsets and incremental sums
MAX_ARC_TURNS = 32767    # arc P: what the block table's int16 `turns` column holds


def sci(x: float) -> str:
    """1e9, not 1e+09."""
    return f"{x:.0e}".replace("e+0", "e").replace("e+", "e")


def out_of_range(values: np.ndarray, bound: float) -> np.ndarray:
    """True where a value is inf or beyond +-bound (NaN, an absent word, is not out of range)."""
    with np.errstate(invalid="ignore"):
        return np.abs(values) > bound


def check_positions(start: np.ndarray, end: np.ndarray, rows: np.ndarray,
                    fail: Callable[[int, str, str], ProgramError]) -> None:
    """Start and end positions (6, n) of the `rows` that move must stay within MAX_POSITION."""
    bad = (out_of_range(end, MAX_POSITION) | out_of_range(start, MAX_POSITION)).any(axis=0) & rows
    if bad.any():
        r = int(np.flatnonzero(bad)[0])
        j = int(np.flatnonzero(out_of_range(end[:, r], MAX_POSITION) | out_of_range(start[:, r], MAX_POSITION))[0])
        axis = AXES[j]
        value = end[j, r] if out_of_range(end[j:j + 1, r], MAX_POSITION).any() else start[j, r]
        raise fail(r, f"position {axis.upper()} {value:.4g} {AXIS_UNITS[axis]} is out of range (beyond "
                      f"+-{sci(MAX_POSITION)}: a typo, or incremental moves summed too far)", axis.upper())


def check_run_time(seconds: np.ndarray, fail: Callable[[int, str, str], ProgramError], *, what: str,
                   code: Callable[[int], str], before: float = 0.0) -> float:
    """The running sum of per-row times (NaN: no time), after `before` seconds of earlier rows, must stay
    within MAX_TIME_S. Returns the sum after the last row."""
    finite = np.nan_to_num(np.asarray(seconds, dtype=np.float64), nan=0.0, posinf=np.inf)
    total = np.cumsum(np.r_[before, finite])[1:] if before else np.cumsum(finite)
    if len(total) and not total[-1] <= MAX_TIME_S:
        r = int(np.flatnonzero(~(total <= MAX_TIME_S))[0])
        raise fail(r, f"the program would run longer than {sci(MAX_TIME_S)} s (31.7 years) by this block, "
                      f"which alone takes {finite[r]:.3g} s ({what})", code(r))
    return float(total[-1]) if len(total) else float(before)


def check_axes(table: pd.DataFrame, axes: tuple[str, ...], profile_name: str, rows: np.ndarray | None = None) -> None:
    """No row of the block table may move an axis the machine does not have (`axes`)."""
    moving = table["kind"].isin(MOTION_KINDS).to_numpy()
    if rows is not None:
        moving &= rows
    for axis in AXES:
        end, start = f"{axis}_{AXIS_UNITS[axis]}", f"{axis}0_{AXIS_UNITS[axis]}"
        if axis in axes or end not in table.columns:
            continue
        e = table[end].to_numpy(dtype=np.float64, na_value=np.nan)
        s = table[start].to_numpy(dtype=np.float64, na_value=np.nan) if start in table.columns else np.full(len(e), np.nan)
        with np.errstate(invalid="ignore"):  # an unknown start (NaN) is no motion
            moved = moving & (np.abs(e - s) > 1e-9)
        if moved.any():
            r = int(np.flatnonzero(moved)[0])
            file = str(table["file"].iloc[r]) if "file" in table.columns else None
            raise ProgramError(f"the program moves axis {axis.upper()}, which machine profile {profile_name!r} "
                               f"does not have (axes: {', '.join(axes)}); give --profile a machine with it",
                               file=file, line=int(table["line"].iloc[r]), code=axis.upper())
