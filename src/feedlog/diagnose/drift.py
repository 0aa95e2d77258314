"""A gradual change during a session (a machine that warms up): a parameter that holds one value until
t0, drifts linearly to another by t1, and holds that one after it.

The simulation runs one value per session, so a drift is modelled from the segment residuals of many
values: each segment's weighted residual is interpolated (linearly in the hypothesis' own scale, log or
linear) between the simulated values around the value the drift has during that segment (the mean
over the segment's measured interval), which is what that segment alone would show run at that value.
The values simulated are the grid plus a dense set (`DENSE_STEP` apart) around the step's two values,
so the interpolation error stays far below a segment's timing noise (a duration that
goes as 1/value: 0.008 % of it midway between two values 2.5 % apart).

Fitting a drift: every pair (t0 <= t1) of candidate times (the segments' ends, at most `MAX_TIMES` of
them) gets its two values by Gauss-Newton on all pairs at once; the best pair and its values are then
refined together (Nelder-Mead on t0, t1 and the two values). A step is the drift with t1 = t0, so a
drift can only be preferred to a step on data the two were not fitted on (`changes._judge`).
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
REFINE_FROM = 3      # Nelder-Mead refines the best this many pairs


@dataclass(frozen=True)
class Drift:
    before: float      # the value until t0
    after: float       # the value from t1 on
    t0_s: float        # the drift starts (measured time from motion start)
    t1_s: float        # ... and ends
    loss: float        # weighted squared residuals over the segments fitted on


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
        the first one's simulations."""
        a, b = float(self.to_x(min(lo, hi))), float(self.to_x(max(lo, hi)))
        step = DENSE_STEP if self.log else DENSE_STEP * (self.upper - self.lower) / 16.0
        a, b = a - PAD * (b - a) - step, b + PAD * (b - a) + step
        while (b - a) / step > MAX_DENSE:
            step *= 2.0
        self.add(self.from_x(step * np.arange(np.floor(a / step), np.ceil(b / step) + 1)))

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
    u = (np.arange(SUBSAMPLES) + 0.5) / SUBSAMPLES
    t = start_s[None, :, None] + (end_s - start_s)[None, :, None] * u                  # (1, n, S)
    t0, t1 = np.asarray(t0, float)[:, None, None], np.asarray(t1, float)[:, None, None]
    span = t1 - t0
    frac = np.where(span > 0, (t - t0) / np.where(span > 0, span, 1.0), (t >= t0).astype(float))
    return np.clip(frac, 0.0, 1.0).mean(axis=2)


def fit_drift(model: Interpolated, start_s: np.ndarray, end_s: np.ndarray, use: np.ndarray,
              first: tuple[float, float]) -> Drift | None:
    """The drift with the least loss over the segments `use`, starting from the values `first` (a
    step's before and after)."""
    X, E = model.table()
    if len(X) < 2 or use.sum() < 4:
        return None
    times = np.unique(np.concatenate([[0.0], end_s]))
    if len(times) > MAX_TIMES:
        times = times[np.unique(np.linspace(0, len(times) - 1, MAX_TIMES).round().astype(int))]
    i0, i1 = np.triu_indices(len(times))
    t0, t1 = times[i0], times[i1]
    share = ramp_share(start_s, end_s, t0, t1)                                           # (P, n)
    w = use.astype(float)
    vmin, vmax = float(model.from_x(X[0])), float(model.from_x(X[-1]))
    a0, b0 = float(first[0]), float(first[1])
    found = []
    for start in ((a0, b0), (a0 + 0.25 * (a0 - b0), b0 - 0.5 * (a0 - b0))):   # the step's values, and beyond them
        a, b = _gauss_newton(model, X, E, share, w, np.full(len(t0), start[0]), np.full(len(t0), start[1]))
        e, _ = model.at(a[:, None] + (b - a)[:, None] * share, X, E)
        found.append((a, b, (e * e * w).sum(1)))
    a = np.concatenate([f[0] for f in found])
    b = np.concatenate([f[1] for f in found])
    loss = np.concatenate([f[2] for f in found])
    t0, t1 = np.tile(t0, len(found)), np.tile(t1, len(found))
    end = float(end_s[-1])

    def objective(p: np.ndarray) -> float:
        p0, p1 = float(np.clip(p[2], 0.0, end)), float(np.clip(p[3], 0.0, end))
        lo, hi = min(p0, p1), max(p0, p1)
        sh = ramp_share(start_s, end_s, np.array([lo]), np.array([hi]))[0]
        ee, _ = model.at(p[0] + (p[1] - p[0]) * sh, X, E)
        return float((ee * ee * w).sum())

    best_p, best_loss = None, np.inf
    for i in np.argsort(loss)[:REFINE_FROM]:   # Nelder-Mead from the best few pairs
        p0 = np.array([a[i], b[i], t0[i], t1[i]])
        res = minimize(objective, p0, method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-12, "maxiter": 600})
        p, f = (res.x, float(res.fun)) if res.fun < loss[i] else (p0, float(loss[i]))
        if f < best_loss:
            best_p, best_loss = p, f
    p2, p3 = sorted((float(np.clip(best_p[2], 0.0, end)), float(np.clip(best_p[3], 0.0, end))))
    return Drift(before=float(np.clip(best_p[0], vmin, vmax)), after=float(np.clip(best_p[1], vmin, vmax)),
                 t0_s=p2, t1_s=p3, loss=best_loss)


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


def drift_residuals(model: Interpolated, drift: Drift, start_s: np.ndarray, end_s: np.ndarray) -> np.ndarray:
    """The weighted segment residuals `drift` leaves."""
    X, E = model.table()
    sh = ramp_share(start_s, end_s, np.array([drift.t0_s]), np.array([drift.t1_s]))[0]
    e, _ = model.at(drift.before + (drift.after - drift.before) * sh, X, E)
    return e


def inside(drift: Drift, start_s: np.ndarray, end_s: np.ndarray) -> int:
    """Segments that lie wholly within the drift: how many a gradual change spans."""
    return int(((start_s >= drift.t0_s) & (end_s <= drift.t1_s)).sum())
