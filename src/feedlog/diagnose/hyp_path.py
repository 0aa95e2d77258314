"""Path limits: the controller's caps on the tool-centre-point speed and acceleration.

A path velocity cap (LinuxCNC `[TRAJ] MAX_LINEAR_VELOCITY`) holds every linear move below it
whatever its direction (plateaus at one speed for all programmed feeds above it); a path
acceleration cap slows every speed change of every move, whatever axis carries it.
"""

from __future__ import annotations

import math

import numpy as np

from feedlog.diagnose.evidence import against_limit, seed
from feedlog.diagnose.hypothesis import Family, Hypothesis
from feedlog.diagnose.programs import feeds

SPAN = 30.0


def _candidates(profile, cases) -> list[Hypothesis]:
    interp = profile.interpolator
    lin = [profile.axes[a] for a in ("x", "y", "z")]
    f = feeds(cases)
    top = max(float(f.max()) / 60.0 if len(f) else 0.0, profile.rapid_mm_min / 60.0)
    v0 = interp.path_vel_max_mm_s
    a0 = interp.path_acc_max_mm_s2
    acc_ref = a0 if math.isfinite(a0) else min(x.acc_max for x in lin)
    vel_ref = v0 if math.isfinite(v0) else top
    return [
        Hypothesis(key="interpolator.path_vel_max_mm_s", family="path_limits", lower=vel_ref / SPAN,
                   upper=max(vel_ref, top) * 2, baseline=v0,
                   predicts="every linear move at or below one speed, whatever its direction (plateaus at the "
                            "same height for all programmed feeds above it)"),
        Hypothesis(key="interpolator.path_acc_max_mm_s2", family="path_limits", lower=acc_ref / SPAN,
                   upper=float(np.max([x.acc_max for x in lin])) * 3, baseline=a0,
                   predicts="every speed change slower in every direction: time lost at starts, stops and "
                            "corners of all moves alike"),
    ]


class PathLimits(Family):
    name = "path_limits"
    rank = 2

    def candidates(self, profile, cases) -> list[Hypothesis]:
        return _candidates(profile, cases)

    def describe(self, ev, key, fitted=None) -> str:
        if key == "interpolator.path_vel_max_mm_s" and ev.path_speed_ceiling_mm_s is not None:
            return f"path speed never exceeds {ev.path_speed_ceiling_mm_s:.4g} mm/s"
        if key == "interpolator.path_acc_max_mm_s2" and ev.plateau_ratio is not None:
            return (f"long feed moves cruise at {ev.plateau_ratio:.3f} x their programmed F "
                    f"(median of {ev.plateau_blocks})")
        return ""

    def suggest(self, ev, key, baseline) -> tuple[float, ...]:
        return seed(ev.path_speed_ceiling_mm_s) if key == "interpolator.path_vel_max_mm_s" else ()

    def contradicts(self, ev, key, profile_value, fitted) -> str | None:
        if key != "interpolator.path_vel_max_mm_s" or ev.path_speed_ceiling_mm_s is None:
            return None
        seen = ev.path_speed_ceiling_mm_s
        side = against_limit(seen, profile_value, fitted)
        if side == "above":
            return f"the path speed never exceeded the profile's cap ({seen:.4g} mm/s at most)"
        if side == "below":
            return f"the path speed reached {seen:.4g} mm/s, far above the fitted cap {fitted:.4g}"
        return None


FAMILY = PathLimits()
