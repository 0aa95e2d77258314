"""`feedlog program` on a program read in chunks: the summary and the block table of the whole file."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from feedlog.cli import main
from feedlog.profile import load_profile
from feedlog.toolpath import parse_program
from feedlog.toolpath.stream import ProgramReader
from feedlog.toolpath.summary import Summary, summarize
from feedlog.manifest import read_manifest

ROOT = Path(__file__).resolve().parents[2]
MANIFEST = read_manifest(ROOT / "recordings" / "manifest.toml")
PROGRAMS = sorted({(r["program"], r["profile"]) for r in MANIFEST})[::12] + [
    ("../examples/work_offsets.ngc", "linuxcnc-xyz"), ("../examples/fiveaxis_ac.ngc", "linuxcnc-xyzac"),
    ("../examples/arcs_g18_g19.ngc", "linuxcnc-xyz")]


def _close(a, b):
    """Equal, floats to 1e-12 relative (sums over batches add in another order)."""
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for k in a:
            _close(a[k], b[k])
    elif isinstance(a, list):
        assert len(a) == len(b)
        for x, y in zip(a, b):
            _close(x, y)
    elif isinstance(a, float):
        assert a == pytest.approx(b, rel=1e-12, abs=1e-12)
    else:
        assert a == b


@pytest.mark.parametrize("program, profile", PROGRAMS, ids=lambda p: Path(p).stem)
def test_summary_in_batches_is_the_whole_summary(program, profile):
    path = ROOT / "recordings" / program
    prof = load_profile(profile)
    whole = summarize(parse_program(path, lenient=True), prof)
    with ProgramReader(path, lenient=True, chunk_bytes=400) as reader:
        summary = Summary(prof, name=reader.name)
        batches = 0
        for batch in reader:
            summary.add(batch)
            batches += 1
        streamed = summary.result(warnings=reader.warnings, unsupported=reader.unsupported, metadata=reader.metadata)
    assert batches > 1 or path.stat().st_size < 800
    _close(streamed, whole)


def test_rotary_axis_at_zero_in_some_batches_keeps_zero_in_its_range():
    text = "G21 G90 F1000\n" + "".join(f"G1 X{i} A0\n" for i in range(30)) + "".join(
        f"G1 X{i} A{5 + i}\n" for i in range(30)) + "M2\n"
    prof = load_profile("linuxcnc-xyzac")
    summary = Summary(prof, name="a.ngc")
    with ProgramReader(text, name="a.ngc", chunk_bytes=100) as reader:
        for batch in reader:
            summary.add(batch)
    assert summary.result(warnings=[], unsupported=[], metadata={})["bbox"]["a_deg"] == [0.0, 34.0]


def test_program_cli_streamed_writes_the_same_table(tmp_path, capsys):
    path = ROOT / "examples" / "work_offsets.ngc"
    docs, tables = [], []
    for flag in ("--no-stream", "--stream"):
        out = tmp_path / f"{flag}.parquet"
        assert main(["program", str(path), "--json", "--parquet", str(out), flag]) == 0
        docs.append({k: v for k, v in json.loads(capsys.readouterr().out).items() if k != "parquet"})
        tables.append(pd.read_parquet(out))
    _close(docs[1], docs[0])
    pd.testing.assert_frame_equal(tables[1], tables[0], check_exact=True)
