"""MCAP sources through the registry: feedlog recordings as is, generic JSON MCAP by mapping."""

from __future__ import annotations

import json

import numpy as np
import pytest
from mcap.writer import Writer

from feedlog.errors import IngestError
from feedlog.ingest import Recording, write_recording
from feedlog.ingest.readers import ImportOptions, read_source


def write_json_mcap(path, n=50, *, broken_at=None):
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("axes", "jsonschema", b'{"type":"object"}')
        axes = w.register_channel("/machine/axes", "json", sid)
        feed = w.register_channel("/machine/feed", "json", sid)
        for i in range(n):
            t = 1_000_000_000 + i * 10_000_000
            body = {"pos": {"x": i * 0.1, "y": [i * 0.2, 0]}}
            if i == broken_at:
                body = {"pos": {"y": [0, 0]}}
            w.add_message(axes, t, json.dumps(body).encode(), t)
            if i % 5 == 0:
                w.add_message(feed, t + 1, json.dumps({"value": 10.0 * i}).encode(), t + 1)
        w.finish()


def test_generic_json_mcap_by_mapping_with_units(tmp_path):
    path = tmp_path / "other.mcap"
    write_json_mcap(path)
    opts = ImportOptions(mapping="x=/machine/axes:pos.x,y=/machine/axes:pos.y.0,feed=/machine/feed:value",
                         length_unit="in", feed_unit="mm/s")
    rec = read_source(path, opts)
    axes = rec.streams["axes"]
    assert axes["t_ns"].iloc[1] - axes["t_ns"].iloc[0] == 10_000_000 and len(axes) == 50
    np.testing.assert_allclose(axes["x_mm"], np.arange(50) * 0.1 * 25.4)
    np.testing.assert_allclose(axes["y_mm"], np.arange(50) * 0.2 * 25.4)
    np.testing.assert_allclose(rec.streams["feed"]["feed_mm_min"], np.arange(0, 50, 5) * 10.0 * 60)


def test_generic_mcap_missing_field_strict_and_lenient(tmp_path):
    path = tmp_path / "other.mcap"
    write_json_mcap(path, broken_at=7)
    mapping = "x=/machine/axes:pos.x"
    with pytest.raises(IngestError, match=r"other\.mcap \(/machine/axes message 8 \(log_time 1070000000\)\)"):
        read_source(path, ImportOptions(mapping=mapping))
    rec = read_source(path, ImportOptions(mapping=mapping, strict=False))
    assert len(rec.streams["axes"]) == 49 and "1 messages" in rec.metadata["bad_records"]


def test_generic_mcap_without_mapping_or_with_split_stream_is_refused(tmp_path):
    path = tmp_path / "other.mcap"
    write_json_mcap(path)
    with pytest.raises(IngestError, match="needs --map"):
        read_source(path, ImportOptions())
    with pytest.raises(IngestError, match="two topics"):
        read_source(path, ImportOptions(mapping="x=/machine/axes:pos.x,y=/machine/feed:value"))


def test_feedlog_recording_through_the_registry_and_recover(tmp_path):
    t = np.arange(100_000, dtype=np.int64) * 1000
    rec = Recording(streams={"line": __import__("pandas").DataFrame({"t_ns": t, "line": t // 7})})
    path = tmp_path / "rec.mcap"
    write_recording(path, rec, compression="none")
    assert read_source(path).streams["line"]["line"].equals(rec.streams["line"]["line"])
    data = path.read_bytes()
    path.write_bytes(data[:-200])
    with pytest.raises(IngestError, match="truncated"):
        read_source(path)
    assert len(read_source(path, ImportOptions(recover=True)).streams["line"]) == 100_000
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap at all")
    with pytest.raises(IngestError, match=r"junk\.mcap \(byte 0\): not an MCAP"):
        read_source(junk)


def test_truncated_generic_mcap_names_byte_and_recovers(tmp_path):
    path = tmp_path / "other.mcap"
    write_json_mcap(path, 5000)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.99)])
    mapping = "x=/machine/axes:pos.x"
    with pytest.raises(IngestError, match=r"cut\.mcap \(byte \d+\): file is truncated"):
        read_source(cut, ImportOptions(mapping=mapping))
    rec = read_source(cut, ImportOptions(mapping=mapping, recover=True))
    assert len(rec.streams["axes"]) == 5000 and "truncated" in rec.metadata["recovered"]


def test_generic_mcap_time_from_a_field_in_declared_units(tmp_path):
    path = tmp_path / "stamped.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        cid = w.register_channel("/pos", "json", 0)
        for i in range(20):
            body = {"stamp_ms": 5000 + 2 * i, "x": i}
            w.add_message(cid, 10**9 + 7 * i, json.dumps(body).encode(), 0)
        w.finish()
    rec = read_source(path, ImportOptions(mapping="t=/pos:stamp_ms,x=/pos:x", time_unit="ms"))
    assert rec.streams["axes"]["t_ns"].tolist() == [(5000 + 2 * i) * 1_000_000 for i in range(20)]
    np.testing.assert_allclose(rec.streams["axes"]["x_mm"], np.arange(20))


FIX = __import__("pathlib").Path(__file__).resolve().parents[1] / "fixtures" / "ingest"


def test_committed_format_v1_file_still_reads_exactly():
    """A v1 file written when the format was defined: later readers must keep reading it."""
    rec = read_source(FIX / "format_v1.mcap")
    i = np.arange(100)
    axes = rec.streams["axes"]
    assert list(axes.columns) == ["t_ns", "x_mm", "y_mm", "z_mm"]
    assert axes["t_ns"].tolist() == (i * 1_000_000).tolist()
    np.testing.assert_array_equal(axes["x_mm"], i * 0.5)
    assert rec.streams["line"]["line"].tolist() == list(range(10, 20))
    assert rec.streams["status"]["in_position"].tolist() == [True, False]
    assert rec.streams["status"]["motion_type"].dtype == np.int8
    assert rec.metadata["machine"] == "fixture-mill" and rec.dropped_frames == 2
    assert rec.program_text == "G1 X49.5 Y-24.75 F1000\nM2\n"


def test_committed_generic_json_fixture():
    rec = read_source(FIX / "generic_json.mcap",
                      ImportOptions(mapping="x=/robot/pose:pos.x,y=/robot/pose:pos.y,z=/robot/pose:pos.z"))
    axes = rec.streams["axes"]
    assert axes["t_ns"].tolist() == [2_000_000_000 + k * 20_000_000 for k in range(50)]
    np.testing.assert_array_equal(axes["y_mm"], np.arange(50) * 2.0)
    np.testing.assert_array_equal(axes["z_mm"], 0.5)
