"""Overrides: the operator's feed and rapid dials.

A feed override scales every programmed feed (plateaus at k x F on every feed move, time lost in
proportion to the time spent cruising; rapids unchanged); a rapid override scales the rapid moves
only.
"""

from __future__ import annotations

from feedlog.diagnose import keys
from feedlog.diagnose.evidence import seed
from feedlog.diagnose.hypothesis import Family, Hypothesis
from feedlog.diagnose.programs import has_kind


def _override(profile, key: str):
    mech = key.split(".")[1]
    on = keys.enabled(profile, mech)
    return (keys.value(profile, key) if on else 1.0), not on


def _candidates(profile, cases) -> list[Hypothesis]:
    out = []
    value, off = _override(profile, "sim.feed_override.override")
    out.append(Hypothesis(key="sim.feed_override.override", family="overrides", lower=0.05, upper=2.0,
                          baseline=value, switches_on=off,
                          predicts="every feed move's plateau at the same fraction of its programmed F; rapids "
                                   "as modelled"))
    if has_kind(cases, "rapid"):
        value, off = _override(profile, "sim.rapid_override.override")
        out.append(Hypothesis(key="sim.rapid_override.override", family="overrides", lower=0.05, upper=1.0,
                              baseline=value, switches_on=off,
                              predicts="rapid (G0) moves slower by one factor; feed moves as modelled"))
    return out


class Overrides(Family):
    name = "overrides"
    rank = 0

    def candidates(self, profile, cases) -> list[Hypothesis]:
        return _candidates(profile, cases)

    def describe(self, ev, key, fitted=None) -> str:
        if key == "sim.feed_override.override" and ev.plateau_ratio is not None:
            return (f"long feed moves cruise at {ev.plateau_ratio:.3f} x their programmed F "
                    f"(median of {ev.plateau_blocks})")
        return ""

    def suggest(self, ev, key, baseline) -> tuple[float, ...]:
        if key != "sim.feed_override.override" or ev.plateau_ratio is None:
            return ()
        return seed(ev.plateau_ratio * (baseline if isinstance(baseline, (int, float)) else 1.0))

    def contradicts(self, ev, key, profile_value, fitted) -> str | None:
        return None  # nothing seen without a simulation bounds an operator's dial


FAMILY = Overrides()
