"""G5 / G5.1 splines (toolpath/interp/spline.py): the motion controller's biarcs, LinuxCNC's checks.

Without LinuxCNC: the curve, the biarcs' tangency and the errors, each derived here. With LinuxCNC's
`gcode` module (tests/toolpath/reference): that module draws a spline as 15 chords per control point
where the motion controller (which feedlog follows) runs 4 biarcs per control point; both sample the
same curve at equal steps of u, so every 15th chord end must be every 4th biarc end to 1e-6 mm (with
the offsets, rotation, tool offset, line and feed of the move), every chord end must lie on feedlog's
arcs within SPLINE_PATH_TOL_MM, and every other move must be the same move by move."""

from __future__ import annotations

import math
import os
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from feedlog.errors import ProgramError
from feedlog.toolpath import load_program
from feedlog.toolpath.interp import interpret

from .reference import NCFILES, Reference, check_refused_alike, compare, needs_linuxcnc, reference, run_both

# LinuxCNC's chord ends (points of the curve) to feedlog's biarcs: systems.ngc (gentle curves) within
# SPLINE_PATH_TOL_MM; tight random loops within SPLINE_PATH_SHARE of the spline's length (measured: see
# docs/interpreter.md): the biarc fit's own error, which the motion controller runs too
SPLINE_PATH_TOL_MM = 1e-5
SPLINE_PATH_SHARE = 0.05
MOVES = ["rapid", "linear", "arc_cw", "arc_ccw"]


def _bezier(ctrl, u):
    """de Casteljau (independent of spline.py's Bernstein sums)."""
    pts = [np.array(c, float) for c in ctrl]
    while len(pts) > 1:
        pts = [(1 - u) * a + u * b for a, b in zip(pts, pts[1:])]
    return pts[0]


def _moves(program, line=None):
    b = program.blocks
    m = b[b["kind"].astype(str).isin(MOVES)]
    return m if line is None else m[m["line"] == line]


def _tangent(row, start, *, at_end=False):
    """Unit tangent of a move at its start point (or its end)."""
    end = np.array([row.x_mm, row.y_mm])
    if row.kind == "linear":
        d = end - start
        return d / np.linalg.norm(d)
    r = (end if at_end else start) - np.array([row.cx_mm, row.cy_mm])
    t = np.array([-r[1], r[0]]) if row.kind == "arc_ccw" else np.array([r[1], -r[0]])
    return t / np.linalg.norm(t)


def test_a_cubic_spline_is_16_biarcs_through_the_bezier_curve_with_one_tangent():
    text = "G21 G17 G90 F600\nG0 X1 Y2\nG5 X11 Y2 I2 J5 P-2 Q5\nM2\n"
    program = interpret(text, name="g5.ngc")
    rows = _moves(program, 3)
    assert len(rows) == 32 and set(rows["kind"].astype(str)) <= {"arc_cw", "arc_ccw", "linear"}
    ctrl = [(1, 2), (3, 7), (9, 7), (11, 2)]
    start = np.array([1.0, 2.0])
    prev_tangent = None
    for k, row in enumerate(rows.itertuples()):
        end = np.array([row.x_mm, row.y_mm])
        if row.kind != "linear":      # an arc: start and end on its circle
            c = np.array([row.cx_mm, row.cy_mm])
            assert abs(np.linalg.norm(start - c) - np.linalg.norm(end - c)) < 1e-9
        if k % 2 == 1:                # every biarc ends on the curve at u = (k + 1) / 32
            assert np.allclose(end, _bezier(ctrl, (k + 1) / 32), atol=1e-9)
        t0 = _tangent(row, start)
        if prev_tangent is not None:  # tangent-continuous (the curve's tangent is a 1e-5 chord: ~1e-6 rad)
            assert np.dot(t0, prev_tangent) > 1 - 1e-9
        prev_tangent = _tangent(row, start, at_end=True)
        start = end
    assert np.allclose(start, (11, 2)) and rows["z_mm"].eq(0).all() and rows["feed_mm_min"].eq(600).all()
    first = _tangent(next(rows.itertuples()), np.array([1.0, 2.0]))
    # the start tangent is the I J direction (to the one-sided 1e-5 chord LinuxCNC takes there)
    assert np.allclose(first, np.array([2, 5]) / math.hypot(2, 5), atol=1e-4)


def test_g5_without_i_j_continues_with_the_last_end_tangent_and_g5_1_is_quadratic():
    text = ("G21 F300\nG0 X0 Y0 Z3\nG5 X10 Y0 I0 J4 P-3 Q-4\nG5 X20 Y0 P0 Q4\n"
            "G5.1 X30 Y5 I5 J0\nG91 G5.1 X5 Y5 I0 J5\nM2\n")
    program = interpret(text, name="g5.ngc")
    second = _moves(program, 4)
    assert len(second) == 32
    # no I J: the first control point is the start minus the last G5's P Q: (10, 0) + (3, 4)
    for k in (7, 15, 23, 31):
        row = second.iloc[k]
        u = (k + 1) / 32
        assert np.allclose([row.x_mm, row.y_mm], _bezier([(10, 0), (13, 4), (20, 4), (20, 0)], u), atol=1e-9)
    quad = _moves(program, 5)
    assert len(quad) == 24
    for k in (5, 11, 17, 23):
        row = quad.iloc[k]
        assert np.allclose([row.x_mm, row.y_mm], _bezier([(20, 0), (25, 0), (30, 5)], (k + 1) / 24), atol=1e-9)
    rel = _moves(program, 6)     # G91: X Y relative to the start, I J always relative
    assert np.allclose(rel[["x_mm", "y_mm"]].iloc[-1], (35, 10)) and rel["z_mm"].eq(3).all()
    row = rel.iloc[11]
    assert np.allclose([row.x_mm, row.y_mm], _bezier([(30, 5), (30, 10), (35, 10)], 0.5), atol=1e-9)


@pytest.mark.parametrize(("text", "line", "message"), [
    ("G18 F100\nG5.1 X1 Y1 I1 J0\n", 2, "XY plane"),
    ("F100\nG5.1 X1 Y1 Z1 I1 J0\n", 2, "Z, A, B, or C"),
    ("F100\nG5.1 X1 Y1 I1\n", 2, "both I and J with G5.1"),
    ("F100\nG5 X1 Y1 I1 P1 Q1\n", 2, "both I and J, or neither"),
    ("F100\nG5 X1 Y1 I1 J1 P1\n", 2, "both P and Q"),
    ("F100\nG5.1 X1 Y1 I1 J0 P1\n", 2, "P word with no"),
    ("F100\nG5.1 X1 Y1 I1 J0 Q1\n", 2, "Q word with no"),
    ("G5.1 X1 Y1 I1 J0\n", 1, "zero feed rate"),
    ("F100\nG41.1 D1 G1 X5\nG5.1 X9 Y1 I1 J0\n", 3, "cutter radius compensation"),
    ("G93\nG5.1 X1 Y1 I1 J0\n", 2, "F word missing"),
    ("G93\nG5.1 X1 Y1 I1 J0 F2\n", 2, "inverse time"),
    ("F100\nG5\n", 2, "all axes missing"),
    ("F100\nG5.1 X1 Y0 I0.5 J0\n", 2, "straight"),
])
def test_spline_errors_name_the_line(text, line, message):
    with pytest.raises(ProgramError, match=re.escape(message)) as err:
        interpret(text, name="bad.ngc")
    assert err.value.line == line and err.value.file == "bad.ngc"


def test_an_ngc_file_with_g5_1_goes_to_the_interpreter_not_the_fanuc_translation(tmp_path):
    path = tmp_path / "spline.ngc"
    path.write_text("G21 F300\nG0 X0 Y0\nG5.1 X10 Y10 I10 J0\nM2\n")
    program = load_program(path)
    assert program.metadata["dialect"] == "rs274ngc"
    assert program.metadata["interpreter"] == "feedlog.toolpath.interp" and len(_moves(program, 3)) == 24
    fanuc = load_program("G0 X5 Y5\nG05.1 Q1\nG1 X1 F100\nM30\n")   # Fanuc's look-ahead switch stays Fanuc's
    assert fanuc.metadata["dialect"] == "fanuc"


def test_a_quadratic_nurbs_with_unit_weights_is_the_g5_1_curve_and_weights_make_a_circle():
    g51 = _moves(interpret("G21 F300\nG0 X0 Y0\nG5.1 X10 Y10 I10 J0\nM2\n", name="a.ngc"), 3)
    nurbs = _moves(interpret("G21 F300\nG0 X0 Y0\nG5.2 X10 Y0 P1\nX10 Y10 P1\nG5.3\nM2\n", name="b.ngc"), 5)
    assert len(nurbs) == len(g51) == 24
    assert np.allclose(nurbs[["x_mm", "y_mm", "cx_mm", "cy_mm"]].to_numpy(float),
                       g51[["x_mm", "y_mm", "cx_mm", "cy_mm"]].to_numpy(float), atol=1e-9, equal_nan=True)
    # a quarter circle of radius 10 about (0, 10): weights 1, cos 45 deg, 1; every biarc end on the circle
    w = math.cos(math.radians(45))
    circle = _moves(interpret(f"G21 F300\nG0 X0 Y0\nG5.2 X10 Y0 P{w!r}\nX10 Y10 P1\nG5.3\nM2\n", name="c.ngc"), 5)
    ends = circle[["x_mm", "y_mm"]].to_numpy()[1::2]
    assert np.allclose(np.hypot(ends[:, 0], ends[:, 1] - 10), 10, atol=1e-9)
    # order 4 over 6 points: 24 biarcs, ending on the last point; the position moves only at G5.3
    p = interpret("G21 F300\nG0 X0 Y0\nG5.2 X10 Y0 P1 L4\nX10 Y10 P2\nX0 Y10 P1\nX-5 Y5 P1\nX-3 Y0 P3\n"
                  "G5.3\nG91 G1 X1\nM2\n", name="d.ngc")
    assert len(_moves(p, 8)) == 48 and _moves(p, 9)[["x_mm", "y_mm"]].to_numpy().tolist() == [[-2.0, 0.0]]
    assert len(_moves(p, 3)) == 0


@pytest.mark.parametrize(("text", "line", "message"), [
    ("F100\nG5.2 X1 P1\n", 2, "both X and Y"),
    ("F100\nG5.2 X1 Y1 P1\nP2\n", 3, "P word with no"),
    ("F100\nG5.2 X1 Y1 P1\nX2 Y2\n", 3, "positive weight P"),
    ("F100\nG5.2 X1 Y1 P1 L4\nX2 Y0 P1\nG5.3\n", 4, "at least equal to the order L = 4"),
    ("F100\nG5.3\n", 2, "without G5.2 first"),
    ("G5.2 X1 Y1 P1\n", 1, "0 feedrate"),
    ("F100\nG18\nG5.2 X1 Y1 P1\n", 3, "XY plane"),
])
def test_nurbs_errors_name_the_line(text, line, message):
    with pytest.raises(ProgramError, match=re.escape(message)) as err:
        interpret(text, name="bad.ngc")
    assert err.value.line == line


# -- against LinuxCNC -------------------------------------------------------------------------------

_G5 = re.compile(r"G\s*0*5(\.[13])?(?![.\d])", re.IGNORECASE)


def _spline_points(line_text: str) -> int:
    """Control points of the spline a line runs: 4 (G5), 3 (G5.1), -1 (G5.3: as many as were given)."""
    m = _G5.search(line_text.split("(")[0])
    return 0 if m is None else {None: 4, ".1": 3, ".3": -1}[m.group(1)]


def _distance_to_path(points, start, rows) -> np.ndarray:
    """Shortest distance from each of `points` (n x 2) to the moves `rows` (lines and arcs) from `start`."""
    pts = np.asarray(points, float)
    ends = rows[["x_mm", "y_mm"]].to_numpy()
    starts = np.vstack([np.asarray(start, float)[None, :], ends[:-1]])
    best = np.minimum(np.linalg.norm(pts[:, None, :] - ends[None], axis=2).min(axis=1),
                      np.linalg.norm(pts[:, None, :] - starts[None], axis=2).min(axis=1))
    for a, b, kind, c in zip(starts, ends, rows["kind"].astype(str), rows[["cx_mm", "cy_mm"]].to_numpy()):
        if kind == "linear":
            d = b - a
            t = np.clip((pts - a) @ d / max(float(d @ d), 1e-300), 0, 1)
            best = np.minimum(best, np.linalg.norm(a + t[:, None] * d - pts, axis=1))
            continue
        ang0, ang1 = math.atan2(a[1] - c[1], a[0] - c[0]), math.atan2(b[1] - c[1], b[0] - c[0])
        angp = np.arctan2(pts[:, 1] - c[1], pts[:, 0] - c[0])
        sign = 1.0 if kind == "arc_ccw" else -1.0
        sweep = (sign * (ang1 - ang0)) % (2 * math.pi)
        at = (sign * (angp - ang0)) % (2 * math.pi)
        on = np.abs(np.linalg.norm(pts - c, axis=1) - np.linalg.norm(a - c))
        best = np.where(at <= sweep, np.minimum(best, on), best)
    return best


def spline_problems(program, ref: Reference, text: str, *, tol: float = 1e-6) -> tuple[list[str], float, float]:
    """Differences to LinuxCNC's `gcode` module (empty: the same), the largest distance of its chord ends
    from feedlog's spline moves (mm), and the largest such distance as a share of its spline's length."""
    lines = text.splitlines()
    ours = _moves(program).reset_index(drop=True)
    kept_ours, kept_ref, node_ours, node_ref = [], [], [], []
    problems, worst, worst_share = [], 0.0, 0.0
    i = j = 0
    while i < len(ours) and j < len(ref.moves):
        line = int(ours["line"].iloc[i])
        n = _spline_points(lines[line - 1]) if 0 < line <= len(lines) else 0
        if not n:
            kept_ours.append(i)
            kept_ref.append(j)
            i, j = i + 1, j + 1
            continue
        nurbs = n < 0
        if nurbs:         # G5.3: the NURBS of the G5.2 lines before; its chords may count one more
            n = int((ours["line"].iloc[i:i + 8 * 200] == line).cumprod().sum()) // 8
        rows, chords = ours.iloc[i:i + 8 * n], ref.moves[j:j + 15 * n]
        extra = nurbs and j + 15 * n < len(ref.moves) and ref.moves[j + 15 * n]["line"] == line
        if len(rows) != 8 * n or len(chords) != 15 * n or not (rows["line"] == line).all() \
                or any(c["line"] != line for c in chords):
            problems.append(f"line {line}: {len(rows)} rows vs {len(chords)} chords")
            break
        node_ours += [i + 8 * k - 1 for k in range(1, n + 1)]
        node_ref += [j + 15 * k - 1 for k in range(1, n + 1)]
        start = ours[["x_mm", "y_mm"]].iloc[i - 1].to_numpy() if i else np.zeros(2)
        ends = np.array([start] + [c["end"][:2] for c in chords], float)
        length = float(np.linalg.norm(np.diff(ends, axis=0), axis=1).sum())
        gap = float(_distance_to_path(ends[1:], start, rows).max())
        worst = max(worst, gap)
        worst_share = max(worst_share, gap / max(length, 1e-6))   # a spline of no length: gap in mm
        before = ours["z_mm"].iloc[i - 1] + ours["wz_mm"].iloc[i - 1] + ours["tool_z_mm"].iloc[i - 1] if i else 0.0
        machine_z = rows["z_mm"] + rows["wz_mm"] + rows["tool_z_mm"]
        if i and not np.allclose(machine_z, before, atol=tol):
            problems.append(f"line {line}: the spline moves Z (machine {machine_z.iloc[-1]} from {before})")
        i, j = i + 8 * n, j + 15 * n + int(extra)
    if (i, j) != (len(ours), len(ref.moves)):
        problems.append(f"{len(ours)} moves, LinuxCNC {len(ref.moves)}; compared up to {i} and {j}")
    sub = Reference(moves=[ref.moves[k] for k in kept_ref], error=False, line=0, message="")
    problems += compare(ours.iloc[kept_ours], sub, tol=tol)
    nodes = ours.iloc[node_ours].copy()
    nodes["kind"] = "linear"          # the chord and the biarc end at the same point of the curve
    # the gcode module's chords keep the Z of its last move as it stored it (before a later G92, G43 or
    # G10 shift, in the units of then: 5 mm read as 5 inch after a G20); the motion controller (and
    # feedlog) stay where the tool is, which the machine-Z check above holds. X and Y are compared.
    node_moves = [dict(ref.moves[k], end=[ref.moves[k]["end"][0], ref.moves[k]["end"][1], z]
                       + list(ref.moves[k]["end"][3:])) for k, z in zip(node_ref, nodes["z_mm"])]
    problems += [f"spline node: {p}" for p in compare(nodes, Reference(moves=node_moves, error=False, line=0,
                                                                       message=""), tol=tol)]
    return problems, worst, worst_share


@needs_linuxcnc
def test_systems_ngc_matches_linuxcnc_node_by_node():
    path = NCFILES / "systems.ngc"
    if not path.exists():
        pytest.skip("LinuxCNC's ncfiles are not installed")
    ref = reference(path)
    assert not ref.error, ref.message
    program = interpret(path)
    problems, worst, share = spline_problems(program, ref, path.read_text())
    assert not problems, problems
    assert worst < SPLINE_PATH_TOL_MM, worst
    assert len(program.blocks) > 1000


NUM = st.integers(-300, 300).map(lambda v: f"{v / 10:g}")


@st.composite
def spline_programs(draw):
    """Splines among lines, G91, inch, polar, offsets, rotation, a tool offset, a subroutine and loops;
    and now and then something LinuxCNC refuses (G18, Z, comp on, a missing word)."""
    lines = ["G17 G21 G90 G94 G40 G49 G54 G80 F800", "G0 X1 Y1 Z5", "o<sp> sub",
             "G5.1 X[#1 + 4] Y[#2] I2 J3", "o<sp> endsub"]
    for _ in range(draw(st.integers(2, 9))):
        kind = draw(st.sampled_from(["g5", "g5", "g5-cont", "g51", "g51", "nurbs", "g1", "dist", "units", "offset",
                                     "call", "loop", "bad"]))
        if kind == "g5":
            lines.append(f"G5 X{draw(NUM)} Y{draw(NUM)} I{draw(NUM)} J{draw(NUM)} P{draw(NUM)} Q{draw(NUM)}")
        elif kind == "g5-cont":
            lines.append(f"G5 X{draw(NUM)} Y{draw(NUM)} P{draw(NUM)} Q{draw(NUM)}")
        elif kind == "g51":
            where = draw(st.sampled_from(["xy", "xy", "polar"]))
            pos = f"X{draw(NUM)} Y{draw(NUM)}" if where == "xy" else f"@{draw(NUM)} ^{draw(st.integers(0, 359))}"
            lines.append(f"G5.1 {pos} I{draw(NUM)} J{draw(NUM)}")
        elif kind == "nurbs":
            points = [f"X{draw(NUM)} Y{draw(NUM)} P{draw(st.integers(1, 30)) / 10:g}"
                      for _ in range(draw(st.integers(2, 6)))]
            lines += [f"G5.2 {points[0]} L{draw(st.sampled_from([3, 4]))}"] + points[1:] + ["G5.3"]
        elif kind == "g1":
            lines.append(f"G1 X{draw(NUM)} Y{draw(NUM)} Z{draw(NUM)}")
        elif kind == "dist":
            lines.append(draw(st.sampled_from(["G91", "G90"])))
        elif kind == "units":
            lines.append(draw(st.sampled_from(["G20", "G21"])))
        elif kind == "offset":
            lines.append(draw(st.sampled_from([
                f"G10 L2 P1 X{draw(NUM)} Y{draw(NUM)} R{draw(st.integers(-60, 60))}", f"G92 X{draw(NUM)}",
                "G92.1", "G55", "G54", f"G43.1 Z{draw(NUM)}", "G49", f"F{draw(st.integers(50, 2000))}"])))
        elif kind == "call":
            lines += ["#1 = [#<_x> + 1]", "#2 = [#<_y> - 2]", "o<sp> call"]
        elif kind == "loop":
            lines += [f"o10{len(lines)} repeat [{draw(st.integers(1, 3))}]",
                      f"G91 G5.1 X3 Y{draw(NUM)} I1 J{draw(NUM)}", "G90", f"o10{len(lines)} endrepeat"]
        else:
            lines += draw(st.sampled_from([["G18", "G5.1 X1 Y1 I1 J1"], ["G5.1 X1 Y1 Z2 I1 J1"],
                                           ["G41.1 D0.5 G1 X3", "G5.1 X1 Y1 I1 J1"], ["G5 X1 Y1 I1 J1"],
                                           ["G5.1 X1 Y1 J1"]]))
    return "\n".join(lines + ["G90 G0 X0 Y0", "M2"]) + "\n"


@needs_linuxcnc
@settings(max_examples=int(os.environ.get("FEEDLOG_SPLINE_EXAMPLES", "150")), deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(spline_programs())
def test_random_spline_programs_match_linuxcnc(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("spline") / "spline.ngc"
    path.write_text(text)
    ref, program, error = run_both(path)
    if error is not None and "straight" in str(error) and (not ref.error or ref.line > error.line):
        return   # a span LinuxCNC's motion controller cannot fit (documented refusal); its preview draws it
    if ref.error:
        check_refused_alike(ref, error, text)
        return
    assert error is None, f"{error}\n{text}"
    problems, worst, share = spline_problems(program, ref, text)
    assert not problems, (problems, text)
    assert share < SPLINE_PATH_SHARE, (worst, share, text)


def test_spline_problems_finds_a_moved_node():
    """The comparison above can fail: a node moved by 1e-5 mm in feedlog's rows is reported."""
    text = "G21 F600\nG0 X0 Y0\nG5.1 X10 Y10 I10 J0\nM2\n"
    program = interpret(text, name="t.ngc")
    # LinuxCNC's chords, derived here: 45 points of the curve at u = k / 45
    ref_moves = [dict(kind="rapid", line=2, end=[0, 0, 0, 0, 0, 0], feed=600.0, g5x=[0.0] * 6, g92=[0.0] * 6,
                      rot=0.0, tool=[0.0] * 6)]
    for k in range(1, 46):
        p = _bezier([(0, 0), (10, 0), (10, 10)], k / 45)
        ref_moves.append(dict(ref_moves[0], kind="linear", line=3, end=[p[0], p[1], 0, 0, 0, 0]))
    ref = Reference(moves=ref_moves, error=False, line=0, message="")
    problems, worst, share = spline_problems(program, ref, text)
    assert not problems and worst < 1e-3
    assert spline_problems(program, Reference(moves=ref_moves[:-1], error=False, line=0, message=""), text)[0]
    blocks = program.blocks.copy()
    node = blocks.index[blocks["line"] == 3][15]
    blocks.loc[node, "x_mm"] += 1e-5
    program.blocks = blocks
    problems, _, _ = spline_problems(program, ref, text)
    assert any("spline node" in p for p in problems)

