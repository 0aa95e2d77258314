"""The Sinumerik 840D front-end (toolpath.interp.sinumerik). There is no open Sinumerik interpreter to
compare with, so the cases follow the examples of Siemens' published manuals (SINUMERIK 840D sl
Programming Manual Fundamentals, Job Planning, and the 840D Programming Guide Cycles), written anew
here, and the expected motion is derived by hand in each test from the manuals' descriptions."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from feedlog.errors import ProgramError
from feedlog.toolpath import load_program
from feedlog.toolpath.interp.sinumerik import interpret_sinumerik, needs_sinumerik_interpreter

ROOT = Path(__file__).resolve().parents[2]


def run(text: str, **kw):
    return interpret_sinumerik(text, name="main.mpf", **kw)


def moves(program) -> list[tuple]:
    m = program.blocks[program.blocks["kind"].isin(["rapid", "linear", "arc_cw", "arc_ccw"])]
    return [(k, round(x, 6), round(y, 6), round(z, 6)) for k, x, y, z in
            m[["kind", "x_mm", "y_mm", "z_mm"]].itertuples(index=False)]


def ends(program) -> np.ndarray:
    return np.array([m[1:] for m in moves(program)])


# -- parameters, variables, expressions -----------------------------------------------------------------

def test_r_parameters_and_arithmetic():
    """Fundamentals, "Arithmetic parameters (R)": R1=10 ... X=R1 moves to the value; assignments read
    values already set earlier on the same block (left to right)."""
    p = run("N10 R1=10 R2=R1*3 R3=-R2/4\nN20 G1 F100 X=R1 Y=R2 Z=R3\nN30 R1=R1+1 X=R1*2\nM30\n")
    assert moves(p) == [("linear", 10, 30, -7.5), ("linear", 22, 30, -7.5)]


def test_operators_priority_and_functions_in_degrees():
    """Job Planning, "Arithmetic operators / calculation functions" and "Priority of operators": NOT;
    * / DIV MOD; + -; ...; AND; XOR; OR; comparisons last. SIN/COS/ATAN2 work in degrees."""
    p = run("R1=2+3*4 R2=7 DIV 2 R3=-7 MOD 3 R4=SIN(30)+COS(60) R5=ATAN2(1,1) R6=SQRT(16)+POT(3)\n"
            "R7=TRUNC(-2.7)+ROUND(2.5)+ROUND(-2.5) R8=ABS(-4)\n"
            "R9=1==1 AND 0\n"            # comparisons bind last: 1 == (1 AND 0) -> false
            "R10=(1==1) AND (2>1)\n"
            "R11=NOT 0 OR 0 R12=3<>4 R13=5>=5 XOR 0\n"
            "G1 F100 X=R1 Y=R2 Z=R3\nX=R4 Y=R5 Z=R6\nX=R7 Y=R8 Z=R9\nX=R10 Y=R11 Z=R12\nX=R13\nM30\n")
    e = ends(p)
    assert e[0].tolist() == [14, 3, -1]          # 2+12; 7 DIV 2 truncates; MOD keeps the dividend's sign
    assert e[1].tolist() == pytest.approx([1.0, 45.0, 13.0])
    assert e[2].tolist() == [-2 + 3 - 3, 4, 0]
    assert e[3].tolist() == [1, 1, 1]
    assert e[4, 0] == 1


def test_def_variables_types_and_initial_values():
    """Job Planning, "Definition of user variables (DEF)": DEF INT/REAL/BOOL with initial values; an INT
    takes a REAL rounded; a BOOL is TRUE for any non-zero value."""
    p = run("DEF REAL LEN=12.5, W\nDEF INT N=2.5\nDEF BOOL ON=7\nW=LEN/5\nN=N*1.4\n"
            "G1 F100 X=LEN Y=W Z=N\nX=ON\nM30\n")
    assert moves(p) == [("linear", 12.5, 2.5, 4.0), ("linear", 1.0, 2.5, 4.0)]  # N: 3 (2.5 rounds up), 3*1.4=4.2 -> 4


def test_msg_with_string_concatenation_goes_to_the_comment():
    p = run('R1=3\nMSG("PASS " << R1)\nG1 F100 X1 ; cut\nM30\n')
    assert "MSG PASS 3" in p.blocks["comment"].tolist()
    assert "cut" in p.blocks["comment"].tolist()


# -- control flow -----------------------------------------------------------------------------------------

def test_gotob_loop_with_label_and_if():
    """Job Planning, "Program jumps to jump markers": a counter loop with a label and a conditional
    backward jump (IF R1<5 GOTOB MA1) and a forward jump over a block (GOTOF)."""
    p = run("N10 R1=0 G1 F100\nN20 MA1: G91 X10\nN30 R1=R1+1\nN40 IF R1<3 GOTOB MA1\nN50 GOTOF END1\n"
            "N60 Y99\nN70 END1: G90 Y5\nM30\n")
    assert moves(p) == [("linear", 10, 0, 0), ("linear", 20, 0, 0), ("linear", 30, 0, 0), ("linear", 30, 5, 0)]
    assert p.blocks[p.blocks["kind"] == "linear"]["line"].tolist() == [2, 2, 2, 7]


def test_goto_to_a_block_number_and_gotoc_without_target():
    p = run("G1 F100\nGOTOF N50\nX99\nN50 X1\nGOTOC NOWHERE\nX2\nM30\n")
    assert [m[1] for m in moves(p)] == [1, 2]


def test_structured_if_else_for_while_repeat_loop():
    """Job Planning, "Control structures": IF-ELSE-ENDIF, FOR ... TO ... ENDFOR, WHILE ... ENDWHILE,
    REPEAT ... UNTIL, LOOP ... ENDLOOP left with GOTOF."""
    p = run("DEF INT I\nG1 F100\n"
            "FOR I=1 TO 3\n  IF I==2\n    X=I*10\n  ELSE\n    Y=I\n  ENDIF\nENDFOR\n"
            "R1=0\nWHILE R1<2\n  R1=R1+1\n  Z=-R1\nENDWHILE\n"
            "REPEAT\n  R1=R1+1\n  Z=-R1\nUNTIL R1>=4\n"
            "LOOP\n  R1=R1+1\n  IF R1>5 GOTOF OUT\n  X=R1\nENDLOOP\nOUT: M30\n")
    assert moves(p) == [("linear", 0, 1, 0), ("linear", 20, 1, 0), ("linear", 20, 3, 0),
                        ("linear", 20, 3, -1), ("linear", 20, 3, -2), ("linear", 20, 3, -3), ("linear", 20, 3, -4),
                        ("linear", 5, 3, -4)]


def test_for_whose_start_is_past_its_end_runs_no_pass():
    p = run("DEF INT I\nG1 F100\nFOR I=5 TO 1\n X=I\nENDFOR\nX=I+100\nM30\n")
    assert moves(p) == [("linear", 105, 0, 0)]


# -- errors: one ProgramError naming file and line -------------------------------------------------------

@pytest.mark.parametrize("text, line, message", [
    ("G1 F100\nGOTOF MISSING\nM30\n", 2, "jump target MISSING not found after"),
    ("R1=0\nR2=5/R1\nM30\n", 2, "division by zero"),
    ("R1=4 DIV 0\nM30\n", 1, "division by zero"),
    ("G1 F100 X1\nNOSUCHSUB\nM30\n", 2, "subprogram NOSUCHSUB not found"),
    ("G1 F100\nX=UNDECLARED\nM30\n", 2, "unknown name UNDECLARED"),
    ("IF R1==0\nG1 F100 X1\nM30\n", 1, "IF without its ENDIF"),
    ("G1 F100\nENDWHILE\nM30\n", 2, "ENDWHILE without its WHILE"),
    ("R1=SQRT(-1)\nM30\n", 1, "SQRT of a negative"),
    ("G41 G1 F100 X1\nM30\n", 1, "G41"),
    ("SCALE X2\nM30\n", 1, "SCALE"),
    ("G1 F100 X1 X2\nM30\n", 1, "twice"),
])
def test_errors_name_file_and_line(text, line, message):
    with pytest.raises(ProgramError) as exc:
        run(text)
    assert exc.value.line == line
    assert "main.mpf" in str(exc.value)
    assert message in str(exc.value)


def test_a_runaway_loop_stops_with_a_clear_error():
    with pytest.raises(ProgramError, match=r"main.mpf:3: more than 1000 blocks executed: a runaway loop"):
        run("G1 F100\nLOOP\nG91 X1\nENDLOOP\nM30\n", max_blocks=1000)
    with pytest.raises(ProgramError, match="runaway loop"):
        run("MA1: GOTOB MA1\n", max_blocks=500)


def test_recursion_stops_at_the_program_level_limit(tmp_path):
    (tmp_path / "SELF.SPF").write_text("PROC SELF\nSELF\nM17\n")
    (tmp_path / "main.mpf").write_text("SELF\nM30\n")
    with pytest.raises(ProgramError, match=r"SELF.SPF:2: too many nested subprogram calls") as exc:
        interpret_sinumerik(tmp_path / "main.mpf")
    assert "called from main.mpf:1 > SELF.SPF:2" in str(exc.value)


# -- subprograms -------------------------------------------------------------------------------------------

def test_subprograms_by_name_number_parameters_and_repeats(tmp_path):
    """Fundamentals / Job Planning, "Subprograms": L123 (a numbered subprogram L123.SPF), a call by name
    with PROC parameters (PROC NAME(REAL A, INT B)), P repeat count, M17 and RET; R parameters are
    global, DEF variables local; rows keep the subprogram's file, line and the call stack."""
    subs = tmp_path / "subs"
    subs.mkdir()
    (tmp_path / "L123.SPF").write_text("G91 G1 X1\nR10=R10+1\nM17\n")
    (subs / "slot.spf").write_text("PROC SLOT(REAL DEPTH, INT N)\nDEF REAL HALF=DEPTH/2\nG90 G1 Z=-HALF\n"
                                   "Y=N\nRET\n")
    (tmp_path / "main.mpf").write_text("R10=0\nG1 F100\nL123 P3\nG90 X=R10*10\nSLOT(8, 2)\nSLOT(4)\nM30\n")
    p = interpret_sinumerik(tmp_path / "main.mpf", search_path=[subs])
    assert moves(p) == [("linear", 1, 0, 0), ("linear", 2, 0, 0), ("linear", 3, 0, 0), ("linear", 30, 0, 0),
                        ("linear", 30, 0, -4), ("linear", 30, 2, -4), ("linear", 30, 2, -2), ("linear", 30, 0, -2)]
    m = p.blocks[p.blocks["kind"] == "linear"]
    assert Path(m["file"].iloc[0]).name == "L123.SPF" and m["line"].iloc[0] == 1
    assert m["stack"].iloc[0] == "main.mpf:3" and m["stack"].iloc[3] == ""
    assert m["stack"].iloc[4] == "main.mpf:5" and m["line"].iloc[4] == 3
    assert m["stack"].iloc[6] == "main.mpf:6"


def test_local_variables_of_the_caller_are_not_visible_in_a_subprogram(tmp_path):
    (tmp_path / "SUB1.SPF").write_text("G1 X=MINE\nM17\n")
    (tmp_path / "main.mpf").write_text("DEF REAL MINE=3\nG1 F100\nSUB1\nM30\n")
    with pytest.raises(ProgramError, match=r"SUB1.SPF:1: unknown name MINE"):
        interpret_sinumerik(tmp_path / "main.mpf")


# -- drilling cycles ---------------------------------------------------------------------------------------

def test_cycle81_the_manuals_example():
    """840D Programming Guide Cycles, CYCLE81 example: Z110 is the retraction plane; holes at X40 Y120
    (RFP 100, SDIS 2, DP 35), at Y30 (RFP 102, SDIS left out, DP 35) and at X90 (DPR 65). Each: G0 to
    RFP+SDIS, G1 to the depth, G0 back to RTP."""
    p = run("N10 G0 G17 G90 F200 S300 M3\nN20 D3 T3 Z110\nN30 X40 Y120\nN40 CYCLE81(110, 100, 2, 35)\n"
            "N50 Y30\nN60 CYCLE81(110, 102, , 35)\nN70 G0 G90 F180 S300 M03\nN80 X90\n"
            "N90 CYCLE81(110, 100, 2, , 65)\nN100 M30\n")
    assert moves(p) == [
        ("rapid", 0, 0, 110), ("rapid", 40, 120, 110),
        ("rapid", 40, 120, 102), ("linear", 40, 120, 35), ("rapid", 40, 120, 110),
        ("rapid", 40, 30, 110),
        ("rapid", 40, 30, 102), ("linear", 40, 30, 35), ("rapid", 40, 30, 110),
        ("rapid", 90, 30, 110),
        ("rapid", 90, 30, 102), ("linear", 90, 30, 35), ("rapid", 90, 30, 110)]
    feeds = p.blocks[p.blocks["kind"] == "linear"]["feed_mm_min"].tolist()
    assert feeds == [200, 200, 180]


def test_cycle82_dwells_at_depth_and_mcall_repeats_at_every_position():
    """CYCLE82 (drilling, counterboring): as CYCLE81 with a dwell DTB (s) at the final depth. MCALL
    makes it modal: it runs after every following block that moves, until MCALL alone."""
    p = run("G0 G90 Z50 F100 S1000 M3\nMCALL CYCLE82(50, 0, 1, -5, , 0.5)\nX10 Y10\nX20\nMCALL\nX30\nM30\n")
    b = p.blocks
    assert moves(p) == [("rapid", 0, 0, 50),
                        ("rapid", 10, 10, 50), ("rapid", 10, 10, 1), ("linear", 10, 10, -5), ("rapid", 10, 10, 50),
                        ("rapid", 20, 10, 50), ("rapid", 20, 10, 1), ("linear", 20, 10, -5), ("rapid", 20, 10, 50),
                        ("rapid", 30, 10, 50)]
    dwells = b[b["kind"] == "dwell"]
    assert dwells["dwell_s"].tolist() == [0.5, 0.5] and dwells["line"].tolist() == [3, 4]


def test_cycle83_swarf_removal_and_chip_breaking():
    """CYCLE83 deep-hole drilling (Programming Guide Cycles): first depth FDPR below RFP at F*FRF, then
    strokes reduced by the degression DAM. VARI=1 (swarf removal): back to RFP+SDIS with G0 after each
    stroke and down again with G0 to the last depth less the anticipation distance (depth/50, at most
    0.6 mm); VARI=0 (chip breaking): back 1 mm with G1 after each stroke."""
    p = run("G0 G90 X5 Y5 Z20 F100\nCYCLE83(20, 0, 2, -25, , , 10, 3, 0, 0, 0.5, 1)\nM30\n")
    z = [m[3] for m in moves(p)][1:]
    # strokes: -10 (first, feed 50), then 7 (10-3), then 4 (7-3) -> -17, -21, then 3 (= DAM) -> -24, then -25
    assert z == pytest.approx([2, -10, 2, -10 + 0.2, -17, 2, -17 + 0.34, -21, 2, -21 + 0.42, -24, 2,
                               -24 + 0.48, -25, 20])
    lin = p.blocks[p.blocks["kind"] == "linear"]
    assert lin["feed_mm_min"].tolist() == [50, 100, 100, 100, 100]
    p = run("G0 G90 Z20 F100\nCYCLE83(20, 0, 2, -12, , -5, , 0, 0, 0, 1, 0)\nM30\n")
    z = [m[3] for m in moves(p)][1:]
    assert z == pytest.approx([2, -5, -4, -10, -9, -12, 20])


def test_cycle_errors():
    with pytest.raises(ProgramError, match="CYCLE81 without a feed"):
        run("G0 Z10\nCYCLE81(10, 0, 1, -5)\nM30\n")
    with pytest.raises(ProgramError, match=r"main.mpf:2: CYCLE800 is not simulated"):
        run("G0 Z10\nCYCLE800(1)\nM30\n")


# -- frames -----------------------------------------------------------------------------------------------

def test_trans_atrans_rot_arot():
    """Fundamentals, "Frames": TRANS X.. Y.. sets the programmable zero offset (replacing the whole
    programmable frame); ATRANS adds in the current (rotated) system; ROT RPL= replaces the frame with a
    rotation; AROT adds a rotation about the current zero; TRANS alone clears it. The machine position
    of X10 Y0 is derived by hand."""
    p = run("G1 F100 G17\nTRANS X20 Y10\nX10 Y0\nAROT RPL=90\nX10 Y0\nATRANS X5\nX0 Y0\n"
            "ROT RPL=45\nX10 Y0\nTRANS\nX0 Y0\nM30\n")
    b = p.blocks[p.blocks["kind"] == "linear"]
    # program coordinates in the rows; with the work offset and rotation they give the machine position
    got = []
    for x, y, wx, wy, r in b[["x_mm", "y_mm", "wx_mm", "wy_mm", "rot_deg"]].itertuples(index=False):
        c, s = math.cos(math.radians(r)), math.sin(math.radians(r))
        got.append((round(wx + c * x - s * y, 9), round(wy + s * x + c * y, 9)))
    # TRANS: (20,10)+(10,0); AROT 90: (20,10)+R90(10,0) = (20,20); ATRANS X5 moves the zero along the
    # rotated X, i.e. machine +Y: (20,15); ROT 45 drops the translation: R45(10,0); TRANS alone: (0,0)
    assert np.array(got) == pytest.approx(np.array([(30, 10), (20, 20), (20, 15), (10 / math.sqrt(2), 10 / math.sqrt(2)),
                                                   (0, 0)]))
    assert b["rot_deg"].tolist() == [0, 90, 90, 45, 0]


def test_settable_frames_are_warned_and_taken_as_zero():
    p = run("G500 G0 X1\nG54 X2\nG1 F100 R1=1 X=R1\nM30\n")
    assert any("G54 selected" in w for w in p.warnings)
    assert not any("G500" in w for w in p.warnings)
    assert p.blocks["x_mm"].iloc[-2] == 1


# -- geometry: arcs, AC/IC, units --------------------------------------------------------------------------

def test_arcs_with_cr_ijk_ac_and_turn():
    """Fundamentals, "Circular interpolation": I, J are the centre relative to the start unless written
    I=AC(..); CR= the radius (negative: more than a semicircle); TURN= adds full turns to a helix."""
    p = run("G90 G17 G0 X0 Y0 Z0\nG2 X20 Y0 CR=10 F100\nG3 X0 Y0 I=AC(10) J=AC(0)\nG2 X0 Y0 Z-6 I10 J0 TURN=2\n"
            "G3 X20 Y0 CR=-10\nM30\n")
    b = p.blocks[p.blocks["kind"].isin(["arc_cw", "arc_ccw"])]
    assert b[["cx_mm", "cy_mm"]].to_numpy() == pytest.approx(np.array([[10, 0]] * 4))
    assert b["turns"].tolist() == [1, 1, 3, 1]
    assert b["sweep_deg"].abs().tolist() == pytest.approx([180, 180, 3 * 360, 180])


def test_ac_ic_in_g90_and_g91():
    p = run("G90 G1 F100 X10 Y10\nX=IC(5) Y=AC(2)\nG91 X=AC(1) Y3\nX=IC(2)\nM30\n")
    assert ends(p)[:, :2].tolist() == [[10, 10], [15, 2], [1, 5], [3, 5]]


def test_g70_keeps_feeds_in_mm_g700_takes_them_in_inch():
    """Fundamentals, "Inch/metric dimensions": G70/G71 switch the geometry only (feeds stay in the basic
    system, mm/min here); G700/G710 switch the feeds too."""
    p = run("G71 G1 F254 X10\nG70 X1\nG700 F10 X2\nM30\n")
    lin = p.blocks[p.blocks["kind"] == "linear"]
    assert lin["x_mm"].tolist() == pytest.approx([10, 25.4, 50.8])
    assert lin["feed_mm_min"].tolist() == pytest.approx([254, 254, 254])


def test_path_modes_and_dwell():
    p = run("G1 F100 G60 X1\nG64 X2\nG641 X3\nG9 X4\nG4 F1.5\nM30\n")
    b = p.blocks[p.blocks["kind"] == "linear"]
    assert b["path_mode"].tolist() == ["exact_stop", "continuous", "continuous", "exact_stop"]
    assert p.blocks[p.blocks["kind"] == "dwell"]["dwell_s"].tolist() == [1.5]
    assert any("G641" in w for w in p.warnings)


# -- routing in load_program ----------------------------------------------------------------------------------

def test_load_program_routes_sinumerik_programs(tmp_path):
    plain = load_program(ROOT / "tests/fixtures/ingest/real/sinumerik_part.mpf")
    assert plain.metadata.get("interpreter") is None and plain.metadata["dialect"] == "sinumerik"
    f = tmp_path / "drill.mpf"
    f.write_text("G0 Z10 F100\nR1=5\nCYCLE81(10, 0, 1, -R1)\nM30\n")
    p = load_program(f)
    assert p.metadata["interpreter"] == "feedlog.toolpath.interp.sinumerik"
    assert [m[3] for m in moves(p)] == [10, 1, -5, 10]
    sub = tmp_path / "PART.SPF"
    sub.write_text("PROC PART\nDEF INT K\nG1 F10 X1\nRET\n")
    assert load_program(sub).metadata["interpreter"] == "feedlog.toolpath.interp.sinumerik"
    assert load_program("R1=2\nG1 F100 X=R1\nM30\n", dialect="sinumerik").blocks["x_mm"].iloc[0] == 2
    bad = tmp_path / "bad.mpf"
    bad.write_text("R1=1\nG1 F100 X1\nGOTOF NOWHERE\nM30\n")
    with pytest.raises(ProgramError, match="bad.mpf:3"):
        load_program(bad)
    assert needs_sinumerik_interpreter("X=IC(2)") and not needs_sinumerik_interpreter("N10 G1 X=80 F200\n")
    lenient = load_program("R1=2\nG1 F100 X=R1\nG41 X5\nM30\n", dialect="sinumerik", lenient=True)
    assert lenient.warnings[0].startswith("the Sinumerik front-end refused it (<string>:3: G41")


# -- fuzzing ----------------------------------------------------------------------------------------------

_STATEMENTS = [
    "G0 X{a} Y{b}", "G1 F100 X{a} Z{b}", "G91 X{a}", "G90", "R{i}={a}", "R{i}=R{j}+{a}", "R{i}=R{j}/{b}",
    "X=R{i}", "Y=IC({a})", "IF R{i}>{a} GOTOF LB{j}", "IF R{i}<{a} GOTOB LB{j}", "LB{j}: G1 X{b}", "GOTOF LB{i}",
    "LOOP", "ENDLOOP", "FOR R{i}={a} TO {b}", "ENDFOR", "WHILE R{i}<{b}", "ENDWHILE", "REPEAT", "UNTIL R{i}>={a}",
    "IF R{i}=={a}", "ELSE", "ENDIF", "CYCLE81({b}, 0, 1, -{a})", "MCALL CYCLE82(10, 0, 1, -2, , 0.1)", "MCALL",
    "TRANS X{a}", "AROT RPL={b}", "ATRANS Y{a}", "G2 X{a} Y{b} CR={a}", "G3 X{a} Y{b} I{a} J{b}", "DEF REAL V{i}={a}",
    "M17", "M30", "MSG(\"x\" << R{i})", "G4 F0.1", "SUB{i}", "X=SIN(R{i})*{a}", "R{i}=R{j} MOD {b}", "G54",
]


_SIMPLE = [s for s in _STATEMENTS if s.split()[0] not in ("LOOP", "ENDLOOP", "FOR", "ENDFOR", "WHILE", "ENDWHILE",
                                                           "REPEAT", "UNTIL", "ELSE", "ENDIF")
           and not s.startswith("IF R{i}==")]
_WRAPS = [("IF R{i}=={a}", None, "ENDIF"), ("IF R{i}<{a}", "ELSE", "ENDIF"), ("FOR R{i}={a} TO {b}", None, "ENDFOR"),
          ("WHILE R{i}<{b}", None, "ENDWHILE"), ("REPEAT", None, "UNTIL R{i}>={a}"), ("LOOP", None, "ENDLOOP")]
_FILL = st.fixed_dictionaries({"i": st.integers(0, 3), "j": st.integers(0, 3), "a": st.integers(-20, 20),
                               "b": st.integers(0, 20)})


_FUZZ_SUBS = {"SUB0": "G91 G1 X1\nM17\n", "SUB1": "PROC SUB1\nDEF INT K\nFOR K=1 TO 2\nG1 Y=K\nENDFOR\nRET\n",
              "SUB2": "R3=R3+1\nIF R3<3 GOTOF LB9\nSUB0\nLB9: M17\n", "SUB3": "SUB3\n"}


@st.composite
def _programs(draw, depth=0):
    """Mostly well-nested programs, so that most run; a few structure errors stay in (depth 0 lists
    may end early or carry a stray keyword)."""
    out = []
    for _ in range(draw(st.integers(0, 6))):
        if depth < 3 and draw(st.integers(0, 3)) == 0:
            head, middle, tail = draw(st.sampled_from(_WRAPS))
            f = draw(_FILL)
            out.append(head.format(**f))
            out += draw(_programs(depth + 1))
            if middle:
                out.append(middle)
                out += draw(_programs(depth + 1))
            out.append(tail.format(**f))
        else:
            out.append(draw(st.sampled_from(_SIMPLE)).format(**draw(_FILL)))
    if depth == 0 and draw(st.integers(0, 9)) == 0:
        out.insert(draw(st.integers(0, len(out))), draw(st.sampled_from(["ENDIF", "ELSE", "ENDFOR", "UNTIL R1>0"])))
    return out


@settings(max_examples=300, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(_programs())
def test_fuzz_random_programs_give_a_table_or_one_program_error(lines):
    text = "G1 F100\n" + "\n".join(lines) + "\n"
    try:
        p = run(text, max_blocks=2000, subprograms=_FUZZ_SUBS)
    except ProgramError as exc:
        assert exc.line is not None and "main.mpf" in str(exc)
        return
    assert {"file", "line", "stack"} <= set(p.blocks.columns)
    assert np.isfinite(p.blocks[["x_mm", "y_mm", "z_mm"]].to_numpy()).all()


@settings(max_examples=150, deadline=None, derandomize=True)
@given(st.text(alphabet="GXYZRIJKLF0123456789.=-+*/()<>:; \nABCDEFIMNOPSTUW\"", max_size=120))
def test_fuzz_character_soup(text):
    try:
        run(text, max_blocks=2000)
    except ProgramError:
        pass


def test_proc_save_restores_the_callers_modal_state_and_frame():
    """Job Planning, "SAVE attribute": at the end of a subprogram defined with PROC ... SAVE the modal G
    functions and the frame of the caller are in force again."""
    subs = {"INC": "PROC INC SAVE\nG91 G1 X1\nTRANS X100\nRET\n", "NOSAVE": "PROC NOSAVE\nG91\nRET\n"}
    p = run("G90 G0 X0 F100\nINC\nX5\nNOSAVE\nX5\nM30\n", subprograms=subs)
    assert [m[:2] for m in moves(p)] == [("rapid", 0), ("linear", 1), ("rapid", 5), ("rapid", 10)]
    assert p.blocks[p.blocks["kind"] == "rapid"]["wx_mm"].tolist() == [0, 0, 0]


def test_g53_moves_in_machine_coordinates_for_one_block():
    p = run("TRANS X50\nG0 X10\nG53 X10\nX10\nM30\n")
    b = p.blocks[p.blocks["kind"] == "rapid"]
    assert (b["x_mm"] + b["wx_mm"]).tolist() == [60, 10, 60]


def test_words_without_effect_on_the_path_are_warned_and_other_cycles_stay_with_the_translation():
    p = run("R1=1\nG642 ADIS=0.5 G1 F100 X=R1 TRAORI\nM30\n")
    assert any("ADIS" in w for w in p.warnings) and any("TRAORI" in w for w in p.warnings)
    assert not needs_sinumerik_interpreter("G0 X0\nCYCLE800(1,\"TC1\",0,57,0,0,0,0,0,0,0,0,0,1)\nG1 X1 F10\n")


def test_a_plain_real_program_reads_alike_through_the_front_end_and_the_line_translation():
    """The bundled real program (tests/fixtures/ingest/real/sinumerik_part.mpf: G500 G54 in one block,
    T="..", D1, CYCLE832, G642, X=80, SOFT, CR=, MSG) run through the front-end gives the motion the line
    translation gives (its usual path), row for row."""
    f = ROOT / "tests/fixtures/ingest/real/sinumerik_part.mpf"
    a, b = load_program(f), interpret_sinumerik(f)
    cols = ["x_mm", "y_mm", "z_mm", "cx_mm", "cy_mm", "feed_mm_min", "line"]
    assert a.motion["kind"].tolist() == b.motion["kind"].tolist()
    assert np.allclose(a.motion[cols].to_numpy(float), b.motion[cols].to_numpy(float), equal_nan=True)
    assert any("CYCLE832" in w for w in b.warnings) and any("G54 selected" in w for w in b.warnings)


def test_subprogram_errors_name_the_subprogram_file_and_line(tmp_path):
    subs = tmp_path / "lib"
    subs.mkdir()
    (subs / "POCKET.SPF").write_text("PROC POCKET(REAL D)\nG1 Z=-D\nWHILE D>0\nD=D-1\nM17\n")
    (tmp_path / "main.mpf").write_text("G1 F100\nPOCKET(3)\nM30\n")
    from feedlog.toolpath.interp import InterpOptions
    with pytest.raises(ProgramError, match=r"POCKET.SPF:3: WHILE without its ENDWHILE"):
        load_program(tmp_path / "main.mpf", interp=InterpOptions(search_path=(subs,)))
    (subs / "POCKET.SPF").write_text("PROC POCKET(REAL D)\nG1 Z=-D/0\nM17\n")
    with pytest.raises(ProgramError, match=r"POCKET.SPF:2: division by zero \(called from main.mpf:2\)"):
        load_program(tmp_path / "main.mpf", interp=InterpOptions(search_path=(subs,)))
    with pytest.raises(ProgramError, match=r"main.mpf:2: POCKET takes 1 parameter\(s\), called with 2 \[POCKET"):
        run("G1 F100\nPOCKET(3, 4)\nM30\n", subprograms={"POCKET": "PROC POCKET(REAL D)\nM17\n"})


def test_a_move_before_any_motion_code_is_warned_and_taken_as_g0():
    p = run("X10 Y5\nG1 F100 X0\nM30\n")
    assert moves(p) == [("rapid", 10, 5, 0), ("linear", 0, 5, 0)]
    assert any("initial motion code is machine data" in w for w in p.warnings)


def test_cycles_drill_along_the_planes_tool_axis():
    """Programming Guide Cycles: the drilling axis is the one normal to the plane (G19: X)."""
    p = run("G19 G0 X30 Y5 Z5 F100\nCYCLE81(30, 20, 1, 10)\nM30\n")
    assert [m[1] for m in moves(p)] == [30, 21, 10, 30]
    assert {m[2:] for m in moves(p)} == {(5, 5)}


_FLIP_PROGRAM = ("DEF INT I\nDEF REAL D=2.5\nR1=0 G17 G90 G0 Z10 F200 S1000 M3\nTRANS X10\nFOR I=1 TO 3\n"
                 "  IF I==2 GOTOF SK\n  G1 X=I*5 Y=R1\n  SK: R1=R1+D\nENDFOR\nMCALL CYCLE81(10, 0, 1, -3)\n"
                 "X20 Y20\nMCALL\nAROT RPL=30\nG2 X30 Y0 CR=20\nWHILE R1>0\n R1=R1-5\n L7\nENDWHILE\n"
                 "CYCLE83(10, 0, 1, -20, , -5, , 2, 0, 0, 1, 1)\nM30\n")


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.lists(st.tuples(st.integers(0, len(_FLIP_PROGRAM) - 1), st.integers(1, 255)), min_size=1, max_size=4))
def test_fuzz_bit_flipped_program(flips):
    """A program using most features, with a few bytes changed: a table or one ProgramError."""
    data = bytearray(_FLIP_PROGRAM.encode())
    for at, xor in flips:
        data[at] ^= xor
    try:
        run(data.decode("utf-8", errors="replace"), max_blocks=5000, subprograms={"L7": "G91 G1 Z-1\nG90\nM17\n"})
    except ProgramError as exc:
        assert exc.line is not None
