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
segments. It says when (the measured time of the boundary, from motion start, the segment it ends and
the program line), from what, to what, and what one value would have been. The averaged finding of the
same parameter is not reported, and the extended profile keeps the profile's value for it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from feedlog.diagnose.fit import Scorer, _grid, refine
from feedlog.diagnose.hypothesis import Hypothesis

CHANGING = ("sim.feed_override.override", "sim.rapid_override.override")
MIN_SIDE = 4          # segments on each side of a change at least
REFINE_ITER = 12


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
    segment: int                 # index of the first segment after the change
    error_single_pct: float      # the recording's timing error with one value for the whole session
    error_change_pct: float      # ... with the change
    held_out_gain: float         # share of the held-out loss (odd segments) removed against one value
    single_value: float          # the one value the whole session would be averaged into

    def as_dict(self) -> dict[str, Any]:
        return {"recording": self.recording, "parameter": self.parameter, "unit": self.unit,
                "before": self.before, "after": self.after, "at_s": self.at_s, "between_s": list(self.between_s),
                "line": self.line, "segment": self.segment, "error_single_pct": self.error_single_pct,
                "error_change_pct": self.error_change_pct, "held_out_gain": self.held_out_gain,
                "single_value": self.single_value}

    def text(self) -> str:
        where = f" (program line {self.line})" if self.line is not None else ""
        return (f"change during {self.recording}: {self.parameter} {self.before:.4g} -> {self.after:.4g} "
                f"{self.unit} at {self.at_s:.2f} s{where}, not one value ({self.single_value:.4g}): "
                f"timing error {self.error_single_pct:.2f} % -> {self.error_change_pct:.2f} %").replace("  ", " ")


def _best_split(sq: np.ndarray, use: np.ndarray) -> tuple[int, float, float]:
    """(boundary m, loss of the best step at m, loss of the best single value) for squared residuals
    `sq` (grid, segments) counted where `use`."""
    s = sq * use
    cum = np.cumsum(s, axis=1)
    total = cum[:, -1]
    n = s.shape[1]
    best_m, best = -1, np.inf
    for m in range(MIN_SIDE, n - MIN_SIDE + 1):
        loss = float(cum[:, m - 1].min() + (total - cum[:, m - 1]).min())
        if loss < best:
            best_m, best = m, loss
    return best_m, best, float(total.min())


class _OneRecording:
    """Squared, weighted segment residuals of one recording for values of one hypothesis (cached)."""

    def __init__(self, scorer: Scorer, base: Mapping[str, Any], hyp: Hypothesis, case: int) -> None:
        self.scorer, self.base, self.hyp, self.case = scorer, dict(base), hyp, case
        self._cache: dict[float, np.ndarray] = {}

    def sq(self, v: float) -> np.ndarray:
        key = float(f"{v:.12g}")
        if key not in self._cache:
            r = self.scorer.case_residual(self.case, {**self.base, **self.hyp.values(key)})
            w = self.scorer.weights[self.case]
            self._cache[key] = np.full(len(w), np.inf) if r is None else w * np.square(r)
        return self._cache[key]

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


def _split(one: _OneRecording, rows: np.ndarray, grid: list[float], sq: np.ndarray) -> tuple[int, float, float]:
    """The boundary (an index into `rows`) and the two values fitted on the segments `rows`: the boundary
    from the grid, the values refined on their sides, the boundary found again with them."""
    use = np.zeros(sq.shape[1], bool)
    use[rows] = True
    m_all, _, _ = _best_split(np.where(np.isfinite(sq), sq, 1e30), use)
    if m_all < 0:
        return -1, np.nan, np.nan
    m = int(np.searchsorted(rows, m_all))
    v1 = v2 = np.nan
    for _ in range(2):
        if not MIN_SIDE // 2 <= m <= len(rows) - MIN_SIDE // 2:
            return -1, np.nan, np.nan
        v1, _ = one.best(rows[:m], grid, sq)
        v2, _ = one.best(rows[m:], grid, sq)
        a, b = one.sq(v1)[rows], one.sq(v2)[rows]
        cand = [(float(a[:k].sum() + b[k:].sum()), k) for k in range(1, len(rows))]
        m_new = min(cand)[1]
        if m_new == m:
            break
        m = m_new
    return m, v1, v2


def _judge(one: _OneRecording, grid: list[float], sq: np.ndarray, *, min_gain: float,
           min_effect_pct: float) -> Change | None:
    scorer, hyp, i = one.scorer, one.hyp, one.case
    n = sq.shape[1]
    rows = np.arange(n)
    even, odd = rows[rows % 2 == 0], rows[rows % 2 == 1]
    # held out: boundary and values from the even segments, scored on the odd ones, against one value
    m_e, a_e, b_e = _split(one, even, grid, sq)
    if m_e < 0:
        return None
    single_e, _ = one.best(even, grid, sq)
    at = even[m_e]                                   # the first segment after the change
    single_odd = float(one.sq(single_e)[odd].sum())
    change_odd = float(one.sq(a_e)[odd[odd < at]].sum() + one.sq(b_e)[odd[odd >= at]].sum())
    case = scorer.cases[i]
    floor_odd = float(scorer.weights[i][odd].sum()) * 2.0 * case.segment_sigma_s ** 2
    excess = single_odd - floor_odd
    gain = (single_odd - change_odd) / excess if excess > 0 else 0.0
    if gain < min_gain:
        return None
    # all segments: where, from what, to what
    m, v1, v2 = _split(one, rows, grid, sq)
    if m < MIN_SIDE or n - m < MIN_SIDE:
        return None
    v0, l0 = one.best(rows, grid, sq)
    l12 = float(one.sq(v1)[:m].sum() + one.sq(v2)[m:].sum())
    err_single, err_change = _error_pct(scorer, i, l0), _error_pct(scorer, i, l12)
    if err_single - err_change < min_effect_pct:
        return None
    seg = scorer.segments[i]
    start = float(seg.end_s[m - 2]) if m >= 2 else 0.0
    at_s = float(seg.end_s[m - 1])
    return Change(recording=case.name, parameter=hyp.key, unit=hyp.unit, before=v1, after=v2, at_s=at_s,
                  between_s=(start, at_s), line=_line_of(case, int(seg.anchors[m - 1])), segment=m,
                  error_single_pct=err_single, error_change_pct=err_change, held_out_gain=float(gain),
                  single_value=v0)


def _line_of(case: Any, block: int) -> int | None:
    blocks = case.alignment.blocks
    if block < 0 or "line" not in blocks.columns:
        return None
    hit = blocks.loc[blocks["block"].to_numpy() == block, "line"]
    return int(hit.iloc[0]) if len(hit) else None
