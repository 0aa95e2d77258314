"""Time-optimal speed planning over a chain of pieces, and sampling the result.

`plan_speeds` finds the junction speeds with the classic backward/forward passes, written as
cumulative minima so that 100k pieces take milliseconds: in squared speeds w = v^2 the backward
recursion w[j] = min(C[j], w[j+1] + 2 a[j+1] L[j+1]) unrolls to
w[j] = min_{k>=j}(C[k] + D[k]) - D[j] with D the cumulative sum of 2 a L (a reversed running
minimum), and the forward pass likewise. Each piece then gets a trapezoidal (acceleration-limited)
profile between its junction speeds. `sample_plan` evaluates positions and speed on a time grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.sim.path import Pieces


@dataclass
class Plan:
    """Per-piece timing of a planned trajectory (seconds, path units)."""

    t0: np.ndarray      # start time of each piece
    v0: np.ndarray      # speed entering
    v1: np.ndarray      # speed leaving
    vp: np.ndarray      # peak (cruise) speed
    acc: np.ndarray     # acceleration used in the ramps
    t_acc: np.ndarray
    t_cru: np.ndarray
    t_dec: np.ndarray
    hold: np.ndarray    # standstill after the piece
    overlap_s: np.ndarray  # time the next piece starts before this one ends (parabolic blends)

    @property
    def duration(self) -> np.ndarray:
        """Motion time of each piece (without the hold)."""
        return self.t_acc + self.t_cru + self.t_dec

    @property
    def t_end(self) -> np.ndarray:
        return self.t0 + self.duration

    @property
    def total_s(self) -> float:
        if not len(self.t0):
            return 0.0
        return float(np.max(self.t_end + self.hold))


def junction_caps(pieces: Pieces, *, lookahead: int | None = None) -> np.ndarray:
    """Squared speed caps at the end of each piece: corner law, both pieces' limits, stopping distance."""
    m = len(pieces)
    vmax = pieces.v_max
    nxt = np.append(vmax[1:], 0.0)
    cap = np.minimum(np.minimum(pieces.v_end, vmax), nxt)
    cap = np.where(pieces.overlap, 0.0, cap)
    if m:
        cap[-1] = 0.0
    w = cap ** 2
    if lookahead is not None and m:
        d = 2.0 * pieces.a_max * pieces.length
        dcum = np.cumsum(d)
        ahead = dcum[np.minimum(np.arange(m) + lookahead, m - 1)] - dcum
        w = np.minimum(w, ahead)
    return w


def plan_speeds(pieces: Pieces, *, lookahead: int | None = None) -> Plan:
    """Junction speeds by backward/forward passes, then a trapezoid per piece."""
    m = len(pieces)
    length = pieces.length
    acc = pieces.a_max
    d = 2.0 * acc * length
    dcum = np.cumsum(d)
    cap = junction_caps(pieces, lookahead=lookahead)
    # backward: w[j] = min_{k>=j}(C[k] + D[k]) - D[j]
    w = np.minimum.accumulate((cap + dcum)[::-1])[::-1] - dcum
    # forward from rest: u[j] = D[j] + min(0, min_{k<=j}(w[k] - D[k]))
    u = dcum + np.minimum(0.0, np.minimum.accumulate(w - dcum))
    u = np.clip(np.minimum(u, w), 0.0, None)
    v1 = np.sqrt(u)
    v0 = np.concatenate(([0.0], v1[:-1])) if m else v1
    vmax = np.maximum(pieces.v_max, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        vp = np.minimum(vmax, np.sqrt(np.maximum((d + v0 ** 2 + v1 ** 2) / 2.0, 0.0)))
        vp = np.maximum(vp, np.maximum(v0, v1))
        safe_a = np.where(acc > 0, acc, np.inf)
        t_acc = (vp - v0) / safe_a
        t_dec = (vp - v1) / safe_a
        s_ramp = (2 * vp ** 2 - v0 ** 2 - v1 ** 2) / (2 * safe_a)
        s_cru = np.maximum(length - s_ramp, 0.0)
        t_cru = np.where(vp > 0, s_cru / np.where(vp > 0, vp, 1.0), 0.0)
    moving = length > 0
    t_acc = np.where(moving, t_acc, 0.0)
    t_dec = np.where(moving, t_dec, 0.0)
    t_cru = np.where(moving, t_cru, 0.0)
    # parabolic blends: the next piece starts while this one decelerates from the blend speed
    blend_v = np.minimum(pieces.v_end, vp)
    overlap_s = np.where(pieces.overlap & moving, np.minimum(blend_v / np.where(acc > 0, acc, np.inf), t_dec), 0.0)
    step = t_acc + t_cru + t_dec + pieces.hold_s - overlap_s
    t0 = np.concatenate(([0.0], np.cumsum(step)[:-1])) if m else step
    return Plan(t0=t0, v0=v0, v1=v1, vp=vp, acc=acc, t_acc=t_acc, t_cru=t_cru, t_dec=t_dec,
                hold=pieces.hold_s.copy(), overlap_s=overlap_s)


def _progress(v0, vp, a, ta, tc, td, length, tau) -> tuple[np.ndarray, np.ndarray]:
    """Distance travelled and speed at local time tau of trapezoids given per sample."""
    t_end = ta + tc + td
    tau = np.minimum(np.maximum(tau, 0.0), t_end)
    t1 = np.minimum(tau, ta)
    t2 = np.minimum(np.maximum(tau - ta, 0.0), tc)
    t3 = np.maximum(tau - ta - tc, 0.0)
    s = v0 * t1 + 0.5 * a * t1 * t1 + vp * (t2 + t3) - 0.5 * a * t3 * t3
    v = np.where(tau > ta + tc, vp - a * t3, np.where(tau > ta, vp, v0 + a * t1))
    return np.minimum(s, length), np.maximum(v, 0.0)


def grid_counts(start_s: np.ndarray, n: int, dt_s: float) -> np.ndarray:
    """How many grid samples k * dt fall in [start[i], start[i + 1]) (the last piece takes the rest)."""
    first = np.clip(np.ceil(start_s / dt_s - 1e-9).astype(np.int64), 0, n)
    first = np.maximum.accumulate(first)
    return np.diff(first, append=n)


class _Repeat:
    """Per-piece arrays expanded to per-sample arrays with np.repeat (contiguous runs, no gathers)."""

    def __init__(self, counts: np.ndarray) -> None:
        self.counts = counts

    def __call__(self, values: np.ndarray) -> np.ndarray:
        return np.repeat(values, self.counts, axis=0)


def _positions(pieces: Pieces, rep: _Repeat, sigma: np.ndarray) -> np.ndarray:
    pos = rep(pieces.p0) + rep(pieces.dir) * sigma[:, None]
    curved = pieces.radius > 0
    if curved.any():
        mask = rep(curved)
        idx_c = np.flatnonzero(curved)
        sub_counts = rep.counts[idx_c]
        omega = np.repeat(pieces.omega[idx_c], sub_counts)
        radius = np.repeat(pieces.radius[idx_c], sub_counts)
        e1 = np.repeat(pieces.e1[idx_c], sub_counts, axis=0)
        e2 = np.repeat(pieces.e2[idx_c], sub_counts, axis=0)
        ang = omega * sigma[mask]
        pos[mask] += radius[:, None] * ((np.cos(ang) - 1.0)[:, None] * e1 + np.sin(ang)[:, None] * e2)
    return pos


def sample_plan(plan: Plan, pieces: Pieces, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions (len(t), k), path speed and piece index at the regular grid times t (seconds)."""
    m = len(pieces)
    if not m:
        return np.zeros((len(t), pieces.p0.shape[1])), np.zeros(len(t)), np.zeros(len(t), np.int64)
    dt = float(t[1] - t[0]) if len(t) > 1 else 1.0
    counts = grid_counts(plan.t0, len(t), dt)
    rep = _Repeat(counts)
    idx = rep(np.arange(m))
    tau = t - rep(plan.t0)
    s, v = _progress(rep(plan.v0), rep(plan.vp), rep(plan.acc), rep(plan.t_acc), rep(plan.t_cru),
                     rep(plan.t_dec), rep(pieces.length), tau)
    pos = _positions(pieces, rep, s)
    if plan.overlap_s.any():  # the previous piece may still be finishing its parabolic blend
        prev = np.concatenate(([0], np.arange(m - 1)))
        has_prev = np.concatenate(([False], plan.overlap_s[:-1] > 0))
        tau_prev = t - rep(plan.t0[prev])
        active = rep(has_prev) & (tau_prev < rep(plan.duration[prev]))
        if active.any():
            pp = pieces.take(prev)
            sub = _Repeat(np.bincount(idx[active], minlength=m))
            sp, vprev = _progress(sub(plan.v0[prev]), sub(plan.vp[prev]), sub(plan.acc[prev]), sub(plan.t_acc[prev]),
                                  sub(plan.t_cru[prev]), sub(plan.t_dec[prev]), sub(pp.length), tau_prev[active])
            pos[active] += _positions(pp, sub, sp) - _positions(pp, sub, sub(pp.length))
            v[active] += vprev
    return pos, v, idx
