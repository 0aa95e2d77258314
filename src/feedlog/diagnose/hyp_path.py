"""Path limits: the controller's caps on the tool-centre-point speed and acceleration.

A path velocity cap (LinuxCNC `[TRAJ] MAX_LINEAR_VELOCITY`) holds every linear move below it
whatever its direction (plateaus at one speed for all programmed feeds above it); a path
acceleration cap slows every speed change of every move, whatever axis carries it.
"""

from __future__ import annotations

import math

import numpy as np

from feedlog.diagnose.hypothesis import Hypothesis
from feedlog.diagnose.programs import feeds

SPAN = 30.0


def candidates(profile, cases) -> list[Hypothesis]:
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
