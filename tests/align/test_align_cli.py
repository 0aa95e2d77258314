"""feedlog align end to end: CLI, Parquet tables, batch over several recordings."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from align_synth import Motion, zigzag
from feedlog.align import align_recording
from feedlog.align.batch import align_many
from feedlog.align.tables import FORMAT_VERSION, META_KEY, read_table, write_alignment
from feedlog.cli import main
from feedlog.errors import AlignmentError, FeedlogError
from feedlog.ingest import Recording, write_recording
from feedlog.profile import load_profile


def program_and_motion(step: float = 3.0):
    """A G61 program (rapid up, plunge, zig-zag) and the exact-stop motion that runs it from X0 Y0 Z0."""
    v = zigzag(passes=4, length=30.0, step=step, z=-1.0)
    lines = ["%", "G21 G90 G17 G94", "G61", "F3000", "G0 X0 Y0 Z5", "G1 Z-1"]
    first = 5  # line of the first motion ("%" is line 1)
    for x, y, _ in v[1:]:
        lines.append(f"G1 X{x:.3f} Y{y:.3f}")
    lines += ["M2", "%"]
    text = "\n".join(lines) + "\n"
    motion = Motion(np.vstack([[[0.0, 0.0, 0.0], [0.0, 0.0, 5.0]], v]), feed_mm_min=3000.0, lead_s=0.3, tail_s=0.3)
    return text, motion, first


def synthetic_recording(rate_hz: float = 1000.0, *, with_lines: bool = True) -> Recording:
    text, motion, first = program_and_motion()
    axes = motion.axes(rate_hz)
    t = axes["t_ns"].to_numpy()
    streams = {"axes": axes}
    if with_lines:
        k = np.searchsorted(motion.arrival_ns, t, side="right") - 1
        line = np.where((k >= 0) & (k < len(motion.lengths)), first + k, 0).astype(np.int64)
        streams["line"] = pd.DataFrame({"t_ns": t, "line": line})
    prof = load_profile("linuxcnc-xyz")
    return Recording(streams=streams, metadata={"machine": "linuxcnc-xyz", "nominal_rate_hz": str(rate_hz)},
                     attachments={"program.ngc": text.encode(), "profile.toml": prof.to_toml().encode()},
                     source="synthetic")


@pytest.fixture(scope="module")
def rec_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("recs")
    a, b = d / "one.mcap", d / "two.mcap"
    write_recording(a, synthetic_recording(1000.0))
    write_recording(b, synthetic_recording(250.0, with_lines=False))
    return a, b


def test_align_synthetic_recording_block_times():
    rec = synthetic_recording()
    text, motion, _ = program_and_motion()
    a = align_recording(rec)
    assert a.cycle_time_s == pytest.approx(motion.motion_s, abs=0.002)
    np.testing.assert_allclose(a.blocks["duration_s"].to_numpy(), motion.durations, atol=0.0015)
    np.testing.assert_allclose(a.geometry_blocks["duration_s"].to_numpy(), motion.durations, atol=0.0015)
    assert a.report["blocks"]["source"] == "line"
    assert a.report["feed_source"] == "positions"


def test_cli_writes_tables_and_prints_json(rec_files, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["align", str(rec_files[0]), "-o", str(out), "--json", "-q"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["cycle_time_s"] > 0 and len(doc["blocks"]) == 9
    assert {"block", "line", "t_start_ns", "t_end_ns", "duration_s"} <= set(doc["blocks"][0])
    folder = out / "one"
    blocks, meta = read_table(folder / "blocks.parquet")
    points, _ = read_table(folder / "points.parquet")
    assert meta["format_version"] == FORMAT_VERSION and meta["table"] == "blocks"
    assert meta["recording"] == str(rec_files[0]) and meta["recording_path"] == str(Path(rec_files[0]).resolve())
    assert blocks["duration_s"].sum() == pytest.approx(doc["cycle_time_s"], abs=1e-9)
    assert {"length_mm", "corner_start_deg", "nominal_time_s", "vx_nom_mm_min"} <= set(blocks.columns)
    assert {"feed_meas_mm_min", "vx_meas_mm_min", "dist_mm", "t_ns"} <= set(points.columns)
    report = json.loads((folder / "report.json").read_text())
    assert report["cycle_time_s"] == pytest.approx(doc["cycle_time_s"])
    # never overwrite without being asked
    assert main(["align", str(rec_files[0]), "-o", str(out), "-q"]) == 2
    assert "exists" in capsys.readouterr().err
    assert main(["align", str(rec_files[0]), "-o", str(out), "-q", "--overwrite"]) == 0


def test_cli_batch_parallel_with_a_failure(rec_files, tmp_path, capsys):
    bad = tmp_path / "bad.mcap"
    rec = synthetic_recording(1000.0)
    rec.attachments["program.ngc"] = b"G21 G90\nG1 X500 Y500 F100\nM2\n"  # another part's program
    write_recording(bad, rec)
    out = tmp_path / "out"
    argv = ["align", str(rec_files[0]), str(rec_files[1]), str(bad), "-o", str(out), "-j", "2", "--json", "-q"]
    assert main(argv) == 0  # a refused recording is a warning: the batch goes on
    captured = capsys.readouterr()
    doc = json.loads(captured.out)  # a summary: the blocks are in the output folders
    assert (doc["aligned"], doc["refused"], doc["exit_code"]) == (2, 1, 0) and "blocks" not in captured.out
    assert [(Path(d["recording"]).stem, d["outcome"]) for d in doc["not_aligned"]] == [("bad", "refused")]
    assert "farther than their tolerance" in doc["not_aligned"][0]["error"] and doc["not_aligned"][0]["try"]
    assert f"feedlog align: warning: {bad}: " in captured.err and "2 aligned, 1 refused" in captured.err
    assert (out / "two" / "blocks.parquet").exists() and not (out / "bad").exists()
    # --strict: a refused recording fails the batch; outputs already there (no --overwrite) too
    assert main([*argv, "--overwrite", "--strict"]) == 2
    assert f"feedlog align: error: {bad}: " in capsys.readouterr().err
    assert main(argv) == 2
    assert "0 aligned, 1 refused, 2 with outputs already there" in capsys.readouterr().err


def test_missing_program_is_an_error(tmp_path):
    rec = synthetic_recording()
    del rec.attachments["program.ngc"]
    with pytest.raises(AlignmentError, match="no program given and none attached"):
        align_recording(rec)
    path = tmp_path / "noprog.mcap"
    write_recording(path, rec)
    assert main(["align", str(path), "-o", str(tmp_path / "o"), "-q"]) == 2


def test_tables_refuse_newer_format_and_foreign_files(tmp_path):
    a = align_recording(synthetic_recording())
    write_alignment(tmp_path / "x", a)
    import pyarrow.parquet as pq

    table = pq.read_table(tmp_path / "x" / "blocks.parquet")
    meta = dict(table.schema.metadata)
    meta[META_KEY] = json.dumps({"format_version": FORMAT_VERSION + 1}).encode()
    pq.write_table(table.replace_schema_metadata(meta), tmp_path / "newer.parquet")
    with pytest.raises(AlignmentError, match="newer"):
        read_table(tmp_path / "newer.parquet")
    pd.DataFrame({"a": [1]}).to_parquet(tmp_path / "foreign.parquet")
    with pytest.raises(AlignmentError, match="not written by feedlog align"):
        read_table(tmp_path / "foreign.parquet")
    with pytest.raises(FeedlogError, match="exists"):
        write_alignment(tmp_path / "x", a)


def test_align_many_api_keeps_input_order(rec_files, tmp_path):
    items = align_many(list(rec_files), tmp_path / "o", jobs=1, progress=False)
    assert [Path(i.recording).name for i in items] == ["one.mcap", "two.mcap"] and all(i.ok for i in items)
    with pytest.raises(FeedlogError, match="share the file name"):
        align_many([rec_files[0], rec_files[0]], tmp_path / "o2", progress=False)


def test_join_by_block_equals_merge():
    from feedlog.align.pipeline import join_by_block

    kinds = pd.Categorical(["linear", "arc_cw", "rapid"], categories=["rapid", "linear", "arc_cw"])
    right = pd.DataFrame({"block": np.array([3, 1, 2], dtype=np.int32), "line": [30, 10, 20],
                          "length_mm": [3.0, 1.0, 2.0], "kind": kinds,
                          "label": pd.array(["c", "a", "b"], dtype="string")})
    left = pd.DataFrame({"point": np.arange(5), "block": np.array([1, 1, 2, 3, 3], dtype=np.int32)},
                        index=[10, 11, 12, 13, 14])
    for lf in (left, left.assign(block=np.array([0, 1, 2, 3, 3], dtype=np.int32))):  # block 0: no features
        got = join_by_block(lf, right, exclude=("line",))
        want = lf.merge(right.drop(columns=["line"]), on="block", how="left")
        pd.testing.assert_frame_equal(got, want)
        for j in range(got.shape[1]):  # every column writable (not a read-only view of the inputs)
            got.iloc[0, j] = got.iloc[-1, j]
        assert right["length_mm"].tolist() == [3.0, 1.0, 2.0] and lf["point"].tolist() == [0, 1, 2, 3, 4]
    # an integer column with a missing block: merge's own upcast (here via the fallback)
    with_int = right.assign(count=np.array([7, 5, 6], dtype=np.int64))
    lf = left.assign(block=np.array([0, 1, 2, 3, 3], dtype=np.int32))
    pd.testing.assert_frame_equal(join_by_block(lf, with_int), lf.merge(with_int, on="block", how="left"))
