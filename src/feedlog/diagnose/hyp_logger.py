"""Logger latency: the line stream lags (or leads) the positions by a constant time.

Predicts every block change in the line stream shifted by the same time against where the positions
show the block ending, whatever the block; the motion itself and the cycle time are unchanged. Judged
on recordings that carry both a line stream and positions.
"""

from __future__ import annotations

from feedlog.diagnose import keys
from feedlog.diagnose.hypothesis import Hypothesis


def candidates(profile, cases) -> list[Hypothesis]:
    if not any(c.line_offsets is not None for c in cases):
        return []
    on = keys.enabled(profile, "logger_latency")
    return [Hypothesis(key="sim.logger_latency.line_s", family="logger", lower=-0.5, upper=2.0, scale="linear",
                       level="line", baseline=keys.value(profile, "sim.logger_latency.line_s") if on else None,
                       switches_on=not on,
                       predicts="every block change of the line stream late (or early) by the same time against "
                                "the positions; motion and cycle time unchanged")]
