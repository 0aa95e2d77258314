"""The LinuxCNC reference profiles reproduce measured LinuxCNC cycle times (../shared/LINUXCNC.md)."""

from __future__ import annotations

from pathlib import Path

import pytest

from feedlog.sim import simulate
from feedlog.toolpath import parse_program

SHARED = Path(__file__).resolve().parents[3] / "shared" / "linuxcnc"
# program -> (profile, measured cycle time in s, first motion to end of motion)
MEASURED = {
    "test_p001.ngc": ("linuxcnc-xyz", 10.065),
    "test_p01.ngc": ("linuxcnc-xyz", 9.651),
    "test_g61.ngc": ("linuxcnc-xyz", 13.788),
    "dense002q0.ngc": ("linuxcnc-xyz", 5.466),
    "5ax_p001.ngc": ("linuxcnc-xyzac", 13.951),
    "5ax_g61.ngc": ("linuxcnc-xyzac", 13.044),
}


@pytest.mark.skipif(not SHARED.is_dir(), reason=f"reference programs not found in {SHARED}")
@pytest.mark.parametrize("name", sorted(MEASURED))
def test_cycle_time_within_two_percent(name):
    profile, measured = MEASURED[name]
    res = simulate(parse_program(SHARED / name), profile)
    assert res.cycle_time_s == pytest.approx(measured, rel=0.02)
    # the CAM estimate is far off: the simulation is doing real work
    assert abs(res.cam_time_s - measured) / measured > 0.2
