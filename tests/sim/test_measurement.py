"""Measurement model: rate, latency, jitter, quantisation, noise, determinism, recording format."""

from __future__ import annotations

import numpy as np
import pytest

from feedlog.errors import SimulationError
from feedlog.ingest.recording import PROFILE_ATTACHMENT, Recording
from feedlog.sim import MeasurementModel, measure, simulate

PROGRAM = "G21 G90 G61\nG1 X40 F3000\nG1 Y20\n"


@pytest.fixture
def result(plain, gcode):
    return simulate(gcode(PROGRAM), plain)


def test_standard_streams_at_the_requested_rate(result):
    rec = measure(result, MeasurementModel(rate_hz=50))
    assert isinstance(rec, Recording)
    assert set(rec.streams) == {"axes", "feed", "line"}
    t = rec.stream("axes")["t_ns"].to_numpy()
    assert np.allclose(np.diff(t), 20_000_000)
    assert list(rec.stream("axes").columns) == ["t_ns", "x_mm", "y_mm", "z_mm"]
    assert rec.metadata["nominal_rate_hz"] == "50" and PROFILE_ATTACHMENT in rec.attachments
    assert set(rec.stream("line")["line"]) <= set(result.series["line"])


def test_latency_delays_what_is_seen(result):
    plain_rec = measure(result, MeasurementModel(rate_hz=1000))
    late = measure(result, MeasurementModel(rate_hz=1000, latency_s=0.1))
    x0 = plain_rec.stream("axes")["x_mm"].to_numpy()
    x1 = late.stream("axes")["x_mm"].to_numpy()
    assert np.allclose(x1[100:600], x0[:500], atol=1e-9)


def test_quantisation_noise_and_jitter(result):
    rec = measure(result, MeasurementModel(rate_hz=200, quantum_mm=0.01))
    x = rec.stream("axes")["x_mm"].to_numpy()
    assert np.allclose(np.round(x / 0.01) * 0.01, x)
    clean = measure(result, MeasurementModel(rate_hz=200)).stream("axes")["y_mm"].to_numpy()
    noisy = measure(result, MeasurementModel(rate_hz=200, noise_mm=0.005, seed=3)).stream("axes")["y_mm"].to_numpy()
    assert np.std(noisy - clean) == pytest.approx(0.005, rel=0.2)
    jit = measure(result, MeasurementModel(rate_hz=200, jitter_s=0.0005, seed=3)).stream("axes")["t_ns"].to_numpy()
    dt = np.diff(jit)
    assert dt.std() > 1e5 and (dt >= 0).all()


def test_deterministic_for_a_seed(result):
    m = MeasurementModel(rate_hz=100, noise_mm=0.01, jitter_s=0.001, seed=7)
    a, b = measure(result, m), measure(result, m)
    assert a.stream("axes").equals(b.stream("axes"))
    c = measure(result, MeasurementModel(rate_hz=100, noise_mm=0.01, jitter_s=0.001, seed=8))
    assert not a.stream("axes").equals(c.stream("axes"))


@pytest.mark.parametrize("kwargs", [{"rate_hz": 2}, {"rate_hz": 5000}, {"noise_mm": -1}, {"rate_hz": 100, "jitter_s": 0.01}])
def test_bad_models_raise(kwargs):
    with pytest.raises(SimulationError):
        MeasurementModel(**kwargs)


def test_five_axis_recording_has_joints(make_machine, gcode):
    prof = make_machine(five_axis=True)
    res = simulate(gcode("G21 G90 G61\nF1200\nG1 X10 C90\n"), prof)
    rec = measure(res, MeasurementModel(rate_hz=100))
    joints = rec.stream("joints")
    assert list(joints.columns) == ["t_ns", "j0_pos", "j1_pos", "j2_pos", "j3_pos", "j4_pos"]
    # table rotated 90 deg about C: the workpiece point (10, 0) is at machine (0, 10)
    assert joints[["j0_pos", "j1_pos"]].iloc[-1].to_numpy() == pytest.approx([0.0, 10.0], abs=1e-6)
