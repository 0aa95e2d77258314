"""Per-axis following lag: each axis trails its command like a first-order servo loop.

Source: a P position loop with velocity feed-forward gain k_ff has the steady following error
e = (1 - k_ff) v / K_v (Altintas, Manufacturing Automation, ch. 4); the axis position is the
command through a first-order lag of time constant T = 1 / K_v. Implemented as an exact
discretisation (scipy.signal.lfilter) of x' = (u - x) / T on the interpolation grid, per axis.
`lag_s` = 0 leaves an axis unchanged. Applies to the reported (actual) positions; the commanded
motion and so the cycle time are unchanged, the series gets `settle` lags of standstill appended.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from feedlog.sim.context import hold_end
from feedlog.sim.mechanism import Mechanism


@dataclass
class FollowingLag(Mechanism):
    name = "following_lag"
    kind = "series"

    lag_s: dict[str, float] = field(default_factory=lambda: {"x": 0.01, "y": 0.01, "z": 0.01})

    def __post_init__(self) -> None:
        for axis, value in self.lag_s.items():
            if not value >= 0:
                raise ValueError(f"lag_s[{axis!r}] must be >= 0, got {value}")

    settle: float = 10.0  # standstill appended after the end, in multiples of the largest lag

    def after(self, ctx, trajectory):
        from scipy.signal import lfilter  # noqa: PLC0415 (scipy.signal imports slowly)

        trajectory = hold_end(trajectory, self.settle * max(self.lag_s.values(), default=0.0), ctx.dt_s)
        dt = ctx.dt_s
        lags = [(i, float(self.lag_s.get(axis, 0.0))) for i, axis in enumerate(ctx.blocks.axes)]

        def lag(t, pos, speed, row):
            pos = pos.copy()
            for i, tau in lags:
                if tau <= 0 or not len(pos):
                    continue
                alpha = 1.0 - np.exp(-dt / tau)
                x0 = pos[0, i]
                out, _ = lfilter([alpha], [1.0, alpha - 1.0], pos[:, i] - x0, zi=[0.0])
                pos[:, i] = out + x0
            return t, pos, speed, row

        return trajectory.map(lag)
