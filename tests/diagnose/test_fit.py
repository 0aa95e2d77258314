"""Fitting and holding out, on a scorer whose losses are known in closed form."""

from __future__ import annotations

import numpy as np
import pytest

from feedlog.diagnose.fit import Unit, fit, folds_for, held_out
from feedlog.diagnose.hypothesis import Hypothesis


class QuadraticScorer:
    """Unit u's loss: w_u (log v - log truth_u)^2 + floor; the hypothesis key is 'axes.x.acc_max'."""

    level = "timing"

    def __init__(self, truths, weights, groups):
        self.truths, self.weights = np.asarray(truths, float), np.asarray(weights, float)
        self.units = [Unit(g, 0, 1, f"u{i}") for i, g in enumerate(groups)]
        self.floor = np.full(len(truths), 1e-6)
        self.calls = 0

    @property
    def groups(self):
        out = {}
        for j, u in enumerate(self.units):
            out.setdefault(u.case, []).append(j)
        return list(out.values())

    def unit_losses(self, values):
        self.calls += 1
        v = values.get("axes.x.acc_max", 1000.0)
        return self.weights * (np.log(v) - np.log(self.truths)) ** 2 + self.floor

    def loss(self, values, units):
        return float(self.unit_losses(values)[list(units)].sum())


HYP = Hypothesis(key="axes.x.acc_max", family="axis_limits", lower=1000 / 30, upper=3000, baseline=1000.0)


def test_fit_finds_the_minimum_between_grid_points():
    sc = QuadraticScorer([317.0] * 3, [1, 1, 1], [0, 0, 0])
    f = fit(sc, {}, HYP, range(3))
    assert f.value == pytest.approx(317.0, rel=2e-3)
    assert f.evaluations < 60


def test_an_unconstrained_parameter_stays_where_the_profile_has_it():
    sc = QuadraticScorer([317.0] * 2, [0.0, 0.0], [0, 1])
    assert fit(sc, {}, HYP, range(2)).value == 1000.0


def test_held_out_scores_each_unit_with_a_value_fitted_without_it():
    sc = QuadraticScorer([300.0, 300.0, 330.0, 330.0], [1, 1, 1, 1], [0, 0, 1, 1])
    ho = held_out(sc, {}, HYP)
    assert ho.extra["scheme"] == "leave one recording out"
    # recording 0's units were scored with the value fitted on recording 1 alone, and the other way round
    assert ho.fold_values[0] == pytest.approx(330.0, rel=5e-3) and ho.fold_values[3] == pytest.approx(300.0, rel=5e-3)
    assert ho.interval[0] <= 300.0 * 1.01 and ho.interval[1] >= 330.0 * 0.99
    assert 0.9 < ho.gain <= 1.0


def test_a_recording_that_does_not_constrain_the_parameter_is_not_a_fold():
    sc = QuadraticScorer([300.0, 300.0, 300.0, 300.0], [1, 1, 0, 0], [0, 0, 1, 1])
    folds, scheme = folds_for(sc, {}, HYP)
    assert scheme == "held-out stretches" and folds == [[0], [1], [2], [3]]
    assert held_out(sc, {}, HYP).fold_values[0] == pytest.approx(300.0, rel=5e-3)


def test_integer_parameters_are_searched_as_integers():
    class IntScorer(QuadraticScorer):
        def unit_losses(self, values):
            v = values.get("interpolator.lookahead_blocks", 50)
            return np.array([(v - 7) ** 2 + 0.5, (v - 7) ** 2 + 0.5])

    hyp = Hypothesis(key="interpolator.lookahead_blocks", family="planner", lower=1, upper=400, scale="int", baseline=50)
    assert fit(IntScorer([1, 1], [1, 1], [0, 1]), {}, hyp, range(2)).value == 7


def _judged(key: str, family: str, held_after: float, fit_after: float):
    from feedlog.diagnose.fit import HeldOut
    from feedlog.diagnose.select import Judged

    hyp = Hypothesis(key=key, family=family, lower=1.0, upper=1000.0, baseline=500.0)
    held = HeldOut(hyp=hyp, value=100.0, fold_values=[100.0], before=np.array([1.0]), after=np.array([held_after]),
                   fit_after=np.array([fit_after]))
    return Judged(held=held, error_before=5.0, error_after=0.5)


def test_within_noise_one_family_is_ranked_by_its_fit_on_all_data_others_by_held_out_loss():
    from feedlog.diagnose.select import rank

    y = _judged("axes.y.acc_max", "axis_limits", 0.027, 0.0263)
    x = _judged("axes.x.acc_max", "axis_limits", 0.040, 0.0257)
    path = _judged("interpolator.path_acc_max_mm_s2", "path_limits", 0.035, 0.020)
    # the X limit's held-out loss is within the noise of Y's and it fits all the data better: it leads;
    # the path limit fits better still but is another form, judged on held-out loss
    assert [j.key for j in rank([y, x, path], spread=0.03)] == ["axes.x.acc_max", "axes.y.acc_max",
                                                                "interpolator.path_acc_max_mm_s2"]
    # beyond the noise the held-out loss decides alone
    assert [j.key for j in rank([y, x, path], spread=0.005)] == ["axes.y.acc_max", "interpolator.path_acc_max_mm_s2",
                                                                 "axes.x.acc_max"]
    # a candidate that failed its held-out test never leads by its fit
    x.reasons.append("does not help every held-out part")
    assert rank([y, x, path], spread=0.03)[0].key == "axes.y.acc_max"


def test_a_material_error_halved_counts_though_it_drops_by_less_than_one_point():
    from types import SimpleNamespace

    from feedlog.diagnose.fit import HeldOut
    from feedlog.diagnose.select import SelectConfig, judge

    scorer = SimpleNamespace(units=[0], groups=[[0]], cases=[SimpleNamespace(name="r")], data_size=100,
                             data_unit="segments", data_s=30.0)
    hyp = Hypothesis(key="interpolator.lookahead_blocks", family="planner", lower=1, upper=400, scale="int",
                     baseline=48)

    def judged(before: float, after: float):
        held = HeldOut(hyp=hyp, value=8, fold_values=[8], before=np.array([before]), after=np.array([after]),
                       fit_after=np.array([after]), floor=np.zeros(1))
        return judge(held, scorer, SelectConfig(), lambda losses, units: float(losses[units].sum()), None)

    assert judged(1.6, 0.6).accepted               # 1.6 -> 0.6 points: not one point, but halved
    assert not judged(3.0, 2.2).accepted           # 0.8 of 3: neither
    assert not judged(0.9, 0.0).accepted           # nothing material to explain
    assert judged(3.0, 1.9).accepted               # one point and more
    scorer.data_size = hyp.needs - 1                # too few segments to judge on, however good the fit
    assert judged(3.0, 0.1).reasons == [f"too little data: {hyp.needs - 1} segments (30.00 s of motion), needs "
                                        f"{hyp.needs} segments and 5 s"]
    scorer.data_size, scorer.data_s = 100, 2.0       # ... or too short a stretch of motion
    assert judged(3.0, 0.1).reasons[0].startswith("too little data: 100 segments (2.00 s of motion)")


def test_a_loss_over_some_units_simulates_only_their_recordings(hidden):
    """`Scorer.loss` over one recording's units re-simulates that recording alone (a fold's fit leaves the
    held-out recording out), gives the sum `unit_losses` gives, and a repeated profile is not simulated again."""
    from feedlog.diagnose.engine import load_cases
    from feedlog.diagnose.fit import Scorer

    profile, cases = load_cases(hidden("xacc", values={"axes.x.acc_max": 300.0}), None)
    sc = Scorer(profile, cases, "timing")
    first = sc.groups[0]
    values = {"axes.x.acc_max": 330.0}
    part = sc.loss(values, first)
    assert sc.simulations == 1
    assert sc.loss(values, first) == part and sc.simulations == 1
    whole = sc.unit_losses(values)
    assert sc.simulations == len(cases) == 2
    assert part == float(whole[first].sum()) and np.isfinite(part)
    assert sc.loss({"axes.x.acc_max": 300.0}, first) < part  # the hidden value fits better: it is a real loss


def test_the_motion_span_from_the_grid_ends_is_the_whole_grids(hidden):
    """The timing residual measures a re-simulation's motion span from the head and tail of its samples
    (`residuals._span_from_ends`): the same times as from every sample, on profiles that move the span."""
    from feedlog.diagnose.engine import load_cases
    from feedlog.diagnose.keys import with_values
    from feedlog.diagnose.residuals import _span_from_ends, sim_span
    from feedlog.sim import simulate

    profile, cases = load_cases(hidden("xacc", values={"axes.x.acc_max": 300.0}), None)
    fast = 0
    for case in cases:
        for values in ({}, {"axes.x.acc_max": 150.0}, {"sim.feed_override.override": 0.6, "axes.z.vel_max": 8.0}):
            sim = simulate(case.sim_input, with_values(profile, values) if values else profile)
            fast += _span_from_ends(case, sim.trajectory) is not None
            ends = sim_span(case, sim)
            sim.trajectory.sample_at = None  # the whole grid
            assert sim_span(case, sim) == ends
    assert fast == 3 * len(cases)
