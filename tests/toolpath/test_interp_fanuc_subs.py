"""Fanuc-style subprograms in RS274/NGC files (`M98 P L` / `O<n>` / `M99`, toolpath/interp/fanuc_subs.py):
the motion derived in each test, LinuxCNC's errors with the line, `.ngc` files routed to the RS274/NGC
interpreter; and, where LinuxCNC's `gcode` module runs, the same moves as LinuxCNC on hand-written and
seeded random programs."""

from __future__ import annotations

import os
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from feedlog.errors import ProgramError
from feedlog.toolpath import load_program
from feedlog.toolpath.interp import interpret

from .reference import check_refused_alike, compare, needs_linuxcnc, run_both

MOVES = ["rapid", "linear", "arc_cw", "arc_ccw"]


def _xy(program):
    m = program.blocks[program.blocks["kind"].astype(str).isin(MOVES)]
    return m[["x_mm", "y_mm"]].to_numpy().tolist(), m["line"].tolist(), m["stack"].astype(str).tolist()


def test_m98_l_calls_a_subprogram_after_m2_and_nested_ones_repeat():
    text = ("G21 F100\nG0 X0 Y0\nM98 P100 L2\nG0 X5\nM2\n"
            "O100\nG91 G1 X1\nM98 P200 L2\nG90\nM99\n"
            "O200\nG91 G1 Y1\nM99\n")
    xy, lines, stacks = _xy(interpret(text, name="m.ngc"))
    # each call of O100: X+1, then O200 twice (Y+1 each)
    assert xy == [[0, 0], [1, 0], [1, 1], [1, 2], [2, 2], [2, 3], [2, 4], [5, 4]]
    assert lines == [2, 7, 12, 12, 7, 12, 12, 4]
    assert stacks[1] == "m.ngc:3" and stacks[2] == "m.ngc:3 > m.ngc:8" and stacks[-1] == ""


def test_l0_skips_the_call_and_a_negative_l_calls_once():
    sub = "M2\nO7\nG91 G1 X1\nG90\nM99\n"
    assert _xy(interpret(f"F100\nM98 P7 L0\nG0 Y1\n{sub}", name="m.ngc"))[0] == [[0, 1]]
    assert _xy(interpret(f"F100\nM98 P7 L-3\nG0 Y1\n{sub}", name="m.ngc"))[0] == [[1, 0], [1, 1]]


def test_a_program_number_met_by_the_main_program_runs_through_and_is_called_later():
    # LinuxCNC runs into an O<n> the main program meets (a program number); M99 there ends the program
    p = interpret("G21 F100\nO100\nG91 G1 X1\nG90\nM99\nG0 X9\nM2\n", name="m.ngc")
    assert _xy(p)[0] == [[1, 0]] and any("M99 in the main program" in w for w in p.warnings)
    assert p.metadata["program_number"] == 100


def test_parameters_1_to_30_are_the_callers_and_named_locals_are_the_subprograms(tmp_path):
    p = interpret("F100\n#1=7\nM98 P100\nG0 X#1\nM2\nO100\n#1=3\nG1 Y#1\nM99\n", name="m.ngc")
    assert _xy(p)[0] == [[0, 3], [3, 3]]      # the sub sees and changes #1; nothing is restored
    with pytest.raises(ProgramError, match=r"#<a> not defined") as err:
        interpret("F100\n#<a>=2\nM98 P100\nM2\nO100\nG1 X#<a>\nM99\n", name="m.ngc")
    assert err.value.line == 6 and "m.ngc:3" in str(err.value)


def test_an_o_call_finds_its_sub_further_down_the_file_as_linuxcnc_does():
    p = interpret("G21 F100\no<x> call [3]\nG0 X5\nM2\no<x> sub\nG1 X#1\no<x> endsub\n", name="m.ngc")
    assert _xy(p)[0] == [[3, 0], [5, 0]]
    with pytest.raises(ProgramError, match="found in illegal location") as err:   # the main flow runs into it
        interpret("G21 F100\no<x> call [3]\nG0 X5\no<x> sub\nG1 X#1\no<x> endsub\nM2\n", name="m.ngc")
    assert err.value.line == 4


def test_a_subprogram_file_along_the_search_path(tmp_path):
    lib = tmp_path / "lib"
    lib.mkdir()
    (lib / "4711.ngc").write_text("O4711 (slot)\nG91 G1 X2\nG90\nM99\n")
    main = tmp_path / "main.ngc"
    main.write_text("G21 F300\nM98 P4711 L3\nM2\n")
    p = interpret(main, search_path=[lib])
    assert _xy(p)[0] == [[2, 0], [4, 0], [6, 0]]
    assert set(p.motion["file"].astype(str)) == {str(lib / "4711.ngc")}


@pytest.mark.parametrize(("text", "line", "message"), [
    ("F100\nM98 P100\nM2\no100 sub\nG1 X1\no100 endsub\n", 2, "must be called with 'O.... call'"),
    ("F100\no100 sub\nG1 X1\no100 endsub\nM98 P100\nM2\n", 5, "must be called with 'O.... call'"),
    ("F100\nM98 P100\nM2\nO100\nG1 X2\no100 endsub\n", 6, "must end with 'M99'"),
    ("F100\no100 sub\nG1 X1\nM99\no100 endsub\no100 call\nM2\n", 4, "must follow 'O.... sub'"),
    ("F100\nM98 P100\nM2\nO100\nG1 X2 M99\nM99\n", 5, "only at the start of its line"),
    ("F100\nM98\nM2\n", 2, "no P word"),
    ("F100\nM98 P1.5\nM2\n", 2, "non-integer"),
    ("F100\nG0 X1 M98 P1\nM2\n", 2, "must begin its line"),
    ("F100\nM98 P300\nM2\n", 2, "subroutine o<300> not found"),
    ("F100\nM98 P1\nM2\nO1\nG91 G1 X1\nM98 P1\nM99\n", 6, "too many nested"),
])
def test_fanuc_style_errors_name_the_line(text, line, message):
    with pytest.raises(ProgramError, match=re.escape(message)) as err:
        interpret(text, name="bad.ngc")
    assert err.value.line == line, str(err.value)


def test_an_ngc_file_with_m98_goes_to_the_rs274ngc_interpreter(tmp_path):
    path = tmp_path / "part.ngc"
    path.write_text("G21 F100\n#<_d>=2\nM98 P100 L2\nM2\nO100\nG91 G1 X#<_d>\nG90\nM99\n")
    program = load_program(path)
    assert program.metadata["dialect"] == "rs274ngc" and program.motion["x_mm"].tolist() == [2.0, 4.0]
    # undeclared text and other suffixes with M98 P stay with the Fanuc front-end, as before
    fanuc = load_program("G21 F100\nM98 P100 L2\nM30\nO100\nG91 G1 X2.\nG90\nM99\n")
    assert fanuc.metadata["dialect"] == "fanuc"


# -- against LinuxCNC ---------------------------------------------------------------------------------

def _same_as_linuxcnc(path, text):
    ref, program, error = run_both(path)
    if ref.error:
        check_refused_alike(ref, error, text)
        return None
    assert error is None, f"{error}\n{text}"
    problems = compare(program.blocks, ref)
    assert not problems, (problems, text)
    return program


HAND_WRITTEN = [
    "G21 F100\nG0 X0 Y0\nM98 P100 L2\nG0 X5\nM2\nO100\nG91 G1 X1\nM98 P200 L2\nG90\nM99\nO200\nG91 G1 Y1\nM99\n",
    "G21 F100\n#1=7\nG0 X0 Y0\nM98 P100\nG0 X#1\nM2\nO100\n#1=3\nG1 X#1\nM99\n",
    "G21 F100\nG0 X0 Y0\nM98 P100 L0\nG0 X5\nM2\nO100\nG91 G1 X1\nG90\nM99\n",
    "G21 F100\nO100\nG91 G1 X1\nG90\nM99\nG0 X0 Y0\nM98 P100 L3\nG0 X0\nM2\n",
    "G21 F100\no<a> sub\nM98 P100\no<a> endsub\nG0 X0 Y0\no<a> call\nM2\nO100\nG1 X2\nM99\n",
    "G21 F100\nG0 X0\nM98 P100\nM2\nO100\nG1 X2\nM2\nM99\n",
    "G21 F100\nG0 X0 Y0\nM99\nG1 X3\nM2\n",
    "G21 F100\nN10 M98 P100 L2 (twice)\nM2\nO100 (sub)\nG91 G2 X2 Y0 I1 J0\nG90\nM99 (back)\n",
    "G21 F100\nG0 X0\nM98 P100\nM2\no100 sub\nG1 X1\no100 endsub\n",
    "G21 F100\nG0 X0\nM98 P100\nM2\nO100\nG1 X2\no100 endsub\n",
    "G21 F100\nG0 X0\nM98 P300\nM2\n",
    "G21 F100\n#<a>=2\nG0 X0 Y0\nM98 P100 L2\nM2\nO100\nG91 G1 X#<a>\nG90\nM99\n",
    # LinuxCNC's search for an o<name> call's definition further down the file, too
    "G21 F100\nG0 X0 Y0\no<x> call [3]\nG0 X5\nM2\no<x> sub\nG1 X#1\no<x> endsub\n",
    "G21 F100\nG0 X0 Y0\no<x> call [3]\nG0 X5\no<x> sub\nG1 X#1\no<x> endsub\nM2\n",
    "G21 F100\nG0 X0 Y0\no<y> call [3]\nG0 X5\nM2\n",
]


@needs_linuxcnc
@pytest.mark.parametrize("k", range(len(HAND_WRITTEN)))
def test_hand_written_fanuc_style_programs_match_linuxcnc(tmp_path, k):
    path = tmp_path / "m.ngc"
    path.write_text(HAND_WRITTEN[k])
    _same_as_linuxcnc(path, HAND_WRITTEN[k])


@st.composite
def m98_programs(draw):
    """A main program calling numbered subprograms (after M2, or before it when it jumps over them with
    a program number of its own) with L repeats; subprograms call later ones; moves in G90 and G91."""
    n_subs = draw(st.integers(1, 4))
    move = st.builds(lambda d, a, v: f"{d} G1 {a}{v}", st.sampled_from(["G90", "G91"]),
                     st.sampled_from(["X", "Y", "Z"]), st.integers(-50, 50).map(lambda v: f"{v / 10:g}"))
    call = st.builds(lambda s, n: f"M98 P{s}" + ("" if n is None else f" L{n}"),
                     st.integers(0, n_subs - 1).map(lambda s: 100 + s), st.one_of(st.none(), st.integers(0, 3)))
    main = ["G21 G90 F500", "G0 X0 Y0 Z0"] + [draw(st.one_of(move, call)) for _ in range(draw(st.integers(1, 5)))]
    main += ["G90 G0 X0 Y0", draw(st.sampled_from(["M2", "M30"]))]
    subs = []
    for s in range(n_subs):
        body = [f"O{100 + s}"]
        for _ in range(draw(st.integers(1, 3))):
            inner = [draw(move)]
            if s + 1 < n_subs and draw(st.booleans()):
                inner.append(f"M98 P{draw(st.integers(s + 1, n_subs - 1)) + 100} L{draw(st.integers(1, 2))}")
            body += inner
        subs += body + ["G90", "M99"]
    return "\n".join(main + subs) + "\n"


@needs_linuxcnc
@settings(max_examples=int(os.environ.get("FEEDLOG_M98_EXAMPLES", "60")), deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(m98_programs())
def test_random_fanuc_style_programs_match_linuxcnc(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("m98") / "m98.ngc"
    path.write_text(text)
    program = _same_as_linuxcnc(path, text)
    if program is not None:
        assert np.isfinite(program.motion["x_mm"]).all()
