"""Arcs as chords: `linearize` for consumers that need segments, `cl_points` for alignment.

An arc is cut into n equal-angle chords, the fewest whose deviation from the arc, r (1 - cos(dphi/2)),
stays within `chord_tol_mm`, and never more than 90 deg each. Radius (spiral arcs), the helical rise
and rotary axes vary linearly with the angle along the arc, as the interpolator moves them.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from feedlog.errors import FeedlogError
from feedlog.toolpath import arcs
from feedlog.toolpath.offsets import WORK_OFFSET_COLUMNS
from feedlog.toolpath.program import K_ARC_CCW, K_ARC_CW, Program, kind_codes
from feedlog.toolpath.schema import ARC_CCW, ARC_CW, AXES, END_COLUMNS, LINEAR, MOTION_KINDS, START_COLUMNS

DEFAULT_CHORD_TOL_MM = 0.001


def _check_tol(chord_tol_mm: float) -> None:
    if not chord_tol_mm > 0:
        raise FeedlogError(f"chord_tol_mm must be > 0, got {chord_tol_mm}")


def segments_per_block(blocks: pd.DataFrame, chord_tol_mm: float) -> np.ndarray:
    """Number of chords for each row: 1 for everything but arcs."""
    kind = kind_codes(blocks["kind"])
    n_seg = np.ones(len(blocks), dtype=np.int64)
    arc = (kind == K_ARC_CW) | (kind == K_ARC_CCW)
    if arc.any():
        r = np.maximum(blocks["radius_mm"].to_numpy()[arc], 1e-12)
        swept = np.radians(blocks["sweep_deg"].to_numpy()[arc])
        step = 2.0 * np.arccos(np.clip(1.0 - chord_tol_mm / r, -1.0, 1.0))
        step = np.minimum(step, np.pi / 2)
        n_seg[arc] = np.maximum(1, np.ceil(swept / step - 1e-9)).astype(np.int64)
    return n_seg


def _expand(blocks: pd.DataFrame, chord_tol_mm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows repeated per chord: (source row per output row, end points (m, 6), fraction along block)."""
    n_seg = segments_per_block(blocks, chord_tol_mm)
    src = np.repeat(np.arange(len(blocks)), n_seg)
    first = np.cumsum(n_seg) - n_seg
    k = np.arange(len(src)) - first[src] + 1
    frac = k / n_seg[src]
    p0 = blocks[list(START_COLUMNS)].to_numpy()
    p1 = blocks[list(END_COLUMNS)].to_numpy()
    end = p1[src].copy()
    kind = kind_codes(blocks["kind"])
    is_arc = (kind == K_ARC_CW) | (kind == K_ARC_CCW)
    arc_out = is_arc[src] & (n_seg[src] > 1)
    if arc_out.any():
        a = np.flatnonzero(is_arc)
        local = np.full(len(blocks), -1)
        local[a] = np.arange(len(a))
        idx = arcs.plane_index(blocks["plane"].to_numpy()[a])
        s = arcs.to_plane(p0[a, :3], idx)
        e = arcs.to_plane(p1[a, :3], idx)
        c = arcs.to_plane(blocks[["cx_mm", "cy_mm", "cz_mm"]].to_numpy()[a], idx)
        r0 = np.hypot(s[:, 0] - c[:, 0], s[:, 1] - c[:, 1])
        r1 = np.hypot(e[:, 0] - c[:, 0], e[:, 1] - c[:, 1])
        a0 = np.arctan2(s[:, 1] - c[:, 1], s[:, 0] - c[:, 0])
        swept = np.radians(blocks["sweep_deg"].to_numpy()[a])
        ccw = kind[a] == K_ARC_CCW
        owner = local[src[arc_out]]
        uvw = arcs.sample(s, c[:, :2], r0, r1, a0, swept, ccw, e[:, 2] - s[:, 2], frac[arc_out], owner)
        end[arc_out, :3] = arcs.from_plane(uvw, idx[owner])
        f = frac[arc_out, None]
        end[arc_out, 3:] = p0[src[arc_out], 3:] + (p1[src[arc_out], 3:] - p0[src[arc_out], 3:]) * f
        last = frac[arc_out] == 1.0
        end[np.flatnonzero(arc_out)[last]] = p1[src[arc_out][last]]  # exact block end points
    return src, end, frac


def linearize(program: Program | pd.DataFrame, chord_tol_mm: float) -> Program:
    """A copy of `program` (a Program or its block table) whose arcs are G1 chords within
    `chord_tol_mm`; every chord keeps its arc's `block` and `line` (so `block` is no longer unique)
    and `segment` numbers the chords."""
    _check_tol(chord_tol_mm)
    if isinstance(program, pd.DataFrame):
        program = Program(blocks=program)
    blocks = program.blocks
    src, end, _ = _expand(blocks, chord_tol_mm)
    out = blocks.iloc[src].reset_index(drop=True)
    start = np.vstack([blocks[list(START_COLUMNS)].to_numpy()[:1], end[:-1]]) if len(end) else end
    if len(src):  # a block's first chord starts at the block's start (its own work coordinates)
        first_chord = np.r_[True, src[1:] != src[:-1]]
        start[first_chord] = blocks[list(START_COLUMNS)].to_numpy()[src[first_chord]]
    out[list(END_COLUMNS)] = end
    out[list(START_COLUMNS)] = start
    was_arc = out["kind"].isin([ARC_CW, ARC_CCW]).to_numpy()
    out.loc[was_arc, "kind"] = LINEAR
    out.loc[was_arc, ["cx_mm", "cy_mm", "cz_mm", "radius_mm", "sweep_deg"]] = np.nan
    out.loc[was_arc, "turns"] = 0
    moving = out["kind"].isin(MOTION_KINDS).to_numpy()
    d = end[:, :3] - start[:, :3]
    out["length_mm"] = np.where(moving, np.linalg.norm(d, axis=1), 0.0)
    first = np.r_[True, src[1:] != src[:-1]] if len(src) else np.zeros(0, bool)
    out["segment"] = np.arange(len(src)) - np.maximum.accumulate(np.where(first, np.arange(len(src)), 0))
    meta = {**program.metadata, "linearized_chord_tol_mm": chord_tol_mm}
    return Program(blocks=out, path=program.path, warnings=list(program.warnings),
                   unsupported=list(program.unsupported), metadata=meta)


FRAMES = ("program", "machine")


def cl_points(program: Program | pd.DataFrame, chord_tol_mm: float = DEFAULT_CHORD_TOL_MM, *,
              frame: str = "program") -> pd.DataFrame:
    """Ordered cutter-location points: the start point (block -1), then the end of every motion
    block, arcs as chord end points within `chord_tol_mm`.

    `frame="program"`: positions in program (work) coordinates, as in the block table, each point in
    the coordinates of its block; `frame="machine"`: program + the block's work offset (`wx_mm` ...
    `wc_deg`), what a controller's axis positions show. Columns: `block`, `line`, `kind`, `x_mm` ...
    `c_deg`, `ori_i/j/k`, `feed_mm_min`, `s_mm` (cumulative TCP path length along the chords, measured
    in machine coordinates, so a change of work offset between blocks is no jump), `wx_mm` ... `wc_deg`
    (the block's work offset; the start point takes the first motion block's).
    """
    _check_tol(chord_tol_mm)
    if frame not in FRAMES:
        raise FeedlogError(f"frame must be one of {FRAMES}, got {frame!r}")
    blocks = getattr(program, "blocks", program)
    kc = kind_codes(blocks["kind"])
    m = blocks[(kc >= 0) & (kc <= K_ARC_CCW)]
    src, end, _ = _expand(m, chord_tol_mm)
    names = [f"{a}_{'mm' if a in 'xyz' else 'deg'}" for a in AXES]
    pts = np.vstack([m[list(START_COLUMNS)].to_numpy()[:1], end]) if len(m) else np.zeros((0, 6))
    if all(c in m.columns for c in WORK_OFFSET_COLUMNS) and len(m):
        w_blk = m[list(WORK_OFFSET_COLUMNS)].to_numpy(dtype=np.float64)
        work = np.vstack([w_blk[:1], w_blk[src]])
    else:
        work = np.zeros_like(pts)
    machine = pts + work
    step = np.linalg.norm(np.diff(machine[:, :3], axis=0), axis=1)
    if frame == "machine":
        pts = machine
    out = pd.DataFrame(pts, columns=names)
    block = m["block"].to_numpy()[src]
    line = m["line"].to_numpy()[src]
    out.insert(0, "block", np.r_[-1, block].astype(np.int32) if len(m) else np.zeros(0, np.int32))
    out.insert(1, "line", np.r_[line[:1], line].astype(np.int32) if len(m) else np.zeros(0, np.int32))
    kind = kind_codes(m["kind"])[src]
    out.insert(2, "kind", pd.Categorical.from_codes(np.r_[-1, kind] + 1 if len(m) else np.zeros(0, np.int8),
                                                    categories=["start", *MOTION_KINDS]))
    for col in ("ori_i", "ori_j", "ori_k", "feed_mm_min"):
        vals = m[col].to_numpy()[src]
        out[col] = np.r_[vals[:1], vals] if len(m) else []
    out["s_mm"] = np.r_[0.0, np.cumsum(step)] if len(m) else []
    for j, col in enumerate(WORK_OFFSET_COLUMNS):
        out[col] = work[:, j]
    return out
