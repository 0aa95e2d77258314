"""The look-ahead planner and the CAM estimate on a stream of pieces: plans, block times and series
window by window, the same floats as planning the whole program at once (feedlog.sim.window).

Why the windows give the whole program's answer (docs/sim.md, "Windowed simulation"):

- Running sums continue: the cumulative `2 a L` of the backward/forward passes and the start times
  of the pieces are one `np.cumsum` over the carried value and the window's terms, which is the same
  sequence of additions as one sum over the program.
- The backward pass is a running minimum from the program's end, `M[j] = min_{k >= j} (w[k] + D[k])`.
  A minimum is exact, so only the set matters: every term beyond the window is at least `D[r]` (w >= 0
  and D never decreases), so for the pieces whose partial minimum is already <= D[r] the rest of the
  program cannot change it. The look-ahead window caps every w[j] at `D[last(j)] - D[j]`, so this holds
  about `lookahead_blocks` queue entries before the window's end; those pieces are final, the others
  wait for the next window. A piece's cap also needs its look-ahead entries and the next piece's speed
  limit, which the window must hold.
- The forward pass is a running minimum from the program's start: its value is carried.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from feedlog.sim.motion import Plan, _phases, evaluate_phases, plan_from_speeds
from feedlog.sim.path import Pieces

PIECE_FIELDS = tuple(Pieces.__dataclass_fields__)
LINE_SPAN = 1 << 32   # a sample's program block and line packed into one int64: block * LINE_SPAN + line


def _cumsum_from(initial: float, values: np.ndarray) -> np.ndarray:
    """values' running sum continuing from `initial` (np.cumsum over the whole program, to the bit)."""
    return np.cumsum(np.concatenate(([initial], values)))[1:]


@dataclass
class Chunk:
    """Pieces (their `block` is the global row of the limited block stream), columns per piece the
    later stages need (`side`: program block and line, feed scale, ...), and their plan."""

    pieces: Pieces
    side: dict[str, np.ndarray]
    plan: Plan | None = None

    def __len__(self) -> int:
        return len(self.pieces)

    def slice(self, lo: int, hi: int) -> Chunk:
        plan = None if self.plan is None else Plan(**{k: getattr(self.plan, k)[lo:hi] for k in Plan.__dataclass_fields__})
        return Chunk(self.pieces.slice(lo, hi), {k: v[lo:hi] for k, v in self.side.items()}, plan)

    @staticmethod
    def concat(parts: list[Chunk]) -> Chunk:
        parts = [p for p in parts if p is not None and len(p)]
        if len(parts) == 1:
            return parts[0]
        return Chunk(Pieces.concat([p.pieces for p in parts]),
                     {k: np.concatenate([p.side[k] for p in parts]) for k in parts[0].side})


class LookaheadStream:
    """`plan_speeds` on a piece stream: `push` pieces, get back the prefix whose plan is final."""

    def __init__(self, lookahead: int | None) -> None:
        self.lookahead = lookahead
        self.buf: Chunk | None = None
        self.d_sum = 0.0          # cumulative 2 a L through the last planned piece
        self.entries = 0          # queue entries through the last planned piece
        self.forward_min = np.inf  # running minimum of (w - D) of the forward pass
        self.v1 = 0.0             # speed leaving the last planned piece
        self.t = 0.0              # start time of the next piece

    def push(self, chunk: Chunk | None, end: bool) -> Chunk | None:
        self.buf = Chunk.concat([self.buf, chunk]) if chunk is not None else self.buf
        buf = self.buf
        if buf is None or not len(buf):
            return None
        pc = buf.pieces
        m = len(pc)
        vmax = pc.v_max
        cap = np.minimum(np.minimum(pc.v_end, vmax), np.append(vmax[1:], 0.0))
        cap = np.where(pc.overlap, 0.0, cap)
        if end:
            cap[-1] = 0.0
        w = cap ** 2
        d_cum = _cumsum_from(self.d_sum, 2.0 * pc.a_max * pc.length)
        resolved = m if end else m - 1          # a piece's cap needs the next piece
        if self.lookahead is not None:
            entry = self.entries + np.cumsum(pc.clamp_len > 0)
            last = np.searchsorted(entry, entry + self.lookahead, side="right") - 1
            w = np.minimum(w, d_cum[np.clip(last, 0, m - 1)] - d_cum)
            if not end:   # the look-ahead entries must all be in the buffer
                resolved = min(resolved, int(np.searchsorted(entry, entry[-1] - self.lookahead, side="left")))
        if resolved <= 0:
            return None
        e = w[:resolved] + d_cum[:resolved]
        back = np.minimum.accumulate(e[::-1])[::-1]
        # final where the rest of the program (every term >= D[resolved]) cannot lower the minimum
        final = resolved if end else int(np.searchsorted(back, d_cum[resolved], side="right"))
        if final <= 0:
            return None
        wb = back[:final] - d_cum[:final]
        run = np.minimum.accumulate(np.concatenate(([self.forward_min], wb - d_cum[:final])))[1:]
        u = d_cum[:final] + np.minimum(0.0, run)
        v1 = np.sqrt(np.clip(np.minimum(u, wb), 0.0, None))
        v0 = np.concatenate(([self.v1], v1[:-1]))
        out = buf.slice(0, final)
        out.plan = plan_from_speeds(out.pieces, v0, v1, self.t)
        p = out.plan
        self.t = float(p.t0[-1] + (p.t_acc[-1] + p.t_cru[-1] + p.t_dec[-1] + p.hold[-1] - p.overlap_s[-1]))
        self.d_sum = float(d_cum[final - 1])
        if self.lookahead is not None:
            self.entries = int(entry[final - 1])
        self.forward_min = float(run[-1])
        self.v1 = float(v1[-1])
        self.buf = buf.slice(final, m)
        return out


class CamStream:
    """The CAM estimate on a piece stream: every piece at its programmed feed, one after the other."""

    def __init__(self) -> None:
        self.t = 0.0

    def push(self, chunk: Chunk | None, end: bool) -> Chunk | None:
        if chunk is None or not len(chunk):
            return None
        pc = chunk.pieces
        speed = chunk.side["feed"]
        with np.errstate(divide="ignore", invalid="ignore"):
            dur = np.where(pc.length > 0, pc.length / speed, 0.0)
        zero = np.zeros(len(pc))
        sums = np.cumsum(np.concatenate(([self.t], dur + pc.hold_s)))
        chunk.plan = Plan(t0=sums[:-1], v0=np.where(dur > 0, speed, 0.0), v1=np.where(dur > 0, speed, 0.0),
                          vp=np.where(dur > 0, speed, 0.0), acc=zero, t_acc=zero, t_cru=dur, t_dec=zero,
                          hold=pc.hold_s.copy(), overlap_s=zero)
        self.t = float(sums[-1])
        return chunk


def grid_first(times: np.ndarray, dt: float) -> np.ndarray:
    """`grid_counts`' first grid index at or after each time: ceil(t / dt - 1e-9), at least 0."""
    return np.maximum(np.ceil(times / dt - 1e-9).astype(np.int64), 0)


@dataclass
class Owners:
    """Which item (piece, block) each grid sample belongs to when items take over at grid indices
    `first` (non-decreasing): items whose index is not reached yet wait here for the next window."""

    first: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    value: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    current: int = 0
    top: int = 0              # running maximum of the take-over indices

    def add(self, first: np.ndarray, value: np.ndarray) -> None:
        first = np.maximum.accumulate(np.maximum(first, self.top)) if len(first) else first
        if len(first):
            self.top = int(first[-1])
        self.first = np.concatenate([self.first, first])
        self.value = np.concatenate([self.value, value])

    def take(self, k0: int, k1: int) -> np.ndarray:
        """The owner of samples k0 .. k1 - 1 (and forget the items that took over before k1)."""
        n = k1 - k0
        firsts = np.concatenate(([k0], np.clip(self.first, k0, k1)))
        values = np.concatenate(([self.current], self.value))
        counts = np.diff(firsts, append=k1)
        out = np.repeat(values, counts)
        started = int(np.searchsorted(self.first, k1 - 1, side="right")) if n else 0
        if started:
            self.current = int(self.value[started - 1])
        self.first, self.value = self.first[started:], self.value[started:]
        return out


class PlanSampler:
    """Block times and the sampled series of a stream of planned chunks (`trajectory_from_plan` and
    `sample_plan`, window by window). `blocks(chunk)` returns the rows whose times are final."""

    def __init__(self, dt_s: float) -> None:
        self.dt = dt_s
        self.half = 0.0                   # half the previous piece's blend overlap
        self.prev: Chunk | None = None    # the piece before the chunk (predecessor of a blend)
        self.k = 0                        # next grid sample to produce
        self.switch = Owners()            # which piece's block each sample reports
        self.open_row = -1                # the row whose last piece may still come
        self.open_packed = 0
        self.open_times = (np.nan, np.nan)
        self.motion = (np.inf, -np.inf)
        self.total_s = 0.0

    def block_times(self, chunk: Chunk) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(program block and line packed, start s, end s) of the rows this chunk finishes (its last row
        stays open: its next pieces may come with the next chunk)."""
        pc, plan = chunk.pieces, chunk.plan
        half = 0.5 * plan.overlap_s
        switch = plan.t0 + np.concatenate(([self.half], half[:-1]))
        end = plan.t_end + plan.hold - half
        self.half = float(half[-1])
        moving = pc.length > 0
        if moving.any():
            self.motion = (min(self.motion[0], float(plan.t0[moving].min())),
                           max(self.motion[1], float(plan.t_end[moving].max())))
        self.total_s = max(self.total_s, float(np.max(plan.t_end + plan.hold)))
        packed = chunk.side["block"] * LINE_SPAN + chunk.side["line"]
        self.switch.add(grid_first(switch, self.dt), packed)
        rows = pc.block
        if np.any(rows[1:] < rows[:-1]) or rows[0] < self.open_row:
            raise AssertionError("pieces out of block order in a windowed simulation")
        change = np.flatnonzero(rows[1:] != rows[:-1]) + 1
        first = np.concatenate(([0], change))
        last = np.append(change - 1, len(rows) - 1)
        r, p, s, e = rows[first], packed[first], switch[first], end[last]
        if r[0] == self.open_row:    # the open row continues: it keeps its start
            s = s.copy()
            s[0] = self.open_times[0]
        elif self.open_row >= 0:
            p = np.concatenate(([self.open_packed], p))
            s = np.concatenate(([self.open_times[0]], s))
            e = np.concatenate(([self.open_times[1]], e))
            r = np.concatenate(([self.open_row], r))
        self.open_row, self.open_packed, self.open_times = int(r[-1]), int(p[-1]), (float(s[-1]), float(e[-1]))
        return p[:-1], s[:-1], e[:-1]

    def close(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The last open row."""
        if self.open_row < 0:
            return np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
        return np.array([self.open_packed]), np.array([self.open_times[0]]), np.array([self.open_times[1]])

    def samples(self, chunk: Chunk, k_end: int | None):
        """Samples of the grid from where the last call stopped up to the chunk's last piece's end
        (`k_end`: the grid's end, for the program's last chunk; else the next piece's start):
        (t, pos, speed, block * LINE_SPAN + line) or None when the chunk holds no grid sample."""
        plan = chunk.plan
        t_next = plan.t0[-1] + (plan.t_acc[-1] + plan.t_cru[-1] + plan.t_dec[-1] + plan.hold[-1] - plan.overlap_s[-1])
        k1 = k_end if k_end is not None else max(self.k, int(grid_first(np.array([t_next]), self.dt)[0]))
        ctx = Chunk.concat([self.prev, chunk]) if self.prev is not None else chunk
        ctx.plan = plan if self.prev is None else Plan(**{k: np.concatenate([getattr(self.prev.plan, k), getattr(plan, k)])
                                                          for k in Plan.__dataclass_fields__})
        skip = 0 if self.prev is None else 1
        self.prev = chunk.slice(len(chunk) - 1, len(chunk))
        k0 = self.k
        if k1 <= k0:
            return None
        phases = _phases(ctx.plan, ctx.pieces)
        starts = phases[0]
        first = grid_first(starts, self.dt)
        first[:4 * skip] = 0                  # the context piece has no samples here
        first = np.clip(np.maximum.accumulate(first), k0, k1)
        first[4 * skip] = k0
        counts = np.diff(first[4 * skip:], append=k1)
        g = np.repeat(np.arange(4 * skip, len(starts), dtype=np.int32), counts)
        t = np.arange(k0, k1, dtype=np.float64) * self.dt
        pos, speed = evaluate_phases(ctx.plan, ctx.pieces, phases, t, g)
        self.k = k1
        return t, pos, speed, self.switch.take(k0, k1)


class PlannedStream:
    """A plan-based interpolator's windowed form (look-ahead, CAM) with its block times and series."""

    def __init__(self, planner, dt_s: float) -> None:
        self.planner = planner
        self.sampler = PlanSampler(dt_s)
        self.dt = dt_s

    @property
    def motion(self) -> tuple[float, float]:
        return self.sampler.motion

    def push(self, chunk: Chunk, end: bool) -> Chunk | None:
        return self.planner.push(chunk, end)

    def block_times(self, final: Chunk, end: bool):
        return self.sampler.block_times(final)

    def close(self):
        return self.sampler.close()

    def samples(self, final: Chunk, end: bool):
        k_end = int(np.ceil(self.sampler.total_s / self.dt - 1e-9)) + 1 if end else None
        return self.sampler.samples(final, k_end)
