"""A scorer's recordings on several processes (`scorer_pool.ScorerPool`): the same residuals as a serial
scorer, bit for bit, and a worker that dies leaves its share to this process."""

from __future__ import annotations

import numpy as np
import pytest

from feedlog.diagnose.scorer_pool import ScorerPool, share_out

PROGRAMS = ("corners_f3000_p001", "pocket_f3000_p001", "mix_020")
HIDDEN = {"axes.x.acc_max": 300.0, "sim.feed_override.override": 0.9}
PROBES = ({"axes.x.acc_max": 330.0}, {"axes.x.acc_max": 300.0, "sim.feed_override.override": 0.9},
          {"axes.y.vel_max": 20.0, "axes.z.acc_max": 150.0}, {"axes.x.acc_max": -5.0})


@pytest.fixture(scope="module")
def prepared(hidden):
    from feedlog.diagnose.engine import load_cases

    return load_cases(hidden("pool3", values=HIDDEN, programs=PROGRAMS), None)


def test_the_costliest_recording_goes_first_to_the_least_loaded_process():
    assert share_out([0, 1, 2], [1.0, 1.0, 2.0], 2) == [[0, 1], [2]]   # a tie: the worker takes it
    assert share_out([0, 2], [1.0, 1.0, 2.0], 2) == [[0], [2]]
    assert share_out([0, 1, 2], [1.5, 1.6, 3.7], 2) == [[1, 0], [2]]
    assert share_out([1], [1.0, 1.0, 2.0], 3) == [[], [1], []]
    assert share_out([0, 1, 2], [3.0, 1.0, 1.0], 3) == [[2], [0], [1]]


def test_a_pool_gives_the_serial_residuals_bit_for_bit(prepared):
    from feedlog.diagnose.fit import Scorer

    profile, cases = prepared
    serial = Scorer(profile, cases, "timing")
    pooled = Scorer(profile, cases, "timing")
    with ScorerPool(pooled, 2) as pool:
        assert pooled.pool is pool and len(pool.workers) == 1 and pool.workers[0][0].is_alive()
        for values in PROBES:
            a, b = serial.residuals(values), pooled.residuals(values)
            assert len(a) == len(b) == len(cases)
            for x, y in zip(a, b):
                assert (x is None and y is None) or np.array_equal(x, y)
            group = pooled.groups[1]
            assert pooled.loss({**values, "axes.z.vel_max": 44.0}, group) == serial.loss(
                {**values, "axes.z.vel_max": 44.0}, group)
        # an invalid profile (a negative limit) is no residual either way; the others are real and differ
        assert all(r is None for r in pooled.residuals(PROBES[-1]))
        assert not np.array_equal(pooled.residuals(PROBES[0])[0], pooled.residuals(PROBES[1])[0])
        assert pooled.simulations == serial.simulations > 0
    assert pooled.pool is None and pool.workers == []


def test_a_worker_that_dies_leaves_its_share_here(prepared):
    from feedlog.diagnose.fit import Scorer

    profile, cases = prepared
    serial = Scorer(profile, cases, "timing")
    pooled = Scorer(profile, cases, "timing")
    with ScorerPool(pooled, 3) as pool:
        assert len(pool.workers) == 2
        pool.workers[0][0].kill()
        pool.workers[0][0].join(5)
        for values in PROBES[:2]:
            for x, y in zip(serial.residuals(values), pooled.residuals(values)):
                assert np.array_equal(x, y)
        assert len(pool.workers) == 1 and pooled.pool is pool
    assert pooled.pool is None


def test_a_pool_slower_than_serial_pauses_and_gives_the_same_residuals(prepared, monkeypatch):
    """Where waking a worker costs more than it saves (a machine busy with other work), the pool pauses
    after `TRIAL` requests and computes here; its pace is judged from the measured costs."""
    from feedlog.diagnose import scorer_pool
    from feedlog.diagnose.fit import Scorer

    profile, cases = prepared
    serial = Scorer(profile, cases, "timing")
    for slower, pauses in ((float("inf"), 0), (0.0, 1)):
        monkeypatch.setattr(scorer_pool, "SLOWER", slower)
        pooled = Scorer(profile, cases, "timing")
        with ScorerPool(pooled, 2) as pool:
            for k in range(scorer_pool.TRIAL + 3):
                values = {"axes.x.acc_max": 250.0 + 5 * k}
                for x, y in zip(serial.residuals(values), pooled.residuals(values)):
                    assert np.array_equal(x, y)
            assert pool.pauses == pauses and np.isfinite(pool.pace) and pool.pace > 0
            assert pool.paused == (scorer_pool.PAUSE - 3 if pauses else 0)
            assert all(c > 0 for c in pool.costs)
