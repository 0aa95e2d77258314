"""What the recorded programs exercise: moving axes, rapids, reversals, blending, short blocks.

Hypothesis families ask these questions so that they only offer causes the data can speak to.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from feedlog.sim.path import m6_rows
from feedlog.toolpath.schema import AXIS_UNITS

MOVE = 1e-6


def motion_rows(case: Any) -> pd.DataFrame:
    blocks = case.program.blocks
    return blocks[blocks["kind"].astype(str).isin(("rapid", "linear", "arc_cw", "arc_ccw"))]


def axis_delta(case: Any, axis: str) -> np.ndarray:
    rows = motion_rows(case)
    col = f"{axis}_{AXIS_UNITS[axis]}"
    if col not in rows.columns:
        return np.zeros(len(rows))
    d = rows[col].to_numpy(np.float64) - rows[f"{axis}0_{AXIS_UNITS[axis]}"].to_numpy(np.float64)
    return np.nan_to_num(d)


def moves_axis(cases: Sequence[Any], axis: str) -> bool:
    return any((np.abs(axis_delta(c, axis)) > MOVE).any() for c in cases)


def has_kind(cases: Sequence[Any], *kinds: str) -> bool:
    return any(motion_rows(c)["kind"].astype(str).isin(kinds).any() for c in cases)


def has_reversal(cases: Sequence[Any], axes: Sequence[str]) -> bool:
    """Some axis changes direction between consecutive moves that move it."""
    for case in cases:
        for axis in axes:
            d = axis_delta(case, axis)
            s = np.sign(d[np.abs(d) > 1e-4])
            if len(s) > 1 and (s[1:] * s[:-1] < 0).any():
                return True
    return False


def has_blending(cases: Sequence[Any]) -> bool:
    """Some block runs in continuous mode (G64) with a tolerance."""
    for case in cases:
        rows = motion_rows(case)
        cont = rows["path_mode"].astype(str) == "continuous"
        if cont.any():
            return True
    return False


def feeds(cases: Sequence[Any]) -> np.ndarray:
    """Programmed feeds of the feed moves (mm/min)."""
    out = [motion_rows(c).query("kind != 'rapid'")["feed_mm_min"].to_numpy(np.float64) for c in cases]
    values = np.concatenate(out) if out else np.zeros(0)
    return values[np.isfinite(values) & (values > 0)]


def short_block_share(cases: Sequence[Any], servo_period_s: float) -> float:
    """Share of feed moves that last under 20 servo periods at their programmed feed."""
    total = short = 0
    for case in cases:
        rows = motion_rows(case).query("kind != 'rapid'")
        length = rows["length_mm"].to_numpy(np.float64)
        feed = rows["feed_mm_min"].to_numpy(np.float64) / 60.0
        ok = np.isfinite(length) & np.isfinite(feed) & (feed > 0) & (length > 0)
        total += int(ok.sum())
        short += int((length[ok] / feed[ok] < 20 * servo_period_s).sum())
    return short / total if total else 0.0


def tool_changes(cases: Sequence[Any]) -> int:
    """Tool changes (M6) between two moves in the recorded programs: the ones a cycle pays for."""
    total = 0
    for case in cases:
        blocks = case.program.blocks
        moving = np.flatnonzero(blocks["kind"].astype(str).isin(("rapid", "linear", "arc_cw", "arc_ccw")).to_numpy())
        if len(moving):
            m6 = m6_rows(blocks)
            total += int(((m6 > moving[0]) & (m6 < moving[-1])).sum())
    return total
