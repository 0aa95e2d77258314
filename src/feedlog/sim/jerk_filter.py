"""Jerk limit by FIR smoothing: the acceleration-limited motion through one moving average.

Source: Biagiotti & Melchiorri, "FIR filters for online trajectory planning with time- and
frequency-domain specifications" (Control Eng. Practice 2012) and Tajima & Sencer (2017): a
trapezoidal (acceleration-limited) velocity profile passed through a moving average of width
T_j = a_max / j_max becomes the jerk-limited S-curve profile, its jerk bounded by a_max / T_j. The
motion ends T_j later; blocks shift by T_j / 2 (the filter's group delay). The corner deviation
this adds is of order v T_j^2 (acceleration change across a corner times T_j^2 / 24) and is not
checked against the tolerance here.

`jerk_time_s` defaults to the largest a_max / jerk_max over the profile's axes that have a jerk limit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.profile import MachineProfile
from feedlog.sim.context import Context, Trajectory, cover_motion, hold_end
from feedlog.sim.fir import moving_average, path_speed
from feedlog.sim.mechanism import Mechanism


def jerk_time(profile: MachineProfile) -> float:
    times = [lim.acc_max / lim.jerk_max for lim in profile.axes.values() if lim.jerk_max > 0]
    return max(times, default=0.0)


@dataclass
class JerkFilter(Mechanism):
    name = "jerk_filter"
    kind = "series"
    order = 10  # before the servo lag

    jerk_time_s: float = 0.01

    def __post_init__(self) -> None:
        self.check_positive(jerk_time_s=self.jerk_time_s)

    @classmethod
    def default_enabled(cls, profile: MachineProfile) -> bool:
        # the FIR interpolator limits jerk itself (T2)
        return jerk_time(profile) > 0 and profile.interpolator.fir_t1_s <= 0

    @classmethod
    def defaults(cls, profile: MachineProfile) -> dict:
        t = jerk_time(profile)
        return {"jerk_time_s": t} if t > 0 else {}

    def after(self, ctx: Context, trajectory: Trajectory) -> Trajectory:
        n = max(int(round(self.jerk_time_s / ctx.dt_s)), 1)
        tj = n * ctx.dt_s
        longer = hold_end(trajectory, tj, ctx.dt_s)
        lin = ctx.blocks.linear_index
        dt = ctx.dt_s

        def smooth(t, pos, speed, row):
            pos = moving_average(pos, n)
            new_speed = path_speed(pos, lin, dt)
            shift = n // 2  # the executing block follows the group delay
            row = np.concatenate([np.repeat(row[:1], shift), row[:len(row) - shift]]) if shift else row
            return t, pos, new_speed, row

        smoothed = longer.map(smooth)
        m_end = trajectory.motion_end_s + tj
        b_start, b_end = cover_motion(trajectory.block_start_s + tj / 2, trajectory.block_end_s + tj / 2,
                                      trajectory.motion_start_s, m_end)
        return Trajectory(smoothed._sampler, block_start_s=b_start, block_end_s=b_end,
                          motion_start_s=trajectory.motion_start_s, motion_end_s=m_end, plan=trajectory.plan)
