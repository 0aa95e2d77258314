"""Look-ahead planner: acceleration-limited speed planning over a window of blocks.

Source: the classic look-ahead scheme of CNC kernels (backward pass for the deceleration the next
blocks need, forward pass for the achievable acceleration; e.g. LinuxCNC src/emc/tp/tp.c
`tpRunOptimization`, grbl planner.c). Per-axis velocity and acceleration limits are projected on
each block's direction (`feedlog.sim.path.prepare_blocks`); arcs (G2/G3 and blend arcs) split the
acceleration into a tangential and a normal share, so their speed is limited by the centripetal
acceleration v^2 / R <= a_n (LinuxCNC `BLEND_ACC_RATIO_TANGENTIAL` = 0.5, normal sqrt(1 - 0.5^2)).
A programmed arc (G2/G3, a spline's biarcs) keeps that 0.5 share only where its maximum speed needs the
whole normal share: LinuxCNC 2.9 (tc.c `tcUpdateCircleAccRatio`, blendmath.c `pmCircleActualMaxVel`)
gives it the tangential share sqrt(1 - (v_ini^2 / R / a)^2), where v_ini is the arc's maximum speed
(the canon's `ini_maxvel`: plane axes, centripetal cap, one servo cycle over its length; not the feed),
so a wide arc accelerates almost as a line (`arc_share_from_speed`, on in the LinuxCNC profiles; a
blend arc keeps 0.5).
The look-ahead window guarantees that the tool can stop within the next `lookahead_blocks` queue
entries (a line a blend arc consumed is part of that arc's entry, as in LinuxCNC's queue). Each
piece lasts at least `min_piece_cycles` servo periods over its clamp length: LinuxCNC caps a
segment's speed at length / (TP_MIN_SEGMENT_CYCLES = 1.02 cycles), the length being what is left
of a line after the blend arcs at its ends trimmed it (tcFinalizeLength, tpComputeOptimalVelocity).
On runs of very short blocks this is what sets the speed: dense002q0's 0.02 mm blocks leave 0.01 mm
line pieces next to their blend arcs, run at under 10 mm/s. Without a corner law every junction is
an exact stop; `stop_settle_s` adds a standstill at each exact stop (an in-position wait of
controllers that check the following error before the next block; 0 by default and for LinuxCNC).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from feedlog.profile import MachineProfile
from feedlog.sim.context import Context, Trajectory, trajectory_from_plan
from feedlog.sim.mechanism import Mechanism
from feedlog.sim.motion import plan_speeds
from feedlog.sim.path import Pieces, feed_scale, with_columns


@dataclass
class LookAheadPlanner(Mechanism):
    name = "lookahead"
    kind = "interpolator"
    windowed = True

    lookahead_blocks: int = 50
    arc_acc_ratio_tangential: float = 0.5
    min_piece_cycles: float = 1.02
    servo_period_s: float = 0.001
    path_acc_max_mm_s2: float = math.inf  # cap on the TCP acceleration of every block (inf: axes only)
    stop_settle_s: float = 0.0  # standstill added at every exact stop inside the program
    arc_share_from_speed: bool = False  # programmed arcs: tangential share from their max speed (LinuxCNC)
    finalize_on_next: bool = False   # the last move before the queue drains is never finalized (LinuxCNC)

    def __post_init__(self) -> None:
        self.check_positive(lookahead_blocks=self.lookahead_blocks, servo_period_s=self.servo_period_s)
        self.check_non_negative(min_piece_cycles=self.min_piece_cycles, stop_settle_s=self.stop_settle_s)
        if not 0 < self.arc_acc_ratio_tangential < 1:
            raise ValueError(f"arc_acc_ratio_tangential must be in (0, 1), got {self.arc_acc_ratio_tangential}")

    @classmethod
    def default_enabled(cls, profile: MachineProfile) -> bool:
        return profile.interpolator.fir_t1_s <= 0

    @classmethod
    def defaults(cls, profile: MachineProfile) -> dict:
        return {"lookahead_blocks": profile.interpolator.lookahead_blocks,
                "servo_period_s": profile.interpolator.servo_period_s,
                "path_acc_max_mm_s2": profile.interpolator.path_acc_max_mm_s2}

    stream = "feedlog.sim.stream_plan:LookaheadStream"   # its windowed form (feedlog.sim.window)

    def limit_pieces(self, pieces: Pieces, scale: np.ndarray | None = None, *, ends_program: bool = True,
                     v_axis: np.ndarray | None = None) -> Pieces:
        """Centripetal and sample-rate limits on the pieces' cruise speed and acceleration. `scale`: per
        piece, the feed override factor, which scales a programmed arc's centripetal speed (part of its
        requested speed in LinuxCNC) but not a blend arc's or the sample-rate clamp (caps).
        `ends_program`: the last piece is the program's last (a windowed run passes False before).
        `v_axis`: per piece, its block's axis speed limit (`Blocks.v_axis`: not the feed, not the TRAJ cap,
        which LinuxCNC applies while running), which sets a programmed arc's tangential share
        (`arc_share_from_speed`); without it every arc gets the fixed share."""
        curved = pieces.radius > 0
        pieces = with_columns(pieces, a_max=np.minimum(pieces.a_max, self.path_acc_max_mm_s2))
        ratio_n = math.sqrt(1.0 - self.arc_acc_ratio_tangential ** 2)
        v_curve_max = np.sqrt(ratio_n * pieces.a_max * pieces.radius)
        v_curve = v_curve_max
        if scale is not None:
            v_curve = v_curve * np.where(pieces.blend, 1.0, scale)
        v_max = np.where(curved, np.minimum(pieces.v_max, v_curve), pieces.v_max)
        share = np.full(len(pieces), self.arc_acc_ratio_tangential)
        open_end = pieces.open_end.copy()       # nothing is queued after the piece: LinuxCNC never finalizes it
        if ends_program and len(pieces):
            open_end[-1] = True
        if self.arc_share_from_speed and v_axis is not None:
            programmed = curved & ~pieces.blend
            if self.finalize_on_next:    # the last arc before the queue drains keeps the fixed share
                programmed &= ~open_end
            share = np.where(programmed, self.programmed_arc_share(pieces, v_axis, v_curve_max), share)
        a_max = np.where(curved, pieces.a_max * share, pieces.a_max)
        if self.min_piece_cycles > 0:
            v_sample = pieces.clamp_len / (self.min_piece_cycles * self.servo_period_s)
            v_max = np.where(pieces.clamp_len > 0, np.minimum(v_max, v_sample), v_max)
        hold = pieces.hold_s
        if self.stop_settle_s > 0 and len(pieces):
            stops = (pieces.v_end <= 0) & ~pieces.overlap & (pieces.length > 0)
            if ends_program:
                stops[-1] = False
            hold = hold + np.where(stops, self.stop_settle_s, 0.0)
        return with_columns(pieces, v_max=v_max, a_max=a_max, hold_s=hold)

    def programmed_arc_share(self, pieces: Pieces, v_axis: np.ndarray, v_curve: np.ndarray) -> np.ndarray:
        """Per piece, the tangential acceleration share of a programmed arc: its maximum speed v_ini
        (`v_axis`, the centripetal cap `v_curve`, one servo period over its clamp length) needs the normal
        acceleration a_n = v_ini^2 / R; what is left of the path acceleration a goes along the path,
        sqrt(1 - (a_n / a)^2), and never less than `arc_acc_ratio_tangential` (where a_n reaches the
        normal share the speed is capped there instead)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            v_ini = np.minimum(v_axis, v_curve)
            if self.servo_period_s > 0:
                v_ini = np.where(pieces.clamp_len > 0, np.minimum(v_ini, pieces.clamp_len / self.servo_period_s),
                                 v_ini)
            a_n = v_ini ** 2 / np.maximum(pieces.radius, 1e-12) / pieces.a_max
            share = np.sqrt(np.clip(1.0 - a_n ** 2, 0.0, 1.0))
        share = np.where(np.isfinite(share), share, self.arc_acc_ratio_tangential)
        return np.maximum(share, self.arc_acc_ratio_tangential)

    def run(self, ctx: Context) -> Trajectory:
        pieces = self.limit_pieces(ctx.pieces, feed_scale(ctx.blocks)[ctx.pieces.block],
                                   v_axis=ctx.blocks.v_axis[ctx.pieces.block])
        plan = plan_speeds(pieces, lookahead=int(self.lookahead_blocks))
        return trajectory_from_plan(plan, pieces, ctx.blocks, ctx.dt_s)
