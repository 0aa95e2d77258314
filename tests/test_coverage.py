"""The `[coverage]` table of a fitted profile: read strictly (seeded fuzz), written and read back, and
checked against a program (`feedlog sim` warns naming the parameter; `feedlog program --calibration`
writes the air-cut for what is missing)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, seed, settings
from hypothesis import strategies as st

from feedlog.coverage import beyond
from feedlog.errors import ProfileError
from feedlog.profile import MachineProfile, load_profile

ROOT = Path(__file__).resolve().parents[1]
COVERAGE = {"format_version": 1, "recordings": ["a.mcap"], "blocks": {"median_move_min": 2.0},
            "axes": {"z": {"vel_observed": 25.0, "acc_observed": 250.0, "move_max": 5.0}},
            "parameters": {"axes.z.vel_max": {"constrained": False, "interval": [25.0, 750.0]},
                           "axes.z.acc_max": {"constrained": True, "interval": [245.0, 255.0]}}}


def _fitted(coverage=COVERAGE) -> MachineProfile:
    data = load_profile("generic-xyz").to_dict()
    return MachineProfile.from_dict({**data, "coverage": coverage}, source="fitted.toml")


def test_a_fitted_profile_keeps_its_coverage_through_toml_and_shipped_ones_have_none():
    again = MachineProfile.from_toml(_fitted().to_toml(), source="x.toml")
    assert again.coverage == COVERAGE
    assert "coverage" not in load_profile("linuxcnc-xyz").to_toml()


def test_a_newer_or_malformed_coverage_is_refused_naming_the_file():
    with pytest.raises(ProfileError, match=r"fitted.toml.*format_version 2 not supported"):
        _fitted({**COVERAGE, "format_version": 2})
    with pytest.raises(ProfileError, match=r"\[coverage.axes\] must hold one table per entry"):
        _fitted({**COVERAGE, "axes": {"z": 3}})
    params = COVERAGE["parameters"]
    for pair in (3, "axes.z.vel_max", "axes.q.acc_max"):   # not a string, itself, not in the table
        bad = {**params, "axes.z.vel_max": {**params["axes.z.vel_max"], "pair": pair}}
        with pytest.raises(ProfileError, match=r"fitted.toml.*axes.z.vel_max.*pair must name another parameter"):
            _fitted({**COVERAGE, "parameters": bad})
    good = {**params, "axes.z.vel_max": {**params["axes.z.vel_max"], "pair": "axes.z.acc_max"}}
    assert _fitted({**COVERAGE, "parameters": good}).coverage["parameters"]["axes.z.vel_max"]["pair"] == "axes.z.acc_max"


@seed(31)
@settings(max_examples=150, deadline=None)
@given(st.dictionaries(st.sampled_from(["format_version", "axes", "parameters", "blocks", "recordings", "x"]),
                       st.recursive(st.none() | st.integers(-3, 3) | st.floats(allow_nan=True) | st.text(max_size=3),
                                    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=3), inner,
                                                                                                max_size=3),
                                    max_leaves=8), max_size=5))
def test_any_coverage_table_loads_or_is_refused_with_a_profile_error(table):
    try:
        profile = _fitted(table)
    except ProfileError as exc:
        assert "fitted.toml" in str(exc)
        return
    peaks = {a: (1e9, 1e9) for a in "xyz"}
    for line in beyond(profile.coverage, peaks, {a: 1e9 for a in "xyz"}):
        assert line.startswith("axes.")


def test_a_program_of_much_shorter_moves_than_the_recordings_is_named_with_the_planner():
    from feedlog.coverage import shorter

    assert shorter(COVERAGE, 1.5) == []
    assert shorter(COVERAGE, 0.5)[0].startswith("interpolator.lookahead_blocks: the program's median move is 0.5 mm")
    with pytest.raises(ProfileError, match=r"\[coverage.blocks\] must hold numbers"):
        _fitted({**COVERAGE, "blocks": {"median_move_min": "x"}})


def test_only_what_goes_beyond_an_unconstrained_parameter_is_named():
    inside = beyond(COVERAGE, {"z": (25.5, 900.0)}, {"z": 5.0})
    assert inside == []   # within 5 % of the speed seen; the acceleration limit was pinned
    out = beyond(COVERAGE, {"z": (40.0, 900.0)}, {"z": 30.0})
    assert [w.split(":")[0] for w in out] == ["axes.z.vel_max", "axes.z.vel_max"]
    assert "40 mm/s" in out[0] and "25 mm/s" in out[0] and "30 mm in one block" in out[1]


def _feedlog(*args: str) -> subprocess.CompletedProcess:
    env = {"PYTHONPATH": str(ROOT / "src"), "PATH": "/usr/bin:/bin"}
    return subprocess.run([sys.executable, "-m", "feedlog", *args], capture_output=True, text=True, env=env, cwd=ROOT)


def test_sim_warns_and_program_writes_the_calibration_air_cut(tmp_path):
    prof = tmp_path / "fitted.toml"
    prof.write_text(_fitted().to_toml())
    prog = tmp_path / "z.ngc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z0\nG0 Z60\nG0 Z0\nM2\n")
    done = _feedlog("sim", str(prog), "--profile", str(prof))
    assert done.returncode == 0, done.stderr
    assert "feedlog sim: warning: axes.z.vel_max: the program moves Z at" in done.stderr
    cal = tmp_path / "cal.ngc"
    done = _feedlog("program", "--calibration", str(cal), "--profile", str(prof), "--travel", "40")
    assert done.returncode == 0, done.stderr
    text = cal.read_text()
    assert "G0 Z40" in text and "G0 X40" in text and "Z acceleration" not in text and "X acceleration" in text
    again = _feedlog("program", "--calibration", str(cal), "--profile", str(prof))
    assert again.returncode != 0 and "exists; pass --overwrite" in again.stderr
    blocked = _feedlog("program", "--calibration", str(tmp_path / "no" / "such" / "dir" / "c.ngc"),
                       "--profile", str(prof))
    assert blocked.returncode != 0 and len(blocked.stderr.strip().splitlines()) == 1, blocked.stderr
    assert not (tmp_path / "no").exists()
