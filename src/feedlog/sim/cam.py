"""CAM estimate: every block at its programmed feed, rapids at the rapid rate, no acceleration.

Source: the time estimate CAM systems print (block time = L / F), the baseline that Chien et al.
(2024) §3 and Sun et al. (2021) compare against (31-41 % error in Chien Tables 2-3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.sim.context import Context, Trajectory, trajectory_from_plan
from feedlog.sim.mechanism import Mechanism
from feedlog.sim.motion import Plan
from feedlog.sim.path import Blocks


def cam_block_times(blocks: Blocks) -> np.ndarray:
    """L / F per block (plus dwells), in seconds."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(blocks.length > 0, blocks.length / blocks.feed, 0.0)
    return t + blocks.hold_s


@dataclass
class CamEstimate(Mechanism):
    name = "cam"
    kind = "interpolator"
    uses_corner_law = False
    windowed = True
    stream = "feedlog.sim.stream_plan:CamStream"   # its windowed form (feedlog.sim.window)

    def run(self, ctx: Context) -> Trajectory:
        pieces = ctx.pieces
        blocks = ctx.blocks
        speed = blocks.feed[pieces.block]
        with np.errstate(divide="ignore", invalid="ignore"):
            dur = np.where(pieces.length > 0, pieces.length / speed, 0.0)
        zero = np.zeros(len(pieces))
        t0 = np.concatenate(([0.0], np.cumsum(dur + pieces.hold_s)[:-1])) if len(pieces) else zero
        plan = Plan(t0=t0, v0=np.where(dur > 0, speed, 0.0), v1=np.where(dur > 0, speed, 0.0),
                    vp=np.where(dur > 0, speed, 0.0), acc=zero, t_acc=zero, t_cru=dur, t_dec=zero,
                    hold=pieces.hold_s.copy(), overlap_s=zero)
        return trajectory_from_plan(plan, pieces, blocks, ctx.dt_s)
