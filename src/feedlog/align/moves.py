"""Planner moves: which program blocks LinuxCNC runs as one move, and where each move's line shows.

LinuxCNC 2.9 (read in src/emc/task/emccanon.cc and src/emc/tp/tp.c):

- **Merge (canon layer).** Under G64 P.. Q.. (Q > 0, Q defaults to P) `STRAIGHT_FEED` does not send a
  line to the planner at once: `see_segment` collects end points in `chained_points` while `linkable`
  holds (continuous mode, no rotary/UVW change, not zero length, at most ~100 points, every chained end
  point within Q of the straight line from the last sent end point to the new one). `flush_segments`
  then sends ONE line from the last sent end point to the chain's last point, with the chain's last line
  number. So a merged move is exactly the chord of whole blocks; the blocks before its last one never
  show in `motion.program-line`. feedlog.sim models this as its `naive_cam` mechanism
  (`NaiveCamMerge`); `planner_moves` runs that mechanism on the program and reads off the chains.
- **Blends (planner).** Between two xyz moves the planner inserts a blend arc. The arc is queued when
  the next move is added and takes the next move's id (`tp->nextId`), i.e. its line: the line switches
  where the tool leaves the straight move into the blend. When the straight rest of a move left over by
  its two blends would take less than `ARC_BLEND_GAP_CYCLES` servo cycles (INI [TRAJ], default 4, the
  profile's `[sim.blend_arc] gap_cycles`; `blendCheckConsume` in src/emc/tp/blendmath.c: rest length /
  planned speed), the next blend arc
  *consumes* it (`param.consume`, `tcqPopBack`, the rest added to the arc as `line_length`): the move's
  line shows only during the blend INTO it; the next line starts where the tool arrives on its chord.
  Moves with rotary motion (or into one) blend parabolically, not by arcs, and are not consumed this way.

Geometry boundaries from this: a straight move ends at the first sample off its chord after the last
sample on it (`move_leave_times`); when its on-chord run lasts less than the gap cycles (measured from
where the blends meet the chord tangentially), at the first sample of that run. A move whose chord the
path only touches ends at the touching point; one never near its chord gets zero time at the end of
the move before it. Blocks inside a move end where the tool passes their end point (their CL match),
never after the move's end.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from feedlog.align.blocks import NO_TIME, SHORT_LEAVE_SAMPLES, MotionSpan, _last_on, blocks_from_geometry
from feedlog.align.feed import LINEAR
from feedlog.align.pipeline import STRAIGHT, Alignment, position_quantum
from feedlog.errors import AlignmentError, FeedlogError
from feedlog.profile import MachineProfile
from feedlog.ingest.subroutine_files import load_recorded_program
from feedlog.recording import PROFILE_ATTACHMENT, Recording
from feedlog.sim.mechanism import mechanism_params
from feedlog.toolpath import Program, to_machine


def planner_moves(program: Program, profile: MachineProfile) -> np.ndarray:
    """Per motion block of `program.motion` (in order): the index of the planner move it belongs to
    (0, 1, ...; consecutive blocks merged by LinuxCNC's collinear merge share one index). The chains
    come from feedlog.sim's `naive_cam` mechanism run on the program's blocks with `profile`'s axes."""
    from feedlog.sim.context import Context  # sim is only needed for this model
    from feedlog.sim.naive_cam import NaiveCamMerge
    from feedlog.sim.path import prepare_blocks

    motion_block = program.motion["block"].to_numpy(dtype=np.int64)
    if len(motion_block) == 0:
        return np.zeros(0, dtype=np.int64)
    try:
        blocks = prepare_blocks(program, profile)
    except FeedlogError as exc:  # a program the simulator refuses (e.g. an axis the profile lacks)
        raise AlignmentError(f"{program.name}: cannot model LinuxCNC's collinear merge ({exc})") from exc
    ctx = Context(profile=profile, blocks=blocks)
    NaiveCamMerge().limit(ctx)
    ends = np.sort(np.asarray(ctx.blocks.block, dtype=np.int64))
    # a block belongs to the first remaining (chain-end) block at or after it
    move = np.searchsorted(ends, motion_block, side="left")
    move = np.minimum(move, len(ends) - 1) if len(ends) else np.zeros(len(motion_block), np.int64)
    # renumber 0.. over the motion blocks (dwells among the sim blocks leave gaps)
    _, dense = np.unique(move, return_inverse=True)
    return dense.astype(np.int64)


def move_leave_times(t_ns: np.ndarray, positions: np.ndarray, seg_start: np.ndarray, seg_end: np.ndarray,
                     end_index: np.ndarray, move: np.ndarray, *, on_path_mm: float = 1e-4,
                     touch_mm: float = 0.01, gap_cycles: float | None = None, arc_blends: np.ndarray | None = None,
                     search_s: float = 0.5) -> np.ndarray:
    """Per motion block: where the line switches, for the last block of each straight planner move.

    `seg_start`/`seg_end` (k, 3) are the blocks' straight segments in the measured frame (NaN rows:
    arcs and other non-straight blocks), `end_index` the fractional sample index of each block's end
    CL match (non-decreasing), `move` from `planner_moves`. A straight move (all its blocks straight)
    runs the chord from its first block's start to its last block's end; its last block gets the time
    of the first sample farther than `on_path_mm` from that chord after the last sample on it, searched
    among the samples after the previous move's end match up to its own end match (at most `search_s`
    before it). When the tool runs the chord for less than `gap_cycles` servo cycles (LinuxCNC's
    ARC_BLEND_GAP_CYCLES: the profile's `[sim.blend_arc] gap_cycles`, `moves_from_blocks` passes it;
    None: that mechanism's default, 4) between two blend arcs (`arc_blends`: per block, xyz-only motion;
    default all), the next blend consumed that straight rest and its line shows from where the tool
    arrived on the chord: that sample instead. A straight move whose chord the path only touches (the
    blends before and after it meet) ends at the touching point (nearest sample within `touch_mm`);
    one never within `touch_mm` of its chord gets the previous move's result (zero time). Other
    blocks: NO_TIME (their end is their CL match)."""
    if gap_cycles is None:
        gap_cycles = float(mechanism_params(None, "blend_arc")["gap_cycles"])
    t = np.asarray(t_ns, dtype=np.int64)
    p = np.asarray(positions, dtype=np.float64)[:, :3]
    a = np.asarray(seg_start, dtype=np.float64)
    b = np.asarray(seg_end, dtype=np.float64)
    mv = np.asarray(move, dtype=np.int64)
    n, k = len(t), len(a)
    out = np.full(k, NO_TIME, dtype=np.int64)
    if k == 0 or n < 2:
        return out
    if len(mv) != k or len(end_index) != k or (len(mv) and np.any(np.diff(mv) < 0)):
        raise AlignmentError(f"move_leave_times: need one non-decreasing move id per block ({k} blocks, "
                             f"{len(mv)} ids, {len(end_index)} end matches)")
    straight_blk = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    first = np.flatnonzero(np.r_[True, mv[1:] != mv[:-1]])    # first block of each move
    last = np.r_[first[1:] - 1, k - 1]                        # last block of each move
    all_straight = np.minimum.reduceat(straight_blk.astype(np.int8), first).astype(bool)
    ei = np.asarray(end_index, dtype=np.float64)
    has = np.isfinite(ei)
    hi_blk = np.maximum.accumulate(np.where(has, np.ceil(np.nan_to_num(ei, nan=0.0)), 0)).astype(np.int64)
    hi_blk = np.minimum(hi_blk, n - 1)
    hi = hi_blk[last]
    dt = np.diff(t)
    period = float(np.median(dt[dt > 0])) if (dt > 0).any() else 1.0
    lo = np.r_[0, hi[:-1] + 1]
    lo = np.maximum(lo, hi - int(np.ceil(search_s * 1e9 / period)) + 1)
    ok = all_straight & has[last] & (hi >= lo)
    rows = np.flatnonzero(ok)
    ca, cb = a[first[rows]], b[last[rows]]
    # the blend is short: look at the last samples before the end match first, then the whole window
    short = np.maximum(lo[rows], hi[rows] - SHORT_LEAVE_SAMPLES + 1)
    on = _last_on(t, p, rows, short, hi, ca, cb - ca, on_path_mm)
    retry = (on < 0) & (short > lo[rows])
    if retry.any():
        on[retry] = _last_on(t, p, rows[retry], lo[rows[retry]], hi, ca[retry], cb[retry] - ca[retry], on_path_mm)
    leave = np.full(len(first), NO_TIME, dtype=np.int64)
    found = on >= 0
    leave[rows[found]] = t[np.minimum(on[found] + 1, n - 1)]
    # a straight part shorter than `gap_cycles` servo cycles is consumed by the next blend arc (its
    # line shows from where the tool arrives on the chord): first sample of the on-chord run
    # (blend arcs join xyz lines only: moves with rotary motion, or into one, blend parabolically)
    arcs = np.ones(k, bool) if arc_blends is None else np.asarray(arc_blends, dtype=bool)
    arc_move = np.minimum.reduceat(arcs.astype(np.int8), first).astype(bool)
    arc_move &= np.r_[arc_move[1:], False]
    sel = found & arc_move[rows]
    if gap_cycles > 0 and sel.any():
        r, last_on, sa, sb = rows[sel], on[sel], ca[sel], cb[sel]
        upto = hi.copy()
        upto[r] = last_on
        # only a run shorter than gap_cycles matters: look at its last few samples first; a row with no
        # sample off the chord there is a long run (unless those samples span too little time: then the
        # whole window, as before)
        tail = np.maximum(lo[r], last_on - int(np.ceil(gap_cycles)) - 16)
        off_before = _last_on(t, p, r, tail, upto, sa, sb - sa, on_path_mm, off=True)
        unsure = (off_before < 0) & (tail > lo[r]) & (t[last_on] - t[tail] < gap_cycles * period)
        if unsure.any():
            off_before[unsure] = _last_on(t, p, r[unsure], lo[r[unsure]], upto, sa[unsure], sb[unsure] - sa[unsure],
                                          on_path_mm, off=True)
        first_on = off_before + 1
        arrive = _tangent_time(t, p, np.maximum(first_on - 1, 0), -1, sa, sb)
        depart = _tangent_time(t, p, np.minimum(last_on + 1, n - 1), 1, sa, sb)
        short_run = (off_before >= 0) & (last_on + 2 < n) & (depart - arrive < gap_cycles * period)
        leave[r[short_run]] = t[first_on[short_run]]
    # no straight stretch left: the blends before and after the move meet on its chord (the path only
    # touches it); the line switches at that touching point, the sample nearest the chord
    miss = rows[~found]
    if len(miss):
        touch_t, touch_d = _touch_times(t, p, lo[miss], hi[miss], a[first[miss]], b[last[miss]])
        hit = touch_d <= touch_mm
        leave[miss[hit]] = touch_t[hit]
        found[~found] = hit
    # consumed (or sub-period) straight moves: zero time where the move before them ended
    consumed = ok.copy()
    consumed[rows[found]] = False
    if consumed.any():
        known = np.where(leave != NO_TIME, np.arange(len(first)), -1)
        prev = np.maximum.accumulate(np.r_[-1, known[:-1]])   # last move before with a leave time
        c = np.flatnonzero(consumed & (prev >= 0))
        leave[c] = leave[prev[c]]
    out[last] = leave
    return out


def _seg_dist(p: np.ndarray, idx: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of samples p[idx[i]] to the segments a[i] -> b[i]."""
    d = b - a
    w = p[idx] - a
    u = np.clip((w * d).sum(axis=1) / np.maximum((d * d).sum(axis=1), 1e-300), 0.0, 1.0)
    return np.linalg.norm(w - u[:, None] * d, axis=1)


def _tangent_time(t: np.ndarray, p: np.ndarray, off_idx: np.ndarray, step: int, a: np.ndarray,
                  b: np.ndarray) -> np.ndarray:
    """Sub-sample time (float ns) where a blend meets the segment a -> b tangentially: off_idx is the
    sample just off the segment, off_idx + step the next one farther out. A circular blend leaves a
    tangent line as d = (v tau)^2 / 2R, so sqrt(d) is linear in time: extrapolated to zero, clipped to
    the interval next to off_idx."""
    n = len(t)
    i1 = np.clip(off_idx, 0, n - 1)
    i2 = np.clip(off_idx + step, 0, n - 1)
    i0 = np.clip(off_idx - step, 0, n - 1)     # the on-segment neighbour
    r1 = np.sqrt(_seg_dist(p, i1, a, b))
    r2 = np.sqrt(_seg_dist(p, i2, a, b))
    t1, t2, t0 = t[i1].astype(np.float64), t[i2].astype(np.float64), t[i0].astype(np.float64)
    grow = r2 - r1
    est = np.where(grow > 0, t1 - r1 * (t2 - t1) / np.where(grow > 0, grow, 1.0), t1)
    lo_t, hi_t = np.minimum(t0, t1), np.maximum(t0, t1)
    return np.clip(est, lo_t, hi_t)


def _touch_times(t: np.ndarray, p: np.ndarray, lo: np.ndarray, hi: np.ndarray, a: np.ndarray,
                 b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per window [lo[i], hi[i]] of samples: where the path touches the segment a[i] -> b[i] (time of
    the first sample after the sub-sample minimum of the distance, from a parabola through the nearest
    sample and its neighbours) and that least distance (mm)."""
    n = len(t)
    d = b - a
    dd = np.maximum((d * d).sum(axis=1), 1e-300)

    def dist(idx: np.ndarray, sel: np.ndarray) -> np.ndarray:
        w = p[idx] - a[sel, None, :]
        u = np.clip((w * d[sel, None, :]).sum(axis=2) / dd[sel, None], 0.0, 1.0)
        return np.sqrt(((w - u[..., None] * d[sel, None, :]) ** 2).sum(axis=2))

    best = np.zeros(len(lo), dtype=np.int64)
    dmin = np.full(len(lo), np.inf)
    width = int((hi - lo).max()) + 1 if len(lo) else 1
    for sel in np.array_split(np.arange(len(lo)), max(1, len(lo) * width // 2_000_000 + 1)):
        if not len(sel):
            continue
        idx = np.minimum(lo[sel, None] + np.arange(width)[None, :], n - 1)
        dist_w = np.where(idx <= hi[sel, None], dist(idx, sel), np.inf)
        j = width - 1 - np.argmin(dist_w[:, ::-1], axis=1)   # the last of equal minima
        best[sel] = idx[np.arange(len(sel)), j]
        dmin[sel] = dist_w[np.arange(len(sel)), j]
    sel = np.arange(len(lo))
    i0, i2 = np.maximum(best - 1, 0), np.minimum(best + 1, n - 1)
    three = dist(np.column_stack([i0, best, i2]), sel)
    curv = three[:, 0] - 2 * three[:, 1] + three[:, 2]
    shift = np.where(curv > 0, 0.5 * (three[:, 0] - three[:, 2]) / np.where(curv > 0, curv, 1.0), 0.0)
    shift = np.clip(shift, -0.5, 0.5)
    # the first sample after the minimum: the nearest one when the minimum lies before it
    at = np.where(shift < 0, best, np.minimum(best + 1, n - 1))
    return t[at], dmin


def clip_to_moves(end_ns: np.ndarray, move: np.ndarray) -> np.ndarray:
    """Block ends with every block of a move ending no later than the move's last block."""
    e = np.asarray(end_ns, dtype=np.int64)
    mv = np.asarray(move, dtype=np.int64)
    if len(e) == 0:
        return e.copy()
    first = np.flatnonzero(np.r_[True, mv[1:] != mv[:-1]])
    last = np.r_[first[1:] - 1, len(e) - 1]
    move_end = np.repeat(e[last], last - first + 1)
    return np.minimum(e, move_end)


def geometry_blocks_by_moves(recording: Recording, alignment: Alignment, *, program: Program | None = None,
                             profile: MachineProfile | None = None, positions: str = "axes") -> pd.DataFrame:
    """`alignment.geometry_blocks` recomputed with LinuxCNC's planner moves (`planner_moves`): straight
    moves end where the tool leaves their chord, consumed moves get zero time, blocks inside a move end
    at their CL match but never after the move. Uses the alignment's CL matches (points `t_ns`), motion
    span, standstill threshold and work offset; the departures from stops are those of
    `alignment.geometry_blocks` (a block that starts after its predecessor's end started at a departure).
    `program` and `profile` default to the ones attached to the recording. Adds column `move`."""
    src = recording.source or "recording"
    if program is None:
        if recording.program_text is None:
            raise AlignmentError(f"{src}: no program given and none attached (program.ngc)")
        program = load_recorded_program(recording, name=f"{src}:program.ngc")
    if profile is None:
        data = recording.attachments.get(PROFILE_ATTACHMENT)
        if data is None:
            raise AlignmentError(f"{src}: no machine profile given and none attached ({PROFILE_ATTACHMENT}); "
                                 "the merge model needs the machine's axes")
        profile = MachineProfile.from_toml(data.decode("utf-8"), source=f"{src}:{PROFILE_ATTACHMENT}")
    # align_recording keeps its per-block estimate apart when it already ran this model
    geo = alignment.geometry_blocks_base if alignment.geometry_blocks_base is not None else alignment.geometry_blocks
    if geo is None:
        raise AlignmentError(f"{src}: the alignment has no geometry blocks")
    return moves_from_blocks(recording, geo, alignment.points, alignment.report, program=program, profile=profile,
                             positions=positions)


def moves_from_blocks(recording: Recording, geo: pd.DataFrame, points: pd.DataFrame, report: dict, *,
                      program: Program, profile: MachineProfile, positions: str = "axes") -> pd.DataFrame:
    """`geometry_blocks_by_moves` from its parts: align's per-block geometry table `geo`, its CL points
    table and report (config, still_mm, motion span), as `align_recording` has them before it returns."""
    axes = recording.stream(positions)
    t = axes["t_ns"].to_numpy(dtype=np.int64)
    xyz = axes[list(LINEAR)].to_numpy(dtype=np.float64)
    motion = program.motion.reset_index(drop=True)
    if len(motion) != len(geo) or (motion["block"].to_numpy() != geo["block"].to_numpy()).any():
        raise AlignmentError(f"{program.name}: the alignment's blocks are not this program's motion blocks")
    offset = np.asarray(report.get("config", {}).get("work_offset_mm", (0.0, 0.0, 0.0)), dtype=np.float64)
    last_pt = points.groupby("block")["t_ns"].last().reindex(motion["block"]).to_numpy()
    arrival = np.where(last_pt == NO_TIME, geo["t_end_ns"].to_numpy(), last_pt).astype(np.int64)
    end_index = np.interp(arrival.astype(np.float64), t.astype(np.float64), np.arange(len(t), dtype=np.float64))
    start = geo["t_start_ns"].to_numpy(dtype=np.int64)
    end = geo["t_end_ns"].to_numpy(dtype=np.int64)
    departure = np.r_[np.where(start[1:] > end[:-1], start[1:], arrival[:-1]), arrival[-1]]
    straight = motion["kind"].astype(str).isin(STRAIGHT).to_numpy()[:, None]
    in_machine = to_machine(motion)
    p0 = in_machine[["x0_mm", "y0_mm", "z0_mm"]].to_numpy(dtype=np.float64) + offset
    p1 = in_machine[["x_mm", "y_mm", "z_mm"]].to_numpy(dtype=np.float64) + offset
    on_path = max(float(report.get("config", {}).get("on_path_mm", 1e-6)), 2 * position_quantum(xyz),
                  float(report.get("still_mm", 0.0)))
    move = planner_moves(program, profile)
    rotary = np.zeros(len(motion), dtype=bool)
    for ax in ("a", "b", "c"):
        if f"{ax}_deg" in motion.columns and f"{ax}0_deg" in motion.columns:
            turn = (motion[f"{ax}_deg"] - motion[f"{ax}0_deg"]).abs().to_numpy(dtype=np.float64)
            rotary |= np.nan_to_num(turn, nan=0.0) > 1e-9
    leave = move_leave_times(t, xyz, np.where(straight, p0, np.nan), np.where(straight, p1, np.nan), end_index,
                             move, on_path_mm=on_path, arc_blends=~rotary,
                             gap_cycles=float(mechanism_params(profile, "blend_arc")["gap_cycles"]))
    span = MotionSpan(t_start_ns=int(report["motion"]["t_start_ns"]), t_end_ns=int(report["motion"]["t_end_ns"]),
                      first_index=0, last_index=len(t) - 1)
    # blocks inside a move: their own end is their CL match (arrival); the move's last block: the leave
    use = (leave != NO_TIME) & (leave < arrival)
    ends = clip_to_moves(np.where(use, leave, arrival), move)
    out = blocks_from_geometry(motion, arrival, departure, span=span, end_leave_ns=ends)
    out["source"] = "geometry"
    out["move"] = move
    return out
