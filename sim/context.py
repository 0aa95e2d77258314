"""What flows between mechanisms: the simulation context and the interpolated trajectory."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from feedlog.profile import MachineProfile
from feedlog.sim.motion import Plan, sample_plan
from feedlog.sim.path import Blocks, Pieces


@dataclass
class Context:
    """Mutable state of one simulation run. `limits` mechanisms edit `blocks`, corner laws `pieces`."""

    profile: MachineProfile
    blocks: Blocks
    pieces: Pieces | None = None
    dt_s: float = 0.001
    notes: dict[str, object] = field(default_factory=dict)


@dataclass
class Trajectory:
    """Interpolated motion on a regular time grid (seconds; axis units)."""

    t_s: np.ndarray          # (N,) sample times, 0 = start of the first block
    pos: np.ndarray          # (N, k) axis positions
    speed: np.ndarray        # (N,) path speed (mm/s; deg/s for rotary-only moves)
    row: np.ndarray          # (N,) index into Blocks of the executing block
    block_start_s: np.ndarray  # (n,) per Blocks row
    block_end_s: np.ndarray
    motion_start_s: float
    motion_end_s: float
    plan: Plan | None = None

    @property
    def cycle_time_s(self) -> float:
        return max(self.motion_end_s - self.motion_start_s, 0.0)


def time_grid(total_s: float, dt_s: float) -> np.ndarray:
    """Regular grid from 0 through the end (the last sample at or after total_s)."""
    n = int(np.ceil(total_s / dt_s - 1e-9)) + 1
    return np.arange(n, dtype=np.float64) * dt_s


def block_times(row_of_piece: np.ndarray, start: np.ndarray, end: np.ndarray, n_rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Per block: earliest start and latest end of its pieces (NaN for blocks with no piece)."""
    b_start = np.full(n_rows, np.inf)
    b_end = np.full(n_rows, -np.inf)
    np.minimum.at(b_start, row_of_piece, start)
    np.maximum.at(b_end, row_of_piece, end)
    b_start[np.isinf(b_start)] = np.nan
    b_end[np.isinf(b_end)] = np.nan
    return b_start, b_end


def trajectory_from_plan(plan: Plan, pieces: Pieces, blocks: Blocks, dt_s: float) -> Trajectory:
    total = plan.total_s
    t = time_grid(total, dt_s)
    pos, speed, idx = sample_plan(plan, pieces, t)
    row = pieces.block[idx] if len(pieces) else np.zeros(len(t), np.int64)
    b_start, b_end = block_times(pieces.block, plan.t0, plan.t_end + plan.hold, len(blocks))
    moving = pieces.length > 0
    if moving.any():
        m_start = float(plan.t0[moving].min())
        m_end = float(plan.t_end[moving].max())
    else:
        m_start = m_end = 0.0
    return Trajectory(t_s=t, pos=pos, speed=speed, row=row, block_start_s=b_start, block_end_s=b_end,
                      motion_start_s=m_start, motion_end_s=m_end, plan=plan)


def hold_end(traj: Trajectory, extra_s: float, dt_s: float) -> Trajectory:
    """The trajectory with `extra_s` of standstill appended (for mechanisms that settle after the end)."""
    n = int(np.ceil(extra_s / dt_s))
    if n <= 0 or not len(traj.t_s):
        return traj
    t = np.concatenate([traj.t_s, traj.t_s[-1] + dt_s * np.arange(1, n + 1)])
    pos = np.vstack([traj.pos, np.repeat(traj.pos[-1:], n, axis=0)])
    speed = np.concatenate([traj.speed, np.zeros(n)])
    row = np.concatenate([traj.row, np.repeat(traj.row[-1:], n)])
    return Trajectory(t_s=t, pos=pos, speed=speed, row=row, block_start_s=traj.block_start_s,
                      block_end_s=traj.block_end_s, motion_start_s=traj.motion_start_s,
                      motion_end_s=traj.motion_end_s, plan=traj.plan)
