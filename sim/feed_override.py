"""Feed override: the operator's feed-rate dial scales every programmed feed (not rapids).

Source: RS274/NGC and LinuxCNC feed override (`halui.feed-override`, MAX_FEED_OVERRIDE); ISO 6983
controllers alike. Axis limits still cap the resulting feed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.errors import SimulationError
from feedlog.sim.mechanism import MAX_OVERRIDE, MIN_OVERRIDE, Mechanism
from feedlog.sim.path import KIND_RAPID


@dataclass
class FeedOverride(Mechanism):
    name = "feed_override"
    kind = "limits"
    order = 10

    override: float = 1.0  # 1.0 = 100 %

    def __post_init__(self) -> None:
        if not MIN_OVERRIDE <= self.override <= MAX_OVERRIDE:
            raise SimulationError(f"mechanism {self.name!r}: override must be from {MIN_OVERRIDE:g} to "
                                  f"{MAX_OVERRIDE:g} (0.1 % to 1000 %), got {self.override}")

    def limit(self, ctx) -> None:
        b = ctx.blocks
        b.feed = np.where(b.kind != KIND_RAPID, b.feed * self.override, b.feed)
