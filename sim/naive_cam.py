"""Collinear merge ("naive CAM"): the interpreter joins nearly collinear G1 lines into one move.

Source: LinuxCNC emccanon.cc `see_segment` / `linkable` / `flush_segments` (G64 P- Q-; Q defaults to
P): consecutive straight feed moves without rotary motion are chained while every chained end point
stays within Q of the straight line from the chain's start to the newest end point, up to
`max_chain` points; the chain then goes to the planner as one line (reported with the last block's
line number). Merged-away blocks get no time in the block table.

Exactness note: a vectorised three-point test (the previous end point against the line from the
previous start to the new end) pre-selects the candidates; the exact test of all chained points
then runs in a short Python loop over the candidate runs only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.sim.context import Context
from feedlog.sim.mechanism import Mechanism
from feedlog.sim.path import KIND_LINEAR, projected_limits


@dataclass
class NaiveCamMerge(Mechanism):
    name = "naive_cam"
    kind = "limits"
    order = 5

    max_chain: int = 100

    def __post_init__(self) -> None:
        self.check_positive(max_chain=self.max_chain)

    def limit(self, ctx: Context) -> None:
        b = ctx.blocks
        n = len(b)
        if n < 2:
            return
        lin = b.linear_index
        tol = np.nan_to_num(b.merge_tol, nan=0.0)
        ok = (b.kind == KIND_LINEAR) & ~b.rotary & (b.length > 0) & ~b.stop_after & (tol > 0)
        # i can join the chain of i - 1 only if both are eligible, the feed is unchanged, and (pre-test)
        # the end of i - 1 lies within tol of the line from the start of i - 1 to the end of i
        p0, p1 = b.p0[:, lin], b.p1[:, lin]
        m = p1[1:] - p0[:-1]
        mm = np.einsum("ij,ij->i", m, m)
        t = np.clip(np.einsum("ij,ij->i", p1[:-1] - p0[:-1], m) / np.where(mm > 0, mm, 1.0), 0.0, 1.0)
        d3 = np.linalg.norm(p1[:-1] - (p0[:-1] + t[:, None] * m), axis=1)
        cand = ok[:-1] & ok[1:] & (b.feed[1:] == b.feed[:-1]) & (d3 <= tol[1:])
        if not cand.any():
            return
        keep = np.ones(n, bool)
        start_of = np.arange(n)       # for kept rows: the row whose start is the merged start
        idx = np.flatnonzero(cand) + 1  # rows that may join their predecessor
        # an isolated candidate (neither neighbour is one) forms the chain [i - 1, i], whose exact
        # test is the three-point pre-test it passed: merge those without the loop
        is_cand = np.zeros(n + 1, bool)
        is_cand[idx] = True
        alone = ~is_cand[idx - 1] & ~is_cand[idx + 1]
        keep[idx[alone] - 1] = False
        start_of[idx[alone]] = idx[alone] - 1
        idx = idx[~alone]
        # plain Python values for the loop, aligned with idx (ends and starts of i and i - 1)
        e_cur, s_cur = p1[idx].tolist(), p0[idx].tolist()
        e_prev, s_prev = p1[idx - 1].tolist(), p0[idx - 1].tolist()
        max_chain = self.max_chain
        dropped: list[int] = []      # rows merged into the next one
        joined: list[int] = []       # rows joined to a chain
        joined_start: list[int] = []  # the start row of that chain
        chain_start, chain_len, pts, s0 = -1, 0, [], None
        prev = -2
        for i, e_i, s_i, e_p, s_p, tol_i in zip(idx.tolist(), e_cur, s_cur, e_prev, s_prev, tol[idx].tolist()):
            if i != prev + 1 or chain_start < 0:
                chain_start, chain_len, pts, s0 = i - 1, 1, [e_p], s_p
            # _within(pts, s0, e_i, tol_i) written out: the same float operations, no calls
            ok = chain_len <= max_chain
            if ok:
                sx, sy, sz = s0
                mx, my, mz = e_i[0] - sx, e_i[1] - sy, e_i[2] - sz
                mm = mx * mx + my * my + mz * mz
                tol2 = tol_i * tol_i
                for px, py, pz in pts:
                    dx, dy, dz = px - sx, py - sy, pz - sz
                    if mm <= 0:
                        t = 0.0
                    else:
                        t = (dx * mx + dy * my + dz * mz) / mm
                        t = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
                    ex, ey, ez = dx - t * mx, dy - t * my, dz - t * mz
                    if ex * ex + ey * ey + ez * ez > tol2:
                        ok = False
                        break
            if ok:
                dropped.append(i - 1)
                joined.append(i)
                joined_start.append(chain_start)
                pts.append(e_i)
                chain_len += 1
            else:  # the chain ending at i - 1 is flushed; i starts a new one
                chain_start, chain_len, pts, s0 = i, 1, [e_i], s_i
            prev = i
        if dropped:
            keep[np.asarray(dropped)] = False
            start_of[np.array(joined, dtype=np.int64)] = np.array(joined_start, dtype=np.int64)
        merged = np.flatnonzero(keep & (start_of != np.arange(n)))
        if not len(merged):
            return
        b.p0[merged] = b.p0[start_of[merged]]
        delta = b.p1[merged] - b.p0[merged]
        length = np.linalg.norm(delta[:, lin], axis=1)
        vel = np.array([ctx.profile.axes[a].vel_max for a in b.axes])
        acc = np.array([ctx.profile.axes[a].acc_max for a in b.axes])
        v_axis, a_axis = projected_limits(delta, length, vel, acc)
        b.length[merged] = length
        b.v_axis[merged] = v_axis
        b.v_limit[merged] = np.minimum(v_axis, ctx.profile.interpolator.path_vel_max_mm_s)
        b.a_max[merged] = a_axis
        ctx.blocks = b.take(np.flatnonzero(keep))
        ctx.notes["merged_blocks"] = int(n - keep.sum())
