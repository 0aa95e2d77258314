"""Two limits the recordings cannot tell apart are reported as a pair, with the air-cut that separates them.

A machine's Z runs at 40 mm/s and 350 mm/s^2; its recording moves Z only in 10 mm strokes, which take
d / v + v / a whatever the two are, as long as that sum stays: every (v, a) on that curve fits. X and Y
move over three lengths and are pinned. `--calibrate` from generic-xyz must report Z's velocity and
acceleration as a pair, not constrained alone, with a ridge that holds the truth, name the calibration
air-cut whose time differs between the ridge's ends, and, with that air-cut recorded (simulated on the
machine) beside the first recording, pin both within 5 %."""

from __future__ import annotations

import pytest

from feedlog.diagnose.calibrate import calibrate
from feedlog.diagnose.engine import load_cases
from feedlog.diagnose.evidence import gather
from feedlog.diagnose.keys import with_values
from feedlog.diagnose.summary import calibration_lines
from feedlog.ingest.recording import PROFILE_ATTACHMENT
from feedlog.profile import load_profile
from feedlog.sim import MeasurementModel, measure, simulate
from feedlog.toolpath import parse_program
from feedlog.toolpath.calibration import calibration_program

BASE = "generic-xyz"
TRUTH = {"axes.x.vel_max": 70.0, "axes.x.acc_max": 600.0, "axes.y.vel_max": 55.0, "axes.y.acc_max": 450.0,
         "axes.z.vel_max": 40.0, "axes.z.acc_max": 350.0}
ZV, ZA = "axes.z.vel_max", "axes.z.acc_max"


def _strokes() -> str:
    lines = ["G21 G90 G94 G17", "G61", "F6000"]
    for axis in "XY":
        for length in (60, 8, 2):
            lines += [f"G1 {axis}{length}", f"G1 {axis}0"] * 2
    lines += ["G1 Z10", "G1 Z0"] * 4     # Z in one length only
    return "\n".join([*lines, "M2"]) + "\n"


def _recorded(name: str, text: str, seed: int):
    truth = with_values(load_profile(BASE), TRUTH)
    rec = measure(simulate(parse_program(text, name=name), truth),
                  MeasurementModel(rate_hz=1000.0, noise_mm=0.002, quantum_mm=0.001, rest_s=0.3, seed=seed),
                  program_text=text)
    rec.attachments[PROFILE_ATTACHMENT] = load_profile(BASE).to_toml().encode()
    rec.source = f"{name}.mcap"
    return rec


def _calibrated(recs):
    prof, cases = load_cases(recs, BASE)
    return calibrate(prof, cases, gather(cases, prof))


@pytest.fixture(scope="module")
def strokes():
    return _recorded("strokes", _strokes(), seed=0)


@pytest.fixture(scope="module")
def first(strokes):
    return _calibrated([strokes])


def test_a_pair_the_recording_cannot_tell_apart_is_said_with_its_separating_aircut(first):
    cal = first
    by_key = {p.key: p for p in cal.parameters}
    assert not by_key[ZV].constrained and by_key[ZV].pair == ZA and by_key[ZA].pair == ZV
    for axis in "xy":   # three stroke lengths: each limit alone
        assert by_key[f"axes.{axis}.acc_max"].constrained and by_key[f"axes.{axis}.acc_max"].pair is None
    (pair,) = cal.pairs
    assert pair.keys == (ZV, ZA)
    # the ridge holds the truth: velocity between its ends, and the acceleration falls as it rises
    assert pair.low[ZV] < TRUTH[ZV] < pair.high[ZV] and pair.low[ZA] > TRUTH[ZA] > pair.high[ZA]
    assert pair.high[ZV] / pair.low[ZV] >= 1.1
    sep = pair.separated_by
    assert sep is not None and sep["difference_pct"] > 1.0 and set(sep["for"]) <= {ZV, ZA}
    text = "\n".join(calibration_lines(cal))
    assert f"pair {ZV} and {ZA}" in text and "--for" in text
    # the coverage the profile carries: not constrained, the partner named; the air-cut writes Z patterns
    cov = cal.profile.coverage["parameters"]
    assert cov[ZV] == {"constrained": False, "interval": [pair.low[ZV], pair.high[ZV]], "pair": ZA}
    assert "G1 Z" in calibration_program(cal.profile, keys=sep["for"])


def test_the_named_aircut_recorded_pins_the_pair(strokes, first):
    (pair,) = first.pairs
    aircut = _recorded("aircut", calibration_program(first.profile, keys=pair.separated_by["for"], travel=30.0), seed=1)
    cal = _calibrated([strokes, aircut])
    by_key = {p.key: p for p in cal.parameters}
    assert cal.pairs == []
    for key in (ZV, ZA):
        assert by_key[key].constrained and by_key[key].fitted_value == pytest.approx(TRUTH[key], rel=0.05), by_key[key]
