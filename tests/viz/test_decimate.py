"""The demo's downsampled series draw what the full series draws: every peak and valley per pixel
column survives, within one vertical step (a series' range / rows)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from feedlog.viz.decimate import linear_keep, minmax_keep, rate_keep, spacing_keep


def stride_keep(n, count):
    """The naive decimation: `count` evenly spaced samples."""
    keep = np.zeros(n, dtype=bool)
    keep[np.linspace(0, n - 1, count).round().astype(np.int64)] = True
    return keep


def drawn_extremes(t, values, keep, columns):
    """Per pixel column: lowest and highest value of the line drawn through the kept samples, and of
    the full series (the line evaluated at every sample's time: that is what lands in the column)."""
    drawn = np.interp(t, t[keep], values[keep])
    col = np.minimum(((t - t[0]) * (columns / (t[-1] - t[0]))).astype(np.int64), columns - 1)
    out = []
    for c in np.unique(col):
        inside = col == c
        out.append((drawn[inside].min(), drawn[inside].max(), values[inside].min(), values[inside].max()))
    return np.array(out)


def noisy_feed(seed=3, n=60_000):
    """A 1 kHz measured feed: ramps, a held feed with encoder noise, a slow wave; one-sample spike and
    dip hidden in the noise at random places."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 1_000_000.0  # ns
    feed = np.interp(np.arange(n), [0, 3000, 20_000, 23_000, 40_000, n - 1], [0, 2000, 2000, 800, 800, 0])
    feed = feed + 300 * np.sin(np.arange(n) / 4000.0) + rng.normal(0, 4.0, n)
    spike, dip = rng.integers(5000, n - 5000, size=2)
    feed[spike] += 900.0
    feed[dip] -= 700.0
    return t, feed, int(spike), int(dip)


def test_hidden_spike_and_dip_survive_and_the_series_shrinks():
    t, feed, spike, dip = noisy_feed()
    keep = linear_keep(t, feed, columns=1000, rows=1000)
    assert keep[spike] and keep[dip]
    assert keep[0] and keep[-1]
    assert keep.sum() <= 4 * 1000 < len(feed) / 10
    # the same number of evenly spaced samples misses them: the check above can fail
    naive = stride_keep(len(feed), int(keep.sum()))
    assert not (naive[spike] and naive[dip])


def test_every_pixel_column_keeps_its_extremes_within_one_step():
    t, feed, _, _ = noisy_feed(seed=11)
    tol = np.ptp(feed) / 1000
    for keep in (linear_keep(t, feed, 1000, 1000), minmax_keep(t, feed, 1000)):
        ext = drawn_extremes(t, feed, keep, 1000)
        assert np.all(np.abs(ext[:, 0] - ext[:, 2]) <= tol + 1e-9)
        assert np.all(np.abs(ext[:, 1] - ext[:, 3]) <= tol + 1e-9)
    # a decimation that only keeps evenly spaced samples does not: the check can fail
    naive = stride_keep(len(feed), int(linear_keep(t, feed, 1000, 1000).sum()))
    ext = drawn_extremes(t, feed, naive, 1000)
    assert np.abs(ext[:, 1] - ext[:, 3]).max() > 10 * tol


def test_straight_pieces_keep_only_their_ends():
    t = np.arange(30_000) * 1e6
    trapezoid = np.interp(np.arange(30_000), [0, 5000, 25_000, 29_999], [0.0, 3000.0, 3000.0, 0.0])
    keep = linear_keep(t, trapezoid, 1000, 1000)
    assert keep.sum() <= 100  # of 30 000: the corners split the aligned column groups, nothing else
    ext = drawn_extremes(t, trapezoid, keep, 1000)
    assert np.abs(ext[:, :2] - ext[:, 2:]).max() <= 3000 / 1000


def test_short_series_and_flat_series_are_kept_whole_or_as_ends():
    t = np.arange(100) * 1e6
    assert linear_keep(t, np.sin(t), 1000).all()  # fewer than 4 per column: nothing to drop
    assert minmax_keep(np.zeros(5000), np.arange(5000.0), 10).all()  # no time span
    flat = linear_keep(np.arange(50_000) * 1e6, np.full(50_000, 1500.0), 1000)
    assert flat[0] and flat[-1] and flat.sum() <= 4


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 6000), columns=st.integers(1, 400),
       rows=st.integers(1, 2000), scale=st.floats(1e-6, 1e6))
def test_fuzz_drawn_extremes_hold_for_any_series(seed, n, columns, rows, scale):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.integers(1, 3, n)).astype(np.float64) * 1e6
    values = np.cumsum(rng.normal(0, scale, n)) * rng.integers(0, 2, n)  # random walk with flat stretches
    keep = linear_keep(t, values, columns, rows)
    assert keep[0] and keep[-1]
    if keep.all():
        return
    tol = np.ptp(values) / rows
    ext = drawn_extremes(t, values, keep, columns)
    slack = tol + 1e-9 * max(1.0, np.abs(values).max())
    assert np.all(np.abs(ext[:, :2] - ext[:, 2:]) <= slack)


def test_path_points_one_per_pixel_along_the_path():
    s = np.linspace(0, 2 * np.pi, 20_000)
    circle = np.c_[50 * np.cos(s), 50 * np.sin(s), np.zeros_like(s)]
    still = np.repeat(circle[-1:], 5000, axis=0)  # a standstill at the end: one point for it
    xyz = np.r_[circle, still]
    keep = spacing_keep(xyz, columns=1000)
    kept = xyz[keep]
    gaps = np.linalg.norm(np.diff(kept, axis=0), axis=1)
    step = np.linalg.norm(np.diff(circle, axis=0), axis=1).max()
    assert gaps[:-1].max() <= 100 / 1000 + step  # never more than a pixel (and one sample) apart along the path
    assert 2 * np.pi * 50 / 0.1 * 0.9 < keep.sum() < 2 * np.pi * 50 / 0.1 * 1.1
    assert keep[-1] and keep[20_000:-1].sum() == 0


def test_the_moving_tool_keeps_one_position_per_display_frame():
    t = np.cumsum(np.full(10_000, 1_000_000, dtype=np.int64))  # 10 s at 1 kHz
    keep = rate_keep(t, 60.0)  # at 60 Hz
    assert keep[0] and keep[-1] and 600 <= keep.sum() <= 602
    assert np.diff(t[keep][:-1]).max() <= 1e9 / 60 + 1_000_000


def test_cloud_spacing_never_below_the_smallest_step():
    s = np.linspace(0, 10.0, 10_001)  # a 10 mm line sampled every 1 um: a pixel of it is 10 um
    xyz = np.c_[s, np.zeros_like(s), np.zeros_like(s)]
    assert 60 <= spacing_keep(xyz, 1000, min_step=0.15).sum() <= 70   # every 0.15 mm
    assert 30 <= spacing_keep(xyz, 1000, min_step=0.3).sum() <= 36    # every 0.3 mm: touching 0.15 mm spheres
    assert 990 <= spacing_keep(xyz, 1000).sum() <= 1002              # every pixel
