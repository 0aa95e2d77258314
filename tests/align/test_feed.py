import numpy as np
import pandas as pd
import pytest

from align_synth import Motion, zigzag
from feedlog.align.feed import FeedSmoothing, feed_at, feed_from_positions, moving_average, path_length
from feedlog.errors import AlignmentError


@pytest.fixture(scope="module")
def motion():
    # long 60 mm passes at 3000 mm/min, 1000 mm/s^2: 0.05 s ramps, ~1.1 s cruise per pass
    return Motion(zigzag(passes=4, length=60.0, step=5.0), feed_mm_min=3000.0)


def _cruise_mask(motion, t_ns, margin_s):
    ts = (t_ns - motion.t0_ns) / 1e9
    k = np.clip(np.searchsorted(motion.arrival_s, ts, side="right") - 1, 0, len(motion.durations) - 1)
    tau = ts - motion.arrival_s[k]
    ramp = motion.feed / motion.acc
    long = motion.lengths[k] > 20
    return long & (tau > ramp + margin_s) & (tau < motion.durations[k] - ramp - margin_s) & (ts > motion.lead_s)


def test_feed_at_1khz_with_quantisation_and_jitter(motion):
    ax = motion.axes(1000.0, jitter_ns=50_000)
    q = 0.001  # 1 um encoder steps
    pos = (ax[["x_mm", "y_mm", "z_mm"]] / q).round() * q
    f = feed_from_positions(ax["t_ns"].to_numpy(), pos)
    truth = motion.speed(ax["t_ns"].to_numpy())
    cruise = _cruise_mask(motion, ax["t_ns"].to_numpy(), 0.01)
    err = np.abs(f["feed_mm_min"].to_numpy() - truth)
    assert err[cruise].max() < 0.02 * 3000  # within 2 % in cruise despite quantisation + jitter
    assert np.median(err) < 15.0  # and close everywhere (ramps included): 4 ms window bias is small
    # per-axis feeds carry the sign of the motion: first pass along +x, second along -x
    vx = f["vx_mm_min"].to_numpy()
    ts = (ax["t_ns"].to_numpy() - motion.t0_ns) / 1e9
    assert vx[np.argmin(np.abs(ts - (motion.arrival_s[0] + 0.6)))] == pytest.approx(3000, rel=0.02)
    assert vx[np.argmin(np.abs(ts - (motion.arrival_s[2] + 0.6)))] == pytest.approx(-3000, rel=0.02)


def test_feed_at_5hz(motion):
    ax = motion.axes(5.0, phase_ns=41_000_000)
    t = ax["t_ns"].to_numpy()
    f = feed_from_positions(t, ax[["x_mm", "y_mm", "z_mm"]])
    cruise = _cruise_mask(motion, t, 0.2)
    assert cruise.sum() >= 8
    np.testing.assert_allclose(f["feed_mm_min"].to_numpy()[cruise], 3000.0, rtol=0.01)
    # the integral of the feed over time equals the sampled path length (no systematic bias); at 5 Hz
    # that chord path cuts the exact-stop corners, so it is shorter than the program
    dist = np.trapezoid(f["feed_mm_min"].to_numpy() / 60.0, t / 1e9)
    assert dist == pytest.approx(path_length(ax[["x_mm", "y_mm", "z_mm"]].to_numpy())[-1], rel=0.01)
    assert 0.9 * motion.lengths.sum() < dist < motion.lengths.sum()


def test_moving_average_exact_on_linear_signal_with_uneven_time():
    t = np.cumsum(np.random.default_rng(4).integers(500_000, 1_500_000, 200)).astype(np.int64)
    v = 3.0 * t / 1e9 + 1.0
    m = moving_average(t, v, 10_000_000)
    inner = (t > t[0] + 5_000_000) & (t < t[-1] - 5_000_000)
    np.testing.assert_allclose(m[inner], v[inner], rtol=1e-9)


def test_bad_input():
    t = np.arange(5, dtype=np.int64) * 1_000_000
    with pytest.raises(AlignmentError, match="x_mm"):
        feed_from_positions(t, pd.DataFrame({"q": np.zeros(5)}))
    with pytest.raises(AlignmentError, match="not finite"):
        feed_from_positions(t, np.array([[0, 0, 0], [1, 0, 0], [np.nan, 0, 0], [3, 0, 0], [4, 0, 0]], float))
    with pytest.raises(AlignmentError, match="window_s"):
        FeedSmoothing(window_s=0)


@pytest.mark.parametrize("rate_hz, jitter", [(1000.0, 80_000), (5.0, 0)])
def test_feed_at_queries_equals_the_full_series_at_samples(motion, rate_hz, jitter):
    ax = motion.axes(rate_hz, jitter_ns=jitter, seed=5)
    t = ax["t_ns"].to_numpy()
    full = feed_from_positions(t, ax)
    pick = np.random.default_rng(1).choice(len(t), min(60, len(t) - 2), replace=False)
    pick = np.concatenate([pick, [0, len(t) - 1]])
    at = feed_at(t, ax, t[pick])
    for col in ("feed_mm_min", "vx_mm_min", "vy_mm_min", "vz_mm_min"):
        np.testing.assert_allclose(at[col].to_numpy(), full[col].to_numpy()[pick], atol=1e-6, rtol=1e-9)
    # between samples it is the same estimator centred at the query: close to interpolating the series
    # at 1 kHz; at 5 Hz it is the mean speed of the interval itself (no averaging with its neighbours)
    mid = (t[10:-10:7] + t[11:-9:7]) // 2
    at_mid = feed_at(t, ax, mid)["feed_mm_min"].to_numpy()
    if rate_hz > 100:
        interp = np.interp(mid, t, full["feed_mm_min"].to_numpy())
        assert np.median(np.abs(at_mid - interp)) < 20.0
    else:
        i = np.searchsorted(t, mid)
        chord = np.linalg.norm(ax[["x_mm", "y_mm", "z_mm"]].to_numpy()[i] - ax[["x_mm", "y_mm", "z_mm"]].to_numpy()[i - 1], axis=1)
        np.testing.assert_allclose(at_mid, chord / ((t[i] - t[i - 1]) / 1e9) * 60.0, rtol=1e-9)
