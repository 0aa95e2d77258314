"""`feedlog program` end to end through the CLI entry point."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pandas as pd
import pytest

from feedlog.cli import main

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def run_json(capsys, *argv) -> dict:
    assert main(["program", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_json_summary_of_a_small_program(tmp_path, capsys):
    prog = tmp_path / "p.ngc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z10\nG1 Z0 F600\nG1 X30 F1200\nG2 X30 Y-20 I0 J-10\nG4 P1.5\nM2\n")
    s = run_json(capsys, str(prog))
    assert s["blocks"] == 4 and s["kinds"]["arc_cw"] == 1 and s["kinds"]["dwell"] == 1
    assert s["length_mm"] == pytest.approx(10 + 10 + 30 + 10 * math.pi)
    rapid_s = 10 / 6000 * 60  # linuxcnc-xyz rapid rate 6000 mm/min
    assert s["cam_time_s"] == pytest.approx(rapid_s + 1.0 + 30 / 20 + 10 * math.pi / 20 + 1.5)
    assert s["bbox"]["x_mm"] == pytest.approx([0, 40], abs=1e-6)  # the arc bulges to x = 40
    assert s["feed_mm_min"] == [600, 1200]
    assert s["warnings"] == []


def test_text_summary_and_parquet_output_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "blocks.parquet"
    assert main(["program", str(EXAMPLES / "pocket.ngc"), "--parquet", str(out)]) == 0
    text = capsys.readouterr().out
    assert "CAM time" in text and "motion blocks" in text
    table = pd.read_parquet(out)
    assert len(table) == 29 and table["kind"].astype(str).eq("arc_cw").sum() == 3  # to the M30; its closing % not a row
    assert table["line"].max() == len((EXAMPLES / "pocket.ngc").read_text().splitlines()) - 1
    before = out.stat().st_mtime_ns
    assert main(["program", str(EXAMPLES / "pocket.ngc"), "--parquet", str(out)]) == 2
    assert "exists" in capsys.readouterr().err and out.stat().st_mtime_ns == before
    assert main(["program", str(EXAMPLES / "pocket.ngc"), "--parquet", str(out), "--overwrite"]) == 0


def test_bad_program_is_one_line_naming_file_line_and_code(tmp_path, capsys):
    prog = tmp_path / "bad.ngc"
    prog.write_text("G1 X1 F100\nG38.2 Z-1\nM2\n")
    assert main(["program", str(prog)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"{prog}:2" in err and "G38.2" in err and "probing" in err
    s = run_json(capsys, str(prog), "--lenient")
    assert {u["code"] for u in s["unsupported"]} == {"G38.2"} and s["warnings"]


def test_five_axis_example_with_its_profile(capsys):
    s = run_json(capsys, str(EXAMPLES / "fiveaxis_ac.ngc"), "--profile", "linuxcnc-xyzac")
    assert s["five_axis"] and s["blocks"] > 10 and "a_deg" in s["bbox"] and "c_deg" in s["bbox"]


def test_plane_arcs_example(capsys):
    s = run_json(capsys, str(EXAMPLES / "arcs_g18_g19.ngc"))
    assert s["kinds"]["arc_cw"] + s["kinds"]["arc_ccw"] >= 4


def test_lenient_json_stays_valid_json_when_feeds_are_missing(tmp_path, capsys):
    prog = tmp_path / "nofeed.ngc"
    prog.write_text("G0 X1\nG1 X2\nG1 X3 F60\n")
    assert main(["program", str(prog)]) == 2
    assert "F" in capsys.readouterr().err
    s = run_json(capsys, str(prog), "--lenient")
    assert s["blocks_without_time"] == 1 and s["cam_time_s"] == pytest.approx(1 / 6000 * 60 + 1.0)
    assert any("feed" in w for w in s["warnings"])


def test_five_axis_cl_data_with_orientation_vectors(capsys):
    path = EXAMPLES / "fiveaxis_cl_ijk.ngc"
    s = run_json(capsys, str(path))
    assert s["five_axis"] and s["blocks"] == 75 and s["warnings"] == []
    from feedlog.toolpath import block_features, parse_program
    f = block_features(parse_program(path))
    cut = f.iloc[2:-1]  # the ring: orientation leans 5-25 deg toward the centre and keeps turning
    assert (cut["ori_arc_deg"] > 0.4).all() and (cut["sin_rot"].between(0.08, 0.43)).all()


def test_without_a_profile_the_program_picks_one_by_its_axes_and_says_so(capsys):
    s = run_json(capsys, str(EXAMPLES / "fiveaxis_ac.ngc"))
    assert s["profile"] == "linuxcnc-xyzac" and "moves A, C" in s["profile_choice"]
    s = run_json(capsys, str(EXAMPLES / "pocket.ngc"))
    assert s["profile"] == "linuxcnc-xyz" and "X, Y, Z only" in s["profile_choice"]
    assert main(["program", str(EXAMPLES / "fiveaxis_ac.ngc"), "--profile", "linuxcnc-xyz"]) == 2
    assert "does not have" in capsys.readouterr().err


def test_program_with_subroutine_files_along_the_given_path(tmp_path, capsys):
    subs = tmp_path / "subs"
    subs.mkdir()
    (subs / "drill.ngc").write_text("o<drill> sub\nG81 R1 Z-#1\no<drill> endsub\nM2\n")
    prog = tmp_path / "main.ngc"
    prog.write_text("G21 F300\nG0 X0 Y0 Z5\no<drill> call [3]\nG0 X10\no<drill> call [4]\nG80\nM2\n")
    assert main(["program", str(prog)]) == 2
    assert "o<drill>" in capsys.readouterr().err
    s = run_json(capsys, str(prog), "--subroutine-path", str(subs))
    assert s["kinds"]["linear"] == 2 and s["bbox"]["z_mm"][0] == -4.0
