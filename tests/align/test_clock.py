import numpy as np
import pytest

from align_synth import Motion, zigzag
from feedlog.align.clock import estimate_offset, event_offset
from feedlog.align.feed import feed_from_positions
from feedlog.errors import AlignmentError


@pytest.fixture(scope="module")
def motion():
    return Motion(zigzag(passes=6, length=30.0), feed_mm_min=2400.0, lead_s=0.3, tail_s=0.3)


@pytest.mark.parametrize("rate_hz, offset_ns", [(1000.0, 37_300_000), (1000.0, -12_700_000), (100.0, 123_000_000)])
def test_synthetic_offset_recovered_within_one_sample(motion, rate_hz, offset_ns):
    # device A: positions at 1 kHz on the reference clock; device B: its own feed export, sampled at
    # rate_hz with jitter, stamped by a clock that runs offset_ns ahead
    a = motion.axes(1000.0)
    fa = feed_from_positions(a["t_ns"].to_numpy(), a[["x_mm", "y_mm", "z_mm"]])
    tb_true = motion.timestamps(rate_hz, jitter_ns=int(0.05e9 / rate_hz), seed=3)
    fb = motion.speed(tb_true)
    est = estimate_offset(fa["t_ns"].to_numpy(), fa["feed_mm_min"].to_numpy(), tb_true + offset_ns, fb,
                          max_offset_ns=500_000_000)
    period = int(1e9 / rate_hz)
    assert abs(est.offset_ns - offset_ns) <= period, est
    assert est.confidence > 0.9


def test_unrelated_signal_has_low_confidence(motion):
    a = motion.axes(1000.0)
    fa = feed_from_positions(a["t_ns"].to_numpy(), a[["x_mm", "y_mm", "z_mm"]])
    noise = np.random.default_rng(0).normal(size=len(a))
    est = estimate_offset(fa["t_ns"].to_numpy(), fa["feed_mm_min"].to_numpy(), a["t_ns"].to_numpy(), noise)
    assert est.confidence < 0.2


def test_constant_signal_refused(motion):
    t = motion.timestamps(100.0)
    with pytest.raises(AlignmentError, match="constant"):
        estimate_offset(t, np.ones(len(t)), t, np.arange(len(t), dtype=float))


def test_event_offset_median_and_confidence():
    rng = np.random.default_rng(2)
    ref = np.sort(rng.integers(0, 10**10, 200))
    other = ref + 4_000_000 + rng.integers(-300_000, 300_001, 200)
    other[:5] += 80_000_000  # a few wrong pairings
    est = event_offset(ref, other)
    assert abs(est.offset_ns - 4_000_000) < 100_000
    assert 0.95 <= est.confidence < 1.0
    with pytest.raises(AlignmentError, match="paired"):
        event_offset(ref, other[:-1])
