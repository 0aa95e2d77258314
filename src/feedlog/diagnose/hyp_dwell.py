"""Reversal dwell: the controller stops and waits where an axis reverses (backlash compensation).

Predicts time lost at every junction where an axis changes direction, the same amount each time,
independent of the feed; none elsewhere.
"""

from __future__ import annotations

from feedlog.diagnose import keys
from feedlog.diagnose.hypothesis import Family, Hypothesis
from feedlog.diagnose.programs import has_reversal


def _candidates(profile, cases) -> list[Hypothesis]:
    if not has_reversal(cases, [a for a in profile.axis_names if a in ("x", "y", "z")]):
        return []
    on = keys.enabled(profile, "reversal_dwell")
    return [Hypothesis(key="sim.reversal_dwell.dwell_s", family="dwell", lower=1e-3, upper=1.0,
                       baseline=keys.value(profile, "sim.reversal_dwell.dwell_s") if on else None,
                       switches_on=not on,
                       predicts="the same time lost at every axis reversal, whatever the feed; none elsewhere")]


class Dwell(Family):
    name = "dwell"
    rank = 4

    def candidates(self, profile, cases) -> list[Hypothesis]:
        return _candidates(profile, cases)

    def describe(self, ev, key, fitted=None) -> str:
        return f"{ev.stops} stops inside the motion" if key == "sim.reversal_dwell.dwell_s" else ""

    def suggest(self, ev, key, baseline) -> tuple[float, ...]:
        return ()

    def contradicts(self, ev, key, profile_value, fitted) -> str | None:
        return None


FAMILY = Dwell()
