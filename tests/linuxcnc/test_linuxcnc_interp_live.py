"""On the real kernel, for programs that need the interpreter: the recorder sees the end of programs that
end in canned cycles, and finds subroutine files along the subroutine path it gives LinuxCNC."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from feedlog.align import align_recording
from feedlog.errors import ProgramError
from feedlog.ingest import read_recording
from feedlog.ingest.linuxcnc import record_linuxcnc
from feedlog.ingest.linuxcnc_capture import load_capture, motion_span
from feedlog.ingest.linuxcnc_session import MachineIni, cleanup, isolation_available, run_session
from feedlog.ingest.subroutine_files import load_recorded_program

pytestmark = pytest.mark.linuxcnc

CONFIGS = Path(__file__).resolve().parents[2] / "recordings" / "configs"
ISOLATE = os.geteuid() == 0 and isolation_available() is None

# programs that end inside or right after a canned cycle (LINUXCNC.md warned that a recorder waiting for
# interpreter idle, empty queue, in position and execution done may not see such an end)
ENDINGS = {
    "no_g80.ngc": "G21 G90 G0 Z10\nG0 X0 Y0\nF600\nG99 G81 X10 Y10 R2 Z-4\nX20\nM2\n",
    "percent_no_m2.ngc": "%\nG21 G90 G0 Z10\nF600\nG98 G81 X10 Y10 R2 Z-4\nX20\n%\n",
    "g91_l3.ngc": "G21 G90 G0 Z10\nF600\nG91 G98 G81 X5 Y0 R-8 Z-4 L3\nG90\nM2\n",
    "g83_in_place.ngc": "G21 G90 G0 X0 Y0 Z2\nF600\nG98 G83 R2 Z-6 Q2\nG80\nM2\n",
}


def test_the_end_of_a_program_ending_in_canned_cycles_is_seen(tmp_path):
    ini = MachineIni.read(CONFIGS / "xyz.ini")
    for name, text in ENDINGS.items():
        program = tmp_path / name
        program.write_text(text)
        session = run_session(ini, program, isolate=ISOLATE, timeout_s=30)
        try:
            report = session.report
            assert report["ok"], (name, report.get("abort"))
            # what LinuxCNC reports when the driver saw the end: every flag of the end condition set
            end = report["end_state"]
            assert end["interp_state"] == 1 and end["queue"] == 0 and end["inpos"] and end["exec_state"] == 2, end
            streams, missing = load_capture(session.sample_files, session.layout, period_ns=ini.servo_period_ns,
                                            linear_units="mm", source=name)
            assert missing == 0
            t = streams["axes"]["t_ns"].to_numpy()
            span = motion_span(streams["axes"], ini.servo_period_ns)
            tail_s = (t[-1] - t[span.last]) / 1e9
            assert 0.02 <= tail_s < 0.3, (name, tail_s)        # seen within a few polls, no time-out
            assert streams["line"]["line"].to_numpy()[-1] == 0  # motion.program-line is 0 once it is over
        finally:
            cleanup(session)


def test_a_subroutine_file_is_found_along_the_given_path_and_aligned(tmp_path):
    subs = tmp_path / "lib"
    subs.mkdir()
    (subs / "slot.ngc").write_text("o<slot> sub\nG0 X#1 Y#2\nG1 Z-1 F900\nG1 X[#1+6]\nG0 Z2\n"
                                   "o<slot> endsub\nM2\n")
    program = tmp_path / "main.ngc"
    # main lines 2-5 are moves too: the same numbers as the sub file's moves
    program.write_text("G21 G90 G64 P0.01\nG0 Z2\nG0 X-5 Y-5\nG1 Z0 F900\nG0 Z2\n#1 = 0\n"
                       "o10 repeat [3]\no<slot> call [#1*10] [5]\n#1 = [#1 + 1]\no10 endrepeat\nG0 X0 Y0\nM2\n")
    with pytest.raises(ProgramError, match="slot"):   # LinuxCNC does not look in the program's folder
        record_linuxcnc(CONFIGS / "xyz.ini", program, tmp_path / "x.mcap", isolate=ISOLATE, timeout_s=30)
    out = tmp_path / "main.mcap"
    summary = record_linuxcnc(CONFIGS / "xyz.ini", program, out, isolate=ISOLATE, timeout_s=30,
                              subroutine_path=(subs,))
    assert summary["status"] == "complete"
    rec = read_recording(out)
    assert rec.attachments["subroutines/slot.ngc"] == (subs / "slot.ngc").read_bytes()
    # LinuxCNC's line inside the sub file is the sub file's own line: 2-5, never the caller's line 8
    runs = rec.streams["line"]["line"].to_numpy()
    shown = set(np.unique(runs)) - {0}
    assert {2, 3, 4, 5} <= shown and 8 not in shown
    motion = load_recorded_program(rec, name="main.ngc").motion.reset_index(drop=True)
    blocks = align_recording(rec).blocks
    axes = rec.streams["axes"].set_index("t_ns")
    for k in np.flatnonzero(motion["file"].to_numpy() == "subroutines/slot.ngc"):
        b = blocks.iloc[k]
        assert b["seen"], k
        at_end = axes.index[min(axes.index.searchsorted(b["t_end_ns"]), len(axes) - 1)]
        want = motion.loc[k, ["x_mm", "y_mm", "z_mm"]].to_numpy(dtype=float)
        assert np.linalg.norm(axes.loc[at_end, ["x_mm", "y_mm", "z_mm"]].to_numpy(dtype=float) - want) < 0.05, k
