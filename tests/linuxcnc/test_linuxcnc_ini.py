"""Preparing a LinuxCNC INI for a recording session, and turning LinuxCNC's errors into ours."""

from __future__ import annotations

from pathlib import Path

import pytest

from feedlog.errors import IngestError, ProgramError
from feedlog.ingest.linuxcnc import profile_for_ini
from feedlog.ingest.linuxcnc_session import MachineIni, program_error, session_error

CONFIGS = Path(__file__).resolve().parents[2] / "recordings" / "configs"


def test_reference_ini_is_read():
    ini = MachineIni.read(CONFIGS / "xyzac.ini")
    assert ini.coordinates == "XYZAC" and ini.joints == 5
    assert ini.servo_period_ns == 1_000_000 and ini.linear_units == "mm"
    assert profile_for_ini(ini) == "linuxcnc-xyzac"
    assert profile_for_ini(MachineIni.read(CONFIGS / "xyz.ini")) == "linuxcnc-xyz"


def test_rewritten_ini_runs_our_driver_and_recorder(tmp_path):
    ini = MachineIni.read(CONFIGS / "xyzac.ini")
    text = ini.rewritten(display="/w/driver.py /w/job.json", recorder=tmp_path / "record.tcl")
    lines = [line.strip() for line in text.splitlines()]
    assert "DISPLAY = /w/driver.py /w/job.json" in lines
    halfiles = [line.split("=", 1)[1].strip() for line in lines if line.startswith("HALFILE")]
    assert halfiles[0].startswith("LIB:basic_sim.tcl")
    assert str(tmp_path / "record.tcl") in halfiles
    assert "/tmp/lcnc/record.tcl" not in text
    # relative HAL files keep pointing at the INI's folder
    assert str(CONFIGS.resolve() / "trt.hal") in halfiles
    assert "TOOL_TABLE = feedlog.tbl" in lines
    assert ini.hal_files() == [CONFIGS.resolve() / "trt.hal"]


def test_recorder_is_appended_when_the_ini_has_no_recording_halfile(tmp_path):
    src = (CONFIGS / "xyz.ini").read_text().replace("HALFILE = /tmp/lcnc/record.tcl\n", "")
    path = tmp_path / "plain.ini"
    path.write_text(src)
    text = MachineIni.read(path).rewritten(display="d", recorder=Path("/r/record.tcl"))
    halfiles = [line for line in text.splitlines() if line.startswith("HALFILE")]
    assert halfiles[-1] == "HALFILE = /r/record.tcl" and len(halfiles) == 2


def test_ini_without_servo_period_is_refused(tmp_path):
    path = tmp_path / "broken.ini"
    path.write_text((CONFIGS / "xyz.ini").read_text().replace("SERVO_PERIOD = 1000000", ""))
    with pytest.raises(IngestError, match=r"broken\.ini: LinuxCNC INI lacks \[EMCMOT\] SERVO_PERIOD"):
        MachineIni.read(path)
    with pytest.raises(IngestError, match="cannot read LinuxCNC INI"):
        MachineIni.read(tmp_path / "missing.ini")


def test_unknown_kinematics_needs_a_profile(tmp_path):
    path = tmp_path / "delta.ini"
    path.write_text((CONFIGS / "xyz.ini").read_text().replace("trivkins coordinates=XYZ", "lineardeltakins"))
    with pytest.raises(IngestError, match="no shipped machine profile for kinematics 'lineardeltakins'"):
        profile_for_ini(MachineIni.read(path))


def test_gcode_error_becomes_program_error_with_file_and_line(tmp_path):
    program = tmp_path / "p.ngc"
    program.write_text("G21\nF1000\nG1 X10\nG1 X2000\nM2\n")
    report = {"ok": False, "errors": [{"kind": "error", "text": "Linear move on line 4 would exceed "
                                       "X's positive limit", "motion_line": 0}], "abort": "x"}
    err = session_error(report, program)
    assert isinstance(err, ProgramError)
    assert err.line == 4 and err.file == str(program)
    assert "would exceed X's positive limit" in str(err)
    assert session_error({"ok": True, "errors": []}, program) is None
    aborted = session_error({"ok": False, "errors": [], "phase": "run", "abort": "timed out"}, program)
    assert isinstance(aborted, IngestError) and "timed out" in str(aborted)


def test_a_stop_is_an_error_only_when_nothing_was_sampled(tmp_path):
    program = tmp_path / "p.ngc"
    stopped = {"ok": False, "errors": [], "phase": "startup", "stopped": True}
    assert session_error(stopped, program) is None  # a shorter recording
    err = session_error(stopped, program, sampled=False)
    assert isinstance(err, IngestError) and err.file == str(program)
    assert "nothing was written" in str(err)


def test_error_line_falls_back_to_the_interpreter_position(tmp_path):
    program = tmp_path / "p.ngc"
    program.write_text("G21\nG1 X1 F100\n")
    err = program_error({"errors": [{"text": "Bad number format", "read_line": 2}]}, program)
    assert err.line == 2


def test_namespace_setup_binds_back_paths_under_tmp_only():
    from feedlog.ingest.linuxcnc_session import HOST_TMP, namespace_setup

    plain = namespace_setup("/work/main", "/var/tmp/x")
    assert plain.startswith("mount -t tmpfs tmpfs /tmp") and HOST_TMP not in plain
    kept = namespace_setup("/tmp/ci/main/.venv", "/tmp/ci/main/recordings/configs", "/tmp/other/file.ini")
    assert kept.startswith(f"mkdir -p {HOST_TMP} && mount --bind /tmp {HOST_TMP} && mount -t tmpfs tmpfs /tmp")
    assert kept.count("mount --bind") == 3  # the host /tmp, then /tmp/ci and /tmp/other once each
    assert f"mount --bind {HOST_TMP}/ci /tmp/ci" in kept and f"mount --bind {HOST_TMP}/other /tmp/other" in kept


def test_subroutine_path_is_written_absolute_before_the_ini_own(tmp_path):
    (tmp_path / "subs").mkdir()
    src = (CONFIGS / "xyz.ini").read_text().replace("PARAMETER_FILE = sim.var\n",
                                                    "PARAMETER_FILE = sim.var\nSUBROUTINE_PATH = mine:/abs/lib\n")
    path = tmp_path / "m.ini"
    path.write_text(src)
    ini = MachineIni.read(path)
    assert ini.subroutine_dirs() == [tmp_path.resolve() / "mine", Path("/abs/lib")]
    text = ini.rewritten(display="d", recorder=tmp_path / "record.tcl", subroutine_path=(tmp_path / "subs",))
    found = [line for line in text.splitlines() if line.startswith("SUBROUTINE_PATH")]
    # one key (LinuxCNC reads the first), in [RS274NGC], the given folder first, the INI's relative one absolute
    assert found == [f"SUBROUTINE_PATH = {tmp_path.resolve() / 'subs'}:{tmp_path.resolve() / 'mine'}:/abs/lib"]
    section = text.split("[RS274NGC]", 1)[1].split("[", 1)[0]
    assert found[0] in section


def test_subroutine_path_adds_the_section_an_ini_lacks(tmp_path):
    src = (CONFIGS / "xyz.ini").read_text().replace("[RS274NGC]\nPARAMETER_FILE = sim.var\n", "")
    path = tmp_path / "m.ini"
    path.write_text(src)
    ini = MachineIni.read(path)
    assert "SUBROUTINE_PATH" not in ini.rewritten(display="d", recorder=tmp_path / "r.tcl")
    text = ini.rewritten(display="d", recorder=tmp_path / "r.tcl", subroutine_path=(tmp_path,))
    assert text.rstrip().endswith(f"[RS274NGC]\nSUBROUTINE_PATH = {tmp_path.resolve()}")
