"""Planner settings: look-ahead depth, blend tolerance, servo period, block processing time, FIR times.

A shorter look-ahead makes runs of short blocks slower (the planner must be able to stop within
the window); a smaller share of the G64 tolerance used for blending slows blended corners; a longer
servo period slows runs of very short segments (each lasts at least about one period) and changes
which corners count as tangent; a block processing time floor caps short blocks at
length / floor (time lost on runs of short blocks, none on long ones); an FIR interpolator's T1 and T2
spread every speed change over the filter's length.
"""

from __future__ import annotations

from feedlog.diagnose import keys
from feedlog.diagnose.hypothesis import Family, Hypothesis
from feedlog.diagnose.programs import has_blending


def _candidates(profile, cases) -> list[Hypothesis]:
    out = []
    interp = profile.interpolator
    planner = keys.enabled(profile, "lookahead")
    if planner:
        key = ("sim.lookahead.lookahead_blocks" if "lookahead_blocks" in profile.mechanism("lookahead")
               else "interpolator.lookahead_blocks")
        out.append(Hypothesis(key=key, family="planner", lower=1, upper=400, scale="int",
                              baseline=int(keys.value(profile, key)),
                              predicts="runs of short blocks slower than modelled (the planner must stop within a "
                                       "shorter window); long blocks unchanged"))
    if keys.enabled(profile, "fir"):  # FIR-filter interpolation: acceleration time T1 and jerk time T2
        t1, t2 = interp.fir_t1_s, interp.fir_t2_s
        out.append(Hypothesis(key="interpolator.fir_t1_s", family="planner", lower=max(t2, 1e-3), upper=max(10 * t1, 0.01),
                              baseline=t1, predicts="every speed change spread over T1: longer corners and starts, "
                                                    "slower short blocks"))
        if t1 > 2e-4:
            out.append(Hypothesis(key="interpolator.fir_t2_s", family="planner", lower=1e-4, upper=t1,
                                  baseline=max(t2, 1e-4), predicts="jerk-limited edges of every speed change (T2)"))
    if keys.enabled(profile, "blend_arc") and has_blending(cases):
        out.append(Hypothesis(key="sim.blend_arc.tolerance_scale", family="planner", lower=0.02, upper=1.0,
                              baseline=float(keys.value(profile, "sim.blend_arc.tolerance_scale")),
                              predicts="blended (G64) corners slower than modelled, more at sharper corners and "
                                       "larger tolerances; exact stops unchanged"))
    out.append(Hypothesis(key="interpolator.servo_period_s", family="planner", lower=1e-4, upper=0.02,
                          baseline=interp.servo_period_s,
                          predicts="runs of very short segments slower (each lasts about a servo period at "
                                   "least); long moves unchanged"))
    floor = interp.block_time_s
    out.append(Hypothesis(key="interpolator.block_time_s", family="planner", lower=1e-4, upper=0.05,
                          baseline=floor if floor > 0 else None, switches_on=not floor > 0,
                          predicts="every block lasts at least one processing time: short blocks capped at "
                                   "length / time, long blocks unchanged"))
    return out


class Planner(Family):
    name = "planner"
    rank = 3

    def candidates(self, profile, cases) -> list[Hypothesis]:
        return _candidates(profile, cases)

    def describe(self, ev, key, fitted=None) -> str:
        if key == "sim.blend_arc.tolerance_scale" and ev.blend_deviation_mm is not None:
            tol = "" if ev.blend_tolerance_mm is None else f" (G64 P{ev.blend_tolerance_mm:g})"
            return f"the path leaves the program's corners by up to {ev.blend_deviation_mm:.4g} mm{tol}"
        return ""

    def suggest(self, ev, key, baseline) -> tuple[float, ...]:
        return ()  # the data alone points at no planner setting

    def contradicts(self, ev, key, profile_value, fitted) -> str | None:
        return None


FAMILY = Planner()
