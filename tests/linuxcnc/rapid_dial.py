"""Programs for LinuxCNC's rapid dial and the comparison of a recording with the simulation line by line
(tests/linuxcnc/test_linuxcnc_rapid_dial.py and benchmarks/bench_rapid_dial.py).

`G0_G1`: rapids (single-axis, XY and XYZ diagonals) into and out of G1 moves (F4000) under G64 P0.01,
G61 and G64 P0.1. `ZIG`: chains of rapids blended under G64 P1 (rapid-to-rapid blend arcs) with a G1 pair between.
The XYZ diagonals ask for more than the 100 mm/s TRAJ cap at 100 % (their axis-limited speed is up to
133 mm/s), so the dial's place before or after that cap shows in their times.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.ingest import read_recording
from feedlog.sim import simulate
from feedlog.toolpath import parse_program
from tests.sim.test_linuxcnc_accuracy import _line_times_ms

G0_G1 = """G21 G90 G64 P0.01
G0 X0 Y0 Z5
G0 X40 Y10
G1 X80 Y10 F4000
G1 X80 Y40
G0 X20 Y40 Z10
G0 X20 Y5
G1 X20 Y0 Z0 F4000
G1 X50 Y0
G0 X50 Y30
G0 X90 Y30
G0 X90 Y60 Z15
G1 X60 Y60 F4000
G1 X60 Y50
G61
G0 X60 Y0
G1 X60 Y30 F4000
G0 X40 Y30 Z5
G0 X40 Y10
G1 X30 Y0 F4000
G64 P0.1
G0 X100 Y60 Z20
G0 X100 Y0 Z0
G1 X120 Y0 F4000
G1 X120 Y20
G0 X100 Y30 Z10
M2
"""

ZIG = """G21 G90 G64 P1
G0 X0 Y0 Z5
G0 X20 Y5
G0 X40 Y0
G0 X60 Y8
G0 X80 Y0 Z8
G0 X100 Y10
G0 X100 Y40
G0 X70 Y50 Z4
G1 X40 Y50 F2400
G1 X10 Y40
G0 X10 Y70 Z10
G0 X40 Y72
G0 X120 Y80 Z2
G0 X0 Y0 Z5
M2
"""

PROGRAMS = {"g0_g1": G0_G1, "zig": ZIG}


@dataclass(frozen=True)
class Comparison:
    """One recording against the simulation at the dial it ran at."""

    measured_s: float
    simulated_s: float
    line_errors_ms: np.ndarray   # simulated - measured time on each program line both have

    @property
    def cycle_error_pct(self) -> float:
        return 100.0 * (self.simulated_s - self.measured_s) / self.measured_s

    def line(self) -> str:
        err = np.abs(self.line_errors_ms)
        return (f"measured {self.measured_s:8.3f} s  simulated {self.simulated_s:8.3f} s  "
                f"cycle {self.cycle_error_pct:+7.3f} %  per line mean |err| {err.mean():6.2f} ms  max {err.max():7.2f} ms")


def compare(recording, program_text: str, dial: float, *, profile: str = "linuxcnc-xyz",
            scale_axis_speed: bool | None = None) -> Comparison:
    """Simulate `program_text` on `profile` with the rapid dial at `dial` and compare it with `recording`
    (cycle from the first to the last motion, time on each program line from motion.program-line).
    `scale_axis_speed` overrides the profile's rule (False: the dial scales the capped rapid rate)."""
    rec = read_recording(recording)
    params: dict = {"override": dial}
    if scale_axis_speed is not None:
        params["scale_axis_speed"] = scale_axis_speed
    res = simulate(parse_program(program_text), profile, mechanisms={"rapid_override": params})
    measured = _line_times_ms(rec)
    simulated = res.blocks.groupby("line")["duration_s"].sum() * 1e3
    both = measured.index.intersection(simulated.index)
    cycle_s = (int(rec.metadata["motion_end_ns"]) - int(rec.metadata["motion_start_ns"])) / 1e9
    return Comparison(cycle_s, res.cycle_time_s, (simulated[both] - measured[both]).to_numpy())
