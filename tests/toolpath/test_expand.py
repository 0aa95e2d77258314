"""The flattened program (`feedlog program --expand`) moves exactly as the program it came from."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from feedlog.cli import main
from feedlog.toolpath import load_program
from feedlog.toolpath.expand import expand, motion_equal
from feedlog.toolpath.interp import interpret

ROOT = Path(__file__).resolve().parents[2]
NCFILES = Path("/usr/share/linuxcnc/ncfiles")
TOOLS = ROOT / "tests" / "fixtures" / "interp" / "tools.tbl"

PROGRAM = """G21 G17 F300
#1 = 0
o10 while [#1 LT 3]
  o<peck> call [#1 * 10] [2 + #1]
  #1 = [#1 + 1]
o10 endwhile
G10 L2 P1 X5 Y-3 R30
G0 X0 Y0 Z5
G2 X10 Y0 I5 J0 P2
G64 P0.02
G1 @12 ^45
G4 P0.5
G18 G3 Z1 K-2 I0
M2
o<peck> sub
  G0 X#1 Y0 Z5
  G83 R2 Z-#2 Q1
  G80
o<peck> endsub
"""


def test_expanded_program_moves_like_the_original(tmp_path):
    prog = tmp_path / "p.ngc"
    # the sub is defined after M2 in the text: move it before, as LinuxCNC needs it defined first
    body, sub = PROGRAM.split("M2\n")
    prog.write_text(sub + body + "M2\n")
    original = interpret(prog)
    text = expand(original)
    assert "o10" not in text and "#" not in text.split("\n", 1)[1]     # loops unrolled, parameters resolved
    assert "(p.ngc:" in text and "called from p.ngc:9" in text
    again = load_program(text)
    assert motion_equal(original, again)
    assert len(again.motion) == len(original.motion) > 20


@pytest.mark.skipif(not NCFILES.is_dir(), reason="LinuxCNC's example programs are not installed")
@pytest.mark.parametrize("name", ["comp.ngc", "polar.ngc", "hole-circle.ngc", "tort.ngc", "useful-subroutines.ngc",
                                  "daisy.ngc"])
def test_expanded_linuxcnc_examples_move_alike(name):
    subs = [NCFILES, NCFILES / "ngcgui_lib", NCFILES / "ngcgui_lib" / "utilitysubs"]
    original = interpret(NCFILES / name, search_path=subs, tool_table=TOOLS)
    assert motion_equal(original, load_program(expand(original)), atol=1e-9)


def test_program_cli_writes_the_expansion(tmp_path, capsys):
    prog = tmp_path / "p.ngc"
    prog.write_text("F100\no1 repeat [3]\nG91 G1 X1\no1 endrepeat\nM2\n")
    flat = tmp_path / "flat.ngc"
    assert main(["program", str(prog), "--expand", str(flat), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["expanded"] == str(flat)
    assert flat.read_text().count("G1 X") == 3
    assert main(["program", str(prog), "--expand", str(flat)]) == 2          # exists: not replaced
    assert "exists" in capsys.readouterr().err
