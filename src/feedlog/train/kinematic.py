"""A program's kinematic time per block: one acceleration-limited trapezoid per block, joined by look-ahead.

The learners' default base time (`base = "kinematic"`; also an optional input, `kin_time_s`): with
base "cam" they start from the axis-limited CAM time L / F, up to 75 % short on our programs. The
estimate uses what each block and its two corners say, and one look-ahead pass over the program:

- the path limits of the block: acceleration and speed the slowest axis allows along it,
  `path_acc_mm_s2` = min over moving axes of acc_max x L / |d axis| and `path_vel_mm_s` likewise
  with vel_max (rotary axes in deg; arcs also v <= sqrt(a R / 2)); from the program and the machine
  profile (`path_limits`, attached by `features.with_program_columns`);
- the speed cap at each end: 0 at rest (corner 180 deg), in G61 (`tol_mm` 0) and where rapid and
  feed moves meet (LinuxCNC stops there); else the speed on a blend arc that leaves the corner by at
  most the path tolerance P (and uses at most half the shorter block), at 0.87 of the smallest linear
  axis acceleration across the path (LinuxCNC's normal share), capped at both blocks' feeds;
- LinuxCNC's parabolic blend next to a block that turns a rotary axis: the block ending in it runs
  at half acceleration from rest to rest, and the next block starts while it decelerates from the
  blend speed (from the half-block triangle and the tolerance), so the pair overlaps by
  v_blend / a;
- LinuxCNC's kink reduction at G61 corners without a rotary move: both blocks at 90 % acceleration;
- LinuxCNC's tangent check: a G64 junction whose direction change needs under 10 % of the axis
  acceleration in one servo cycle (per axis, `junction_kink`, at both lines' feed or length per
  cycle) is passed without a blend arc at that speed, the blocks' acceleration lowered by that share;
- blend arcs use half the path acceleration along the path: for look-ahead a block's acceleration is
  lowered by the share of it the arcs at its two ends cover (runs of very short blocks are all arc);
- look-ahead: the end speeds are lowered to what the blocks before can reach and the blocks after
  can stop from (the backward and forward passes of `sim.motion.reachable_speeds_sq`);
- a trapezoid from the start speed to the end speed at the block's feed and path limits; a block with
  a blend arc at an end runs as LinuxCNC plans it, in pieces: the half arcs at no more than the arc's
  speed and at half acceleration, the line between their tangent points as a trapezoid
  (`arc_pieces_time`);
- LinuxCNC's planner segments last at least 1.02 servo cycles over their length: a line over what
  the arcs at its ends left of it (a rest shorter than 4 cycles at the arc's speed rides with the
  arc after it), an arc over its length plus such a rest. This is what sets the speed on runs of very
  short blocks (dense002q0's 0.02 mm blocks leave 0.01 mm rests next to their arcs: about 10 mm/s).
  Not where G64 Q > 0 lets the interpreter merge lines (`merge`): the segment is longer than the block.

It knows nothing of the interpreter's collinear merging or an interpolation filter: those are what
the learners learn. Over the 106 aligned training recordings it is off the measured sums by 1.08 %
(72 three-axis, the long dense runs included; 0.96 % without them) and 1.10 % (34 five-axis) mean
|error|, where the axis-limited CAM time is 16 % and 39 % short; nothing in it is fitted (the kink
ratio, the arcs' tangential share, the segment and gap cycles are the planner constants the profile's
sim mechanisms hold, `planner_constants`, LinuxCNC's unless a profile changes them; the normal shares
are round values).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from feedlog.profile import MachineProfile
from feedlog.sim.mechanism import mechanism_params
from feedlog.sim.motion import reachable_speeds_sq

ROTARY = ("a", "b", "c")
# share of the path acceleration a G2/G3 arc may use across the path (`path_limits`): a round choice,
# not fitted
NORMAL_SHARE = 0.5
# share of the arc plane's acceleration (the smallest linear axis acceleration) a blend arc may use
# across the path: about LinuxCNC's sqrt(1 - 0.5^2) (sim/corner_blend.py); with the blend arc run
# as a piece of its own it gave 1.64 % against 2.05 % for 0.5 on the three-axis training recordings' sums
BLEND_NORMAL_SHARE = 0.87
# the smallest direction change (rad) taken as a G61 corner rather than a tangent junction
KINK_MIN_RAD = 0.01
BIG = 1e12


@dataclass(frozen=True)
class PlannerConstants:
    """LinuxCNC's planner constants, as the profile's sim mechanisms hold them (`planner_constants`).

    - `kink_ratio`: the kink acceleration reduction (tp.c; blend_arc's `kink_ratio`);
    - `gap_cycles`: a line piece shorter than this many servo cycles at the arc's speed is consumed by
      the blend arc after it (ARC_BLEND_GAP_CYCLES, blendCheckConsume; blend_arc's `gap_cycles`);
    - `min_segment_cycles`: each planner segment lasts at least this many servo cycles over its length
      (TP_MIN_SEGMENT_CYCLES; lookahead's `min_piece_cycles`);
    - `tangential_share`: of the path acceleration a blend arc may use along the path (lookahead's
      `arc_acc_ratio_tangential`).
    """

    kink_ratio: float
    gap_cycles: float
    min_segment_cycles: float
    tangential_share: float


def planner_constants(profile: MachineProfile | None) -> PlannerConstants:
    """The planner constants of `profile` (the mechanisms' defaults without one): the values the simulation
    runs with, so a profile that changes them (e.g. one `feedlog diagnose` extended) changes both."""
    blend, plan = mechanism_params(profile, "blend_arc"), mechanism_params(profile, "lookahead")
    return PlannerConstants(kink_ratio=float(blend["kink_ratio"]), gap_cycles=float(blend["gap_cycles"]),
                            min_segment_cycles=float(plan["min_piece_cycles"]),
                            tangential_share=float(plan["arc_acc_ratio_tangential"]))


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


def junction_kink(source: pd.DataFrame, profile: MachineProfile) -> np.ndarray:
    """Per program block, the direction change at its end junction as LinuxCNC's tangent check weighs
    it: max over the linear axes of |u_next - u| / acc_max (s^2/mm), u the unit direction of this and
    of the next block that moves the linear axes. NaN where a G2/G3 arc or no such next block is
    involved (`kinematic_time` then uses the corner angle)."""
    out = np.full(len(source), np.nan)
    lin = [a for a in ("x", "y", "z") if f"{a}_mm" in source and f"{a}0_mm" in source and a in profile.axes]
    if not lin:
        return out
    d = np.column_stack([np.nan_to_num((source[f"{a}_mm"] - source[f"{a}0_mm"]).to_numpy(np.float64)) for a in lin])
    norm = np.sqrt(np.einsum("ij,ij->i", d, d))
    idx = np.flatnonzero(norm > 0)
    if len(idx) < 2:
        return out
    u = d[idx] / norm[idx, None]
    acc = np.array([profile.axes[a].acc_max for a in lin], np.float64)
    kink = (np.abs(u[1:] - u[:-1]) / np.where(acc > 0, acc, np.inf)).max(axis=1)
    if "radius_mm" in source:
        radius = np.nan_to_num(source["radius_mm"].to_numpy(np.float64))[idx]
        kink = np.where((radius[1:] > 0) | (radius[:-1] > 0), np.nan, kink)
    out[idx[:-1]] = kink
    return out


def kinematic_time(length: np.ndarray, feed_mm_min: np.ndarray, acc: np.ndarray, vel: np.ndarray,
                   tol_mm: np.ndarray, corner_end_deg: np.ndarray, rapid: np.ndarray,
                   servo_period_s: float, rotary: np.ndarray | None = None,
                   arc_acc: float | None = None, kink: np.ndarray | None = None,
                   merge: np.ndarray | None = None, planner: PlannerConstants | None = None) -> np.ndarray:
    """Per block the trapezoid time (s) of one program, blocks in order (see the module text).

    `rotary` marks blocks that turn a rotary axis: a continuous-mode junction next to one is a
    parabolic blend (the block ending in it at half acceleration and from rest to rest, the next
    block starting while it decelerates from the blend speed). `arc_acc` (mm/s^2): the acceleration
    limit of a blend arc's plane (the smallest linear axis acceleration); else the blocks' path limits.
    `kink` (s^2/mm): per block, the direction change at its end junction as LinuxCNC's tangent check
    weighs it, max over the linear axes of |u_next - u| / acc_max (`junction_kink`); else the turn
    2 sin(half) over the arc plane's (or the block's path) acceleration. `merge` marks blocks the
    interpreter may join with their neighbours (G64 with Q > 0): LinuxCNC's segment is then longer
    than the block, so neither the tangent check nor the segment clamp applies there. `planner`: the
    planner constants (`planner_constants`; default: those of the sim mechanisms' defaults).
    """
    pc = planner_constants(None) if planner is None else planner
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
    a_plane = np.minimum(acc, nxt_acc) if arc_acc is None else np.full(n, float(arc_acc))
    a_corner = BLEND_NORMAL_SHARE * a_plane
    v_end = np.minimum(np.minimum(cruise, nxt_cruise), np.sqrt(a_corner * radius))
    rapid = np.asarray(rapid, bool)
    mode_change = np.append(rapid[nxt] != rapid[:-1], True)
    exact = np.nan_to_num(tol, nan=1.0) == 0
    stop = exact | (turn >= np.pi) | mode_change
    rot = np.zeros(n, bool) if rotary is None else np.asarray(rotary, bool)
    rot_junction = rot | np.append(rot[nxt], False)
    para = rot_junction & ~stop
    # LinuxCNC's tangent check (tpSetupTangent): a junction whose direction change needs under
    # kink_ratio of the axis acceleration in one servo cycle, at both lines' speed caps (feed, length
    # per cycle), is passed without an arc at that speed; the blocks' acceleration drops by the share
    tangent = np.zeros(n, bool)
    scale = np.zeros(n)
    own = np.ones(n, bool) if merge is None else ~np.asarray(merge, bool)  # the block is its own segment
    own_pair = own & np.append(own[nxt], True)  # ... and so is the one after its end junction
    if servo_period_s > 0:
        v_line = np.minimum(cruise, length / servo_period_s)
        v_kink = np.minimum(v_line, np.append(v_line[nxt], 0.0))
        by_angle = 2 * np.sin(half) / a_plane
        kink = by_angle if kink is None else np.where(np.isfinite(kink), kink, by_angle)
        scale = np.nan_to_num((v_kink / servo_period_s + nxt_acc) * np.asarray(kink, np.float64))
        tangent = ~stop & ~para & (half > 0) & (scale < pc.kink_ratio) & own_pair
        v_end = np.where(tangent, np.minimum(np.minimum(cruise, nxt_cruise), v_kink), v_end)
    # G61 corners without a rotary move keep LinuxCNC's kink reduction: both blocks at 90 % acceleration
    kink_g61 = exact & (turn > KINK_MIN_RAD) & (turn < np.pi) & ~mode_change & ~rot_junction
    reduce = np.where(kink_g61, pc.kink_ratio, np.where(tangent, scale, 0.0))
    reduce = np.maximum(reduce, np.append(0.0, reduce[:-1]))
    acc = acc * (1.0 - reduce)
    acc = np.where(para, acc / 2, acc)
    # blend arcs take at most half the path acceleration along the path (LinuxCNC's tangential share):
    # lowered by the share of the block the arcs at its two ends cover (each R tan(half) long)
    arc = ~stop & ~para & (half > 0) & ~tangent
    with np.errstate(invalid="ignore"):
        d_arc = np.where(arc, np.minimum(radius * np.tan(half), np.minimum(length, nxt_len) / 2), 0.0)
    cover = np.clip((d_arc + np.append(0.0, d_arc[:-1])) / np.where(length > 0, length, 1.0), 0.0, 1.0)
    line_acc = acc
    arc_cap = np.where(arc, v_end, 0.0)  # the arc's own speed limit, before look-ahead
    with np.errstate(invalid="ignore"):
        s_arc = np.where(arc, np.nan_to_num(radius * half), 0.0)  # half of the arc
    # LinuxCNC's segments last at least min_segment_cycles servo cycles over what the arcs left of a
    # line (a 0.02 mm block with an arc at one end keeps a 0.01 mm segment: under 10 mm/s); a rest
    # shorter than gap_cycles cycles at the arc's speed rides with the arc at its end
    line_cruise = cruise
    if servo_period_s > 0:
        t_min = pc.min_segment_cycles * servo_period_s
        rest = np.maximum(length - d_arc - np.append(0.0, d_arc[:-1]), 0.0)
        eaten = arc & (rest < pc.gap_cycles * servo_period_s * arc_cap)
        seg_cap = np.where(arc & own_pair, (2 * s_arc + np.where(eaten, rest, 0.0)) / t_min, BIG)
        rest_cap = np.where(eaten | (rest <= 0) | ~own, BIG, rest / t_min)
        arc_cap = np.where(arc, np.minimum(arc_cap, seg_cap), arc_cap)
        line_cruise = np.minimum(cruise, np.where(eaten, np.maximum(arc_cap, 1e-9), rest_cap))
        v_end = np.minimum(v_end, np.minimum(seg_cap, np.minimum(rest_cap, np.append(rest_cap[nxt], BIG))))
    acc = acc * (1.0 - (1.0 - pc.tangential_share) * cover)
    v_tri = np.minimum(np.sqrt(acc * length), cruise)
    # deviation of the parabola: v <= 2 sqrt(a P / sin(corner / 2)) (LinuxCNC's blend tolerance rule)
    with np.errstate(divide="ignore", invalid="ignore"):
        v_tol = np.where(np.isfinite(tol) & (half > 0), 2 * np.sqrt(acc * np.nan_to_num(tol) / np.sin(half)), BIG)
    v_end = np.where(para, np.minimum(np.minimum(v_tri, np.append(v_tri[nxt], 0.0)), v_tol), v_end)
    v_end = np.where(stop, 0.0, v_end)
    # look-ahead: every end speed reachable from the previous stop and able to meet the next one
    v_end = np.sqrt(reachable_speeds_sq(np.square(v_end), acc, length))
    # a parabolic blend joins two rest-to-rest moves: the next starts while this one decelerates
    v_blend = np.where(para, v_end, 0.0)
    v_end = np.where(para, 0.0, v_end)
    v_in = np.append(0.0, v_end[:-1])
    peak = np.minimum(line_cruise, np.sqrt(acc * length + np.square(v_in) / 2))
    time = trapezoid_time(length, v_in, v_end, line_cruise, acc) - np.minimum(v_blend, peak) / acc
    # a block with blend arcs at its ends: the half arcs at no more than their own speed, the line between
    plain = ~para & ~np.append(False, para[:-1])
    pieces = plain & (arc | np.append(False, arc[:-1])) & (length > 0)
    if pieces.any():
        time = np.where(pieces, arc_pieces_time(length, v_in, v_end, line_cruise, line_acc, d_arc, s_arc, arc_cap,
                                                 pc.tangential_share), time)
    return np.where(length > 0, np.maximum(time, servo_period_s), 0.0)


def arc_pieces_time(length, v_in, v_end, cruise, acc, tangent, arc_len, cap, tangential_share):
    """Per block the time (s) of its three pieces: the second half of the blend arc at its start, the
    line left between the arcs' tangent points, the first half of the arc at its end. The block's
    length reaches to the corners; an arc replaces `tangent` of it at each end by `arc_len` of arc,
    run at no more than the arc's speed `cap` and at `tangential_share` of the acceleration (LinuxCNC
    plans a blend arc as a segment of its own). Arrays per block; `tangent`, `arc_len` and `cap` are
    per end junction (0 where no arc)."""
    t_s, t_e = np.append(0.0, tangent[:-1]), tangent
    s_s, s_e = np.append(0.0, arc_len[:-1]), arc_len
    c_s, c_e = np.append(0.0, cap[:-1]), cap
    line = np.maximum(length - t_s - t_e, 0.0)
    a_arc = tangential_share * acc
    u_s = np.where(s_s > 0, np.minimum(np.minimum(c_s, cruise), np.sqrt(np.square(v_in) + 2 * a_arc * s_s)), v_in)
    u_e = np.where(s_e > 0, np.minimum(np.minimum(c_e, cruise), np.sqrt(np.square(v_end) + 2 * a_arc * s_e)), v_end)
    u_s = np.minimum(u_s, np.sqrt(np.square(u_e) + 2 * acc * line))
    u_e = np.minimum(u_e, np.sqrt(np.square(u_s) + 2 * acc * line))
    with np.errstate(divide="ignore", invalid="ignore"):
        first = np.where(s_s > 0, trapezoid_time(s_s, v_in, u_s, np.maximum(c_s, 1e-9), a_arc), 0.0)
        last = np.where(s_e > 0, trapezoid_time(s_e, u_e, v_end, np.maximum(c_e, 1e-9), a_arc), 0.0)
        middle = np.where(line > 0, trapezoid_time(line, u_s, u_e, cruise, acc), 0.0)
    return np.nan_to_num(first) + np.nan_to_num(middle) + np.nan_to_num(last)


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
