"""Noisy, quantised, jittery and sparse measurements of a simulated run (feedlog.sim as the truth)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feedlog.align import align_recording
from feedlog.align.blocks import compare_blocks
from feedlog.ingest import Recording
from feedlog.sim import MeasurementModel, measure, simulate
from feedlog.toolpath import parse_program

PROGRAM = Path(__file__).resolve().parents[2] / "recordings" / "programs" / "corners_f3000_p001.ngc"


@pytest.fixture(scope="module")
def run():
    if not PROGRAM.exists():
        pytest.skip(f"{PROGRAM} not present")
    text = PROGRAM.read_text()
    prog = parse_program(text, name=PROGRAM.name)
    return text, prog, simulate(prog, "linuxcnc-xyz")


def _logged(sim, text: str, rate_hz: float, noise_mm: float, quantum_mm: float, jitter_s: float, seed: int):
    """A logger at rate_hz that runs 0.5 s before and after the motion, with noise and quantisation."""
    rec = measure(sim, MeasurementModel(rate_hz=rate_hz, jitter_s=jitter_s), program_text=text)
    axes = rec.stream("axes")
    period = int(round(1e9 / rate_hz))
    n = int(0.5e9 // period)
    t = axes["t_ns"].to_numpy()
    final = sim.series.iloc[-1]  # the logger keeps logging: the machine rests at the final position
    head = axes.iloc[[0] * n].assign(t_ns=t[0] - np.arange(n, 0, -1) * period)
    tail = pd.DataFrame({"t_ns": t[-1] + np.arange(1, n + 1) * period,
                         **{c: np.full(n, final[c]) for c in ("x_mm", "y_mm", "z_mm")}})
    axes = pd.concat([head, axes, tail], ignore_index=True)
    rng = np.random.default_rng(seed)
    for c in ("x_mm", "y_mm", "z_mm"):
        v = axes[c].to_numpy() + rng.normal(0.0, noise_mm, len(axes))
        axes[c] = np.round(v / quantum_mm) * quantum_mm if quantum_mm else v
    return Recording(streams={"axes": axes}, metadata={}, attachments={"program.ngc": text.encode()},
                     source=f"sim@{rate_hz:g}Hz")


@pytest.mark.parametrize("rate_hz, noise_mm, quantum_mm, jitter_s, cycle_tol_s, block_tol_s", [
    (1000.0, 0.0, 0.001, 0.0, 0.003, 0.001),
    (1000.0, 0.002, 0.001, 0.0001, 0.01, 0.003),
    (100.0, 0.002, 0.0, 0.0, 0.02, 0.01),
    (5.0, 0.002, 0.001, 0.0, 0.03, 0.1),
])
def test_cycle_and_block_times_survive_measurement_errors(run, rate_hz, noise_mm, quantum_mm, jitter_s,
                                                          cycle_tol_s, block_tol_s):
    text, prog, sim = run
    rec = _logged(sim, text, rate_hz, noise_mm, quantum_mm, jitter_s, seed=7)
    a = align_recording(rec, prog, profile="linuxcnc-xyz")
    assert a.cycle_time_s == pytest.approx(sim.cycle_time_s, abs=cycle_tol_s)
    cmp = compare_blocks(sim.blocks.assign(seen=True), a.blocks)
    assert cmp["duration_err_median_s"] <= block_tol_s, cmp
    if noise_mm:
        assert a.report["still_mm"] > 3 * noise_mm  # the standstill threshold followed the noise


def test_a_long_noisy_standstill_mid_program_does_not_lose_the_tool():
    # a 3 s hold (a tool change) at 1 kHz with 2 um noise lays ~10 mm of jitter into the measured
    # path length; the progress window of the next points must still find the tool where it went on
    text = PROGRAM.read_text()
    lines = text.splitlines(keepends=True)
    feeds = [i for i, line in enumerate(lines) if line.startswith("G1 ")]
    lines.insert(feeds[5] + 1, "G4 P3\n")
    held = "".join(lines)
    prog = parse_program(held, name="held.ngc")
    sim = simulate(prog, "linuxcnc-xyz")
    rec = _logged(sim, held, 1000.0, 0.002, 0.001, 0.0, seed=3)
    a = align_recording(rec, prog, profile="linuxcnc-xyz")
    assert a.cycle_time_s == pytest.approx(sim.cycle_time_s, abs=0.01)
    cmp = compare_blocks(sim.blocks.assign(seen=True), a.blocks)
    assert cmp["duration_err_median_s"] <= 0.003, cmp


def test_noise_steps_mark_only_a_noisy_standstill():
    from feedlog.align.match import noise_steps

    rng = np.random.default_rng(0)
    still = np.zeros((2000, 3))
    moving = np.c_[np.arange(2000) * 0.05, np.zeros(2000), np.zeros(2000)]   # 50 mm/s at 1 kHz
    p = np.vstack([moving, moving[-1] + still, moving[-1] + moving]) + rng.normal(0, 0.002, (6000, 3))
    mask = noise_steps(p, 1e-3)
    assert mask[2100:3900].all() and not mask[100:1900].any() and not mask[4100:5900].any()
    assert noise_steps(np.vstack([moving, moving[-1] + still]), 1e-3) is None   # noise-free: nothing to do
    assert noise_steps(p[::200], 0.2) is None                                    # sparse: left alone
