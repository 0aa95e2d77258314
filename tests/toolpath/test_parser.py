"""parse_program against hand-computed expectations."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from feedlog.errors import ProgramError
from feedlog.toolpath import parse_program
from feedlog.toolpath.schema import BLOCK_COLUMNS

SHARED = Path(__file__).resolve().parents[2] / "recordings" / "programs"  # the shared LinuxCNC programs
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def motion(text: str, **kw):
    return parse_program(text, **kw).motion.reset_index(drop=True)


def test_columns_and_dtypes_follow_the_contract():
    b = parse_program("G21 G90\nG1 X1 F100\n").blocks
    assert list(b.columns[:len(BLOCK_COLUMNS)]) == list(BLOCK_COLUMNS)
    for col, dtype in BLOCK_COLUMNS.items():
        if dtype in ("string", "category"):
            assert str(b[col].dtype) in ("string", "str", "category") and (dtype != "category" or
                                                                          b[col].dtype == "category")
        else:
            assert b[col].dtype == np.dtype(dtype), col
    assert b["block"].tolist() == [0, 1]


def test_modal_state_units_and_feed_on_the_same_line():
    m = motion("G20 G91 G1 X1 F10\nY2\nG21 X1\n")
    assert m["x_mm"].tolist() == pytest.approx([25.4, 25.4, 26.4])
    assert m["y_mm"].tolist() == pytest.approx([0, 50.8, 50.8])
    # F is read before the line's G20 (LinuxCNC's order; its interpreter gives 10 mm/min): F10 is mm/min
    assert m["feed_mm_min"].tolist() == pytest.approx([10.0, 10.0, 10.0])
    assert m["units"].tolist() == ["in", "in", "mm"]
    assert m["kind"].tolist() == ["linear"] * 3


def test_incremental_and_absolute_moves_mix():
    m = motion("G0 X5 Y5\nG91 G1 X1 Y-1 F100\nX1\nG90 X0\nG91 Z-2\n")
    assert m["x_mm"].tolist() == [5, 6, 7, 0, 0]
    assert m["y_mm"].tolist() == [5, 4, 4, 4, 4]
    assert m["z_mm"].tolist() == [0, 0, 0, 0, -2]
    assert m["x0_mm"].tolist() == [0, 5, 6, 7, 0]
    assert m["kind"].tolist() == ["rapid"] + ["linear"] * 4
    assert math.isnan(m["feed_mm_min"][0])  # rapids carry no programmed feed
    assert m["length_mm"].tolist() == pytest.approx([math.hypot(5, 5), math.sqrt(2), 1, 7, 2])


@pytest.mark.parametrize("program, centre, sweep, length, mid", [
    # G17, CW half circle from (0,0) to (10,0) around (5,0): passes (5,5)
    ("G17 G2 X10 Y0 I5 J0", (5, 0, 0), 180, 5 * math.pi, None),
    # G18: (u, v) = (z, x); G2 from x=0 to x=10 around x=5 passes z=-5
    ("G18 G2 X10 Z0 I5 K0", (5, 0, 0), 180, 5 * math.pi, None),
    # G19: (u, v) = (y, z)
    ("G19 G3 Y10 Z0 J5 K0", (0, 5, 0), 180, 5 * math.pi, None),
    # quarter arc by radius: CW, R > 0 -> centre right of the chord
    ("G17 G2 X10 Y0 R7.0710678118654755", (5, -5, 0), 90, 5 * math.sqrt(2) * math.pi / 2, None),
    # negative R: the long way round, centre on the other side
    ("G17 G2 X10 Y0 R-7.0710678118654755", (5, 5, 0), 270, 5 * math.sqrt(2) * 3 * math.pi / 2, None),
    # helical full circle descending 3 mm
    ("G17 G3 X0 Y0 Z-3 I5 J0", (5, 0, 0), 360, math.hypot(10 * math.pi, 3), None),
    # two turns with P2
    ("G17 G3 X0 Y0 I5 J0 P2", (5, 0, 0), 720, 20 * math.pi, None),
])
def test_arcs_in_all_planes(program, centre, sweep, length, mid):
    m = motion(f"G21 G90 F100\n{program}\n")
    row = m.iloc[0]
    assert (row.cx_mm, row.cy_mm, row.cz_mm) == pytest.approx(centre, abs=1e-9)
    assert row.sweep_deg == pytest.approx(sweep)
    assert row.length_mm == pytest.approx(length)
    assert row.kind in ("arc_cw", "arc_ccw")
    assert row.turns >= 1


def test_arc_plane_and_absolute_centre_mode():
    m = motion("G0 X2\nG90.1 G18 G2 X8 Z0 I5 K0 F100\nG91.1 G17 G3 X2 Y0 I-3 J0\n")
    arc1, arc2 = m.iloc[1], m.iloc[2]
    assert arc1.plane == 18 and (arc1.cx_mm, arc1.cz_mm) == (5, 0) and arc1.radius_mm == 3
    assert arc2.plane == 17 and (arc2.cx_mm, arc2.cy_mm) == (5, 0) and arc2.radius_mm == 3


def test_comments_line_numbers_n_words_percent_and_m_codes():
    text = "%\n(title here)\n\nN10 G1 X1 F100 (move) ; trailing\nn20 m3 s1200\nM30\n%\n"
    p = parse_program(text)
    b = p.blocks
    assert b["line"].tolist() == [1, 2, 4, 5, 6]  # blank line 3 has no row; the table ends at the M30
    assert b["comment"].tolist() == ["", "title here", "move trailing", "", ""]
    assert b["n_word"].tolist() == [-1, -1, 10, 20, -1]
    assert b["mcodes"].tolist() == ["", "", "", "M3", "M30"]
    assert b["spindle_rpm"].tolist() == [0, 0, 0, 1200, 1200]
    assert p.metadata["percent_lines"] == [1, 7]
    assert p.metadata["title"] == "title here"
    assert p.metadata["end_line"] == 6


def test_g64_p_q_and_exact_stop_modes():
    b = parse_program("G64\nG1 X1 F1\nG64 P0.05\nX2\nG64 P0.05 Q0\nX3\nG61\nX4\nG61.1\nX5\n"
                      "G20 G64 P0.001\nX6\n").motion
    assert b["path_mode"].tolist() == ["continuous"] * 3 + ["exact_path", "exact_stop", "continuous"]
    tol = b["tol_mm"].to_numpy()
    assert math.isnan(tol[0]) and tol[1:].tolist() == pytest.approx([0.05, 0.05, 0, 0, 0.0254])
    merge = b["merge_tol_mm"].to_numpy()
    assert math.isnan(merge[0]) and merge[1] == 0.05 and merge[2] == 0 and merge[5] == pytest.approx(0.0254)


def test_dwell_inverse_time_and_orientation_vectors():
    b = parse_program("G1 X10 F100\nG4 P0.5\nG93 G1 X20 F2\nG94 G1 X0 Y0 Z1 I0 J0 K2 F500\nX1\n").blocks
    assert b["kind"].tolist() == ["linear", "dwell", "linear", "linear", "linear"]
    assert b["dwell_s"].tolist() == [0, 0.5, 0, 0, 0]
    assert b["feed_mm_min"][2] == pytest.approx(20.0)  # 10 mm in 1/2 min
    assert b["inverse_time"].tolist() == [False, False, True, False, False]
    with pytest.raises(ProgramError, match="feed"):  # G93 -> G94 forgets F, as LinuxCNC does
        parse_program("G1 X1 F100\nG93 G1 X2 F1\nG94 G1 X3\n")
    assert np.isnan(b["ori_k"][0])
    assert b.loc[3, ["ori_i", "ori_j", "ori_k"]].tolist() == [0, 0, 1]
    assert b.loc[4, ["ori_i", "ori_j", "ori_k"]].tolist() == [0, 0, 1]  # modal once given


def test_rotary_axes_in_degrees_are_not_scaled_by_inches():
    m = motion("G20 G1 X1 A90 C-45 F10\n")
    assert (m.x_mm[0], m.a_deg[0], m.c_deg[0]) == (25.4, 90, -45)


@pytest.mark.parametrize("text, code", [
    ("G1 X1 F100\nG41 X2\n", "G41"),
    ("G1 X1 F100\nG83 X2\n", "G83"),
    ("G1 X1 U3 F100\n", "U3"),
    ("M98\n", "M98"),
    ("#1 = 5\n", "#1 = 5"),
    ("o100 sub\n", "o100 sub"),
])
def test_unsupported_codes_name_file_line_and_code(text, code):
    with pytest.raises(ProgramError) as info:
        parse_program(text, name="part.ngc")
    err = info.value
    assert err.file == "part.ngc" and err.code == code
    assert err.line == text.count("\n", 0, text.index(code.split()[0][:2]) if code[0] != "#" else 0) + 1
    assert "part.ngc:" in str(err)


def test_lenient_mode_lists_unsupported_codes_and_skips_them():
    p = parse_program("G1 X1 F100\nG41 X2\nG1 Y3 U4\n#1=2\n", lenient=True)
    assert [(u.line, u.code) for u in p.unsupported] == [(4, "#1=2"), (3, "U4"), (2, "G41")] or \
        sorted((u.line, u.code) for u in p.unsupported) == [(2, "G41"), (3, "U4"), (4, "#1=2")]
    m = p.motion
    assert m["x_mm"].tolist() == [1, 1] and m["y_mm"].tolist() == [0, 3]  # G41's X2 not applied
    assert any("G41" in w for w in p.warnings)


@pytest.mark.parametrize("text", [
    "G1 X1.2.3 F1\n", "G1 X F1\n", "G1 X--1 F1\n", "12 G1\n", "G1 (unclosed\n", "G1 ((nested)) X1\n",
    "G1 X1 X2 F1\n", "G0 G1 X1\n", "G2 X1 Y1 I2 J0 F1\n",  # radius mismatch
    "G2 X10 Y0 R2 F1\n", "G1 X1\n", "G4\n", "G1 X1 F1\nG4 P1 X2\n", "X1\n", "G2 X1 R1 I1 F1\n",
    "G17 G2 X1 Y1 I1 K1 F1\n", "%G1\n",
])
def test_malformed_programs_raise_program_error_with_line(text):
    with pytest.raises(ProgramError) as info:
        parse_program(text, name="bad.ngc")
    assert info.value.line == 1 or info.value.line == 2
    assert info.value.file == "bad.ngc"


def test_missing_file_is_a_program_error(tmp_path):
    with pytest.raises(ProgramError, match="cannot read"):
        parse_program(tmp_path / "missing.ngc")


def _simple_linuxcnc_reference(path: Path) -> tuple[int, float]:
    """Independent reading of the G0/G1 absolute XYZ test programs: motion count and path length."""
    pos = {"X": 0.0, "Y": 0.0, "Z": 0.0}
    n, total = 0, 0.0
    for line in path.read_text().splitlines():
        words = dict(re.findall(r"([XYZ])(-?[0-9.]+)", line.split("(")[0]))
        if not words:
            continue
        new = {**pos, **{k: float(v) for k, v in words.items()}}
        total += math.dist([pos[a] for a in "XYZ"], [new[a] for a in "XYZ"])
        pos, n = new, n + 1
    return n, total


@pytest.mark.parametrize("name", ["test_p001.ngc", "dense002q0.ngc", "5ax_g61.ngc"])
def test_real_linuxcnc_programs(name):
    path = SHARED / name
    p = parse_program(path)
    n, length = _simple_linuxcnc_reference(path)
    assert len(p.motion) == n
    assert p.motion["length_mm"].sum() == pytest.approx(length)
    assert p.warnings == [] and p.unsupported == []
    assert p.blocks["file"].iloc[0] == str(path)


def test_linuxcnc_program_modes():
    path = SHARED / "dense002q0.ngc"
    m = parse_program(path).motion
    assert (m["tol_mm"] == 0.01).all() and (m["merge_tol_mm"] == 0).all()
    assert (m["feed_mm_min"].iloc[1:] == 3000).all()
    assert m["line"].iloc[0] == 6  # G0 X10 Y0 Z0


def test_bundled_pocket_example():
    p = parse_program(EXAMPLES / "pocket.ngc")
    m = p.motion
    assert p.metadata["program_number"] == 1000
    assert m["kind"].value_counts()[lambda c: c > 0].to_dict() == {"linear": 9, "arc_cw": 3, "arc_ccw": 2, "rapid": 2}
    helix = m[m["z0_mm"] != m["z_mm"]].iloc[-2]
    assert helix.kind == "arc_cw" and helix.length_mm == pytest.approx(math.hypot(5 * math.pi, 0.5))


def test_byte_order_mark_crlf_and_text_after_the_end(tmp_path):
    path = tmp_path / "win.ngc"
    path.write_bytes("\ufeff%\r\nG1 X1 F100\r\n%\r\nG1 X2\r\n".encode("utf-8"))
    p = parse_program(path)
    assert p.motion["x_mm"].tolist() == [1] and p.motion["line"].tolist() == [2]  # not run after the '%'
    assert any("closing '%'" in w for w in p.warnings)
    q = parse_program("G1 X1 F1\nM30\nG1 X3\n")
    assert any("program end" in w for w in q.warnings) and q.motion["x_mm"].tolist() == [1]


@pytest.mark.parametrize("tail", ["", "\nG1 X9 ; semicolon comment forces the line-by-line path"])
def test_paren_comments_several_per_line_and_unicode(tail):
    p = parse_program(f"G1 X1 F1 (a) (b é)\n( c )\nG1(mid)X2\n{tail}")
    b = p.blocks
    assert b["comment"].tolist()[:3] == ["a b é", "c", "mid"]
    assert b["x_mm"].tolist()[:3] == [1, 1, 2]
    with pytest.raises(ProgramError, match="comment"):
        parse_program("G1 X1 F1 (a (b) c)\n" + tail)


def test_lenient_skipped_parameter_line_does_not_shift_later_numbers():
    p = parse_program("G21 F100\n#5=1 [2]\nG90 G0 X1.5\nG1 X2.25 Y-3\n", lenient=True)
    assert [(u.line, u.code) for u in p.unsupported] == [(2, "#5=1 [2]")]
    assert p.motion[["x_mm", "y_mm"]].to_numpy().tolist() == [[1.5, 0], [2.25, -3]]


@pytest.mark.parametrize("chunk_bytes", [16, 1 << 20])
def test_moves_after_the_program_end_are_not_in_the_table(chunk_bytes):
    """A controller stops at the first M2/M30 (or the closing '%'): the moves after it are counted in a
    warning, not simulated, also when the end falls in an earlier chunk than the moves."""
    from feedlog.toolpath.stream import open_program_reader

    tail = "".join(f"G1 X{i} Y{i % 3}\n" for i in range(2, 9))
    for text, end in (("G21 G90\nG1 X1 F100\nM30\n" + tail, 3), ("%\nG21 G90\nG1 X1 F100\n%\n" + tail, 4)):
        with open_program_reader(text, name="end.ngc", chunk_bytes=chunk_bytes) as reader:
            program = reader.program()
        assert program.blocks["line"].max() == end
        assert (program.blocks["kind"] == "linear").sum() == 1
        assert reader.motion_rows == 1
        assert any(w.startswith("7 motion blocks after the") and "not run" in w for w in program.warnings)
