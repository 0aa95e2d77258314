"""The test recordings' cache (sessions.py) serves a recording again only for the same machine, program and
dial: a changed INI key, HAL parameter, program byte or recorder option is a new session."""

from __future__ import annotations

import sys
from pathlib import Path

from .sessions import Job, expected_s

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "recordings" / "programs"
sys.path.insert(0, str(ROOT / "scripts"))
from linuxcnc_variants import derive_machine  # noqa: E402


def test_the_same_machine_and_program_under_other_paths_is_one_recording(tmp_path):
    program = tmp_path / "copy.ngc"
    program.write_bytes((PROGRAMS / "corners_f3000_p001.ngc").read_bytes())
    a = Job(ROOT / "recordings" / "configs" / "xyz.ini", PROGRAMS / "corners_f3000_p001.ngc", tmp_path / "a.mcap")
    b = Job(derive_machine("xyz", tmp_path / "control"), program, tmp_path / "b.mcap")
    assert a.key() == b.key()


def test_any_difference_in_what_the_machine_runs_is_another_recording(tmp_path):
    corners = PROGRAMS / "corners_f3000_p001.ngc"
    base = Job(derive_machine("xyz", tmp_path / "base"), corners, tmp_path / "o.mcap")
    changed_ini = Job(derive_machine("xyz", tmp_path / "acc", changes=[("AXIS_X", "MAX_ACCELERATION", 300)]),
                      corners, tmp_path / "o.mcap")
    lagged = Job(derive_machine("xyz", tmp_path / "lag", feedback_lag={0: 0.02}), corners, tmp_path / "o.mcap")
    # the same INI text (HALFILE = lag_j0.hal), another gain in the HAL file
    slower = Job(derive_machine("xyz", tmp_path / "lag30", feedback_lag={0: 0.03}), corners, tmp_path / "o.mcap")
    dial = Job(base.ini, corners, tmp_path / "o.mcap", {"feed_override": 0.8})
    turned = Job(base.ini, corners, tmp_path / "o.mcap", {"feed_override_at": ((3.5, 0.7),)})
    edited = tmp_path / "edited.ngc"
    edited.write_bytes(corners.read_bytes().replace(b"F3000", b"F2999", 1))
    program = Job(base.ini, edited, tmp_path / "o.mcap")
    five = derive_machine("xyzac", tmp_path / "five")
    offsets = derive_machine("xyzac", tmp_path / "offsets", hal_params={"xyzac-trt-kins.y-offset": 22.5})
    trunnion = [Job(ini, PROGRAMS / "mix5ax_011.ngc", tmp_path / "o.mcap") for ini in (five, offsets)]
    keys = [job.key() for job in (base, changed_ini, lagged, slower, dial, turned, program, *trunnion)]
    assert lagged.ini.read_text() == slower.ini.read_text()
    assert edited.read_bytes() != corners.read_bytes()
    assert len(set(keys)) == len(keys)


def test_the_longest_programs_are_started_first():
    # the manifest's cycle times: mix_003 11.168 s, longdense_002 2.886 s; a program it lacks counts 0
    assert expected_s(PROGRAMS / "mix_003.ngc") > expected_s(PROGRAMS / "longdense_002.ngc") > 0
    assert expected_s(Path("nowhere.ngc")) == 0.0
