"""Many causes on a real NC kernel: a LinuxCNC machine made from the shipped xyz config with three limits
changed (X acceleration 400, Y velocity 30, Z acceleration 300) and the feed override dial at 0.85, recorded
with LinuxCNC on three programs, diagnosed with the shipped profile: all four named within 5 %."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from feedlog.diagnose.engine import DiagnoseConfig, diagnose

from .sessions import Job, record_all

pytestmark = [pytest.mark.linuxcnc, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "recordings" / "programs"
sys.path.insert(0, str(ROOT / "scripts"))
from linuxcnc_variants import derive_machine  # noqa: E402

CHANGES = [("AXIS_X", "MAX_ACCELERATION", 400), ("JOINT_0", "MAX_ACCELERATION", 400),
           ("AXIS_Y", "MAX_VELOCITY", 30), ("JOINT_1", "MAX_VELOCITY", 30),
           ("AXIS_Z", "MAX_ACCELERATION", 300), ("JOINT_2", "MAX_ACCELERATION", 300)]
EXPECTED = {"axes.x.acc_max": 400.0, "axes.y.vel_max": 30.0, "axes.z.acc_max": 300.0,
            "sim.feed_override.override": 0.85}
PROGRAMS_USED = ("corners_f3000_p001", "pocket_f3000_p001", "mix_010")


def test_three_limits_and_an_override_on_linuxcnc_are_all_named(tmp_path):
    ini = derive_machine("xyz", tmp_path / "four", changes=CHANGES)
    recordings = [tmp_path / f"four_{name}.mcap" for name in PROGRAMS_USED]
    record_all([Job(ini, PROGRAMS / f"{name}.ngc", out, {"feed_override": 0.85})
                for name, out in zip(PROGRAMS_USED, recordings)])
    dx = diagnose(recordings, "linuxcnc-xyz", config=DiagnoseConfig(learned=False))
    found = {f.parameter: f.fitted_value for f in dx.findings}
    assert set(found) == set(EXPECTED), [f.as_dict() for f in dx.findings]
    for key, value in EXPECTED.items():
        assert found[key] == pytest.approx(value, rel=0.05), key
    assert abs(dx.levels["cycle"]["error_after_pct"]) <= 0.1 * abs(dx.levels["cycle"]["error_before_pct"])
