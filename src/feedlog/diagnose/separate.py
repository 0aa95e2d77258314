"""Which recording would tell two equally good explanations apart.

When the recordings cannot tell two causes apart (a program that moves Z only in rapids: a Z velocity
limit or a rapid override fit it equally well), each explanation is put into the profile and the
calibration air-cuts (`feedlog.toolpath.calibration`) for the axis limits involved are simulated on
both: the pattern whose predicted cycle times differ most is the recording to make. It is named when
the two predictions differ by at least `MIN_DIFFERENCE` (what a cause must explain to be named);
otherwise nothing short of other kinds of programs would tell them apart, and the finding says so.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from feedlog.diagnose import keys as profile_keys
from feedlog.errors import FeedlogError
from feedlog.profile import MachineProfile

MIN_DIFFERENCE = 0.01   # predicted cycle times must differ by this share
LIMITS = ("vel_max", "acc_max")


def _patterns(profile: MachineProfile, keys: list[str]) -> list[list[str]]:
    """Calibration patterns worth trying for `keys`: each axis limit named alone, then both limits of
    every axis the keys name; with no axis among them (a dial against a path cap), every axis' limits
    one axis at a time."""
    axis = [k for k in keys if k.split(".")[0] == "axes" and k.split(".")[-1] in LIMITS]
    axes = sorted({k.split(".")[1] for k in axis}, key=profile.axis_names.index) or list(profile.axis_names)
    out = [[k] for k in axis]
    out += [[f"axes.{a}.{lim}" for lim in LIMITS] for a in axes]
    return out


def separating_program(profile: MachineProfile, a: Mapping[str, Any], b: Mapping[str, Any]) -> dict[str, Any] | None:
    """The calibration pattern whose cycle time `profile` + `a` and `profile` + `b` predict most differently
    (None when no pattern moves them `MIN_DIFFERENCE` apart)."""
    from feedlog.sim import simulate
    from feedlog.toolpath import parse_program
    from feedlog.toolpath.calibration import calibration_program

    try:
        pa, pb = profile_keys.with_values(profile, a), profile_keys.with_values(profile, b)
    except FeedlogError:
        return None
    best = None
    for pattern in _patterns(profile, [*a, *b]):
        prog = parse_program(calibration_program(profile, keys=pattern), name="calibration")
        ta, tb = simulate(prog, pa).cycle_time_s, simulate(prog, pb).cycle_time_s
        diff = abs(ta - tb) / max(ta, tb)
        if best is None or diff > best[0]:
            best = (diff, pattern, ta, tb)
    if best is None or best[0] < MIN_DIFFERENCE:
        return None
    diff, pattern, ta, tb = best
    return {"program": f"feedlog program --calibration CAL.ngc --profile PROFILE --for {','.join(pattern)}",
            "for": pattern, "cycle_s": [round(ta, 4), round(tb, 4)], "difference_pct": round(100 * diff, 2)}
