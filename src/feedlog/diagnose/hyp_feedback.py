"""Feedback: how the reported (feedback) position trails the command, per joint.

A feedback delay shifts every joint's feedback by the same time (error proportional to the speed,
no change of shape); a following lag on one axis smooths that axis' feedback like a first-order
servo loop (error proportional to its speed, corners rounded, the axis settles after each stop).
Neither changes the cycle time: they are judged on recordings that carry joint feedback.
"""

from __future__ import annotations

from feedlog.diagnose import keys
from feedlog.diagnose.evidence import seed
from feedlog.diagnose.hypothesis import Family, Hypothesis


def _candidates(profile, cases) -> list[Hypothesis]:
    with_fb = [c for c in cases if c.feedback is not None]
    if not with_fb:
        return []
    out = []
    on = keys.enabled(profile, "feedback_delay")
    out.append(Hypothesis(key="sim.feedback_delay.delay_s", family="feedback", lower=1e-5, upper=0.05,
                          level="feedback",
                          baseline=keys.value(profile, "sim.feedback_delay.delay_s") if on else None,
                          switches_on=not on,
                          predicts="every joint's feedback behind its command by one time, error proportional "
                                   "to speed"))
    lag_on = keys.enabled(profile, "following_lag")
    axes = sorted({a for c in with_fb for a in c.feedback.axes}, key=profile.axis_names.index)
    for axis in axes:
        key = f"sim.following_lag.lag_s.{axis}"
        out.append(Hypothesis(key=key, family="feedback", lower=1e-4, upper=0.5, level="feedback",
                              baseline=keys.value(profile, key) if lag_on else None, switches_on=not lag_on,
                              predicts=f"{axis.upper()} feedback lags its command like a first-order servo: error "
                                       "proportional to speed, overshoot-free settling after stops"))
    return out


class Feedback(Family):
    name = "feedback"
    rank = 5

    def candidates(self, profile, cases) -> list[Hypothesis]:
        return _candidates(profile, cases)

    def describe(self, ev, key, fitted=None) -> str:
        parts = key.split(".")
        if key == "sim.feedback_delay.delay_s" and ev.feedback_delay_s:
            return "feedback trails the command by " + ", ".join(
                f"{a.upper()} {d * 1e3:.3g} ms" for a, d in ev.feedback_delay_s.items())
        if parts[:2] == ["sim", "following_lag"] and len(parts) == 4 and parts[3] in ev.feedback_delay_s:
            return f"{parts[3].upper()} feedback trails its command by {ev.feedback_delay_s[parts[3]] * 1e3:.3g} ms"
        return ""

    def suggest(self, ev, key, baseline) -> tuple[float, ...]:
        parts = key.split(".")
        if parts[:2] == ["sim", "following_lag"] and len(parts) == 4:
            return seed(ev.feedback_delay_s.get(parts[3]))
        return ()

    def contradicts(self, ev, key, profile_value, fitted) -> str | None:
        return None


FAMILY = Feedback()
