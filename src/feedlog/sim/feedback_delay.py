"""Feedback delay: the reported axis (joint) position is the command of `delay_s` earlier.

Source: the transport delay of a servo loop's position feedback (encoder sampling, fieldbus cycle;
one servo period in LinuxCNC's simulated machines, whose `pid` pass-through and sample-hold `mux`
put `joint.N.motor-pos-fb` exactly one servo cycle behind `joint.N.motor-pos-cmd`: measured on the
bundled full recordings, docs/diagnose.md). A `feedback` mechanism: the commanded motion and the
cycle time are unchanged. Delays that are not a whole number of samples interpolate linearly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.sim.mechanism import Mechanism


def delayed(pos: np.ndarray, delay_samples: float) -> np.ndarray:
    """`pos` (n, k) delayed by a (fractional) number of samples, held at the first sample before it."""
    pos = np.asarray(pos, dtype=np.float64)
    n = len(pos)
    if delay_samples <= 0 or n == 0:
        return pos.copy()
    whole = int(np.floor(delay_samples))
    frac = delay_samples - whole
    idx = np.arange(n) - whole
    early = np.clip(idx, 0, n - 1)
    earlier = np.clip(idx - 1, 0, n - 1)
    return (1.0 - frac) * pos[early] + frac * pos[earlier]


@dataclass
class FeedbackDelay(Mechanism):
    name = "feedback_delay"
    kind = "feedback"
    order = 10

    delay_s: float = 0.001

    def __post_init__(self) -> None:
        self.check_non_negative(delay_s=self.delay_s)

    def settle_s(self) -> float:
        return self.delay_s

    def feedback(self, dt_s: float, axes: tuple[str, ...], pos: np.ndarray) -> np.ndarray:
        return delayed(pos, self.delay_s / dt_s)
