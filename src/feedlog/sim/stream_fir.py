"""The FIR interpolator on a stream of pieces (feedlog.sim.window): pulses, block times and the
filtered series window by window, the same floats as the whole program at once.

A piece's pulse depends on the corners at its two ends, so the last piece of a window waits for the
next one. The start times are a running sum continued across windows. The two moving averages are
running sums too (`moving_average`: the difference of a cumulative sum n samples apart): the window
continues the cumulative sum from the carried value and keeps its last n values, so every filtered
sample is the same float. The speed is the difference to the previous sample, which is carried.
"""

from __future__ import annotations

import numpy as np

from feedlog.sim.fir import raw_samples
from feedlog.sim.path import Pieces
from feedlog.sim.stream_plan import LINE_SPAN, Chunk, Owners


class RunningMean:
    """`fir.moving_average` (causal, n samples, the signal held at its first value before the start)
    over successive blocks of samples."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.tail: np.ndarray | None = None     # (n, k) last cumulative sums

    def __call__(self, x: np.ndarray) -> np.ndarray:
        n = self.n
        if n <= 1 or not len(x):
            return x
        k = x.shape[1]
        out = np.empty(x.shape, order="F")
        tail = np.empty((n, k))
        for c in range(k):
            if self.tail is None:
                buf = np.empty(len(x) + n)
                buf[:n] = x[0, c]
                buf[n:] = x[:, c]
                np.cumsum(buf, out=buf)
            else:
                buf = np.empty(len(x) + n)
                buf[:n] = self.tail[:, c]
                buf[n:] = x[:, c]
                buf[n - 1:] = np.cumsum(buf[n - 1:])
            np.subtract(buf[n:], buf[:-n], out=out[:, c])
            out[:, c] /= n
            tail[:, c] = buf[-n:]
        self.tail = tail
        return out


def grid_at_or_after(times: np.ndarray, dt: float, *, shift: float = 0.0) -> np.ndarray:
    """For each time s, the first grid index k with k * dt - shift >= s (np.searchsorted(t - shift, s,
    "left") on the unbounded grid t = k * dt), in the grid's own arithmetic."""
    k = np.maximum(np.ceil((times + shift) / dt).astype(np.int64), 0)
    for _ in range(2):   # ceil of a rounded quotient may be one off either way
        lower = k - 1
        k = np.where((lower >= 0) & (lower.astype(np.float64) * dt - shift >= times), lower, k)
        k = np.where(k.astype(np.float64) * dt - shift < times, k + 1, k)
    return k


class FirStream:
    """`FirInterpolator.run` on a piece stream; `push` returns the pieces whose pulses are final,
    `block_times` and `samples` turn them into per-block times and series."""

    def __init__(self, mech, dt_s: float, lin: list[int]) -> None:
        self.mech, self.dt, self.lin = mech, dt_s, lin
        self.td = mech.t1_s + mech.t2_s
        self.delay = 0.5 * self.td
        self.buf: Chunk | None = None       # the last final piece (context), then pieces not yet final
        self.has_context = False
        self.t = 0.0
        self.top = -np.inf                  # running maximum of the phase starts
        self.k = 0
        self.first_sample = True
        n1, n2 = mech.filter_samples(dt_s)
        self.mean1, self.mean2 = RunningMean(n1), RunningMean(n2)
        self.prev_pos: np.ndarray | None = None
        self.rows = Owners()
        self.first_rows = True
        self.held: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []   # rows before any motion
        self.open: tuple[int, float, float] | None = None   # (packed, start, end) of the open row
        self.open_row = -1
        self.first_row_open = True
        self.motion = (np.inf, -np.inf)
        self.raw_end = 0.0

    def push(self, chunk: Chunk | None, end: bool):
        """(pieces, pulses, t0) of the pieces that are final now, or None."""
        self.buf = Chunk.concat([self.buf, chunk]) if chunk is not None else self.buf
        buf = self.buf
        if buf is None:
            return None
        skip = 1 if self.has_context else 0
        upto = len(buf) if end else len(buf) - 1     # a piece's end corner needs the next piece
        if upto <= skip:
            return None
        shapes = self.mech.shapes(buf.pieces.slice(0, upto + (0 if end else 1)), buf.side["tol"][:upto + (0 if end else 1)],
                                  self.lin)
        shapes = tuple(a[skip:upto] for a in shapes)
        out = buf.slice(skip, upto)
        stop = out.side["stop_after"].copy()
        if end:
            stop[-1] = False
        pulses = self.mech.timing(out.pieces, shapes, stop)
        sums = np.cumsum(np.concatenate(([self.t], pulses.dur + pulses.gap)))
        t0, self.t = sums[:-1], float(sums[-1])
        self.buf = buf.slice(upto - 1, len(buf))
        self.has_context = True
        moving = out.pieces.length > 0
        if moving.any():
            self.motion = (min(self.motion[0], float(t0[moving].min())),
                           max(self.motion[1], float((t0 + pulses.dur)[moving].max() + self.td)))
        self.raw_end = float((t0 + pulses.dur + pulses.gap)[-1])
        packed = out.side["block"] * LINE_SPAN + out.side["line"]
        first = grid_at_or_after(t0, self.dt, shift=self.delay)
        if self.first_rows:     # grid_index: the first piece owns the grid from its start
            first[0] = 0
            self.first_rows = False
        self.rows.add(first, packed)
        return out, pulses, t0

    def block_times(self, final, end: bool):
        """(packed block and line, start s, end s) of the rows finished, the first one stretched back to
        the motion start and, at the end, the last one to the motion end (`cover_motion`)."""
        out, pulses, t0 = final
        rows = out.pieces.block
        packed = out.side["block"] * LINE_SPAN + out.side["line"]
        start = t0 + self.delay
        stop = t0 + pulses.dur + pulses.gap + self.delay
        change = np.flatnonzero(rows[1:] != rows[:-1]) + 1
        first = np.concatenate(([0], change))
        last = np.append(change - 1, len(rows) - 1)
        r, p, s, e = rows[first], packed[first], start[first], stop[last]
        if r[0] == self.open_row:
            s = s.copy()
            s[0] = self.open[1]
        elif self.open is not None:
            r, p = np.concatenate(([self.open_row], r)), np.concatenate(([self.open[0]], p))
            s, e = np.concatenate(([self.open[1]], s)), np.concatenate(([self.open[2]], e))
        self.open_row, self.open = int(r[-1]), (int(p[-1]), float(s[-1]), float(e[-1]))
        p, s, e = p[:-1], s[:-1], e[:-1]
        return self._release(p, s, e)

    def _release(self, p, s, e):
        """Rows go out once the motion start is known: the first row that ran starts no later
        (`cover_motion`)."""
        if self.first_row_open:
            if not np.isfinite(self.motion[0]):
                self.held.append((p, s, e))
                return np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
            if self.held:
                p, s, e = (np.concatenate([h[i] for h in self.held] + [x]) for i, x in enumerate((p, s, e)))
                self.held = []
            if len(p):
                s = s.copy()
                s[0] = min(s[0], self.motion[0])
                self.first_row_open = False
        return p, s, e

    def close(self):
        """The held and the last open row, the last one stretched to the motion end (a program that
        never moves has its motion at 0, as `FirInterpolator.run` has)."""
        if not np.isfinite(self.motion[0]):
            self.motion = (0.0, 0.0)
        if self.open is None:
            return self._release(np.zeros(0, np.int64), np.zeros(0), np.zeros(0))
        p, s, e = self.open
        return self._release(np.array([p]), np.array([s]), np.array([max(e, self.motion[1])]))

    def samples(self, final, end: bool):
        """(t, pos, speed, packed block and line) of the grid samples up to the next piece's start (the
        whole grid's end for the last window), or None."""
        out, pulses, t0 = final
        starts = pulses.phase_starts(t0)
        starts = np.maximum.accumulate(np.maximum(starts, self.top))
        self.top = float(starts[-1])
        first = grid_at_or_after(starts, self.dt)
        if self.first_sample:
            first[0] = 0
            self.first_sample = False
        k0 = self.k
        k1 = int(np.ceil((self.raw_end + self.td) / self.dt - 1e-9)) + 1 if end else \
            int(grid_at_or_after(np.array([max(self.t, self.top)]), self.dt)[0])
        if k1 <= k0:
            return None
        first = np.clip(first, k0, k1)
        first[0] = k0
        g = np.repeat(np.arange(len(starts), dtype=np.int32), np.diff(first, append=k1))
        t = np.arange(k0, k1, dtype=np.float64) * self.dt
        raw = raw_samples(out.pieces, pulses, starts, t, g)
        pos = self.mean2(self.mean1(raw))
        speed = self._speed(pos)
        self.k = k1
        return t, pos, speed, self.rows.take(k0, k1)

    def _speed(self, pos: np.ndarray) -> np.ndarray:
        """`fir.path_speed`: TCP speed from the previous sample, the rotary axes' where only they move."""
        prev = pos[:1] if self.prev_pos is None else self.prev_pos
        self.prev_pos = pos[-1:].copy()
        rot = [i for i in range(pos.shape[1]) if i not in self.lin]

        def norm(cols: list[int]) -> np.ndarray:
            total = np.zeros(len(pos))
            for c in cols:
                step = np.diff(np.concatenate((prev[:, c], pos[:, c])))
                total += step * step
            return np.sqrt(total) / self.dt

        speed = norm(self.lin)
        if rot:
            rot_only = speed < 1e-9
            if rot_only.any():
                speed = np.where(rot_only, norm(rot), speed)
        return speed


__all__ = ["FirStream", "Pieces"]
