"""What the recordings behind a fitted profile covered, and where a program goes beyond it.

A profile fitted by `feedlog diagnose --calibrate` carries a `[coverage]` table: per axis the
sustained peak speed and acceleration the recordings showed and the longest single move along it,
and per fitted parameter whether the recordings constrain it (an interval closed on both sides) or
only bound it from one side (a limit that never bound: the data says it is at least so much). A
program simulated on such a profile is checked against it (`beyond`): an axis moved faster, accelerated
harder or further in one move than the recordings ever did is named with the parameter that decides
it there, because the profile's value for it is a guess on that ground; and a program of much shorter
moves than any recording's (`shorter`) is named with the planner's look-ahead: runs of short blocks
are the planner's, which no axis limit covers.

    [coverage]
    format_version = 1
    recordings = ["a.mcap", "b.mcap"]
    [coverage.axes.z]
    vel_observed = 40.1      # unit/s, sustained peak in the recordings
    acc_observed = 296.0     # unit/s^2 (absent when the sampling cannot show accelerations)
    move_max = 25.0          # unit, longest single programmed move along the axis
    [coverage.blocks]
    median_move_min = 2.4    # mm, the shortest median move length of the recordings' programs
    [coverage.parameters."axes.z.vel_max"]
    constrained = false
    interval = [40.1, 750.0] # the values the recordings allow (profile likelihood, 95 %)
    pair = "axes.z.acc_max"  # optional: a limit it trades off against (the interval: along their ridge)
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from feedlog.errors import ProfileError

FORMAT_VERSION = 1
MARGIN = 0.05          # a demand this much above what was observed is beyond it
SHORTER = 0.5          # a program whose median move is below this share of the recordings' shortest median
WINDOW_S = 0.01        # speeds and accelerations of a position series from differences over this time
KINDS = ("rapid", "linear")


def check(coverage: Mapping[str, Any], where: str) -> None:
    """A coverage table read from a file: its version and shape (ProfileError naming `where`)."""
    if not coverage:
        return
    version = coverage.get("format_version")
    if not isinstance(version, int) or version > FORMAT_VERSION or version < 1:
        raise ProfileError(f"{where}: [coverage] format_version {version!r} not supported (this feedlog reads "
                           f"up to {FORMAT_VERSION})")
    blocks = coverage.get("blocks", {})
    if not isinstance(blocks, dict) or not all(isinstance(v, (int, float)) for v in blocks.values()):
        raise ProfileError(f"{where}: [coverage.blocks] must hold numbers")
    for key in ("axes", "parameters"):
        table = coverage.get(key, {})
        if not isinstance(table, dict) or not all(isinstance(v, dict) for v in table.values()):
            raise ProfileError(f"{where}: [coverage.{key}] must hold one table per entry")
    for name, entry in coverage.get("parameters", {}).items():
        pair = entry.get("pair")  # the limit it trades off against (diagnose --calibrate): one of the others
        if pair is not None and (not isinstance(pair, str) or pair == name or pair not in coverage["parameters"]):
            raise ProfileError(f"{where}: [coverage.parameters.\"{name}\"] pair must name another parameter of "
                               f"the table, got {pair!r}")


def move_lengths(blocks: Any, axes: tuple[str, ...]) -> dict[str, float]:
    """Longest single straight move (rapid or linear block) along each axis of a program's block table."""
    out = {}
    kind = blocks["kind"].astype(str).to_numpy() if "kind" in blocks.columns else np.full(len(blocks), "linear")
    straight = np.isin(kind, KINDS)
    for a in axes:
        unit = "deg" if a in "abc" else "mm"
        c0, c1 = f"{a}0_{unit}", f"{a}_{unit}"
        if c0 not in blocks.columns or c1 not in blocks.columns:
            continue
        d = np.abs(blocks[c1].to_numpy(np.float64) - blocks[c0].to_numpy(np.float64))[straight]
        d = d[np.isfinite(d)]
        out[a] = float(d.max()) if len(d) else 0.0
    return out


def median_move(blocks: Any) -> float:
    """The median path length of a program's motion blocks (0 when it has none)."""
    if "length_mm" not in blocks.columns:
        return 0.0
    kind = blocks["kind"].astype(str).to_numpy() if "kind" in blocks.columns else np.full(len(blocks), "linear")
    length = blocks["length_mm"].to_numpy(np.float64)
    keep = (kind != "start") & np.isfinite(length) & (length > 0)
    return float(np.median(length[keep])) if keep.any() else 0.0


def series_peaks(t_ns: np.ndarray, positions: Mapping[str, np.ndarray]) -> dict[str, tuple[float, float]]:
    """(peak speed, peak acceleration) per axis of a noiseless position series (a simulation's), from
    differences over `WINDOW_S`."""
    t = (np.asarray(t_ns, dtype=np.int64) - int(t_ns[0])) / 1e9 if len(t_ns) else np.zeros(0)
    out = {}
    if len(t) < 3:
        return {a: (0.0, 0.0) for a in positions}
    dt = float(np.median(np.diff(t)))
    k = max(1, int(round(WINDOW_S / dt))) if dt > 0 else 1
    for a, p in positions.items():
        p = np.asarray(p, dtype=np.float64)
        if len(p) <= 2 * k:
            out[a] = (0.0, 0.0)
            continue
        v = (p[k:] - p[:-k]) / (t[k:] - t[:-k])
        tv = (t[k:] + t[:-k]) / 2
        acc = (v[k:] - v[:-k]) / (tv[k:] - tv[:-k]) if len(v) > k else v[:0]
        out[a] = (float(np.max(np.abs(v))), float(np.max(np.abs(acc))) if len(acc) else 0.0)
    return out


def beyond(coverage: Mapping[str, Any], peaks: Mapping[str, tuple[float, float]],
           moves: Mapping[str, float]) -> list[str]:
    """Where a program goes beyond what the recordings covered: one sentence per (axis, quantity), each
    naming the profile parameter that decides the motion there."""
    axes = coverage.get("axes", {}) if coverage else {}
    params = coverage.get("parameters", {}) if coverage else {}
    out = []
    for a, seen in axes.items():
        name, unit = a.upper(), ("deg" if a in "abc" else "mm")
        vel, acc = peaks.get(a, (0.0, 0.0))
        checks = (("vel_max", vel, seen.get("vel_observed"), f"{unit}/s", "moves {n} at {d:.4g} {u}",
                   "never saw {n} faster than {o:.4g} {u}"),
                  ("acc_max", acc, seen.get("acc_observed"), f"{unit}/s^2", "accelerates {n} at {d:.4g} {u}",
                   "never saw {n} accelerate harder than {o:.4g} {u}"),
                  ("vel_max", moves.get(a, 0.0), seen.get("move_max"), unit, "moves {n} {d:.4g} {u} in one block",
                   "never moved {n} more than {o:.4g} {u} in one block"))
        for limit, demand, observed, u, did, never in checks:
            if observed is None or demand <= observed * (1 + MARGIN) + 1e-9:
                continue
            key = f"axes.{a}.{limit}"
            if params.get(key, {}).get("constrained"):
                continue  # the recordings pinned the value that decides it: the simulation there is backed
            out.append(f"{key}: the program {did.format(n=name, d=demand, u=u)}; the recordings this profile was "
                       f"fitted on {never.format(n=name, o=observed, u=u)}, so the profile's value there is not "
                       "backed by data")
    return out


def shorter(coverage: Mapping[str, Any], median: float) -> list[str]:
    """A program of much shorter moves than every recording's: the planner's handling of runs of short
    blocks (look-ahead, segments, blends), which axis limits do not cover, is not backed by data."""
    seen = (coverage.get("blocks", {}) if coverage else {}).get("median_move_min")
    if seen is None or not median > 0 or median >= SHORTER * seen:
        return []
    return [f"interpolator.lookahead_blocks: the program's median move is {median:.4g} mm; the recordings this "
            f"profile was fitted on had a median move of {seen:.4g} mm at the shortest, so its runs of short "
            "blocks (look-ahead, segments, blends) are not backed by data"]


def program_warnings(profile: Any, series: Any, blocks: Any) -> list[str]:
    """`beyond` and `shorter` for a program simulated on `profile` (its series: t_ns and axis position
    columns; its parsed block table): [] when the profile carries no coverage."""
    if not getattr(profile, "coverage", None):
        return []
    axes = [a for a in profile.coverage.get("axes", {})]
    cols = {a: f"{a}_{'deg' if a in 'abc' else 'mm'}" for a in axes}
    positions = {a: series[c].to_numpy(np.float64) for a, c in cols.items() if c in series.columns}
    peaks = series_peaks(series["t_ns"].to_numpy(np.int64), positions) if positions else {}
    return (beyond(profile.coverage, peaks, move_lengths(blocks, tuple(axes)))
            + shorter(profile.coverage, median_move(blocks)))
