"""Rapid override: the rapid-traverse dial scales G0 speed (typically 0-100 %).

Source: LinuxCNC `halui.rapid-override` / Fanuc ROV. By default (`scale_axis_speed = false`) the rapid
speed is the profile's rapid rate (`rapid_mm_min`, capped by the axis limits) times the dial.

LinuxCNC (`scale_axis_speed = true`, both LinuxCNC profiles) scales something else. Its canon asks a
traverse for the speed its axis limits allow along it (emccanon.cc STRAIGHT_TRAVERSE: `vel` from every
axis' MAX_VELOCITY, no rapid rate); while the executing segment is a traverse the dial is the motion
controller's net feed scale (control.c: `rapid_scale` when `motionType == TRAVERSE`, else
`feed_scale`), which multiplies that request before the TRAJ velocity cap clips it (tp.c
tpGetRealTargetVel: `min(reqvel * scale, max target)`). So a rapid whose axis-limited speed is above
the cap runs faster than the cap times the dial: a 93.4 mm XYZ rapid on the 100 mm/s machine (axis
speed 133.4 mm/s, capped to 100 at 100 %) ran at 66.72 mm/s at 50 % and 33.36 mm/s at 25 %, not 50 and
25. The rapid rate (here the TRAJ cap) applies after the dial. The dial's factor is kept per block
(`feed_scale`, `feedlog.sim.path.feed_scale`) as the feed override's is: the planner sizes a blend arc
between two rapids for their requested speeds and runs it at the request times the dial, as LinuxCNC
does (blend arcs take the traverse type of the segment before them, tp.c tpInitBlendArcFromPrev).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.sim.mechanism import Mechanism, check_override
from feedlog.sim.path import KIND_RAPID, apply_feed_scale


@dataclass
class RapidOverride(Mechanism):
    name = "rapid_override"
    kind = "limits"
    order = 10
    windowed = True

    override: float = 1.0  # 1.0 = 100 %
    scale_axis_speed: bool = False  # LinuxCNC: the dial scales the axis-limited speed, the rapid rate caps after

    def __post_init__(self) -> None:
        check_override(self.name, self.override)

    def limit(self, ctx) -> None:
        b = ctx.blocks
        rapid = b.kind == KIND_RAPID
        if not self.scale_axis_speed:
            b.feed = np.where(rapid, np.minimum(b.feed, b.v_axis) * self.override, b.feed)
            return
        b.feed = np.where(rapid, np.minimum(b.feed, b.v_axis * self.override), b.feed)
        scale = np.where(rapid, self.override, 1.0)
        apply_feed_scale(b, scale)
