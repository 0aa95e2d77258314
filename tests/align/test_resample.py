import numpy as np
import pandas as pd
import pytest

from feedlog.align.resample import common_timebase, resample, uniform_timebase
from feedlog.align.timing import stream_timing
from feedlog.errors import AlignmentError


def _stream(t_ns, **cols):
    return pd.DataFrame({"t_ns": np.asarray(t_ns, dtype=np.int64), **cols})


def test_continuous_interpolates_and_discrete_holds():
    t = np.arange(0, 10) * 1_000_000
    s = _stream(t, x_mm=np.arange(10) * 2.0, line=np.arange(10, 20, dtype=np.int64))
    target = np.array([500_000, 2_250_000, 8_999_999])
    r = resample(s, target, anti_alias=False)
    np.testing.assert_allclose(r.table["x_mm"], [1.0, 4.5, 17.999998])
    assert r.table["line"].tolist() == [10, 12, 18]
    assert r.table["line"].dtype == np.int64


def test_gaps_are_nan_and_reported_never_bridged():
    t = np.concatenate([np.arange(0, 10), np.arange(50, 60)]) * 1_000_000
    s = _stream(t, x_mm=np.arange(20.0), line=np.arange(20, dtype=np.int64))
    grid = uniform_timebase(0, 59_000_000, 1_000_000)
    r = resample(s, grid)
    x = r.table["x_mm"].to_numpy()
    assert r.in_gap == 40  # 10..49 ms lie strictly inside the gap (9, 50)
    assert np.isnan(x[10:50]).all() and np.isfinite(x[:10]).all() and np.isfinite(x[50:]).all()
    assert r.report["source"]["gaps"] == 1
    outside = resample(s, np.array([-5, 70_000_000]))
    assert outside.outside == 2 and np.isnan(outside.table["x_mm"]).all()


def test_jitter_and_gaps_measured():
    rng = np.random.default_rng(1)
    t = np.arange(1000) * 1_000_000 + rng.integers(-50_000, 50_001, 1000)
    t = np.sort(t)
    t[500:] += 10_000_000
    timing = stream_timing(t)
    assert abs(timing.period_ns - 1_000_000) < 10_000
    assert 20_000 < timing.jitter_ns < 60_000
    assert timing.gaps == 1 and timing.first_gap_index == 499
    assert timing.largest_gap_ns > 10_000_000


def test_anti_alias_filter_on_downsampling():
    # 1 kHz: slow ramp + 98 Hz ripple; resampled at 5 Hz the ripple must not alias into the result
    t = np.arange(0, 20_000) * 1_000_000
    ts = t / 1e9
    ripple = 0.5 * np.sin(2 * np.pi * 98.0 * ts)
    s = _stream(t, x_mm=10.0 * ts + ripple)
    grid = uniform_timebase(1_000_000_000, 19_000_000_000, 200_000_000) + 3_000_000
    filtered = resample(s, grid).table["x_mm"].to_numpy() - 10.0 * grid / 1e9
    naive = resample(s, grid, anti_alias=False).table["x_mm"].to_numpy() - 10.0 * grid / 1e9
    assert np.abs(naive).max() > 0.3          # point sampling catches the ripple
    assert np.abs(filtered).max() < 0.02      # the filter removed it, the ramp survived


def test_common_timebase_overlap_and_errors():
    a = _stream(np.arange(0, 100) * 1_000_000, x_mm=np.zeros(100))
    b = _stream(np.arange(20, 300) * 500_000 + 5_000_000, x_mm=np.zeros(280))
    grid = common_timebase([a, b])
    assert grid[0] == 15_000_000 and grid[-1] <= 99_000_000
    assert np.all(np.diff(grid) == 500_000)
    c = _stream(np.arange(200, 300) * 1_000_000, x_mm=np.zeros(100))
    with pytest.raises(AlignmentError, match="do not overlap"):
        common_timebase([a, c])
    with pytest.raises(AlignmentError, match="no column"):
        resample(a, grid, columns=["y_mm"])


def test_timing_without_gaps_or_duplicates_matches_the_general_measure():
    # a jittered stream with neither gaps nor repeated timestamps takes stream_timing's short path:
    # its figures must be those of the general definition (over the positive, non-gap intervals)
    rng = np.random.default_rng(7)
    t = np.cumsum(rng.integers(700_000, 1_300_001, 2000)).astype(np.int64)
    timing = stream_timing(t)
    dt = np.diff(t)
    period = int(np.median(dt))
    assert timing.period_ns == period
    assert timing.jitter_ns == pytest.approx(float(np.std(dt)), rel=1e-12)
    assert timing.max_jitter_ns == int(np.abs(dt - period).max())
    assert (timing.gaps, timing.duplicates, timing.largest_gap_ns, timing.first_gap_index) == (0, 0, 0, -1)
    # one repeated timestamp: the general path, the zero interval counted and kept out of the jitter
    t2 = np.insert(t, 1000, t[1000])
    dup = stream_timing(t2)
    assert dup.duplicates == 1 and dup.gaps == 0
    assert dup.jitter_ns == pytest.approx(float(np.std(np.diff(t2)[np.diff(t2) > 0])), rel=1e-12)
