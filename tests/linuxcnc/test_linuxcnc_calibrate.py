"""A LinuxCNC machine far from every shipped profile (X/Y/Z at 70/55/30 mm/s and 600/450/250 mm/s^2, TRAJ
70 mm/s), calibrated from `generic-xyz` on three recorded air-cuts and judged on recordings of programs the
fit never saw: within 1 % where the recordings covered the program, a warning naming the parameter where
they did not (a program with long X and Z rapids; one of far shorter moves than any recording)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from feedlog.coverage import program_warnings
from feedlog.diagnose.engine import DiagnoseConfig, diagnose, load_cases
from feedlog.sim import simulate

from .sessions import Job, record_all

pytestmark = [pytest.mark.linuxcnc, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "recordings" / "programs"
sys.path.insert(0, str(ROOT / "scripts"))
from linuxcnc_variants import derive_machine  # noqa: E402

LIMITS = {"X": (0, 70, 600), "Y": (1, 55, 450), "Z": (2, 30, 250)}
CHANGES = [(s, key, v) for ax, (j, vel, acc) in LIMITS.items()
           for s in (f"AXIS_{ax}", f"JOINT_{j}") for key, v in (("MAX_VELOCITY", vel), ("MAX_ACCELERATION", acc))]
CHANGES.append(("TRAJ", "MAX_LINEAR_VELOCITY", 70))
FIT_ON = ("corners_f3000_p001", "pocket_f3000_p001", "mix_010")
# program -> the parameters its warning must name ([]: covered, must be within 1 %)
JUDGE = {"pocket_f2000_p01": [], "test_p001": ["axes.x.vel_max", "axes.z.vel_max"],
         "longdense_003": ["interpolator.lookahead_blocks"]}


def test_a_far_machine_calibrated_from_generic_predicts_unseen_programs_or_says_it_cannot(tmp_path):
    ini = derive_machine("xyz", tmp_path / "far", changes=CHANGES)
    rec = {name: tmp_path / f"far_{name}.mcap" for name in (*FIT_ON, *JUDGE)}
    record_all([Job(ini, PROGRAMS / f"{name}.ngc", out) for name, out in rec.items()], timeout_s=180)
    dx = diagnose([rec[n] for n in FIT_ON], "generic-xyz", config=DiagnoseConfig(learned=False, calibrate=True))
    params = {p.key: p for p in dx.calibration.parameters}
    for ax, (_, vel, acc) in LIMITS.items():
        p = params[f"axes.{ax.lower()}.acc_max"]
        assert p.constrained and p.fitted_value == pytest.approx(acc, rel=0.06), p
        assert not params[f"axes.{ax.lower()}.vel_max"].constrained   # feeds of 50 mm/s, 5 mm Z rapids
    profile = dx.extended
    for name, expected in JUDGE.items():
        _, cases = load_cases([rec[name]], profile)
        case = cases[0]
        sim = simulate(case.sim_input, profile)
        named = sorted({w.split(":")[0] for w in program_warnings(profile, sim.series, case.program.blocks)})
        assert named == sorted(expected), (name, named)
        if not expected:
            assert abs(sim.cycle_time_s / case.cycle_s - 1) < 0.01, (name, sim.cycle_time_s, case.cycle_s)
