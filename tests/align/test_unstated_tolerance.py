"""Where the program states no blending tolerance, align measures the machine's rounding instead of refusing."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from feedlog.align import align_recording
from feedlog.cli import main
from feedlog.errors import AlignmentError
from feedlog.ingest.readers import ImportOptions, read_source
from feedlog.toolpath import load_program

REAL = Path(__file__).resolve().parents[1] / "fixtures" / "ingest" / "real"


@pytest.fixture(scope="module")
def sinumerik():
    return read_source(REAL / "sinumerik_trace.csv", ImportOptions(preset="sinumerik-trace"))


def _same_part_in_rs274(mode: str):
    """The fixture's part in LinuxCNC's dialect, on the same file lines as the .mpf (its line stream)."""
    text = "G21 G90 G17\n" + "(pad)\n" * 7 + (
        f"N60 G0 X0 Y0 Z5\nN70 {mode} G1 Z-1 F500\nN80 X80 F2000\nN90 Y40\nN100 G2 X60 Y60 R20\n"
        "N110 G1 X0\n(msg)\nN130 Y0\nN140 G0 Z5\nM2\n")
    return load_program(text, name=f"part {mode}.ngc")


def test_sinumerik_trace_aligns_with_one_command_and_reports_its_rounding(tmp_path, capsys):
    rec = tmp_path / "s.mcap"
    assert main(["import", str(REAL / "sinumerik_trace.csv"), "--preset", "sinumerik-trace",
                 "--program", str(REAL / "sinumerik_part.mpf"), "-o", str(rec)]) == 0
    capsys.readouterr()
    assert main(["align", str(rec), "-o", str(tmp_path / "a"), "-q"]) == 0
    assert "rounds corners the program gives no tolerance for by up to 0.114 mm" in capsys.readouterr().out
    report = json.loads((tmp_path / "a" / "s" / "report.json").read_text())
    rounding = report["unstated_tolerance"]
    assert 0.1 < rounding["dist_max_mm"] < 0.13 and rounding["dist_p95_mm"] < 0.05
    assert report["match"]["matched"] == report["match"]["cl_points"]
    assert any("states no blending tolerance" in w for w in report["warnings"])
    # a bound below what the machine did refuses, naming the corners
    assert main(["align", str(rec), "-o", str(tmp_path / "b"), "-q", "--unstated-tol-mm", "0.06"]) == 2
    assert "farther than their tolerance" in capsys.readouterr().err


def test_a_stated_tolerance_stays_strict_on_the_same_motion(sinumerik):
    """Bare G64 (no P) lets the corners be measured; G64 P0.01 states a bound they break."""
    bare = align_recording(sinumerik, _same_part_in_rs274("G64"))
    assert bare.report["unstated_tolerance"]["dist_max_mm"] == pytest.approx(0.114, abs=0.01)  # beyond the chords
    assert bare.cycle_time_s == pytest.approx(align_recording(sinumerik, REAL / "sinumerik_part.mpf").cycle_time_s)
    with pytest.raises(AlignmentError, match=r"farther than their tolerance.*block \d+ \(line 1[14]\)"):
        align_recording(sinumerik, _same_part_in_rs274("G64 P0.01"))


def test_exact_stop_blocks_are_not_unstated(sinumerik):
    """G61 states a tolerance of zero: no rounding is measured there, and the rounded corners are refused."""
    with pytest.raises(AlignmentError, match="farther than their tolerance"):
        align_recording(sinumerik, _same_part_in_rs274("G61"))


def test_the_bound_must_be_positive():
    with pytest.raises(AlignmentError, match="unstated_tol_mm must be > 0"):
        from feedlog.align.pipeline import AlignConfig
        AlignConfig(unstated_tol_mm=0.0)
