"""Axis limits: every moving axis' velocity and acceleration limit (rotary axes too).

A lower acceleration limit than the profile's makes every start, stop, corner and reversal with
that axis' motion slower (time lost where the axis changes speed, more at higher feeds); a lower
velocity limit caps moves along that axis below the programmed feed (time lost on long moves and
rapids dominated by it, plateaus below F).
"""

from __future__ import annotations

from feedlog.diagnose.evidence import SUSTAIN_S, AxisEvidence, against_limit, seed
from feedlog.diagnose.hypothesis import Family, Hypothesis
from feedlog.diagnose.programs import moves_axis

SPAN = 30.0  # search from profile / SPAN up to profile x 3


def _axis_key(ev, key: str) -> tuple[AxisEvidence, str] | None:
    """The evidence of the axis `key` (axes.<a>.vel_max / acc_max) names, with the limit's name."""
    parts = key.split(".")
    if parts[0] == "axes" and len(parts) == 3 and parts[1] in ev.axes:
        return ev.axes[parts[1]], parts[2]
    return None


class AxisLimits(Family):
    name = "axis_limits"
    rank = 1

    def candidates(self, profile, cases) -> list[Hypothesis]:
        out = []
        for axis in profile.axis_names:
            if not moves_axis(cases, axis):
                continue
            out += _limits(profile, axis)
        return out

    def describe(self, ev, key, fitted=None) -> str:
        found = _axis_key(ev, key)
        if found is None:
            return ""
        axis, limit = found
        name = axis.axis.upper()
        if limit == "acc_max":
            if axis.peak_acc is None:
                return f"{name} accelerations are not observable at this sampling rate"
            return f"{name} acceleration peaks at {axis.peak_acc:.4g} {axis.unit}/s^2 (sustained {SUSTAIN_S * 1e3:g} ms)"
        if limit == "vel_max":
            return f"{name} speed peaks at {axis.peak_vel:.4g} {axis.unit}/s"
        return ""

    def suggest(self, ev, key, baseline) -> tuple[float, ...]:
        found = _axis_key(ev, key)
        if found is None:
            return ()
        axis, limit = found
        return seed({"vel_max": axis.peak_vel, "acc_max": axis.peak_acc}.get(limit))

    def contradicts(self, ev, key, profile_value, fitted) -> str | None:
        found = _axis_key(ev, key)
        if found is None or found[1] not in ("vel_max", "acc_max") or found[0].travel <= 0:
            return None
        axis, limit = found
        seen = axis.peak_vel if limit == "vel_max" else axis.peak_acc
        what = "velocity" if limit == "vel_max" else "acceleration"
        unit = f"{axis.unit}/s" if limit == "vel_max" else f"{axis.unit}/s^2"
        side = against_limit(seen, profile_value, fitted)
        if side == "above":
            return (f"{axis.axis.upper()} was never seen above the profile's {what} ({seen:.4g} {unit} at most, "
                    f"profile {profile_value:.4g}): a higher limit cannot be what slows it")
        if side == "below":
            return f"{axis.axis.upper()} was seen at {seen:.4g} {unit}, far above the fitted limit {fitted:.4g}"
        return None


FAMILY = AxisLimits()


def _limits(profile, axis: str) -> list[Hypothesis]:
    lim = profile.axes[axis]
    name = axis.upper()
    return [
        Hypothesis(
            key=f"axes.{axis}.acc_max", family="axis_limits", lower=lim.acc_max / SPAN, upper=lim.acc_max * 3,
            baseline=lim.acc_max,
            predicts=f"time lost where {name} changes speed: starts, stops, corners and reversals with {name} "
                     "motion; more at higher feeds"),
        Hypothesis(
            key=f"axes.{axis}.vel_max", family="axis_limits", lower=lim.vel_max / SPAN, upper=lim.vel_max * 3,
            baseline=lim.vel_max,
            predicts=f"moves dominated by {name} cruise below their programmed feed (plateaus under F, rapids "
                     "slower); time lost in proportion to the length of such moves"),
    ]
