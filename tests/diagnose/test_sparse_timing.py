"""Sparse recordings (5 Hz) as the timing level compares them: what the samples show, not where a
model placed motion start and end, and a noise floor from what does not cancel."""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd
import pytest

from feedlog.diagnose.cases import MIN_SIGMA_S, sampled_sigma
from feedlog.diagnose.engine import DiagnoseConfig, diagnose


def _ends_in_motion(rec):
    """The recording as a logger that stopped with the program saw it: nothing after the last sample
    that shows the tool moving."""
    out = copy.copy(rec)
    axes = rec.streams["axes"]
    pos = axes[["x_mm", "y_mm", "z_mm"]].to_numpy()
    moving = np.flatnonzero(np.linalg.norm(pos - pos[-1], axis=1) > 0.05)
    t_last = int(axes["t_ns"].iloc[moving[-1]])
    out.streams = {k: (v[v["t_ns"] <= t_last].reset_index(drop=True) if "t_ns" in v.columns else v)
                   for k, v in rec.streams.items()}
    return out


def test_a_5_hz_recording_that_ends_in_motion_is_compared_up_to_its_last_sample(hidden):
    """The motion end falls after the last sample, where only a model could place it: the cycle is
    compared from the first to the last moving sample, the last one's distance taken from the program's
    end point. The unchanged machine then shows no cycle error and no finding."""
    recs = [_ends_in_motion(r) for r in hidden("control_5hz", rate_hz=5.0)]
    dx = diagnose(recs, "linuxcnc-xyz", config=DiagnoseConfig(learned=False))
    rows = dx.levels["cycle"]["recordings"]
    assert [r["span"] for r in rows] == ["moving samples"] * len(rows)
    assert all(abs(r["error_before_pct"]) < 0.3 for r in rows), rows
    assert all(c.span_samples[1] is not None and c.span_samples[1][1] > 0.05 for c in dx.cases)
    assert dx.findings == [] and dx.unexplained == []


def _axes(t_s: np.ndarray, speed: float = 50.0) -> pd.DataFrame:
    return pd.DataFrame({"t_ns": (t_s * 1e9).astype(np.int64), "x_mm": speed * t_s, "y_mm": 0.0, "z_mm": 0.0})


def test_the_sparse_noise_floor_comes_from_timestamp_jitter_and_position_noise():
    t = np.arange(0.0, 10.0, 0.2)
    exact = sampled_sigma(_axes(t), 0, 10.0, still_mm=0.005)
    assert exact == pytest.approx(MIN_SIGMA_S)              # exact instants, 0.1 ms of noise: the minimum
    rng = np.random.default_rng(1)
    jittered = sampled_sigma(_axes(t + rng.normal(0.0, 0.01, len(t))), 0, 10.0, still_mm=0.005)
    assert 0.005 < jittered < 0.02                          # ~10 ms of timestamp jitter
    slow = sampled_sigma(_axes(t, speed=1.0), 0, 10.0, still_mm=0.005)
    assert slow == pytest.approx(0.005, rel=0.05)           # 5 um of noise at 1 mm/s
