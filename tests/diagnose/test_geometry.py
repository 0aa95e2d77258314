"""The geometry family on simulated recordings with a hidden geometry change: trunnion offsets (the
commanded joints against the recorded axes through the kinematics), an axis scale and backlash (the
feedback against the command). Each must be named with its value; an unchanged machine names nothing."""

from __future__ import annotations

import numpy as np
import pytest

from feedlog.diagnose import keys
from feedlog.diagnose.cases import geometry_data
from feedlog.diagnose.engine import DiagnoseConfig, diagnose
from feedlog.errors import FeedlogError
from feedlog.profile import load_profile
from feedlog.sim.backlash import Backlash, play
from feedlog.sim.mechanism import mechanism_class

P5 = ("mix5ax_011", "mix5ax_015")
GEOMETRY = DiagnoseConfig(learned=False, families=("geometry",))


def _found(dx) -> dict[str, float]:
    return {f.parameter: f.fitted_value for f in dx.findings}


def test_trunnion_offsets_found_from_the_joints(hidden):
    recs = hidden("geo_offsets", base="linuxcnc-xyzac", programs=P5,
                  values={"kinematics.rotary_offset_mm.1": -23.0, "kinematics.workpiece_offset_mm.0": 1.5})
    dx = diagnose(recs, "linuxcnc-xyzac", config=GEOMETRY)
    found = _found(dx)
    assert set(found) == {"kinematics.rotary_offset_mm.1", "kinematics.workpiece_offset_mm.0"}, found
    assert found["kinematics.rotary_offset_mm.1"] == pytest.approx(-23.0, abs=0.1)
    assert found["kinematics.workpiece_offset_mm.0"] == pytest.approx(1.5, abs=0.1)
    geo = dx.levels["geometry"]
    assert geo["rms_before_mm"] > 0.5 and geo["rms_after_mm"] < 0.005   # what is left is the 2 um noise
    assert all(f.level == "geometry" and f.family == "geometry" for f in dx.findings)


@pytest.mark.parametrize(("key", "true", "tol"), [("sim.backlash.backlash_mm.x", 0.03, 0.003),
                                                  ("sim.axis_scale.scale.y", 1.0005, 5e-5)])
def test_scale_and_backlash_found_from_the_feedback(hidden, key, true, tol):
    dx = diagnose(hidden(f"geo_{key}", values={key: true}), "linuxcnc-xyz", config=GEOMETRY)
    found = _found(dx)
    assert set(found) == {key}, found
    assert found[key] == pytest.approx(true, abs=tol)
    fb = dx.levels["feedback"]
    assert fb["rms_after_mm"] < 0.5 * fb["rms_before_mm"]


def test_unchanged_machine_names_no_geometry(hidden):
    for base, programs in (("linuxcnc-xyz", ("corners_f3000_p001", "pocket_f3000_p001")), ("linuxcnc-xyzac", P5)):
        dx = diagnose(hidden(f"geo_none_{base}", base=base, programs=programs), base, config=GEOMETRY)
        assert dx.findings == [], _found(dx)


def test_joints_recorded_behind_the_axes_are_lined_up(hidden):
    rec = hidden("geo_none_linuxcnc-xyzac", base="linuxcnc-xyzac", programs=P5)[0]
    profile = load_profile("linuxcnc-xyzac")
    shifted = rec.streams["joints"].copy()
    cols = [c for c in shifted.columns if c != "t_ns"]
    shifted[cols] = shifted[cols].shift(2).bfill()    # joints two samples late, as LinuxCNC records them
    rec2 = type(rec)(streams={**rec.streams, "joints": shifted}, metadata=rec.metadata,
                     attachments=rec.attachments, source=rec.source)
    assert geometry_data(rec, profile).lag == 0
    geo = geometry_data(rec2, profile)
    assert geo.lag == 2
    assert np.abs(geo.joints - rec.streams["joints"][[f"j{i}_pos" for i in range(5)]].to_numpy()[5:-5]).max() == 0


def test_list_elements_are_profile_keys():
    p = load_profile("linuxcnc-xyzac")
    assert keys.value(p, "kinematics.rotary_offset_mm.2") == -10.0
    assert keys.unit("kinematics.rotary_offset_mm.2") == "mm"
    q = keys.with_values(p, {"kinematics.rotary_offset_mm.2": -7.25})
    assert q.kinematics.rotary_offset_mm == (0.0, -20.0, -7.25)
    with pytest.raises(FeedlogError, match="rotary_offset_mm.3"):
        keys.value(p, "kinematics.rotary_offset_mm.3")


def test_play_operator_holds_after_a_reversal():
    cmd = np.array([0.0, 1.0, 2.0, 1.99, 1.95, 1.9, 1.0, 0.0])
    out = play(cmd, 0.1)
    # forward: half the play behind; after the reversal it holds until the command crossed the play
    np.testing.assert_allclose(out, [0.0, 0.95, 1.95, 1.95, 1.95, 1.95, 1.05, 0.05])
    with pytest.raises((ValueError, FeedlogError), match="backlash_mm"):
        Backlash(backlash_mm={"x": -1.0})
    with pytest.raises((ValueError, FeedlogError), match="scale"):
        mechanism_class("axis_scale")(scale={"y": 3.0})
