"""feedlog diagnose's backlash hypothesis against a real NC kernel.

LinuxCNC's own backlash setting ([JOINT_n] BACKLASH) is a *compensation*: the motion controller adds a
ramped +-BACKLASH/2 to the joint's motor command (joint.N.motor-pos-cmd = pos-cmd + backlash_filt) and
subtracts the same from the motor feedback (pos-fb = motor-pos-fb - backlash_filt, control.c). On a
machine whose drive has no play (LinuxCNC's simulated configs loop the motor command back as its
feedback) the two cancel: the recorded joint.N.pos-cmd and pos-fb stay exactly as without it, and
diagnose must name nothing. The play itself is a property of the mechanics: here it is put between the
joint's simulated drive and its feedback in HAL (`derive_machine(backlash=...)`: a table with lost
motion in its screw, measured by a linear scale), and diagnose must find its width within 5 % from the
recorded pos-cmd / pos-fb, with nothing else named. The unchanged machine: nothing."""

from __future__ import annotations

import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from feedlog.diagnose.engine import DiagnoseConfig, diagnose
from feedlog.ingest import read_recording
from feedlog.ingest.linuxcnc import record_linuxcnc
from feedlog.ingest.linuxcnc_session import isolation_available

pytestmark = [pytest.mark.linuxcnc, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "recordings" / "programs"
sys.path.insert(0, str(ROOT / "scripts"))
from linuxcnc_variants import derive_machine  # noqa: E402

PROGRAM = "corners_f3000_p001"   # X reverses six times, 6.5 s
PLAY_MM = 0.037
# name: derive_machine arguments
MACHINES = {"control": {}, "play": {"backlash": {0: PLAY_MM}},
            "compensation": {"changes": [("JOINT_0", "BACKLASH", PLAY_MM)]}}
CONFIG = DiagnoseConfig(learned=False)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("backlash")
    isolate = isolation_available() is None   # private namespaces where allowed: two sessions at a time

    def run(name: str) -> tuple[str, Path]:
        ini = derive_machine("xyz", root / name, **MACHINES[name])
        out = ini.parent / f"{name}_{PROGRAM}.mcap"
        summary = record_linuxcnc(ini, PROGRAMS / f"{PROGRAM}.ngc", out, isolate=isolate, timeout_s=120)
        assert summary["status"] == "complete", summary
        return name, out

    with ThreadPoolExecutor(2 if isolate else 1) as pool:
        return dict(pool.map(run, MACHINES))


def _feedback_off_command_mm(path: Path) -> float:
    """Largest distance of X's feedback from its command one servo cycle earlier (basic_sim's pass-through)."""
    joints = read_recording(path).streams["joints"]
    cmd, fb = joints["j0_pos"].to_numpy(), joints["j0_pos_fb"].to_numpy()
    return float(np.abs(fb[1:] - cmd[:-1]).max())


def test_play_in_the_drive_is_found_from_command_and_feedback(recorded):
    assert _feedback_off_command_mm(recorded["play"]) > 0.9 * PLAY_MM / 2   # the play shows in the joints
    dx = diagnose([recorded["play"]], "linuxcnc-xyz", config=CONFIG)
    found = {f.parameter: f.fitted_value for f in dx.findings}
    assert set(found) == {"sim.backlash.backlash_mm.x"}, [f.as_dict() for f in dx.findings]
    assert found["sim.backlash.backlash_mm.x"] == pytest.approx(PLAY_MM, rel=0.05)
    fb = dx.levels["feedback"]
    assert fb["rms_before_mm"] > 0.005 and fb["rms_after_mm"] < 0.05 * fb["rms_before_mm"]
    assert dx.unexplained == []


@pytest.mark.parametrize("name", ["control", "compensation"])
def test_no_play_names_nothing_and_the_ini_compensation_leaves_no_trace(recorded, name):
    # the compensation's +-BACKLASH/2 is added to motor-pos-cmd and taken off motor-pos-fb again: the
    # recorded X feedback is the command of one cycle earlier, as on the unchanged machine
    assert _feedback_off_command_mm(recorded[name]) < 1e-9
    dx = diagnose([recorded[name]], "linuxcnc-xyz", config=CONFIG)
    assert dx.findings == [] and dx.unexplained == [], ([f.as_dict() for f in dx.findings], dx.unexplained)
    assert dx.levels["feedback"]["rms_before_mm"] < 1e-6, dx.levels["feedback"]
