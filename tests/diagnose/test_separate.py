"""A single recording that cannot tell two causes apart says which recording would, and that recording
does: Z moves only in rapids, so a Z velocity limit of 20 mm/s and a rapid override of 0.2 fit it alike;
the diagnosis names the air-cut that separates them, and with that air-cut recorded on the same machine
the Z limit is named alone."""

from __future__ import annotations

import pytest

from feedlog.diagnose.engine import DiagnoseConfig, diagnose
from feedlog.diagnose.keys import with_values
from feedlog.diagnose.separate import separating_program
from feedlog.diagnose.summary import summary_lines
from feedlog.ingest.recording import PROFILE_ATTACHMENT
from feedlog.profile import load_profile
from feedlog.sim import MeasurementModel, measure, simulate
from feedlog.toolpath import parse_program
from feedlog.toolpath.calibration import calibration_program

TRUE = {"axes.z.vel_max": 20.0}
FAST = DiagnoseConfig(learned=False)


def _drilling() -> str:
    """Nine holes: XY only at F2400, Z only in rapids (up 30 mm, down to 2 mm)."""
    lines = ["G21 G90 G64 P0.01", "G0 X0 Y0 Z30"]
    for i in range(3):
        for j in range(3):
            lines += [f"G1 X{40 * j} Y{40 * i} F2400", "G0 Z2", "G0 Z30"]
    return "\n".join(lines + ["M2"]) + "\n"


def _record(text: str, name: str, seed: int):
    truth = with_values(load_profile("linuxcnc-xyz"), TRUE)
    result = simulate(parse_program(text, name=name), truth)
    rec = measure(result, MeasurementModel(rate_hz=1000.0, noise_mm=0.002, quantum_mm=0.001, rest_s=0.5, seed=seed),
                  program_text=text)
    rec.attachments[PROFILE_ATTACHMENT] = load_profile("linuxcnc-xyz").to_toml().encode()
    rec.source = f"{name}.mcap"
    return rec


def test_two_equal_explanations_name_the_recording_that_separates_them():
    dx = diagnose([_record(_drilling(), "drill", 0)], "linuxcnc-xyz", config=FAST)
    assert len(dx.findings) == 1
    f = dx.findings[0]
    named = {f.parameter, *(a["parameter"] for a in f.alternatives)}
    assert named >= {"axes.z.vel_max", "sim.rapid_override.override"}, named
    sep = f.separated_by
    assert sep is not None and "axes.z.vel_max" in sep["for"] and sep["difference_pct"] > 5
    assert any(line.startswith("  to tell them apart record: feedlog program --calibration") for line in summary_lines(dx))
    # the air-cut it names, recorded on the same machine, settles it
    cal = calibration_program(load_profile("linuxcnc-xyz"), keys=sep["for"], travel=50.0)
    both = diagnose([_record(_drilling(), "drill", 0), _record(cal, "zcal", 1)], "linuxcnc-xyz", config=FAST)
    found = {g.parameter: g for g in both.findings}
    assert set(found) == {"axes.z.vel_max"}
    assert found["axes.z.vel_max"].fitted_value == pytest.approx(20.0, rel=0.05)
    assert found["axes.z.vel_max"].alternatives == []


def test_explanations_no_air_cut_separates_are_not_given_one():
    profile = load_profile("linuxcnc-xyz")
    # the same value under two spellings predicts the same everywhere
    assert separating_program(profile, {"axes.z.vel_max": 20.0}, {"axes.z.vel_max": 20.0}) is None
    sep = separating_program(profile, {"axes.z.vel_max": 20.0}, {"sim.rapid_override.override": 0.2})
    assert sep is not None and sep["for"][0] == "axes.z.vel_max"
