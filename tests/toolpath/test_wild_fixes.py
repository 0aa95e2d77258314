"""What the programs of the wild (tests/fixtures/programs/wild) showed feedlog misreading, each with the
expected motion derived here: the dialect of a Fusion 360 program, LinuxCNC's G10 L1 tool entries, full
circles without axis words, Sinumerik values computed in a plain-looking line, Sinumerik splines and an
unreadable loop end named where they are, Fanuc's WH abbreviation of WHILE."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from feedlog.errors import ProgramError
from feedlog.toolpath import load_program
from feedlog.toolpath.dialects import detect
from feedlog.toolpath.interp import interpret
from feedlog.toolpath.interp.fanuc import interpret_fanuc

from .reference import TOOLS, available, compare, reference

MISSING = available()
needs_linuxcnc = pytest.mark.skipif(MISSING is not None and os.environ.get("FEEDLOG_REQUIRE_LINUXCNC") != "1",
                                    reason=MISSING or "")

FUSION_HEADER = "%\n(1001)\n(T1 D=6. CR=0. - ZMIN=-5. - FLAT END MILL)\n(SOFT JAWS, G500 FIXTURE)\n"


@pytest.mark.parametrize("body, name, dialect", [
    (FUSION_HEADER + "G90 G94 G17\nG21\nG0 X1 Y2\nM30\n", "part.nc", "rs274ngc"),
    (FUSION_HEADER + "G90 G94 G17\nG21\nG53 G0 Z0.\nG0 X1 Y2\nM30\n", "part.nc", "fanuc"),
    (FUSION_HEADER + "G90 G94 G17\nG21\nG53 G0 Z0.\nG0 X1 Y2\nM30\n", "part.ngc", "rs274ngc"),
    ("#<depth> = 2\nG28\nG0 Z#<depth>\nM2\n", None, "rs274ngc"),
    ("G1 X10 F100\nG2 X20 Y10 CR=10\nM30\n", None, "sinumerik"),
    ("N10 MSG(\"(a comment in a call)\")\nG1 X1 F100\nM30\n", None, "sinumerik"),
    ("G1 X1 F100 (SOFT JAWS)\nG28 Z0\nM30\n", None, "fanuc"),
])
def test_comments_do_not_make_a_dialect_and_ngc_files_stay_rs274(body, name, dialect):
    assert detect(body, name) == dialect


def test_fusion_header_program_reads_as_rs274ngc_with_its_moves():
    program = load_program(FUSION_HEADER + "G90 G94 G17\nG21\nG0 X1 Y2\nG1 Z-1 F300\nM30\n")
    assert program.metadata["dialect"] == "rs274ngc" and not program.warnings
    assert program.motion[["x_mm", "y_mm", "z_mm"]].to_numpy().tolist() == [[1, 2, 0], [1, 2, -1]]


G10_L1 = """G21 G90 G17
T2 M6
G43 H2
G0 X0 Y0 Z10
G10 L1 P2 Z5.0 R[3/2]
G0 Z8
G43 H2
G0 Z8
G20
G10 L1 P3 Z0.1 X0.05
T3 M6
G43
G0 X1 Y1 Z1
G21
G41 D2
G1 X20 Y0 F500
G1 X20 Y20
G40
G1 X40 Y40
M2
"""


def test_g10_l1_sets_the_tool_entry_that_g43_and_compensation_read_next(tmp_path):
    path = tmp_path / "g10l1.ngc"
    path.write_text(G10_L1)
    program = interpret(path, tool_table=TOOLS)          # T2: 1.0 mm long, 0.04 mm across in the table
    rows = program.motion.set_index("line")
    assert rows.loc[6, "tool_z_mm"] == pytest.approx(1.0)    # the old entry until G43 reads it again
    assert rows.loc[8, "tool_z_mm"] == pytest.approx(5.0)
    assert rows.loc[13, "tool_x_mm"] == pytest.approx(0.05 * 25.4) and rows.loc[13, "tool_z_mm"] == pytest.approx(2.54)
    # G41 with D2 = R 1.5 mm: left of the path along +X, then along +Y (an outside corner arc)
    end = program.motion[program.motion["line"] == 17].iloc[-1]
    assert end["x_mm"] == pytest.approx(20 - 1.5) and end["y_mm"] == pytest.approx(20)
    assert load_program(path).motion["x_mm"].tolist() == pytest.approx(
        interpret(path).motion["x_mm"].tolist())     # load_program routes G10 L1 to the interpreter


@pytest.mark.parametrize("text, message", [
    ("G21\nG10 L1 P2\nM2\n", "without offsets"),
    ("G21\nG10 L1 P99 Z1\nM2\n", "tool 99 not found"),
])
def test_g10_l1_errors_name_the_line(tmp_path, text, message):
    path = tmp_path / "bad.ngc"
    path.write_text(text)
    with pytest.raises(ProgramError, match=message) as info:
        interpret(path, tool_table=TOOLS)
    assert info.value.line == 2


@needs_linuxcnc
def test_g10_l1_matches_linuxcnc_move_by_move(tmp_path):
    path = tmp_path / "g10l1.ngc"
    path.write_text(G10_L1)
    assert not compare(interpret(path, tool_table=TOOLS).blocks, reference(path))


FULL_CIRCLE = "G21 G90 G17\nG0 X-5 Y0\nG2 I5 J0 F200\nG3 I5\nG0 Z5\nM2\n"


def test_a_full_circle_without_axis_words_returns_to_its_start():
    program = load_program(FULL_CIRCLE)
    arcs = program.motion[program.motion["kind"].isin(["arc_cw", "arc_ccw"])]
    assert len(arcs) == 2
    assert np.allclose(arcs[["x_mm", "y_mm", "cx_mm", "cy_mm"]].to_numpy(), [[-5, 0, 0, 0], [-5, 0, 0, 0]])
    assert arcs["sweep_deg"].tolist() == [360.0, 360.0]
    assert arcs["length_mm"].to_numpy() == pytest.approx([2 * math.pi * 5] * 2, rel=1e-9)


@needs_linuxcnc
def test_a_full_circle_without_axis_words_matches_linuxcnc(tmp_path):
    path = tmp_path / "circle.ngc"
    path.write_text(FULL_CIRCLE)
    assert not compare(interpret(path).blocks, reference(path))


def test_sinumerik_values_computed_in_a_line_without_other_words():
    program = load_program("G1 F100\nX=SIN(30)\nY=2*3 Z=SQRT(POT(3)+POT(4))\nX=7 DIV 2\nM30\n", dialect="sinumerik")
    assert program.motion[["x_mm", "y_mm", "z_mm"]].to_numpy() == pytest.approx(
        np.array([[0.5, 0, 0], [0.5, 6, 5], [3, 6, 5]]))


def test_a_quoted_tool_name_keeps_a_plain_sinumerik_program_plain():
    program = load_program('N10 G90 G17\nN20 T="CUTTER 10" D1\nN30 G1 X10 F100\nN40 M30\n', dialect="sinumerik")
    assert program.metadata.get("interpreter") is None


@pytest.mark.parametrize("text, line, message", [
    ("G1 X1 F100\nBSPLINE X10 Y10\nM30\n", 2, "BSPLINE (spline or polynomial interpolation) is not simulated"),
    ("G1 X1 F100\nN20 CSPLINE X10 Y10\nM30\n", 2, "CSPLINE"),
    ("G1 X0 F100\nREPEAT\nX=IC(1)\nUNTIL $AA_IW[X] > 5\nM30\n", 4, "$AA_IW"),
])
def test_sinumerik_refusals_name_what_and_where(text, line, message):
    with pytest.raises(ProgramError) as info:
        load_program(text, dialect="sinumerik", name="part.mpf")
    assert info.value.line == line and message in str(info.value)


def test_fanuc_wh_is_while():
    loop = "%\nO1\n#1=0;\n{w}[#1LT3]DO1;\nG91G1X10.F100;\n#1=#1+1;\nEND1;\nM30;\n%\n"
    short, full = interpret_fanuc(loop.format(w="WH")), interpret_fanuc(loop.format(w="WHILE"))
    assert short.motion["x_mm"].tolist() == full.motion["x_mm"].tolist() == [10.0, 20.0, 30.0]


def test_a_program_with_a_full_circle_is_refused_where_linuxcnc_refuses_it():
    """The vectorised parser reads no full circle; the interpreter, which follows LinuxCNC, must name the
    line LinuxCNC names (cncjs' full-circle example: its line 11), not the circle's."""
    with pytest.raises(ProgramError) as info:
        load_program("G21 G90 G17\nG0 X-5 Y0\nG2 I5 J0 F200\nG2 X1\nM2\n")
    assert info.value.line == 4 and "R, I, J, and K words all missing" in str(info.value)


HAAS = "%\nO1001\nT1 M6\nG187 P3 E0.01\nG103 P1\nG10 L20 P2 X100. Y-20.\n{select} G0 X1. Y2.\nG0 X5.\nM30\n%\n"


@pytest.mark.parametrize("select", ["G154 P2", "G111"])
def test_haas_g154_and_g110_g129_select_the_extended_offsets_and_smoothing_is_dropped(select):
    """What Fusion 360's Haas post writes: G187 smoothing and G103 look-ahead (no effect on the path: dropped,
    noted), G154 P1-P99 work offsets (G110-G129 = G154 P1-P20), here set by G10 L20 P2 (X100 Y-20)."""
    program = load_program(HAAS.format(select=select), name="haas.nc")
    assert program.metadata["dialect"] == "fanuc"
    motion = program.motion
    assert (motion["x_mm"] + motion["wx_mm"]).tolist() == [101.0, 105.0]
    assert (motion["y_mm"] + motion["wy_mm"]).tolist() == [-18.0, -18.0]
    assert motion["coord_system"].tolist() == [11, 11]          # 9 + P, as for G54.1 P2
    assert any("G187" in w for w in program.warnings) and any("G103" in w for w in program.warnings)
