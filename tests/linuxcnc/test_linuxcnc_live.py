"""End to end on a real LinuxCNC (linuxcnc-uspace): skipped with a reason where it is absent."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from feedlog.errors import ProgramError
from feedlog.ingest import PROFILE_ATTACHMENT, PROGRAM_ATTACHMENT, read_recording
from feedlog.ingest.linuxcnc import INI_ATTACHMENT, record_linuxcnc
from feedlog.ingest.linuxcnc_session import isolation_available

pytestmark = pytest.mark.linuxcnc

CONFIGS = Path(__file__).resolve().parents[2] / "recordings" / "configs"
# namespaces keep this run apart from any other LinuxCNC on the host, where they are permitted
ISOLATE = os.geteuid() == 0 and isolation_available() is None
SQUARE = """%
(feedlog integration test: 20 mm square, F3000)
G21 G90 G17 G94
G64 P0.01
F3000
G0 X0 Y0 Z0
G1 X20 Y0
G1 X20 Y20
G1 X0 Y20
G1 X0 Y0
M2
%
"""
SQUARE_MOVE_LINES = {7, 8, 9, 10}


@pytest.fixture(scope="module")
def square_recording(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("lcnc")
    program = tmp / "square.ngc"
    program.write_text(SQUARE)
    out = tmp / "square.mcap"
    summary = record_linuxcnc(CONFIGS / "xyz.ini", program, out, isolate=ISOLATE, timeout_s=60)
    return summary, read_recording(out)


def test_recording_is_1khz_without_missing_samples(square_recording):
    summary, rec = square_recording
    assert summary["dropped_frames"] == 0 and rec.dropped_frames == 0
    for name in ("axes", "joints", "feed", "line", "status"):
        t = rec.stream(name)["t_ns"].to_numpy()
        assert t.dtype == np.int64
        assert len(t) > 1500
        assert np.all(np.diff(t) == 1_000_000), f"stream {name} is not one sample per 1 ms servo period"
    assert rec.metadata["nominal_rate_hz"] == "1000"
    # the two samplers are joined row by row: joint commands trail the planner by 2 servo periods
    x, j0 = rec.stream("axes")["x_mm"].to_numpy(), rec.stream("joints")["j0_pos"].to_numpy()
    assert np.abs(j0[2:] - x[:-2]).max() < 1e-3 < np.abs(j0[1:] - x[:-1]).max()
    assert rec.metadata["sampler_overruns"] == "0"


def test_program_lines_and_feed_are_recorded(square_recording):
    _, rec = square_recording
    lines = set(rec.stream("line")["line"].to_numpy().tolist())
    assert SQUARE_MOVE_LINES <= lines
    feed = rec.stream("feed")
    assert feed["feed_mm_min"].max() == pytest.approx(3000.0, rel=1e-3)
    assert feed["requested_feed_mm_min"].max() == pytest.approx(3000.0, rel=1e-3)
    axes = rec.stream("axes")
    assert axes["x_mm"].max() == pytest.approx(20.0, abs=1e-6)
    assert axes["y_mm"].max() == pytest.approx(20.0, abs=1e-6)
    assert rec.attachments[PROGRAM_ATTACHMENT].decode() == SQUARE
    assert b"[EMCMOT]" in rec.attachments[INI_ATTACHMENT]
    assert b'name = "linuxcnc-xyz"' in rec.attachments[PROFILE_ATTACHMENT]


def test_cycle_time_matches_linuxcnc_motion_time_within_one_servo_period(square_recording):
    summary, rec = square_recording
    # recomputed here from the positions: first sample that moved to last sample that moved
    axes = rec.stream("axes")
    pos = axes[["x_mm", "y_mm", "z_mm"]].to_numpy()
    moved = np.flatnonzero(np.any(np.diff(pos, axis=0) != 0, axis=1)) + 1
    t = axes["t_ns"].to_numpy()
    cycle_s = (t[moved[-1]] - t[moved[0]] + 1_000_000) / 1e9
    assert cycle_s == pytest.approx(summary["cycle_time_s"], abs=1e-9)
    assert abs(cycle_s - summary["linuxcnc_motion_time_s"]) <= 0.001
    assert abs(cycle_s - float(rec.metadata["linuxcnc_motion_time_s"])) <= 0.001
    # 80 mm at 50 mm/s plus acceleration and corners: a little over 1.6 s
    assert 1.6 < cycle_s < 2.5


def test_gcode_error_is_reported_with_file_and_line(tmp_path):
    program = tmp_path / "limit.ngc"
    program.write_text("G21 G90\nF3000\nG1 X5\nG1 X2000\nM2\n")
    out = tmp_path / "limit.mcap"
    with pytest.raises(ProgramError, match=r"limit\.ngc:4: LinuxCNC: Linear move on line 4 would exceed "
                                           r"X's positive limit") as info:
        record_linuxcnc(CONFIGS / "xyz.ini", program, out, isolate=ISOLATE, timeout_s=60)
    assert info.value.line == 4
    if out.exists():  # the machine had started moving: what was recorded is kept, marked aborted
        assert read_recording(out).metadata["status"].startswith("aborted")


def test_feedlog_record_cli_runs_a_program_and_feedlog_info_reads_it(tmp_path, capsys):
    from feedlog.cli import main

    program = tmp_path / "line.ngc"
    program.write_text("G21 G90 G64 P0.01\nF3000\nG0 X0 Y0 Z0\nG1 X30 Y10\nM2\n")
    out = tmp_path / "line.mcap"
    argv = ["record", "--source", "linuxcnc", "--ini", str(CONFIGS / "xyz.ini"), str(program), "-o", str(out),
            "--timeout-s", "60"] + (["--isolate"] if ISOLATE else [])
    assert main(argv) == 0
    assert "cycle_time_s" in capsys.readouterr().out
    assert main(["record", *argv[1:]]) == 2  # refuses to overwrite
    assert "output exists" in capsys.readouterr().err
    assert main(["info", str(out)]) == 0
    info = capsys.readouterr().out
    assert "axes" in info and "1000.0 Hz" in info and "cycle_time_s" in info


def test_stop_event_stops_the_machine_and_keeps_what_was_recorded(tmp_path):
    import threading

    program = tmp_path / "long.ngc"
    program.write_text("G21 G90 G64 P0.01\nF300\nG0 X0 Y0 Z0\nG1 X100\nG1 X0\nM2\n")  # 20 s per move
    out = tmp_path / "long.mcap"
    stop = threading.Event()
    timer = threading.Timer(8.0, stop.set)  # start-up takes 1.5-4 s: the stop comes during the first move
    timer.start()
    try:
        summary = record_linuxcnc(CONFIGS / "xyz.ini", program, out, isolate=ISOLATE, timeout_s=60,
                                  stop_event=stop)
    finally:
        timer.cancel()
    assert summary["status"] == "stopped"
    rec = read_recording(out)
    assert rec.metadata["status"] == "stopped"
    x = rec.stream("axes")["x_mm"].to_numpy()
    assert 0.5 < x.max() < 99.0  # moved, but not to the end of the first move
    assert np.ptp(x[-50:]) < 1e-6  # the machine stood still at the end, it was not just the recording that ended


def test_a_stop_before_the_machine_starts_says_nothing_was_recorded(tmp_path):
    import threading

    from feedlog.errors import IngestError

    program = tmp_path / "line.ngc"
    program.write_text("G21 G90 G64 P0.01\nF1000\nG0 X0 Y0 Z0\nG1 X100\nM2\n")
    out = tmp_path / "line.mcap"
    stop = threading.Event()
    stop.set()
    with pytest.raises(IngestError, match=r"line\.ngc.*stopped before the machine started recording"):
        record_linuxcnc(CONFIGS / "xyz.ini", program, out, isolate=ISOLATE, timeout_s=60, stop_event=stop)
    assert not out.exists()


def test_timeout_keeps_what_was_recorded_and_says_so(tmp_path):
    from feedlog.errors import IngestError

    program = tmp_path / "slow.ngc"
    program.write_text("G21 G90 G64 P0.01\nF1000\nG0 X0 Y0 Z0\nG1 X100\nG1 X0\nM2\n")  # ~12 s
    out = tmp_path / "slow.mcap"
    with pytest.raises(IngestError, match=r"timed out waiting for program end.*recording up to the error kept"):
        record_linuxcnc(CONFIGS / "xyz.ini", program, out, isolate=ISOLATE, timeout_s=4)
    rec = read_recording(out)
    assert rec.metadata["status"].startswith("aborted")
    assert 0.5 < rec.stream("axes")["x_mm"].max() < 99.0
