"""Machine profiles: shipped ones load, TOML round-trips, impossible values are refused."""

from __future__ import annotations

import math

import pytest

from feedlog.errors import ProfileError
from feedlog.profile import AxisLimits, MachineProfile, load_profile, shipped_profiles


def test_shipped_profiles_are_the_three_reference_machines_and_two_generic_starts():
    assert shipped_profiles() == ["chien-ac", "generic-xyz", "generic-xyzac", "linuxcnc-xyz", "linuxcnc-xyzac"]


def test_generic_xyz_is_a_3_axis_starting_guess_that_says_so():
    p = load_profile("generic-xyz")
    assert p.axis_names == ("x", "y", "z") and p.kinematics.type == "xyz"
    assert all(p.axes[a].vel_max == 250.0 and p.axes[a].acc_max == 2000.0 for a in "xyz")
    assert "guess" in p.description and "diagnose" in p.description


def test_linuxcnc_xyz_matches_the_reference_config():
    p = load_profile("linuxcnc-xyz")
    assert p.axis_names == ("x", "y", "z")
    assert all(p.axes[a].vel_max == 100.0 and p.axes[a].acc_max == 1000.0 for a in "xyz")
    assert p.interpolator.servo_period_s == 0.001
    assert p.rapid_mm_min == 6000.0
    assert p.kinematics.type == "xyz"


def test_linuxcnc_xyzac_has_trunnion_kinematics_and_rotary_limits():
    p = load_profile("linuxcnc-xyzac")
    assert p.kinematics.type == "xyzac-trt"
    assert p.kinematics.rotary_axes == ("a", "c")
    assert p.kinematics.rotary_offset_mm == (0.0, -20.0, -10.0)
    assert p.axes["a"].vel_max == 60.0 and p.axes["c"].acc_max == 600.0


def test_chien_profile_has_the_papers_filter_time_constants():
    p = load_profile("chien-ac")
    assert p.interpolator.fir_t1_s == pytest.approx(0.070)
    assert p.interpolator.fir_t2_s == pytest.approx(0.010)
    assert p.kinematics.type == "xyzac-trt"


@pytest.mark.parametrize("name", ["chien-ac", "linuxcnc-xyz", "linuxcnc-xyzac"])
def test_toml_round_trip_is_lossless(name, tmp_path):
    p = load_profile(name)
    path = tmp_path / f"{name}.toml"
    p.save(path)
    assert load_profile(path) == p


def test_sim_mechanism_tables_survive_the_round_trip(tmp_path):
    p = load_profile("linuxcnc-xyz").replace(sim={"corner": {"law": "blend_arc", "tol_mm": 0.05}})
    p.save(tmp_path / "m.toml")
    q = load_profile(tmp_path / "m.toml")
    assert q.mechanism("corner") == {"law": "blend_arc", "tol_mm": 0.05}
    assert q.mechanism("absent") == {}


def test_unknown_short_name_lists_the_shipped_ones():
    with pytest.raises(ProfileError, match="linuxcnc-xyz"):
        load_profile("no-such-machine")


def test_missing_file_names_the_file(tmp_path):
    with pytest.raises(ProfileError, match="nope.toml"):
        load_profile(tmp_path / "nope.toml")


def test_broken_toml_names_the_file(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text("name = 'x'\n[axes.x\n")
    with pytest.raises(ProfileError, match="broken.toml"):
        load_profile(path)


def test_unknown_key_is_refused(tmp_path):
    text = load_profile("linuxcnc-xyz").to_toml().replace("rapid_mm_min", "rapid_speed")
    with pytest.raises(ProfileError, match="rapid"):
        MachineProfile.from_toml(text, source="m.toml")


@pytest.mark.parametrize("limits, match", [
    (dict(vel_max=0.0, acc_max=1.0), "vel_max"),
    (dict(vel_max=1.0, acc_max=-1.0), "acc_max"),
    (dict(vel_max=1.0, acc_max=1.0, min_limit=5.0, max_limit=1.0), "min_limit"),
])
def test_impossible_axis_limits_quote_the_values(limits, match):
    with pytest.raises(ProfileError, match=match):
        MachineProfile(name="m", axes={"x": AxisLimits(**limits), "y": AxisLimits(1, 1), "z": AxisLimits(1, 1)},
                       rapid_mm_min=100.0)


def test_five_axis_kinematics_needs_its_rotary_axes():
    axes = {a: AxisLimits(1.0, 1.0) for a in "xyz"}
    from feedlog.profile import Kinematics
    with pytest.raises(ProfileError, match="needs axes a, c"):
        MachineProfile(name="m", axes=axes, rapid_mm_min=1.0, kinematics=Kinematics(type="xyzac-trt"))


def test_fir_t2_may_not_exceed_t1():
    from feedlog.profile import Interpolator
    with pytest.raises(ProfileError, match="fir_t2_s"):
        Interpolator(fir_t1_s=0.01, fir_t2_s=0.02).check()


def test_unbounded_limits_are_left_out_of_toml():
    p = load_profile("chien-ac")
    assert math.isinf(p.interpolator.path_vel_max_mm_s)
    assert "path_vel_max_mm_s" not in p.to_toml()


def test_generic_xyzac_is_a_five_axis_starting_guess_that_says_so():
    p = load_profile("generic-xyzac")
    assert p.axis_names == ("x", "y", "z", "a", "c") and p.kinematics.type == "xyzac-trt"
    assert all(p.axes[a].vel_max == 250.0 for a in "xyz") and p.axes["a"].vel_max == 90.0
    assert "guess" in p.description and "diagnose" in p.description and not p.coverage
