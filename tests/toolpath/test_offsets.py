"""Work coordinate systems (G10 L2/L20, G54-G59.3, G92/G92.1) against hand-computed expectations.

Convention checked everywhere: machine = program + work offset; an offset change never moves the machine,
so the next block starts at (previous machine point - new offset) in program coordinates."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from feedlog.errors import ProgramError
from feedlog.toolpath import block_features, cl_points, linearize, parse_program, to_machine
from feedlog.toolpath.schema import OFFSET_COLUMNS, OFFSET_FEATURE_COLUMNS

WORK = ["wx_mm", "wy_mm", "wz_mm", "wa_deg", "wb_deg", "wc_deg"]
END = ["x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"]
START = ["x0_mm", "y0_mm", "z0_mm", "a0_deg", "b0_deg", "c0_deg"]


def motion(text: str, **kw):
    return parse_program(text, **kw).motion.reset_index(drop=True)


def test_programs_without_offsets_have_zero_offsets_in_g54():
    b = parse_program("G21 G90\nG1 X1 F100\nG55\nG1 Y2\n").blocks
    assert list(b.columns[b.columns.get_loc("comment") + 1:][:len(OFFSET_COLUMNS)]) == list(OFFSET_COLUMNS)
    assert (b[WORK].to_numpy() == 0).all()
    assert b["coord_system"].tolist() == [1, 1, 2, 2]
    assert b["coord_system"].dtype == np.int8


def test_g10_l2_on_the_active_system_shifts_the_current_point():
    m = motion("G0 X1 Y2 Z3\nG10 L2 P1 X15 Y-10 Z5 A1 C2\nG1 X4 F100\n")
    # line 3: the machine stays at (1, 2, 3, 0, 0, 0); in the new coordinates that is (-14, 12, -2, -1, 0, -2)
    assert m.loc[1, START].tolist() == pytest.approx([-14, 12, -2, -1, 0, -2])
    assert m.loc[1, END].tolist() == pytest.approx([4, 12, -2, -1, 0, -2])
    assert m.loc[1, WORK].tolist() == pytest.approx([15, -10, 5, 1, 0, 2])
    assert m.loc[0, WORK].tolist() == pytest.approx([0] * 6)
    assert m.loc[1, "length_mm"] == pytest.approx(18.0)  # machine X 1 -> 19


def test_g10_l2_of_another_system_applies_when_selected_and_p0_means_active():
    b = parse_program("G10 L2 P2 X5\nG0 X1\nG55\nG1 X2 F100\nG10 L2 P0 Y3\nG1 X2\nG54 G0 X0\n").blocks
    assert b["wx_mm"].tolist() == pytest.approx([0, 0, 5, 5, 5, 5, 0])
    assert b["wy_mm"].tolist() == pytest.approx([0, 0, 0, 0, 3, 3, 0])
    assert b["coord_system"].tolist() == [1, 1, 2, 2, 2, 2, 1]
    m = motion("G10 L2 P2 X5\nG0 X1\nG55\nG1 X2 F100\nG10 L2 P0 Y3\nG1 X2\nG54 G0 X0\n")
    assert m["x0_mm"].tolist() == pytest.approx([0, -4, 2, 7])   # machine 1 = G55 X-4; G54 again: 7
    assert m["y_mm"].tolist() == pytest.approx([0, 0, -3, 0])


def test_g10_values_are_absolute_in_g91_and_in_program_units():
    m = motion("G20 G91\nG10 L2 P1 X1 Z-0.5\nG1 X1 F10\n")
    assert m.loc[0, ["wx_mm", "wz_mm"]].tolist() == pytest.approx([25.4, -12.7])
    # machine starts at 0 -> program X -25.4; incremental X1 inch -> program 0, machine 25.4
    assert m.loc[0, ["x0_mm", "x_mm", "z_mm"]].tolist() == pytest.approx([-25.4, 0.0, 12.7])


def test_g10_l20_makes_the_current_point_the_given_value():
    # machine at X7 Y1; G56 set so that this point is X2 there: G56 X = 7 - 2 = 5
    m = motion("G91 G0 X3 Y1\nX4\nG10 L20 P3 X2\nG56\nG1 X1 F100\n")
    assert m.loc[2, "wx_mm"] == pytest.approx(5.0)
    assert m.loc[2, ["x0_mm", "x_mm", "y_mm"]].tolist() == pytest.approx([2.0, 3.0, 1.0])
    assert to_machine(m).loc[2, "x_mm"] == pytest.approx(8.0)


def test_g92_and_g92_1_add_to_the_coordinate_system_offset():
    text = "G10 L2 P1 X10\nG0 X5\nG92 X1 Y2\nG1 X3 F100\nG92.1\nG1 X3\n"
    m = motion(text)
    # machine X 15; G92 X = 15 - 10 - 1 = 4, G92 Y = 0 - 0 - 2 = -2
    assert m["wx_mm"].tolist() == pytest.approx([10, 14, 10])
    assert m["wy_mm"].tolist() == pytest.approx([0, -2, 0])
    assert m["x0_mm"].tolist() == pytest.approx([-10, 1, 7])
    assert to_machine(m)["x_mm"].tolist() == pytest.approx([15, 17, 13])


def test_to_machine_shifts_ends_starts_and_arc_centres_only():
    p = parse_program("G10 L2 P1 X100 Y50\nG0 X0 Y0\nG2 X10 Y0 I5 J0 F100\n")
    m = to_machine(p.blocks)
    arc = m[m["kind"] == "arc_cw"].iloc[0]
    assert [arc.x0_mm, arc.y0_mm, arc.x_mm, arc.cx_mm, arc.cy_mm] == pytest.approx([100, 50, 110, 105, 50])
    assert arc.radius_mm == pytest.approx(5.0) and arc.length_mm == pytest.approx(5 * np.pi)
    assert p.blocks.loc[2, "x_mm"] == pytest.approx(10.0)  # the program table is untouched
    assert to_machine(p).equals(m)  # a Program works too
    plain = parse_program("G1 X1 F10\n").blocks
    assert to_machine(plain)[END].equals(plain[END])
    assert to_machine(plain.drop(columns=WORK))[END].equals(plain[END])  # hand-built tables


def test_cl_points_in_both_frames_with_one_path_length():
    text = "G10 L2 P1 X10\nG10 L2 P2 X20\nG0 X0\nG1 X1 F100\nG55\nG1 Y1\n"
    prog = parse_program(text)
    prg = cl_points(prog, frame="program")
    mach = cl_points(prog, frame="machine")
    assert prg["x_mm"].tolist() == pytest.approx([-10, 0, 1, -9])  # each point in its block's coordinates
    assert mach["x_mm"].tolist() == pytest.approx([0, 10, 11, 11])
    assert mach["y_mm"].tolist() == pytest.approx([0, 0, 0, 1])
    assert mach["s_mm"].tolist() == pytest.approx([0, 10, 11, 12])
    assert prg["s_mm"].tolist() == pytest.approx(mach["s_mm"].tolist())
    assert mach["wx_mm"].tolist() == pytest.approx([10, 10, 10, 20])
    with pytest.raises(Exception, match="frame"):
        cl_points(prog, frame="world")


def test_linearize_starts_each_block_at_its_own_start():
    p = parse_program("G0 X5\nG10 L2 P1 X2\nG2 X0 Y0 I-1.5 J0 F100\n")
    lin = linearize(p, 1e-4)
    chords = lin.blocks[lin.blocks["block"] == 2]
    assert len(chords) > 1
    assert chords.iloc[0][["x0_mm", "y0_mm"]].tolist() == pytest.approx([3.0, 0.0])  # machine 5 - 2
    assert chords["length_mm"].sum() == pytest.approx(1.5 * np.pi, rel=1e-3)


def test_features_carry_the_workpiece_offset():
    p = parse_program("G10 L2 P1 X15 Y-10 Z5\nG0 X0 Y0 Z0\nG1 X1 F100\nG92 X0\nG1 X1\n")
    f = block_features(p)
    assert list(f.columns[-3:]) == list(OFFSET_FEATURE_COLUMNS)
    assert f["xo_mm"].tolist() == pytest.approx([15, 15, 16])
    assert f["yo_mm"].tolist() == pytest.approx([-10, -10, -10])
    assert f["zo_mm"].tolist() == pytest.approx([5, 5, 5])
    assert f["length_mm"].tolist() == pytest.approx([np.sqrt(15**2 + 10**2 + 5**2), 1, 1])
    assert f.loc[2, "corner_start_deg"] == pytest.approx(0.0)  # collinear in machine coordinates
    plain = block_features(parse_program("G1 X1 F100\n"))
    assert (plain[list(OFFSET_FEATURE_COLUMNS)].to_numpy() == 0).all()


def test_rotary_work_offset_turns_the_orientation_from_machine_angles():
    # program A0 with a G54 A offset of 30 deg: the machine tilts 30 deg, sin(A) = 0.5
    f = block_features(parse_program("G10 L2 P1 A30\nG1 X1 A0 F100\n"), "linuxcnc-xyzac")
    assert f.loc[0, "sin_rot"] == pytest.approx(0.5)


@pytest.mark.parametrize("text, line, code", [
    ("G0 X1\nG10 L1 P1 Z1\n", 2, "G10 L1 P1"),            # tool table
    ("G10 L10 P1 Z1\n", 1, "G10 L10 P1"),
    ("G10 L2 X1\n", 1, "G10 L2"),                         # no P
    ("G10 L2 P10 X1\n", 1, "G10 L2 P10"),
    ("G10 L2 P1 R30 X1\n", 1, "G10 L2 P1 R30"),            # XY rotation
    ("G10 P1 X1\n", 1, "G10 P1"),                         # no L
    ("G1 X1 F10\nG1 L2 X2\n", 2, "L2"),                   # L without G10
    ("G92.2\n", 1, "G92.2"),
    ("G53 G0 X1\n", 1, "G53"),
    ("G0 X1\nG92\n", 2, "G92"),                           # G92 needs axis words
    ("G92.1 X1\n", 1, "X"),
    ("G4 G10 L2 P1 X1\n", 1, "G4 G10"),                   # one non-modal code per line
])
def test_unsupported_or_malformed_offset_codes_raise_naming_file_line_and_code(text, line, code):
    with pytest.raises(ProgramError) as info:
        parse_program(text, name="part.ngc")
    err = info.value
    assert err.code == code
    assert f"part.ngc:{line}" in str(err)


def test_lenient_skips_unsupported_g10_with_its_words():
    p = parse_program("G10 L2 P1 X5\nG0 X1\nG10 L1 P1 Z3 R2\nG1 X2 F100\n", lenient=True)
    assert [(u.line, u.code) for u in p.unsupported] == [(3, "G10 L1 P1 R2")]
    assert any("G10 L1 P1" in w for w in p.warnings)
    m = p.motion.reset_index(drop=True)
    assert m["wx_mm"].tolist() == pytest.approx([5, 5])
    assert m["z_mm"].tolist() == pytest.approx([0, 0])
    assert to_machine(m)["x_mm"].tolist() == pytest.approx([6, 7])


def test_offset_rows_are_not_motion():
    b = parse_program("G1 X1 F100\nG10 L2 P1 X3 Y4\nG92 Z1\nG92.1\n").blocks
    assert b["kind"].tolist() == ["linear", "none", "none", "none"]
    assert b["length_mm"].tolist() == [1.0, 0.0, 0.0, 0.0]


RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"
RECORDED = sorted(RECORDINGS.glob("*offset*.mcap"))


@pytest.mark.parametrize("path", RECORDED, ids=lambda p: p.stem)
def test_machine_frame_cl_points_lie_on_the_linuxcnc_recording(path):
    """LinuxCNC's recorded axis positions are machine coordinates: the program's CL points plus the G54
    offset must lie on the measured path (within the G64 P blend tolerance); in program coordinates they
    are off by the offset."""
    from scipy.spatial import cKDTree

    from feedlog.ingest import read_recording

    program = parse_program(RECORDINGS / "programs" / f"{path.stem}.ngc")
    measured = read_recording(path).streams["axes"][["x_mm", "y_mm", "z_mm"]].to_numpy(dtype=float)
    tree = cKDTree(measured)
    tol = float(np.nan_to_num(program.motion["tol_mm"].max()))
    offset = float(np.linalg.norm(program.motion[["wx_mm", "wy_mm", "wz_mm"]].to_numpy()[-1]))
    for frame, check in (("machine", lambda d: d.max() <= tol + 0.01),
                         ("program", lambda d: np.median(d) > offset / 4)):
        cl = cl_points(program, chord_tol_mm=0.001, frame=frame)
        feed = (cl["kind"] != "start") & (cl["kind"] != "rapid")
        dist, _ = tree.query(cl.loc[feed, ["x_mm", "y_mm", "z_mm"]].to_numpy())
        assert check(dist), (frame, dist.max(), np.median(dist))


def test_summary_lists_work_offsets_and_the_machine_bbox():
    from feedlog.profile import load_profile
    from feedlog.toolpath import summarize

    p = parse_program("G10 L2 P2 X100 Y-5\nG0 X0 Y0\nG1 X10 F100\nG55\nG1 X0\nG1 Y2\n")
    s = summarize(p, load_profile("linuxcnc-xyz"))
    assert s["work_offsets"] == [{"coord_system": "G54", "offset": {}, "blocks": 2},
                                 {"coord_system": "G55", "offset": {"wx_mm": 100.0, "wy_mm": -5.0}, "blocks": 2}]
    # machine path: 0 -> 10 (G54), then G55 starts at program X-90 Y5, goes to X0 (machine 100), Y2 (machine -3)
    assert s["bbox_machine"]["x_mm"] == pytest.approx([0.0, 100.0])
    assert s["bbox_machine"]["y_mm"] == pytest.approx([-3.0, 0.0])
    assert s["bbox"]["x_mm"] == pytest.approx([-90.0, 10.0])  # program coordinates, each block in its own
    plain = summarize(parse_program("G1 X1 F10\n"), load_profile("linuxcnc-xyz"))
    assert plain["work_offsets"] == [] and plain["bbox_machine"] is None
