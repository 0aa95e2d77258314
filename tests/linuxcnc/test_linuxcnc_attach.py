"""Attaching feedlog's recorder to a LinuxCNC that someone else started (attach_scenario.py)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from feedlog.ingest import PROGRAM_ATTACHMENT, read_recording
from feedlog.ingest.linuxcnc_session import UNSHARE, isolation_available, namespace_setup

pytestmark = pytest.mark.linuxcnc

HERE = Path(__file__).resolve().parent
CONFIGS = HERE.parents[1] / "recordings" / "configs"
PROGRAM = "G21 G90 G64 P0.01\nF3000\nG0 X0 Y0 Z0\nG1 X20 Y0\nG1 X20 Y20\nG1 X0 Y0\nM2\n"


@pytest.mark.parametrize("machine_hal", ["plain", "uses-integ"])
def test_attach_records_the_running_program_until_it_ends(tmp_path_factory, machine_hal):
    """`uses-integ`: the machine's HAL already loads integ, so the recorder runs without its clock."""
    # the scenario may run in a private /tmp: keep its files where both sides see them
    base = Path("/var/tmp") if Path("/var/tmp").is_dir() else None
    tmp = tmp_path_factory.mktemp("attach") if base is None else Path(
        __import__("tempfile").mkdtemp(prefix="feedlog-attach-test-", dir=base))
    tmp.chmod(0o755)
    program, out, result = tmp / "tri.ngc", tmp / "tri.mcap", tmp / "result.json"
    program.write_text(PROGRAM)
    args = [sys.executable, str(HERE / "attach_scenario.py"), str(CONFIGS / "xyz.ini"), str(program), str(out),
            str(result)] + (["--machine-uses-integ"] if machine_hal == "uses-integ" else [])
    if os.geteuid() == 0 and isolation_available() is None:
        # the venv, this checkout and the configs stay visible even when they live under /tmp
        setup = namespace_setup(sys.prefix, HERE, CONFIGS)
        cmd = [*UNSHARE, "sh", "-c", setup + ' && exec "$@"', "sh", *args]
    else:
        cmd = args
    try:
        subprocess.run(cmd, check=True, timeout=150, capture_output=True)
        outcome = json.loads(result.read_text())
        assert "error" not in outcome, outcome.get("error", "") + outcome.get("linuxcnc_log", "")
        assert outcome["operator"]["ok"], outcome["operator"]
        summary = outcome["summary"]
        assert summary["dropped_frames"] == 0
        rec = read_recording(out)
        t = rec.stream("axes")["t_ns"].to_numpy()
        assert np.all(np.diff(t) == 1_000_000)
        assert {4, 5, 6} <= set(rec.stream("line")["line"].tolist())
        assert rec.attachments[PROGRAM_ATTACHMENT].decode() == PROGRAM
        # 20 + 20 + 28.3 mm at 50 mm/s with accelerations: ~1.5 s, as LinuxCNC itself counted it
        assert 1.3 < summary["cycle_time_s"] < 2.0
        if machine_hal == "plain":
            assert abs(summary["cycle_time_s"] - summary["linuxcnc_motion_time_s"]) <= 0.001
        else:
            assert not np.isfinite(summary["linuxcnc_motion_time_s"])
        # samplers joined row by row: joint commands trail the planner by exactly 2 servo periods
        x, j0 = rec.stream("axes")["x_mm"].to_numpy(), rec.stream("joints")["j0_pos"].to_numpy()
        assert np.abs(j0[2:] - x[:-2]).max() < 1e-3 < np.abs(j0[1:] - x[:-1]).max()
    finally:
        if base is not None:
            import shutil
            shutil.rmtree(tmp, ignore_errors=True)
