"""CSV readers: presets, --map, declared units, wall-clock time, bad rows with line numbers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feedlog.cli import main
from feedlog.errors import IngestError
from feedlog.ingest import read_recording
from feedlog.ingest.csv_reader import read_csv
from feedlog.ingest.mapping import ColumnMap, load_preset, parse_map, preset_names
from feedlog.ingest.readers import ImportOptions, read_source

FIX = Path(__file__).resolve().parents[1] / "fixtures" / "ingest"


def test_linuxcnc_trace_preset_maps_pins_and_converts_feed_to_mm_min():
    rec = read_csv(FIX / "linuxcnc_trace.csv", load_preset("linuxcnc-trace"))
    assert set(rec.streams) == {"axes", "feed", "line", "status", "joints"}
    axes = rec.streams["axes"]
    assert list(axes.columns) == ["t_ns", "x_mm", "y_mm", "z_mm", "a_deg", "c_deg"]
    assert axes["t_ns"].tolist() == [0, 1_000_000, 2_000_000, 3_000_000, 4_000_000, 5_000_000]
    np.testing.assert_allclose(axes["x_mm"], [0, 0.001, 0.003, 0.006, 0.010, 0.015])
    np.testing.assert_allclose(axes["c_deg"], [0, 0, 0.1, 0.2, 0.3, 0.4])
    feed = rec.streams["feed"]
    np.testing.assert_allclose(feed["feed_mm_min"], [0, 60, 120, 180, 240, 300])  # mm/s * 60
    np.testing.assert_allclose(feed["requested_feed_mm_min"], 3000.0)
    assert rec.streams["line"]["line"].dtype == np.int64
    assert rec.streams["line"]["line"].tolist() == [3, 3, 3, 4, 4, 5]
    assert rec.streams["status"]["in_position"].tolist() == [True] + [False] * 5
    assert rec.streams["status"]["motion_type"].dtype == np.int8
    assert list(rec.streams["joints"].columns) == ["t_ns", "j0_pos_fb", "j1_pos_fb"]
    assert rec.metadata["controller"] == "linuxcnc"
    assert rec.metadata["nominal_rate_hz"] == "1000"


def test_monitoring_export_with_local_wall_clock_and_irregular_spacing():
    cmap = load_preset("monitoring-5hz").with_units(timezone="Europe/Berlin")
    rec = read_csv(FIX / "monitoring_5hz.csv", cmap)
    t = rec.streams["axes"]["t_ns"].to_numpy()
    # 13:00 in Berlin (CET, UTC+1) is 12:00 UTC
    assert t[0] == np.datetime64("2026-11-22T12:00:00", "ns").astype(np.int64)
    assert np.diff(t).tolist() == [180_000_000, 230_000_000, 190_000_000, 230_000_000]
    assert rec.metadata["start_time"] == "2026-11-22T12:00:00+00:00"
    assert rec.streams["line"]["line"].tolist() == [12, 12, 13, 13, 14]
    assert "a_deg" not in rec.streams["axes"]  # optional preset columns absent from the file are skipped


def test_servo_trace_preset_and_equivalent_map_with_declared_units():
    rec = read_csv(FIX / "servo_trace_1khz.csv", load_preset("servo-trace-1khz"))
    axes = rec.streams["axes"]
    assert len(axes) == 200 and axes["t_ns"].iloc[-1] == 199_000_000
    cmap = ColumnMap(mapping=parse_map("t=time,x=X1_ActualPosition,feed=PathVelocity"), time_unit="ms",
                     length_unit="in", feed_unit="in/min")
    inch = read_csv(FIX / "servo_trace_1khz.csv", cmap)
    np.testing.assert_allclose(inch.streams["axes"]["x_mm"], axes["x_mm"] * 25.4)
    np.testing.assert_allclose(inch.streams["feed"]["feed_mm_min"], 3000 * 25.4)


def test_bad_rows_strict_names_first_line_and_count():
    with pytest.raises(IngestError, match=r"bad_rows\.csv:4: 4 bad rows at lines 4, 6, 8, 9"):
        read_csv(FIX / "bad_rows.csv", load_preset("servo-trace-1khz"))


def test_bad_rows_lenient_drops_and_reports_them():
    rec = read_csv(FIX / "bad_rows.csv", load_preset("servo-trace-1khz"), strict=False)
    assert rec.streams["axes"]["t_ns"].tolist() == [0, 1_000_000, 4_000_000, 6_000_000]
    report = rec.metadata["bad_rows"]
    assert report.startswith("4 bad rows at lines 4, 6, 8, 9") and "'oops' is not a finite number" in report


def test_missing_column_and_bad_mapping_are_clear():
    with pytest.raises(IngestError, match=r"columns not in the file: y=nope.*the file has: time"):
        read_csv(FIX / "servo_trace_1khz.csv", ColumnMap(mapping=parse_map("t=time,y=nope")))
    with pytest.raises(IngestError, match="unknown mapping target 'q'"):
        ColumnMap(mapping={"t": "time", "q": "x"})
    with pytest.raises(IngestError, match="no time column"):
        ColumnMap(mapping={"x": "X"})
    with pytest.raises(IngestError, match="not TARGET=COLUMN"):
        parse_map("t=time,x")
    with pytest.raises(IngestError, match="unknown preset 'nope'.*linuxcnc-trace"):
        load_preset("nope")
    assert {"linuxcnc-trace", "monitoring-5hz", "servo-trace-1khz"} <= set(preset_names())


def test_registry_picks_by_suffix_and_scheme_and_lists_supported(tmp_path):
    rec = read_source(FIX / "servo_trace_1khz.csv", ImportOptions(preset="servo-trace-1khz"))
    assert len(rec.streams["axes"]) == 200
    txt = tmp_path / "trace.dat"
    txt.write_bytes((FIX / "servo_trace_1khz.csv").read_bytes())
    with pytest.raises(IngestError, match=r"no reader for suffix '\.dat'; supported: \.mcap, \.csv"):
        read_source(txt, ImportOptions(preset="servo-trace-1khz"))
    assert len(read_source(f"csv:{txt}", ImportOptions(preset="servo-trace-1khz")).streams["axes"]) == 200
    with pytest.raises(IngestError, match="give either a preset"):
        ImportOptions(preset="servo-trace-1khz", mapping="t=time,x=X")


def test_import_cli_writes_recording_with_program_and_profile(tmp_path, capsys):
    program = tmp_path / "p.ngc"
    program.write_text("G1 X1 F600\nM2\n")
    out = tmp_path / "rec.mcap"
    argv = ["import", str(FIX / "linuxcnc_trace.csv"), "--preset", "linuxcnc-trace", "--program", str(program),
            "--profile", "linuxcnc-xyz", "-o", str(out)]
    assert main(argv) == 0
    rec = read_recording(out)
    assert rec.program_text.startswith("G1 X1") and b"[axes" in rec.attachments["profile.toml"]
    assert rec.metadata["machine"] == "linuxcnc-xyz" and len(rec.streams["axes"]) == 6
    assert main(argv) == 2  # refuses to overwrite
    assert "exists" in capsys.readouterr().err
    assert main(argv + ["--overwrite", "--compression", "zstd"]) == 0
    assert len(read_recording(out).streams["axes"]) == 6
    assert main(["import", str(FIX / "bad_rows.csv"), "--preset", "servo-trace-1khz", "-o", str(tmp_path / "b.mcap")]) == 2
    assert "bad_rows.csv:4" in capsys.readouterr().err
    assert not (tmp_path / "b.mcap").exists()


def test_truncated_csv_last_line_is_a_bad_row(tmp_path):
    data = (FIX / "servo_trace_1khz.csv").read_bytes()
    cut = tmp_path / "cut.csv"
    cut.write_bytes(data[: data.rindex(b",")])  # the last row loses its last field
    with pytest.raises(IngestError, match=r"cut\.csv:201: 1 bad rows at lines 201"):
        read_csv(cut, load_preset("servo-trace-1khz"))


@settings(max_examples=15, deadline=None)
@given(n=st.integers(2, 300), seed=st.integers(0, 2**31), delimiter=st.sampled_from([",", ";", "\t"]))
def test_csv_round_trip_of_random_traces(tmp_path_factory, n, seed, delimiter):
    import pyarrow as pa
    import pyarrow.csv as pacsv

    rng = np.random.default_rng(seed)
    t_ms = np.cumsum(rng.integers(1, 50, n)).astype(np.float64)
    x = np.round(rng.normal(size=n) * 100, 6)
    line = rng.integers(0, 10**6, n)
    path = tmp_path_factory.mktemp("csv") / "trace.csv"
    pacsv.write_csv(pa.table({"T": t_ms, "X": x, "N": line}), path,
                    write_options=pacsv.WriteOptions(delimiter=delimiter))
    cmap = ColumnMap(mapping=parse_map("t=T,x=X,line=N"), time_unit="ms", length_unit="um")
    rec = read_csv(path, cmap, delimiter=delimiter)
    assert rec.streams["axes"]["t_ns"].tolist() == (t_ms.astype(np.int64) * 1_000_000).tolist()
    np.testing.assert_allclose(rec.streams["axes"]["x_mm"], x * 1e-3, rtol=1e-12)
    assert rec.streams["line"]["line"].tolist() == line.tolist()


def test_bytes_that_are_not_utf8_are_a_bad_value_not_a_crash(tmp_path):
    path = tmp_path / "binary.csv"
    path.write_bytes(b"t,x\n0,1\n1,\xff\xfe\n2,3\n")
    cmap = ColumnMap(mapping=parse_map("t=t,x=x"))
    with pytest.raises(IngestError, match=r"binary\.csv:3: 1 bad rows at lines 3; first: column 'x'"):
        read_csv(path, cmap)
    assert read_csv(path, cmap, strict=False).streams["axes"]["x_mm"].tolist() == [1.0, 3.0]


@pytest.mark.parametrize("value", ["1e20", "-1e308", "1e13"])
@pytest.mark.parametrize("column", ["motion.program-line", "motion.current-vel", "axis.x.pos-cmd"])
def test_out_of_range_cells_name_file_and_line(tmp_path, capsys, value, column):
    """A finite but absurd cell (issue #30: 1e20 and 1e308 imported with exit 0 after numpy's overflow
    warning) is a bad row like NaN: an error naming file and line, or a counted skip with --lenient."""
    lines = (FIX / "linuxcnc_trace.csv").read_text().splitlines(keepends=True)
    header = lines[0].strip().split(",")
    cells = lines[3].rstrip("\n").split(",")
    cells[header.index(column)] = value
    lines[3] = ",".join(cells) + "\n"
    path = tmp_path / "big.csv"
    path.write_text("".join(lines))
    with pytest.raises(IngestError, match=rf"big\.csv:4: 1 bad rows at lines 4; first: column '{column}': "
                                          rf"'{value}' is not a finite number within"):
        read_csv(path, load_preset("linuxcnc-trace"))
    assert main(["import", str(path), "--preset", "linuxcnc-trace", "-o", str(tmp_path / "o.mcap")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Warning" not in err and not (tmp_path / "o.mcap").exists()
    rec = read_csv(path, load_preset("linuxcnc-trace"), strict=False)
    assert rec.metadata["bad_rows"].startswith("1 bad rows at lines 4") and rec.metadata["rows"] == "5"
    assert np.abs(rec.streams["axes"]["x_mm"]).max() < 1


def test_large_but_real_values_still_import(tmp_path):
    path = tmp_path / "far.csv"
    path.write_text("t,x\n0,0\n0.001,999999999.5\n")  # a kilometre-long axis in um: unusual, not corrupt
    rec = read_csv(path, ColumnMap(mapping=parse_map("t=t,x=x"), time_unit="s", length_unit="um"))
    np.testing.assert_allclose(rec.streams["axes"]["x_mm"], [0, 999999.9995])


def test_the_wall_clock_time_column_mapped_to_a_position_too_is_a_clear_error(tmp_path):
    """The time column read as datetimes, mapped to an axis as well, was a numpy ValueError traceback."""
    from feedlog.ingest.csv_reader import read_csv
    from feedlog.ingest.mapping import ColumnMap
    path = tmp_path / "stamps.csv"
    path.write_text("t,y,z\n" + "".join(f"2024-01-01T00:00:00.00{i},{i},0\n" for i in range(5)))
    cmap = ColumnMap(mapping={"t": "t", "x": "t", "y": "y", "z": "z"}, name="--map", time_unit="datetime")
    with pytest.raises(IngestError, match=r"x=t: the column does not hold numbers"):
        read_csv(path, cmap)
