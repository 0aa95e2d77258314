"""Partial recordings (--lines, from the line or block-number stream), N words -> lines, work offsets."""

from __future__ import annotations

import json

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feedlog.align import align_recording
from feedlog.align.partial import auto_lines, parse_lines, program_lines, slice_program
from feedlog.align.work_offset import estimate_work_offset
from feedlog.cli import main
from feedlog.errors import AlignmentError
from feedlog.ingest.readers import ImportOptions, read_source
from feedlog.ingest.recording import Recording
from feedlog.toolpath import load_program

REAL = Path(__file__).resolve().parents[1] / "fixtures" / "ingest" / "real"


@pytest.fixture(scope="module")
def mazak():
    return read_source(REAL / "mazak_streams.xml", ImportOptions()), load_program(REAL / "mazak_part.nc")


def test_block_numbers_become_program_lines(mazak):
    rec, prog = mazak
    mapped = program_lines(rec, prog)
    line = mapped.streams["line"]
    assert "line" in line.columns and line["line"].iloc[-1] == 20          # N190 is on line 20
    assert program_lines(mapped, prog) is mapped                            # already in lines
    unknown = Recording(streams={"line": pd.DataFrame({"t_ns": np.arange(3, dtype=np.int64),
                                                       "block_number": np.array([7, 8, 9], dtype=np.int64)})})
    with pytest.raises(AlignmentError, match=r"none of the recorded block numbers \(N7, N8, N9\)"):
        program_lines(unknown, prog)


def test_a_line_stream_leaving_feed_moves_out_cuts_the_program(mazak):
    rec, prog = mazak
    assert auto_lines(program_lines(rec, prog), prog) == (9, 20)
    whole = Recording(streams={"line": pd.DataFrame({"t_ns": np.arange(3, dtype=np.int64),
                                                     "line": np.array([4, 12, 20], dtype=np.int64)})})
    assert auto_lines(whole, prog) is None        # only the first rapid (line 3) unseen: the whole program
    part = slice_program(prog, (13, 20))
    assert part.motion["line"].min() == 13 and part.motion["x0_mm"].iloc[0] == 0.0
    with pytest.raises(AlignmentError, match="no motion on lines 1:2"):
        slice_program(prog, (1, 2))
    assert parse_lines("13:20") == (13, 20)
    for bad in ("20:13", "0:3", "x", ""):
        with pytest.raises(AlignmentError, match="--lines wants FIRST:LAST"):
            parse_lines(bad)


def test_partial_recording_aligns_automatically_and_with_lines(mazak):
    rec, prog = mazak
    with pytest.raises(AlignmentError, match="farther than their tolerance"):
        align_recording(rec, prog, auto_lines=False)
    out = align_recording(rec, prog)
    assert out.report["lines"] == {"first": 9, "last": 20, "from": "line stream"}
    assert out.report["match"]["matched"] >= out.report["match"]["cl_points"] - 2
    assert out.blocks["line"].min() == 9 and out.blocks["line"].max() == 20
    assert 9.0 < out.cycle_time_s < 12.0
    given = align_recording(rec, prog, lines=(12, 20))
    assert given.report["lines"]["from"] == "config" and given.blocks["line"].min() == 12


def test_work_offset_estimate_recovers_a_g54_set_on_the_machine():
    rng = np.random.default_rng(3)
    program = np.array([[0, 0, 5], [0, 0, -1], [40, 0, -1], [40, 30, -1], [0, 30, -1], [0, 0, -1], [0, 0, 5]], float)
    dense = np.concatenate([np.linspace(a, b, 50) for a, b in zip(program[:-1], program[1:])])
    shift = np.array([-317.5, -209.55, -355.6])
    est = estimate_work_offset(program, dense + shift + rng.normal(0, 0.002, dense.shape))
    np.testing.assert_allclose(est.offset_mm, shift, atol=0.01)
    assert est.residual_median_mm < 0.01


def test_hurco_shdr_in_machine_coordinates_aligns_with_an_estimated_offset(tmp_path, capsys):
    rec = tmp_path / "h.mcap"
    assert main(["import", str(REAL / "hurco_shdr.txt"), "--length-unit", "in", "--feed-unit", "in/min",
                 "--program", str(REAL / "hurco_part.nc"), "-o", str(rec)]) == 0
    assert main(["align", str(rec), "-o", str(tmp_path / "a"), "-q", "--no-auto-offset"]) == 2  # machine coordinates
    assert main(["align", str(rec), "-o", str(tmp_path / "a"), "-q", "--estimate-offset"]) == 0
    report = json.loads((tmp_path / "a" / "h" / "report.json").read_text())
    np.testing.assert_allclose(report["work_offset_estimate"]["offset_mm"], [-317.5, -209.55, -355.6], atol=0.05)
    capsys.readouterr()
    assert main(["align", str(rec), "-o", str(tmp_path / "b"), "-q"]) == 0     # retried with an estimate by itself
    assert "cycle time" in (out := capsys.readouterr().out) and "(work offset estimated (-317.500, -209.550" in out
    report = json.loads((tmp_path / "b" / "h" / "report.json").read_text())
    assert report["config"]["estimate_offset"] is True
    assert any("aligned with an estimated work offset (-317.5" in w for w in report["warnings"])


def test_many_recordings_end_in_an_aligned_refused_summary_with_what_to_try():
    from feedlog.align.batch import BatchItem
    from feedlog.align.cli import summary

    items = [BatchItem(recording=f"r{k}.mcap", outdir="o", ok=True) for k in range(116)]
    items.append(BatchItem(recording="bad.mcap", outdir="o", ok=False,
                           error="the measured path never comes within 0.05 mm of the program's first points; x"))
    text = summary(items)
    assert text.startswith("116 aligned, 1 refused\n  1 x the measured path never comes within")
    assert "(e.g. bad.mcap)" in text and "--estimate-offset" in text


def test_a_recording_without_positions_aligns_on_its_block_numbers(tmp_path):
    from feedlog.ingest.writer import write_recording

    # this fixture's sequence column holds N words (the public files' is a counter: the preset leaves it out)
    mapping = "x=X1_ActualPosition,y=Y1_ActualPosition,z=Z1_ActualPosition,block_number=M1_sequence_number"
    rec = read_source(REAL / "umich_experiment.csv", ImportOptions(mapping=mapping, rate_hz=10.0))
    full = align_recording(rec, REAL / "umich_part.nc")
    del rec.streams["axes"]
    lines_only = align_recording(rec, REAL / "umich_part.nc")
    assert lines_only.report["mode"] == "line stream only" and lines_only.report["match"]["matched"] == 0
    inner = full.blocks["line"].between(4, 14).to_numpy()
    np.testing.assert_allclose(lines_only.blocks["duration_s"].to_numpy()[inner],
                               full.blocks["duration_s"].to_numpy()[inner], atol=0.1)   # 10 Hz block numbers
    assert lines_only.cycle_time_s >= full.cycle_time_s      # the line shows before motion starts and after it ends
    write_recording(tmp_path / "u.mcap", rec)
    assert main(["align", str(tmp_path / "u.mcap"), "--program", str(REAL / "umich_part.nc"), "-o",
                 str(tmp_path / "a"), "-q"]) == 0
    points = pd.read_parquet(tmp_path / "a" / "dataset" / "points")
    assert len(points) == lines_only.report["match"]["cl_points"] and points["feed_meas_mm_min"].isna().all()
    del rec.streams["line"]
    with pytest.raises(AlignmentError, match="nothing to align on"):
        align_recording(rec, REAL / "umich_part.nc")
