"""Real part programs from public repositories (tests/fixtures/programs/wild, README.md there): each must
read as its controller reads it. `programs.toml` says, per file, its dialect and whether it runs or is
refused (on which line, naming what). The motion is checked against an independent reference where one
exists: LinuxCNC's own interpreter move by move for the RS274/NGC programs (a copy with `M2` appended
where the file has no program end, which LinuxCNC requires and feedlog only warns about), and the
expected output its upstream interpreter ships for the Sinumerik ones (CEAD's nc-gcode-interpreter)."""

from __future__ import annotations

import csv
import os
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from feedlog.errors import ProgramError
from feedlog.toolpath import load_program
from feedlog.toolpath.dialects import detect
from feedlog.toolpath.interp import InterpOptions, interpret

from .reference import TOOLS, available, compare, reference

WILD = Path(__file__).resolve().parents[1] / "fixtures" / "programs" / "wild"
PROGRAMS = tomllib.loads((WILD / "programs.toml").read_text())["program"]
MISSING = available()
needs_linuxcnc = pytest.mark.skipif(MISSING is not None and os.environ.get("FEEDLOG_REQUIRE_LINUXCNC") != "1",
                                    reason=MISSING or "")


def _ids(entries):
    return [e["file"] for e in entries]


def test_every_vendored_program_is_listed_with_its_source():
    listed = {e["file"] for e in PROGRAMS}
    on_disk = {p.name for p in WILD.iterdir() if p.is_file() and p.suffix not in (".md", ".toml", ".csv")}
    assert listed == on_disk
    for e in PROGRAMS:
        assert len(e["commit"]) == 40 and e["repo"].count("/") == 1 and e["licence"] in ("MIT", "Apache-2.0")
    readme = (WILD / "README.md").read_text()
    assert all(e["file"] in readme for e in PROGRAMS)


@pytest.mark.parametrize("entry", PROGRAMS, ids=_ids(PROGRAMS))
def test_wild_program_reads_as_its_controller_does(entry):
    path = WILD / entry["file"]
    assert detect(path.read_text(encoding="utf-8", errors="replace"), path) == entry["dialect"]
    if entry["expect"] == "refused":
        with pytest.raises(ProgramError) as info:
            load_program(path)
        error = info.value
        assert Path(error.file).name == entry["file"] and error.line == entry["line"], str(error)
        assert entry["reason"] in str(error) and "\n" not in str(error)
        return
    program = load_program(path)
    assert program.metadata["dialect"] == entry["dialect"]
    assert len(program.motion) > 0
    if entry["reference"] == "cead-csv":
        _matches_expected_csv(program, WILD / entry["expected_csv"])


def _dedupe(points: np.ndarray) -> np.ndarray:
    keep = np.r_[True, np.any(np.abs(np.diff(points, axis=0)) > 6e-4, axis=1)]
    return points[keep]


def _matches_expected_csv(program, expected: Path) -> None:
    """CEAD's expected output: one row per block, the axes it knows (3 decimals, machine coordinates:
    TRANS included), blank where a block leaves them; blocks that stay put repeat a point."""
    rows = list(csv.DictReader(expected.open(newline="")))
    axes = [a for a in "XYZ" if a in rows[0]]
    current = dict.fromkeys(axes, 0.0)
    points = []
    for row in rows:
        if any(row[a] for a in axes):
            current.update({a: float(row[a]) for a in axes if row[a]})
            points.append([current[a] for a in axes])
    motion = program.motion
    ours = np.column_stack([(motion[f"{a.lower()}_mm"] + motion[f"w{a.lower()}_mm"]).to_numpy() for a in axes])
    ref = _dedupe(np.asarray(points))
    ours = _dedupe(ours)
    assert ours.shape == ref.shape, (ours.shape, ref.shape)
    assert np.allclose(ours, ref, atol=6e-4), np.abs(ours - ref).max()


LINUXCNC = [e for e in PROGRAMS if e["reference"] == "linuxcnc"]


@needs_linuxcnc
@pytest.mark.parametrize("entry", LINUXCNC, ids=_ids(LINUXCNC))
def test_wild_rs274_program_matches_linuxcnc_move_by_move(entry, tmp_path):
    source = WILD / entry["file"]
    text = source.read_text(encoding="utf-8", errors="replace")
    path = tmp_path / source.name
    ends = any(line.split(";")[0].strip().upper() in ("M2", "M02", "M30", "%") for line in text.splitlines())
    path.write_text(text if ends else text.rstrip("\n") + "\nM2\n")
    ref = reference(path)
    try:
        program, error = interpret(path, tool_table=TOOLS), None
    except ProgramError as exc:
        program, error = None, exc
    if entry["expect"] == "refused":
        assert ref.error and error is not None and error.line == ref.line == entry["line"], (ref.message, error)
        return
    assert not ref.error, f"LinuxCNC refuses {entry['file']} (line {ref.line}: {ref.message})"
    assert error is None, str(error)
    problems = compare(program.blocks, ref)
    assert not problems, problems[:5]
    # what a user gets (load_program: the vectorised parser for plain programs) moves the same way
    plain = load_program(path, interp=InterpOptions(tool_table=TOOLS)).motion
    assert len(plain) == len(program.motion)
    for axis in ("x_mm", "y_mm", "z_mm"):
        assert np.allclose(plain[axis].to_numpy(), program.motion[axis].to_numpy(), atol=1e-6), axis


SMALL = sorted(e["file"] for e in PROGRAMS if (WILD / e["file"]).stat().st_size < 8000)


@settings(max_examples=80, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(name=st.sampled_from(SMALL), cut=st.integers(0, 8000), flips=st.lists(
    st.tuples(st.integers(0, 8000), st.sampled_from(list(b"()[];=#<>%:$\"'GXYZIJKRFNOM0123456789.- \n\r\x00\xff"))),
    max_size=6))
def test_damaged_wild_programs_give_a_table_or_one_program_error(tmp_path_factory, name, cut, flips):
    """Real programs of every dialect, truncated and with bytes replaced: dialect detection and
    load_program end in a block table or one ProgramError naming the file, nothing else."""
    data = bytearray((WILD / name).read_bytes()[:max(cut, 1)])
    for at, byte in flips:
        data[at % len(data)] = byte
    path = tmp_path_factory.mktemp("wild") / name
    path.write_bytes(bytes(data))
    assert detect(bytes(data).decode("utf-8", errors="replace"), path) in ("rs274ngc", "fanuc", "sinumerik")
    try:
        program = load_program(path)
    except ProgramError as error:
        assert error.file is not None and "\n" not in str(error)
    else:
        assert program.blocks is not None
