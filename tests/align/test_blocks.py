import numpy as np
import pandas as pd
import pytest

from align_synth import Motion, zigzag
from feedlog.align.blocks import blocks_from_geometry, blocks_from_lines, compare_blocks, line_runs, motion_span
from feedlog.align.match import MatchConfig, match_cl_points
from feedlog.errors import AlignmentError


@pytest.fixture(scope="module")
def motion():
    v = np.vstack([zigzag(passes=5, length=30.0, step=3.0), [[0.0, 12.0, 5.0], [20.0, 12.0, 5.0]]])
    return Motion(v, feed_mm_min=3000.0, acc_mm_s2=1000.0, lead_s=0.7, tail_s=0.4)


def _blocks(motion):
    n = len(motion.lengths)
    return pd.DataFrame({"block": np.arange(n) + 3, "line": np.arange(n) + 10})


def _line_stream(motion, rate_hz):
    t = motion.timestamps(rate_hz)
    k = np.searchsorted(motion.arrival_ns, t, side="right") - 1  # segment being executed
    line = np.where(k < 0, 4, k + 10)
    line = np.where(k >= len(motion.lengths), 0, line)  # idle after the end
    return t, line.astype(np.int64)


def test_motion_span_at_1khz(motion):
    ax = motion.axes(1000.0)
    span = motion_span(ax["t_ns"].to_numpy(), ax[["x_mm", "y_mm", "z_mm"]].to_numpy())
    assert span.duration_s == pytest.approx(motion.motion_s, abs=0.002)
    assert abs(span.t_start_ns - motion.arrival_ns[0]) <= 1_000_000


@pytest.mark.parametrize("phase_ms", [0, 63, 141])
def test_motion_span_at_5hz_within_half_percent(motion, phase_ms):
    ax = motion.axes(5.0, phase_ns=phase_ms * 1_000_000)
    p = ax[["x_mm", "y_mm", "z_mm"]].to_numpy()
    span = motion_span(ax["t_ns"].to_numpy(), p, acc_mm_s2=1000.0)
    assert span.duration_s == pytest.approx(motion.motion_s, rel=0.005)
    # without the sub-interval estimate the error would be up to two sample periods
    crude = (ax["t_ns"].iloc[span.last_index] - ax["t_ns"].iloc[span.first_index]) / 1e9
    assert crude >= span.duration_s


def test_motion_span_refuses_a_still_recording():
    t = np.arange(10, dtype=np.int64) * 1_000_000
    with pytest.raises(AlignmentError, match="never moves"):
        motion_span(t, np.zeros((10, 3)))


def test_blocks_from_lines(motion):
    t, line = _line_stream(motion, 1000.0)
    blocks = _blocks(motion)
    span = motion_span(t, motion.positions(t))
    got = blocks_from_lines(t, line, blocks, span=span)
    true_dur = motion.durations
    np.testing.assert_allclose(got["duration_s"], true_dur, atol=0.0011)
    assert got["seen"].all()
    assert got["t_start_ns"].iloc[0] >= span.t_start_ns and got["t_end_ns"].iloc[-1] <= span.t_end_ns
    # a block whose line never shows gets zero duration at its neighbour's boundary
    line2 = np.where(line == 13, 14, line)
    got2 = blocks_from_lines(t, line2, blocks, span=span)
    row = got2[got2["line"] == 13].iloc[0]
    assert not row["seen"] and row["duration_s"] == 0
    assert row["t_start_ns"] == got2[got2["line"] == 14]["t_start_ns"].iloc[0]
    with pytest.raises(AlignmentError, match="never shows"):
        blocks_from_lines(t, np.full(len(t), 999), blocks)


def test_line_runs():
    runs = line_runs(np.array([0, 1, 2, 3, 4]), np.array([5, 5, 7, 7, 5]))
    assert runs["line"].tolist() == [5, 7, 5]
    assert runs["t_start_ns"].tolist() == [0, 2, 4] and runs["t_end_ns"].tolist() == [2, 4, 4]


@pytest.mark.parametrize("rate_hz, tol_mm, max_median_s", [(1000.0, 0.01, 0.001), (5.0, 5.0, 0.1)])
def test_geometry_blocks_match_line_truth(motion, rate_hz, tol_mm, max_median_s):
    ax = motion.axes(rate_hz, phase_ns=0 if rate_hz > 100 else 91_000_000)
    t = ax["t_ns"].to_numpy()
    p = ax[["x_mm", "y_mm", "z_mm"]].to_numpy()
    span = motion_span(t, p, acc_mm_s2=1000.0)
    m = match_cl_points(motion.v, t, p, config=MatchConfig(tol_mm=tol_mm))
    blocks = _blocks(motion)
    geo = blocks_from_geometry(blocks, m.t_ns[1:], m.t_depart_ns[1:], span=span)
    tl, line = _line_stream(motion, 1000.0)
    truth = blocks_from_lines(tl, line, blocks, span=motion_span(tl, motion.positions(tl)))
    cmp = compare_blocks(truth, geo, servo_period_s=0.001)
    assert cmp["blocks"] == len(blocks)
    assert cmp["duration_err_median_s"] <= max_median_s
    assert (geo["t_end_ns"].iloc[-1] - geo["t_start_ns"].iloc[0]) / 1e9 == pytest.approx(motion.motion_s, rel=0.005)
