"""Every hypothesis family declares its rank and its evidence beside its candidates (issue #29)."""

from __future__ import annotations

import pytest

from feedlog.diagnose import hypothesis
from feedlog.diagnose.evidence import AxisEvidence, Evidence
from feedlog.diagnose.hypothesis import FAMILIES, Family, Hypothesis, family
from feedlog.errors import FeedlogError


def test_every_registered_family_has_a_distinct_rank_and_its_registered_name():
    fams = {name: family(name) for name in FAMILIES}
    for name, fam in fams.items():
        assert isinstance(fam, Family) and fam.name == name
        assert isinstance(fam.rank, int)
    ranks = [f.rank for f in fams.values()]
    assert len(set(ranks)) == len(ranks), f"two families share a rank: {ranks}"
    # the order of the tie-break (the operator's dials, the machine's limits, planner, ...) as before the move
    order = sorted(fams, key=lambda n: fams[n].rank)
    assert order == ["overrides", "axis_limits", "path_limits", "planner", "dwell", "feedback", "logger", "geometry",
                     "tool_change"]


def test_a_family_without_a_rank_or_without_evidence_cannot_be_made():
    class NoRank(Family):
        name = "norank"

        def candidates(self, profile, cases):
            return []

        def describe(self, ev, key, fitted=None):
            return ""

        def suggest(self, ev, key, baseline):
            return ()

        def contradicts(self, ev, key, profile_value, fitted):
            return None

    with pytest.raises(FeedlogError, match="norank: declares no integer rank"):
        NoRank()

    class NoEvidence(Family):
        name = "noevidence"
        rank = 9

        def candidates(self, profile, cases):
            return []

    with pytest.raises(TypeError, match="abstract"):
        NoEvidence()


def test_an_unregistered_or_misnamed_family_is_an_error_not_the_lowest_rank(monkeypatch):
    with pytest.raises(FeedlogError, match="unknown hypothesis family 'jerk'"):
        family("jerk")
    monkeypatch.setattr(hypothesis, "FAMILIES", hypothesis.FAMILIES.copy({"jerk": "feedlog.diagnose.hyp_dwell:FAMILY"}))
    with pytest.raises(FeedlogError, match="not a Family named 'jerk'"):
        family("jerk")
    from feedlog.diagnose.select import _priority

    with pytest.raises(FeedlogError):
        _priority(Hypothesis(key="sim.reversal_dwell.dwell_s", family="nobody", lower=1e-3, upper=1.0))


def test_each_family_reads_the_evidence_of_its_own_keys_only():
    ev = Evidence(axes={"x": AxisEvidence("x", "mm", peak_vel=50.0, peak_acc=800.0, travel=100.0)},
                  path_speed_ceiling_mm_s=60.0, plateau_ratio=0.8, plateau_blocks=4, stops=3,
                  feedback_delay_s={"x": 0.002})
    assert family("axis_limits").suggest(ev, "axes.x.vel_max", 100.0) == (50.0,)
    assert family("axis_limits").suggest(ev, "interpolator.path_vel_max_mm_s", 100.0) == ()
    assert family("path_limits").suggest(ev, "interpolator.path_vel_max_mm_s", 100.0) == (60.0,)
    assert family("overrides").suggest(ev, "sim.feed_override.override", 0.5) == pytest.approx((0.4,))
    assert family("feedback").suggest(ev, "sim.following_lag.lag_s.x", None) == (0.002,)
    assert "800" in family("axis_limits").describe(ev, "axes.x.acc_max")
    assert family("dwell").describe(ev, "sim.reversal_dwell.dwell_s") == "3 stops inside the motion"
    assert family("logger").describe(ev, "sim.logger_latency.line_s") == ""
