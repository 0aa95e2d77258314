"""Tool change time: the machine stands still for the same time at every M6 between two moves.

The simulation's `tool_change` mechanism (sim/tool_change.py) adds that standstill; a profile without it
predicts none, so a recorded cycle with tool changes is long by their time, all of it at the M6 lines.
Offered only where the recorded programs change tools between moves.
"""

from __future__ import annotations

from feedlog.diagnose import keys
from feedlog.diagnose.hypothesis import Family, Hypothesis
from feedlog.diagnose.programs import tool_changes

KEY = "sim.tool_change.time_s"


class ToolChange(Family):
    name = "tool_change"
    rank = 8

    def candidates(self, profile, cases) -> list[Hypothesis]:
        n = tool_changes(cases)
        if not n:
            return []
        on = keys.enabled(profile, "tool_change")
        return [Hypothesis(key=KEY, family=self.name, lower=0.05, upper=60.0,
                           baseline=keys.value(profile, KEY) if on else None, switches_on=not on,
                           predicts=f"the same standstill at each of the {n} tool changes (M6) between moves; "
                                    "none elsewhere")]

    def describe(self, ev, key, fitted=None) -> str:
        return f"{ev.stops} stops inside the motion" if key == KEY else ""

    def suggest(self, ev, key, baseline) -> tuple[float, ...]:
        return ()

    def contradicts(self, ev, key, profile_value, fitted) -> str | None:
        return None


FAMILY = ToolChange()
