"""Property-based fuzzing (hypothesis, derandomized): random G-code, CSV cells, MCAP damage, CAN frames
and damaged LinuxCNC INI files. Each reader either raises our located error or returns values that
are all finite, with int64 times that a recording may hold."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from feedlog.errors import FeedlogError, IngestError, LocatedError, ProgramError
from feedlog.ingest import read_recording
from feedlog.ingest.can_dbc import CanFrames, DbcLayout
from feedlog.ingest.can_log import frames_to_recording
from feedlog.ingest.csv_reader import read_csv
from feedlog.ingest.mapping import load_preset
from feedlog.profile import load_profile
from feedlog.toolpath import parse_program
from feedlog.toolpath.summary import summarize
from feedlog.units import MAX_ABS_T_NS, MAX_TIME_S
from tests.fuzz import mcap_edit

FUZZ = settings(max_examples=80, derandomize=True, deadline=None, suppress_health_check=list(HealthCheck))

NUMBERS = st.one_of(st.integers(-10**6, 10**6).map(str), st.floats(allow_nan=False, allow_infinity=False,
                                                                   width=32).map(lambda x: f"{x:.6g}"),
                    st.sampled_from(["0", "-0", ".5", "1.", "9" * 20, "9" * 320, "0." + "0" * 30 + "1", "1e5"]))
WORDS = st.tuples(st.sampled_from("GGGMXYZXYZABCIJKRFFPNSQ"), NUMBERS).map("".join)
LINES = st.lists(st.one_of(WORDS, st.sampled_from(["G0", "G1", "G2", "G3", "G91", "G90", "G20", "G21", "G4",
                                                     "G93", "G94", "G64", "(c)", ";x", "%", "#1", "/"])),
                 max_size=6).map(" ".join)
ENDINGS = st.sampled_from(["\n", "\r\n", "\r"])


def finite_table(table: pd.DataFrame, columns, *, bound: float = math.inf) -> None:
    """Every value present is finite and within +-bound (NaN is "no such value here" in a block table;
    recordings, checked with `no_gaps`, have none)."""
    for column in columns:
        if column in table:
            values = table[column].to_numpy(dtype=np.float64, na_value=np.nan)
            present = ~np.isnan(values)
            assert np.isfinite(values[present]).all() and (np.abs(values[present]) <= bound).all(), column


def no_gaps(table: pd.DataFrame) -> None:
    t = table["t_ns"].to_numpy()
    assert t.dtype == np.int64 and (np.abs(t) <= MAX_ABS_T_NS).all() and (np.diff(t) >= 0).all()
    assert not table.isna().any().any()
    finite_table(table, table.columns[1:])


@FUZZ
@given(st.lists(LINES, min_size=1, max_size=25), ENDINGS, st.booleans())
def test_random_gcode_parses_to_finite_blocks_or_a_located_error(lines, ending, lenient):
    text = ending.join(lines) + ending
    try:
        program = parse_program(text, lenient=lenient, name="fuzz.ngc")
        summary = summarize(program, load_profile("linuxcnc-xyzac"))
    except ProgramError as exc:
        assert exc.file == "fuzz.ngc" and exc.line is not None and 1 <= exc.line <= len(lines) + 1
        return
    except FeedlogError as exc:  # a profile limit, not the program's text
        assert "fuzz.ngc" in str(exc)
        return
    finite_table(program.blocks, ["x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg", "length_mm", "feed_mm_min",
                                  "dwell_s", "radius_mm", "tol_mm", "spindle_rpm"], bound=1e12)
    assert (program.blocks["n_word"] >= -1).all()
    assert math.isfinite(summary["cam_time_s"]) and 0 <= summary["cam_time_s"] <= MAX_TIME_S


CELLS = st.sampled_from(["1.5", "0", "-2", "nan", "NaN", "inf", "-inf", "1e400", "", " 3 ", "abc", "9" * 400,
                         "1e300", "0x10", "\u00b5", '"4"'])


@FUZZ
@given(st.lists(st.lists(CELLS, min_size=4, max_size=6), min_size=1, max_size=30), ENDINGS, st.booleans())
def test_random_csv_cells_import_finite_or_fail_on_a_line(tmp_path_factory, rows, ending, lenient):
    header = "time,X1_ActualPosition,Y1_ActualPosition,Z1_ActualPosition,PathVelocity"
    body = ending.join(",".join(r) for r in rows)
    path = tmp_path_factory.mktemp("csv") / "f.csv"
    path.write_bytes((header + ending + body + ending).encode("utf-8"))
    try:
        rec = read_csv(path, load_preset("servo-trace-1khz"), strict=not lenient)
    except IngestError as exc:
        assert exc.file == str(path) and exc.line is not None and 1 <= exc.line <= len(rows) + 1
        return
    for table in rec.streams.values():
        no_gaps(table)


SEED = mcap_edit.write_feedlog(mcap_edit.seed_streams(1500), chunk_size=8 * 1024, compression="zstd",
                               rows_per_message=100)


@FUZZ
@given(st.integers(9, len(SEED) - 1), st.lists(st.tuples(st.integers(0, len(SEED) - 1), st.integers(0, 7)),
                                                max_size=3), st.booleans())
def test_damaged_mcap_reads_back_a_clean_prefix_or_names_the_byte(tmp_path_factory, cut, flips, recover):
    data = bytearray(SEED[:cut])
    for at, bit in flips:
        if at < len(data):
            data[at] ^= 1 << bit
    path = tmp_path_factory.mktemp("mcap") / "d.mcap"
    path.write_bytes(bytes(data))
    try:
        rec = read_recording(path, recover=recover)
    except IngestError as exc:
        assert exc.file == str(path) and exc.position
        return
    for table in rec.streams.values():
        no_gaps(table)


FRAMES = st.lists(st.tuples(st.sampled_from([0x100, 0x101, 0x102, 0x110, 0x7FF, 0x1FFFFFFF]),
                            st.binary(min_size=0, max_size=8), st.integers(0, 10**9)), max_size=60)


@FUZZ
@given(FRAMES)
def test_random_can_frames_decode_to_complete_finite_samples(frames):
    ids = np.array([f[0] for f in frames], dtype=np.uint32)
    data = np.zeros((len(frames), 8), dtype=np.uint8)
    for k, (_, payload, _) in enumerate(frames):
        data[k, :len(payload)] = np.frombuffer(payload, dtype=np.uint8)
    dlc = np.array([len(f[1]) for f in frames], dtype=np.uint8)
    t = np.sort(np.array([f[2] for f in frames], dtype=np.int64) * 1000)
    try:
        rec = frames_to_recording(CanFrames(t, ids, data, dlc), DbcLayout(), source="bus.asc")
    except LocatedError as exc:  # pragma: no cover - decoding frames never needs one today
        pytest.fail(f"decoding raised {exc}")
    short = int((dlc < 8)[np.isin(ids, [0x100, 0x101, 0x102, 0x110])].sum())
    assert str(short) in rec.metadata.get("short_frames", "0 ")
    for table in rec.streams.values():
        no_gaps(table)


INI = (Path(__file__).resolve().parents[2] / "recordings" / "configs" / "xyz.ini").read_bytes()


@FUZZ
@given(st.integers(0, len(INI) - 1), st.binary(max_size=12), st.integers(0, len(INI)))
def test_a_damaged_linuxcnc_ini_reads_or_names_the_file(tmp_path_factory, at, junk, cut):
    """The recorder's --ini: whatever the bytes, MachineIni.read and the values it hands to the
    session are either usable or an IngestError naming the file (before LinuxCNC is started)."""
    from feedlog.ingest.linuxcnc_session import MachineIni

    path = tmp_path_factory.mktemp("ini") / "m.ini"
    path.write_bytes((INI[:at] + junk + INI[at:])[:max(cut, 1)])
    try:
        ini = MachineIni.read(path)
        layout = ini.layout()
    except IngestError as exc:
        assert exc.file == str(path)
        return
    assert 1 <= ini.joints <= 16 and 1_000 <= ini.servo_period_ns <= 10**9 and layout.groups
