"""Profile parameters by dotted key: read what is in force, set values, switch mechanisms on, diff."""

from __future__ import annotations

import math

import pytest

from feedlog.diagnose import keys
from feedlog.errors import ProfileError
from feedlog.profile import load_profile


@pytest.fixture
def xyz():
    return load_profile("linuxcnc-xyz")


def test_values_in_force_come_from_the_profile_or_the_mechanism_defaults(xyz):
    assert keys.value(xyz, "axes.x.acc_max") == 1000.0
    assert keys.value(xyz, "interpolator.lookahead_blocks") == 50
    assert keys.value(xyz, "interpolator.path_acc_max_mm_s2") == math.inf   # left out of the TOML
    assert keys.value(xyz, "sim.lookahead.stop_settle_s") == 0.0005
    assert keys.value(xyz, "sim.feedback_delay.delay_s") == 0.001
    assert not keys.enabled(xyz, "feed_override") and keys.value(xyz, "sim.feed_override.override") == 1.0


def test_setting_a_parameter_of_a_switched_off_mechanism_switches_it_on(xyz):
    ext = keys.with_values(xyz, {"sim.reversal_dwell.dwell_s": 0.02, "axes.y.vel_max": 40})
    assert keys.enabled(ext, "reversal_dwell") and keys.value(ext, "sim.reversal_dwell.dwell_s") == 0.02
    assert ext.axes["y"].vel_max == 40 and xyz.axes["y"].vel_max == 100
    assert ("sim.reversal_dwell.enabled", None, True) in keys.diff(xyz, ext)
    assert ("axes.y.vel_max", 100.0, 40) in keys.diff(xyz, ext)


def test_a_per_axis_entry_keeps_the_other_axes(xyz):
    lagged = keys.with_values(xyz, {"sim.following_lag.lag_s.x": 0.02})
    assert keys.value(lagged, "sim.following_lag.lag_s.x") == 0.02
    assert keys.value(lagged, "sim.following_lag.lag_s.y") == 0.0   # switched on with x only
    both = keys.with_values(lagged, {"sim.following_lag.lag_s.y": 0.01})
    assert keys.value(both, "sim.following_lag.lag_s.x") == 0.02 and keys.value(both, "sim.following_lag.lag_s.y") == 0.01


def test_units_come_from_the_key(xyz):
    assert keys.unit("axes.x.acc_max") == "mm/s^2" and keys.unit("axes.a.vel_max") == "deg/s"
    assert keys.unit("interpolator.path_vel_max_mm_s") == "mm/s" and keys.unit("sim.following_lag.lag_s.x") == "s"
    assert keys.unit("interpolator.lookahead_blocks") == "blocks" and keys.unit("sim.feed_override.override") == ""


@pytest.mark.parametrize(("bad", "message"), [("axes", "names a table"), ("frobnicate.x", "not a profile key"),
                                              ("sim.feed_override", "sim.<mechanism>.<param>"),
                                              ("sim.nope.x", "unknown sim mechanism"),
                                              ("sim.feed_override.nope", "has no parameter")])
def test_keys_that_name_no_value_are_profile_errors(xyz, bad, message):
    with pytest.raises(ProfileError, match=message):
        keys.value(xyz, bad)


def test_setting_an_axis_the_machine_lacks_is_a_profile_error(xyz):
    with pytest.raises(ProfileError, match=r"axes.q.acc_max: \[axes.q\]: missing key"):
        keys.with_values(xyz, {"axes.q.acc_max": 1.0})


def test_an_impossible_value_is_refused_like_any_profile(xyz):
    with pytest.raises(ProfileError, match="acc_max must be a number from"):
        keys.with_values(xyz, {"axes.x.acc_max": -1.0})
