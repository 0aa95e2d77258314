"""`feedlog sim` end to end through the CLI registry."""

from __future__ import annotations

import json

import pandas as pd

from feedlog.cli import main

PROGRAM = "G21 G90 G61\nG1 X40 F3000\nG1 Y20\nM2\n"


def test_json_summary_and_parquet(tmp_path, capsys):
    src = tmp_path / "p.ngc"
    src.write_text(PROGRAM)
    out = tmp_path / "series.parquet"
    assert main(["sim", str(src), "--profile", "linuxcnc-xyz", "--json", "--out", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["cycle_time_s"] > summary["cam_time_s"] > 0
    assert summary["blocks"] >= 2
    series = pd.read_parquet(out)
    assert {"t_ns", "x_mm", "y_mm", "feed_mm_min", "block", "line"} <= set(series.columns)
    # refuses to overwrite without --force
    assert main(["sim", str(src), "--profile", "linuxcnc-xyz", "--out", str(out)]) == 2
    assert "exists" in capsys.readouterr().err


def test_set_changes_the_result(tmp_path, capsys):
    src = tmp_path / "p.ngc"
    src.write_text(PROGRAM)
    main(["sim", str(src), "--profile", "linuxcnc-xyz", "--json"])
    base = json.loads(capsys.readouterr().out)["cycle_time_s"]
    main(["sim", str(src), "--profile", "linuxcnc-xyz", "--json", "--set", "feed_override.override=0.5"])
    slow = json.loads(capsys.readouterr().out)["cycle_time_s"]
    assert slow > 1.5 * base


def test_bad_input_is_one_line(tmp_path, capsys):
    src = tmp_path / "p.ngc"
    src.write_text(PROGRAM)
    assert main(["sim", str(src), "--profile", "nope"]) == 2
    assert main(["sim", str(src), "--profile", "linuxcnc-xyz", "--set", "warp.x=1"]) == 2
    err = capsys.readouterr().err
    assert "unknown machine profile" in err and "unknown sim mechanism" in err
    assert "Traceback" not in err
