"""What flows between mechanisms: the simulation context and the interpolated trajectory.

A `Trajectory` knows its timing (per-block start/end, motion start/end: the cycle time) as soon as
the interpolator has planned; the sampled series (positions on the interpolation grid) is computed
on first access, so a cycle-time prediction does not pay for a million-row series it never reads.
`series` mechanisms chain transformations onto the sampler with `Trajectory.map`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from feedlog.errors import SimulationError
from feedlog.profile import MachineProfile
from feedlog.sim.motion import Plan, grid_counts, sample_plan, sample_plan_at
from feedlog.sim.path import Blocks, Pieces

MAX_SAMPLES = 50_000_000  # one sampled series: 13.9 h at 1 kHz, about 3 GB with six axes
# (t_s, pos, speed, row): sample times, (N, k) axis positions, path speed, Blocks row index
Samples = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


@dataclass
class Window:
    """What a windowed simulation (feedlog.sim.window) tells the mechanisms about the rows they see.

    `last`: the rows reach the program's end (the last row is the program's last). `state`: what each
    mechanism handed over from the previous window (by name). A `limits` mechanism whose result for
    the last rows may change with rows still to come calls `pending(name, block)`: the rows from
    program block `block` on are done again, with the next rows, in the next window. The window
    restarts at the earliest such block of all mechanisms, P; a mechanism that carries state across
    windows registers `carry(name, state_at)`, and `state_at(P)` is what it gets in the next window.
    `core`: the pieces [lo, hi) of `ctx.pieces` the window keeps (the rest is context either side),
    for a corner law's counts."""

    last: bool = True
    state: dict[str, dict] = field(default_factory=dict)
    core: tuple[int, int] | None = None
    pending_from: dict[str, int] = field(default_factory=dict)
    hand_over: dict[str, object] = field(default_factory=dict)

    def pending(self, name: str, block: int) -> None:
        """Rows from program block `block` on may still change with later rows."""
        self.pending_from[name] = min(int(block), self.pending_from.get(name, int(block)))

    def restart(self) -> float:
        """The earliest pending block so far (inf: none): rows from it on may change, so a row whose
        result depends on a later row at or after it is pending too."""
        return min(self.pending_from.values(), default=float("inf"))

    def carry(self, name: str, state_at) -> None:
        """`state_at(block) -> dict`: the state to start from when the next window starts at `block`."""
        self.hand_over[name] = state_at

    def mine(self, name: str) -> dict:
        return self.state.get(name) or {}


@dataclass
class Context:
    """Mutable state of one simulation run. `limits` mechanisms edit `blocks`, corner laws `pieces`.
    `window` is None when the whole program is simulated at once."""

    profile: MachineProfile
    blocks: Blocks
    pieces: Pieces | None = None
    dt_s: float = 0.001
    notes: dict[str, object] = field(default_factory=dict)
    window: Window | None = None


class Trajectory:
    """Interpolated motion: timing now, samples on a regular grid on demand (seconds; axis units).

    `grid` (n samples, period) and `sample_at(index) -> (t, pos)`, given only where the samples are
    each a function of their own time (a planned trajectory, not one a filter has passed over): the
    grid rows `index` alone, equal to those of `samples`."""

    def __init__(self, sampler: Callable[[], Samples], *, block_start_s: np.ndarray, block_end_s: np.ndarray,
                 motion_start_s: float, motion_end_s: float, plan: Plan | None = None,
                 grid: Callable[[], tuple[int, float]] | None = None,
                 sample_at: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None) -> None:
        self._sampler = sampler
        self._grid = grid
        self.sample_at = sample_at
        self._samples: Samples | None = None
        self.block_start_s = block_start_s
        self.block_end_s = block_end_s
        self.motion_start_s = motion_start_s
        self.motion_end_s = motion_end_s
        self.plan = plan

    @property
    def samples(self) -> Samples:
        if self._samples is None:
            self._samples = self._sampler()
        return self._samples

    @property
    def grid(self) -> tuple[int, float] | None:
        """(samples, period s) of the regular grid when `sample_at` is given, else None."""
        return None if self._grid is None or self.sample_at is None else self._grid()

    @property
    def t_s(self) -> np.ndarray:
        return self.samples[0]

    @property
    def pos(self) -> np.ndarray:
        return self.samples[1]

    @property
    def speed(self) -> np.ndarray:
        return self.samples[2]

    @property
    def row(self) -> np.ndarray:
        return self.samples[3]

    @property
    def cycle_time_s(self) -> float:
        return max(self.motion_end_s - self.motion_start_s, 0.0)

    def map(self, fn: Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], Samples]) -> Trajectory:
        """The same timing with the samples passed through `fn` (applied lazily)."""
        return Trajectory(lambda: fn(*self.samples), block_start_s=self.block_start_s,
                          block_end_s=self.block_end_s, motion_start_s=self.motion_start_s,
                          motion_end_s=self.motion_end_s, plan=self.plan)


def grid_samples(total_s: float, dt_s: float) -> int:
    """Samples of a regular grid from 0 through `total_s`; SimulationError beyond MAX_SAMPLES (a
    series that would not fit in memory: a program of years, or a period of picoseconds)."""
    n = total_s / dt_s - 1e-9
    if not n < MAX_SAMPLES:
        raise SimulationError(f"the simulated series would hold {n:.3g} samples ({total_s:.6g} s every {dt_s:g} s), "
                              f"more than {MAX_SAMPLES:,}; sample it coarser (--dt)")
    return int(np.ceil(n)) + 1


def time_grid(total_s: float, dt_s: float) -> np.ndarray:
    """Regular grid from 0 through the end (the last sample at or after total_s)."""
    return np.arange(grid_samples(total_s, dt_s), dtype=np.float64) * dt_s


def block_times(row_of_piece: np.ndarray, start: np.ndarray, end: np.ndarray, n_rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Per block: earliest start and latest end of its pieces (NaN for blocks with no piece)."""
    b_start = np.full(n_rows, np.inf)
    b_end = np.full(n_rows, -np.inf)
    # pieces are in time order, so a block's first piece has its start and its last piece its end
    if len(row_of_piece):
        if np.all(row_of_piece[1:] >= row_of_piece[:-1]):  # the usual case: blocks in order, no sort
            change = np.flatnonzero(row_of_piece[1:] != row_of_piece[:-1]) + 1
            first = np.concatenate(([0], change))
            last = np.append(change - 1, len(row_of_piece) - 1)
        else:
            first = np.unique(row_of_piece, return_index=True)[1]
            last = len(row_of_piece) - 1 - np.unique(row_of_piece[::-1], return_index=True)[1]
        rows = row_of_piece[first]
        b_start[rows] = np.minimum(b_start[rows], start[first])
        b_end[row_of_piece[last]] = np.maximum(b_end[row_of_piece[last]], end[last])
    b_start[np.isinf(b_start)] = np.nan
    b_end[np.isinf(b_end)] = np.nan
    return b_start, b_end


def cover_motion(b_start: np.ndarray, b_end: np.ndarray, m_start: float, m_end: float) -> tuple[np.ndarray, np.ndarray]:
    """Stretch the first block back to the motion start and the last one to the motion end, so the
    block durations add up to the cycle time when a filter delays and spreads the motion."""
    b_start, b_end = b_start.copy(), b_end.copy()
    ran = np.flatnonzero(~np.isnan(b_start))
    if len(ran):
        first = ran[np.argmin(b_start[ran])]
        last = ran[np.argmax(b_end[ran])]
        b_start[first] = min(b_start[first], m_start)
        b_end[last] = max(b_end[last], m_end)
    return b_start, b_end


def one_row_per_block(block: np.ndarray, line: np.ndarray, start: np.ndarray, end: np.ndarray):
    """Rows of one block next to each other (an arc LinuxCNC's canon ran as two lines in two chains,
    feedlog.sim.naive_cam) become one: the first start, the last end."""
    if len(block) < 2 or not np.any(block[1:] == block[:-1]):
        return block, line, start, end
    first = np.flatnonzero(np.r_[True, block[1:] != block[:-1]])
    return block[first], line[first], start[first], np.maximum.reduceat(end, first)


def trajectory_from_plan(plan: Plan, pieces: Pieces, blocks: Blocks, dt_s: float) -> Trajectory:
    # during a parabolic blend both pieces move; the executing block changes halfway through the
    # overlap (LinuxCNC reports whichever segment is faster, which swaps at the middle)
    half = 0.5 * plan.overlap_s
    switch = plan.t0 + np.concatenate(([0.0], half[:-1])) if len(plan.t0) else plan.t0

    def sample() -> Samples:
        t = time_grid(plan.total_s, dt_s)
        pos, speed, _ = sample_plan(plan, pieces, t)
        if not len(pieces):
            return t, pos, speed, np.zeros(len(t), np.int64)
        counts = grid_counts(switch, len(t), dt_s)
        row = np.repeat(pieces.block, counts)
        return t, pos, speed, row

    def grid() -> tuple[int, float]:
        return grid_samples(plan.total_s, dt_s), dt_s

    def sample_at(index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return sample_plan_at(plan, pieces, index, grid_samples(plan.total_s, dt_s), dt_s)

    b_start, b_end = block_times(pieces.block, switch, plan.t_end + plan.hold - half, len(blocks))
    moving = pieces.length > 0
    if moving.any():
        m_start = float(plan.t0[moving].min())
        m_end = float(plan.t_end[moving].max())
    else:
        m_start = m_end = 0.0
    return Trajectory(sample, block_start_s=b_start, block_end_s=b_end, motion_start_s=m_start,
                      motion_end_s=m_end, plan=plan, grid=grid, sample_at=sample_at)


def hold_end(traj: Trajectory, extra_s: float, dt_s: float) -> Trajectory:
    """The trajectory with `extra_s` of standstill appended (for mechanisms that settle after the end)."""
    grid_samples(extra_s, dt_s)  # refuses a standstill too long to sample
    n = int(np.ceil(extra_s / dt_s))
    if n <= 0:
        return traj

    def extend(t, pos, speed, row) -> Samples:
        if not len(t):
            return t, pos, speed, row
        return (np.concatenate([t, t[-1] + dt_s * np.arange(1, n + 1)]),
                np.vstack([pos, np.repeat(pos[-1:], n, axis=0)]),
                np.concatenate([speed, np.zeros(n)]), np.concatenate([row, np.repeat(row[-1:], n)]))

    return traj.map(extend)
