"""Fitting a hypothesis by re-simulation, and judging it on held-out data.

A `Scorer` computes a level's residuals for a profile given as overrides of the diagnosed one
(`{key: value}`), cached per recording and overrides, and sums squared residuals over *held-out
units*: the recordings when there are several (leave one recording out), otherwise contiguous
chunks of the one recording (held-out blocks, or stretches of samples for feedback).

`fit(scorer, model, hyp, units)` finds the value of `hyp` (on top of the accepted `model`) that
minimises the loss over `units`: a grid over the bounds (log or linear, integers, or every choice),
then scipy's bounded Brent search (`minimize_scalar`) between the best grid point's neighbours.
`held_out(scorer, model, hyp)` fits once without each unit and scores that unit with the value
fitted on the others: the gain it reports is what the hypothesis does on data it has not seen.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

from feedlog.diagnose import keys
from feedlog.diagnose.cases import Case
from feedlog.diagnose.hypothesis import Hypothesis
from feedlog.diagnose.residuals import (Segments, feedback_residual, geometry_residual, line_latency, make_segments,
                                        model_line_offsets, timing_residual)
from feedlog.errors import FeedlogError
from feedlog.profile import MachineProfile

GRID_POINTS = 17
INT_GRID = (1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 400)
CHUNKS = 5               # held-out chunks of a single recording
CHUNKS_EACH = 3          # ... of each recording when there are several
INFORMATIVE = 0.2        # a recording constrains a parameter when the best grid value removes this share of its residual
MATERIAL = 0.05          # ... and what it removes there is at least this share of the excess loss of all recordings
FEEDBACK_CHUNK_MIN = 200  # samples per feedback chunk at least
BRENT_ITER = 20
XATOL = 2e-3             # Brent's tolerance as a share of the bracket (two grid steps)
TIE = 1e-6               # losses within this share of the best count as equal
_MISSING = object()      # a recording's residual not computed yet for some values


def _key(values: Mapping[str, Any]) -> tuple:
    def norm(v: Any) -> Any:
        return float(f"{v:.12g}") if isinstance(v, (float, np.floating)) else v
    return tuple(sorted((k, norm(v)) for k, v in values.items()))


@dataclass
class Unit:
    """A held-out unit: a part of one recording's residual vector (rows `lo:hi`)."""

    case: int
    lo: int
    hi: int
    label: str


class Scorer:
    """Residuals and per-unit losses of one level for profiles = base + overrides (cached)."""

    def __init__(self, profile: MachineProfile, cases: Sequence[Case], level: str, *,
                 min_segment_s: float | None = None) -> None:
        from feedlog.sim import simulate

        self.profile, self.cases, self.level = profile, list(cases), level
        self._cache: dict[tuple, list[Any]] = {}   # values -> [profile or None, residual per recording]
        self.pool: Any = None                      # processes sharing the recordings out (scorer_pool)
        self.simulations = 0
        self.segments: list[Segments | None] = []
        if level == "timing":
            self.baseline_sims = [simulate(c.sim_input, profile) for c in self.cases]
            self.segments = [make_segments(c, s, min_segment_s=min_segment_s)
                             for c, s in zip(self.cases, self.baseline_sims)]
        if level == "line":
            self.line_model = [model_line_offsets(c, profile) for c in self.cases]
        lengths = [self._length(i) for i in range(len(self.cases))]
        self.data_size = sum(lengths)   # what the level is judged on, in `data_unit`s, over data_s of motion
        self.data_unit = {"timing": "segments", "feedback": "samples", "line": "blocks", "geometry": "samples"}[level]
        self.data_s = float(sum(c.cycle_s for c, n in zip(self.cases, lengths) if n > 0))
        self.weights = [s.weight if self.level == "timing" else np.ones(n) for s, n in
                        zip(self.segments or [None] * len(lengths), lengths)]
        self.units = self._units(lengths)
        self.floor = np.array([self._floor(u) for u in self.units])

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without its pool of processes (a copy elsewhere computes serially)."""
        return {**self.__dict__, "pool": None}

    def _floor(self, u: Unit) -> float:
        """The loss a perfect model leaves on a unit: the measurement's own resolution. Timing: each
        segment's two boundaries are uncertain by `Case.segment_sigma_s` (a sampling period / sqrt(12);
        on sparse data, whose sampling the simulation shares, the timestamps' jitter and the position
        noise); line: a sampling period / sqrt(12); feedback: the noise of the feedback positions at rest;
        geometry: the joints' recorded resolution (`geometry_sigma`)."""
        case = self.cases[u.case]
        if self.level == "timing":
            return float(self.weights[u.case][u.lo:u.hi].sum()) * 2.0 * case.segment_sigma_s ** 2
        if self.level == "line":  # two events on each side, each good to a sampling period
            return (u.hi - u.lo) * 4.0 * case.boundary_sigma_s ** 2
        if self.level == "geometry":
            return (u.hi - u.lo) * 3 * geometry_sigma(case) ** 2
        from feedlog.align.blocks import rest_noise

        fb = case.feedback
        return (u.hi - u.lo) * fb.cmd.shape[1] * rest_noise(fb.t_ns, fb.fb) ** 2

    def _length(self, i: int) -> int:
        if self.level == "timing":
            return len(self.segments[i])
        if self.level == "line":
            pair = self.line_model[i]
            return 0 if pair is None else len(pair[0])
        if self.level == "geometry":
            geo = self.cases[i].geometry
            return 0 if geo is None else len(geo.t_ns)
        fb = self.cases[i].feedback
        return 0 if fb is None else len(fb.t_ns)

    def _units(self, lengths: list[int]) -> list[Unit]:
        """Contiguous chunks of each recording (five of a single recording, three of each of several)."""
        used = [i for i, n in enumerate(lengths) if n > 0]
        per_case = CHUNKS if len(used) == 1 else CHUNKS_EACH
        minimum = FEEDBACK_CHUNK_MIN if self.level in ("feedback", "geometry") else 1
        what = {"timing": "segments", "feedback": "samples", "line": "blocks", "geometry": "samples"}[self.level]
        units = []
        for i in used:
            n = lengths[i]
            k = max(1, min(per_case, n // minimum))
            edges = np.linspace(0, n, k + 1).round().astype(int)
            units += [Unit(i, int(a), int(b), f"{self.cases[i].name} {what} {a}-{b}")
                      for a, b in zip(edges[:-1], edges[1:])]
        return units

    @property
    def groups(self) -> list[list[int]]:
        """Unit indices per recording."""
        out: dict[int, list[int]] = {}
        for j, u in enumerate(self.units):
            out.setdefault(u.case, []).append(j)
        return list(out.values())

    @property
    def chunked(self) -> bool:
        return len(self.groups) == 1

    def residuals(self, values: Mapping[str, Any], cases: Sequence[int] | None = None) -> list[np.ndarray | None]:
        """One residual array per recording (None where a recording lacks the level or the profile is invalid).
        With `cases`, only those recordings' residuals are computed (the others are None): a loss over some
        units needs no simulation of the recordings it leaves out. Cached per recording and values."""
        key = _key(values)
        entry = self._cache.get(key)
        if entry is None:
            try:
                profile = keys.with_values(self.profile, values) if values else self.profile
            except FeedlogError:
                profile = None
            entry = self._cache[key] = [profile, [_MISSING] * len(self.cases)]
        profile, out = entry
        wanted = range(len(self.cases)) if cases is None else cases
        missing = [i for i in wanted if out[i] is _MISSING]
        if missing and profile is None:
            for i in missing:
                out[i] = None
        elif missing:
            for i, r in self._compute(values, profile, missing).items():
                out[i] = r
        return [None if r is _MISSING else r for r in out]

    def _compute(self, values: Mapping[str, Any], profile: MachineProfile, cases: list[int]
                 ) -> dict[int, np.ndarray | None]:
        """The residuals of recordings `cases` for base + `values` (= `profile`): on the scorer's `pool`
        of processes when it has one (`scorer_pool.ScorerPool`), else here one after another."""
        if self.pool is not None and len(cases) > 1:
            return self.pool.compute(values, profile, cases)
        return self.compute_here(values, profile, cases)

    def compute_here(self, values: Mapping[str, Any], profile: MachineProfile, cases: Sequence[int]
                     ) -> dict[int, np.ndarray | None]:
        """The residuals of recordings `cases` for base + `values` (= `profile`), in this process."""
        return {i: self._residual(i, self.cases[i], profile, bool(values)) for i in cases}

    def case_residual(self, i: int, values: Mapping[str, Any]) -> np.ndarray | None:
        """The residual of recording `i` alone for base + `values` (not cached; None where invalid)."""
        try:
            profile = keys.with_values(self.profile, values) if values else self.profile
            return self._residual(i, self.cases[i], profile, bool(values))
        except FeedlogError:
            return None

    def _residual(self, i: int, case: Case, profile: MachineProfile, changed: bool) -> np.ndarray | None:
        if self.level == "timing":
            from feedlog.sim import simulate

            try:
                sim = simulate(case.sim_input, profile) if changed else self.baseline_sims[i]
            except FeedlogError:
                return None
            self.simulations += int(changed)
            return timing_residual(case, self.segments[i], sim)
        if self.level == "feedback":
            return feedback_residual(case, profile)
        if self.level == "geometry":
            return geometry_residual(case, profile)
        if self.level == "line":
            pair = self.line_model[i]
            if pair is None:  # no line stream here: no units of this recording on this level
                return None
            measured, model = pair
            return model + line_latency(profile) - measured
        raise FeedlogError(f"unknown residual level {self.level!r}")

    def unit_losses(self, values: Mapping[str, Any]) -> np.ndarray:
        """The loss of every unit for base + `values` (inf where the profile is invalid)."""
        return self._losses(self.residuals(values), range(len(self.units)))

    def loss(self, values: Mapping[str, Any], units: Sequence[int]) -> float:
        """The summed loss of `units` for base + `values`: only their recordings are simulated (the sum
        equals `unit_losses(values)[units].sum()`)."""
        units = list(units)
        res = self.residuals(values, sorted({self.units[j].case for j in units}))
        return float(self._losses(res, units)[units].sum())

    def _losses(self, res: list[np.ndarray | None], units: Sequence[int]) -> np.ndarray:
        out = np.zeros(len(self.units))
        for j in units:
            u = self.units[j]
            r = res[u.case]
            if r is None:
                out[j] = np.inf
                continue
            sq = np.square(r[u.lo:u.hi])
            w = self.weights[u.case][u.lo:u.hi]
            out[j] = float(np.sum(sq * (w[:, None] if sq.ndim == 2 else w)))
        return out


def geometry_sigma(case: Case) -> float:
    """What a perfect kinematic model still misses per joint sample: the joints' recorded resolution (the
    smallest step between distinct values / sqrt(12)), at least 1e-6 mm."""
    from feedlog.align.pipeline import position_quantum

    geo = case.geometry
    return max(float(position_quantum(geo.joints[:, :3])) / np.sqrt(12.0), 1e-6)


@dataclass
class Fit:
    value: Any
    loss: float                 # over the units it was fitted on
    evaluations: int = 0


@dataclass
class HeldOut:
    """A hypothesis judged on held-out units."""

    hyp: Hypothesis
    value: Any                          # fitted on all units
    fold_values: list[Any]              # per unit: the value it was scored with (fitted without its fold)
    before: np.ndarray                  # per-unit loss of the model without the hypothesis
    after: np.ndarray                   # per-unit loss with the value fitted on the other units
    fit_after: np.ndarray               # per-unit loss with the value fitted on all units
    interval: tuple[float, float] | None = None
    floor: np.ndarray | None = None     # per-unit loss of a perfect model (the measurement's resolution)
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def gain(self) -> float:
        """Share of the held-out loss above the noise floor removed (1: all of it; negative: worse)."""
        floor = 0.0 if self.floor is None else float(self.floor.sum())
        excess = float(self.before.sum()) - floor
        return float(self.before.sum() - self.after.sum()) / excess if excess > 0 else 0.0


def _grid(hyp: Hypothesis, points: int = GRID_POINTS) -> list[Any]:
    if hyp.scale == "choice":
        return list(hyp.choices)
    if hyp.scale == "int":
        pts = [v for v in INT_GRID if hyp.lower <= v <= hyp.upper][::max(1, GRID_POINTS // points)]
    elif hyp.scale == "log":
        pts = list(np.geomspace(hyp.lower, hyp.upper, points))
    else:
        pts = list(np.linspace(hyp.lower, hyp.upper, points))
    for v in (hyp.baseline, *hyp.seeds):
        if v is not None and np.isfinite(v) and hyp.lower <= v <= hyp.upper:
            pts.append(int(round(v)) if hyp.scale == "int" else float(v))
    return sorted(set(pts))


def fit(scorer: Scorer, model: Mapping[str, Any], hyp: Hypothesis, units: Sequence[int]) -> Fit:
    """The value of `hyp` (on top of `model`) with the least loss over `units` (indices into scorer.units)."""
    units = list(units)

    def loss(v: Any) -> float:
        return scorer.loss({**model, **hyp.values(v)}, units)

    grid = _grid(hyp)
    losses = np.array([loss(v) for v in grid])
    value, best_loss, extra = refine(hyp, loss, grid, losses, BRENT_ITER)
    return Fit(value=value, loss=best_loss, evaluations=len(grid) + extra)


def refine(hyp: Hypothesis, loss: Callable[[Any], float], grid: list[Any], losses: np.ndarray,
           budget: int) -> tuple[Any, float, int]:
    """The least-loss value between the neighbours of the best grid point: (value, loss, evaluations).
    A continuous parameter gets a bounded Brent search of at most `budget` iterations; an integer one a
    ternary then exhaustive search when `budget` is the full fit's, else the integer grid's points
    between the neighbours (a screen's few evaluations)."""
    best = _closest_best(hyp, grid, losses)
    value, best_loss = grid[best], float(losses[best])
    if not np.isfinite(best_loss):
        return value, best_loss, 0
    if hyp.scale in ("log", "linear"):
        lo, hi = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
        if hi <= lo:
            return value, best_loss, 0
        to_x = np.log if hyp.scale == "log" else (lambda v: v)
        from_x = np.exp if hyp.scale == "log" else (lambda v: v)
        span = float(to_x(hi)) - float(to_x(lo))
        res = minimize_scalar(lambda x: loss(float(from_x(x))), bounds=(float(to_x(lo)), float(to_x(hi))),
                              method="bounded", options={"xatol": XATOL * span, "maxiter": budget})
        if res.fun < best_loss:
            value, best_loss = float(from_x(res.x)), float(res.fun)
        return value, best_loss, int(res.nfev)
    if hyp.scale == "int" and budget >= BRENT_ITER:
        return _refine_int(loss, grid, best, losses)
    if hyp.scale == "int":
        lo, hi = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
        more = [v for v in INT_GRID if lo < v < hi and v not in grid and hyp.lower <= v <= hyp.upper]
        for v in more:
            x = loss(v)
            if x < best_loss:
                value, best_loss = v, x
        return value, best_loss, len(more)
    return value, best_loss, 0


def _closest_best(hyp: Hypothesis, grid: list[Any], losses: np.ndarray) -> int:
    """The grid point with the least loss; among (nearly) equal ones, the one nearest the profile's
    value, so that a parameter the data does not constrain stays where the profile has it."""
    finite = np.isfinite(losses)
    if not finite.any():
        return 0
    low = float(losses[finite].min())
    tied = np.flatnonzero(finite & (losses <= low + TIE * max(low, 1e-300)))
    if len(tied) == 1 or hyp.scale == "choice" or hyp.baseline is None or not np.isfinite(hyp.baseline):
        return int(tied[0]) if hyp.baseline is None else int(tied[np.argmin(losses[tied])])
    g = np.asarray(grid, dtype=np.float64)[tied]
    log = hyp.scale in ("log", "int") and hyp.baseline > 0
    dist = np.abs(np.log(g) - np.log(hyp.baseline)) if log else np.abs(g - hyp.baseline)
    return int(tied[np.argmin(dist)])


def _refine_int(loss, grid: list[Any], best: int, losses: np.ndarray) -> tuple[int, float, int]:
    """Integer search between the best grid point's neighbours (ternary steps, then every value)."""
    lo, hi = int(grid[max(best - 1, 0)]), int(grid[min(best + 1, len(grid) - 1)])
    cache = {int(v): float(x) for v, x in zip(grid, losses)}

    def f(v: int) -> float:
        if v not in cache:
            cache[v] = loss(v)
        return cache[v]

    n0 = len(cache)
    while hi - lo > 6:
        m1, m2 = lo + (hi - lo) // 3, hi - (hi - lo) // 3
        if f(m1) <= f(m2):
            hi = m2
        else:
            lo = m1
    for v in range(lo, hi + 1):
        f(v)
    value = min(cache, key=lambda v: (cache[v], abs(v - int(grid[best]))))
    return value, cache[value], len(cache) - n0


def folds_for(scorer: Scorer, model: Mapping[str, Any], hyp: Hypothesis) -> tuple[list[list[int]], str]:
    """How to hold data out for `hyp`: whole recordings when at least two recordings each constrain it
    (the best value on the grid removes at least `INFORMATIVE` of that recording's own residual above
    its noise floor, and that is a material share, `MATERIAL`, of the excess loss of all recordings:
    a recording with almost nothing left to explain does not constrain anything, however much of its
    little it removes), else single stretches: a recording that barely depends on the parameter cannot
    fit it for the others."""
    grid = _grid(hyp)
    losses = np.array([scorer.unit_losses({**model, **hyp.values(v)}) for v in grid])  # (grid, units)
    base = scorer.unit_losses(model)
    total = float(base.sum() - scorer.floor.sum())
    informative = []
    for group in scorer.groups:
        per = losses[:, group].sum(axis=1)
        excess = float(base[group].sum() - scorer.floor[group].sum())
        best = float(np.min(per[np.isfinite(per)])) if np.isfinite(per).any() else np.inf
        removed = float(base[group].sum()) - best
        if excess > 0 and removed >= INFORMATIVE * excess and removed >= MATERIAL * total:
            informative.append(group)
    if len(informative) >= 2:
        return scorer.groups, "leave one recording out"
    return [[j] for j in range(len(scorer.units))], "held-out stretches"


def held_out(scorer: Scorer, model: Mapping[str, Any], hyp: Hypothesis) -> HeldOut:
    """Fit `hyp` without each fold in turn and score the fold's units; and fit on all units."""
    n = len(scorer.units)
    before = scorer.unit_losses(model)
    all_fit = fit(scorer, model, hyp, range(n))
    fit_after = scorer.unit_losses({**model, **hyp.values(all_fit.value)})
    folds, scheme = folds_for(scorer, model, hyp)
    values: list[Any] = [all_fit.value] * n
    after = fit_after.copy()
    fold_values = []
    for fold in folds:
        if len(folds) == 1:
            break
        f = fit(scorer, model, hyp, [k for k in range(n) if k not in fold])
        fold_values.append(f.value)
        losses = scorer.unit_losses({**model, **hyp.values(f.value)})
        for j in fold:
            values[j] = f.value
            after[j] = losses[j]
    return HeldOut(hyp=hyp, value=all_fit.value, fold_values=values, before=before, after=after,
                   fit_after=fit_after, floor=scorer.floor, interval=_interval(hyp, all_fit.value, fold_values or [all_fit.value]),
                   extra={"scheme": scheme, "folds": len(folds), "fold_fits": fold_values, "folds_units": folds})


def _interval(hyp: Hypothesis, value: Any, folds: Sequence[Any]) -> tuple[float, float] | None:
    """Jackknife interval (+- 2 standard errors, log scale for log parameters), at least the fold range."""
    if hyp.scale == "choice" or len(folds) < 2:
        return None
    x = np.asarray(folds, dtype=np.float64)
    v = float(value)
    log = hyp.scale == "log" and (x > 0).all() and v > 0
    t = np.log(x) if log else x
    n = len(t)
    se = float(np.sqrt((n - 1) / n * np.sum((t - t.mean()) ** 2)))
    centre = np.log(v) if log else v
    lo, hi = min(centre - 2 * se, t.min()), max(centre + 2 * se, t.max())
    if log:
        lo, hi = np.exp(lo), np.exp(hi)
    return float(max(lo, hyp.lower)), float(min(hi, hyp.upper))
