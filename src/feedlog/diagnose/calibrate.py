"""Calibrating a machine from a generic profile: every axis limit the recordings constrain, and what they do not.

`calibrate(profile, cases, evidence)` fits the velocity and acceleration limit of every axis the
recordings move, all at once (`joint.joint_fit`, bounded least squares on the segment times), from
where the data points (each axis' sustained peak speed and acceleration, `evidence`) rather than from
the generic guess: a limit far above what a recording needs has no gradient to follow. Then, per
parameter, the values the recordings allow: a profile likelihood with the other parameters at their
fitted values, `n log(L / L*) <= CHI2` (95 %, one parameter; n segments, L* the fitted loss or the
noise floor if larger), scanned outwards on the parameter's log scale, widened to the Gauss-Newton
interval (+- 1.96 standard errors of the joint fit, `joint.spread`: there the other parameters follow,
so two limits fitted on the same moves widen each other's). A parameter is *constrained*
when the interval closes on both sides within the search bounds; one the recordings only bound from
below (an axis that never reached its limit) keeps the larger of the profile's value and that bound,
and is reported as not constrained. An axis whose velocity and acceleration limit trade off along a
ridge (`ridge.py`: a faster Z with a slower acceleration fits five-axis recordings as well) is reported
as a pair, neither constrained alone, with the ridge's ends and the calibration air-cut that separates
them; the Gauss-Newton widening is taken over the limits the scan closed in off any ridge. Every
recording is also held out in turn (the joint fit on the others, scored on it), so the gain is judged on
data the fit did not see.

The result goes into the written profile as its `[coverage]` table (`feedlog.coverage`), which `feedlog
sim` checks a program against; `feedlog program --calibration` writes the air-cut program for what is
missing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from feedlog import coverage as cov
from feedlog.diagnose import keys
from feedlog.diagnose.cases import Case
from feedlog.diagnose.evidence import Evidence
from feedlog.diagnose.fit import Scorer
from feedlog.diagnose.hypothesis import Hypothesis, family
from feedlog.diagnose.joint import joint_fit, spread
from feedlog.diagnose.ridge import Pair, ridges
from feedlog.diagnose.separate import separating_program
from feedlog.profile import MachineProfile

CHI2 = 3.84                     # 95 % for one parameter
SCAN = (1.02, 1.05, 1.1, 1.2, 1.4, 1.7, 2.2, 3.0, 5.0, 8.0, 13.0, 20.0, 30.0)   # factors scanned outwards
Z95 = 1.96                      # the Gauss-Newton interval: +- this many standard errors
SEED_ABOVE = 1.02               # start a limit just above the sustained peak seen (it is at least that)


@dataclass
class Parameter:
    key: str
    profile_value: float
    fitted_value: float
    constrained: bool
    interval: tuple[float | None, float | None]     # None: open on that side (the search bound reached)
    pair: str | None = None                          # the limit it trades off against (`ridge`): the pair is
    # pinned, each alone is not; `interval` is then the ridge's extent

    def as_dict(self) -> dict[str, Any]:
        return {"parameter": self.key, "profile_value": self.profile_value, "fitted_value": self.fitted_value,
                "constrained": self.constrained, "interval": list(self.interval),
                **({"pair": self.pair} if self.pair else {})}


@dataclass
class Calibration:
    profile: MachineProfile                         # the calibrated profile, with its [coverage]
    parameters: list[Parameter]
    axes: dict[str, dict[str, Any]]                 # observed per axis (coverage.axes)
    held_out: list[dict[str, Any]] = field(default_factory=list)   # per recording: error before / after (%)
    pairs: list[Pair] = field(default_factory=list)                 # limits the recordings cannot tell apart

    def as_dict(self) -> dict[str, Any]:
        return {"parameters": [p.as_dict() for p in self.parameters], "axes": self.axes,
                "held_out": self.held_out, "pairs": [r.as_dict() for r in self.pairs]}

    @property
    def unconstrained(self) -> list[str]:
        return [p.key for p in self.parameters if not p.constrained]


def observed(cases: Sequence[Case], ev: Evidence, profile: MachineProfile) -> dict[str, dict[str, Any]]:
    """Per moving axis: sustained peak speed and acceleration seen, longest programmed move."""
    moves: dict[str, float] = {}
    for c in cases:
        for a, d in cov.move_lengths(c.program.blocks, profile.axis_names).items():
            moves[a] = max(moves.get(a, 0.0), d)
    out = {}
    for a, e in ev.axes.items():
        if e.travel <= 0:
            continue
        row = {"vel_observed": round(e.peak_vel, 4), "move_max": round(moves.get(a, 0.0), 4)}
        if e.peak_acc is not None:
            row["acc_observed"] = round(e.peak_acc, 2)
        out[a] = row
    return out


def _start(hyp: Hypothesis, ev: Evidence) -> float:
    axis, limit = hyp.key.split(".")[1:]
    e = ev.axes.get(axis)
    seen = None if e is None else (e.peak_vel if limit == "vel_max" else e.peak_acc)
    if seen is None or not np.isfinite(seen) or seen <= 0:
        return float(hyp.baseline)
    return float(min(max(seen * SEED_ABOVE, hyp.lower), hyp.upper))


def _interval(scorer: Scorer, model: dict[str, Any], hyp: Hypothesis, n: float) -> tuple[float | None, float | None]:
    """The profile-likelihood interval of `hyp` with the others at `model`: None on a side where the scan
    reached the search bound without the loss crossing the threshold."""
    v0 = float(model[hyp.key])
    best = max(float(scorer.unit_losses(model).sum()), float(scorer.floor.sum()), 1e-300)
    limit = best * np.exp(CHI2 / n)
    ends: list[float | None] = []
    for sign in (-1, 1):
        prev_v, prev_l, end = v0, best, None
        for f in SCAN:
            v = v0 * f ** sign
            if not hyp.lower <= v <= hyp.upper:
                break
            loss = float(scorer.unit_losses({**model, **hyp.values(v)}).sum())
            if loss > limit:  # crossed: interpolate on log value against log loss
                w = (np.log(limit) - np.log(prev_l)) / (np.log(loss) - np.log(prev_l)) if loss > prev_l else 1.0
                end = float(np.exp(np.log(prev_v) + w * (np.log(v) - np.log(prev_v))))
                break
            prev_v, prev_l = v, loss
        ends.append(end)
    return ends[0], ends[1]


def _widen(hyp: Hypothesis, value: float, scan: tuple[float | None, float | None],
           sigma: float) -> tuple[float | None, float | None]:
    """The scanned interval (the others held) widened to +- Z95 Gauss-Newton standard errors (the others
    free to follow): a side stays open where either is open or reaches the search bound."""
    lo, hi = scan
    if not np.isfinite(sigma):
        return lo, None if hi is None else None
    if hyp.scale == "log":  # (a spread beyond e^50 is open either way: no overflow warning)
        g_lo, g_hi = value * np.exp(-min(Z95 * sigma, 50.0)), value * np.exp(min(Z95 * sigma, 50.0))
    else:
        span = hyp.upper - hyp.lower
        g_lo, g_hi = value - Z95 * sigma * span, value + Z95 * sigma * span
    lo = None if lo is None or g_lo <= hyp.lower else min(lo, float(g_lo))
    hi = None if hi is None or g_hi >= hyp.upper else max(hi, float(g_hi))
    return lo, hi


def calibrate(profile: MachineProfile, cases: Sequence[Case], ev: Evidence, *, min_segment_s: float | None = None,
              progress=None) -> Calibration:
    """Every axis limit of `profile` the recordings can speak to, fitted together; coverage per parameter."""
    say = progress or (lambda _m: None)
    scorer = Scorer(profile, cases, "timing", min_segment_s=min_segment_s)
    hyps = family("axis_limits").candidates(profile, cases)
    start = {h.key: _start(h, ev) for h in hyps}
    say(f"calibrating {len(hyps)} axis limits together on {len(cases)} recording(s)")
    model = joint_fit(scorer, start, hyps)
    n = float(sum(w.sum() for w in scorer.weights))
    scans = {h.key: _interval(scorer, model, h, n) for h in hyps}
    closed = [h for h in hyps if None not in scans[h.key]]
    say("looking for pairs of limits the recordings cannot tell apart")
    found = ridges(scorer, model, closed, n, scans)
    for r in found:  # a velocity free along its ridge on its own: its scan widened to the ridge's ends
        if not r.trade_off:
            key = r.keys[0]
            lo, hi = scans[key]
            scans[key] = (None if r.open_ends[0] else min(lo, r.low[key]), None if r.open_ends[1] else max(hi, r.high[key]))
    pairs = [r for r in found if r.trade_off]
    closed = [h for h in hyps if None not in scans[h.key]]
    on_ridge = {k: r for r in pairs for k in r.keys}
    # the Gauss-Newton spread of the limits the scan closed in, off any ridge: a limit whose loss stays
    # flat above it (a velocity never reached) or a pair on a ridge makes J'J singular and blows up the
    # spread of every limit fitted beside it (a Z pair fitted on its ridge, 351.6 / 39.3 for 350 / 40,
    # was reported open on both sides and replaced by generic-xyzac's 2000 / 250)
    sigma = spread(scorer, model, [h for h in closed if h.key not in on_ridge])
    params = []
    for h in hyps:
        value = float(model[h.key])
        ridge = on_ridge.get(h.key)
        if ridge is not None:  # jointly pinned, each alone not: the fitted point of the ridge, its ends
            ends = (ridge.low[h.key], ridge.high[h.key])
            params.append(Parameter(key=h.key, profile_value=float(h.baseline), fitted_value=value,
                                    constrained=False, interval=(min(ends), max(ends)),
                                    pair=next(k for k in ridge.keys if k != h.key)))
            continue
        lo, hi = _widen(h, value, scans[h.key], sigma.get(h.key, float("inf")))
        constrained = lo is not None and hi is not None
        if hi is None:  # bounded from below only: the limit never bound and the fit's value is arbitrary
            # (on LinuxCNC recordings an X limit drifted to the search bound): the profile's, or the bound
            value = max(float(h.baseline), lo) if lo is not None else float(h.baseline)
        params.append(Parameter(key=h.key, profile_value=float(h.baseline), fitted_value=value,
                                constrained=constrained, interval=(lo, hi)))
    final = {p.key: p.fitted_value for p in params}
    axes = observed(cases, ev, profile)
    medians = [cov.median_move(c.program.blocks) for c in cases]
    coverage = {"format_version": cov.FORMAT_VERSION, "recordings": [c.source for c in cases], "axes": axes,
                "blocks": {"median_move_min": round(min(medians), 4)},
                "parameters": {p.key: {"constrained": p.constrained,
                                       "interval": [x for x in p.interval if x is not None] if p.constrained else
                                       [p.interval[0] if p.interval[0] is not None else h.lower,
                                        p.interval[1] if p.interval[1] is not None else h.upper],
                                       **({"pair": p.pair} if p.pair else {})}
                               for p, h in zip(params, hyps)}}
    fitted = keys.with_values(profile, final, name=f"{profile.name}-calibrated")
    fitted = replace(fitted, coverage=coverage)
    for r in pairs:  # the air-cut whose time differs most between the ridge's two ends
        r.separated_by = separating_program(fitted, r.low, r.high)
    cal = Calibration(profile=fitted, parameters=params, axes=axes, pairs=pairs)
    cal.held_out = _held_out(scorer, start, hyps, final)
    return cal


def _held_out(scorer: Scorer, start: dict[str, Any], hyps: Sequence[Hypothesis],
              final: dict[str, Any]) -> list[dict[str, Any]]:
    """Each recording scored with the limits fitted on the others (cycle time error, %)."""
    if len(scorer.groups) < 2:
        return []
    out = []
    for group in scorer.groups:
        rest = [j for j in range(len(scorer.units)) if j not in group]
        model = joint_fit(scorer, start, hyps, rest)
        case = scorer.cases[scorer.units[group[0]].case]
        out.append({"recording": case.name, "error_before_pct": _cycle_error(scorer, {}, group),
                    "error_after_pct": _cycle_error(scorer, model, group),
                    "error_all_pct": _cycle_error(scorer, final, group)})
    return out


def _cycle_error(scorer: Scorer, values: dict[str, Any], group: list[int]) -> float:
    """Simulated minus measured time of the units' segments, as a share of the measured (%)."""
    res = scorer.residuals(values)
    sim = meas = 0.0
    for j in group:
        u = scorer.units[j]
        r = res[u.case]
        m = scorer.segments[u.case].measured_s[u.lo:u.hi]
        sim += float(np.sum(r[u.lo:u.hi])) if r is not None else np.nan
        meas += float(np.sum(m))
    return round(100.0 * sim / meas, 3) if meas > 0 else float("nan")
