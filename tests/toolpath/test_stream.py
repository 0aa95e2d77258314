"""Reading a program in chunks gives the block table, metadata and warnings of reading it at once."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feedlog.errors import ProgramError
from feedlog.toolpath import parse_program
from feedlog.toolpath.interp import needs_interpreter
from feedlog.toolpath.stream import ProgramReader

from .test_rs274_reference import arc_mixes, offset_mixes

ROOT = Path(__file__).resolve().parents[2]
# the plain programs: those with parameters, subroutines or canned cycles go to the interpreter, not this reader
PROGRAMS = [p for p in sorted((ROOT / "recordings" / "programs").glob("*.ngc")) + sorted((ROOT / "examples").glob("*.ngc"))
            if not needs_interpreter(p.read_text())]


def read_in_chunks(source, chunk_bytes: int, **kw):
    """(number of batches, the Program gathered from them)."""
    with ProgramReader(source, chunk_bytes=chunk_bytes, **kw) as reader:
        program = reader.program()
    return reader.batches, program


def assert_same(whole, chunked) -> None:
    pd.testing.assert_frame_equal(whole.blocks, chunked.blocks, check_exact=True)
    assert chunked.metadata == whole.metadata
    assert chunked.warnings == whole.warnings
    assert chunked.unsupported == whole.unsupported


@pytest.mark.parametrize("path", PROGRAMS, ids=lambda p: p.stem)
def test_bundled_programs_read_in_chunks_equal_the_whole(path):
    whole = parse_program(path, lenient=True)
    batches, chunked = read_in_chunks(path, max(301, path.stat().st_size // 6), lenient=True)
    assert batches > 1
    assert_same(whole, chunked)


MIXED = """%
O1234 (title)
G20 G91 G1 X1 F10
Y2 ; incremental, inches
G21 G90 G0 X0 Y0 Z5
G64 P0.01 Q0.005
G93 G1 X1 F2
G94 G1 X2 F300
G18 G2 X4 Z5 I1 K0
G17 G61 G1 X5 Y5 A10
G1 X6 I0 J0 K1
G1 X7 I0.6 J0 K0.8
S1200 M3
G4 P0.5
G10 L2 P1 X10
G55 G0 X1
G92 Y3
G91 G1 X1
G92.1
G90 G54 G1 X1 Y1
/G1 X2
M2
G1 X3
%
G1 X4
"""


@pytest.mark.parametrize("chunk_bytes", [1, 7, 20, 64, 200])
def test_modal_state_offsets_and_warnings_cross_chunk_edges(chunk_bytes):
    whole = parse_program(MIXED, name="mixed.ngc")
    assert whole.warnings and whole.metadata["end_line"] == 22   # the test sees what it should
    _, chunked = read_in_chunks(MIXED, chunk_bytes, name="mixed.ngc")
    assert_same(whole, chunked)


@pytest.mark.parametrize("ending", [b"\n", b"\r\n", b"\r"])
def test_line_ends_split_across_reads(tmp_path, ending):
    text = MIXED.replace("\n", "\0").encode().replace(b"\0", ending)
    path = tmp_path / "p.ngc"
    path.write_bytes(b"\xef\xbb\xbf" + text)
    whole = parse_program(path)
    for chunk_bytes in (1, 2, 3, 5, 16):
        assert_same(whole, read_in_chunks(path, chunk_bytes)[1])
    assert whole.blocks["line"].iloc[-1] == 22  # the M2: a controller runs nothing after it


def test_lenient_skips_and_errors_name_the_file_line(tmp_path):
    text = "G21 F100\n" + "G1 X1\n" * 40 + "G41 D1\nG1 X2\n" + "G1 X3\n" * 40 + "G1 X#1\n"
    whole = parse_program(text, lenient=True, name="t.ngc")
    _, chunked = read_in_chunks(text, 50, lenient=True, name="t.ngc")
    assert_same(whole, chunked)
    assert [u.line for u in chunked.unsupported] == [42, 42, 84]
    with pytest.raises(ProgramError, match=r"t\.ngc:42: .*G41"):
        read_in_chunks(text, 50, name="t.ngc")
    bad = "G21 F100\n" + "G1 X1\n" * 60 + "G1 X1 X2\n"
    with pytest.raises(ProgramError, match=r"t\.ngc:62: word repeated"):
        read_in_chunks(bad, 40, name="t.ngc")
    slow = "G21 F1\n" + "".join(f"G1 X{(-1) ** i * 900000}\n" for i in range(50))
    with pytest.raises(ProgramError, match=r"t\.ngc:11: the program would run longer than 1e9 s"):
        read_in_chunks(slow, 30, name="t.ngc")


def test_utf16_and_unreadable_files_are_one_error(tmp_path):
    path = tmp_path / "u16.ngc"
    path.write_bytes("G1 X1\n".encode("utf-16"))
    with pytest.raises(ProgramError, match="UTF-16"):
        read_in_chunks(path, 4)
    with pytest.raises(ProgramError, match="cannot read"):
        read_in_chunks(tmp_path / "missing.ngc", 4)


@settings(max_examples=30, deadline=None)
@given(st.one_of(offset_mixes(), arc_mixes()), st.integers(1, 120))
def test_random_programs_read_in_chunks_equal_the_whole(text, chunk_bytes):
    whole = parse_program(text)
    assert_same(whole, read_in_chunks(text, chunk_bytes)[1])


def test_memory_is_bounded_by_the_chunk(tmp_path):
    """A program far larger than a chunk: every batch holds about a chunk's rows."""
    path = tmp_path / "long.ngc"
    path.write_text("G21 G90 G64 P0.01 F3000\n" + "".join(f"G1 X{i % 97} Y{i % 89}.5\n" for i in range(60000)))
    with ProgramReader(path, chunk_bytes=64 << 10) as reader:
        sizes = [len(b) for b in reader]
    assert len(sizes) > 10 and max(sizes) < 6000 and sum(sizes) == 60001


def test_g10_p0_after_a_system_switch_in_an_earlier_chunk():
    """G55 in one chunk, G10 L2 P0 (the active system) in a later one: the active system is carried
    (found by the random-program test above)."""
    text = "G21 G90 G94 F600\nG0 X1 Y2 Z3\nG55\nG10 L2 P0 X0.0\nG90 G1 X0\nM2\n"
    for chunk_bytes in (1, 4):
        assert_same(parse_program(text), read_in_chunks(text, chunk_bytes)[1])
