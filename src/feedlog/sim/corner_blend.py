"""Blend-arc corner law: continuous-mode (G64 P) corners cut by an arc inside the path tolerance.

Source: the LinuxCNC 2.9 trajectory planner (src/emc/tp/tp.c `tpHandleBlendArc`, `tpSetupTangent`;
blendmath.c `blendComputeParameters`, `blendCheckConsume`), re-derived here in vectorised form:

- nearly collinear junctions are passed as "tangent" when the direction kink needs less than
  `kink_ratio` of the axis acceleration in one servo cycle (the pieces' acceleration drops by the
  kink share);
- other line-line corners get a circular arc of half-angle theta = acos(-u1.u2) / 2 whose deviation
  from the corner stays inside the tolerance T (G64 P; without P a quarter of the shorter block):
  d_tol = cos(theta) T / (1 - sin(theta)), and which uses at most half of each block; its speed is
  limited by the normal acceleration, v^2 <= a_n R with a_n = a_plane sqrt(1 - 0.5^2);
- line-arc, arc-line and arc-arc corners (`curved_blend_speed`) get the speed of a blend arc along
  the junction tangents; where the arc turns at most `curved_blend_turn` over the blend's length, or,
  with `arc_side_lengths`, with the lengths LinuxCNC allows on an arc side: a third of the next arc's
  sweep (two thirds of the previous arc's), capped by the corner's half-angle where the arc bends away
  from the corner (then along its chord) and by a quarter turn where it bends into it;
- `curved_blend_geometry`: those blend arcs are placed where LinuxCNC puts them, touching both sides,
  the sides cut there (`feedlog.sim.blend_geometry`), and run under the next line;
- `parabolic_choice`: where LinuxCNC rates a parabolic blend above the blend arc and the kink speed
  (tp.c `tpChooseBestBlend`, `feedlog.sim.blend_choice`) the corner is blended parabolically, both moves
  at half acceleration (LinuxCNC 2.9 keeps `blend_prev` on the entered move);
- `open_end_entry`: the move before one nothing is queued after (a word run at rest, a dwell, the
  program's end; never finalized) ends at most at that move's triangle speed sqrt(a L);
- a line shorter than `gap_cycles` servo cycles at the arc speed is "consumed" by the arc;
- a blend arc, and a line it consumes, run under the *next* line: LinuxCNC 2.9's
  `motion.program-line` switches to the next line where the tool leaves the straight line into the
  arc (1 ms after it, measured on the bundled recordings; older tp.c versions copied the previous
  line's tag onto the arc, 2.9's does not). With the arc on the line before it every block ended up
  to a whole blend late: per-line time error against LinuxCNC median 1.66 -> 0.38 ms over the 117
  sessions. `feedlog diagnose` found it as a spurious logger latency (docs/diagnose.md);
- junctions where a rotary axis moves get LinuxCNC's parabolic blend: the block ending in the blend
  runs at half acceleration and the next block starts while it decelerates from the blend speed
  (this is why LinuxCNC's five-axis G64 is slower than G61). LinuxCNC halves the entered block too
  while the blend lasts (`blend_prev`); the recordings show it at its own acceleration after that,
  so the model leaves it whole (`halve_after_blend = true` halves it for its whole length, as the
  model did before: mix5ax_023 +1.43 % instead of -0.04 %);
- corners sharper than `sharp_corner_deg` from a reversal stop;
- `tolerance_scale` is the share of the programmed tolerance the controller blends within (1 in
  LinuxCNC; controllers that keep part of the tolerance for smoothing or compression use less);
- a rapid (G0) next to a feed move (G1/G2/G3) is never blended: LinuxCNC stops between them
  (tp.c `handleModeChange` sets the STOP end condition, so neither block's acceleration is halved);
  `rapid_feed_stop = false` blends them like any other junction;
- a continuous-mode block that is not blended into a next one (the last move, a move before a
  dwell) keeps the parabolic end condition and so half its acceleration;
- `sync_stop`: a block followed by a word the controller executes only at rest (M3/M5, M8, an S or
  work offset change, a message: `feedlog.sim.queue_sync`) is never blended into the next move, which
  is not yet queued when it is planned: it ends at rest, and in G64 with half its acceleration even
  where the next move is a rapid/feed switch or a sharp corner (its end condition stays parabolic).
  The few task cycles LinuxCNC then waits per word (plasmatest: cycle minus motion time 104 ms over
  its 31 M3/M5, 3.4 ms each) are left out: its line stream shows them on the M code's own line;
- in G61 (exact path) tangent junctions are still passed without stopping; at the other G61
  junctions LinuxCNC keeps the kink acceleration reduction (`kink_ratio`) on both blocks, so exact-stop
  blocks run at 90 % of their acceleration (tp.c: `tpChooseBestBlend` returns before
  `tcRemoveKinkProperties` for exact-path segments).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from feedlog.profile import MachineProfile
from feedlog.sim.blend_choice import parabolic_chosen
from feedlog.sim.blend_geometry import arc_frames, arc_sides, place_curved
from feedlog.sim.context import Context
from feedlog.sim.mechanism import Mechanism
from feedlog.sim.path import KIND_RAPID, Pieces, feed_scale, rows, with_columns

ACC_RATIO_TANGENTIAL = 0.5


def _interleave(a: np.ndarray, b: np.ndarray, pos_a: np.ndarray, pos_b: np.ndarray) -> np.ndarray:
    """Rows of a at pos_a and rows of b at pos_b of a new array. (n, k) rows are scattered as single
    k-float elements through a void view: much faster than row-wise fancy indexing."""
    dtype = np.result_type(a, b)
    zero_a, zero_b = not a.any(), not b.any()   # often all zero (directions of arcs, e1/e2 of lines)
    shape = (len(a) + len(b),) + a.shape[1:]
    out = np.zeros(shape, dtype=dtype) if zero_a or zero_b else np.empty(shape, dtype=dtype)
    if a.ndim == 2:
        row = np.dtype((np.void, dtype.itemsize * a.shape[1]))
        view = out.view(row).reshape(-1)
        if not zero_a:
            view[pos_a] = np.ascontiguousarray(a, dtype=dtype).view(row).reshape(-1)
        if not zero_b:
            view[pos_b] = np.ascontiguousarray(b, dtype=dtype).view(row).reshape(-1)
    else:
        if not zero_a:
            out[pos_a] = a
        if not zero_b:
            out[pos_b] = b
    return out


def _sq_norm(x: np.ndarray) -> np.ndarray:
    """Squared Euclidean norm of each row."""
    return np.einsum("ij,ij->i", x, x)


def _norm(x: np.ndarray) -> np.ndarray:
    """Euclidean norm of each row (einsum: faster than np.linalg.norm over a short axis)."""
    return np.sqrt(_sq_norm(x))


def inscribed_limit(binormal: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Largest vector magnitude inside the axis box `bounds` for every direction in the plane with
    normal `binormal` (rows): min over axes of bound / |axis projected on the plane|."""
    scale = np.sqrt(np.clip(1.0 - binormal ** 2, 1e-24, None))
    out = np.full(len(binormal), np.inf)
    for c in range(binormal.shape[1]):  # min over the axes, one column at a time
        np.minimum(out, bounds[c] / scale[:, c], out=out)
    return out


@dataclass
class BlendArcCorner(Mechanism):
    name = "blend_arc"
    kind = "corner"
    windowed = True

    kink_ratio: float = 0.1
    gap_cycles: float = 4.0
    tolerance_ratio: float = 0.25   # default tolerance as a fraction of the block length (no G64 P)
    tolerance_scale: float = 1.0    # share of the programmed G64 P the controller blends within
    sharp_corner_deg: float = 2.0
    servo_period_s: float = 0.001
    rotary_blend: str = "parabolic"  # or "stop"
    rapid_feed_stop: bool = True      # stop where the motion switches between rapid and feed
    halve_after_blend: bool = False   # halve the acceleration of the block after a parabolic blend too
    curved_blend_speed: bool = False  # line-arc / arc-arc corners: the blend arc's speed, not the kink's
    curved_blend_turn: float = 0.1    # ... where the arc turns at most this (rad) over the blend's length
    arc_side_lengths: bool = False    # ... with LinuxCNC's blend lengths on the arc sides instead of that gate
    curved_blend_geometry: bool = False  # ... and the blend arc placed there, run under the next line (blend_geometry)
    parabolic_choice: bool = False    # a parabolic blend where LinuxCNC rates it above the arc and kink (blend_choice)
    open_end_entry: bool = False      # enter a move nothing is queued after at most at its triangle speed sqrt(a L)
    sync_stop: bool = False           # stop, parabolic end, before words executed at rest (queue_sync)

    def __post_init__(self) -> None:
        self.check_positive(servo_period_s=self.servo_period_s, tolerance_ratio=self.tolerance_ratio,
                            tolerance_scale=self.tolerance_scale)
        self.check_non_negative(kink_ratio=self.kink_ratio, gap_cycles=self.gap_cycles,
                                sharp_corner_deg=self.sharp_corner_deg, curved_blend_turn=self.curved_blend_turn)
        if self.rotary_blend not in ("parabolic", "stop"):
            raise ValueError(f"rotary_blend must be 'parabolic' or 'stop', got {self.rotary_blend!r}")

    @classmethod
    def default_enabled(cls, profile: MachineProfile) -> bool:
        return profile.interpolator.fir_t1_s <= 0

    @classmethod
    def defaults(cls, profile: MachineProfile) -> dict:
        return {"servo_period_s": profile.interpolator.servo_period_s}

    def corner(self, ctx: Context) -> None:
        pc = ctx.pieces
        blocks = ctx.blocks
        m = len(pc)
        if m == 1:  # a single move: only the end condition applies
            if self._continuous(blocks, pc.block)[0] and pc.length[0] > 0:
                ctx.pieces = with_columns(pc, a_max=pc.a_max * 0.5)
            return
        if m < 2:
            return
        lin = blocks.linear_index
        axes = blocks.axes
        acc_bound = np.array([ctx.profile.axes[axes[i]].acc_max for i in lin])
        vel_bound = np.array([ctx.profile.axes[axes[i]].vel_max for i in lin])
        cyc = self.servo_period_s
        b = pc.block
        j = np.arange(m - 1)          # junction j: end of piece j / start of piece j + 1
        # (arrays at j and j + 1 are the slices [:-1] and [1:]: views, no gathers)
        b1, b2 = b[:-1], b[1:]
        length = pc.length
        u1 = pc.tangent_xyz(j, length[:-1], lin)
        u2 = pc.tangent_xyz(j + 1, np.zeros(m - 1), lin)
        # speeds as LinuxCNC's segments know them (reqvel, maxvel): the programmed feed capped by the axis
        # limits and one servo cycle; not the feed override dial nor the TRAJ velocity cap, which apply
        # while running (tc.c tcGetMaxTargetVel, tp.c tpGetMaxTargetVel)
        v_tc = np.minimum(blocks.feed / feed_scale(blocks), blocks.v_axis)[b]
        v_seg = np.minimum(v_tc, np.where(length > 0, length / cyc, np.inf))
        v_req = v_seg
        exact = blocks.stop_after[b1]
        # G61 (exact path) still passes tangent junctions; G61.1, dwells and holds always stop
        g61 = exact & blocks.exact_path[b1] & (pc.hold_s[:-1] <= 0)
        hard = (exact & ~g61) | (pc.hold_s[:-1] > 0) | (length[:-1] <= 0) | (length[1:] <= 0)
        rotary = blocks.rotary[b1] | blocks.rotary[b2]
        moves_xyz = (_sq_norm(u1) > 0) & (_sq_norm(u2) > 0)
        dot = np.clip(np.einsum("ij,ij->i", u1, u2), -1.0, 1.0)
        sharp = moves_xyz & (dot < -math.cos(math.radians(self.sharp_corner_deg)))
        hard |= sharp | (g61 & rotary)
        rapid = blocks.kind == KIND_RAPID
        mode_change = (rapid[b1] != rapid[b2]) if self.rapid_feed_stop else np.zeros(m - 1, bool)
        hard |= mode_change
        # a word executed at rest between the blocks: the next move is not queued yet (queue_sync)
        counts = blocks.extra.get("syncs") if self.sync_stop else None
        sync = np.zeros(m - 1, bool) if counts is None else (counts[b1] > 0) & (b1 != b2)
        hard |= sync

        v_end = np.zeros(m)
        a_max = pc.a_max.copy()
        overlap = np.zeros(m, bool)
        halved = np.zeros(m, bool)   # LinuxCNC halves a segment's acceleration once (tcGetOverallMaxAccel)

        # rotary axes move in continuous mode: parabolic blend (or stop)
        para = ~hard & ~g61 & rotary
        if self.rotary_blend == "parabolic" and para.any():
            jp = np.flatnonzero(para)
            overlap[jp] = True
            halved[jp] = True
            if self.halve_after_blend:
                halved[jp + 1] = True
            a_max[halved] *= 0.5
            v_end[jp] = self._parabolic_speed(pc, blocks, jp, u1[jp], u2[jp], a_max, v_req, moves_xyz[jp])

        # tangent (kink) check, LinuxCNC tpSetupTangent
        cand = ~hard & ~rotary & moves_xyz
        # the kink check sees each line as LinuxCNC has it when the next one arrives: its feed, axis caps
        # and its full length in one servo cycle (tcClampVelocityByLength), before any arc trims it
        v_tp = v_seg
        v_kink = np.minimum(v_tp[:-1], v_tp[1:])
        a_inst = v_kink / cyc + pc.a_max[1:]
        acc_scale = np.zeros(m - 1)
        for c in range(u1.shape[1]):  # max over the axes, one column at a time
            np.maximum(acc_scale, np.abs(a_inst * (u2[:, c] - u1[:, c])) / acc_bound[c], out=acc_scale)
        tangent = cand & (acc_scale < self.kink_ratio)
        kink_vel = np.where(acc_scale < self.kink_ratio, v_kink,
                            v_kink * self.kink_ratio / np.maximum(acc_scale, 1e-300))
        reduce = np.where(tangent, acc_scale, self.kink_ratio)

        # blend arcs for the remaining continuous-mode line-line corners
        arc_ok = cand & ~g61 & ~tangent & (pc.radius[:-1] <= 0) & (pc.radius[1:] <= 0)
        curved = cand & ~g61 & ~tangent & ~arc_ok if self.curved_blend_speed else np.zeros(m - 1, bool)
        arcs = self._arcs(pc, blocks, j, u1, u2, v_req, acc_bound, vel_bound, arc_ok | curved, v_tc, lin)
        use_arc = arc_ok & arcs["ok"] & (arcs["v_arc"] >= kink_vel)
        # line-arc, arc-line, arc-arc corners: LinuxCNC 2.9 blends them too (tp.c tpCreateLineArcBlend,
        # tpCreateArcLineBlend, tpCreateArcArcBlend); the junction gets the speed of the blend arc the
        # tolerance and the half-lengths allow along the junction tangents (the arc itself is not placed)
        r_arc = np.minimum(np.where(pc.radius[:-1] > 0, pc.radius[:-1], np.inf),
                           np.where(pc.radius[1:] > 0, pc.radius[1:], np.inf))
        short = arcs["d"] <= self.curved_blend_turn * r_arc
        if self.arc_side_lengths:
            short = np.ones(m - 1, bool)
        use_curved = curved & arcs["ok"] & short & (arcs["v_arc"] >= kink_vel)
        placed = None
        if self.curved_blend_geometry and arcs["sides"] is not None and use_curved.any():
            jc = np.flatnonzero(use_curved)
            placed = place_curved(pc, jc, u1, u2, arcs["sides"], arcs["r"], arcs["tol"], lin)
            use_curved[jc[~placed.ok]] = False          # LinuxCNC gives the blend up: parabolic or kink
        chosen = np.zeros(m - 1, bool)
        if self.parabolic_choice:      # LinuxCNC rates a parabolic blend against the arc and the kink speed
            chosen = parabolic_chosen(pc, cand & ~g61 & ~tangent, np.where(use_arc | use_curved, arcs["v_arc"], 0.0),
                                      kink_vel, u1, u2, feed=(blocks.feed / feed_scale(blocks))[b], v_seg=v_seg,
                                      tol=blocks.tol[b1] * self.tolerance_scale, kink_ratio=self.kink_ratio, lin=lin)
            use_arc &= ~chosen
            use_curved &= ~chosen
            if placed is not None:
                placed = placed.keep(~chosen[placed.j])
            jq = np.flatnonzero(chosen)
            overlap[jq] = True
            # both moves at half acceleration: the one ending in the blend (its parabolic end condition) and
            # the one entered through it, for its whole length (tc.c tcSetTermCond sets blend_prev, which
            # LinuxCNC 2.9 clears only when that junction is changed again)
            both = np.union1d(jq, jq + 1)
            fresh = both[~halved[both]]
            halved[fresh] = True
            a_max[fresh] *= 0.5
            v_end[jq] = self._parabolic_speed(pc, blocks, jq, u1[jq], u2[jq], a_max, v_req, moves_xyz[jq])
        use_kink = cand & ~use_arc & ~use_curved & ~chosen & ~(g61 & ~tangent)   # tangent, incl. arcs worse than the kink
        jk = np.flatnonzero(use_kink)
        v_end[jk] = kink_vel[jk]
        # G61 corners that are not tangent stop, but keep LinuxCNC's kink acceleration reduction
        jr = np.flatnonzero(use_kink | (cand & g61 & ~tangent))
        red = np.zeros(m)
        red[jr] = reduce[jr]                                  # jr is sorted and unique
        red[jr + 1] = np.maximum(red[jr + 1], reduce[jr])
        a_max *= 1.0 - red
        # a continuous-mode segment that ends without a blend keeps LinuxCNC's "parabolic" end
        # condition and so half its acceleration (tcGetOverallMaxAccel): the program's last move and
        # moves before a dwell or other hard stop that is not a sharp corner
        continuous = ~blocks.stop_after[b] | ((np.arange(m) == m - 1) & ~blocks.exact_path[b] & self._continuous(blocks, b))
        end_stop = np.append((hard & ~sharp & ~mode_change) | sync, True)
        half = continuous & end_stop & ~halved & (length > 0)
        a_max[half] *= 0.5
        # an arc is sized for its segments' requested speed; it runs at that request times the dial
        # (LinuxCNC: the blend's reqvel is the faster neighbour's request, its maxvel the planned speed;
        # tp.c tpGetRealTargetVel) under the TRAJ velocity cap
        v_dial = arcs["v_req"] * feed_scale(blocks)[b1]
        arcs["v_run"] = np.minimum(np.minimum(arcs["v"], v_dial), ctx.profile.interpolator.path_vel_max_mm_s)
        if placed is None:
            jb = np.flatnonzero(use_curved)
            v_end[jb] = np.minimum(arcs["v_run"][jb], np.minimum(pc.v_max[jb], pc.v_max[jb + 1]))
        # the queue drains after the piece (a word run at rest, a dwell next): LinuxCNC never finalizes it
        open_end = pc.open_end.copy()
        open_end[:-1] |= sync | ((length[1:] <= 0) & (pc.hold_s[1:] > 0))
        if ctx.window is None or ctx.window.last:
            open_end[-1] = True                      # the program's last move
        pc = with_columns(pc, open_end=open_end)
        ctx.pieces, line_clamp = self._insert_arcs(pc, np.flatnonzero(use_arc), arcs, v_end, a_max, overlap, u1,
                                                   u2, placed)
        if self.open_end_entry:
            ctx.pieces = self._enter_open_end(ctx.pieces)
        # counts over the junctions after the pieces a window keeps (all of them when not windowed)
        lo, hi = ctx.window.core if ctx.window is not None and ctx.window.core is not None else (0, m)
        ctx.notes.update(blend_arcs=int(use_arc[lo:hi].sum()), curved_blends=int(use_curved[lo:hi].sum()),
                         tangent_junctions=int(use_kink[lo:hi].sum()),
                         parabolic_blends=int(overlap[lo:hi].sum()), consumed_lines=int((line_clamp[lo:hi] == 0).sum()))

    @staticmethod
    def _enter_open_end(pc: Pieces) -> Pieces:
        """LinuxCNC's optimizer lets the move before an unfinalized one (nothing queued after it) end at no
        more than that move's triangle speed sqrt(a L), a blend being free to take half of it (tp.c
        tpRunOptimization, tpCalculateOptimizationInitialVel); a programmed arc's acceleration there is its
        fixed tangential share."""
        k = np.flatnonzero(pc.open_end[1:])
        if not len(k):
            return pc
        a_tan = pc.a_max[k + 1] * np.where(pc.radius[k + 1] > 0, ACC_RATIO_TANGENTIAL, 1.0)
        v_end = pc.v_end.copy()
        v_end[k] = np.minimum(v_end[k], np.sqrt(a_tan * pc.length[k + 1]))
        return with_columns(pc, v_end=v_end)

    @staticmethod
    def _continuous(blocks, b: np.ndarray) -> np.ndarray:
        """Blocks programmed in G64 (their `stop_after` may only come from being last or a dwell)."""
        mode = blocks.extra.get("continuous")
        return mode[b] if mode is not None else ~blocks.exact_path[b]

    def _parabolic_speed(self, pc: Pieces, blocks, jp, u1, u2, a_half, v_req, moves_xyz) -> np.ndarray:
        """LinuxCNC tpComputeBlendVelocity: blend speed from the half-segment rule and the tolerance."""
        l1, l2 = pc.length[jp], pc.length[jp + 1]
        a1, a2 = a_half[jp], a_half[jp + 1]
        v1 = np.minimum(np.sqrt(a1 * l1), v_req[jp])       # triangle speed over half the block
        v2 = np.minimum(np.sqrt(a2 * l2), v_req[jp + 1])
        t_reach = np.minimum(l1 / v1, l2 / v2)
        t_blend = np.minimum(t_reach, np.maximum(v1 / a1, v2 / a2))
        v_b = np.minimum(v1, t_blend * a1)
        tol = blocks.tol[pc.block[jp]] * self.tolerance_scale
        theta = np.arccos(np.clip(-np.einsum("ij,ij->i", u1, u2), -1, 1)) / 2.0
        cos_t = np.cos(theta)
        has_tol = (tol > 0) & (cos_t > math.cos(math.pi / 2 - 1e-3)) & moves_xyz
        v_tol = 2.0 * np.sqrt(a1 * np.where(has_tol, tol, 0.0) / np.where(has_tol, cos_t, 1.0))
        return np.where(has_tol, np.minimum(v_b, v_tol), v_b)

    def _arcs(self, pc, blocks, j, u1, u2, v_req, acc_bound, vel_bound, ok, v_tc, lin) -> dict[str, np.ndarray]:
        nominal = blocks.length[pc.block]
        n1, n2 = nominal[:-1], nominal[1:]   # junction j: pieces j ([:-1]) and j + 1 ([1:])
        dot = np.clip(np.einsum("ij,ij->i", u1, u2), -1.0, 1.0)
        theta = np.arccos(-dot) / 2.0
        side1, side2 = 0.5 * n1, 0.5 * n2
        sides = None
        if self.arc_side_lengths:
            sides = arc_sides(pc, u1, u2, theta, side1, side2, lin)
            theta, side1, side2 = sides.theta, sides.side1, sides.side2
        ok = ok & (math.pi / 2 - theta >= 1e-6) & (theta >= 1e-6)
        th = np.where(ok, theta, 0.5)
        binormal = np.column_stack([u1[:, 1] * u2[:, 2] - u1[:, 2] * u2[:, 1],
                                    u1[:, 2] * u2[:, 0] - u1[:, 0] * u2[:, 2],
                                    u1[:, 0] * u2[:, 1] - u1[:, 1] * u2[:, 0]])
        bn = _norm(binormal)
        binormal = binormal / np.where(bn > 0, bn, 1.0)[:, None]
        a_plane = inscribed_limit(binormal, acc_bound)
        v_plane = inscribed_limit(binormal, vel_bound)
        a_n = a_plane * math.sqrt(1 - ACC_RATIO_TANGENTIAL ** 2)
        tol_piece = blocks.tol[pc.block] * self.tolerance_scale
        tol1, tol2 = tol_piece[:-1], tol_piece[1:]
        t1 = np.where(tol1 > 0, tol1, n1 * self.tolerance_ratio)
        t2 = np.where(tol2 > 0, tol2, n2 * self.tolerance_ratio)
        tol = np.minimum(np.minimum(t1, t2), np.minimum(n1, n2) * self.tolerance_ratio)
        phi = math.pi - 2 * th
        v_ask = np.maximum(v_req[:-1], v_req[1:])
        v_goal = v_ask
        cphi = np.cos(np.minimum(phi, math.pi * 0.49))
        vm1 = np.minimum(v_tc[:-1], v_tc[1:] / cphi)
        vm2 = np.minimum(v_tc[1:], v_tc[:-1] / cphi)
        base = _norm(u2 * vm2[:, None] - u1 * vm1[:, None])
        v_alt = vm1 * vm2 * np.sin(phi) / np.where(base > 0, base, np.inf)
        if self.curved_blend_geometry and sides is not None:    # no altitude rule next to an arc (blendParamKinematics)
            v_alt = np.where((pc.radius[:-1] > 0) | (pc.radius[1:] > 0), 0.0, v_alt)
        v_goal = np.minimum(v_goal, np.maximum(v_alt, v_plane))
        d_tol = np.cos(th) * tol / (1 - np.sin(th))
        d_geom = np.minimum(np.minimum(side1, side2), d_tol)
        d_geom = np.minimum(d_geom, np.minimum(pc.length[:-1], pc.length[1:]))
        r_geom = np.tan(th) * d_geom
        v_plan = np.minimum(np.sqrt(a_n * r_geom), v_goal)
        a_par = 0.5 * a_plane
        t_blend = np.minimum(np.sqrt(2 * a_par * d_geom), v_plan) / a_par
        r_blend = np.minimum(t_blend * v_plan / phi, r_geom)
        r_plan = np.maximum(v_plan ** 2 / a_n, r_blend)
        d_plan = r_plan / np.tan(th)
        s_arc = r_plan * phi
        ok = ok & (r_plan > 1e-12) & (s_arc > 1e-6)
        v_arc = np.minimum(v_plan, s_arc / self.servo_period_s)
        return {"ok": ok, "theta": th, "r": r_plan, "d": d_plan, "s": s_arc, "v": v_plan, "v_arc": v_arc, "v_req": v_ask,
                "a": a_plane, "tol": tol, "sides": sides}

    @staticmethod
    def _line_line_arcs(pc: Pieces, ja, arcs, u1, u2) -> dict[str, np.ndarray]:
        """Blend arcs between two lines (blendFindPoints3): d along each line from the corner."""
        na, k = len(ja), pc.p0.shape[1]
        theta = arcs["theta"][ja]
        r = arcs["r"][ja]
        d = arcs["d"][ja]
        dir_a = rows(pc.dir, ja)
        corner = rows(pc.p0, ja) + dir_a * pc.length[ja, None]  # corner point (end of the untrimmed line)
        start = corner - dir_a * d[:, None]
        lin_idx = slice(0, 3)  # profiles list x, y, z first (feedlog.profile.MachineProfile.axis_names)
        e2 = np.zeros((na, k))
        e1 = np.zeros((na, k))
        t1 = rows(u1, ja)
        t2 = rows(u2, ja)
        normal = t2 - t1
        normal /= _norm(normal)[:, None]
        # centre relative to the arc start (LinuxCNC blendFindPoints3): P + n R / sin(theta) - (P - u1 d)
        to_centre = normal * (r / np.sin(theta))[:, None] + t1 * d[:, None]
        e1[:, lin_idx] = -to_centre / _norm(to_centre)[:, None]  # centre -> arc start
        e2[:, lin_idx] = t1                 # tangent at the arc start
        arc_len = arcs["s"][ja]
        phi = math.pi - 2 * theta
        return {"j": ja, "trim_end": d, "trim_start": d, "start": start, "e1": e1, "e2": e2, "radius": r,
                "length": arc_len, "omega": phi / arc_len}

    def _insert_arcs(self, pc: Pieces, ja, arcs, v_end, a_max, overlap, u1, u2, placed=None) -> Pieces:
        m = len(pc)
        k = pc.p0.shape[1]
        geo = self._line_line_arcs(pc, ja, arcs, u1, u2)
        if placed is not None and len(placed.j):
            curved = arc_frames(pc, placed)
            order = np.argsort(np.concatenate([ja, placed.j]), kind="stable")
            geo = {f: np.concatenate([geo[f], curved[f]])[order] for f in geo}
        ja = geo["j"]
        trim_end = np.zeros(m)
        trim_start = np.zeros(m)
        trim_end[ja] = geo["trim_end"]
        trim_start[ja + 1] = geo["trim_start"]
        length = pc.length - trim_end - trim_start
        p0 = pc.p0 + pc.dir * trim_start[:, None]
        e1_p, e2_p = pc.e1, pc.e2
        turned = np.flatnonzero((trim_start > 0) & (pc.radius > 0))   # arcs cut at their start: turn the frame
        if len(turned):
            p0[turned] = pc.position(turned, trim_start[turned])
            ang = pc.omega[turned] * trim_start[turned]
            c, s_ = np.cos(ang)[:, None], np.sin(ang)[:, None]
            e1_p, e2_p = e1_p.copy(), e2_p.copy()
            e1_p[turned] = c * pc.e1[turned] + s_ * pc.e2[turned]
            e2_p[turned] = c * pc.e2[turned] - s_ * pc.e1[turned]
        v_max = pc.v_max.copy()
        # LinuxCNC clamps a line's speed by what the arcs left of it (tcFinalizeLength): a 0.02 mm block
        # with an arc at one end keeps a 0.01 mm piece of line, a segment of its own
        clamp = np.where(pc.clamp_len > 0, np.minimum(pc.clamp_len, length), pc.clamp_len)
        v_end = v_end.copy()
        # consumed lines: a short remainder of a line before the arc runs at the arc speed, as part of it
        v_plan = arcs["v"][ja]
        consumed = ((length[ja] / v_plan < self.gap_cycles * self.servo_period_s) & ~overlap[np.maximum(ja - 1, 0)]
                    & (pc.radius[ja] <= 0))
        jc = ja[consumed]
        v_max[jc] = np.minimum(v_max[jc], v_plan[consumed])
        clamp[jc] = 0.0
        v_run = arcs["v_run"][ja]
        v_end[ja] = v_run
        # arc pieces
        na = len(ja)
        arc_len = geo["length"]
        arc_len_full = arc_len + np.where(consumed, length[ja], 0.0)
        arcp = Pieces(block=pc.block[ja + 1], length=arc_len, p0=geo["start"], dir=np.zeros((na, k)), e1=geo["e1"],
                      e2=geo["e2"], radius=geo["radius"], omega=geo["omega"], v_max=v_run, a_max=arcs["a"][ja],
                      v_end=v_run, hold_s=np.zeros(na), blend=np.ones(na, bool), overlap=np.zeros(na, bool),
                      clamp_len=arc_len_full, open_end=np.zeros(na, bool))
        owner = pc.block.copy()
        owner[jc] = pc.block[jc + 1]   # a consumed line runs inside the arc's queue entry, under the next line
        lines = Pieces(block=owner, length=length, p0=p0, dir=pc.dir, e1=e1_p, e2=e2_p, radius=pc.radius,
                       omega=pc.omega, v_max=v_max, a_max=a_max, v_end=v_end, hold_s=pc.hold_s, blend=pc.blend,
                       overlap=overlap, clamp_len=clamp, open_end=pc.open_end)
        # each arc goes right after its piece: piece i moves down by the number of arcs before it
        has_arc = np.zeros(m, np.int64)
        has_arc[ja] = 1
        line_pos = np.arange(m) + np.concatenate(([0], np.cumsum(has_arc)[:-1]))
        arc_pos = line_pos[ja] + 1
        merged = {f: _interleave(getattr(lines, f), getattr(arcp, f), line_pos, arc_pos)
                  for f in Pieces.__dataclass_fields__}
        return Pieces(**merged), clamp
