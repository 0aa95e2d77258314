"""Collinear merge ("naive CAM"): the interpreter joins nearly collinear G1 lines into one move.

Source: LinuxCNC emccanon.cc `see_segment` / `linkable` / `flush_segments` (G64 P- Q-; Q defaults to
P): consecutive straight feed moves without rotary motion are chained while every chained end point
stays within Q of the straight line from the chain's start to the newest end point, up to
`max_chain` points; the chain then goes to the planner as one line (reported with the last block's
line number). Merged-away blocks get no time in the block table.

Flat arcs go in too (`arcs_as_lines`, on in the LinuxCNC profiles): in continuous mode (G64) in the XY plane, LinuxCNC's canon
(emccanon.cc `ARC_FEED`, `chord_deviation`) sends an arc whose chord deviation r (1 - cos(sweep / 2))
is below Q as two straight segments, start -> the arc's midpoint -> end, into the same merge; the
motion controller then runs lines (with a line's projected acceleration, up to sqrt(2) times an arc's
on a diagonal) where the program has arcs. Short tangent arcs (a spline's biarcs, CAM arc fits) are
mostly such arcs. A block whose two halves end up in different chains has two rows (both with its
block number; the block table gives it the first start and the last end).

How it is computed (`chains`): a three-point pre-test (the previous end point against the line from
the previous start to the new end) finds the rows that may join their predecessor; an isolated
candidate forms the chain [i - 1, i] that the pre-test already decided. Runs of candidates are
walked chain by chain, all runs at once: each step tests, for every run's open chain, the next few
rows (4, then up to 16, then up to `max_chain` + 1) against all the chain's points in one flat array,
and the first failing row starts the run's next chain. The float operations are those of the
sequential loop of emccanon.cc's test, so the chains are the same to the last bit
(tests/sim/test_naive_cam.py compares against that loop).

In a windowed simulation (feedlog.sim.window) the chain still open at the window's end stays
pending, and the next window starts at its first row (`lead_candidate`: that row began a chain after
a failed test, as opposed to after a row that could not join).
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from feedlog.sim.context import Context
from feedlog.sim.mechanism import Mechanism
from feedlog.sim.path import KIND_ARC, KIND_LINEAR, Blocks, projected_limits


def _ragged(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(owner, position) of a flat array holding counts[k] items for each k, positions 0..counts[k]-1."""
    total = int(counts.sum())
    owner = np.repeat(np.arange(len(counts)), counts)
    starts = np.cumsum(counts) - counts
    return owner, np.arange(total) - starts.take(owner)


def _fails(p0: np.ndarray, p1: np.ndarray, tol: np.ndarray, c: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Whether row c + t may not join the chain c .. c + t - 1: some chained end point p1[c + q]
    (q < t) lies farther than tol[c + t] from the segment p0[c] -> p1[c + t]. The operations and their
    order are emccanon's test in floats, point by point."""
    pair, q = _ragged(t)
    cs = c.take(pair)
    ends = cs + t.take(pair)
    pts = cs + q
    s = [p0[:, j].take(cs) for j in range(3)]
    mx, my, mz = (p1[:, j].take(ends) - s[j] for j in range(3))
    dx, dy, dz = (p1[:, j].take(pts) - s[j] for j in range(3))
    mm = mx * mx + my * my + mz * mz
    with np.errstate(divide="ignore", invalid="ignore"):
        u = (dx * mx + dy * my + dz * mz) / mm
    u = np.where(mm <= 0, 0.0, np.clip(u, 0.0, 1.0))
    ex, ey, ez = dx - u * mx, dy - u * my, dz - u * mz
    tol_e = tol.take(ends)
    bad = ex * ex + ey * ey + ez * ez > tol_e * tol_e
    out = np.zeros(len(t), dtype=bool)
    out[pair[bad]] = True
    return out


MEMO_SIZE = 64   # chain results kept (`remembered_chains`): a fit re-simulates a few programs thousands of times
_MEMO: OrderedDict[bytes, tuple[np.ndarray, np.ndarray, int]] = OrderedDict()


def remembered_chains(p0: np.ndarray, p1: np.ndarray, cand: np.ndarray, tol: np.ndarray, max_chain: int, *,
                      lead_candidate: bool = False) -> tuple[np.ndarray, np.ndarray, int]:
    """`chains`, remembered by a digest of its inputs: the chains follow from the geometry, the pre-test
    and the tolerances alone, which a fit that changes limits or the feed override leaves as they were."""
    digest = hashlib.blake2b(digest_size=20)
    for a in (p0, p1, cand, tol):
        a = np.ascontiguousarray(a)
        digest.update(f"{a.dtype.str}{a.shape}".encode())
        digest.update(a.tobytes())
    digest.update(f"{int(max_chain)} {bool(lead_candidate)}".encode())
    key = digest.digest()
    hit = _MEMO.get(key)
    if hit is None:
        hit = chains(p0, p1, cand, tol, max_chain, lead_candidate=lead_candidate)
        _MEMO[key] = hit
        if len(_MEMO) > MEMO_SIZE:
            _MEMO.popitem(last=False)
    else:
        _MEMO.move_to_end(key)
    start, end, open_from = hit
    return start.copy(), end.copy(), open_from


def chains(p0: np.ndarray, p1: np.ndarray, cand: np.ndarray, tol: np.ndarray, max_chain: int, *,
           lead_candidate: bool = False) -> tuple[np.ndarray, np.ndarray, int]:
    """The merge chains of n rows. `cand[i - 1]`: row i may join row i - 1 (the pre-test, n - 1 values);
    `lead_candidate`: row 0 began a chain after a failed test (a window that starts mid-run).

    Returns (start, end, open_from): chains of rows start..end (end > start) that merge into row end,
    and the first row of the chain that holds the last row (it may still grow with later rows)."""
    n = len(p0)
    is_cand = np.zeros(n + 1, bool)
    is_cand[1:n] = cand
    is_cand[0] = lead_candidate and n > 0
    idx = np.flatnonzero(is_cand[1:n]) + 1
    alone = ~is_cand[idx - 1] & ~is_cand[idx + 1]
    starts = [idx[alone] - 1]
    ends = [idx[alone]]
    rest = idx[~alone]
    open_from = n - 1
    if n and is_cand[n - 1] and len(idx) and alone[-1]:
        open_from = n - 2
    if len(rest):
        brk = np.flatnonzero(np.diff(rest) != 1) + 1
        first = rest[np.r_[0, brk]]
        last = rest[np.r_[brk - 1, len(rest) - 1]]
        c = first - 1                  # open chain start per run
        done = np.zeros(len(c), dtype=np.int64)   # rows after c already tested and joined
        active = np.arange(len(c))
        while len(active):
            ca, la, da = c[active], last[active], done[active]
            room = la - ca             # rows after c left in the run
            t_to = np.minimum(np.minimum(room, max_chain + 1), np.maximum(4, 4 * (da + 1)))
            nt = t_to - da
            tr, k = _ragged(nt)
            t = da.take(tr) + 1 + k
            fail = _fails(p0, p1, tol, ca.take(tr), t) | (t > max_chain)
            first_fail = np.full(len(active), np.iinfo(np.int64).max)
            hit = np.flatnonzero(fail)          # (run, t) pairs come sorted by run, then by t
            if len(hit):
                lead_hit = hit[np.r_[True, tr[hit[1:]] != tr[hit[:-1]]]]
                first_fail[tr[lead_hit]] = t[lead_hit]
            failed = first_fail <= t_to
            t_end = np.where(failed, first_fail - 1, t_to)   # rows joined to the chain
            merges = t_end > 0
            finished = failed | (t_to >= room)
            closed = finished & merges
            starts.append(ca[closed])
            ends.append(ca[closed] + t_end[closed])
            # a failure starts the run's next chain at the failing row; a run that ends closes its chain
            nxt = ca + first_fail
            cont = failed & (nxt < la)
            reached_end = (finished & ~failed & (la == n - 1)) | (failed & (nxt == la) & (la == n - 1))
            if reached_end.any():
                at = np.flatnonzero(reached_end)[-1]
                open_from = int(ca[at] if not failed[at] else nxt[at])
            c[active[failed]] = nxt[failed]
            done[active[failed]] = 0
            done[active[~finished]] = t_to[~finished]
            active = active[cont | ~finished]
    return np.concatenate(starts), np.concatenate(ends), int(open_from)


@dataclass
class NaiveCamMerge(Mechanism):
    name = "naive_cam"
    kind = "limits"
    order = 5
    windowed = True

    max_chain: int = 100
    arcs_as_lines: bool = False  # G64, XY plane: an arc within Q of its chord goes in as two lines

    def __post_init__(self) -> None:
        self.check_positive(max_chain=self.max_chain)

    @staticmethod
    def flat_arcs(b: Blocks) -> np.ndarray:
        """Rows LinuxCNC's canon turns into two lines: continuous-mode XY arcs without rotary motion whose
        chord deviation r (1 - cos(|sweep| / 2)) is below their Q (merge tolerance)."""
        tol = np.nan_to_num(b.merge_tol, nan=0.0)
        continuous = b.extra.get("continuous")
        if continuous is None:
            continuous = ~b.stop_after
        with np.errstate(invalid="ignore"):
            deviation = b.radius * (1.0 - np.cos(np.abs(b.sweep) / 2.0))
        return ((b.kind == KIND_ARC) & (b.normal_axis == 2) & continuous.astype(bool) & ~b.rotary
                & (b.length > 0) & (tol > 0) & (deviation < tol))

    def split_flat_arcs(self, b: Blocks, vel: np.ndarray, acc: np.ndarray, v_path: float) -> Blocks:
        """`b` with every flat arc (`flat_arcs`) replaced by its two lines: start -> midpoint (no stop,
        no dwell, no time floor) and midpoint -> end (the arc's own end conditions); both keep the block.
        `vel`, `acc`: the axis limits (profile order); `v_path`: the path speed cap of lines."""
        flat = self.flat_arcs(b)
        if not flat.any():
            return b
        rows_idx = np.repeat(np.arange(len(b)), np.where(flat, 2, 1))
        first = np.zeros(len(rows_idx), bool)
        first[1:] = (rows_idx[1:] == rows_idx[:-1])
        first = np.roll(first, -1)            # the first of each pair (its twin follows it)
        out = b.take(rows_idx)
        lin = b.linear_index
        ia = np.flatnonzero(flat)
        x, y, z = lin[0], lin[1], lin[2]
        cx, cy = b.center[ia, 0], b.center[ia, 1]
        half = b.sweep[ia] / 2.0
        dx, dy = b.p0[ia, x] - cx, b.p0[ia, y] - cy
        mid = b.p0[ia].copy()
        mid[:, x] = cx + dx * np.cos(half) - dy * np.sin(half)
        mid[:, y] = cy + dx * np.sin(half) + dy * np.cos(half)
        mid[:, z] = (b.p0[ia, z] + b.p1[ia, z]) / 2.0
        a_rows = np.flatnonzero(first)
        b_rows = a_rows + 1
        out.p1[a_rows] = mid
        out.p0[b_rows] = mid
        pairs = np.concatenate([a_rows, b_rows])
        out.kind[pairs] = KIND_LINEAR
        out.radius[pairs] = 0.0
        out.sweep[pairs] = 0.0
        out.stop_after[a_rows] = False
        out.exact_path[a_rows] = False
        out.hold_s[a_rows] = 0.0
        out.min_time_s[a_rows] = 0.0
        delta = out.p1[pairs] - out.p0[pairs]
        length = np.linalg.norm(delta[:, lin], axis=1)
        v_axis, a_axis = projected_limits(delta, length, vel, acc)
        out.length[pairs] = length
        out.v_axis[pairs] = v_axis
        out.v_limit[pairs] = np.minimum(v_axis, v_path)
        out.a_max[pairs] = a_axis
        return out

    @staticmethod
    def candidates(b) -> np.ndarray:
        """Row i may join row i - 1 (n - 1 values): both eligible, the same feed, and the end of i - 1
        within tol of the line from the start of i - 1 to the end of i (the pre-test)."""
        lin = b.linear_index
        tol = np.nan_to_num(b.merge_tol, nan=0.0)
        ok = (b.kind == KIND_LINEAR) & ~b.rotary & (b.length > 0) & ~b.stop_after & (tol > 0)
        p0, p1 = b.p0[:, lin], b.p1[:, lin]
        m = p1[1:] - p0[:-1]
        mm = np.einsum("ij,ij->i", m, m)
        t = np.clip(np.einsum("ij,ij->i", p1[:-1] - p0[:-1], m) / np.where(mm > 0, mm, 1.0), 0.0, 1.0)
        d3 = np.linalg.norm(p1[:-1] - (p0[:-1] + t[:, None] * m), axis=1)
        return ok[:-1] & ok[1:] & (b.feed[1:] == b.feed[:-1]) & (d3 <= tol[1:])

    def limit(self, ctx: Context) -> None:
        vel = np.array([ctx.profile.axes[a].vel_max for a in ctx.blocks.axes])
        acc = np.array([ctx.profile.axes[a].acc_max for a in ctx.blocks.axes])
        window = ctx.window
        if self.arcs_as_lines:
            split = self.split_flat_arcs(ctx.blocks, vel, acc, ctx.profile.interpolator.path_vel_max_mm_s)
            if window is not None and window.mine(self.name).get("half") and len(split) > 1 \
                    and split.block[0] == split.block[1]:
                split = split.take(np.arange(1, len(split)))   # its first half ran in the window before
            if window is None and len(split) > len(ctx.blocks):
                ctx.notes["arcs_as_lines"] = int(len(split) - len(ctx.blocks))
            ctx.blocks = split
        b = ctx.blocks
        n = len(b)
        if window is not None:
            lead = bool(window.mine(self.name).get("lead", False))
        if n < 2:
            if window is not None and n and not window.last:
                window.pending(self.name, int(b.block[0]))
                window.carry(self.name, lambda block: {"lead": lead})
            return
        cand = self.candidates(b)
        if window is None:
            lead = False
        lin = b.linear_index
        tol = np.nan_to_num(b.merge_tol, nan=0.0)
        start, end, open_from = remembered_chains(b.p0[:, lin], b.p1[:, lin], cand, tol, self.max_chain,
                                       lead_candidate=lead)
        if window is not None:
            if not window.last:  # the chain holding the last row may still grow: it is redone with the next rows
                window.pending(self.name, int(b.block[open_from]))
            blocks = b.block.copy()

            # the open chain may start at the second half of a split arc whose first half closed the chain
            # before it: the next window then starts with that second half
            half_from = open_from if 0 < open_from < n and blocks[open_from] == blocks[open_from - 1] \
                and bool(np.any((start < open_from - 1) & (end == open_from - 1))) else -1

            def state_at(block: int) -> dict:
                """Whether the row of `block` began its chain after a failed test (a candidate before it),
                and whether it resumes at the second half of a split arc."""
                if half_from > 0 and blocks[half_from] == block:
                    return {"lead": bool(cand[half_from - 1]), "half": True}
                r = int(np.searchsorted(blocks, block))
                return {"lead": bool(cand[r - 1]) if 0 < r <= len(cand) else lead}

            window.carry(self.name, state_at)
        if not len(start):
            return
        keep = np.ones(n, bool)
        counts = end - start
        dropped = np.repeat(start, counts) + _ragged(counts)[1]
        keep[dropped] = False
        merged = end
        b.p0[merged] = b.p0[start]
        delta = b.p1[merged] - b.p0[merged]
        length = np.linalg.norm(delta[:, lin], axis=1)
        v_axis, a_axis = projected_limits(delta, length, vel, acc)
        b.length[merged] = length
        b.v_axis[merged] = v_axis
        b.v_limit[merged] = np.minimum(v_axis, ctx.profile.interpolator.path_vel_max_mm_s)
        b.a_max[merged] = a_axis
        first = b.extra.get("first_block")
        if first is not None:
            first[merged] = first[start]
        ctx.blocks = b.take(np.flatnonzero(keep))
        ctx.notes["merged_blocks"] = int(n - keep.sum())
