"""feedlog diagnose's geometry family against a real NC kernel: the five-axis reference machine with its
trunnion's offsets changed in trt.hal (xyzac-trt-kins y-offset 20 -> 22.5, z-offset 10 -> 8.7), recorded
with LinuxCNC, diagnosed with the shipped profile. The cycle time does not change (LinuxCNC plans in
axis coordinates); the recorded joints do. Diagnose must find both offsets within 0.1 mm, and the
extended profile's kinematics must reproduce the recorded joints; the unchanged machine: nothing named."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from feedlog.diagnose import keys
from feedlog.diagnose.engine import DiagnoseConfig, diagnose

from .sessions import Job, record_all

pytestmark = [pytest.mark.linuxcnc, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "recordings" / "programs"
sys.path.insert(0, str(ROOT / "scripts"))
from linuxcnc_variants import derive_machine  # noqa: E402

P5 = ("mix5ax_011", "mix5ax_015")
# name: HAL parameters of trt.hal changed
MACHINES = {"control": {}, "offsets": {"xyzac-trt-kins.y-offset": 22.5, "xyzac-trt-kins.z-offset": 8.7}}


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> dict[str, list[Path]]:
    root = tmp_path_factory.mktemp("geometry")
    jobs = {name: [Job(ini, PROGRAMS / f"{program}.ngc", ini.parent / f"{name}_{program}.mcap") for program in P5]
            for name, ini in ((name, derive_machine("xyzac", root / name, hal_params=params))
                              for name, params in MACHINES.items())}
    record_all([job for machine in jobs.values() for job in machine])
    return {name: [job.out for job in machine] for name, machine in jobs.items()}


def test_changed_trunnion_offsets_are_found_within_a_tenth_of_a_millimetre(recorded):
    dx = diagnose(recorded["offsets"], "linuxcnc-xyzac", config=DiagnoseConfig(learned=False))
    found = {f.parameter: f.fitted_value for f in dx.findings}
    # xyzac-trt-kins' y/z-offset enter the profile's Eq. 10 with the opposite sign (linuxcnc-xyzac.toml)
    assert set(found) == {"kinematics.rotary_offset_mm.1", "kinematics.rotary_offset_mm.2"}, found
    assert found["kinematics.rotary_offset_mm.1"] == pytest.approx(-22.5, abs=0.1)
    assert found["kinematics.rotary_offset_mm.2"] == pytest.approx(-8.7, abs=0.1)
    geo = dx.levels["geometry"]
    assert geo["rms_before_mm"] > 0.1 and geo["rms_after_mm"] < 0.001   # the extended kinematics make the joints
    assert keys.value(dx.extended, "kinematics.rotary_offset_mm.1") == pytest.approx(-22.5, abs=0.1)


def test_unchanged_five_axis_machine_names_nothing(recorded):
    dx = diagnose(recorded["control"], "linuxcnc-xyzac", config=DiagnoseConfig(learned=False))
    assert dx.findings == [] and dx.unexplained == []
    assert dx.levels["geometry"]["rms_before_mm"] < 0.001   # the shipped profile's kinematics are LinuxCNC's
