"""The writer's zstd level and chunk size (compact LinuxCNC training sessions use zstd 19)."""

from __future__ import annotations

import threading

import mcap.writer
import numpy as np
import pandas as pd
import pytest
from mcap.reader import make_reader

from feedlog.ingest import read_recording
from feedlog.ingest.recording import Recording
from feedlog.ingest.writer import RecordingWriter, write_recording, zstd_level


def _servo_like(n: int = 30_000) -> Recording:
    """Positions at 1 kHz printed with 6 decimals, as halsampler does: smooth, not trivially compressible."""
    rng = np.random.default_rng(3)
    t = np.arange(n, dtype=np.int64) * 1_000_000
    v = np.cumsum(rng.normal(0.0, 0.002, size=(n, 3)), axis=0)
    pos = np.round(np.cumsum(v, axis=0) * 1e-3, 6)
    axes = pd.DataFrame({"t_ns": t, "x_mm": pos[:, 0], "y_mm": pos[:, 1], "z_mm": pos[:, 2]})
    line = pd.DataFrame({"t_ns": t, "line": (np.arange(n) // 37).astype(np.int32)})
    return Recording(streams={"axes": axes, "line": line}, metadata={"machine": "m"}, attachments={})


def _chunk_compressions(path) -> set[str]:
    with open(path, "rb") as f:
        return {c.compression for c in make_reader(f).get_summary().chunk_indexes}


def test_a_higher_zstd_level_writes_a_smaller_file_that_reads_back_the_same(tmp_path):
    rec = _servo_like()
    default, high = tmp_path / "l3.mcap", tmp_path / "l19.mcap"
    write_recording(default, rec, compression="zstd")
    write_recording(high, rec, compression="zstd", level=19)
    assert high.stat().st_size < 0.95 * default.stat().st_size
    assert _chunk_compressions(high) == {"zstd"}
    for path in (default, high):
        back = read_recording(path)
        for name, table in rec.streams.items():
            pd.testing.assert_frame_equal(back.stream(name), table)


def test_level_3_is_what_mcap_wrote_before(tmp_path):
    """Without a level the bytes are zstd's default level, as the mcap library writes them."""
    rec = _servo_like(5000)
    write_recording(tmp_path / "a.mcap", rec, compression="zstd")
    write_recording(tmp_path / "b.mcap", rec, compression="zstd", level=3)
    a, b = (tmp_path / "a.mcap").read_bytes(), (tmp_path / "b.mcap").read_bytes()
    assert len(a) == len(b)


def test_the_level_is_per_thread_and_restored(tmp_path):
    seen = {}

    def worker():
        with zstd_level(19):
            seen["inner"] = mcap.writer.zstandard._local.level
    t = threading.Thread(target=worker)
    t.start()
    t.join()
    assert seen["inner"] == 19
    assert getattr(mcap.writer.zstandard._local, "level", 3) == 3


@pytest.mark.parametrize("kwargs", [{"compression": "zstd", "level": 0}, {"compression": "zstd", "level": 23},
                                    {"compression": "lz4", "level": 5}, {"compression": "none", "level": 19}])
def test_bad_levels_are_refused(tmp_path, kwargs):
    with pytest.raises(ValueError, match="level"):
        RecordingWriter(tmp_path / "x.mcap", **kwargs)
    assert not (tmp_path / "x.mcap").exists()


def test_small_chunks_make_more_chunks(tmp_path):
    rec = _servo_like(20_000)
    write_recording(tmp_path / "small.mcap", rec, compression="zstd", chunk_size=64 * 1024)
    write_recording(tmp_path / "big.mcap", rec, compression="zstd")
    with open(tmp_path / "small.mcap", "rb") as f:
        small = len(make_reader(f).get_summary().chunk_indexes)
    with open(tmp_path / "big.mcap", "rb") as f:
        big = len(make_reader(f).get_summary().chunk_indexes)
    assert small > big >= 1
