"""`feedlog diagnose` from the command line: the outputs and the --json contract, and every input it
cannot diagnose refused with one error line, exit code 2 and nothing written."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from feedlog.cli import main
from feedlog.ingest import read_recording, write_recording
from feedlog.ingest.recording import PROGRAM_ATTACHMENT, Recording
from feedlog.profile import load_profile
from tests.diagnose.conftest import PROGRAMS
from tests.viz.conftest import rrd_content

CONTRACT = {"profile", "recordings", "error_before_pct", "error_after_pct", "feedback_rms_before_mm",
            "feedback_rms_after_mm", "held_out", "levels", "findings", "unexplained", "profile_out"}
FINDING = {"parameter", "profile_value", "fitted_value", "unit", "interval", "gain_pct", "evidence", "kind"}


@pytest.fixture(scope="module")
def xacc_files(tmp_path_factory, hidden):
    folder = tmp_path_factory.mktemp("xacc")
    paths = []
    for rec in hidden("xacc", values={"axes.x.acc_max": 300.0}):
        path = folder / rec.source
        write_recording(path, rec)
        paths.append(path)
    return paths


def _run(args, capsys):
    code = main(["diagnose", *map(str, args)])
    out, err = capsys.readouterr()
    return code, out, err


def test_json_contract_files_and_an_extended_profile_every_command_takes(xacc_files, tmp_path, capsys):
    out = tmp_path / "dx"
    code, stdout, _ = _run([*xacc_files, "--profile", "linuxcnc-xyz", "-o", out, "--json", "--no-learned"], capsys)
    assert code == 0
    data = json.loads(stdout)
    assert CONTRACT <= set(data)
    assert data["profile"] == "linuxcnc-xyz" and len(data["recordings"]) == 2
    assert data["error_before_pct"] < -10 and abs(data["error_after_pct"]) < 1
    assert [f["parameter"] for f in data["findings"]] == ["axes.x.acc_max"]
    assert FINDING <= set(data["findings"][0])
    assert data["findings"][0]["kind"] == "parameter" and data["findings"][0]["unit"] == "mm/s^2"
    assert data["profile_out"] == str(out / "profile.toml")
    assert sorted(p.name for p in out.iterdir()) == ["diagnose.json", "diagnose.rrd", "plots", "profile.toml",
                                                      "report.md"]
    assert json.loads((out / "diagnose.json").read_text())["findings"] == data["findings"]
    report = (out / "report.md").read_text()
    assert report.startswith("# feedlog diagnose") and "axes.x.acc_max" in report
    assert all((out / "plots" / name).stat().st_size > 1000 for name in ("evidence.png", "segment_residuals.png"))
    content = rrd_content(out / "diagnose.rrd")  # read back with Rerun's own reader
    rec = Path(data["recordings"][0]).stem
    assert {f"/diagnose/{rec}/path/before", f"/diagnose/{rec}/path/after"} <= set(content)
    assert all(content[f"/diagnose/{rec}/speed/{s}"]["rows"] > 1000 for s in ("measured", "before", "after"))
    assert not list(tmp_path.glob(".dx.*"))  # no temporary folder left
    # the extended profile is a profile: load it, simulate with it
    ext = load_profile(out / "profile.toml")
    assert ext.axes["x"].acc_max == pytest.approx(300, rel=0.05)
    code = main(["sim", str(PROGRAMS / "corners_f3000_p001.ngc"), "--profile", str(out / "profile.toml"), "--json"])
    sim = json.loads(capsys.readouterr().out)
    assert code == 0 and sim["cycle_time_s"] == pytest.approx(7.90, rel=0.01)


def test_text_summary_puts_the_answer_first(xacc_files, capsys):
    code, stdout, _ = _run([*xacc_files, "--profile", "linuxcnc-xyz", "--no-learned", "-q"], capsys)
    lines = stdout.splitlines()
    assert code == 0
    assert lines[0].startswith("simulation ") and "short on 2 recordings" in lines[0]
    assert lines[1].startswith("cause 1: axes.x.acc_max = ") and "profile 1000 mm/s^2" in lines[1]
    assert lines[2].startswith("extended profile")


def test_the_output_folder_is_not_overwritten_without_asking(xacc_files, tmp_path, capsys):
    out = tmp_path / "dx"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    code, _, err = _run([*xacc_files, "--profile", "linuxcnc-xyz", "-o", out, "--no-learned"], capsys)
    assert code == 2 and "exists; pass --overwrite" in err
    assert [p.name for p in out.iterdir()] == ["keep.txt"]


def _motionless(src: Recording) -> Recording:
    axes = src.streams["axes"].copy()
    for col in ("x_mm", "y_mm", "z_mm"):
        axes[col] = float(axes[col].iloc[0])
    return Recording(streams={"axes": axes}, metadata=dict(src.metadata), attachments=dict(src.attachments))


def _without_program(src: Recording) -> Recording:
    return Recording(streams=dict(src.streams), metadata=dict(src.metadata),
                     attachments={k: v for k, v in src.attachments.items() if k != PROGRAM_ATTACHMENT})


def _other_machine(src: Recording) -> Recording:
    return Recording(streams=dict(src.streams), metadata=dict(src.metadata),
                     attachments={**src.attachments, "machine.ini": b"[EMC]\nMACHINE = another\n"})


def _no_axes(src: Recording) -> Recording:
    """Neither positions nor a line stream (a line stream alone gets the block-level diagnosis)."""
    return Recording(streams={k: v for k, v in src.streams.items() if k not in ("axes", "line")},
                     metadata=dict(src.metadata), attachments=dict(src.attachments))


def _short_line_stream(src: Recording) -> Recording:
    """A line stream and no positions, too short to place a stretch on the program."""
    return Recording(streams={"line": src.streams["line"].iloc[:2]}, metadata=dict(src.metadata),
                     attachments=dict(src.attachments))


BAD = [
    # no program anywhere is no longer an error: what the data alone says (tests/diagnose/test_no_program.py)
    ("no program but --program names a missing file", _without_program, ["--program", "missing.ngc",
                                                                         "--profile", "linuxcnc-xyz"], "missing.ngc"),
    ("no motion", _motionless, [], "shows no motion"),
    ("no positions", _no_axes, [], "has no 'axes' stream"),
    ("line stream too short", _short_line_stream, [], "could be placed"),
    ("wrong kinematics", lambda r: r, ["--profile", "linuxcnc-xyzac"], "no A, C positions"),
    ("unknown profile", lambda r: r, ["--profile", "no-such-machine"], "unknown machine profile"),
]


@pytest.mark.parametrize(("what", "make", "extra", "message"), BAD, ids=[b[0] for b in BAD])
def test_input_it_cannot_diagnose_is_one_error_line_exit_2_nothing_written(xacc_files, tmp_path, capsys, what, make,
                                                                           extra, message):
    bad = tmp_path / "bad.mcap"
    write_recording(bad, make(read_recording(xacc_files[0])))
    out = tmp_path / "dx"
    args = [bad, *extra] if extra else [bad, "--profile", "linuxcnc-xyz"]
    code, stdout, err = _run([*args, "-o", out, "--no-learned", "-q"], capsys)
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists() and not list(tmp_path.glob(".dx*"))


def test_recordings_of_two_machines_are_refused(xacc_files, tmp_path, capsys):
    first, other = tmp_path / "first.mcap", tmp_path / "other.mcap"
    rec = read_recording(xacc_files[0])
    rec.attachments["machine.ini"] = b"[EMC]\nMACHINE = one\n"
    write_recording(first, rec)
    write_recording(other, _other_machine(read_recording(xacc_files[1])))
    code, _, err = _run([first, other, "--profile", "linuxcnc-xyz", "--no-learned", "-q"], capsys)
    assert code == 2 and "recorded on another machine" in err


def test_a_five_axis_recording_under_a_three_axis_profile_is_refused(tmp_path, capsys):
    from feedlog.sim import MeasurementModel, measure, simulate
    from feedlog.toolpath import parse_program

    text = (PROGRAMS / "mix5ax_011.ngc").read_text()
    rec = measure(simulate(parse_program(text), "linuxcnc-xyzac"), MeasurementModel(rate_hz=100, rest_s=0.5),
                  program_text=text)
    path = tmp_path / "five.mcap"
    write_recording(path, rec)
    code, _, err = _run([path, "--profile", "linuxcnc-xyz", "--no-learned", "-q"], capsys)
    assert code == 2 and "moves the A axis" in err


def test_the_command_is_registered_with_help():
    proc = subprocess.run([sys.executable, "-m", "feedlog", "diagnose", "--help"], capture_output=True, text=True)
    assert proc.returncode == 0 and "--profile" in proc.stdout and "--json" in proc.stdout


def _full_disk():  # in the child: a file may not grow past 100 kB (as a nearly full disk)
    import resource
    import signal

    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (100_000, 100_000))


def test_an_output_that_cannot_be_written_is_exit_1_and_leaves_nothing(xacc_files, tmp_path):
    out = tmp_path / "dx"
    proc = subprocess.run([sys.executable, "-m", "feedlog", "diagnose", *map(str, xacc_files), "--profile",
                           "linuxcnc-xyz", "-o", str(out), "--no-learned", "-q"], capture_output=True, text=True,
                          preexec_fn=_full_disk, timeout=600)
    assert proc.returncode == 1, (proc.stdout, proc.stderr)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("feedlog diagnose: error: ") and "cannot write" in lines[0]
    assert list(tmp_path.iterdir()) == []


def test_worker_processes_give_the_same_diagnosis(xacc_files, capsys):
    runs = []
    for jobs in ("1", "2"):
        code, stdout, _ = _run([*xacc_files, "--profile", "linuxcnc-xyz", "--json", "--no-learned", "-j", jobs], capsys)
        assert code == 0
        runs.append(json.loads(stdout))
    assert runs[0]["findings"] == runs[1]["findings"] and runs[0]["levels"]["cycle"] == runs[1]["levels"]["cycle"]


def test_a_recording_with_a_line_stream_and_no_positions_gets_the_block_level(xacc_files, tmp_path, capsys):
    src = read_recording(xacc_files[0])
    lines_only = tmp_path / "lines.mcap"
    write_recording(lines_only, Recording(streams={"line": src.streams["line"]}, metadata=dict(src.metadata),
                                          attachments=dict(src.attachments)))
    code, stdout, err = _run([lines_only, "--profile", "linuxcnc-xyz", "-o", tmp_path / "dx", "-q"], capsys)
    assert code == 0, err
    assert "line stream only" in stdout and "the block level cannot see" in stdout
    assert {p.name for p in (tmp_path / "dx").iterdir()} == {"report.md", "diagnose.json", "profile.toml"}
