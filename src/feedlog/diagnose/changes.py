"""Changes during a session: a parameter that took one value, then another (a dial turned mid-program).

One value fitted to a recording whose feed override went from 100 % to 70 % halfway is a wrong value
for both halves. For each recording, each timing hypothesis that can change while a machine runs
(`CHANGING`: the operator's dials; and every timing cause already named) is tried as a *step*: one
value up to a segment boundary, another after it. The recording's segment residuals are simulated for a
grid of values (`_OneRecording`, cached), every boundary is scored from cumulative sums, the two values
are refined on their sides (Brent, `fit.refine`) and the boundary is found again with them.

Judged like a cause, on data the fit has not seen: the boundary and both values are fitted on the even
segments and scored on the odd ones, against one value fitted on the same even segments. A change is
reported when it removes at least `min_gain` of that held-out loss above the noise floor, the
recording's timing error drops by at least `min_effect_pct` points, and each side has `MIN_SIDE`
segments that the two values tell apart (by `SENSITIVE` timing sigmas: on a family of six bundled
LinuxCNC recordings a rapid dial of 0.36 "before" rested on the one approach rapid it touched). It says when (the measured time of the boundary, from motion start, the segment it ends and
the program line), from what, to what, and what one value would have been. The averaged finding of the
same parameter is not reported, and the extended profile keeps the profile's value for it.

A gradual change (a machine that warms up) is tried beside the step where the step's held-out gain
reaches `DRIFT_SCREEN` of `min_gain`: the drifts of `SHAPES` (`drift.py`: one value until t0, linear
to another at t1, t1 possibly the recording's end or t0 its start; or an exponential approach with
time constant tau) are fitted both ways round (even segments -> odd, odd -> even) and must span
MIN_SIDE whole segments. The line must remove `min_gain` of what the step leaves above the noise floor
over both folds (and `min_gain` of what one value leaves); the approach must too, and must beat the
line (no worse on either fold, `min_gain` of what the line leaves removed over both). The one chosen
is reported as a drift (`shape` "drift": `until_s`, `rate_per_min`; "approach": `tau_s`, `until_s` the
95 % time; both: `open_end` where it had not levelled off when motion ended, `open_start` where it was
under way when motion started) under the same effect and two-segment rules.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from feedlog.diagnose.drift import Drift, Interpolated, drift_residuals, fit_drift, inside
from feedlog.diagnose.fit import Scorer, _grid, refine
from feedlog.diagnose.hypothesis import Hypothesis

CHANGING = ("sim.feed_override.override", "sim.rapid_override.override")
MIN_SIDE = 2          # segments on each side of the segment a change happened in, at least (that its values move)
SENSITIVE = 3.0       # a segment a value moves: the two values' residuals differ by this many timing sigmas
REFINE_ITER = 12
DRIFT_SCREEN = 0.5    # a drift is tried where a step removes at least this share of min_gain (held out)


@dataclass
class Change:
    recording: str
    parameter: str
    unit: str
    before: float
    after: float
    at_s: float                  # measured time of the boundary, from motion start
    between_s: tuple[float, float]  # the boundary lies within this (the segment it ends)
    line: int | None             # program line of the boundary's block
    segment: int                 # the segment the change happened in (before it: `before`; after it: `after`)
    error_single_pct: float      # the recording's timing error with one value for the whole session
    error_change_pct: float      # ... with the change
    held_out_gain: float         # share of the held-out loss (odd segments) removed against one value
    single_value: float          # the one value the whole session would be averaged into
    shape: str = "step"          # "step": a dial turned at at_s; "drift": linear from at_s to until_s;
    #                              "approach": exponential from at_s with time constant tau_s (95 % at until_s)
    until_s: float | None = None  # a drift's end (measured time from motion start)
    tau_s: float | None = None   # an approach's time constant
    motion_end_s: float | None = None  # the recording's motion ends (measured time from motion start)
    open_start: bool = False     # a drift under way when motion started (no whole segment before at_s)
    open_end: bool = False       # ... not levelled off when it ended (no whole segment after until_s)

    @property
    def rate_per_min(self) -> float | None:
        """A drift's rate of change per minute (None for a step)."""
        if self.shape != "drift" or self.until_s is None or self.until_s <= self.at_s:
            return None
        return 60.0 * (self.after - self.before) / (self.until_s - self.at_s)

    def as_dict(self) -> dict[str, Any]:
        return {"recording": self.recording, "parameter": self.parameter, "unit": self.unit, "shape": self.shape,
                "before": self.before, "after": self.after, "at_s": self.at_s, "until_s": self.until_s,
                "rate_per_min": self.rate_per_min, "between_s": list(self.between_s),
                "line": self.line, "segment": self.segment, "error_single_pct": self.error_single_pct,
                "error_change_pct": self.error_change_pct, "held_out_gain": self.held_out_gain,
                "single_value": self.single_value, "tau_s": self.tau_s, "open_start": self.open_start,
                "open_end": self.open_end}

    def text(self) -> str:
        where = f" (program line {self.line})" if self.line is not None else ""
        tail = (f", not one value ({self.single_value:.4g}): timing error {self.error_single_pct:.2f} % -> "
                f"{self.error_change_pct:.2f} %")
        began = " (under way when motion started; it may have begun before)" if self.open_start else ""
        if self.shape == "approach":
            late = (f", after the recording's motion ended at {self.motion_end_s:.2f} s: it did not level off "
                    f"within the recording" if self.open_end and self.motion_end_s is not None else "")
            return (f"drift during {self.recording}: {self.parameter} approaches {self.after:.4g} from "
                    f"{self.before:.4g} after {self.at_s:.2f} s{where}{began} with time constant {self.tau_s:.3g} s "
                    f"(reaches 95 % at {self.until_s:.2f} s{late}){tail}").replace("  ", " ")
        if self.shape == "drift":
            still = (", still drifting when motion ended (it did not level off within the recording)"
                     if self.open_end else "")
            return (f"drift during {self.recording}: {self.parameter} drifts from {self.before:.4g} at "
                    f"{self.at_s:.2f} s{where}{began} to {self.after:.4g} at {self.until_s:.2f} s "
                    f"({self.rate_per_min:+.4g} {self.unit} per minute){still}{tail}").replace("  ", " ")
        return (f"change during {self.recording}: {self.parameter} {self.before:.4g} -> {self.after:.4g} "
                f"{self.unit} at {self.at_s:.2f} s{where}, not one value ({self.single_value:.4g}): "
                f"timing error {self.error_single_pct:.2f} % -> {self.error_change_pct:.2f} %").replace("  ", " ")


def _best_split(sq: np.ndarray, use: np.ndarray, at: np.ndarray) -> tuple[int, float, float]:
    """(boundary segment k, loss of the best step at k, loss of the best single value) for squared
    residuals `sq` (grid, segments) counted where `use`: one value before segment k, another after it;
    segment k itself, where the change happened, is the two mixed and counts in neither (`at`: the
    segments that may be the boundary)."""
    s = sq * use
    cum = np.cumsum(s, axis=1)
    total = cum[:, -1]
    best_k, best = -1, np.inf
    for k in np.flatnonzero(at):
        left = cum[:, k - 1].min() if k else 0.0
        loss = float(left + (total - cum[:, k]).min())
        if loss < best:
            best_k, best = int(k), loss
    return best_k, best, float(total.min())


class _OneRecording:
    """Squared, weighted segment residuals of one recording for values of one hypothesis (cached)."""

    def __init__(self, scorer: Scorer, base: Mapping[str, Any], hyp: Hypothesis, case: int) -> None:
        self.scorer, self.base, self.hyp, self.case = scorer, dict(base), hyp, case
        self._cache: dict[float, np.ndarray] = {}

    def residual(self, v: float) -> np.ndarray:
        """Signed residuals times the square root of the weights (inf where `v` does not simulate)."""
        key = float(f"{v:.12g}")
        if key not in self._cache:
            r = self.scorer.case_residual(self.case, {**self.base, **self.hyp.values(key)})
            w = self.scorer.weights[self.case]
            self._cache[key] = np.full(len(w), np.inf) if r is None else np.sqrt(w) * r
        return self._cache[key]

    def sq(self, v: float) -> np.ndarray:
        return np.square(self.residual(v))

    def best(self, rows: np.ndarray, grid: list[float], sq: np.ndarray) -> tuple[float, float]:
        """The value with the least loss over the segments `rows` (grid, then Brent between neighbours)."""
        value, loss, _ = refine(self.hyp, lambda v: float(self.sq(v)[rows].sum()), grid, sq[:, rows].sum(axis=1),
                                REFINE_ITER)
        return float(value), float(loss)


def _error_pct(scorer: Scorer, case: int, loss: float) -> float:
    seg = scorer.segments[case]
    w = scorer.weights[case]
    n, total = float(w.sum()), float((seg.measured_s * w).sum())
    floor = float(w.sum()) * 2.0 * scorer.cases[case].segment_sigma_s ** 2
    return 100.0 * float(np.sqrt(n * max(loss - floor, 0.0))) / total if total > 0 else 0.0


def find_changes(scorer: Scorer, model: Mapping[str, Any], hyps: Sequence[Hypothesis], *, min_gain: float,
                 min_effect_pct: float) -> list[Change]:
    """Step changes of the changing hypotheses in each recording of a timing `scorer`, on top of `model`."""
    out: list[Change] = []
    for hyp in hyps:
        if hyp.level != "timing" or hyp.scale not in ("log", "linear") or not (hyp.key in CHANGING or hyp.key in model):
            continue
        grid = [float(v) for v in _grid(hyp)]
        if hyp.key in model:
            grid = sorted({*grid, float(model[hyp.key])})
        base = {k: v for k, v in model.items() if k != hyp.key}
        for i, case in enumerate(scorer.cases):
            seg = scorer.segments[i] if i < len(scorer.segments) else None
            if seg is None or len(seg) < 2 * MIN_SIDE + 2:
                continue
            one = _OneRecording(scorer, base, hyp, i)
            sq = np.vstack([one.sq(v) for v in grid])
            if not np.isfinite(sq).all(axis=1).any():
                continue
            change = _judge(one, grid, sq, min_gain=min_gain, min_effect_pct=min_effect_pct)
            if change is not None:
                out.append(change)
    return out


def _split(one: _OneRecording, use: np.ndarray, at: np.ndarray, grid: list[float],
           sq: np.ndarray) -> tuple[int, float, float]:
    """The boundary segment k and the values before and after it, fitted on the segments `use`: k from
    the grid, the values refined on their sides, k found again with them."""
    k, _, _ = _best_split(np.where(np.isfinite(sq), sq, 1e30), use, at)
    v1 = v2 = np.nan
    rows = np.arange(sq.shape[1])
    for _ in range(3):
        if k < 0:
            return -1, np.nan, np.nan
        v1, _ = one.best(rows[use & (rows < k)], grid, sq)
        v2, _ = one.best(rows[use & (rows > k)], grid, sq)
        a, b = one.sq(v1) * use, one.sq(v2) * use
        cand = [(float(a[:j].sum() + b[j + 1:].sum()), int(j)) for j in np.flatnonzero(at)]
        k_new = min(cand)[1]
        if k_new == k:
            break
        k = k_new
    return k, v1, v2


def _turn_time(r1: float, r2: float, measured: float) -> float:
    """When, within a segment of `measured` duration, a change from the value whose simulation misses
    it by r1 to the one that misses it by r2 explains it: the segment run at the first value's speed for
    tau, then the second's, tau = r2 (D + r1) / (r2 - r1) (constant speeds; clipped to the segment)."""
    if not np.isfinite(r1) or not np.isfinite(r2) or r2 == r1:
        return 0.5 * measured
    return float(np.clip(r2 * (measured + r1) / (r2 - r1), 0.0, measured))


def _judge(one: _OneRecording, grid: list[float], sq: np.ndarray, *, min_gain: float,
           min_effect_pct: float) -> Change | None:
    scorer, hyp, i = one.scorer, one.hyp, one.case
    n = sq.shape[1]
    rows = np.arange(n)
    inner = (rows >= MIN_SIDE) & (rows < n - MIN_SIDE)      # a boundary leaves MIN_SIDE segments each side
    even, odd = rows % 2 == 0, rows % 2 == 1
    # held out: boundary (an odd segment, between two even ones) and both values from the even segments,
    # scored on the other odd ones against one value fitted on the same even segments
    k_e, a_e, b_e = _split(one, even, inner & odd, grid, sq)
    if k_e < 0:
        return None
    single_e, _ = one.best(rows[even], grid, sq)
    scored = odd & (rows != k_e)
    single_odd = float(one.sq(single_e)[scored].sum())
    change_odd = float(one.sq(a_e)[scored & (rows < k_e)].sum() + one.sq(b_e)[scored & (rows > k_e)].sum())
    case = scorer.cases[i]
    floor_odd = float(scorer.weights[i][scored].sum()) * 2.0 * case.segment_sigma_s ** 2
    excess = single_odd - floor_odd
    gain = (single_odd - change_odd) / excess if excess > 0 else 0.0
    if gain >= DRIFT_SCREEN * min_gain:
        found = _gradual(one, grid, sq, (k_e, (a_e, b_e), change_odd, single_odd, floor_odd), min_gain=min_gain)
        change = None
        if found is not None:
            model, shape, drift, drift_gain = found
            change = _drift_change(one, grid, sq, (model, shape, drift), drift_gain, min_effect_pct=min_effect_pct)
        if change is not None:
            return change
    if gain < min_gain:
        return None
    # all segments: where, from what, to what
    k, v1, v2 = _split(one, np.ones(n, bool), inner, grid, sq)
    if k < 0:
        return None
    v0, l0 = one.best(rows, grid, sq)
    a, b = one.sq(v1), one.sq(v2)
    l12 = float(a[:k].sum() + b[k + 1:].sum())     # the boundary segment: its two values mixed
    err_single, err_change = _error_pct(scorer, i, l0), _error_pct(scorer, i, l12)
    if err_single - err_change < min_effect_pct:
        return None
    seg = scorer.segments[i]
    start = float(seg.end_s[k - 1]) if k else 0.0
    end = float(seg.end_s[k])
    r1 = scorer.case_residual(i, {**one.base, **hyp.values(v1)})
    r2 = scorer.case_residual(i, {**one.base, **hyp.values(v2)})
    if r1 is None or r2 is None:
        return None
    # each value must rest on segments it moves: a dial that acts on one rapid either side is not a change
    moved = np.abs(r1 - r2) * scorer.weights[i] > SENSITIVE * case.segment_sigma_s
    if moved[:k].sum() < MIN_SIDE or moved[k + 1:].sum() < MIN_SIDE:
        return None
    tau = _turn_time(float(r1[k]), float(r2[k]), float(seg.measured_s[k]))
    return Change(recording=case.name, parameter=hyp.key, unit=hyp.unit, before=v1, after=v2,
                  at_s=end - float(seg.measured_s[k]) + tau, between_s=(start, end),
                  line=_line_of(case, int(seg.anchors[k])), segment=k,
                  error_single_pct=err_single, error_change_pct=err_change, held_out_gain=float(gain),
                  single_value=v0)


Fold = tuple[int, tuple[float, float], float, float, float]   # boundary, (before, after), step, single, floor
SHAPES = (("line", None), ("line", "t1"), ("line", "t0"), ("approach", None), ("approach", "t0"))   # drift.fit_drift


def _fold(one: _OneRecording, grid: list[float], sq: np.ndarray, fit: np.ndarray) -> Fold | None:
    """One held-out fold: a step (its boundary one of the other segments) and one value fitted on the
    segments `fit`, scored on the others but the boundary: (boundary, (before, after), step loss,
    single-value loss, noise floor), or None where no step fits."""
    n = sq.shape[1]
    rows = np.arange(n)
    inner = (rows >= MIN_SIDE) & (rows < n - MIN_SIDE)
    k, a, b = _split(one, fit, inner & ~fit, grid, sq)
    if k < 0:
        return None
    scored = ~fit & (rows != k)
    single, _ = one.best(rows[fit], grid, sq)
    step_loss = float(one.sq(a)[scored & (rows < k)].sum() + one.sq(b)[scored & (rows > k)].sum())
    floor = float(one.scorer.weights[one.case][scored].sum()) * 2.0 * one.scorer.cases[one.case].segment_sigma_s ** 2
    return k, (a, b), step_loss, float(one.sq(single)[scored].sum()), floor


def _gradual(one: _OneRecording, grid: list[float], sq: np.ndarray, even_fold: Fold, *,
             min_gain: float) -> tuple[Interpolated, tuple[str, str | None], Drift, float] | None:
    """A drift judged on both folds (fitted on the even segments and scored on the odd ones, and the
    other way round; each fold's step boundary left out of both scores). Each shape of `SHAPES` is
    fitted on each fold and must span at least MIN_SIDE whole segments. The line (free, or running to
    the recording's end, or from its start: the one with the least held-out loss) must remove at least
    `min_gain` of what the step leaves above the noise floor over both folds (the penalty its fourth
    parameter pays); the approach (free, or from the start) must do the same, and beat the line: no
    worse on either fold, and `min_gain` of what the better line of each fold leaves above the floor
    removed over both. Returns (the model, the shape, the drift fitted on the even segments,
    its held-out gain against one value over both folds), or None: the step stands."""
    seg = one.scorer.segments[one.case]
    rows = np.arange(len(seg))
    start_s, end_s = seg.end_s - seg.measured_s, seg.end_s
    even = rows % 2 == 0
    odd_fold = _fold(one, grid, sq, ~even)
    if odd_fold is None:
        return None
    model = Interpolated(one.residual, one.hyp.scale, one.hyp.lower, one.hyp.upper)
    model.add(grid)
    held = {shape: np.zeros(2) for shape in SHAPES}    # held-out loss per fold
    kept: dict = {}
    step, single, floor = np.zeros(2), np.zeros(2), np.zeros(2)
    for j, (fit, (k, first, step[j], single[j], floor[j])) in enumerate(((even, even_fold), (~even, odd_fold))):
        model.densify(*first)
        for kind, fixed in SHAPES:
            drift = fit_drift(model, start_s, end_s, fit, first, kind=kind, fixed=fixed)
            if drift is not None and model.at_edge(drift.after):   # an approach's end may lie beyond the step's:
                beyond = model.from_x(2.0 * model.to_x(first[1]) - model.to_x(first[0]))   # simulate further out
                model.densify(first[0], float(beyond))
                drift = fit_drift(model, start_s, end_s, fit, first, kind=kind, fixed=fixed)
            if drift is None or inside(drift, start_s, end_s) < MIN_SIDE:
                held[kind, fixed][j] = np.inf
                continue
            held[kind, fixed][j] = float(np.square(drift_residuals(model, drift, start_s, end_s))[~fit & (rows != k)].sum())
            kept.setdefault((kind, fixed), drift)
    left = step.sum() - floor.sum()
    if left <= 0 or single.sum() <= floor.sum():
        return None

    def beats_step(shape) -> bool:
        return bool(np.isfinite(held[shape]).all() and step.sum() - held[shape].sum() >= min_gain * left)

    lines = [s for s in SHAPES if s[0] == "line"]
    line = min(lines, key=lambda s: held[s].sum())
    best_line = np.min([held[s] for s in lines], axis=0)            # per fold, the better line there
    approach = min((s for s in SHAPES if s[0] == "approach"), key=lambda s: held[s].sum())
    chosen = line if beats_step(line) else None
    if beats_step(approach) and (not np.isfinite(best_line).all() or (   # no line spans MIN_SIDE segments, or
            np.all(held[approach] <= best_line)
            and best_line.sum() - held[approach].sum() >= min_gain * (best_line - floor).sum())):
        chosen = approach
    if chosen is None:
        return None
    gain = (single.sum() - held[chosen].sum()) / (single.sum() - floor.sum())
    return (model, chosen, kept[chosen], gain) if gain >= min_gain else None


def _drift_change(one: _OneRecording, grid: list[float], sq: np.ndarray,
                  found: tuple[Interpolated, tuple[str, str | None], Drift], gain: float, *,
                  min_effect_pct: float) -> Change | None:
    """The drift refitted on all segments, reported if it takes the recording's timing error down by
    `min_effect_pct` points and both of its values rest on MIN_SIDE segments they move."""
    scorer, hyp, i = one.scorer, one.hyp, one.case
    model, (kind, fixed), held = found
    case, seg = scorer.cases[i], scorer.segments[i]
    n = len(seg)
    rows = np.arange(n)
    start_s, end_s = seg.end_s - seg.measured_s, seg.end_s
    model.densify(held.before, held.after)
    drift = fit_drift(model, start_s, end_s, np.ones(n, bool), (held.before, held.after), kind=kind, fixed=fixed)
    if drift is None:
        return None
    v0, l0 = one.best(rows, grid, sq)
    e = drift_residuals(model, drift, start_s, end_s)
    err_single, err_change = _error_pct(scorer, i, l0), _error_pct(scorer, i, float(np.square(e).sum()))
    if err_single - err_change < min_effect_pct:
        return None
    r1 = scorer.case_residual(i, {**one.base, **hyp.values(drift.before)})
    r2 = scorer.case_residual(i, {**one.base, **hyp.values(drift.after)})
    if r1 is None or r2 is None:
        return None
    moved = np.abs(r1 - r2) * scorer.weights[i] > SENSITIVE * case.segment_sigma_s
    mid = 0.5 * (drift.t0_s + min(drift.t1_s, float(end_s[-1])))
    if moved[end_s <= mid].sum() < MIN_SIDE or moved[start_s >= mid].sum() < MIN_SIDE:
        return None
    k = int(min(np.searchsorted(end_s, drift.t0_s, side="right"), n - 1))   # the segment the drift starts in
    return Change(recording=case.name, parameter=hyp.key, unit=hyp.unit, before=drift.before, after=drift.after,
                  at_s=drift.t0_s, between_s=(drift.t0_s, drift.t1_s), line=_line_of(case, int(seg.anchors[k])),
                  segment=k, error_single_pct=err_single, error_change_pct=err_change,
                  held_out_gain=float(gain), single_value=v0,
                  shape="drift" if drift.shape == "line" else "approach", until_s=drift.t1_s, tau_s=drift.tau_s,
                  motion_end_s=float(end_s[-1]),
                  open_start=bool(drift.t0_s < float(end_s[0])),          # no whole segment before it
                  open_end=bool(drift.t1_s > float(start_s[-1])))          # ... nor after it


def _line_of(case: Any, block: int) -> int | None:
    blocks = case.alignment.blocks
    if block < 0 or "line" not in blocks.columns:
        return None
    hit = blocks.loc[blocks["block"].to_numpy() == block, "line"]
    return int(hit.iloc[0]) if len(hit) else None
