"""Tool change time: the machine stands still `time_s` for every M6 between two moves.

A tool change is no motion the interpolator plans, but it is part of the cycle: the spindle stops, the
changer swaps the tool, the spindle starts again (on the NIST Hurco VMX the line stream stays 6.9 s on
`T21M6`; docs/diagnose.md). The simulation adds `time_s` per M6 as a standstill after the last move
before it (that move stops exactly). An M6 before the program's first move is not counted: the cycle
starts at the first move. Off unless a profile switches it on (`[sim.tool_change] enabled = true`,
`time_s = ...`);
`feedlog diagnose` fits it from a recording's line stream (diagnose.line_level).

Source: the tool-change time is a machine-tool datasheet figure (chip-to-chip time, typically 1.5-10 s
on vertical machining centres); measured here on the NIST test bed's recording (docs/diagnose.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.sim.mechanism import Mechanism


@dataclass
class ToolChangeTime(Mechanism):
    name = "tool_change"
    kind = "limits"
    order = 60
    windowed = True

    time_s: float = 5.0

    def __post_init__(self) -> None:
        self.check_non_negative(time_s=self.time_s)

    def limit(self, ctx) -> None:
        b = ctx.blocks
        changes = b.extra.get("tool_changes")
        if changes is None:
            return
        rows = np.flatnonzero(changes > 0)
        b.stop_after[rows] = True
        b.hold_s[rows] += self.time_s * changes[rows]
        if ctx.window is None:
            ctx.notes["tool_changes"] = int(changes[rows].sum())
