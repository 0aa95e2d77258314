"""CAN: vectorised DBC decoding against cantools, CAN log fixtures per format, damaged logs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feedlog.errors import IngestError
from feedlog.ingest.can_dbc import CanFrames, DbcLayout
from feedlog.ingest.can_streams import decode_frames, lost_samples
from feedlog.ingest.readers import ImportOptions, read_source

FIX = Path(__file__).resolve().parents[1] / "fixtures" / "ingest"

MIXED_DBC = """VERSION ""
NS_ :
BS_:
BU_: A B
BO_ 512 MOTO: 8 A
 SG_ speed : 7|16@0+ (0.5,10) [0|1000] "rpm" B
 SG_ temp : 23|12@0- (0.1,-5) [-200|200] "degC" B
 SG_ flag : 24|1@1+ (1,0) [0|1] "" B
BO_ 513 INTEL: 6 A
 SG_ pos : 3|21@1- (0.001,0) [-1000|1000] "mm" B
 SG_ Count : 40|8@1+ (1,0) [0|255] "" B
"""


@pytest.fixture(scope="module")
def layouts(tmp_path_factory):
    path = tmp_path_factory.mktemp("dbc") / "mixed.dbc"
    path.write_text(MIXED_DBC)
    return DbcLayout(), DbcLayout(path)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_bulk_decode_equals_cantools_on_random_frames(layouts, seed):
    rng = np.random.default_rng(seed)
    for layout in layouts:
        ids = np.array(list(layout.messages), dtype=np.uint32)
        n = 64
        frames = CanFrames(np.arange(n, dtype=np.int64), rng.choice(ids, n), rng.integers(0, 256, (n, 8), dtype=np.uint8))
        decoded = decode_frames(frames, layout)
        for frame_id, values in decoded.values.items():
            rows = frames.data[frames.can_id == frame_id]
            message = layout.db.get_message_by_frame_id(int(frame_id))
            for k, row in enumerate(rows):
                ref = message.decode(bytes(row[: message.length]), decode_choices=False, scaling=True)
                for name, value in ref.items():
                    assert values[name][k] == pytest.approx(value, abs=1e-9), (message.name, name)


def test_bulk_encode_matches_cantools_and_checks_range(layouts):
    ours, mixed = layouts
    for layout, name, values in [
        (ours, "FEEDLOG_AXES_XY", {"x_mm": [-1.5, 1234.5678], "y_mm": [2.25, -0.0001], "seq": [7, 255]}),
        (ours, "FEEDLOG_PATH", {"feed_mm_min": [1500, 0.01], "line": [12, 99999], "in_position": [1, 0],
                                "motion_type": [2, 1], "seq": [3, 4]}),
        (mixed, "MOTO", {"speed": [234.0, 10.5], "temp": [-3.2, 150.0], "flag": [1, 0]}),
    ]:
        message = layout.by_name(name)
        data = message.encode({k: np.asarray(v, dtype=float) for k, v in values.items()})
        for k in range(2):
            ref = layout.db.encode_message(name, {key: v[k] for key, v in values.items()})
            assert bytes(data[k][: len(ref)]) == ref
    with pytest.raises(IngestError, match="does not fit"):
        ours.by_name("FEEDLOG_PATH").encode({"feed_mm_min": np.array([1e9])})


def test_column_names_carry_units_and_streams_follow_the_dbc(layouts):
    ours, mixed = layouts
    assert {s.stream for m in ours.messages.values() for s in m.signals if s.name != "seq"} == {
        "axes", "feed", "line", "status"}
    columns = {s.name: (s.stream, s.column) for m in mixed.messages.values() for s in m.signals}
    assert columns["speed"] == ("moto", "speed_rpm") and columns["temp"] == ("moto", "temp_degc")
    assert columns["Count"] == ("intel", "count")


@pytest.mark.parametrize("source", ["axes.blf", "axes.asc", "axes.trc", "can:axes.csv"])
def test_can_log_fixture_decodes_into_standard_streams(source):
    scheme, _, name = source.rpartition(":")
    rec = read_source(f"{scheme + ':' if scheme else ''}{FIX / name}")
    assert set(rec.streams) == {"axes", "feed", "line", "status"}
    i = np.array([k for k in range(100) if k != 50])  # sample 50 was never sent
    axes = rec.streams["axes"]
    assert len(axes) == 99
    np.testing.assert_allclose(axes["x_mm"], 0.5 * i, atol=1e-4)
    np.testing.assert_allclose(axes["y_mm"], -0.25 * i, atol=1e-4)
    np.testing.assert_allclose(axes["z_mm"], 3.0)
    t = axes["t_ns"].to_numpy()
    np.testing.assert_allclose(np.diff(t), np.diff(i) * 1_000_000, atol=2_000)
    np.testing.assert_allclose(rec.streams["feed"]["feed_mm_min"], 600 + i, atol=0.005)
    assert rec.streams["line"]["line"].tolist() == (10 + i // 10).tolist()
    assert rec.streams["status"]["in_position"].tolist() == (i == 0).tolist()
    assert rec.metadata["unknown_ids"] == "10 frames with ids not in the DBC: 0x7FF (10)"
    assert rec.dropped_frames == 3 and rec.metadata["lost_samples"] == "1"  # its 3 frames are missing
    assert "feedlog_axes.dbc" in rec.attachments


@pytest.mark.parametrize("name", ["axes.blf", "axes.asc", "axes.trc", "axes.csv"])
def test_truncated_can_log_names_file_and_byte(tmp_path, name):
    data = (FIX / name).read_bytes()
    cut = tmp_path / f"cut{Path(name).suffix}"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(IngestError, match=rf"cut\{cut.suffix} \(byte {len(data) // 2}\).*truncated"):
        read_source(f"can:{cut}")


@pytest.mark.parametrize("name", ["axes.blf", "axes.trc", "axes.csv"])
def test_corrupt_can_log_names_file_and_frame(tmp_path, name):
    data = bytearray((FIX / name).read_bytes())
    middle = len(data) // 2
    data[middle: middle + 16] = b"\xff" * 16
    bad = tmp_path / f"bad{Path(name).suffix}"
    bad.write_bytes(bytes(data))
    with pytest.raises(IngestError, match=rf"bad\{bad.suffix} \((frame \d+|byte \d+)\)"):
        read_source(f"can:{bad}")


def test_lost_samples_from_wrapping_counter():
    assert lost_samples(np.array([254, 255, 0, 1, 3, 3, 4])) == 1
    assert lost_samples(np.array([10, 20])) == 9
    assert lost_samples(np.array([5])) == 0


def test_missing_dbc_is_an_ingest_error(tmp_path):
    with pytest.raises(IngestError, match="DBC file not found"):
        read_source(FIX / "axes.blf", ImportOptions(dbc=str(tmp_path / "none.dbc")))
    bad = tmp_path / "bad.dbc"
    bad.write_text("BO_ nonsense")
    with pytest.raises(IngestError, match="cannot parse DBC"):
        DbcLayout(bad)


def test_import_cli_fills_rate_and_start_time_for_can_logs(tmp_path, capsys):
    from feedlog.cli import main
    from feedlog.ingest import read_recording

    out = tmp_path / "can.mcap"
    assert main(["import", str(FIX / "axes.blf"), "-o", str(out)]) == 0
    assert "unknown_ids" in capsys.readouterr().out
    rec = read_recording(out)
    assert rec.metadata["nominal_rate_hz"] == "1000"
    assert rec.metadata["start_time"].startswith("2023-11-14T22:13:20")
    assert rec.dropped_frames == 3


def _asc_with(tmp_path, *lines: str) -> Path:
    """axes.asc with extra frame lines after its first frame."""
    rows = (FIX / "axes.asc").read_text().split("\n")
    path = tmp_path / "extra.asc"
    path.write_text("\n".join(rows[:6] + list(lines) + rows[6:]))
    return path


def test_a_frame_no_bus_can_carry_stops_a_strict_import_and_is_counted_when_lenient(tmp_path):
    path = _asc_with(tmp_path, " 0.000030 1  3FFFFFFFx       Rx   d 8 00 00 00 00 00 00 00 00",
                     " 0.000035 1  99999999999999999999x Rx   d 8 00 00 00 00 00 00 00 00")
    with pytest.raises(IngestError, match=r"extra\.asc \(frame 2\): identifier 0x3FFFFFFF does not fit 29 bits"):
        read_source(path)
    rec = read_source(path, ImportOptions(strict=False))
    assert rec.metadata["bad_frames"] == "2" and rec.dropped_frames == 3 + 2  # a lost sample's 3 frames + 2
    assert len(rec.streams["axes"]) == 99


def test_short_frames_are_counted_and_their_samples_left_out_not_decoded_as_zeros(tmp_path):
    # sample 0's XY frame cut to 2 bytes: its x and y would read as zero-padded garbage
    rows = (FIX / "axes.asc").read_text().split("\n")
    assert rows[5].split()[2] == "100"
    rows[5] = rows[5][: rows[5].index(" d 8 ")] + " d 2 00 00"
    path = tmp_path / "short.asc"
    path.write_text("\n".join(rows))
    rec = read_source(path)
    assert rec.metadata["short_frames"] == "1 frames shorter than their DBC message, not decoded: 0x100 (1)"
    axes = rec.streams["axes"]
    assert len(axes) == 98 and not axes.isna().any().any()  # sample 0 has no XY frame now: left out whole
    assert rec.metadata["incomplete_samples"] == "axes 1"
    assert rec.dropped_frames == 3  # sample 50 (never sent); the short XY frame of sample 0 has no later seq gap


def test_a_blank_or_header_only_log_is_one_clear_error(tmp_path):
    for name, text in [("blank.asc", ""), ("lines.asc", "\n\n\n"), ("empty.trc", "")]:
        path = tmp_path / name
        path.write_text(text)
        with pytest.raises(IngestError, match=rf"{name} \((byte \d+|end of file)\): .*(empty|no CAN data frames|no 'End TriggerBlock')"):
            read_source(path)
