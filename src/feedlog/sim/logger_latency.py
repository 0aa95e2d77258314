"""Logger latency: the executing program line reaches the logger later than the positions do.

Source: monitoring boxes and fieldbus loggers read the controller's channels on different paths
(positions from the drives or the servo trace, the block number from the NC's status), so one
channel lags another by a constant time. A `measurement` mechanism: it changes nothing the machine
does; the measurement model (`feedlog.sim.measurement`) shows the `line` stream `line_s` late, and
`feedlog diagnose` compares the line stream's block changes with the blocks' ends seen in the
positions.
"""

from __future__ import annotations

from dataclasses import dataclass

from feedlog.sim.mechanism import Mechanism


@dataclass
class LoggerLatency(Mechanism):
    name = "logger_latency"
    kind = "measurement"
    signed_times = ("line_s",)

    line_s: float = 0.0   # the line stream lags the positions by this (negative: it leads them)

    def __post_init__(self) -> None:
        if not -1.0 <= self.line_s <= 10.0:
            raise ValueError(f"line_s must be within -1 .. 10 s, got {self.line_s}")
