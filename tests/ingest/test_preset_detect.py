"""`feedlog import FILE.csv` with neither --preset nor --map finds the preset from the header
(ingest/preset_detect.py): the real UMich and Sinumerik excerpts and the format fixtures get theirs, a CSV
no preset fits (a CAN log) is the error that asks for a mapping, two equal fits name both, and any bytes
end in a preset name or one IngestError (fuzzed)."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from feedlog.cli import main
from feedlog.errors import IngestError
from feedlog.ingest import read_recording
from feedlog.ingest.preset_detect import detect_preset

FIX = Path(__file__).resolve().parents[1] / "fixtures" / "ingest"


@pytest.mark.parametrize("name, preset", [
    ("real/umich_experiment.csv", "umich-tool-wear"), ("real/sinumerik_trace.csv", "sinumerik-trace"),
    ("servo_trace_1khz.csv", "servo-trace-1khz"), ("monitoring_5hz.csv", "monitoring-5hz"),
    ("linuxcnc_trace.csv", "linuxcnc-trace")])
def test_each_format_is_found_from_its_header(name, preset):
    assert detect_preset(FIX / name) == preset


def test_import_without_a_preset_says_which_it_found_and_reads_as_with_it(tmp_path, capsys):
    src = FIX / "real" / "umich_experiment.csv"
    assert main(["import", str(src), "-o", str(tmp_path / "found.mcap")]) == 0
    assert "(preset umich-tool-wear, found from the header)" in capsys.readouterr().out
    assert main(["import", str(src), "--preset", "umich-tool-wear", "-o", str(tmp_path / "given.mcap"), "-q"]) == 0
    found, given = read_recording(tmp_path / "found.mcap"), read_recording(tmp_path / "given.mcap")
    assert found.streams.keys() == given.streams.keys()
    for key in found.streams:
        assert found.streams[key].equals(given.streams[key]), key


def test_a_csv_no_preset_fits_asks_for_a_mapping(tmp_path):
    with pytest.raises(IngestError, match=r"axes.csv.*no shipped preset matches its header.*--preset NAME"):
        detect_preset(FIX / "axes.csv")   # a CAN log: a timestamp column alone is no fit
    odd = tmp_path / "odd.csv"
    odd.write_text("when,where\n1,2\n")
    with pytest.raises(IngestError, match="no shipped preset"):
        detect_preset(odd)


def test_the_better_fit_wins_and_two_equal_fits_name_both(tmp_path, monkeypatch):
    # the UMich and servo-trace presets share the X1/Y1/Z1 columns: a time column decides
    timed = tmp_path / "timed.csv"
    timed.write_text("time,X1_ActualPosition,Y1_ActualPosition,Z1_ActualPosition\n0,1,2,3\n")
    untimed = tmp_path / "untimed.csv"
    untimed.write_text("X1_ActualPosition,Y1_ActualPosition,Z1_ActualPosition,M1_CURRENT_FEEDRATE\n1,2,3,4\n")
    assert detect_preset(timed) == "servo-trace-1khz" and detect_preset(untimed) == "umich-tool-wear"
    import feedlog.ingest.preset_detect as pd_mod
    monkeypatch.setattr(pd_mod, "preset_names", lambda: ["servo-trace-1khz", "servo-trace-1khz"])
    with pytest.raises(IngestError, match="fits presets servo-trace-1khz and servo-trace-1khz equally"):
        detect_preset(timed)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(max_size=3000))
def test_any_bytes_end_in_a_preset_or_one_clear_error(tmp_path, data):
    path = tmp_path / "fuzz.csv"
    path.write_bytes(data)
    try:
        assert detect_preset(path) in {"linuxcnc-trace", "monitoring-5hz", "mtconnect-shdr", "servo-trace-1khz",
                                       "sinumerik-trace", "umich-tool-wear"}
    except IngestError as exc:
        assert "fuzz.csv" in str(exc)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cut=st.integers(0, 4000), flip=st.integers(0, 4000))
def test_a_truncated_or_bit_flipped_real_header_is_found_or_refused_clearly(tmp_path, cut, flip):
    raw = bytearray((FIX / "real" / "umich_experiment.csv").read_bytes()[:cut])
    if raw and flip < len(raw):
        raw[flip] ^= 0x20
    path = tmp_path / "cut.csv"
    path.write_bytes(bytes(raw))
    try:
        detect_preset(path)
    except IngestError as exc:
        assert "cut.csv" in str(exc)
