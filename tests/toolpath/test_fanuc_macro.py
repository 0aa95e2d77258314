"""The Fanuc / Haas / Hurco (custom macro B) front-end, toolpath.interp.fanuc.

There is no open Fanuc interpreter to compare with, so the programs here follow the examples the
controllers' published manuals give (named in each test: Fanuc Series 0i-MF operator's manual, part
"Custom macro" - the sum 1..10 with IF/GOTO and with WHILE, the bolt-hole-circle macro called with G65,
M98/M99 with repeat counts and `M99 P`, the argument table of G65, the vacant-variable rules; the Fanuc
canned-cycle chapter for K repeats, G98/G99 and G91 R; the Haas mill operator's manual, sections
"Macros" and "G68 rotation"), and the expected motion is derived in each test from the manual's
description. Errors are one ProgramError naming file and line; random macro programs give a block
table or one ProgramError, never anything else.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from feedlog.errors import ProgramError
from feedlog.toolpath import load_program
from feedlog.toolpath.interp.fanuc import interpret_fanuc, looks_macro_b, needs_macro
from feedlog.toolpath.interp.fanuc_syntax import parse_line


def run(text: str, **kw):
    return interpret_fanuc(text, name="prog.nc", **kw)


def ends(program) -> np.ndarray:
    return program.motion[["x_mm", "y_mm", "z_mm"]].to_numpy()


def machine_xy(program) -> np.ndarray:
    """Machine X, Y of the motion rows: R(rot_deg) * program + work offset (the block table's frame)."""
    m = program.motion
    t = np.radians(m["rot_deg"].to_numpy())
    x, y = m["x_mm"].to_numpy(), m["y_mm"].to_numpy()
    return np.column_stack([x * np.cos(t) - y * np.sin(t) + m["wx_mm"].to_numpy(),
                            x * np.sin(t) + y * np.cos(t) + m["wy_mm"].to_numpy()])


# -- variables and expressions --------------------------------------------------------------------

def test_sum_of_1_to_10_with_if_goto_and_with_while():
    """Fanuc 0i-MF manual, custom macro, 'Branch and repetition': the sum of 1 to 10 written with
    IF [#2 GT 10] GOTO 2 ... GOTO 1 and again with WHILE [#2 LE 10] DO 1 ... END 1; #1 ends at 55."""
    goto = ("O9500;\n#1=0;\n#2=1;\nN1 IF[#2 GT 10] GOTO 2;\n#1=#1+#2;\n#2=#2+1;\nGOTO 1;\n"
            "N2 G0 X#1 Y#2;\nM30;\n")
    loop = "O0001;\n#1=0;\n#2=1;\nWHILE[#2 LE 10] DO 1;\n#1=#1+#2;\n#2=#2+1;\nEND 1;\nG0 X#1 Y#2;\nM30;\n"
    for text in (goto, loop):
        p = run(text)
        assert ends(p).tolist() == [[55.0, 11.0, 0.0]]
        assert p.motion["line"].tolist() == [8]


def test_operators_precedence_and_functions_in_degrees():
    """Fanuc's precedence: functions, then * / AND MOD, then + - OR XOR, then comparisons; left to right.
    FIX discards and FUP raises fractions away from zero (the manual's #1=1.2, #2=-1.2 example); ATAN of
    two values is 0..360 (parameter NAT = 0)."""
    p = run("#1 = 2 + 3 * 4 - 6 / 3\n#2 = 5 OR 2 AND 3\n#3 = 17 MOD 5\n"
            "#4 = FIX[1.2] + FIX[-1.2] * 10\n#5 = FUP[1.2] + FUP[-1.2] * 10\n"
            "#6 = ATAN[-1]/[-1]\n#7 = ATAN[1,1]\n#8 = SQRT[16] + ABS[-2] + ROUND[2.5] + POW[2,3]\n"
            "#9 = SIN[30] + COS[60] + TAN[45]\n"
            "G0 X#1 Y#2 Z#3\nG0 X#4 Y#5 Z#6\nG0 X#7 Y#8 Z#9\nM30\n")
    e = ends(p)
    assert e[0].tolist() == [12.0, 7.0, 2.0]            # 2 + 12 - 2; 5 OR (2 AND 3) = 5 OR 2; 17 mod 5
    assert e[1, 0] == pytest.approx(1 - 10) and e[1, 1] == pytest.approx(2 - 20)
    assert e[1, 2] == pytest.approx(225.0)
    assert e[2, 0] == pytest.approx(45.0) and e[2, 1] == pytest.approx(4 + 2 + 3 + 8)
    assert e[2, 2] == pytest.approx(2.0)


def test_vacant_variables_follow_fanuc():
    """Fanuc 0i-MF manual, 'Undefined variable': a word with a vacant variable is ignored (G90 X100 Y#1
    with #1 vacant is G90 X100); in arithmetic vacant is 0; EQ/NE tell vacant from 0, GE/GT/LE/LT do not."""
    p = run("G0 X10 Y20\nG0 X100 Y#1\n#2 = #1\n#3 = #1 * 5\n"
            "IF [#1 EQ #0] THEN #4 = 1\nIF [#3 EQ #0] THEN #4 = 99\nIF [#1 GE 0] THEN #5 = 2\n"
            "IF [#2 NE 0] THEN #6 = 3\n"
            "G0 X#3 Y#4 Z#5\nG0 Z#6\nG0 X#2\nM30\n")
    e = ends(p)
    assert e.tolist() == [[10, 20, 0], [100, 20, 0], [0, 1, 2], [0, 1, 3], [0, 1, 3]]


def test_common_and_system_variables():
    """#100-#199 and #500-#999 are common to every level; #4001.. hold the modal G codes, #5001.. the
    end point of the last block, #5221.. the G54 offsets (writing one moves the work origin)."""
    p = run("G21 G91 G0 X5\n#500 = #4003\n#501 = #4006\n#502 = #5001\nG90\n#5221 = 100.\n#5222 = 50.\n"
            "G0 X#500 Y#501 Z#502\nM30\n")
    m = p.motion
    assert ends(p).tolist() == [[5, 0, 0], [91, 21, 5]]
    assert m["wx_mm"].tolist() == [0.0, 100.0] and m["wy_mm"].tolist() == [0.0, 50.0]


def test_macro_alarm_stops_with_its_line():
    with pytest.raises(ProgramError, match=r"prog.nc:3: macro alarm #3000 = 7"):
        run("G0 X1\n#1 = 7\n#3000 = #1 (TOOL BROKEN)\nM30\n")


# -- subprograms and macro calls ------------------------------------------------------------------

def test_bolt_hole_circle_macro_from_the_manual():
    """Fanuc 0i-MF manual, custom macro, 'Macro call (G65)' sample: bolt hole circle O9100 called with
    G65 P9100 X100 Y50 R30 Z-50 F500 I100 A0 B45 H5 after G92 X0 Y0 Z100: five holes on a circle of
    radius 100 about (100, 50) at 0, 45, ... 180 degrees, G81 drilled from R30 to Z-50, back to the initial
    level Z100 (G98, the power-on state); the data are stored by G81 ... K0 without drilling."""
    text = ("O0002;\nG90 G92 X0 Y0 Z100.0;\nG65 P9100 X100.0 Y50.0 R30.0 Z-50.0 F500 I100.0 A0 B45.0 H5;\n"
            "M30;\nO9100;\n#3=#4003;\nG81 Z#26 R#18 F#9 K0;\nIF[#3 EQ 90] GOTO 1;\n#24=#5001+#24;\n"
            "#25=#5002+#25;\nN1 WHILE[#11 GT 0] DO 1;\n#5=#24+#4*COS[#1];\n#6=#25+#4*SIN[#1];\n"
            "G90 X#5 Y#6;\n#1=#1+#2;\n#11=#11-1;\nEND 1;\nG#3 G80;\nM99;\n")
    p = run(text)
    m = p.motion
    holes = m[m["kind"] == "linear"]
    want = [(100 + 100 * math.cos(math.radians(a)), 50 + 100 * math.sin(math.radians(a))) for a in range(0, 181, 45)]
    assert np.allclose(holes[["x_mm", "y_mm"]].to_numpy(), want, atol=1e-9)
    assert (holes["z_mm"] == -50).all() and (holes["feed_mm_min"] == 500).all()
    assert len(m) == 5 * 4                              # per hole: to the point, down to R, feed, back up
    assert set(m["z_mm"]) == {100.0, 30.0, -50.0}
    assert (m["line"] == 14).all() and (m["stack"] == "prog.nc:3").all()


def test_m98_repeats_m99_p_and_shared_locals():
    """Fanuc 0i-MF manual, 'Subprogram': M98 P51002 calls O1002 five times (the count in the first four
    digits), M98 P1002 L3 three times (the Haas form); M99 P0030 returns to N0030 of the caller, skipping
    N0020. A subprogram shares the caller's local variables."""
    text = ("O0001\n#1 = 0\nN0010 M98 P51002\nG0 Y#1\nM98 P1002 L3\nG0 Y#1\nM98 P1010\nN0020 G0 X999\n"
            "N0030 G0 X-1\nM30\nO1002\n#1 = #1 + 1\nG91 G0 X1.\nG90\nM99\nO1010\nG0 Z7\nM99 P0030\n")
    p = run(text)
    e = ends(p)
    assert e[:5, 0].tolist() == [1, 2, 3, 4, 5] and e[5].tolist() == [5, 5, 0]
    assert e[9].tolist() == [8, 8, 0]
    assert e[10:].tolist() == [[8, 8, 7], [-1, 8, 7]]
    m = p.motion
    assert m["stack"].tolist()[:5] == ["prog.nc:3"] * 5 and m["line"].tolist()[:2] == [13, 13]
    assert m["stack"].tolist()[10] == "prog.nc:7" and m["stack"].tolist()[11] == ""


def test_g65_arguments_are_local_to_the_call_level():
    """G65 argument specification I (A=#1 B=#2 C=#3 I=#4 J=#5 K=#6 D=#7 ... X=#24 Y=#25 Z=#26): the
    macro sees its own #1-#33 (the ones not given are vacant); the caller's come back after M99; nested
    G65 calls open new levels."""
    text = ("#1 = 11\n#24 = 99\nG65 P8000 A1. B2. C3. I4. J5. K6. D7. E8. F9. H11. M13. Q17. R18. S19. "
            "T20. U21. V22. W23. X24. Y25. Z26.\nG0 X#1 Y#24\nM30\n"
            "O8000\n#100 = #1+#2+#3+#4+#5+#6+#7+#8+#9+#11+#13+#17+#18+#19+#20+#21+#22+#23+#24+#25+#26\n"
            "IF [#10 EQ #0] THEN #101 = 1\nG65 P8001 A5.\nG0 X#100 Y#101 Z#1\nM99\n"
            "O8001\nG0 X#1 Y#24\nM99\n")
    p = run(text)
    e = ends(p)
    assert e[0].tolist() == [5, 0, 0]                  # the nested call's #1 = 5, its #24 vacant: Y stays
    assert e[1].tolist() == [sum([1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 13, 17, 18, 19, 20, 21, 22, 23, 24, 25, 26]), 1, 1]
    assert e[2].tolist() == [11, 99, 1]
    assert p.motion["stack"].tolist() == ["prog.nc:3 > prog.nc:9", "prog.nc:3", ""]


def test_subprogram_files_along_the_search_path(tmp_path):
    """`O####` files in the program's folder or a given folder, as a control's memory holds them."""
    subs = tmp_path / "subs"
    subs.mkdir()
    (subs / "O2000.nc").write_text("%\nO2000 (SQUARE)\nG91 G1 X#24 F300\nY#24\nG90\nM99\n%\n")
    main = tmp_path / "main.nc"
    main.write_text("%\nO1000\nG0 X0 Y0\nG65 P2000 X7.\nM30\n%\n")
    with pytest.raises(ProgramError, match=r"main.nc:4: program O2000 not found"):
        interpret_fanuc(main)
    from feedlog.toolpath.interp import InterpOptions
    p = interpret_fanuc(main, options=InterpOptions(search_path=(subs,)))
    assert ends(p).tolist() == [[0, 0, 0], [7, 0, 0], [7, 7, 0]]
    assert p.motion["line"].tolist() == [3, 3, 4]
    assert p.motion["file"].iloc[1].endswith("O2000.nc") and p.motion["stack"].iloc[1] == "main.nc:4"


# -- canned cycles ----------------------------------------------------------------------------------

def test_canned_cycle_k_repeats_in_g91_with_r_from_the_initial_level():
    """Fanuc 0i-MF manual, canned cycles: in G91 R is the distance from the initial level to point R and
    Z the distance from R to the bottom; K repeats the cycle, each time moving by X/Y; G99 returns to R."""
    p = run("G90 G0 X0 Y0 Z50.\nG91 G99 G81 X20. Y0 R-45. Z-10. K3 F200\nG80 G90\nM30\n")
    m = p.motion
    drills = m[m["kind"] == "linear"]
    assert drills[["x_mm", "z_mm"]].to_numpy().tolist() == [[20, -5], [40, -5], [60, -5]]
    assert m["z_mm"].iloc[-1] == 5.0                   # G99: the last retract is to R = 50 - 45
    assert m[m["kind"] == "rapid"]["z_mm"].max() == 50.0


def test_peck_drilling_q_and_dwell_p_in_milliseconds():
    """G83 Q pecks (each peck back to R, then down to just above the last depth); G82 P in milliseconds
    (P1500 = 1.5 s, Fanuc's P has no decimal point); G98 returns to the initial level."""
    p = run("G0 X0 Y0 Z10.\nG83 X5. Y5. Z-10. R2. Q4. F100\nG82 X10. Z-3. R2. P1500\nG80\nG4 P250\nG4 X0.5\nM30\n")
    feeds = p.motion[p.motion["kind"] == "linear"]
    assert feeds["z_mm"].tolist()[:3] == [-2.0, -6.0, -10.0]     # 2 - 4, 2 - 8, then the bottom
    dwell = p.blocks[p.blocks["kind"] == "dwell"]["dwell_s"].tolist()
    assert dwell == [1.5, 0.25, 0.5]
    assert p.motion[p.motion["line"] == 2]["z_mm"].iloc[-1] == 10.0


# -- offsets, rotation, compensation ------------------------------------------------------------------

def test_unknown_work_offsets_warn_and_known_ones_move_the_origin():
    """G55 and G54.1 P3 whose values neither a parameter file nor the program gives: taken as 0 (the
    program's coordinates are the machine's there) with a warning naming them; #7001.. (G54.1 P1) and
    G10 L20 P2 set extended offsets, which the rows then carry as their work offset."""
    p = run("G55 G0 X1\nG54.1 P3 G0 X2\n#7001 = 100.\nG54.1 P1 G0 X3\nG10 L20 P2 X-10. Y5.\n"
            "G54.1 P2 G0 X4\nG54 G0 X5\nM30\n")
    m = p.motion
    assert m["x_mm"].tolist() == [1, 2, 3, 4, 5]
    assert m["wx_mm"].tolist() == [0, 0, 100, -10, 0] and m["wy_mm"].tolist() == [0, 0, 0, 5, 0]
    assert m["coord_system"].tolist() == [2, 12, 10, 11, 1]
    text = " ".join(p.warnings)
    assert "G55 selected" in text and "G54.1 P3 selected" in text and "P1" not in text.split("G54.1 P3")[0]


def test_g52_local_offset():
    p = run("G0 X0 Y0\nG52 X10. Y20.\nG0 X1 Y1\nG52 X0 Y0\nG0 X1 Y1\nM30\n")
    assert machine_xy(p).tolist() == [[0, 0], [11, 21], [1, 1]]


def test_g68_rotates_the_program_about_a_point():
    """Haas mill manual, G68 rotation: G68 X Y R rotates the following moves about (X, Y) by R degrees
    (counter-clockwise); G69 cancels. A square corner at (20, 10) rotated 90 degrees about (10, 10) lands
    at (10, 20) on the machine; after G69 the program's coordinates are the machine's again."""
    p = run("G0 X20. Y10.\nG68 X10. Y10. R90.\nG1 X20. Y10. F100\nG1 X30. Y10.\nG91 G1 X0 Y5.\n"
            "G90 G69\nG0 X0 Y0\nM30\n")
    xy = machine_xy(p)
    assert np.allclose(xy, [[20, 10], [10, 20], [10, 30], [5, 30], [0, 0]], atol=1e-9)
    assert p.motion["rot_deg"].tolist() == [0, 90, 90, 90, 0]


def test_cutter_compensation_with_d_and_tool_length_with_h(tmp_path):
    """G41 D (offset number = the tool table's entry) and G43 H run on the interpreter's compensation and
    tool length model: a line along +X with a 6 mm tool on the left runs 3 mm to the +Y side."""
    tbl = tmp_path / "t.tbl"
    tbl.write_text("T1 P1 Z10. D6.\n")
    from feedlog.toolpath.interp import InterpOptions
    p = interpret_fanuc("G0 X-10. Y-10. Z5.\nG43 H1 Z5.\n#1 = 1\nG41 D#1 G1 X0 Y0 F100\nG1 X50.\nG40 G0 X60. Y-10.\n"
                        "M30\n", name="c.nc", options=InterpOptions(tool_table=tbl))
    m = p.motion
    assert m["tool_z_mm"].iloc[-1] == 10.0
    line = m[m["line"] == 5]
    assert line["y_mm"].iloc[-1] == pytest.approx(3.0) and line["x_mm"].iloc[-1] == pytest.approx(50.0)


def test_arc_radius_tolerance_accepts_4_decimal_inch_rounding_and_is_settable():
    """An inch arc whose end radius differs by 0.0001 in (4-decimal rounding) reads; with the tolerance
    set tighter (like the controller's arc-radius error parameter) it is refused with its line."""
    text = "G20 G17 G90\nG0 X1. Y0\nG2 X0 Y-1.0001 I-1. J0 F10.\nM30\n"
    assert len(run(text).motion) == 2
    from feedlog.toolpath.interp import InterpOptions
    with pytest.raises(ProgramError, match=r"prog.nc:3: radius to end of arc differs"):
        run(text, options=InterpOptions(arc_tolerance_inch=0.00001))


# -- errors ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("text, line, message", [
    ("G0 X1\nGOTO 50\nM30\n", 2, r"N50 not found"),
    ("#1 = 1\nIF [#1 GT 0] GOTO 7\nN8 M30\n", 2, r"N7 not found"),
    ("WHILE [1 GT 0] DO 1\nG0 X1\nEND 2\nM30\n", 3, r"END 2 does not match the innermost DO 1"),
    ("G0 X1\nEND 1\nM30\n", 2, r"END 1 without a DO 1"),
    ("#1 = 5\nWHILE [#1 LT 3] DO 1\n#1 = #1 + 1\nM30\n", 2, r"no END 1"),
    ("#1 = 0\n#2 = 5 / #1\nM30\n", 2, r"divide by zero"),
    ("DO 4\nEND 4\nM30\n", 1, r"DO/END number must be 1, 2 or 3"),
    ("M98 P100\nM30\nO100\nM98 P100\nM99\n", 4, r"nested more than 10 deep"),
    ("G65 P100\nM30\nO100\nG65 P100\nM99\n", 4, r"G65 macro calls nested more than 4 deep"),
    ("G66 P77 Z-1\nM30\n", 1, r"program O77 not found"),
    ("M98 P9999\nM30\n", 1, r"program O9999 not found"),
    ("G0 X[1 +\nM30\n", 1, r"value expected"),
    ("O100\nG0 X1\nM99\n", 3, None),
    ("M98 P200\nM30\nO200\nG0 X1\n", 4, r"subprogram O200 ends without M99"),
])
def test_errors_name_file_and_line(text, line, message):
    if message is None:                     # M99 in the main program ends it (noted), no error
        p = run(text)
        assert any("M99 in the main program" in w for w in p.warnings)
        return
    with pytest.raises(ProgramError, match=message) as info:
        run(text)
    assert info.value.file == "prog.nc" and info.value.line == line


def test_runaway_loop_stops_at_the_block_limit():
    from feedlog.toolpath.interp import InterpOptions
    with pytest.raises(ProgramError, match=r"prog.nc:[12]: more than 1000 blocks executed"):
        run("N1 G91 G0 X1\nGOTO 1\n", options=InterpOptions(max_blocks=1000))
    with pytest.raises(ProgramError, match=r"more than 500 blocks"):
        run("WHILE [1 EQ 1] DO 2\n#100 = #100 + 1\nEND 2\n", options=InterpOptions(max_blocks=500))


def test_refused_codes_name_their_line():
    with pytest.raises(ProgramError, match=r"prog.nc:2: G31 skip"):
        run("G0 X0\nG31 X10. F100\nM30\n")
    with pytest.raises(ProgramError, match=r"prog.nc:1: ',C' / ',R'"):
        run("G1 X10. ,R2. F100\nM30\n")


# -- routing and the command line -------------------------------------------------------------------

def test_load_program_routes_macro_programs_and_keeps_plain_ones_on_the_translation(tmp_path):
    macro = tmp_path / "macro.nc"
    macro.write_text("%\nO1000\n#1 = 3\nG0 X#1\nG28 G91 Z0\nM30\n%\n")
    p = load_program(macro, dialect="fanuc")
    assert p.metadata["interpreter"] == "feedlog.toolpath.interp.fanuc" and p.metadata["dialect"] == "fanuc"
    assert load_program(macro).metadata["interpreter"] == "feedlog.toolpath.interp.fanuc"   # detected
    assert load_program(macro, dialect="hurco").metadata["dialect"] == "hurco"
    plain = tmp_path / "plain.nc"
    plain.write_text("%\nO1000\nG90 G0 X1. Y2.\nG1 Z-1. F100\nG28 G91 Z0\nM30\n%\n")
    q = load_program(plain, dialect="fanuc")
    assert q.metadata.get("interpreter") != "feedlog.toolpath.interp.fanuc"
    assert needs_macro("G81 X1 Z-1 R1 K2") and not needs_macro("G0 X1 (#1 in a comment)")
    assert looks_macro_b("WHILE [#1 LT 3] DO 1") and not looks_macro_b("o100 while [#1 lt 3]")


def test_g28_without_a_known_machine_frame_retracts_z_and_keeps_xy():
    p = run("G90 G0 X10. Y10. Z25.\nG1 Z-2. F100\n#1 = 1\nG91 G28 Z0\nG28 X0 Y0\nG90 G0 X#1\nM30\n")
    e = ends(p)
    assert e[2].tolist() == [10, 10, -2]                # the intermediate point (G91 Z0: where it is)
    assert e[3].tolist() == [10, 10, 25]                # Z up to the highest Z reached; X, Y stay
    assert e[-1].tolist() == [1, 10, 25]
    assert any("G28 Z" in w for w in p.warnings) and any("G28 X/Y" in w for w in p.warnings)


def test_feedlog_program_cli_with_dialect_fanuc(tmp_path, capsys):
    import json

    from feedlog.cli import main
    prog = tmp_path / "p.nc"
    prog.write_text("O1\n#1 = 0\nWHILE [#1 LT 4] DO 1\nG1 X[#1 * 10] F600\n#1 = #1 + 1\nEND 1\nM30\n")
    assert main(["program", str(prog), "--dialect", "fanuc", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["kinds"]["linear"] == 4 and doc["length_mm"] == pytest.approx(30.0)


# -- fuzz --------------------------------------------------------------------------------------------

_STATEMENTS = ["#1 = #1 + 1", "#2 = [#1 * 3 - 2] / [#1 + 1]", "#100 = SIN[#1 * 30]", "#3 = #0",
               "G0 X#1 Y#2", "G1 X[#100 * 5] F100", "G91 G0 X1", "G90", "IF [#1 GT 3] GOTO 20",
               "IF [#2 EQ #0] THEN #2 = 1", "WHILE [#1 LT 5] DO 1", "END 1", "N20 G0 Z5", "GOTO 20",
               "M98 P200", "G65 P300 A#1", "G81 X1 Y1 Z-1 R1 K2 F50", "G80", "G2 X5 Y0 R5 F100", "M99",
               "#4 = 1 / #1", "G52 X1", "G68 X0 Y0 R30", "G69", "G54.1 P2", "G55", "DO 2", "END 2",
               "#[#1] = 4", "G0 X#[#1 + 1]", "(comment)", "G4 P100", "G83 Z-3 R1 Q1", "M30", "%", "O300",
               "G41 D1 G1 X3", "G40", "#5221 = 3", "#500 = #4001"]


@settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.sampled_from(_STATEMENTS), max_size=14),
       st.lists(st.sampled_from(_STATEMENTS), max_size=6),
       st.text(alphabet="GXYZIJKRFPLQDHMNO#[]+-*/=0123456789. ;()ADIFGOTHENWLE", max_size=30))
def test_random_macro_programs_give_a_table_or_one_program_error(main, sub, noise):
    from feedlog.toolpath.interp import InterpOptions
    text = "\n".join(main + [noise, "M30", "O200"] + sub + ["M99", "O300", "G0 X#1", "M99"]) + "\n"
    try:
        p = run(text, options=InterpOptions(max_blocks=2000))
    except ProgramError as exc:
        assert exc.file == "prog.nc" and exc.line is not None
        return
    assert list(p.blocks.columns[:4]) == ["file", "line", "block", "kind"]
    assert np.isfinite(p.motion[["x_mm", "y_mm", "z_mm"]].to_numpy()).all()


def test_line_parser_reads_the_macro_statements():
    line = parse_line("N10 IF [#1 GT #2] GOTO #3 (skip)", 1)
    assert (line.kind, line.n, line.comment) == ("if_goto", 10, "skip")
    assert parse_line("WHILE[#1LE10]DO2;", 1).target == 2
    assert parse_line("g01x#1y-[#2+1]f100", 1).words[1][0] == "X"
    with pytest.raises(Exception, match="must stand alone"):
        parse_line("O100 G0 X1", 1)


def test_the_bundled_fanuc_programs_still_read_as_before():
    root = Path(__file__).resolve().parents[2]
    for path in sorted((root / "examples").glob("*.nc")) + sorted((root / "tests" / "fixtures").rglob("*.nc")):
        text = path.read_text(errors="replace")
        if needs_macro(text) or looks_macro_b(text):
            continue
        p = load_program(path, lenient=True)
        assert p.metadata.get("interpreter") != "feedlog.toolpath.interp.fanuc"


def test_haas_m97_local_subprogram():
    """Haas mill manual, M97 local subprogram call: M97 P1000 L2 runs the block N1000 of the same program
    to its M99 twice, then the caller goes on after the M97 block."""
    p = run("O00001\nG0 X0 Y0\nM97 P1000 L2\nG0 X50.\nM30\nN1000 G91 G0 Y10.\nG90\nM99\n")
    e = ends(p)
    assert e.tolist() == [[0, 0, 0], [0, 10, 0], [0, 20, 0], [50, 20, 0]]
    assert p.motion["stack"].tolist() == ["", "prog.nc:3", "prog.nc:3", ""]
    assert p.motion["line"].tolist() == [2, 6, 6, 4]


def test_g10_l2_sets_a_work_offset_and_no_warning_is_given():
    p = run("G10 L2 P2 X100. Y10.\nG55 G0 X1 Y1\nM30\n")
    assert machine_xy(p).tolist() == [[101, 11]]
    assert not any("G55" in w for w in p.warnings)
    with pytest.raises(ProgramError, match=r"prog.nc:1: G10 L2 P0"):
        run("G10 L2 P0 X1.\nM30\n")


def test_routing_keeps_safety_lines_plain_and_names_extended_offsets(tmp_path, capsys):
    """A plain Fanuc program whose safety line cancels rotation (G69) stays on the line translation; an
    undeclared program with G54.1 goes to the front-end (also when streamed), and the summary names
    the extended offset."""
    import json

    from feedlog.cli import main
    from feedlog.toolpath.load import stream_dialect
    plain = tmp_path / "safe.nc"
    plain.write_text("%\nO1\nG17 G40 G49 G80 G69\nG0 X1. Y1.\nG28 G91 Z0\nM30\n%\n")
    assert load_program(plain).metadata.get("interpreter") != "feedlog.toolpath.interp.fanuc"
    ext = tmp_path / "ext.nc"
    ext.write_text("#7001 = 100.\nG54.1 P1 G0 X1\nM30\n")
    assert stream_dialect(ext) == "fanuc"
    assert main(["program", str(ext), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["work_offsets"] == [{"coord_system": "G54.1 P1", "offset": {"wx_mm": 100.0}, "blocks": 1}]


@settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(max_size=120), st.binary(max_size=60))
def test_random_text_gives_a_table_or_one_program_error(text, raw):
    """Any characters (unicode digits, control bytes, half statements) inside and around macro calls."""
    from feedlog.toolpath.interp import InterpOptions
    # each body ends with a line end: one short line with a program suffix ("#1=.NC") is read as a file name
    for body in (text + "\n", raw.decode("latin-1") + "\n", "#1=" + text + "\n",
                 "G65 P1 " + text + "\nM30\nO1\n" + text + "\nM99\n"):
        try:
            run(body, options=InterpOptions(max_blocks=2000))
        except ProgramError as exc:
            assert exc.file == "prog.nc" and exc.line is not None


def test_g53_with_known_offsets_goes_to_machine_coordinates_and_keeps_the_modal_motion(tmp_path):
    """Fanuc G53: machine coordinates for one block, at rapid, the modal G01 stays for the next block.
    With the offsets known (a parameter file: G54 = X10 Y20 Z-100), G53 Z0 is program Z 100."""
    var = tmp_path / "m.var"
    var.write_text("5221 10.0\n5222 20.0\n5223 -100.0\n")
    from feedlog.toolpath.interp import InterpOptions
    p = run("#1 = 1\nG1 F100 X1 Y1 Z1\nG53 Z0\nG53 X0 Y0\nX2\nM30\n", options=InterpOptions(parameter_file=var))
    m = p.motion
    assert m["kind"].tolist() == ["linear", "rapid", "rapid", "linear"]
    assert ends(p).tolist() == [[1, 1, 1], [1, 1, 100], [-10, -20, 100], [2, -20, 100]]
    with pytest.raises(ProgramError, match=r"prog.nc:1: G10 L10 \(tool offset memory\)"):
        run("G10 L10 P1 R5.\nM30\n")


def test_g30_and_dropped_modes_with_their_own_words():
    """G91 G30 Z0 (tool-change position) is read like G28 without a known frame; G05.1 Q1 and Haas
    G187 P1 E0.01 are dropped with their words (noted), the block's path is unchanged."""
    p = run("G0 X5 Y5 Z30.\nG05.1 Q1\nG187 P1 E0.01\nG1 Z-1 F100\n#1 = 0\nG91 G30 Z0\nG90 X#1\nM30\n")
    assert ends(p).tolist()[-2:] == [[5, 5, 30], [0, 5, 30]]
    assert any("G05.1" in w for w in p.warnings) and any("G187" in w for w in p.warnings)


def test_front_end_agrees_with_the_line_translation_on_the_bundled_hurco_program():
    """The real Hurco program (inch, G91 G28 Z0, G43 H, G64 P, G4 P in ms, I/J arcs) read both ways:
    the same moves, lines, feeds and dwells; the front-end also makes G28's (zero-length) move to the
    intermediate point, as the control does."""
    path = Path(__file__).resolve().parents[2] / "tests" / "fixtures" / "ingest" / "real" / "hurco_part.nc"
    a = load_program(path, dialect="hurco")
    assert a.metadata["interpreter"] != "feedlog.toolpath.interp.fanuc"
    b = interpret_fanuc(path)
    mb = b.motion
    lines = mb["line"].to_numpy()
    g28 = np.isin(lines, [4, 28]) & np.r_[lines[1:] == lines[:-1], False]    # the first of the line's two
    assert g28.sum() == 2 and (mb["length_mm"][g28] == 0).all()
    ma, mb = a.motion.reset_index(drop=True), mb[~g28].reset_index(drop=True)
    cols = ["line", "x_mm", "y_mm", "z_mm", "cx_mm", "cy_mm", "feed_mm_min", "tool_z_mm"]
    assert (ma["kind"].astype(str) == mb["kind"].astype(str)).all()
    np.testing.assert_allclose(ma[cols].to_numpy(dtype=float), mb[cols].to_numpy(dtype=float), atol=1e-9)
    assert a.blocks["dwell_s"].sum() == b.blocks["dwell_s"].sum() == pytest.approx(0.3)


def test_nested_loops_and_goto_out_of_a_loop():
    """Fanuc 0i-MF manual, WHILE: DO numbers 1-3 nest three deep and may be used again after their END;
    a GOTO may leave a loop (not enter one). A 2 x 3 grid of moves from two nested loops, a third level
    that runs once, then a loop left by GOTO at its second pass, then DO 1 used again."""
    text = ("#1 = 0\nWHILE [#1 LT 2] DO 1\n#2 = 0\nWHILE [#2 LT 3] DO 2\n#3 = 0\nWHILE [#3 LT 1] DO 3\n"
            "G0 X#1 Y#2\n#3 = #3 + 1\nEND 3\n#2 = #2 + 1\nEND 2\n#1 = #1 + 1\nEND 1\n"
            "#4 = 0\nWHILE [#4 LT 10] DO 1\n#4 = #4 + 1\nIF [#4 EQ 2] GOTO 100\nG0 Z#4\nEND 1\n"
            "N100 #5 = 0\nWHILE [#5 LT 2] DO 1\n#5 = #5 + 1\nG0 Z[10 + #5]\nEND 1\nM30\n")
    e = ends(run(text))
    assert e[:6, :2].tolist() == [[0, 0], [0, 1], [0, 2], [1, 0], [1, 1], [1, 2]]
    assert e[6:, 2].tolist() == [1, 11, 12]


def test_lenient_falls_back_to_the_line_translation_with_a_warning(tmp_path):
    bad = tmp_path / "bad.nc"
    bad.write_text("O1\n#1 = 1\nG0 X1\nG31 X5 F100\nG0 X2\nM30\n")
    with pytest.raises(ProgramError, match=r"bad.nc:4: G31"):
        load_program(bad, dialect="fanuc")
    p = load_program(bad, dialect="fanuc", lenient=True)
    assert "the Fanuc macro front-end refused it" in p.warnings[0] and "bad.nc:4" in p.warnings[0]


def test_g65_argument_specification_ii_and_output_commands():
    """Fanuc 0i-MF manual, argument specification II: A B C then up to ten sets of I J K, the n-th set in
    #(4+3n) #(5+3n) #(6+3n); a set closes when a letter repeats or comes out of order (I1 K3 J4 -> the
    J opens set 2). DPRNT/POPEN/PCLOS (external output) move nothing."""
    text = ("G65 P9 A1. I4. J5. K6. I7. K9. J11. I13.\nM30\nO9\nPOPEN\nDPRNT[X#24[44]]\nPCLOS\n"
            "G0 X#4 Y#5 Z#6\nG0 X#7 Y#8 Z#9\nG0 X#10 Y#11 Z#13\nG0 X#1\nM99\n")
    p = run(text)
    e = ends(p)
    assert e.tolist() == [[4, 5, 6], [7, 5, 9], [7, 11, 13], [1, 11, 13]]
    assert any("DPRNT" in w for w in p.warnings)


def test_an_error_in_a_subprogram_file_names_that_file_its_line_and_the_caller(tmp_path):
    (tmp_path / "O2000.nc").write_text("O2000\n#1 = 0\n#2 = 1 / #1\nM99\n")
    main = tmp_path / "main.nc"
    main.write_text("O1000\nG0 X0\nG0 Y0\nM98 P2000\nM30\n")
    with pytest.raises(ProgramError, match=r"divide by zero \(called from main.nc:4\)") as info:
        load_program(main, dialect="fanuc")
    assert info.value.file.endswith("O2000.nc") and info.value.line == 3


def test_g66_modal_macro_call_after_every_move():
    """Fanuc 0i-MF manual, modal call (G66): after G66 P9110 Z-10 R2 F100 every block that moves calls
    O9110 with those arguments (here a drilling macro), the macro's own moves do not call it again;
    G67 cancels."""
    text = ("G0 X0 Y0 Z20.\nG66 P9110 Z-10. R2. F100.\nG0 X10.\nY10.\nG67\nG0 X50.\nM30\n"
            "O9110\nG0 Z#18\nG1 Z#26 F#9\nG0 Z20.\nM99\n")
    p = run(text)
    e = ends(p)
    assert e.tolist() == [[0, 0, 20], [10, 0, 20], [10, 0, 2], [10, 0, -10], [10, 0, 20],
                          [10, 10, 20], [10, 10, 2], [10, 10, -10], [10, 10, 20], [50, 10, 20]]
    assert p.motion["stack"].tolist()[2:5] == ["prog.nc:3"] * 3 and p.motion["stack"].tolist()[6] == "prog.nc:4"
