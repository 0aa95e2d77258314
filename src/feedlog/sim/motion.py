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
    """Squared speed caps at the end of each piece: corner law, both pieces' limits, stopping distance
    within the next `lookahead` queue entries (pieces with a clamp length; a consumed line rides with
    its arc)."""
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
        # the window counts the controller's queue entries: a consumed line (clamp_len 0) is part of its arc
        entry = np.cumsum(pieces.clamp_len > 0)
        last = np.searchsorted(entry, entry + lookahead, side="right") - 1
        ahead = dcum[np.clip(last, 0, m - 1)] - dcum
        w = np.minimum(w, ahead)
    return w


def reachable_speeds_sq(cap_sq: np.ndarray, acc: np.ndarray, length: np.ndarray) -> np.ndarray:
    """Squared end speeds of a chain of pieces that starts from rest: each as high as its cap allows
    while every later cap can still be met (backward pass) and it can be reached (forward pass)."""
    dcum = np.cumsum(2.0 * acc * length)
    # backward: w[j] = min_{k>=j}(C[k] + D[k]) - D[j]
    w = np.minimum.accumulate((cap_sq + dcum)[::-1])[::-1] - dcum
    # forward from rest: u[j] = D[j] + min(0, min_{k<=j}(w[k] - D[k]))
    u = dcum + np.minimum(0.0, np.minimum.accumulate(w - dcum))
    return np.clip(np.minimum(u, w), 0.0, None)


def plan_speeds(pieces: Pieces, *, lookahead: int | None = None) -> Plan:
    """Junction speeds by backward/forward passes, then a trapezoid per piece."""
    v1 = np.sqrt(reachable_speeds_sq(junction_caps(pieces, lookahead=lookahead), pieces.a_max, pieces.length))
    v0 = np.concatenate(([0.0], v1[:-1])) if len(pieces) else v1
    return plan_from_speeds(pieces, v0, v1)


def plan_from_speeds(pieces: Pieces, v0: np.ndarray, v1: np.ndarray, t_start: float = 0.0) -> Plan:
    """A trapezoid per piece between its junction speeds v0 -> v1, the pieces one after the other from
    `t_start` (a windowed simulation continues the running sum of the times of the pieces before)."""
    length = pieces.length
    acc = pieces.a_max
    d = 2.0 * acc * length
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
    t0 = np.cumsum(np.concatenate(([t_start], step)))[:-1]
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


def _phases(plan: Plan, pieces: Pieces):
    """Each piece as four time phases (accelerate, cruise, decelerate, rest), each a quadratic in the
    time since its start: s = S + tau (V + H tau), speed = V + 2 H tau (+ R while at rest). The phase
    start values come from `_progress` itself, so the result is the trapezoid of `_progress`."""
    m = len(pieces)
    t0, ta, tc, td = plan.t0, plan.t_acc, plan.t_cru, plan.t_dec
    args = (plan.v0, plan.vp, plan.acc, ta, tc, td, pieces.length)
    s_c, _ = _progress(*args, ta)
    s_d, _ = _progress(*args, ta + tc)
    s_end, v_end = _progress(*args, ta + tc + td)
    zero = np.zeros(m)
    half_a = np.where(pieces.length > 0, 0.5 * plan.acc, 0.0)
    start = np.stack([t0, t0 + ta, t0 + ta + tc, t0 + ta + tc + td], axis=1)
    # the next piece takes over at its start (parabolic blends overlap: see sample_plan)
    start = np.minimum(start, np.append(t0[1:], np.inf)[:, None])
    S = np.stack([zero, s_c, s_d, s_end], axis=1)
    V = np.stack([plan.v0, plan.vp, plan.vp, zero], axis=1)
    H = np.stack([half_a, zero, -half_a, zero], axis=1)
    R = np.stack([zero, zero, zero, v_end], axis=1)   # at rest: the speed _progress reports at the end
    # rounding may carry the deceleration phase a hair past the piece's end, which _progress clamps
    overshoot = bool((s_d + td * (plan.vp - half_a * td) > pieces.length).any())
    return start.ravel(), S.ravel(), V.ravel(), H.ravel(), R.ravel(), overshoot


class _Blend:
    """Parabolic blends: while piece i runs, piece i - 1 may still be finishing its deceleration
    (the overlap is at most its deceleration time). Per piece i, its predecessor's deceleration:
    s = s_dec + tau (v_p - a tau / 2), speed v_p - a tau, tau since the deceleration began."""

    def __init__(self, plan: Plan, pieces: Pieces) -> None:
        m = len(pieces)
        has = np.zeros(m, bool)
        has[1:] = plan.overlap_s[:-1] > 0
        self.prev = prev = np.maximum(np.arange(m) - 1, 0)
        self.until = np.where(has, (plan.t0 + plan.duration).take(prev), -np.inf)
        s_dec, _ = _progress(plan.v0, plan.vp, plan.acc, plan.t_acc, plan.t_cru, plan.t_dec, pieces.length,
                             plan.t_acc + plan.t_cru)
        self.t_dec0 = (plan.t0 + plan.t_acc + plan.t_cru).take(prev)
        self.s_dec = s_dec.take(prev)
        self.vp = plan.vp.take(prev)
        self.half_a = np.where(pieces.length > 0, 0.5 * plan.acc, 0.0).take(prev)
        self.length = pieces.length.take(prev)
        self.dir = np.asfortranarray(pieces.dir.take(prev, axis=0))

    def at(self, t: np.ndarray, piece: np.ndarray):
        """(remaining path <= 0, speed, path parameter, active) of the predecessors at times t."""
        active = t < self.until.take(piece)
        if not active.any():
            return None
        tau = t - self.t_dec0.take(piece)
        np.maximum(tau, 0.0, out=tau)
        vp, h, length = self.vp.take(piece), self.half_a.take(piece), self.length.take(piece)
        sp = np.minimum(self.s_dec.take(piece) + tau * (vp - h * tau), length)
        rem = np.where(active, sp - length, 0.0)
        speed = np.where(active, np.maximum(vp - 2.0 * h * tau, 0.0), 0.0)
        return rem, speed, sp, active


class _Arcs:
    """The circular part of arc pieces, radius ((cos(omega s) - 1) e1 + sin(omega s) e2), with the
    arc columns prepared once (only axes that arcs move)."""

    def __init__(self, pieces: Pieces) -> None:
        self.curved = pieces.radius > 0
        self.omega, self.radius = pieces.omega, pieces.radius
        self.cols = [c for c in range(pieces.e1.shape[1]) if pieces.e1[:, c].any() or pieces.e2[:, c].any()]
        self.e1 = {c: np.ascontiguousarray(pieces.e1[:, c]) for c in self.cols}
        self.e2 = {c: np.ascontiguousarray(pieces.e2[:, c]) for c in self.cols}

    def add(self, pos: np.ndarray, piece: np.ndarray, sigma: np.ndarray, rows: np.ndarray, sign: float = 1.0) -> None:
        """Add (sign times) the circular part of pieces `piece[rows]` at `sigma[rows]` to pos[rows]."""
        pc = piece.take(rows)
        ang = self.omega.take(pc) * sigma.take(rows)
        r = sign * self.radius.take(pc)
        cos1, sin = r * (np.cos(ang) - 1.0), r * np.sin(ang)
        for c in self.cols:
            pos[rows, c] += cos1 * self.e1[c].take(pc) + sin * self.e2[c].take(pc)


CHUNK = 1 << 16  # samples evaluated together: the temporaries stay in the CPU cache


def sample_plan(plan: Plan, pieces: Pieces, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions (len(t), k), path speed and piece index at the regular grid times t (seconds).

    Vectorised: the trapezoid phases are found by counting grid points per phase (`grid_counts`),
    one np.repeat gives every sample its phase, and the quadratic of its phase is evaluated in chunks
    of `CHUNK` samples (`evaluate_phases`)."""
    n = len(t)
    if not len(pieces):
        return np.zeros((n, pieces.p0.shape[1]), order="F"), np.zeros(n), np.zeros(n, np.int64)
    dt = float(t[1] - t[0]) if n > 1 else 1.0
    phases = _phases(plan, pieces)
    g = np.repeat(np.arange(len(phases[0]), dtype=np.int32), grid_counts(phases[0], n, dt))
    pos, speed = evaluate_phases(plan, pieces, phases, t, g)
    return pos, speed, g >> 2


def sample_plan_at(plan: Plan, pieces: Pieces, index: np.ndarray, n: int, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Times and positions of the samples `index` (ascending) of the `n`-sample grid k * dt_s: the rows
    `sample_plan` gives there, to the last bit, without evaluating the others (a caller that needs only
    the start and end of the motion, diagnose's motion span, samples those)."""
    index = np.asarray(index, dtype=np.int64)
    t = index.astype(np.float64) * dt_s
    if not len(pieces):
        return t, np.zeros((len(t), pieces.p0.shape[1]), order="F")
    phases = _phases(plan, pieces)
    # sample i is in the phase np.repeat gives it in sample_plan: the first whose cumulative count exceeds i
    ends = np.cumsum(grid_counts(phases[0], n, dt_s))
    g = np.searchsorted(ends, index, side="right").astype(np.int32)
    pos, _ = evaluate_phases(plan, pieces, phases, t, g)
    return t, pos


def evaluate_phases(plan: Plan, pieces: Pieces, phases, t: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (len(t), k) and path speed at times t, sample i in phase g[i] of `phases` (`_phases`):
    np.take of the phase coefficients, positions written column by column into a Fortran-ordered array
    (a DataFrame takes its columns without copying). A windowed simulation passes a window of the grid
    and its pieces with the piece before them first (the predecessor of a parabolic blend)."""
    n = len(t)
    k = pieces.p0.shape[1]
    start, S, V, H, R, _ = phases
    idx = g >> 2                                   # four phases per piece
    blend = _Blend(plan, pieces) if plan.overlap_s.any() else None
    rest_speed = R.any()
    arcs = _Arcs(pieces)
    curved = arcs.curved
    any_curved = curved.any()
    p0 = np.asfortranarray(pieces.p0)
    direction = np.asfortranarray(pieces.dir)
    moves = [bool(direction[:, c].any()) for c in range(k)]
    pos = np.empty((n, k), order="F")
    speed = np.empty(n)
    for a in range(0, n, CHUNK):
        b = min(a + CHUNK, n)
        gc, ic, tc = g[a:b], idx[a:b], t[a:b]
        tau = tc - start.take(gc)
        np.maximum(tau, 0.0, out=tau)
        h, v0 = H.take(gc), V.take(gc)
        s = S.take(gc) + tau * (v0 + h * tau)
        sp = speed[a:b]
        np.multiply(h, 2.0 * tau, out=sp)
        sp += v0
        if rest_speed:
            sp += R.take(gc)
        np.maximum(sp, 0.0, out=sp)
        # rounding may carry a deceleration a hair past the piece's end (a no-op elsewhere, so done
        # everywhere: a window of the grid gives the samples of the whole grid)
        np.minimum(s, pieces.length.take(ic), out=s)
        prev = blend.at(tc, ic) if blend is not None else None
        if prev is not None:
            sp += prev[1]
        for c in range(k):
            out = pos[a:b, c]
            if moves[c]:
                np.multiply(direction[:, c].take(ic), s, out=out)
                out += p0[:, c].take(ic)
                if prev is not None:
                    out += blend.dir[:, c].take(ic) * prev[0]
            else:
                p0[:, c].take(ic, out=out)
        if any_curved:
            chunk = pos[a:b]
            rows = np.flatnonzero(curved.take(ic))
            if len(rows):
                arcs.add(chunk, ic, s, rows)
            if prev is not None:
                pc = blend.prev.take(ic)
                rows = np.flatnonzero(prev[3] & curved.take(pc))
                if len(rows):  # the predecessor is an arc: its circular part at sp minus at its end
                    arcs.add(chunk, pc, prev[2], rows)
                    arcs.add(chunk, pc, pieces.length.take(pc), rows, sign=-1.0)
    return pos, speed
