"""Choosing causes honestly: greedy forward selection judged on held-out data.

At each step every remaining hypothesis of the level is screened on a grid (in-sample), the most
promising ones are fitted without each held-out unit and scored on it (`fit.held_out`), and the best
is accepted only if all of these hold:

- **penalty per parameter**: it removes at least `min_gain` of the held-out loss that remains above
  the noise floor (a cause must pay for its parameter; 20 % by default). The floor is what the data
  itself allows: a perfect model still misses every measured block boundary by the sampling
  resolution (a period / sqrt(12)) and every feedback position by its noise at rest;
- **material**: the level's held-out error drops by at least `min_effect` (timing: 1 percentage
  point of the time the recordings take; feedback: 1 um or twice the noise of the feedback at rest,
  whichever is larger), or a held-out error of at least that is halved: below that the profile
  already explains the data within the simulation's own accuracy, and a faithful recording gives no
  finding;
- **repeatable**: it helps every held-out unit whose error is material (two or three units), or its
  mean relative gain stands two standard errors above zero (four or more): a gain that does not
  repeat across recordings (or stretches of one) is noise;
- **harmless**: no recording's held-out error grows by `min_effect` (a global parameter fitted to what
  one recording does differently must not be "found" at the others' expense);
- **not contradicted** by the evidence the data gives without any simulation
  (its family's `contradicts`, beside the family in its `hyp_*.py`);
- **enough data**: the level holds at least the hypothesis' minimum (`Hypothesis.needs`: 8 segments or
  blocks, 1000 feedback samples) over `MIN_SECONDS` (5 s) of motion; `engine` refuses the whole
  diagnosis when no level has that much.

The best is the one with the least held-out loss; among accepted candidates of its family whose
held-out losses lie closer than noise alone moves them (`noise_spread`), the one that fits all the data
best (`rank`).
Hypotheses whose held-out loss is within `tie` of the best are reported as equally good
alternatives (a program that moves Z only in rapids cannot tell a Z velocity limit from a rapid
override); the primary is the one of the family of the lowest `Family.rank` (the operator's dials,
then the machine's own limits, then planner settings, dwells, feedback and the logger). Accepted values are then refitted in turn
given each other (coordinate descent), so two simultaneous causes do not bias one another.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from feedlog.diagnose.evidence import Evidence
from feedlog.diagnose.fit import HeldOut, Scorer, _grid, fit, held_out, refine
from feedlog.diagnose.hypothesis import MIN_SECONDS, Hypothesis, family

SCREEN_KEEP = 5        # hypotheses fully cross-validated per step
SCREEN_SHARE = 0.5     # ... among those within this share of the best screening gain
SCREEN_POINTS = 9      # grid points per hypothesis when screening
SCREEN_ITER = 5        # ... then Brent iterations between the best point's neighbours (a small effect falls between)
FOLD_SHARE = 0.05      # a held-out fold must hold this share of the excess loss to count for repeatability
SWAP_GAIN = 0.2        # a replacement must lower the held-out loss by this share
HALVES = 0.5           # ... or a material error brought down to this share of itself counts as material too


@dataclass(frozen=True)
class SelectConfig:
    min_gain: float = 0.2          # share of the remaining held-out loss a cause must remove
    min_effect: float = 1.0        # level error units (timing: percentage points; feedback: mm)
    z: float = 2.0                 # standard errors for repeatability with four or more units
    tie: float = 0.05              # held-out losses within this share of the best are ties
    max_causes: int = 3
    refit_rounds: int = 2


@dataclass
class Judged:
    """One hypothesis at one step: its held-out result, errors and the decision."""

    held: HeldOut
    error_before: float
    error_after: float
    veto: str | None = None
    reasons: list[str] = field(default_factory=list)

    @property
    def accepted(self) -> bool:
        return not self.reasons

    @property
    def key(self) -> str:
        return self.held.hyp.key


@dataclass
class Step:
    chosen: Judged
    alternatives: list[Judged]
    considered: list[Judged]


@dataclass
class Selection:
    level: str
    model: dict[str, Any]
    steps: list[Step]
    rejected: list[Judged]          # the best candidates of the step that stopped the search
    base_losses: np.ndarray
    final_losses: np.ndarray        # per unit, held-out (each step's fold values)


def _priority(hyp: Hypothesis) -> int:
    return family(hyp.family).rank


def noise_spread(scorer: Scorer) -> float:
    """How much a level's summed loss varies from measurement noise alone: a perfect model's loss is a sum
    of n squared errors of variance v (the floor, n v), whose standard deviation is sqrt(2 n) v."""
    n = float(sum(w.sum() for w in scorer.weights)) if scorer.level == "timing" else float(
        sum(u.hi - u.lo for u in scorer.units))
    floor = float(scorer.floor.sum())
    return floor * np.sqrt(2.0 / n) if n > 0 and np.isfinite(floor) else 0.0


def rank(judged: list[Judged], spread: float) -> list[Judged]:
    """Candidates best first: the least held-out loss, without a veto. Within one family (the same
    limit on different axes: one form, one parameter each) held-out losses closer than the noise
    `spread` do not tell the candidates apart (each recording held out fits a value from the few
    others, and noise moves that); there the one that fits all the data best goes first, the
    lower-variance criterion for causes of one form. Across families the held-out loss stays the judge:
    a different form generalises differently (an X acceleration limit fitted to what all axes do)."""
    out = sorted(judged, key=lambda j: (j.veto is not None, float(j.held.after.sum())))
    if not out or out[0].veto is not None or not out[0].accepted or spread <= 0:
        return out
    low, family = float(out[0].held.after.sum()), out[0].held.hyp.family
    near = [j for j in out if j.veto is None and j.accepted and j.held.hyp.family == family
            and float(j.held.after.sum()) <= low + spread]
    lead = min(near, key=lambda j: float(j.held.fit_after.sum()))
    return [lead, *(j for j in out if j is not lead)]


def screen(scorer: Scorer, model: dict[str, Any], hyps: Sequence[Hypothesis]) -> list[tuple[Hypothesis, float]]:
    """The hypotheses worth a full held-out fit, with their best in-sample loss (all units): a clear
    gain over `model`, within `SCREEN_SHARE` of the best gain, the most promising first."""
    floor = float(scorer.floor.sum())
    base = float(scorer.unit_losses(model).sum()) - floor
    scored = []
    for hyp in hyps:
        if scorer.level == "timing":  # a coarse grid, refined a little: every point re-simulates every recording
            def loss(v: Any, hyp: Hypothesis = hyp) -> float:
                return float(scorer.unit_losses({**model, **hyp.values(v)}).sum())

            grid = _grid(hyp, SCREEN_POINTS)
            best = refine(hyp, loss, grid, np.array([loss(v) for v in grid]), SCREEN_ITER)[1]
        else:  # no simulation: the full fit is cheap
            best = fit(scorer, model, hyp, range(len(scorer.units))).loss
        gain = (base + floor - best) / base if base > 0 and np.isfinite(best) else 0.0
        scored.append((gain, best, hyp))
    scored.sort(key=lambda s: -s[0])
    if not scored or scored[0][0] <= 0:
        return []
    top = scored[0][0]
    return [(h, best) for g, best, h in scored if g > 0 and g >= SCREEN_SHARE * top][:SCREEN_KEEP]


def judge(held: HeldOut, scorer: Scorer, cfg: SelectConfig, error: Callable[[np.ndarray, list[int]], float],
          evidence: Evidence | None) -> Judged:
    units = list(range(len(scorer.units)))
    j = Judged(held=held, error_before=error(held.before, units), error_after=error(held.after, units))
    short = too_little_data(scorer, held.hyp.needs)
    if short:
        j.reasons.append(short)
    if evidence is not None and held.hyp.baseline is not None:
        j.veto = family(held.hyp.family).contradicts(evidence, held.hyp.key, held.hyp.baseline, held.value)
        if j.veto:
            j.reasons.append(f"contradicted by the data: {j.veto}")
    if held.gain < cfg.min_gain:
        j.reasons.append(f"removes {100 * held.gain:.1f} % of the held-out loss (needs {100 * cfg.min_gain:.0f} %)")
    if j.error_before - j.error_after < cfg.min_effect and not (
            j.error_before >= cfg.min_effect and j.error_after <= HALVES * j.error_before):
        j.reasons.append(f"held-out error {j.error_before:.4g} -> {j.error_after:.4g}: less than the "
                         f"{cfg.min_effect:g} that counts")
    why = _repeatability(held, units, cfg, error)
    if why:
        j.reasons.append(why)
    harm = _harm(held, scorer, cfg, error)
    if harm:
        j.reasons.append(harm)
    return j


def too_little_data(scorer: Scorer, needs: int) -> str | None:
    """Why the level's data is too little for a cause that needs `needs` of its units (None when it is not)."""
    if scorer.data_size >= needs and scorer.data_s >= MIN_SECONDS:
        return None
    return (f"too little data: {scorer.data_size} {scorer.data_unit} ({scorer.data_s:.2f} s of motion), needs "
            f"{needs} {scorer.data_unit} and {MIN_SECONDS:g} s")


def _harm(held: HeldOut, scorer: Scorer, cfg: SelectConfig,
          error: Callable[[np.ndarray, list[int]], float]) -> str | None:
    """A cause must not make a recording materially worse on held-out data: a global parameter fitted
    to what one recording does differently would otherwise be 'found' at the others' expense."""
    worse = []
    for group in scorer.groups:
        before, after = error(held.before, group), error(held.after, group)
        if after - before >= cfg.min_effect:
            worse.append(f"{scorer.cases[scorer.units[group[0]].case].name} {before:.3g} -> {after:.3g}")
    return f"makes a recording worse on held-out data ({'; '.join(worse)})" if worse else None


def _repeatability(held: HeldOut, units: list[int], cfg: SelectConfig,
                   error: Callable[[np.ndarray, list[int]], float]) -> str | None:
    """None when the held-out gain repeats across the held-out folds that carry the residual: every
    such fold gains (two or three of them), or their mean relative gain stands `z` standard errors above
    zero (four or more). A fold carries the residual when its own error is material and it holds at
    least `FOLD_SHARE` of the excess loss (a stretch with almost nothing to explain says nothing)."""
    folds = held.extra.get("folds_units") or [[u] for u in units]
    floor = held.floor if held.floor is not None else np.zeros(len(held.before))
    total = float(held.before.sum() - floor.sum())
    rel = []
    for fold in folds:
        excess = float(held.before[fold].sum() - floor[fold].sum())
        if total <= 0 or excess < FOLD_SHARE * total or error(held.before, fold) < cfg.min_effect:
            continue
        rel.append(float(held.before[fold].sum() - held.after[fold].sum()) / excess)
    if len(rel) <= 1:
        return None
    rel_a = np.array(rel)
    if len(rel_a) <= 3:
        if (rel_a <= 0).any():
            return f"does not help every held-out part (relative gains {', '.join(f'{100 * r:.0f} %' for r in rel_a)})"
        return None
    se = float(rel_a.std(ddof=1) / np.sqrt(len(rel_a)))
    if rel_a.mean() - cfg.z * se <= 0:
        return f"held-out gain does not repeat (mean {100 * rel_a.mean():.0f} % +- {100 * se:.0f} %)"
    return None


def select(scorer: Scorer, hyps: Sequence[Hypothesis], *, error: Callable[[np.ndarray, list[int]], float],
           evidence: Evidence | None = None, cfg: SelectConfig | None = None,
           progress: Callable[[str], None] | None = None,
           held_out_many: Callable[[dict[str, Any], Sequence[Hypothesis]], list[HeldOut]] | None = None) -> Selection:
    """Greedy forward selection of causes on one level. `held_out_many(model, hyps)` runs the held-out fits
    of one step (default: here, one after another; `feedlog.diagnose.parallel` runs them as tasks)."""
    cfg = cfg or SelectConfig()
    many = held_out_many or (lambda model, pool: [held_out(scorer, model, h) for h in pool])
    model: dict[str, Any] = {}
    steps: list[Step] = []
    rejected: list[Judged] = []
    base = scorer.unit_losses({})
    current = base
    remaining = list(hyps)
    units = list(range(len(scorer.units)))
    while len(steps) < cfg.max_causes and remaining and scorer.units:
        if error(current, units) < cfg.min_effect:
            break  # what remains is below what a cause must remove
        pool = [h for h, _ in screen(scorer, model, remaining)]
        if progress:
            progress(f"{scorer.level}: step {len(steps) + 1}, {len(pool)} of {len(remaining)} hypotheses cross-validated")
        judged = rank([judge(held, scorer, cfg, error, evidence) for held in many(model, pool)], noise_spread(scorer))
        if not judged:
            break
        best = judged[0]
        if not best.accepted and len(steps) + 2 <= cfg.max_causes:
            pair = _pair(scorer, model, judged, remaining, cfg, error, evidence, many, progress)
            if pair is not None:
                model, new = pair
                steps.extend(new)
                current = new[-1].chosen.held.after
                taken = {k for st in new for k in st.chosen.held.hyp.keys}
                remaining = [h for h in remaining if not (h.keys & taken)]
                continue
        ties = [j for j in judged[1:] if j.veto is None and
                float(j.held.after.sum()) <= float(best.held.after.sum()) * (1 + cfg.tie) + 1e-300]
        group = sorted([best, *ties], key=lambda j: (_priority(j.held.hyp), judged.index(j)))
        chosen = group[0]
        if not best.accepted:
            rejected = judged
            break
        if not chosen.accepted:
            chosen = best
        steps.append(Step(chosen=chosen, alternatives=[j for j in group if j is not chosen and j.accepted],
                          considered=judged))
        model.update(chosen.held.hyp.values(chosen.held.value))
        current = chosen.held.after
        if len(steps) > 1:  # the causes so far at their joint values before looking for another
            model = _refit(scorer, [s.chosen.held.hyp for s in steps], model, 1)
            current = np.minimum(current, scorer.unit_losses(model))
        remaining = [h for h in remaining if h.key != chosen.key]
    refit = _refit(scorer, [s.chosen.held.hyp for s in steps], model, cfg.refit_rounds)
    if len(steps) > 1:  # each cause judged again with the others at their refitted values
        refit = _rejudged(scorer, steps, refit, cfg, error, evidence)
        refit = _rechoose(scorer, steps, refit, cfg, error, evidence, many, progress)
        if error(scorer.unit_losses(refit), units) >= cfg.min_effect:  # something material left: try swaps
            refit = _swap(scorer, steps, refit, hyps, cfg, error, evidence, progress)
        current = scorer.unit_losses(refit)
    return Selection(level=scorer.level, model=refit, steps=steps, rejected=rejected, base_losses=base,
                     final_losses=current)


def _pair(scorer: Scorer, model: dict[str, Any], judged: list[Judged], remaining: Sequence[Hypothesis],
          cfg: SelectConfig, error: Callable[[np.ndarray, list[int]], float], evidence: Evidence | None,
          many: Callable[[dict[str, Any], Sequence[Hypothesis]], list[HeldOut]],
          progress: Callable[[str], None] | None) -> tuple[dict[str, Any], list[Step]] | None:
    """One step of look-ahead when no single cause survives its held-out test. With two causes in the
    data, the fit of the first on part of it can carry the second and spoil the rest (a path speed cap,
    fitted on recordings whose rapids a Z acceleration limit slows, comes out far too low for a program
    that reaches the cap on its feed moves). So the candidate that fits all the data best is put in
    provisionally, the next cause is looked for given it, and the two are kept only if each then passes
    every rule held out given the other (refitted together first). Otherwise nothing is kept."""
    lead = sorted((j for j in judged if j.veto is None), key=lambda j: float(j.held.fit_after.sum()))
    if not lead or error(lead[0].held.before, list(range(len(scorer.units)))) < cfg.min_effect:
        return None
    first = lead[0].held
    trial = {**model, **first.hyp.values(first.value)}
    pool = [h for h, _ in screen(scorer, trial, [h for h in remaining if not (h.keys & first.hyp.keys)])]
    if not pool:
        return None
    if progress:
        progress(f"{scorer.level}: no single cause holds out; {len(pool)} second causes tried with {first.hyp.key}")
    second = [j for j in (judge(held, scorer, cfg, error, evidence) for held in many(trial, pool)) if j.accepted]
    if not second:
        return None
    pick = min(second, key=lambda j: float(j.held.after.sum()))
    hyps = [first.hyp, pick.held.hyp]
    joint = _refit(scorer, hyps, {**trial, **pick.held.hyp.values(pick.held.value)}, 2)
    steps = []
    for hyp, considered in zip(hyps, (judged, second)):
        others = {k: v for k, v in joint.items() if k not in hyp.keys}
        j = judge(held_out(scorer, others, hyp), scorer, cfg, error, evidence)
        if not j.accepted:
            return None
        steps.append(Step(chosen=j, alternatives=[], considered=considered))
    return joint, steps


def _rechoose(scorer: Scorer, steps: list[Step], model: dict[str, Any], cfg: SelectConfig,
              error: Callable[[np.ndarray, list[int]], float], evidence: Evidence | None,
              many: Callable[[dict[str, Any], Sequence[Hypothesis]], list[HeldOut]],
              progress: Callable[[str], None] | None) -> dict[str, Any]:
    """Each step's choice made again given the other causes: the candidates its step cross-validated
    are judged with the others in the model, and the same rule picks (the least held-out loss; ties to
    family of the lowest rank). A cause chosen before a second one was in the model can
    have stood in for part of it (a path speed cap taking an acceleration limit's time on rapids next
    to a feed override's on feed moves); with the second in place the first choice is no longer best."""
    changed = False
    for i, step in enumerate(steps):
        hyp = step.chosen.held.hyp
        taken = {k for s in steps if s is not step for k in s.chosen.held.hyp.keys}
        pool = [j.held.hyp for j in step.considered
                if j.veto is None and j.held.hyp.key != hyp.key and not (j.held.hyp.keys & taken)]
        if not pool:
            continue
        others = {k: v for k, v in model.items() if k not in hyp.keys}
        if progress:
            progress(f"{scorer.level}: {len(pool)} alternative(s) to {hyp.key} judged with the other causes")
        judged = [step.chosen, *(judge(held, scorer, cfg, error, evidence) for held in many(others, pool))]
        ok = rank([j for j in judged if j.accepted], noise_spread(scorer))
        if not ok:
            continue
        top = float(ok[0].held.after.sum())
        group = [j for j in ok if float(j.held.after.sum()) <= top * (1 + cfg.tie) + 1e-300]
        pick = min(group, key=lambda j: (_priority(j.held.hyp), ok.index(j)))
        if pick is not step.chosen:
            steps[i] = Step(chosen=pick, alternatives=[j for j in group if j is not pick],
                            considered=[step.chosen, *step.considered])
            model = {**others, **pick.held.hyp.values(pick.held.value)}
            changed = True
    if not changed:
        return model
    return _rejudged(scorer, steps, _refit(scorer, [s.chosen.held.hyp for s in steps], model, 2), cfg, error,
                     evidence)


def _swap(scorer: Scorer, steps: list[Step], model: dict[str, Any], hyps: Sequence[Hypothesis], cfg: SelectConfig,
          error: Callable[[np.ndarray, list[int]], float], evidence: Evidence | None,
          progress: Callable[[str], None] | None) -> dict[str, Any]:
    """Forward selection with swaps: each accepted cause is taken out in turn and every other candidate
    tried in its place, given the rest; one that does better on held-out data (by `SWAP_GAIN` of the
    loss) replaces it. A greedy first step can take one parameter that stands in for two true ones
    (a path acceleration cap for an X acceleration limit next to a Y velocity limit)."""
    chosen = {s.chosen.key for s in steps}
    for i, step in enumerate(steps):
        hyp = step.chosen.held.hyp
        others = {k: v for k, v in model.items() if k not in hyp.keys}
        in_sample = float(scorer.unit_losses(model).sum())
        # a replacement can only beat the cause on held-out data if it beats it in sample first
        pool = [h for h, _ in screen(scorer, others, [h for h in hyps if h.key not in chosen]) if h.key != hyp.key]
        pool = [h for h in pool if fit(scorer, others, h, range(len(scorer.units))).loss < in_sample * (1 - SWAP_GAIN)]
        if progress:
            progress(f"{scorer.level}: trying {len(pool)} replacement(s) for {hyp.key}")
        best = step.chosen
        for h in pool:
            j = judge(held_out(scorer, others, h), scorer, cfg, error, evidence)
            if j.accepted and float(j.held.after.sum()) < float(best.held.after.sum()) * (1 - SWAP_GAIN):
                best = j
        if best is not step.chosen:
            chosen = (chosen - {hyp.key}) | {best.key}
            steps[i] = Step(chosen=best, alternatives=[], considered=[step.chosen, *step.considered])
            model = {**others, **best.held.hyp.values(best.held.value)}
    return _rejudged(scorer, steps, _refit(scorer, [s.chosen.held.hyp for s in steps], model, 2), cfg, error,
                     evidence)


def _rejudged(scorer: Scorer, steps: list[Step], model: dict[str, Any], cfg: SelectConfig,
              error: Callable[[np.ndarray, list[int]], float], evidence: Evidence | None) -> dict[str, Any]:
    """Each step's cause judged again, held out, given the others at their values in `model`."""
    for step in steps:
        hyp = step.chosen.held.hyp
        others = {k: v for k, v in model.items() if k not in hyp.keys}
        step.chosen = judge(held_out(scorer, others, hyp), scorer, cfg, error, evidence)
    return model


def _refit(scorer: Scorer, hyps: list[Hypothesis], model: dict[str, Any], rounds: int) -> dict[str, Any]:
    """Each accepted value refitted on all units given the others (coordinate descent)."""
    if len(hyps) < 2:
        return dict(model)
    model = dict(model)
    units = range(len(scorer.units))
    for _ in range(rounds):
        for hyp in hyps:
            others = {k: v for k, v in model.items() if k not in hyp.keys}
            model.update(hyp.values(fit(scorer, others, hyp, units).value))
    return model
