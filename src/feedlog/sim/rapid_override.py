"""Rapid override: the rapid-traverse dial scales G0 speed (typically 0-100 %).

Source: LinuxCNC `halui.rapid-override` / Fanuc ROV; the rapid speed is the axis maximum (or the
profile's `rapid_mm_min`) times the override; the path velocity cap applies after the dial, as
LinuxCNC's TRAJ limit does (tp.c caps `reqvel * scale`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.sim.mechanism import Mechanism, check_override
from feedlog.sim.path import KIND_RAPID


@dataclass
class RapidOverride(Mechanism):
    name = "rapid_override"
    kind = "limits"
    order = 10
    windowed = True

    override: float = 1.0  # 1.0 = 100 %

    def __post_init__(self) -> None:
        check_override(self.name, self.override)

    def limit(self, ctx) -> None:
        b = ctx.blocks
        rapid = b.kind == KIND_RAPID
        b.feed = np.where(rapid, np.minimum(b.feed, b.v_axis) * self.override, b.feed)
