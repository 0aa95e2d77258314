"""feedlog recording format v1: round trips, the plain-MCAP view, versions and damaged files."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pyarrow as pa
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from mcap.writer import Writer

from feedlog.cli import main
from feedlog.errors import IngestError, OutputError
from feedlog.ingest import Recording, RecordingWriter, read_recording, write_recording


def make_recording(n: int = 50_000) -> Recording:
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.integers(900_000, 1_100_000, n)).astype(np.int64)
    axes = pd.DataFrame({"t_ns": t, "x_mm": rng.normal(size=n), "y_mm": rng.normal(size=n),
                         "z_mm": rng.normal(size=n), "a_deg": rng.normal(size=n)})
    line = pd.DataFrame({"t_ns": t[::50], "line": np.arange(len(t[::50]), dtype=np.int64) + 10})
    status = pd.DataFrame({"t_ns": t[:7], "in_position": np.array([1, 0, 1, 1, 0, 0, 1], dtype=bool),
                           "motion_type": np.arange(7, dtype=np.int8)})
    empty = pd.DataFrame({"t_ns": np.array([], dtype=np.int64), "spindle_rpm": np.array([], dtype=np.float32)})
    return Recording(streams={"axes": axes, "line": line, "status": status, "spindle": empty},
                     metadata={"machine": "test-mill", "controller": "none", "units": "mm",
                               "nominal_rate_hz": "1000", "start_time": "2026-11-22T12:00:00Z", "notes": "ü"},
                     attachments={"program.ngc": b"G1 X10 F600\nM2\n", "profile.toml": b"[axes.x]\n"},
                     dropped_frames=17)


@pytest.mark.parametrize("compression", ["lz4", "zstd", "none"])
def test_round_trip_keeps_every_stream_type_and_value(tmp_path, compression):
    rec = make_recording()
    path = tmp_path / "rec.mcap"
    write_recording(path, rec, compression=compression)
    back = read_recording(path)
    assert list(back.streams) == list(rec.streams)
    for name, table in rec.streams.items():
        pd.testing.assert_frame_equal(back.streams[name], table, check_dtype=True)
    assert back.metadata == rec.metadata
    assert back.attachments == rec.attachments
    assert back.dropped_frames == 17
    assert back.program_text.startswith("G1 X10")


def test_plain_mcap_reader_sees_channels_schemas_metadata_attachments(tmp_path):
    path = tmp_path / "rec.mcap"
    rec = make_recording(40_000)
    write_recording(path, rec)
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert reader.get_header().profile == "feedlog"
        topics = {c.topic: c for c in summary.channels.values()}
        assert set(topics) == {"axes", "line", "status", "spindle"}
        assert topics["axes"].metadata["columns"] == "t_ns:int64,x_mm:double,y_mm:double,z_mm:double,a_deg:double"
        assert {s.name for s in summary.schemas.values()} == {f"feedlog.{n}" for n in topics}
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        assert meta["feedlog"]["format_version"] == "1"
        assert meta["session"]["machine"] == "test-mill"
        assert meta["feedlog.stats"]["dropped_frames"] == "17"
        assert {a.name: a.media_type for a in reader.iter_attachments()} == {
            "program.ngc": "text/x-gcode", "profile.toml": "application/toml"}
        # messages are batches: far fewer messages than samples; decoding as documented
        batches = {}
        for schema, channel, message in reader.iter_messages():
            arrow_schema = pa.ipc.read_schema(pa.py_buffer(schema.data))
            batch = pa.ipc.read_record_batch(pa.py_buffer(message.data), arrow_schema)
            assert message.log_time == batch.column(0)[0].as_py()
            batches.setdefault(channel.topic, []).append(batch)
    # batches of hundreds of samples: at most 1 s of them (import) and 1/8 of a 1 MiB chunk
    assert 1 < len(batches["axes"]) < 40_000 / 500
    assert max(b.nbytes for b in batches["axes"]) <= (1 << 20) // 8
    assert max(b.column(0)[-1].as_py() - b.column(0)[0].as_py() for b in batches["axes"]) < 1_000_000_000
    axes = pa.Table.from_batches(batches["axes"]).to_pandas()
    np.testing.assert_array_equal(axes["x_mm"].to_numpy(), rec.streams["axes"]["x_mm"].to_numpy())


def test_overwrite_is_refused_unless_asked(tmp_path):
    path = tmp_path / "rec.mcap"
    write_recording(path, make_recording(100))
    with pytest.raises(IngestError, match="exists"):
        write_recording(path, make_recording(100))
    with pytest.raises(IngestError, match="exists"):
        RecordingWriter(path)
    write_recording(path, make_recording(200), overwrite=True)
    assert len(read_recording(path).streams["axes"]) == 200


def test_unwritable_output_is_an_output_error(tmp_path):
    with pytest.raises(OutputError, match=r"cannot create the recording: its folder does not exist") as info:
        write_recording(tmp_path / "missing" / "rec.mcap", make_recording(10))
    assert info.value.exit_code == 1


def test_newer_format_version_is_refused(tmp_path):
    path = tmp_path / "future.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="feedlog")
        w.add_metadata("feedlog", {"format_version": "2"})
        w.finish()
    with pytest.raises(IngestError, match="format_version 2 is not supported"):
        read_recording(path)


def test_mcap_without_feedlog_metadata_is_not_a_recording(tmp_path):
    path = tmp_path / "other.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("x", "jsonschema", b"{}")
        cid = w.register_channel("/x", "json", sid)
        w.add_message(cid, 1, b"{}", 1)
        w.finish()
    with pytest.raises(IngestError, match="not a feedlog stream|not a feedlog recording"):
        read_recording(path)


@pytest.mark.parametrize("fraction", [0.0, 0.001, 0.3, 0.6, 0.999])
def test_truncated_file_names_file_and_byte_and_recovers_complete_chunks(tmp_path, fraction):
    full = tmp_path / "full.mcap"
    rec = make_recording(400_000)  # 16 MB: four 4 MiB chunks
    write_recording(full, rec, compression="none")
    data = full.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * fraction)])
    with pytest.raises(IngestError, match=r"cut\.mcap \(byte \d+\)") as info:
        read_recording(cut)
    assert "truncated" in str(info.value) or "not an MCAP" in str(info.value)
    if fraction >= 0.3:
        got = read_recording(cut, recover=True)
        axes = got.streams["axes"]
        assert 0 < len(axes) <= len(rec.streams["axes"])
        pd.testing.assert_frame_equal(axes, rec.streams["axes"].iloc[: len(axes)])
        assert "truncated" in got.metadata["recovered"]


def test_flipped_byte_is_a_corrupt_chunk(tmp_path):
    path = tmp_path / "rec.mcap"
    write_recording(path, make_recording(100_000))
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x5A
    path.write_bytes(bytes(data))
    with pytest.raises(IngestError, match=r"rec\.mcap \(byte \d+\).*(corrupt|truncated)"):
        read_recording(path)


def test_writer_appends_batches_and_checks_them(tmp_path):
    path = tmp_path / "live.mcap"
    with RecordingWriter(path, metadata={"machine": "m"}, attachments={"program.ngc": b"M2\n"},
                         rows_per_message=100) as w:
        for k in range(10):
            t = np.arange(k * 30, (k + 1) * 30, dtype=np.int64) * 1000
            w.write("feed", {"t_ns": t, "feed_mm_min": t / 1000.0})
        with pytest.raises(IngestError, match="backwards"):
            w.write("feed", {"t_ns": np.array([5], dtype=np.int64), "feed_mm_min": np.array([1.0])})
        with pytest.raises(IngestError, match="columns changed"):
            w.write("feed", {"t_ns": np.array([10**9], dtype=np.int64), "x_mm": np.array([1.0])})
        with pytest.raises(IngestError, match="t_ns int64"):
            w.write("other", {"time": np.array([1.0])})
        w.dropped_frames = 4
    rec = read_recording(path)
    np.testing.assert_array_equal(rec.streams["feed"]["t_ns"].to_numpy(), np.arange(300) * 1000)
    assert rec.dropped_frames == 4 and rec.metadata == {"machine": "m"}


def test_writer_flushes_on_interval_so_an_unclosed_file_is_recoverable(tmp_path):
    path = tmp_path / "open.mcap"
    w = RecordingWriter(path, flush_interval_s=0.05)
    w.write("line", {"t_ns": np.array([1, 2, 3], dtype=np.int64), "line": np.array([4, 5, 6])})
    import time
    time.sleep(0.06)
    w.flush_if_due()
    w.dropped_frames = 2
    w.write("line", {"t_ns": np.array([4], dtype=np.int64), "line": np.array([7])})  # pending only
    # the writer is still open: the file has no footer but its complete chunks are readable
    with pytest.raises(IngestError, match="truncated"):
        read_recording(path)
    got = read_recording(path, recover=True)
    assert got.streams["line"]["line"].tolist() == [4, 5, 6]
    w.close()
    assert read_recording(path).streams["line"]["line"].tolist() == [4, 5, 6, 7]
    assert read_recording(path).dropped_frames == 2


def test_info_json_reports_duration_streams_and_drops(tmp_path, capsys):
    path = tmp_path / "rec.mcap"
    rec = make_recording(5_001)
    write_recording(path, rec)
    assert main(["info", str(path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    t = rec.streams["axes"]["t_ns"].to_numpy()
    assert info["duration_s"] == pytest.approx((t[-1] - t[0]) / 1e9)
    streams = {s["name"]: s for s in info["streams"]}
    assert streams["axes"]["samples"] == 5_001
    assert streams["axes"]["rate_hz"] == pytest.approx(5_000 / ((t[-1] - t[0]) / 1e9), rel=1e-6)
    assert streams["line"]["columns"] == ["t_ns", "line"]
    assert streams["spindle"]["samples"] == 0 and streams["spindle"]["rate_hz"] == 0
    assert info["dropped_frames"] == 17
    assert main(["info", str(path)]) == 0
    assert "axes" in capsys.readouterr().out


def test_info_on_damaged_file_is_one_line_error(tmp_path, capsys):
    path = tmp_path / "bad.mcap"
    path.write_bytes(b"\x89MCAP0\r\n" + b"\x01" * 40)
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert "bad.mcap" in err and "byte" in err and "Traceback" not in err


class _FailingFile:
    """A file whose writes raise ENOSPC `failures` times once armed (then work again)."""

    def __init__(self, inner, failures: int) -> None:
        self.inner, self.failures, self.armed = inner, failures, False

    def write(self, data):
        if self.armed and self.failures > 0:
            self.failures -= 1
            self.inner.write(data[: len(data) // 2])  # a partial write reaches the disk first
            raise OSError(28, "No space left on device")
        return self.inner.write(data)

    def __getattr__(self, name):
        return getattr(self.inner, name)


@pytest.mark.parametrize("failures", [1, 100])
def test_failed_write_keeps_flushed_data_and_ends_the_file_when_it_can(tmp_path, monkeypatch, failures):
    import feedlog.ingest.writer as writer_module

    opened = []

    def failing_open(path, mode):
        opened.append(_FailingFile(open(path, mode), failures))
        return opened[-1]

    monkeypatch.setattr(writer_module, "open", failing_open, raising=False)
    path = tmp_path / "full.mcap"
    w = RecordingWriter(path, rows_per_message=1000)
    t = np.arange(5000, dtype=np.int64) * 1000
    w.write("feed", {"t_ns": t, "feed_mm_min": t / 1e3})
    w.flush()
    opened[0].armed = True
    with pytest.raises(OutputError, match=r"full\.mcap \(byte \d+\): write failed \(No space left on device\)"):
        w.write("feed", {"t_ns": t + 10**9, "feed_mm_min": t / 1e3})
        w.flush()
    with pytest.raises(OutputError, match="write failed"):
        w.write("feed", {"t_ns": t + 2 * 10**9, "feed_mm_min": t / 1e3})
    w.close()
    if failures == 1:  # the seal fitted: a complete, shorter file that says why it ended
        rec = read_recording(path)
        assert "No space left" in rec.metadata["incomplete"]
    else:  # nothing more could be written: the file is cut back to its last flush
        with pytest.raises(IngestError, match="truncated"):
            read_recording(path)
        rec = read_recording(path, recover=True)
    np.testing.assert_array_equal(rec.streams["feed"]["t_ns"].to_numpy(), t)


_DTYPES = [np.float64, np.float32, np.int64, np.int32, np.int8, np.bool_]


@settings(max_examples=20, deadline=None)
@given(n=st.integers(0, 40_000), seed=st.integers(0, 2**31), kinds=st.lists(st.sampled_from(range(6)), max_size=5),
       rows_per_message=st.sampled_from([1, 7, 16384]))
def test_round_trip_of_random_streams(tmp_path_factory, n, seed, kinds, rows_per_message):
    rng = np.random.default_rng(seed)
    t = np.sort(rng.integers(-10**12, 10**12, n)).astype(np.int64)  # negative times too
    columns = {"t_ns": t}
    for k, kind in enumerate(kinds):
        dtype = _DTYPES[kind]
        values = rng.integers(-100, 100, n) if dtype not in (np.float64, np.float32) else rng.normal(size=n)
        columns[f"c{k}"] = (values > 0) if dtype is np.bool_ else values.astype(dtype)
    table = pd.DataFrame(columns)
    path = tmp_path_factory.mktemp("rt") / "r.mcap"
    with RecordingWriter(path, rows_per_message=rows_per_message if n < 2000 else 16384) as w:
        w.write("s", table.iloc[: n // 2])
        w.write("s", table.iloc[n // 2:])
    pd.testing.assert_frame_equal(read_recording(path).streams["s"], table, check_dtype=True)
