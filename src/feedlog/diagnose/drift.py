"""A gradual change during a session (a machine that warms up): a parameter that holds one value until
t0 and then moves to another, either linearly (a *line*: reaching it at t1 and holding it after) or as
an exponential approach (from t0 towards it with time constant tau, the shape thermal growth takes).
A line may run to the recording's end (t1 held there: it had not levelled off when motion ended) or
from its start (t0 held at 0: already under way); an approach may start at 0.

The simulation runs one value per session, so a drift is modelled from the segment residuals of many
values: each segment's weighted residual is interpolated (linearly in the hypothesis' own scale, log or
linear) between the simulated values around the value the drift has during that segment (the mean
over the segment's measured interval), which is what that segment alone would show run at that value.
The values simulated are the grid plus a dense set (`DENSE_STEP` apart) around the step's two values,
so the interpolation error stays far below a segment's timing noise (a duration that
goes as 1/value: 0.008 % of it midway between two values 2.5 % apart).

Fitting a drift: every pair of candidate times (a line: t0 <= t1 among the segments' ends, at most
`MAX_TIMES` of them, or one of them held at the start or end; an approach: t0 among them and tau among
`TAUS` log-spaced time constants in `TAU_RANGE` of the motion time) gets its two values by Gauss-Newton
on all pairs at once; the best pairs and their values are then refined together (Nelder-Mead on the
two values and the free times; tau in log). A step is the line with t1 = t0, and a line is close to
an approach with a long time constant, so one shape can only be preferred to another on data they
were not fitted on (`changes._gradual`).
"""

from __future__ import annotations

from dataclasses import dataclass
import numpy as np
from scipy.optimize import minimize

DENSE_STEP = 0.025     # the dense values around a step's two values: 2.5 % apart (log scale; linear: 1/640 of the range)
PAD = 0.35             # ... and beyond them by this share of their span each side
MAX_DENSE = 40         # at most this many dense values per range (the lattice coarsens)
MAX_TIMES = 24         # candidate drift starts and ends per recording (the segments' ends, thinned)
SUBSAMPLES = 9         # points per segment at which the drift's value is averaged
GN_ITER = 10
REFINE_FROM = 3      # Nelder-Mead refines the best this many pairs (one where a time is held: three numbers)
TAU_RANGE = (0.02, 2.0)  # an approach's time constants tried: these shares of the recording's motion time
TAUS = 12            # ... this many, log-spaced
REACH = float(np.log(20.0))  # an approach is 95 % of the way after this many time constants (3.0)


@dataclass(frozen=True)
class Drift:
    before: float      # the value until t0
    after: float       # the value from t1 on
    t0_s: float        # the drift starts (measured time from motion start)
    t1_s: float        # ... and ends
    loss: float        # weighted squared residuals over the segments fitted on
    shape: str = "line"  # "line": linear from t0 to t1; "approach": exponential from t0 (t1: 95 % of the way)
    tau_s: float | None = None  # an approach's time constant


class Interpolated:
    """The weighted segment residuals of one recording for any value of its hypothesis, per segment,
    interpolated between simulated ones. `residual(v)` (signed weighted residuals, inf where the value
    does not simulate) gives the simulations; `scale` is the hypothesis' ("log" or "linear")."""

    def __init__(self, residual, scale: str, lower: float, upper: float) -> None:
        self.residual, self.log = residual, scale == "log"
        self.lower, self.upper = float(lower), float(upper)
        self._x: list[float] = []
        self._e: list[np.ndarray] = []

    def to_x(self, v):
        return np.log(v) if self.log else np.asarray(v, float)

    def from_x(self, x):
        return np.exp(x) if self.log else np.asarray(x, float)

    def add(self, values) -> None:
        for v in values:
            v = float(np.clip(v, self.lower, self.upper))
            x = float(self.to_x(v))
            if not any(abs(x - y) < 1e-9 for y in self._x):
                e = self.residual(v)
                if np.isfinite(e).all():
                    self._x.append(x)
                    self._e.append(e)

    def densify(self, lo: float, hi: float) -> None:
        """Simulated values from lo to hi, padded by PAD of their span each side, on a fixed lattice
        (DENSE_STEP apart in the scale, doubled until at most MAX_DENSE fit), so a second call reuses
        the first one's simulations (lo and hi within the hypothesis' bounds)."""
        lo, hi = (float(np.clip(v, self.lower, self.upper)) for v in (lo, hi))
        a, b = float(self.to_x(min(lo, hi))), float(self.to_x(max(lo, hi)))
        step = DENSE_STEP if self.log else DENSE_STEP * (self.upper - self.lower) / 16.0
        a, b = a - PAD * (b - a) - step, b + PAD * (b - a) + step
        while (b - a) / step > MAX_DENSE:
            step *= 2.0
        self.add(self.from_x(step * np.arange(np.floor(a / step), np.ceil(b / step) + 1)))

    def at_edge(self, v: float) -> bool:
        """Whether `v` is at the end of the values simulated (a fit held there wants more of them)."""
        x = float(self.to_x(v))
        return bool(self._x) and (x <= min(self._x) + 1e-9 or x >= max(self._x) - 1e-9)

    def table(self) -> tuple[np.ndarray, np.ndarray]:
        order = np.argsort(self._x)
        return np.asarray(self._x)[order], np.vstack(self._e)[order]

    def at(self, v: np.ndarray, X: np.ndarray, E: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(residuals, their slopes by value) at per-segment values `v` (..., n), from the table (X, E)."""
        n = E.shape[1]
        v = np.clip(v, self.from_x(X[0]), self.from_x(X[-1]))
        x = self.to_x(v)
        hi = np.clip(np.searchsorted(X, x), 1, len(X) - 1)
        lo = hi - 1
        cols = np.broadcast_to(np.arange(n), x.shape)
        span = X[hi] - X[lo]
        slope = (E[hi, cols] - E[lo, cols]) / span
        return E[lo, cols] + slope * (x - X[lo]), slope / v if self.log else slope


def ramp_share(start_s: np.ndarray, end_s: np.ndarray, t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
    """The drift's progress (0 before t0, 1 after t1, linear between) averaged over each segment
    [start_s, end_s): (pairs, segments) for t0, t1 of shape (pairs,)."""
    t, t0, t1 = _instants(start_s, end_s, t0, t1)
    span = t1 - t0
    frac = np.where(span > 0, (t - t0) / np.where(span > 0, span, 1.0), (t >= t0).astype(float))
    return np.clip(frac, 0.0, 1.0).mean(axis=2)


def approach_share(start_s: np.ndarray, end_s: np.ndarray, t0: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """An exponential approach's progress (0 before t0, then 1 - exp(-(t - t0) / tau)) averaged over
    each segment: (pairs, segments) for t0, tau of shape (pairs,)."""
    t, t0, tau = _instants(start_s, end_s, t0, tau)
    return (1.0 - np.exp(-np.maximum(t - t0, 0.0) / tau)).mean(axis=2)


def _instants(start_s, end_s, p, q):
    """The SUBSAMPLES instants of each segment (1, n, S) and p, q shaped (pairs, 1, 1)."""
    u = (np.arange(SUBSAMPLES) + 0.5) / SUBSAMPLES
    t = start_s[None, :, None] + (end_s - start_s)[None, :, None] * u
    return t, np.asarray(p, float)[:, None, None], np.asarray(q, float)[:, None, None]


class _Shape:
    """One way a drift's two times are chosen: `kind` "line" (t0, t1) or "approach" (t0, tau), with
    `fixed` "t0" (the drift was under way when motion started: t0 = 0) or "t1" (a line had not ended
    when motion ended: t1 = the end). Gives the candidate (p, q) pairs, the progress
    per segment, the refined numbers (Nelder-Mead's vector after the two values) and the Drift."""

    def __init__(self, kind: str, fixed: str | None, start_s: np.ndarray, end_s: np.ndarray) -> None:
        if kind not in ("line", "approach") or fixed not in (None, "t0", "t1") or (kind, fixed) == ("approach", "t1"):
            raise ValueError(f"no drift shape {kind!r} with {fixed!r} fixed")
        self.kind, self.fixed, self.start_s, self.end_s = kind, fixed, start_s, end_s
        self.end = float(end_s[-1])
        self.tau_lo, self.tau_hi = TAU_RANGE[0] * self.end, TAU_RANGE[1] * self.end

    def pairs(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.kind == "approach":
            taus = np.geomspace(self.tau_lo, self.tau_hi, TAUS)
            starts = times[:1] if self.fixed == "t0" else times[:-1]
            return np.repeat(starts, len(taus)), np.tile(taus, len(starts))
        if self.fixed == "t1":
            return times, np.full(len(times), self.end)
        if self.fixed == "t0":
            return np.zeros(len(times)), times
        i0, i1 = np.triu_indices(len(times))
        return times[i0], times[i1]

    def share(self, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        if self.kind == "approach":
            return approach_share(self.start_s, self.end_s, p, q)
        return ramp_share(self.start_s, self.end_s, p, q)

    def to_vector(self, p: float, q: float) -> list[float]:
        if self.kind == "approach":
            return [float(np.log(q))] if self.fixed == "t0" else [p, float(np.log(q))]
        return {"t0": [q], "t1": [p]}.get(self.fixed, [p, q])

    def from_vector(self, x: np.ndarray) -> tuple[float, float]:
        """(p, q) from Nelder-Mead's times, within the recording (and the time constants tried)."""
        x = [float(v) for v in x]
        if self.kind == "approach":
            t0 = 0.0 if self.fixed == "t0" else float(np.clip(x[0], 0.0, self.end))
            return t0, float(np.clip(np.exp(x[-1]), self.tau_lo, self.tau_hi))
        if self.fixed == "t0":
            return 0.0, float(np.clip(x[0], 0.0, self.end))
        if self.fixed == "t1":
            return float(np.clip(x[0], 0.0, self.end)), self.end
        p, q = sorted(float(np.clip(v, 0.0, self.end)) for v in x)
        return p, q

    def drift(self, a: float, b: float, p: float, q: float, loss: float) -> Drift:
        if self.kind == "approach":
            return Drift(before=a, after=b, t0_s=p, t1_s=p + REACH * q, loss=loss, shape="approach", tau_s=q)
        return Drift(before=a, after=b, t0_s=p, t1_s=q, loss=loss)


def fit_drift(model: Interpolated, start_s: np.ndarray, end_s: np.ndarray, use: np.ndarray,
              first: tuple[float, float], *, kind: str = "line", fixed: str | None = None) -> Drift | None:
    """The drift of shape `kind` ("line" or "approach"; a line's t0 or t1 may be `fixed` at the
    recording's start or end) with the least loss over the segments `use`, starting from the values
    `first` (a step's before and after)."""
    X, E = model.table()
    if len(X) < 2 or use.sum() < 4:
        return None
    shape = _Shape(kind, fixed, start_s, end_s)
    times = np.unique(np.concatenate([[0.0], end_s]))
    if len(times) > MAX_TIMES:
        times = times[np.unique(np.linspace(0, len(times) - 1, MAX_TIMES).round().astype(int))]
    p, q = shape.pairs(times)
    share = shape.share(p, q)                                                            # (P, n)
    w = use.astype(float)
    vmin, vmax = float(model.from_x(X[0])), float(model.from_x(X[-1]))
    a0, b0 = float(first[0]), float(first[1])
    starts = [(a0, b0), (a0 + 0.25 * (a0 - b0), b0 - 0.5 * (a0 - b0))]   # the step's values, and beyond them
    if kind == "approach":                                               # an approach's end lies further out
        starts.append((a0, b0 - 1.5 * (a0 - b0)))
    found = []
    for start in starts:
        a, b = _gauss_newton(model, X, E, share, w, np.full(len(p), start[0]), np.full(len(p), start[1]))
        e, _ = model.at(a[:, None] + (b - a)[:, None] * share, X, E)
        found.append((a, b, (e * e * w).sum(1)))
    a = np.concatenate([f[0] for f in found])
    b = np.concatenate([f[1] for f in found])
    loss = np.concatenate([f[2] for f in found])
    p, q = np.tile(p, len(found)), np.tile(q, len(found))

    def objective(x: np.ndarray) -> float:
        pp, qq = shape.from_vector(x[2:])
        sh = shape.share(np.array([pp]), np.array([qq]))[0]
        ee, _ = model.at(x[0] + (x[1] - x[0]) * sh, X, E)
        return float((ee * ee * w).sum())

    best_x, best_loss = None, np.inf
    for i in np.argsort(loss)[:1 if fixed else REFINE_FROM]:   # Nelder-Mead from the best few pairs
        x0 = np.array([a[i], b[i], *shape.to_vector(p[i], q[i])])
        res = minimize(objective, x0, method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-12, "maxiter": 600})
        x, f = (res.x, float(res.fun)) if res.fun < loss[i] else (x0, float(loss[i]))
        if f < best_loss:
            best_x, best_loss = x, f
    pp, qq = shape.from_vector(best_x[2:])
    return shape.drift(float(np.clip(best_x[0], vmin, vmax)), float(np.clip(best_x[1], vmin, vmax)), pp, qq,
                       best_loss)


def _gauss_newton(model: Interpolated, X: np.ndarray, E: np.ndarray, share: np.ndarray, w: np.ndarray,
                  a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The two values (a before, b after) of every pair of drift times (`share`: (pairs, segments)) by
    damped Gauss-Newton on all pairs at once, within the table's values."""
    vmin, vmax = float(model.from_x(X[0])), float(model.from_x(X[-1]))
    for _ in range(GN_ITER):
        e, s = model.at(a[:, None] + (b - a)[:, None] * share, X, E)
        ja, jb = s * (1 - share) * w, s * share * w
        g = np.stack([(ja * e).sum(1), (jb * e).sum(1)], 1)
        h = np.stack([np.stack([(ja * ja).sum(1), (ja * jb).sum(1)], 1),
                      np.stack([(ja * jb).sum(1), (jb * jb).sum(1)], 1)], 1)
        h = h + 1e-12 * np.eye(2) + 1e-6 * np.trace(h, axis1=1, axis2=2)[:, None, None] * np.eye(2)
        d = np.linalg.solve(h, -g[..., None])[..., 0]
        a, b = np.clip(a + d[:, 0], vmin, vmax), np.clip(b + d[:, 1], vmin, vmax)
    return a, b


def progress(drift: Drift, start_s: np.ndarray, end_s: np.ndarray) -> np.ndarray:
    """The drift's progress (0 at `before`, 1 at `after`) averaged over each segment."""
    if drift.shape == "approach":
        return approach_share(start_s, end_s, np.array([drift.t0_s]), np.array([drift.tau_s]))[0]
    return ramp_share(start_s, end_s, np.array([drift.t0_s]), np.array([drift.t1_s]))[0]


def drift_residuals(model: Interpolated, drift: Drift, start_s: np.ndarray, end_s: np.ndarray) -> np.ndarray:
    """The weighted segment residuals `drift` leaves."""
    X, E = model.table()
    e, _ = model.at(drift.before + (drift.after - drift.before) * progress(drift, start_s, end_s), X, E)
    return e


def inside(drift: Drift, start_s: np.ndarray, end_s: np.ndarray) -> int:
    """Segments that lie wholly within the drift (an approach: up to 95 % of the way): how many a
    gradual change spans."""
    return int(((start_s >= drift.t0_s) & (end_s <= drift.t1_s)).sum())
