"""Dwell at axis direction reversal: the motion pauses where an axis changes direction.

Source: backlash and friction compensation in servo drives (quadrant glitches; e.g. Siemens
"backlash compensation", Heidenhain "reversal spikes"): the controller stops at a reversal and the
drive waits `dwell_s` while compensation is applied. Acts at every block junction where a linear
axis (or, with `include_rotary`, a rotary one) moves in opposite directions on either side.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.sim.mechanism import Mechanism


@dataclass
class ReversalDwell(Mechanism):
    name = "reversal_dwell"
    kind = "limits"
    order = 50
    windowed = True

    dwell_s: float = 0.005
    min_move_mm: float = 1e-4   # moves of an axis shorter than this do not count as a direction
    include_rotary: bool = False

    def __post_init__(self) -> None:
        self.check_non_negative(dwell_s=self.dwell_s, min_move_mm=self.min_move_mm)

    def limit(self, ctx) -> None:
        b = ctx.blocks
        window = ctx.window
        cols = list(range(len(b.axes))) if self.include_rotary else b.linear_index
        delta = (b.p1 - b.p0)[:, cols]
        sign = np.where(np.abs(delta) > self.min_move_mm, np.sign(delta), 0.0)
        moving = np.flatnonzero(b.length > 0)
        if window is None and len(moving) < 2:
            return
        # the direction each axis last moved in before the rows (a window carries it from the one before)
        before = np.asarray(window.mine(self.name).get("last", np.zeros(len(cols))) if window is not None
                            else np.zeros(len(cols)))
        s = np.vstack([before[None, :], sign[moving]])
        # carry the last non-zero direction of each axis forward over blocks that do not move it
        idx = np.where(s != 0, np.arange(len(s))[:, None], -1)
        idx = np.maximum.accumulate(idx, axis=0)
        last = np.where(idx >= 0, np.take_along_axis(s, np.maximum(idx, 0), axis=0), 0.0)
        # a reversal between the carried direction and the first row concerns a row of an earlier window
        flip = ((last[1:-1] * s[2:]) < 0).any(axis=1)
        rows = moving[:-1][flip]
        b.stop_after[rows] = True
        b.hold_s[rows] += self.dwell_s
        if window is None:
            ctx.notes["reversals"] = int(len(rows))
            return
        mark = np.zeros(len(b), bool)
        mark[rows] = True
        b.extra["reversal"] = mark          # counted by the windowed run on the rows it keeps
        first = b.extra["first_block"].copy()
        # a row stops if the next moving row reverses: the last moving row before the rows still
        # pending (with the program's last row, the rows of an open merge chain) waits for them
        before_pending = moving[first[moving] < window.restart()]
        if not window.last and len(before_pending):
            window.pending(self.name, int(first[before_pending[-1]]))
        moving_first = first[moving]
        window.carry(self.name, lambda block: {"last": last[int(np.searchsorted(moving_first, block))]})
