"""Feed override: the operator's feed-rate dial scales every programmed feed (not rapids).

Source: RS274/NGC and LinuxCNC feed override (`halui.feed-override`, MAX_FEED_OVERRIDE); ISO 6983
controllers alike.

What the dial scales is the *requested* speed, which LinuxCNC's canon layer has already capped by the
axis velocity limits (emccanon.cc: `vel = MIN(linearFeedRate, v_max)`, v_max from every axis' limit,
rotary ones included; tp.c: `reqvel * feed_scale`, then the TRAJ velocity cap). So a move an axis
limit slows runs at the override times that limit, not at the limit: measured on LinuxCNC's five-axis
machine at 55 %, a line whose C axis turns at its 60 deg/s limit at 100 % turns at 33 deg/s. The
path velocity cap is applied after the dial (it is a cap, not part of the request).

LinuxCNC scales a programmed arc's (G2/G3) centripetal speed with the dial, as if it were part of
the requested speed; blend arcs keep theirs (a cap). The dial's factor is kept per block
(`feed_scale`, `feedlog.sim.path.feed_scale`) for the planner. Measured on LinuxCNC at 80 %: the
1.25 mm G2/G3 arcs of pocket_f3000_p001 run at 0.8 x their centripetal speed (8.222 s measured,
8.222 s simulated; scaling only the feed gave 0.119 s instead of 0.149 s per arc, 7.955 s), while
corners_f3000_p001's blend arcs run as at 100 % (7.636 s measured, 7.636 s simulated).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.sim.mechanism import Mechanism, check_override
from feedlog.sim.path import KIND_RAPID, apply_feed_scale


@dataclass
class FeedOverride(Mechanism):
    name = "feed_override"
    kind = "limits"
    order = 10
    windowed = True

    override: float = 1.0  # 1.0 = 100 %

    def __post_init__(self) -> None:
        check_override(self.name, self.override)

    def limit(self, ctx) -> None:
        b = ctx.blocks
        feed_moves = b.kind != KIND_RAPID
        scale = np.where(feed_moves, self.override, 1.0)
        b.feed = np.where(feed_moves, np.minimum(b.feed, b.v_axis) * self.override, b.feed)
        apply_feed_scale(b, scale)
