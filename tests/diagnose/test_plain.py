"""The diagnosis in plain sentences (`diagnose.plain`) and the controller's names for profile keys."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from feedlog.controller_names import controllers_of, label, names_for, with_names
from feedlog.diagnose.plain import answer, glossary, noise_floor_text, pct, timings_text


def _finding(**kw):
    base = dict(parameter="axes.y.acc_max", profile_value=1000.0, fitted_value=350.1, unit="mm/s^2", kind="parameter",
                evidence="Y acceleration peaks at 350 mm/s^2 (sustained 8 ms)")
    return SimpleNamespace(**{**base, **kw})


def _dx(*, before=-12.16, after=0.04, findings=None, controller="LinuxCNC 2.9", unexplained=(), held=None):
    return SimpleNamespace(
        levels={"cycle": {"error_before_pct": before, "error_after_pct": after, "measured_s": 31.843,
                          "simulated_before_s": 27.972}},
        cases=[1, 2, 3], profile=SimpleNamespace(name="linuxcnc-xyz", controller=controller),
        findings=[_finding()] if findings is None else findings, unexplained=list(unexplained),
        held_out={"recordings": held if held is not None else
                  [{"name": "a", "error_after_pct": -0.02}, {"name": "b", "error_after_pct": 0.071}]})


def test_pct_never_prints_minus_zero():
    assert [pct(v) for v in (-0.04, 0.04, -12.16, 12.16, None, float("nan"))] == [
        "0.0 %", "0.0 %", "-12.2 %", "12.2 %", "n/a", "n/a"]


def test_answer_says_which_way_and_names_the_controller_parameter():
    lines = answer(_dx())
    assert lines[0].startswith("The machine took longer than simulated: 31.8 s measured, 28.0 s simulated")
    assert "the simulation is 12.2 % short of the measured time" in lines[0]
    assert ("Cause: the Y-axis maximum acceleration is 350.1 mm/s^2 on this machine, not 1000 mm/s^2 as the "
            "profile says") in lines[1]
    assert "`[AXIS_Y] MAX_ACCELERATION`" in lines[1] and "MD32300" not in lines[1]   # a LinuxCNC profile
    assert "without any simulation: Y acceleration peaks" in lines[2]
    assert "matches the measured time" in lines[3] and "within 0.07 % of that recording" in lines[3]
    # the other way round, and nothing found
    faster = answer(_dx(before=8.0, after=7.9, findings=[], held=[]))
    assert faster[0].startswith("The machine took less time than simulated") and "8.0 % over" in faster[0]
    assert faster[1].startswith("No cause is named")
    unexplained = answer(_dx(findings=[], unexplained=[{"level": "timing", "error_pct": 3.0,
                                                        "systematic_share_pct": 80.0}]))
    assert unexplained[-1] == "Still unexplained (timing): 3.0 % of the time is misplaced, 80 % of it systematic."


def test_mechanisms_read_as_switched_on():
    lines = answer(_dx(findings=[_finding(parameter="sim.feed_override.override", profile_value=None,
                                          fitted_value=0.8, unit="", kind="mechanism", evidence="")]))
    assert "feed override is at work on this machine (0.8); the profile leaves it off" in lines[1]
    assert "[DISPLAY] MAX_FEED_OVERRIDE" in lines[1]


@pytest.mark.parametrize(("controller", "expected"), [
    ("LinuxCNC 2.9 (linuxcnc-uspace)", ("LinuxCNC",)), ("Siemens SINUMERIK 840D sl", ("Sinumerik",)),
    ("FANUC 31i-B", ("Fanuc",)), ("unknown: generic", ("LinuxCNC", "Fanuc", "Sinumerik"))])
def test_which_controllers_names_a_profile_gets(controller, expected):
    assert controllers_of(controller) == expected


def test_controller_names_per_key():
    assert [n.name for n in names_for("axes.z.vel_max", "Sinumerik 840D")] == ["MD32000 $MA_MAX_AX_VELO[Z]"]
    assert [n.name for n in names_for("axes.x.max_limit", "LinuxCNC")] == ["[AXIS_X] MAX_LIMIT"]
    assert [n.name for n in names_for("rapid_mm_min", "Fanuc 0i")] == ["No. 1420"]
    assert names_for("axes.x.acc_max", "Fanuc 0i") == []            # no acceleration parameter we can cite
    assert names_for("sim.logger_latency.latency_s") == []
    assert label("axes.c.jerk_max") == "C-axis maximum jerk" and label("sim.block_time.floor_s") == "floor s"
    text = with_names("axes.y.acc_max", "generic")
    assert text.startswith("`axes.y.acc_max` (LinuxCNC INI `[AXIS_Y] MAX_ACCELERATION`")
    assert "Sinumerik `MD32300 $MA_MAX_AX_ACCEL[Y]` (public docs)" in text


def test_noise_floor_and_timings_are_sentences_not_dicts():
    text = noise_floor_text({"timing_pct": 0.23205, "feedback_mm": None, "min_effect_pct": 1.0, "min_gain": 0.2,
                             "sampling_period_s": [0.001], "line_s": 0.00057735, "min_effect_line_s": 0.002})
    assert text == ("Noise floor: segment timing 0.23 % of the time; program-line timestamps 0.58 ms; sampled "
                    "every 1 ms. A cause is named only if it can change the time by at least 1.0 %, remove at "
                    "least 20 % of the held-out error and move a program line by at least 2.0 ms.")
    assert noise_floor_text({}) == "Noise floor: not measured."
    assert timings_text({"prepare": 0.25, "timing": 1.5, "total": 2.0}) == \
        "Diagnosis run time 2.0 s (prepare 0.25 s, timing 1.50 s)."
    assert all(line.startswith("- *") for line in glossary())
