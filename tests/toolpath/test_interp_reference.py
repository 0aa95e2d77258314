"""feedlog's interpreter against LinuxCNC's own (differential): the example programs LinuxCNC ships and
seeded random programs that use every feature the interpreter reads must give the same canonical
motion (kinds, end points, arc centres and turns, feeds, work offsets, lines) to 1e-6 mm where
LinuxCNC reports full precision (its `gcode` module), to its printed 4 decimals where only `rs274`
can run the program. Where LinuxCNC refuses a program, feedlog refuses it too, naming the line."""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from feedlog.errors import ProgramError
from feedlog.toolpath.interp import interpret

from .reference import NCFILES, TOOLS, available, compare, reference, subroutine_path

MISSING = available()
pytestmark = pytest.mark.skipif(MISSING is not None and os.environ.get("FEEDLOG_REQUIRE_LINUXCNC") != "1",
                                reason=MISSING or "")

# mill examples LinuxCNC runs that feedlog refuses on purpose, with the reason it names
REFUSED_ON_PURPOSE = {
    "gridprobe.ngc": "probing", "smartprobe.ngc": "probing", "x-trim.ngc": "probing",
    "threading.ngc": "G33",
    "lathe_g70_71_demo.ngc": "lathe", "lathe_g7x_face_boring.ngc": "lathe", "lathe_g7x_quadrants.ngc": "lathe",
    "lathe_pawn.ngc": "lathe", "mmount.ngc": "G33.1",
}
NOT_YET: set[str] = set()
# rs274's stand-alone canon re-reads the position after M6 from its own program position, which drops the
# shift of a G43 on the same line; the motion controller keeps the machine still (feedlog's choice)
REFERENCE_QUIRK = {"skeleton.ngc"}
# splines: the gcode module draws chords where the motion controller (and feedlog) runs biarcs; compared
# node by node in test_interp_splines.py
SPLINES = {"systems.ngc"}


def _examples() -> list[str]:
    return sorted(p.name for p in NCFILES.glob("*.ngc")) if NCFILES.is_dir() else []


def _run(path: Path, **kw):
    try:
        return interpret(path, search_path=subroutine_path(), tool_table=TOOLS, **kw), None
    except ProgramError as exc:
        return None, exc


@pytest.mark.parametrize("name", _examples())
def test_linuxcnc_example_programs(name):
    path = NCFILES / name
    ref = reference(path, subs=subroutine_path())
    program, error = _run(path)
    if name in REFUSED_ON_PURPOSE or name in NOT_YET:
        assert error is not None and error.line is not None, name
        expected = REFUSED_ON_PURPOSE.get(name, "cutter radius compensation")
        assert expected.lower() in str(error).lower(), str(error)
        return
    if ref.error and "file ended" in ref.message.lower():   # feedlog reads to the end and says so
        assert error is None and any("without" in w for w in program.warnings), (error, program)
        return
    if ref.error:
        assert error is not None, f"LinuxCNC refuses {name} (line {ref.line}: {ref.message}); feedlog ran it"
        assert error.line is not None
        if ref.line > 0:   # LinuxCNC names the line after the last one it executed for read errors
            assert error.line in (ref.line, ref.line - 1), (error.line, ref.line, str(error))
        return
    assert error is None, str(error)
    if name in REFERENCE_QUIRK or name in SPLINES:
        return
    problems = compare(program.blocks, ref)
    assert not problems, problems


def test_most_examples_are_compared_not_skipped():
    names = _examples()
    if not names:
        pytest.skip("LinuxCNC's ncfiles are not installed")
    compared = [n for n in names if n not in REFUSED_ON_PURPOSE and n not in NOT_YET and n not in REFERENCE_QUIRK]
    assert len(compared) >= 35


# -- random programs --------------------------------------------------------------------------------

NUM = st.integers(-400, 400).map(lambda v: f"{v / 10:g}")
POS = st.integers(1, 300).map(lambda v: f"{v / 10:g}")


@st.composite
def expressions(draw, depth=0):
    atoms = [NUM, st.sampled_from(["#1", "#2", "#<a>", "#<_g>", "#31"])]
    if depth < 2:
        atoms.append(st.builds(lambda a, op, b: f"[{a} {op} {b}]", expressions(depth=depth + 1),
                               st.sampled_from(["+", "-", "*", "/", "MOD", "**", "EQ", "NE", "GT", "GE", "LT",
                                                "LE", "AND", "OR", "XOR"]),
                               expressions(depth=depth + 1)))
        atoms.append(st.builds(lambda f, a: f"{f}[{a}]", st.sampled_from(["ABS", "SIN", "COS", "TAN", "FIX", "FUP",
                                                                          "ROUND"]),
                               expressions(depth=depth + 1)))
        atoms.append(st.builds(lambda a: f"LN[ABS[{a}] + 1]", expressions(depth=depth + 1)))
        atoms.append(st.builds(lambda a, b: f"ATAN[{a}]/[{b}]", expressions(depth=depth + 1), POS))
    return draw(st.one_of(atoms))


@st.composite
def moves(draw):
    kind = draw(st.sampled_from(["G0", "G1", "G1", "arc", "polar", "cycle"]))
    if kind in ("G0", "G1"):
        axes = draw(st.lists(st.sampled_from("XYZAC"), min_size=1, max_size=3, unique=True))
        words = " ".join(f"{a}[{draw(expressions())}]" if draw(st.booleans()) else f"{a}{draw(NUM)}" for a in axes)
        return f"{kind} {words}"
    if kind == "arc":
        g = draw(st.sampled_from(["G2", "G3"]))
        r = draw(st.integers(5, 200)) / 10
        return f"G17 {g} X[#<_x> + {2 * r:g}] Y#<_y> I{r:g} J0"
    if kind == "polar":
        return f"G1 @{draw(POS)} ^{draw(st.integers(0, 359))}"
    cyc = draw(st.sampled_from(["G81", "G82 P0.1", "G83 Q1", "G73 Q0.7", "G85", "G89 P0.2"]))
    dist = draw(st.sampled_from(["G90", "G91"]))
    ret = draw(st.sampled_from(["G98", "G99"]))
    if dist == "G90":
        return f"{dist} {ret} {cyc} X{draw(NUM)} Y{draw(NUM)} R5 Z-3 L{draw(st.integers(1, 3))}\nG80"
    return f"{dist} {ret} {cyc} X{draw(NUM)} Y{draw(NUM)} R2 Z-4 L{draw(st.integers(1, 3))}\nG80 G90"


@st.composite
def statements(draw, depth=0):
    choice = draw(st.sampled_from(["move", "move", "move", "assign", "offset", "units", "if", "loop", "call",
                                   "repeat"] if depth < 2 else ["move", "assign", "offset"]))
    if choice == "move":
        return [draw(moves())]
    if choice == "assign":
        target = draw(st.sampled_from(["#1", "#2", "#<a>", "#<_g>", "#31"]))
        return [f"{target} = [{draw(expressions())}]"]
    if choice == "offset":
        return [draw(st.sampled_from([
            f"G10 L2 P{draw(st.integers(0, 3))} X{draw(NUM)} Y{draw(NUM)} Z{draw(NUM)}",
            f"G10 L20 P{draw(st.integers(0, 3))} X{draw(NUM)} Z{draw(NUM)}",
            f"G10 L2 P{draw(st.integers(1, 3))} R{draw(st.integers(-45, 45))}",
            f"G92 X{draw(NUM)} Y{draw(NUM)}", "G92.1", "G92.2", "G92.3", f"G52 X{draw(NUM)}", "G52 X0 Y0",
            draw(st.sampled_from(["G54", "G55", "G56", "G59.3"])),
            f"G43.1 Z{draw(NUM)}", "G49", f"G53 G0 Z{draw(NUM)}",
            draw(st.sampled_from(["G64 P0.01", "G61", "G64", "G61.1", "G64 P0.05 Q0.02"])),
            f"F{draw(st.integers(100, 3000))}"]))]
    if choice == "units":
        return [draw(st.sampled_from(["G20", "G21"]))]
    body = [s for _ in range(draw(st.integers(1, 3))) for s in draw(statements(depth=depth + 1))]
    label = draw(st.integers(100, 999)) * 10 + depth
    if choice == "if":
        out = [f"o{label} if [{draw(expressions())}]"] + body
        if draw(st.booleans()):
            out += [f"o{label} elseif [{draw(expressions())}]", draw(moves())]
        if draw(st.booleans()):
            out += [f"o{label} else", draw(moves())]
        return out + [f"o{label} endif"]
    if choice == "loop":
        jump = draw(st.sampled_from(["", "break", "continue"]))
        exit_test = ([f"o{label + 5} if [#<n{label}> EQ {draw(st.integers(1, 3))}]", f"o{label} {jump}",
                      f"o{label + 5} endif"] if jump else [])
        return ([f"#<n{label}> = 0", f"o{label} while [#<n{label}> LT {draw(st.integers(0, 3))}]",
                 f"#<n{label}> = [#<n{label}> + 1]"] + exit_test + body + [f"o{label} endwhile"])
    if choice == "repeat":
        return [f"o{label} repeat [{draw(st.integers(0, 3))}]"] + body + [f"o{label} endrepeat"]
    return [f"o<s{depth % 2}> call [{draw(expressions())}] [{draw(NUM)}]"]


@st.composite
def programs(draw):
    lines = ["G17 G21 G90 G94 G40 G49 G54 G80 F800", "#1 = 1", "#2 = 2", "#<a> = 3", "#<_g> = 4", "#31 = 5",
             "G0 X1 Y1 Z10"]
    for depth in (0, 1):
        lines += [f"o<s{depth}> sub", "#<a> = [#1 + #2]", "G1 X[#1] Y[#<a>]", "G0 Z[5 + #2 * 0]",
                  f"o<s{depth}> endsub [#1 * 2]"]
    for _ in range(draw(st.integers(2, 10))):
        lines += draw(statements())
    return "\n".join(lines + ["G90 G0 X0 Y0", "M2"]) + "\n"


@settings(max_examples=int(os.environ.get("FEEDLOG_INTERP_EXAMPLES", "500")), deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                 HealthCheck.data_too_large])
@given(programs())
def test_random_programs_match_linuxcnc(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("rand") / "random.ngc"
    path.write_text(text)
    ref = reference(path)
    try:
        program, error = interpret(path), None
    except ProgramError as exc:
        program, error = None, exc
    if error is not None and "out of range (beyond +-1e9" in str(error):
        return   # feedlog's documented bound on numbers and positions (1e9 mm); LinuxCNC has none (and may
        #          refuse such a program only later, for what the huge numbers lead to)
    if ref.error:
        assert error is not None, f"LinuxCNC: line {ref.line}: {ref.message}\n{text}"
        assert error.line in (ref.line, ref.line - 1), (error.line, ref.line, ref.message, str(error), text)
        return
    assert error is None, f"{error}\n{text}"
    if units_change_under_a_tool_offset(text):
        return   # the gcode module's quirk, not the kernel's (units_change_under_a_tool_offset)
    problems = compare(program.blocks, ref)
    assert not problems, (problems, text)


def units_change_under_a_tool_offset(text: str) -> bool:
    """Whether G20/G21 switches units while a G43 offset is in force. LinuxCNC re-reads the tool offset
    from its canon at a units change: the task's canon gives it in the new program units, but the `gcode`
    module (our reference) gives it back unconverted, so a later G43/G49 shifts program Z by the offset
    read in the wrong unit (0.1 mm taken as 0.1 inch). feedlog follows the kernel (test_interp.py)."""
    units, offset = "G21", False
    for line in text.upper().splitlines():
        for word in re.findall(r"G\s*(\d+(?:\.\d+)?)", line.split("(")[0]):
            code = f"G{float(word):g}"
            if code in ("G43", "G43.1", "G43.2"):
                offset = True
            elif code == "G49":
                offset = False
            elif code in ("G20", "G21"):
                if offset and code != units:
                    return True
                units = code
    return False


@st.composite
def compensated_profiles(draw):
    """A closed profile of lines and arcs cut with G41/G42 (tool radius 0.05-0.2 mm): convex and concave
    corners, line-arc and arc-arc joints, in G17 or G18, entered and left with straight moves."""
    plane = draw(st.sampled_from(["G17", "G18"]))
    a, b = ("X", "Y") if plane == "G17" else ("Z", "X")
    ia, ib = ("I", "J") if plane == "G17" else ("K", "I")
    n = draw(st.integers(3, 7))
    angles = sorted(draw(st.lists(st.floats(0, 6.28), min_size=n, max_size=n, unique=True)))
    radii = draw(st.lists(st.floats(5, 20), min_size=n, max_size=n))
    pts = [(round(r * math.cos(t), 3), round(r * math.sin(t), 3)) for r, t in zip(radii, angles)]
    side = draw(st.sampled_from(["G41", "G42", "G41.1", "G42.1"]))
    tool = draw(st.integers(1, 4))
    # G41.1/G42.1 take the diameter itself (no tool table: LinuxCNC's gcode module, full precision);
    # G41/G42 a tool of the table (rs274 then, 4 decimals)
    change = f"T{tool} M6" if "." not in side else "(no tool change)"
    d_word = f"D{tool}" if "." not in side else f"D{draw(st.floats(0.05, 0.6)):.3f}"
    lines = [f"G21 {plane} G90 G40 F500", change, f"G0 {a}{pts[0][0] - 30} {b}{pts[0][1]}",
             f"{side} {d_word} G1 {a}{pts[0][0]} {b}{pts[0][1]}"]
    for k in range(1, n + 1):
        p, q = pts[k - 1], pts[k % n]
        if draw(st.booleans()):
            lines.append(f"G1 {a}{q[0]} {b}{q[1]}")
        else:
            chord = math.hypot(q[0] - p[0], q[1] - p[1])
            r = round(chord / 2 * draw(st.floats(1.05, 3.0)), 3)
            lines.append(f"{draw(st.sampled_from(['G2', 'G3']))} {a}{q[0]} {b}{q[1]} R{r}")
    lines += [f"G1 {a}{pts[0][0] - 30} {b}{pts[0][1] - 30}", "G40", f"G0 {a}{pts[0][0] - 40}", "M2"]
    return "\n".join(lines) + "\n"


@settings(max_examples=int(os.environ.get("FEEDLOG_INTERP_COMP_EXAMPLES", "150")), deadline=None,
          derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(compensated_profiles())
def test_random_cutter_compensation_matches_linuxcnc(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("comp") / "comp.ngc"
    path.write_text(text)
    ref = reference(path)
    try:
        program, error = interpret(path, tool_table=TOOLS), None
    except ProgramError as exc:
        program, error = None, exc
    if ref.error:
        assert error is not None, f"LinuxCNC refuses: {ref.message}\n{text}"
        return
    assert error is None, f"{error}\n{text}"
    problems = compare(program.blocks, ref)
    assert not problems, (problems, text)


def test_the_reference_module_misreads_a_tool_offset_across_a_units_change(tmp_path):
    """Why the random test passes over such programs: the `gcode` module shifts program Z by 0.1 inch
    (12.44 mm, not 10) where the kernel and feedlog keep 0.1 mm (test_interp.py)."""
    text = "G21 G0 X1 Y1 Z10\nG43.1 Z0.1\nG20\nG43.1 Z0\nG90 G0 X0 Y0\nM2\n"
    assert units_change_under_a_tool_offset(text)
    assert not units_change_under_a_tool_offset(text.replace("G20\n", "G21\n"))
    path = tmp_path / "units.ngc"
    path.write_text(text)
    ref = reference(path)
    assert not ref.error and ref.moves[-1]["end"][2] == pytest.approx(10 - 0.1 + 2.54, abs=1e-6)


def test_parameter_file_offsets_and_homes_match_linuxcnc(tmp_path):
    """A machine's .var file (mm): G54/G55 offsets, the selected system, a G55 rotation, G28/G30 homes.
    (The reference runs with inch machine units, so the program reads no length parameter directly.)"""
    var = tmp_path / "machine.var"
    var.write_text("5161\t10\n5162\t20\n5163\t30\n5181\t-5\n5182\t-6\n5183\t7\n5220\t2\n"
                   "5221\t100\n5222\t50\n5223\t-20\n5241\t-30\n5242\t40\n5243\t5\n5250\t15\n")
    prog = tmp_path / "p.ngc"
    prog.write_text("G21 F500\nG0 X1 Y2 Z3\nG1 X10 Y5\nG28 Z10\nG30\nG54 G1 X2 Y2\nG10 L20 P2 X0 Y0\n"
                    "G55 G0 X5 Y5\nG28.1\nG0 X1\nG28\n#1 = [#5220 * 3]\n#2 = #5220\nG1 X#1 Y#2\nM2\n")
    ref = reference(prog, var=var)
    assert not ref.error, ref.message
    program = interpret(prog, parameter_file=var)
    problems = compare(program.blocks, ref)
    assert not problems, problems
    assert program.motion["coord_system"].iloc[0] == 2 and program.motion["rot_deg"].iloc[0] == 15
