"""Joint refits: every chosen parameter fitted at once, and one cause split into two.

Greedy selection fits one parameter at a time given the others. With three or four causes in the
data the first ones are fitted while the later ones are still missing and carry part of their time
(a feed override fitted to 0.80 where the dial is at 0.85 and two axes accelerate slower than the
profile says), and one parameter of a broader form can take the place of two narrower ones (a path
acceleration cap for an X and a Z acceleration limit). Here:

- `joint_fit` fits all the chosen continuous parameters together: a bounded least-squares problem on
  the weighted residual vector of the level (`scipy.optimize.least_squares`, trust-region reflective),
  each parameter on its own search scale (log for log-scaled ones), with a finite-difference Jacobian
  whose step (`STEP` of the scale) is wide enough for a simulation that moves in whole servo cycles.
  Integer and choice parameters stay where they are (coordinate descent in `select` moves them).
- `split` tries, for each chosen cause, the pairs of candidates (the cause itself among them) that
  could stand in for it: each pair is fitted jointly with every other cause, and replaces the cause only
  when it lowers the in-sample loss by `SPLIT_GAIN` of what is left above the noise floor and each of
  the two then passes every held-out rule given the rest (`select.judge`). A pair that keeps the cause
  is a forward step with the cause refitted: its value fitted while the other was missing (an X
  velocity limit of 27.5 standing in for 31 next to a feed override of 0.89) no longer blocks it.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from itertools import combinations
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from feedlog.diagnose.fit import Scorer, _grid
from feedlog.diagnose.hypothesis import Hypothesis

STEP = 0.01          # finite-difference step, as a share of the parameter's scale (log: 1 %)
MAX_NFEV = 40        # least-squares iterations at most
QUICK_NFEV = 6       # ... when a pair is only being compared with the others
SPLIT_KEEP = 5       # candidates (least loss given the other causes first) whose pairs may replace one cause
SCREEN_POINTS = 9    # coarse grid points per candidate
SPLIT_GAIN = 0.3     # a pair must remove this share of the in-sample loss left above the floor


def _continuous(hyps: Sequence[Hypothesis]) -> list[Hypothesis]:
    return [h for h in hyps if h.scale in ("log", "linear")]


def _to_x(hyp: Hypothesis, v: float) -> float:
    return float(np.log(v)) if hyp.scale == "log" else float(v) / (hyp.upper - hyp.lower)


def _from_x(hyp: Hypothesis, x: float) -> float:
    return float(np.exp(x)) if hyp.scale == "log" else float(x) * (hyp.upper - hyp.lower)


def residual_vector(scorer: Scorer, values: dict[str, Any], units: Sequence[int]) -> np.ndarray:
    """The level's weighted residuals over `units`, one vector (its squared sum is the units' loss);
    a profile the simulation refuses gives a large constant vector."""
    res = scorer.residuals(values)
    parts = []
    for j in units:
        u = scorer.units[j]
        r = res[u.case]
        if r is None:
            return np.full(sum(scorer.units[k].hi - scorer.units[k].lo for k in units), 1e3)
        w = np.sqrt(scorer.weights[u.case][u.lo:u.hi])
        seg = r[u.lo:u.hi]
        parts.append((seg * (w[:, None] if seg.ndim == 2 else w)).ravel())
    return np.concatenate(parts) if parts else np.zeros(0)


def joint_fit(scorer: Scorer, model: dict[str, Any], hyps: Sequence[Hypothesis],
              units: Sequence[int] | None = None, *, max_nfev: int = MAX_NFEV) -> dict[str, Any]:
    """`model` with every continuous parameter of `hyps` fitted together on `units` (default: all);
    the result is kept only when its loss is lower than the model's own."""
    units = list(range(len(scorer.units))) if units is None else list(units)
    free = [h for h in _continuous(hyps) if isinstance(model.get(h.key), (int, float))]
    if not free or not units:
        return dict(model)
    fixed = {k: v for k, v in model.items() if not any(k in h.keys for h in free)}

    def values(x: np.ndarray) -> dict[str, Any]:
        out = dict(fixed)
        for h, xi in zip(free, x):
            out.update(h.values(min(max(_from_x(h, xi), h.lower), h.upper)))
        return out

    def fun(x: np.ndarray) -> np.ndarray:
        return residual_vector(scorer, values(x), units)

    def jac(x: np.ndarray) -> np.ndarray:
        return _jacobian(fun, x, hi)

    lo = np.array([_to_x(h, h.lower) for h in free])
    hi = np.array([_to_x(h, h.upper) for h in free])
    x0 = np.clip([_to_x(h, float(model[h.key])) for h in free], lo, hi)
    start = float(np.sum(fun(x0) ** 2))
    try:
        res = least_squares(fun, x0, jac=jac, bounds=(lo, hi), method="trf", max_nfev=max_nfev)
    except ValueError:  # a residual that is not finite somewhere: keep what we had
        return dict(model)
    if not np.isfinite(res.cost) or 2 * res.cost >= start:
        return dict(model)
    return values(res.x)


def _jacobian(fun, x: np.ndarray, hi: np.ndarray) -> np.ndarray:
    f0 = fun(x)
    cols = []
    for i in range(len(x)):
        xi = x.copy()
        # step away from the upper bound when it is near, so the probe stays inside
        xi[i] = x[i] - STEP if x[i] + STEP > hi[i] else x[i] + STEP
        cols.append((fun(xi) - f0) / (xi[i] - x[i]))
    return np.column_stack(cols)


def spread(scorer: Scorer, model: dict[str, Any], hyps: Sequence[Hypothesis]) -> dict[str, float]:
    """Per continuous parameter of `hyps`: its standard error on its search scale (log for log-scaled
    ones) from the Gauss-Newton covariance s^2 (J'J)^-1 at `model`, s^2 the loss per residual left
    (at least the noise floor's): correlated parameters (a Z velocity and a Z acceleration limit fitted
    on the same short moves) widen each other's. inf for a parameter the residuals do not move."""
    units = list(range(len(scorer.units)))
    free = [h for h in _continuous(hyps) if isinstance(model.get(h.key), (int, float))]
    if not free:
        return {}
    fixed = {k: v for k, v in model.items() if not any(k in h.keys for h in free)}

    def fun(x: np.ndarray) -> np.ndarray:
        out = dict(fixed)
        for h, xi in zip(free, x):
            out.update(h.values(min(max(_from_x(h, xi), h.lower), h.upper)))
        return residual_vector(scorer, out, units)

    x = np.array([_to_x(h, float(model[h.key])) for h in free])
    hi = np.array([_to_x(h, h.upper) for h in free])
    jac = _jacobian(fun, x, hi)
    f0 = fun(x)
    n, p = jac.shape
    s2 = max(float(np.sum(f0 ** 2)), float(scorer.floor.sum())) / max(n - p, 1)
    moving = np.linalg.norm(jac, axis=0) > 1e-12 * max(1.0, float(np.abs(jac).max(initial=0.0)))
    out = {h.key: float("inf") for h in free}
    if moving.any():
        sub = jac[:, moving]
        try:
            cov = np.linalg.inv(sub.T @ sub) * s2
        except np.linalg.LinAlgError:
            return out
        for h, var in zip([h for h, m in zip(free, moving) if m], np.diag(cov)):
            out[h.key] = float(np.sqrt(var)) if var >= 0 else float("inf")
    return out


def loss(scorer: Scorer, values: dict[str, Any]) -> float:
    return float(scorer.unit_losses(values).sum())


def _coarse(scorer: Scorer, model: dict[str, Any], hyps: Sequence[Hypothesis]) -> list[tuple[float, Hypothesis, Any]]:
    """(in-sample loss, hypothesis, value) of each hypothesis' best point on a coarse grid given `model`,
    the best first."""
    out = []
    for h in hyps:
        grid = _grid(h, SCREEN_POINTS)
        losses = [loss(scorer, {**model, **h.values(v)}) for v in grid]
        k = int(np.argmin(losses))
        if np.isfinite(losses[k]):
            out.append((losses[k], h, grid[k]))
    out.sort(key=lambda t: t[0])
    return out


def split(scorer: Scorer, chosen: Sequence[Hypothesis], model: dict[str, Any],
          pool: Sequence[Hypothesis]) -> Iterator[tuple[Hypothesis, tuple[Hypothesis, Hypothesis], dict[str, Any]]]:
    """Replacements of one chosen cause by two candidates: (cause, pair, joint model). The causes are
    tried last chosen first (a later step is the likelier stand-in: it was fitted to what the earlier
    ones left); for each, the `SPLIT_KEEP` candidates of the least loss given the other causes are
    paired, each pair fitted jointly with the other causes (a short least-squares run), and the best
    pair, if it removes `SPLIT_GAIN` of the loss left above the floor, is fitted fully and yielded.
    The held-out judgement is the caller's."""
    floor = float(scorer.floor.sum())
    now = loss(scorer, model)
    if now - floor <= 0:
        return
    for cause in reversed(list(chosen)):
        others = {k: v for k, v in model.items() if k not in cause.keys}
        rest = [h for h in chosen if h is not cause]
        taken = {k for h in rest for k in h.keys}
        # the cause itself stays a candidate: (cause, another) fitted jointly is a forward step whose
        # first value is no longer the one fitted while the other was missing
        free = [h for h in pool if not (h.keys & taken)]
        tops = _coarse(scorer, others, free)[:SPLIT_KEEP]
        trials = []
        for (_, a, va), (_, b, vb) in combinations(tops, 2):
            if a.keys & b.keys:
                continue
            start = {**others, **a.values(va), **b.values(vb)}
            trial = joint_fit(scorer, start, [*rest, a, b], max_nfev=QUICK_NFEV)
            trials.append((loss(scorer, trial), a, b, trial))
        if not trials:
            continue
        after, a, b, trial = min(trials, key=lambda t: t[0])
        if now - after >= SPLIT_GAIN * (now - floor):
            yield cause, (a, b), joint_fit(scorer, trial, [*rest, a, b])
