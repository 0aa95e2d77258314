"""The import's cheap paths still catch everything (issue #28, import >= 2 M rows/s with every check).

The CSV reader decides "all in range" from each column's extremes, joins pyarrow's 1 MiB blocks once and
hands its arrays to the streams without copies; the data checks share one `PositionSteps` and skip
their masks when every interval is positive. Each test here hides an effect where only the full path
would see it (a late block, a zero interval, a sampled long trace, an aliased column) and requires it
to be reported: skipping the check, or taking the shortcut where it does not hold, fails them.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.csv as pacsv
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from feedlog.errors import IngestError
from feedlog.ingest.csv_reader import BLOCK_SIZE, read_csv
from feedlog.ingest.data_checks import position_jumps, run_checks
from feedlog.ingest.mapping import ColumnMap, load_preset, parse_map
from feedlog.ingest.quantum import position_step_mm
from feedlog.ingest.unit_check import MAX_PAIRS
from feedlog.recording import Recording

SERVO = load_preset("servo-trace-1khz")   # time ms, X1/Y1/Z1_ActualPosition mm, PathVelocity mm/min


def servo_columns(rows: int, feed: float = 3000.0) -> dict[str, np.ndarray]:
    """A 1 kHz circle of radius 50 mm at 3000 mm/min, positions to 4 decimals."""
    t = np.arange(rows, dtype=np.float64)
    angle = t * (0.05 / 50.0)                           # 0.05 mm per 1 ms sample on a 50 mm radius: 50 mm/s
    return {"time": t, "X1_ActualPosition": np.round(50 * np.cos(angle), 4),
            "Y1_ActualPosition": np.round(50 * np.sin(angle) + 60, 4),
            "Z1_ActualPosition": np.round(t * 1e-5, 4), "PathVelocity": np.full(rows, feed)}


def write(path, columns: dict[str, np.ndarray]):
    pacsv.write_csv(pa.table(columns), path)
    return path


def glitch(columns: dict[str, np.ndarray], row: int, mm: float = 120.0) -> None:
    """One sample away from the path (a home position) and back: two steps faster than any feed."""
    columns["X1_ActualPosition"][row] += mm


def test_a_long_trace_hides_a_wrong_feed_unit_jumps_and_a_zero_interval(tmp_path):
    rows = MAX_PAIRS + 60_000                            # the unit check samples: it does not see every pair
    cols = servo_columns(rows, feed=50.0)                # mm/s in a column the preset declares mm/min
    glitch(cols, 230_001)
    glitch(cols, 250_001)
    cols["time"][240_001] = cols["time"][240_000]        # two samples at one time, 0.02 mm apart: no jump
    cols["X1_ActualPosition"][240_001] = cols["X1_ActualPosition"][240_000] + 0.02
    path = write(tmp_path / "long.csv", cols)
    assert path.stat().st_size > 4 * BLOCK_SIZE          # several parse blocks
    found = run_checks(read_csv(path, SERVO))
    assert "the feed column is per second, not per minute" in found["unit_check"]
    # the limit is twice the fastest feed as declared (50 mm/min), so the circle itself moves "too fast"
    # everywhere; with the feed declared right only the glitches remain
    right = run_checks(read_csv(path, SERVO.with_units(feed_unit="mm/s")))
    assert "unit_check" not in right
    assert right["position_jumps"].startswith("4 position steps faster than 100 mm/s (2 x the fastest "
                                              "recorded feed, 50 mm/s): up to 120 mm in 0.001 s")
    assert "first at axes rows 230001 (t = 230 s), 230002 (t = 230 s), 250001 (t = 250 s)" in right["position_jumps"]
    assert "quantised" not in right                      # 4 decimals: finer than worth a word


def test_a_long_trace_hides_rounded_positions_and_jumps_without_zero_intervals(tmp_path):
    cols = servo_columns(MAX_PAIRS + 10_000)
    cols["Y1_ActualPosition"] = np.array([float(f"{y:.3g}") for y in cols["Y1_ActualPosition"]])
    glitch(cols, 205_000, mm=2000.0)
    found = run_checks(read_csv(write(tmp_path / "rounded.csv", cols), SERVO))
    assert found["quantised"].startswith("positions are rounded: y to 3 significant digits (a step of 1 mm at "
                                         "100-110 mm)")
    assert "too coarse for a feed of 50 mm/s" in found["unit_check"]       # one 1 mm step per 1 ms sample
    # the rounded y steps 1 mm in one 1 ms sample (1000 mm/s) against a limit of 100 mm/s: every such step
    # is reported; the glitch is the largest of them
    assert "up to 2000 mm in 0.001 s" in found["position_jumps"]


@pytest.mark.parametrize("column, value", [("time", "nan"), ("X1_ActualPosition", "inf"),
                                           ("PathVelocity", "1e20"), ("Z1_ActualPosition", "-1e13"),
                                           ("time", "1e300")])
def test_a_bad_cell_in_a_late_block_names_its_line(tmp_path, column, value):
    cols = {k: v.astype(object) for k, v in servo_columns(80_000).items()}
    cols[column][70_000] = value
    path = write(tmp_path / "late.csv", {k: pa.array([str(x) for x in v]) for k, v in cols.items()})
    assert path.stat().st_size > 2 * BLOCK_SIZE
    with pytest.raises(IngestError, match=rf"late\.csv:70002: 1 bad rows at lines 70002; first: column '{column}'"):
        read_csv(path, SERVO)


def test_a_time_beyond_146_years_in_a_late_block_names_its_line(tmp_path):
    cols = servo_columns(80_000)
    cols["time"] = cols["time"] / 1000.0
    cols["time"][70_000] = 1e11                         # s: 3000 years, though within the 1e12 of any value
    seconds = ColumnMap(mapping=dict(SERVO.mapping), time_unit="s")
    with pytest.raises(IngestError, match=r"years\.csv:70002: 1 bad rows at lines 70002; first: column 'time': "
                                          r"'1e\+11' is not a time"):
        read_csv(write(tmp_path / "years.csv", cols), seconds)


def test_time_going_back_in_a_late_block_names_its_line(tmp_path):
    cols = servo_columns(80_000)
    cols["time"][75_000] = 10.0
    with pytest.raises(IngestError, match=r"back\.csv:75002: 1 bad rows at lines 75002; first: time goes backwards"):
        read_csv(write(tmp_path / "back.csv", cols), SERVO)


def test_streams_own_their_columns(tmp_path):
    """read_csv's arrays go to the streams without copies: one source mapped twice, the time shared by two
    streams and a one-block file (pyarrow's read-only buffers) still give independent, writable columns."""
    cols = servo_columns(50)
    path = write(tmp_path / "twice.csv", cols)
    rec = read_csv(path, ColumnMap(mapping=parse_map("t=time,x=X1_ActualPosition,y=X1_ActualPosition,"
                                                     "feed=PathVelocity"), time_unit="ms"))
    axes, feed = rec.streams["axes"], rec.streams["feed"]
    axes.loc[3, "x_mm"] = 99.0
    axes.loc[4, "t_ns"] = 3_500_000
    feed.loc[5, "feed_mm_min"] = 1.0
    assert axes["y_mm"][3] == cols["X1_ActualPosition"][3] != 99.0 and axes["x_mm"][3] == 99.0
    assert feed["t_ns"][4] == 4_000_000 and rec.streams["axes"]["t_ns"][4] == 3_500_000
    assert feed["feed_mm_min"][5] == 1.0 and read_csv(path, SERVO).streams["feed"]["feed_mm_min"][5] == 3000.0


def test_recording_checks_find_the_first_bad_value():
    t = np.arange(6, dtype=np.int64) * 1000
    x = np.arange(6.0)
    for column, k, value in ((np.where(np.arange(6) == 4, np.nan, x), 4, "nan"),
                             (np.where(np.arange(6) == 2, -np.inf, x), 2, "-inf")):
        with pytest.raises(IngestError, match=rf"sample {k}: stream 'axes': column 'x_mm' holds .*{value}"):
            Recording(streams={"axes": pd.DataFrame({"t_ns": t, "x_mm": column})})
    with pytest.raises(IngestError, match=r"sample 3: stream 'axes': t_ns 4611686018427387905 is not a time"):
        Recording(streams={"axes": pd.DataFrame({"t_ns": np.where(np.arange(6) == 3, 2**62 + 1, t), "x_mm": x})})
    with pytest.raises(IngestError, match=r"time goes backwards at sample 5"):
        Recording(streams={"axes": pd.DataFrame({"t_ns": np.r_[t[:5], 10], "x_mm": x})})


def test_a_position_column_with_nan_is_resolved_as_its_finite_values():
    values = np.round(np.linspace(0, 50, 400), 2)
    holed = values.copy()
    holed[[5, 100]] = [np.nan, np.inf]
    assert position_step_mm(holed) == position_step_mm(np.delete(values, [5, 100])) == position_step_mm(values)
    assert position_step_mm(np.r_[np.full(50, 3.0), np.nan]) is None       # constant where it is a number
    assert position_step_mm(np.r_[np.round(np.linspace(0, 5, 50), 1), np.inf])[0] == pytest.approx(0.1)


def _reference_jumps(t: np.ndarray, p: np.ndarray, limit: float) -> np.ndarray:
    """Rows a jump arrives at, by the definition: (n, 3) differences, their norm, every mask applied."""
    dt = np.diff(t) / 1e9
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    with np.errstate(invalid="ignore"):
        return np.flatnonzero((dt > 0) & (step > limit * dt) & np.isfinite(step)) + 1


@settings(max_examples=60, derandomize=True, deadline=None, suppress_health_check=list(HealthCheck))
@given(n=st.integers(2, 400), seed=st.integers(0, 2**31), zero_intervals=st.booleans(),
       axes=st.integers(1, 3), glitches=st.integers(0, 6), epoch=st.booleans())
def test_position_jumps_match_their_definition(n, seed, zero_intervals, axes, glitches, epoch):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.integers(0 if zero_intervals else 1, 2_000_000, n)).astype(np.int64)
    t += 1_700_000_000_000_000_000 if epoch else 0      # epoch times: the differences are taken in int64
    p = np.cumsum(rng.normal(0, 0.01, (n, axes)), axis=0)
    p[rng.integers(0, n, glitches), rng.integers(0, axes, glitches)] += rng.uniform(-500, 500, glitches)
    cols = ("x_mm", "y_mm", "z_mm")[:axes]
    feed = np.abs(rng.normal(600, 100, n))
    rec = Recording(streams={"axes": pd.DataFrame({"t_ns": t, **dict(zip(cols, p.T))}),
                             "feed": pd.DataFrame({"t_ns": t, "feed_mm_min": feed})})
    expected = _reference_jumps(t, p, 2.0 * feed.max() / 60.0)
    text = position_jumps(rec)
    if not len(expected):
        assert text is None
    else:
        assert text.startswith(f"{len(expected)} position steps faster than")
        assert f"first at axes rows {expected[0]} (t = " in text
