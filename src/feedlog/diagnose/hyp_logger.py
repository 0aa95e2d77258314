"""Logger latency: the line stream lags (or leads) the positions by a constant time.

Predicts every block change in the line stream shifted by the same time against where the positions
show the block ending, whatever the block; the motion itself and the cycle time are unchanged. Judged
on recordings that carry both a line stream and positions.
"""

from __future__ import annotations

from feedlog.diagnose import keys
from feedlog.diagnose.hypothesis import Family, Hypothesis


def _candidates(profile, cases) -> list[Hypothesis]:
    if not any(c.line_offsets is not None for c in cases):
        return []
    on = keys.enabled(profile, "logger_latency")
    return [Hypothesis(key="sim.logger_latency.line_s", family="logger", lower=-0.5, upper=2.0, scale="linear",
                       level="line", baseline=keys.value(profile, "sim.logger_latency.line_s") if on else None,
                       switches_on=not on,
                       predicts="every block change of the line stream late (or early) by the same time against "
                                "the positions; motion and cycle time unchanged")]


class Logger(Family):
    name = "logger"
    rank = 6

    def candidates(self, profile, cases) -> list[Hypothesis]:
        return _candidates(profile, cases)

    def describe(self, ev, key, fitted=None) -> str:
        return ""  # the evidence gathered without a simulation holds nothing on the line stream's latency

    def suggest(self, ev, key, baseline) -> tuple[float, ...]:
        return ()

    def contradicts(self, ev, key, profile_value, fitted) -> str | None:
        return None


FAMILY = Logger()
