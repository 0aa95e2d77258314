"""Two limits the recordings cannot tell apart are reported as a pair, with the air-cut that separates them.

A five-axis machine (Z at 40 mm/s and 350 mm/s^2, the limits of benchmarks/bench_calibrate_five.py)
recorded on one mix5ax program, calibrated from generic-xyzac: Z moves there with the rotaries, and a
faster Z with a slower acceleration fits as well (the fit lands near 48.8 / 312, where the first
five-axis calibration had reported 47.6 / 313 as constrained). `--calibrate` must report the Z velocity
and acceleration as a pair, neither constrained alone, on a ridge that holds the truth, name the
calibration air-cut whose time differs between the ridge's ends, and, with that air-cut recorded
(simulated on the machine) beside the program, pin both within 5 %. The rotary A, driven hard by the
program, stays constrained on its own."""

from __future__ import annotations

import pytest

from feedlog.diagnose.calibrate import calibrate
from feedlog.diagnose.engine import load_cases
from feedlog.diagnose.evidence import gather
from feedlog.diagnose.summary import calibration_lines
from feedlog.toolpath.calibration import calibration_program
from tests.diagnose.conftest import make_hidden

BASE = "generic-xyzac"
TRUTH = {"axes.x.vel_max": 70.0, "axes.y.vel_max": 55.0, "axes.z.vel_max": 40.0,
         "axes.x.acc_max": 600.0, "axes.y.acc_max": 450.0, "axes.z.acc_max": 350.0,
         "axes.a.vel_max": 30.0, "axes.a.acc_max": 300.0, "axes.c.vel_max": 45.0, "axes.c.acc_max": 400.0}
ZV, ZA = "axes.z.vel_max", "axes.z.acc_max"


def _calibrated(recs):
    prof, cases = load_cases(recs, BASE)
    return calibrate(prof, cases, gather(cases, prof))


@pytest.fixture(scope="module")
def program():
    return make_hidden("pair", values=TRUTH, programs=("mix5ax_015",), base=BASE)


@pytest.fixture(scope="module")
def first(program):
    return _calibrated(program)


def test_a_pair_the_recording_cannot_tell_apart_is_said_with_its_separating_aircut(first):
    cal = first
    by_key = {p.key: p for p in cal.parameters}
    assert not by_key[ZV].constrained and by_key[ZV].pair == ZA and by_key[ZA].pair == ZV
    for key in ("axes.a.vel_max", "axes.a.acc_max"):
        assert by_key[key].constrained and by_key[key].pair is None
        assert by_key[key].fitted_value == pytest.approx(TRUTH[key], rel=0.02)
    pair = next(r for r in cal.pairs if r.keys == (ZV, ZA))
    # the ridge holds the truth: velocity between its ends, and the acceleration falls as it rises
    assert pair.low[ZV] < TRUTH[ZV] < pair.high[ZV] and pair.low[ZA] > TRUTH[ZA] > pair.high[ZA]
    sep = pair.separated_by
    assert sep is not None and sep["difference_pct"] > 1.0 and set(sep["for"]) <= {ZV, ZA}
    text = "\n".join(calibration_lines(cal))
    assert f"pair {ZV} and {ZA}" in text and "--for" in text
    # the coverage the profile carries: not constrained, the partner named; the air-cut moves Z
    cov = cal.profile.coverage["parameters"]
    assert cov[ZV]["constrained"] is False and cov[ZV]["pair"] == ZA and cov[ZA]["pair"] == ZV
    assert "G1 Z" in calibration_program(cal.profile, keys=sep["for"])


def test_the_named_aircut_recorded_pins_the_pair(program, first):
    pair = next(r for r in first.pairs if r.keys == (ZV, ZA))
    text = calibration_program(first.profile, keys=pair.separated_by["for"], travel=30.0)
    aircut = make_hidden("pair_aircut", values=TRUTH, programs=[("aircut", text)], base=BASE, seed=1)
    cal = _calibrated([*program, *aircut])
    by_key = {p.key: p for p in cal.parameters}
    assert all(ZV not in r.keys for r in cal.pairs)
    for key in (ZV, ZA):
        assert by_key[key].constrained and by_key[key].fitted_value == pytest.approx(TRUTH[key], rel=0.05), by_key[key]
