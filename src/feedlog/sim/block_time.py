"""Block processing time floor: the controller prepares at most 1 / min_block_time_s blocks per second.

Source: NC block processing time (e.g. Fanuc/Siemens "block cycle time", 0.5-4 ms per block on
classic kernels; Sun et al. 2021 §2 lists it among the reasons short segments run below F). Modelled
as a minimum duration of every moving block (its cruise speed is capped at length / min_block_time_s).
Off in the LinuxCNC profiles: LinuxCNC's slow runs of very short blocks come from its segments'
sample-rate clamp (sim/planner.py), not from the block rate. A dense002q0 run behind a 5 s slow move,
which lets the task fill the motion queue first, took as long as the plain run (5.26 s for the
3142 blocks either way; docs/sim.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.profile import MachineProfile
from feedlog.sim.mechanism import Mechanism


@dataclass
class BlockTimeFloor(Mechanism):
    name = "block_time"
    kind = "limits"
    order = 40
    windowed = True

    min_block_time_s: float = 0.001

    def __post_init__(self) -> None:
        self.check_positive(min_block_time_s=self.min_block_time_s)

    @classmethod
    def default_enabled(cls, profile: MachineProfile) -> bool:
        return profile.interpolator.block_time_s > 0

    @classmethod
    def defaults(cls, profile: MachineProfile) -> dict:
        t = profile.interpolator.block_time_s
        return {"min_block_time_s": t} if t > 0 else {}

    def limit(self, ctx) -> None:
        b = ctx.blocks
        b.min_time_s = np.maximum(b.min_time_s, np.where(b.length > 0, self.min_block_time_s, 0.0))
