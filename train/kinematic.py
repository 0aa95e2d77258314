"""A block's local kinematic time: one acceleration-limited trapezoid per block, no look-ahead.

The learners' default base time (`base = "kinematic"`; also an optional input, `kin_time_s`): with
base "cam" they start from the axis-limited CAM time L / F, up to 75 % short on our programs. The
estimate knows only what one block and its two corners say:

- the path limits of the block: acceleration and speed the slowest axis allows along it,
  `path_acc_mm_s2` = min over moving axes of acc_max x L / |d axis| and `path_vel_mm_s` likewise
  with vel_max (rotary axes in deg; arcs also v <= sqrt(a R / 2)); from the program and the machine
  profile (`path_limits`, attached by `features.with_program_columns`);
- the speed at each end: 0 at rest (corner 180 deg), in G61 (`tol_mm` 0) and where rapid and feed
  moves meet (LinuxCNC stops there); else the speed on a blend arc that leaves the corner by at most
  the path tolerance P (or uses at most half the shorter block without P), at half the path
  acceleration, capped at both blocks' feeds; next to a block that turns a rotary axis, LinuxCNC's
  parabolic blend instead: half acceleration on the block ending in it, and a blend speed from the
  half-block triangle and the tolerance;
- a trapezoid from the start speed to the end speed at the block's feed and path limits, at least one
  servo period for a moving block.

It knows nothing of look-ahead over several short blocks, the block rate, the kink rule or the
machine's interpolation filter: those are what the learners learn. Over the 100 training recordings
its sum is off the measured time by 2.9 % (three-axis) and 8.9 % (five-axis) mean |error|, where the
axis-limited CAM time is 16 % and 39 % short; nothing in it is fitted.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from feedlog.profile import MachineProfile

ROTARY = ("a", "b", "c")
# share of the path acceleration a blend arc may use across the path: a round choice, not fitted or tried
# against others (LinuxCNC's blend arcs use sqrt(1 - 0.5^2) = 0.87, sim/corner_blend.py)
NORMAL_SHARE = 0.5
BIG = 1e12


def path_limits(source: pd.DataFrame, profile: MachineProfile) -> tuple[np.ndarray, np.ndarray]:
    """Per program block, the path acceleration (mm/s^2) and speed (mm/s) its axes allow.

    `source` is a toolpath program table (`x0_mm`, `x_mm`, ..., `length_mm`, `radius_mm`). Blocks
    without TCP length get BIG for both (their time is the axes' own: `axis_time_s`).
    """
    length = np.nan_to_num(source["length_mm"].to_numpy(np.float64)) if "length_mm" in source else np.zeros(len(source))
    acc = np.full(len(source), BIG)
    vel = np.full(len(source), BIG)
    moving = length > 0
    for axis, limits in profile.axes.items():
        unit = "deg" if axis in ROTARY else "mm"
        end, start = f"{axis}_{unit}", f"{axis}0_{unit}"
        if end not in source or start not in source:
            continue
        dist = np.nan_to_num((source[end] - source[start]).abs().to_numpy(np.float64))
        share = np.where(moving & (dist > 0), dist / np.where(moving, length, 1.0), 0.0)  # axis units per mm of path
        with np.errstate(divide="ignore"):
            if limits.acc_max > 0:
                acc = np.minimum(acc, np.where(share > 0, limits.acc_max / share, BIG))
            if limits.vel_max > 0:
                vel = np.minimum(vel, np.where(share > 0, limits.vel_max / share, BIG))
    if "radius_mm" in source:
        radius = source["radius_mm"].to_numpy(np.float64)
        arc = np.isfinite(radius) & (radius > 0)
        vel = np.where(arc, np.minimum(vel, np.sqrt(NORMAL_SHARE * acc * np.where(arc, radius, 0.0))), vel)
    return acc, vel


def kinematic_time(length: np.ndarray, feed_mm_min: np.ndarray, acc: np.ndarray, vel: np.ndarray,
                   tol_mm: np.ndarray, corner_end_deg: np.ndarray, rapid: np.ndarray,
                   servo_period_s: float, rotary: np.ndarray | None = None) -> np.ndarray:
    """Per block the trapezoid time (s) of one program, blocks in order (see the module text).

    `rotary` marks blocks that turn a rotary axis: a continuous-mode junction next to one is a
    parabolic blend (half acceleration on the block ending in it, blend speed from the half-block
    triangle and the tolerance).
    """
    length = np.maximum(np.nan_to_num(np.asarray(length, np.float64)), 0.0)
    n = len(length)
    if n == 0:
        return np.zeros(0)
    acc = np.clip(np.nan_to_num(np.asarray(acc, np.float64), nan=BIG), 1e-9, BIG)
    cruise = np.minimum(np.nan_to_num(np.asarray(feed_mm_min, np.float64)) / 60.0,
                        np.nan_to_num(np.asarray(vel, np.float64), nan=BIG))
    cruise = np.maximum(cruise, 1e-9)
    tol = np.asarray(tol_mm, np.float64)
    nxt = slice(1, None)
    nxt_len = np.append(length[nxt], 0.0)
    nxt_cruise = np.append(cruise[nxt], 0.0)
    nxt_acc = np.append(acc[nxt], BIG)
    turn = np.radians(np.clip(np.nan_to_num(np.asarray(corner_end_deg, np.float64), nan=180.0), 0.0, 180.0))
    half = turn / 2
    with np.errstate(divide="ignore", invalid="ignore"):
        # ... and the arc's tangent points within half of the shorter block: R tan(half) <= min(L) / 2
        r_len = np.where(half > 0, np.minimum(length, nxt_len) / 2.0 / np.tan(half), BIG)
    radius = np.nan_to_num(np.minimum(blend_radius(half, tol), r_len), nan=BIG, posinf=BIG)
    a_corner = NORMAL_SHARE * np.minimum(acc, nxt_acc)
    v_end = np.minimum(np.minimum(cruise, nxt_cruise), np.sqrt(a_corner * radius))
    rapid = np.asarray(rapid, bool)
    stop = (np.nan_to_num(tol, nan=1.0) == 0) | (turn >= np.pi) | np.append(rapid[nxt] != rapid[:-1], True)
    if rotary is not None:
        rot = np.asarray(rotary, bool)
        para = (rot | np.append(rot[nxt], False)) & ~stop
        acc = np.where(para, acc / 2, acc)
        v_tri = np.minimum(np.sqrt(acc * length), cruise)
        # deviation of the parabola: v <= 2 sqrt(a P / sin(corner / 2)) (LinuxCNC's blend tolerance rule)
        with np.errstate(divide="ignore", invalid="ignore"):
            v_tol = np.where(np.isfinite(tol) & (half > 0), 2 * np.sqrt(acc * np.nan_to_num(tol) / np.sin(half)), BIG)
        v_end = np.where(para, np.minimum(np.minimum(v_tri, np.append(v_tri[nxt], 0.0)), v_tol), v_end)
    v_end = np.where(stop, 0.0, v_end)
    time = trapezoid_time(length, np.append(0.0, v_end[:-1]), v_end, cruise, acc)
    return np.where(length > 0, np.maximum(time, servo_period_s), 0.0)


def blend_radius(half_turn: np.ndarray, tol_mm: np.ndarray | float) -> np.ndarray:
    """Radius (mm) of the arc through a corner of half-angle `half_turn` (rad, half the direction
    change) whose deviation from the corner, R (1 / cos(half) - 1), is the tolerance; BIG where the
    path does not turn or has no tolerance (NaN)."""
    half = np.asarray(half_turn, np.float64)
    tol = np.broadcast_to(np.asarray(tol_mm, np.float64), half.shape)
    cos_h = np.cos(half)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.isfinite(tol) & (half > 0), tol * cos_h / np.maximum(1.0 - cos_h, 1e-300), BIG)


def trapezoid_time(length: np.ndarray, v_in: np.ndarray, v_out: np.ndarray, v_max: np.ndarray | float,
                   acc: np.ndarray | float) -> np.ndarray:
    """Time (s) to travel `length` from v_in to v_out, cruising at most at v_max, accelerating at acc.

    An end speed the length cannot reach from the other end is lowered to what it can reach.
    """
    length = np.asarray(length, np.float64)
    v_in = np.minimum(v_in, np.sqrt(np.square(v_out) + 2 * acc * length))
    v_out = np.minimum(v_out, np.sqrt(np.square(v_in) + 2 * acc * length))
    peak = np.minimum(v_max, np.sqrt(acc * length + (np.square(v_in) + np.square(v_out)) / 2))
    ramps = (2 * np.square(peak) - np.square(v_in) - np.square(v_out)) / (2 * acc)
    with np.errstate(divide="ignore", invalid="ignore"):  # peak 0 only where length is 0
        return (2 * peak - v_in - v_out) / acc + np.maximum(length - ramps, 0.0) / peak
