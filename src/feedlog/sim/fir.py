"""FIR-filter interpolation: blocks as velocity pulses smoothed by cascaded moving-average filters.

Source: Tajima & Sencer, "Global tool-path smoothing for CNC machine tools with uninterrupted
acceleration" (IJMTM 2017) as used by Chien et al. (2024) §2.1 and §3.1 (T1 = 70 ms, T2 = 10 ms).
Each block k is a pulse of constant feed F_k along the block (raw motion); the axis positions are
that raw motion through two causal moving averages of widths T1 and T2 (acceleration time and jerk
time). Short blocks' pulses overlap in the filter window, so "global blending" of short segments
emerges without explicit corner handling. Around a junction with cornering angle theta the pulses
are lowered to F* over half the filter delay (Td / 2, Td = T1 + T2) each side so that the blend
error stays within eps_TCP (Chien Eq. 3 with F1* = F2* = F*):

    eps = F* sqrt(2 - 2 cos theta) (3 T1^2 + T2^2) / (24 T1)

Exact stops (G61) insert a standstill of Td so the filter settles. The pulse height is capped by the
axis velocity limits and by a_max * T1 (the acceleration one pulse edge produces through T1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.profile import MachineProfile
from feedlog.sim.context import Context, Trajectory, block_times, cover_motion, time_grid
from feedlog.sim.mechanism import Mechanism
from feedlog.sim.path import Pieces

CHUNK = 1 << 16  # samples evaluated together


def moving_average(x: np.ndarray, n: int) -> np.ndarray:
    """Causal moving average over n samples along axis 0, the signal held at x[0] before the start.
    Running sums column by column in one reused buffer; 2-D results are Fortran-ordered."""
    if n <= 1:
        return x
    if x.ndim == 1:
        return moving_average(x[:, None], n)[:, 0]
    out = np.empty(x.shape, order="F")
    buf = np.empty(len(x) + n)
    for c in range(x.shape[1]):
        buf[:n] = x[0, c]
        buf[n:] = x[:, c]
        np.cumsum(buf, out=buf)
        np.subtract(buf[n:], buf[:-n], out=out[:, c])
        out[:, c] /= n
    return out


def path_speed(pos: np.ndarray, lin: list[int], dt: float, *, chunk: int = 1 << 16) -> np.ndarray:
    """Speed from successive positions (first sample 0): TCP speed, or the rotary axes' speed where
    only they move (mm/s or deg/s). Evaluated in chunks of samples so temporaries stay in cache."""
    n = len(pos)
    rot = [i for i in range(pos.shape[1]) if i not in lin]
    speed = np.empty(n)
    for a in range(0, n, chunk):
        b = min(a + chunk, n)

        def norm(cols: list[int]) -> np.ndarray:
            total = np.zeros(b - a)
            for c in cols:
                step = np.diff(pos[a - 1:b, c]) if a else np.diff(pos[:b, c], prepend=pos[0, c])
                total += step * step
            return np.sqrt(total) / dt

        part = norm(lin)
        if rot:
            rot_only = part < 1e-9
            if rot_only.any():
                part = np.where(rot_only, norm(rot), part)
        speed[a:b] = part
    return speed


def grid_index(t: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """For each grid time t (regular, increasing): the last i with starts[i] <= t (0 before the first);
    starts non-decreasing. Equals searchsorted(starts, t, 'right') - 1 clipped at 0, via one repeat."""
    first = np.searchsorted(t, starts, side="left")
    first[0] = 0
    return np.repeat(np.arange(len(starts), dtype=np.int32), np.diff(first, append=len(t)))


def corner_feed(theta: np.ndarray, tol_mm: np.ndarray, t1: float, t2: float) -> np.ndarray:
    """F* (per second) that keeps the blend error of a corner of angle theta within tol (Eq. 3)."""
    chord = np.sqrt(np.clip(2.0 - 2.0 * np.cos(theta), 0.0, None))
    k = (3 * t1 ** 2 + t2 ** 2) / (24 * t1)
    with np.errstate(divide="ignore"):
        return np.where(chord > 1e-12, tol_mm / (chord * k), np.inf)


@dataclass
class FirInterpolator(Mechanism):
    name = "fir"
    kind = "interpolator"
    uses_corner_law = False
    windowed = True
    stream = "feedlog.sim.stream_fir:FirStream"   # its windowed form (feedlog.sim.window)

    t1_s: float = 0.070
    t2_s: float = 0.010
    tolerance_mm: float = 0.01  # eps_TCP when the block has no G64 P

    def __post_init__(self) -> None:
        self.check_positive(t1_s=self.t1_s, tolerance_mm=self.tolerance_mm)
        self.check_non_negative(t2_s=self.t2_s)
        if self.t2_s > self.t1_s:
            raise ValueError(f"t2_s ({self.t2_s}) must not exceed t1_s ({self.t1_s})")

    @classmethod
    def default_enabled(cls, profile: MachineProfile) -> bool:
        return profile.interpolator.fir_t1_s > 0

    @classmethod
    def defaults(cls, profile: MachineProfile) -> dict:
        ip = profile.interpolator
        out: dict = {}
        if ip.fir_t1_s > 0:
            out.update(t1_s=ip.fir_t1_s, t2_s=ip.fir_t2_s)
        if ip.path_tolerance_mm > 0:
            out["tolerance_mm"] = ip.path_tolerance_mm
        return out

    def pulses(self, ctx: Context) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per piece: feed F, corner feeds at start/end, zone lengths at start/end."""
        return self.shapes(ctx.pieces, ctx.blocks.tol[ctx.pieces.block], ctx.blocks.linear_index)

    def shapes(self, pc: Pieces, tol_piece: np.ndarray, lin: list[int]):
        """`pulses` from the pieces, each piece's G64 P tolerance and the linear axis columns."""
        m = len(pc)
        feed = np.minimum(pc.v_max, pc.a_max * self.t1_s)
        f_start = np.full(m, np.inf)
        f_end = np.full(m, np.inf)
        if m > 1:
            j = np.arange(m - 1)
            u1 = pc.tangent_xyz(j, pc.length[j], lin)
            u2 = pc.tangent_xyz(j + 1, np.zeros(m - 1), lin)
            theta = np.arccos(np.clip(np.einsum("ij,ij->i", u1, u2), -1.0, 1.0))
            tol = tol_piece[:-1]
            tol = np.where(tol > 0, tol, self.tolerance_mm)
            fc = np.minimum(corner_feed(theta, tol, self.t1_s, self.t2_s), np.minimum(feed[j], feed[j + 1]))
            f_end[j] = fc
            f_start[j + 1] = fc
        half = 0.5 * (self.t1_s + self.t2_s)
        slow_s = f_start < feed
        slow_e = f_end < feed
        zone_s = np.where(slow_s, np.minimum(f_start * half, 0.5 * pc.length), 0.0)
        zone_e = np.where(slow_e, np.minimum(f_end * half, 0.5 * pc.length), 0.0)
        f_start = np.where(slow_s, f_start, feed)
        f_end = np.where(slow_e, f_end, feed)
        return feed, f_start, f_end, zone_s, zone_e

    def timing(self, pc: Pieces, shapes, stop: np.ndarray) -> Pulses:
        """The pulses of the pieces: phase durations, the standstill after each (`stop`: an exact stop
        follows, the filter settles), and their positions along the piece."""
        feed, f_s, f_e, z_s, z_e = shapes
        mid = np.maximum(pc.length - z_s - z_e, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            d_s = np.where(z_s > 0, z_s / f_s, 0.0)
            d_m = np.where(mid > 0, mid / feed, 0.0)
            d_e = np.where(z_e > 0, z_e / f_e, 0.0)
        gap = pc.hold_s + np.where(stop, self.t1_s + self.t2_s, 0.0)
        dur = d_s + d_m + d_e
        s_1 = d_s * f_s
        s_2 = s_1 + d_m * feed
        s_end = np.minimum(s_2 + d_e * f_e, pc.length)
        return Pulses(d_s=d_s, d_m=d_m, dur=dur, gap=gap,
                      s_phase=np.stack([np.zeros(len(pc)), s_1, s_2, s_end], axis=1).ravel(),
                      f_phase=np.stack([f_s, feed, f_e, np.zeros(len(pc))], axis=1).ravel())

    def run(self, ctx: Context) -> Trajectory:
        pc = ctx.pieces
        blocks = ctx.blocks
        dt = ctx.dt_s
        stop = blocks.stop_after[pc.block].copy()
        if len(stop):
            stop[-1] = False
        pulses = self.timing(pc, self.pulses(ctx), stop)
        dur, gap = pulses.dur, pulses.gap
        t0 = np.concatenate(([0.0], np.cumsum(dur + gap)[:-1])) if len(pc) else dur
        raw_end = float((t0 + dur + gap)[-1]) if len(pc) else 0.0
        td = self.t1_s + self.t2_s
        delay = 0.5 * td
        n1, n2 = self.filter_samples(dt)
        lin = blocks.linear_index

        def sample():
            t = time_grid(raw_end + td, dt)
            if not len(pc):
                return t, np.repeat(blocks.p0[:1], len(t), axis=0) if len(blocks) else \
                    np.zeros((len(t), len(blocks.axes))), np.zeros(len(t)), np.zeros(len(t), np.int64)
            phase_start = np.maximum.accumulate(pulses.phase_starts(t0))
            raw = raw_samples(pc, pulses, phase_start, t, grid_index(t, phase_start))
            pos = moving_average(moving_average(raw, n1), n2)
            speed = path_speed(pos, lin, dt)
            row = pc.block.take(grid_index(t - delay, t0))
            return t, pos, speed, row

        b_start, b_end = block_times(pc.block, t0 + delay, t0 + dur + gap + delay, len(blocks))
        moving = pc.length > 0
        m_start = float(t0[moving].min()) if moving.any() else 0.0
        m_end = float((t0 + dur)[moving].max() + td) if moving.any() else 0.0
        b_start, b_end = cover_motion(b_start, b_end, m_start, m_end)
        return Trajectory(sample, block_start_s=b_start, block_end_s=b_end,
                          motion_start_s=m_start, motion_end_s=m_end)

    def filter_samples(self, dt: float) -> tuple[int, int]:
        """Widths of the two moving averages in samples."""
        return max(int(round(self.t1_s / dt)), 1), max(int(round(self.t2_s / dt)), 1)


@dataclass
class Pulses:
    """Per piece: start-zone and middle durations, pulse duration, standstill after; per phase (start
    zone, middle, end zone, rest: four per piece) the position at its start and the feed in it."""

    d_s: np.ndarray
    d_m: np.ndarray
    dur: np.ndarray
    gap: np.ndarray
    s_phase: np.ndarray
    f_phase: np.ndarray

    def phase_starts(self, t0: np.ndarray) -> np.ndarray:
        return np.stack([t0, t0 + self.d_s, t0 + self.d_s + self.d_m, t0 + self.dur], axis=1).ravel()


def raw_samples(pc: Pieces, pulses: Pulses, phase_start: np.ndarray, t: np.ndarray, g: np.ndarray) -> np.ndarray:
    """The unfiltered motion (len(t), k) at times t, sample i in phase g[i]: constant feed in each phase."""
    k = pc.p0.shape[1]
    p0_cols = [np.ascontiguousarray(pc.p0[:, c]) for c in range(k)]
    dir_cols = [np.ascontiguousarray(pc.dir[:, c]) if pc.dir[:, c].any() else None for c in range(k)]
    curved = pc.radius > 0
    raw = np.empty((len(t), k), order="F")
    for a in range(0, len(t), CHUNK):  # chunks of samples: temporaries stay in cache
        b = min(a + CHUNK, len(t))
        gc = g[a:b]
        tau = t[a:b] - phase_start.take(gc)
        np.maximum(tau, 0.0, out=tau)
        s = pulses.s_phase.take(gc) + pulses.f_phase.take(gc) * tau
        idx = gc >> 2
        np.minimum(s, pc.length.take(idx), out=s)
        for c in range(k):
            out = raw[a:b, c]
            p0_cols[c].take(idx, out=out)
            if dir_cols[c] is not None:
                out += dir_cols[c].take(idx) * s
        rows_c = np.flatnonzero(curved.take(idx))
        if len(rows_c):  # arcs: the full position including the circular part
            raw[a + rows_c] = pc.position(idx.take(rows_c).astype(np.int64), s.take(rows_c))
    return raw
