"""Per-axis following lag: each axis' feedback trails its command like a first-order servo loop.

Source: a P position loop with velocity feed-forward gain k_ff has the steady following error
e = (1 - k_ff) v / K_v (Altintas, Manufacturing Automation, ch. 4); the axis position is the
command through a first-order lag of time constant T = 1 / K_v. Implemented as the exact
discretisation (scipy.signal.lfilter) of x' = (u - x) / T on the sampling grid, per axis, the form
of LinuxCNC's `lowpass` HAL component (gain = 1 - exp(-dt / T)). `lag_s` = 0 leaves an axis
unchanged. A `feedback` mechanism: it changes the feedback positions (`SimResult.feedback`, the
recorded `joints.jN_pos_fb`), never the commanded motion, so the cycle time is unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from feedlog.sim.mechanism import Mechanism


@dataclass
class FollowingLag(Mechanism):
    name = "following_lag"
    kind = "feedback"
    order = 20  # after the feedback delay

    lag_s: dict[str, float] = field(default_factory=lambda: {"x": 0.01, "y": 0.01, "z": 0.01})

    def __post_init__(self) -> None:
        for axis, value in self.lag_s.items():
            if not (isinstance(value, (int, float)) and value >= 0):
                raise ValueError(f"lag_s[{axis!r}] must be a number >= 0, got {value!r}")

    def settle_s(self) -> float:
        return 10.0 * max(self.lag_s.values(), default=0.0)

    def feedback(self, dt_s: float, axes: tuple[str, ...], pos: np.ndarray) -> np.ndarray:
        from scipy.signal import lfilter  # scipy.signal imports slowly

        pos = np.array(pos, dtype=np.float64, order="F")
        for i, axis in enumerate(axes):
            tau = float(self.lag_s.get(axis, 0.0))
            if tau <= 0 or not len(pos):
                continue
            alpha = 1.0 - np.exp(-dt_s / tau)
            x0 = pos[0, i]
            out, _ = lfilter([alpha], [1.0, alpha - 1.0], pos[:, i] - x0, zi=[0.0])
            pos[:, i] = out + x0
        return pos
