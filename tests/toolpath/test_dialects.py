"""G-code dialects: Fanuc/Hurco and Sinumerik text read line for line as RS274/NGC."""

from __future__ import annotations

from pathlib import Path

import pytest

from feedlog.errors import ProgramError
from feedlog.toolpath import load_program
from feedlog.toolpath.dialects import translate

REAL = Path(__file__).resolve().parents[1] / "fixtures" / "ingest" / "real"


def test_fanuc_program_keeps_its_lines_and_rewrites_the_fanuc_words():
    text = (REAL / "hurco_part.nc").read_text()
    out = translate(text, "auto", name="hurco_part.nc")
    assert out.dialect == "fanuc"
    assert len(out.text.splitlines()) == len(text.splitlines())
    lines = out.text.splitlines()
    assert lines[2] == "N10 G0G17G20G40G49G90"            # G80 dropped beside G0
    assert lines[3] == "N20 G91 G0 Z0.2"                   # G28 Z: retract to the program's highest Z
    assert lines[20] == "N190 G4 P0.3"                     # Fanuc P300 is milliseconds
    assert any("G28" in note for note in out.notes)
    program = load_program(REAL / "hurco_part.nc")
    assert program.metadata["dialect"] == "fanuc"
    assert program.blocks["line"].max() <= len(text.splitlines())


def test_sinumerik_program_with_g710_g500_cr_msg_and_dynamics_keywords():
    text = (REAL / "sinumerik_part.mpf").read_text()
    lines = translate(text, "auto", name="part.mpf").text.splitlines()
    assert lines[3] == "N10 G21 G90 G17 G54"               # G710 -> G21, G500 G54 -> one G54
    assert lines[9] == "N70 G64 G1 Z-1 F500"               # G642 -> G64
    assert lines[11] == "N90 Y40"                          # SOFT dropped
    assert lines[12] == "N100 G2 X60 Y60 R20"              # CR= -> R
    assert "MSG" in lines[14] and lines[14].startswith("N120 ;")
    program = load_program(REAL / "sinumerik_part.mpf")
    assert program.metadata["dialect"] == "sinumerik"


def test_rs274ngc_text_is_left_alone_and_unknown_dialects_are_refused():
    text = "G21 G90\nG80\nG4 P0.5\nG1 X1 F100\nM2\n"
    out = translate(text, "auto")
    assert out.dialect == "rs274ngc" and out.text == text and not out.notes
    with pytest.raises(ProgramError, match="unknown G-code dialect 'heidenhain'"):
        load_program(text, dialect="heidenhain")
