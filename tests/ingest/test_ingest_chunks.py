"""Chunked recordings (#19): chunks of at most 1 MiB, streams interleaved by time, and `--recover` cut at
every chunk boundary, for `write_recording` (import) and the live logger; damaged files cost no more
memory than their size."""

from __future__ import annotations

import threading
import time
import tracemalloc
from pathlib import Path

import can
import numpy as np
import pandas as pd
import pytest
from mcap.records import Chunk
from mcap.stream_reader import StreamReader

from feedlog.errors import IngestError
from feedlog.ingest import Recording, read_recording, write_recording
from feedlog.ingest.can_dbc import DbcLayout
from feedlog.ingest.live import record_bus
from feedlog.ingest.source_sim import sim_frames
from feedlog.ingest.writer import CHUNK_SIZE
from tests.fuzz import mcap_edit


def chunks(path: Path) -> list[tuple[int, Chunk]]:
    """(byte offset just after the chunk, chunk) for every chunk of a complete file."""
    data = path.read_bytes()
    ends = mcap_edit.chunk_ends(data)
    found = [r for r in StreamReader(str(path), emit_chunks=True).records if isinstance(r, Chunk)]
    assert len(found) == len(ends)
    return list(zip(ends, found))


def big_recording(n: int = 120_000) -> Recording:
    t = np.arange(n, dtype=np.int64) * 1_000_000
    rng = np.random.default_rng(1)
    axes = pd.DataFrame({"t_ns": t, **{c: rng.normal(size=n) for c in ("x_mm", "y_mm", "z_mm")}})
    feed = pd.DataFrame({"t_ns": t, "feed_mm_min": rng.normal(size=n)})
    line = pd.DataFrame({"t_ns": t[::10], "line": np.arange(len(t[::10]), dtype=np.int64)})
    return Recording(streams={"axes": axes, "feed": feed, "line": line}, metadata={"machine": "m"})


def assert_recovers_every_complete_chunk(path: Path, full: Recording) -> None:
    """Cut the file after each chunk: strict reading fails naming the byte, --recover keeps a prefix of
    every stream that grows chunk by chunk, and all of it when the cut follows the last chunk."""
    data = path.read_bytes()
    cut = path.with_name("cut.mcap")
    previous = -1
    bounds = chunks(path)
    for k, (end, _) in enumerate(bounds):
        cut.write_bytes(data[:end])
        with pytest.raises(IngestError, match=rf"cut\.mcap \(byte {end}\): file is truncated"):
            read_recording(cut)
        rec = read_recording(cut, recover=True)
        assert f"at byte {end}" in rec.metadata["recovered"]
        total = 0
        for name, table in rec.streams.items():
            whole = full.streams[name]
            pd.testing.assert_frame_equal(table, whole.iloc[:len(table)].reset_index(drop=True))
            total += len(table)
        assert total > previous
        previous = total
        if k == len(bounds) - 1:
            assert all(len(rec.streams[n]) == len(t) for n, t in full.streams.items())


def test_import_writes_small_chunks_interleaved_by_time(tmp_path):
    rec = big_recording()
    path = tmp_path / "big.mcap"
    write_recording(path, rec, compression="zstd")
    found = chunks(path)
    assert len(found) >= 5 and max(c.uncompressed_size for _, c in found) <= CHUNK_SIZE
    # each chunk spans a stretch of time in every stream, not one stream after another
    spans = [(c.message_start_time, c.message_end_time) for _, c in found]
    assert all(b0 >= a0 for (a0, _), (b0, _) in zip(spans, spans[1:]))
    cut = tmp_path / "half.mcap"
    cut.write_bytes(path.read_bytes()[:found[len(found) // 2][0]])
    half = read_recording(cut, recover=True)
    ends = [int(t["t_ns"].iloc[-1]) for t in half.streams.values()]
    # every stream, each up to the same second: one message (1 s) plus one sample of the slowest stream (10 ms)
    assert set(half.streams) == set(rec.streams) and max(ends) - min(ends) <= 1_010_000_000


def test_import_recovers_every_chunk_before_a_cut(tmp_path):
    rec = big_recording(60_000)
    path = tmp_path / "rec.mcap"
    write_recording(path, rec)
    assert_recovers_every_complete_chunk(path, rec)


def test_logger_flushes_chunks_that_recover_at_every_boundary(tmp_path):
    layout = DbcLayout()
    n = 3000
    i = np.arange(n)
    data = pd.DataFrame({"t_ns": i * 1_000_000, "x_mm": 0.01 * i, "y_mm": np.cos(i / 50), "z_mm": -1.0,
                         "feed_mm_min": 600.0, "line": 10 + i // 300})
    frames = sim_frames(data, layout, t0_ns=1_700_000_000_000_000_000)

    def paced() -> None:  # ten bursts 0.15 s apart, so the logger flushes between them
        bus = can.Bus(interface="virtual", channel="chunks", preserve_timestamps=True)
        try:
            for burst in np.array_split(np.arange(len(frames)), 10):
                for k in burst:
                    bus.send(can.Message(timestamp=frames.t_ns[k] / 1e9, arbitration_id=int(frames.can_id[k]),
                                         data=frames.data[k].tobytes(), is_extended_id=False))
                time.sleep(0.15)
        finally:
            bus.shutdown()

    rx = can.Bus(interface="virtual", channel="chunks")
    sender = threading.Thread(target=paced, daemon=True)
    sender.start()
    try:
        summary = record_bus(rx, tmp_path / "live.mcap", progress=None, flush_interval_s=0.1,
                             finished=lambda: not sender.is_alive() and rx.queue.empty())
    finally:
        rx.shutdown()
    assert summary["dropped_frames"] == 0 and summary["incomplete_samples"] == 0
    full = read_recording(tmp_path / "live.mcap")
    assert len(full.streams["axes"]) == n
    assert len(chunks(tmp_path / "live.mcap")) >= 5
    assert_recovers_every_complete_chunk(tmp_path / "live.mcap", full)


@pytest.mark.parametrize("damage", ["header-string-4gb", "chunk-claims-4gb", "chunk-length-2e40"])
def test_a_small_damaged_file_costs_no_more_memory_than_its_size(tmp_path, damage):
    data = mcap_edit.write_feedlog(mcap_edit.seed_streams(300), chunk_size=1 << 20, compression="zstd",
                                   rows_per_message=100)
    recs = mcap_edit.records(data)
    chunk = recs[next(i for i, r in enumerate(recs) if r.opcode == 0x06)]
    if damage == "header-string-4gb":
        data = mcap_edit.set_u32(data, recs[0].offset + 9, 0xFFFF_FFFF)
    elif damage == "chunk-claims-4gb":
        data = mcap_edit.set_u64(data, mcap_edit.chunk_fields(chunk)["uncompressed_size"], 2**32)
    else:
        data = mcap_edit.set_length(data, recs.index(chunk), 2**40)
    path = tmp_path / "small.mcap"
    path.write_bytes(data)
    assert len(data) < 20_000
    tracemalloc.start()
    try:
        for recover in (False, True):
            try:
                read_recording(path, recover=recover)
            except IngestError as exc:
                assert "small.mcap" in str(exc) and "byte" in str(exc)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20 * 2**20  # megabytes, where the length fields ask for gigabytes
