"""Feedback: how the reported (feedback) position trails the command, per joint.

A feedback delay shifts every joint's feedback by the same time (error proportional to the speed,
no change of shape); a following lag on one axis smooths that axis' feedback like a first-order
servo loop (error proportional to its speed, corners rounded, the axis settles after each stop).
Neither changes the cycle time: they are judged on recordings that carry joint feedback.
"""

from __future__ import annotations

from feedlog.diagnose import keys
from feedlog.diagnose.hypothesis import Hypothesis


def candidates(profile, cases) -> list[Hypothesis]:
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
