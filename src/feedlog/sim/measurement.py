"""Measurement model: what a data logger would record of a simulated run.

Turns a `SimResult` into a `feedlog.recording.Recording` with the standard streams `axes`,
`feed` and `line` (and `joints` when the machine has five-axis kinematics or the profile models
feedback: `jN_pos` commanded, `jN_pos_fb` through the feedback mechanisms), sampled at `rate_hz`
(5 Hz .. 1 kHz) with a constant latency (the logger sees the motion `latency_s` late), Gaussian
timestamp jitter, position quantisation (encoder or fieldbus resolution) and Gaussian measurement
noise. Continuous channels (positions, feed) are interpolated, the executing line holds its last
value (shown late by the profile's `logger_latency`). Noise and quantisation apply to measured
positions (axes, joint feedback), not to the joint commands. Deterministic for a given `seed`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from feedlog.errors import SimulationError
from feedlog.recording import PROFILE_ATTACHMENT, PROGRAM_ATTACHMENT, Recording
from feedlog.sim.simulate import SimResult

MIN_RATE_HZ, MAX_RATE_HZ = 5.0, 1000.0


@dataclass(frozen=True)
class MeasurementModel:
    rate_hz: float = 1000.0
    latency_s: float = 0.0
    jitter_s: float = 0.0            # standard deviation of the sample time error
    quantum_mm: float = 0.0          # position resolution (0: none); rotary axes use quantum_deg
    quantum_deg: float = 0.0
    noise_mm: float = 0.0            # standard deviation of position noise
    noise_deg: float = 0.0
    feed_noise_mm_min: float = 0.0
    rest_s: float = 0.0              # standstill recorded before the motion starts and after it ends
    seed: int = 0

    def __post_init__(self) -> None:
        if not MIN_RATE_HZ <= self.rate_hz <= MAX_RATE_HZ:
            raise SimulationError(f"measurement rate_hz must be within {MIN_RATE_HZ:g}..{MAX_RATE_HZ:g}, "
                                  f"got {self.rate_hz}")
        for name in ("latency_s", "jitter_s", "quantum_mm", "quantum_deg", "noise_mm", "noise_deg",
                     "feed_noise_mm_min", "rest_s"):
            if not getattr(self, name) >= 0:
                raise SimulationError(f"measurement {name} must be >= 0, got {getattr(self, name)}")
        if self.jitter_s >= 0.5 / self.rate_hz:
            raise SimulationError(f"measurement jitter_s ({self.jitter_s}) must stay below half the sample "
                                  f"period ({0.5 / self.rate_hz:g} s) so samples keep their order")


def measure(result: SimResult, model: MeasurementModel | None = None, *, program_text: str | None = None,
            start_time_ns: int = 0, notes: str = "") -> Recording:
    """A recording of `result` as the measurement `model` describes it."""
    model = model or MeasurementModel()
    series = result.series
    rng = np.random.default_rng(model.seed)
    t_sim = series["t_ns"].to_numpy(np.int64) / 1e9
    if not len(t_sim):
        raise SimulationError("the simulation produced no samples to measure")
    period = 1.0 / model.rate_hz
    n = int(np.floor((t_sim[-1] + model.latency_s + 2 * model.rest_s) / period)) + 1
    t_nominal = np.arange(n) * period - model.rest_s   # positions hold before the start and after the end
    t_log = t_nominal + (rng.normal(0.0, model.jitter_s, n) if model.jitter_s > 0 else 0.0)
    t_log = np.maximum.accumulate(np.clip(t_log, -model.rest_s, None))
    t_seen = t_log - model.latency_s   # the motion state the logger actually captures
    t_ns = (start_time_ns + np.rint((t_log + model.rest_s) * 1e9)).astype(np.int64)

    def measured(values: np.ndarray, rotary: bool) -> np.ndarray:
        sigma = model.noise_deg if rotary else model.noise_mm
        if sigma > 0:
            values = values + rng.normal(0.0, sigma, n)
        q = model.quantum_deg if rotary else model.quantum_mm
        if q > 0:
            values = np.round(values / q) * q
        return values

    axes_cols = [c for c in series.columns if c.endswith("_mm") or c.endswith("_deg")]
    axes = {"t_ns": t_ns}
    for col in axes_cols:
        axes[col] = measured(np.interp(t_seen, t_sim, series[col].to_numpy(np.float64)), col.endswith("_deg"))
    feed = np.interp(t_seen, t_sim, series["feed_mm_min"].to_numpy(np.float64))
    if model.feed_noise_mm_min > 0:
        feed = np.clip(feed + rng.normal(0.0, model.feed_noise_mm_min, n), 0.0, None)
    lag = next((m.line_s for m in result.mechanisms if m.name == "logger_latency"), 0.0)
    held = np.clip(np.searchsorted(t_sim, t_seen - lag, side="right") - 1, 0, len(t_sim) - 1)
    line = series["line"].to_numpy(np.int64)[held]

    streams = {"axes": pd.DataFrame(axes), "feed": pd.DataFrame({"t_ns": t_ns, "feed_mm_min": feed}),
               "line": pd.DataFrame({"t_ns": t_ns, "line": line})}
    joints = result.feedback   # commanded and feedback joint positions, when the profile models feedback
    if joints is None:
        joints = result.joints  # five-axis kinematics: machine joint positions
    if joints is not None:  # sampled the same way as the axes
        jt = joints["t_ns"].to_numpy(np.int64) / 1e9
        rotary_joint = {f"j{i}": a not in ("x", "y", "z") for i, a in enumerate(result.profile.axis_names)}
        table = {"t_ns": t_ns}
        for c in joints.columns[1:]:
            values = np.interp(t_seen, jt, joints[c].to_numpy(np.float64))
            # feedback is measured (noise, resolution); the command is a number the controller computed
            table[c] = measured(values, rotary_joint.get(c.split("_")[0], False)) if c.endswith("_fb") else values
        streams["joints"] = pd.DataFrame(table)
    profile = result.profile
    metadata = {"machine": profile.name, "controller": f"feedlog.sim ({profile.controller or 'simulated'})",
                "units": "mm", "nominal_rate_hz": f"{model.rate_hz:g}", "start_time": str(start_time_ns),
                "notes": notes or (f"simulated; latency {model.latency_s:g} s, jitter {model.jitter_s:g} s, "
                                   f"quantum {model.quantum_mm:g} mm, noise {model.noise_mm:g} mm, seed {model.seed}")}
    attachments = {PROFILE_ATTACHMENT: profile.to_toml().encode()}
    if program_text is not None:
        attachments[PROGRAM_ATTACHMENT] = program_text.encode()
    return Recording(streams=streams, metadata=metadata, attachments=attachments, source="feedlog.sim")
