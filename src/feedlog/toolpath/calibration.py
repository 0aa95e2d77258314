"""An air-cut program that pins down the axis limits a profile's recordings did not constrain.

For each axis whose velocity limit is not constrained (by the profile's `[coverage]`; every axis when
it has none) the program moves the axis alone, back and forth over `travel`, in rapids and at a feed
above the profile's limit (so the limit, not the programmed feed, sets the cruise). For each axis whose
acceleration limit is not constrained it runs exact-stop zig-zags of short moves (1, 2 and 5 mm, or
degrees) at that feed: their time is mostly speeding up and slowing down. One axis at a time, so that
no limit can stand in for another's (a path cap for an axis limit, one axis for another). The moves
are relative to where the program starts (G91), so the operator places the tool where `travel` is free
in every direction; the program says so in its header.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from feedlog.errors import FeedlogError

SHORT = (1.0, 2.0, 5.0)   # zig-zag move lengths (unit of the axis)
REPEAT = 3                # each pattern this many times
FEED_ABOVE = 1.5          # programmed feed as a multiple of the profile's velocity limit


def missing(profile: Any) -> list[str]:
    """The axis-limit keys the profile's coverage does not mark constrained (all of them without coverage)."""
    params = (profile.coverage or {}).get("parameters", {})
    out = []
    for a in profile.axis_names:
        for limit in ("vel_max", "acc_max"):
            key = f"axes.{a}.{limit}"
            if not params.get(key, {}).get("constrained"):
                out.append(key)
    return out


def calibration_program(profile: Any, *, travel: float = 100.0, keys: Iterable[str] | None = None) -> str:
    """G-code (RS274/NGC) of the calibration air-cut for `keys` (default: `missing(profile)`)."""
    if not travel > 0:
        raise FeedlogError(f"calibration travel must be positive, got {travel}")
    want = list(missing(profile) if keys is None else keys)
    unknown = [k for k in want if k.split(".")[:1] != ["axes"] or k.split(".")[1] not in profile.axis_names]
    if unknown:
        raise FeedlogError(f"no calibration pattern for {', '.join(unknown)} (axis limits of {profile.name!r} only)")
    lines = [f"(feedlog calibration air-cut for {profile.name}: {', '.join(want) if want else 'nothing missing'})",
             f"(moves are relative to the start: leave {travel:g} mm / deg free in + and - on every axis used)",
             "G21 G91 G94 G17", "G61 (exact stop: every move starts and ends at rest)"]
    for a in profile.axis_names:
        name = a.upper()
        lim = profile.axes[a]
        feed = round(FEED_ABOVE * lim.vel_max * 60.0, 1)
        if f"axes.{a}.vel_max" in want:
            lines.append(f"({name} velocity: long moves alone, rapid and at F{feed:g} above the limit)")
            for _ in range(REPEAT):
                lines += [f"G0 {name}{travel:g}", f"G0 {name}{-travel:g}"]
                lines += [f"G1 {name}{travel:g} F{feed:g}", f"G1 {name}{-travel:g}"]
        if f"axes.{a}.acc_max" in want:
            lines.append(f"({name} acceleration: short exact-stop zig-zags at F{feed:g})")
            for step in SHORT:
                for _ in range(REPEAT):
                    lines += [f"G1 {name}{step:g} F{feed:g}", f"G1 {name}{-step:g}"]
    lines += ["G90", "M2"]
    return "\n".join(lines) + "\n"
