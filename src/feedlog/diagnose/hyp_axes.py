"""Axis limits: every moving axis' velocity and acceleration limit (rotary axes too).

A lower acceleration limit than the profile's makes every start, stop, corner and reversal with
that axis' motion slower (time lost where the axis changes speed, more at higher feeds); a lower
velocity limit caps moves along that axis below the programmed feed (time lost on long moves and
rapids dominated by it, plateaus below F).
"""

from __future__ import annotations

from feedlog.diagnose.hypothesis import Hypothesis
from feedlog.diagnose.programs import moves_axis

SPAN = 30.0  # search from profile / SPAN up to profile x 3


def candidates(profile, cases) -> list[Hypothesis]:
    out = []
    for axis in profile.axis_names:
        if not moves_axis(cases, axis):
            continue
        lim = profile.axes[axis]
        name = axis.upper()
        out.append(Hypothesis(
            key=f"axes.{axis}.acc_max", family="axis_limits", lower=lim.acc_max / SPAN, upper=lim.acc_max * 3,
            baseline=lim.acc_max,
            predicts=f"time lost where {name} changes speed: starts, stops, corners and reversals with {name} "
                     "motion; more at higher feeds"))
        out.append(Hypothesis(
            key=f"axes.{axis}.vel_max", family="axis_limits", lower=lim.vel_max / SPAN, upper=lim.vel_max * 3,
            baseline=lim.vel_max,
            predicts=f"moves dominated by {name} cruise below their programmed feed (plateaus under F, rapids "
                     "slower); time lost in proportion to the length of such moves"))
    return out
