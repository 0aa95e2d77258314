"""The rapid dial's two rules, derived here from the program's geometry and the profile's limits.

Generic (`scale_axis_speed = false`): a rapid runs at min(rapid rate, axis-limited speed) x dial.
LinuxCNC (`scale_axis_speed = true`, the shipped LinuxCNC profiles): the dial scales the axis-limited
speed and the rapid rate (there the TRAJ cap) clips after it, min(axis speed x dial, rapid rate); and a
blend arc between two rapids is sized for their undialed request, so it is the same arc at every dial.
"""

from __future__ import annotations

import numpy as np
import pytest

from feedlog.profile import load_profile
from feedlog.sim import simulate
from feedlog.toolpath import parse_program

# line 3 is an XYZ rapid whose axis-limited speed is above the rapid rate on both profiles
DIAGONAL = "G21 G90 G61\nG0 X0 Y0 Z0\nG0 X120 Y90 Z30\nG0 X0 Y0 Z0\nM2\n"
START, END = np.array([0.0, 0.0, 0.0]), np.array([120.0, 90.0, 30.0])


def _plateau(program, profile, **params) -> float:
    res = simulate(program, profile, mechanisms={"rapid_override": params})
    series = res.series
    return float(series["feed_mm_min"].to_numpy()[series["line"].to_numpy() == 3].max() / 60.0)


@pytest.mark.parametrize("dial", [0.5, 0.25])
@pytest.mark.parametrize(("profile", "axis_first"), [("linuxcnc-xyz", True), ("generic-xyz", False)])
def test_a_diagonal_rapid_runs_at_the_rule_of_its_profile(profile, axis_first, dial):
    prof = load_profile(profile)
    delta = np.abs(END - START)
    vel = np.array([prof.axes[a].vel_max for a in "xyz"])
    axis_speed = np.linalg.norm(delta) / np.max(delta / vel)
    rate = min(prof.rapid_mm_min / 60.0, prof.interpolator.path_vel_max_mm_s or np.inf)
    assert axis_speed > rate * 1.2   # the case where the two rules differ
    expected = min(axis_speed * dial, rate) if axis_first else min(axis_speed, rate) * dial
    program = parse_program(DIAGONAL)
    assert _plateau(program, profile, override=dial) == pytest.approx(expected, rel=1e-3)
    other = min(axis_speed, rate) * dial if axis_first else min(axis_speed * dial, rate)
    assert _plateau(program, profile, override=dial, scale_axis_speed=not axis_first) == pytest.approx(other, rel=1e-3)


def _corner_deviation_mm(dial: float, **params) -> float:
    program = parse_program("G21 G90 G64 P2\nG0 X0 Y0 Z0\nG0 X30 Y0\nG0 X30 Y4\nG0 X60 Y4\nM2\n")
    series = simulate(program, "linuxcnc-xyz", mechanisms={"rapid_override": {"override": dial, **params}}).series
    return float(np.hypot(series["x_mm"] - 30.0, series["y_mm"]).min())


def test_a_blend_arc_between_rapids_is_the_same_arc_at_every_dial():
    full = _corner_deviation_mm(1.0)
    assert 0.1 < full <= 2.0
    for dial in (0.5, 0.25, 0.1):
        assert _corner_deviation_mm(dial) == pytest.approx(full, abs=1e-3), dial
    # sized for the dialed speed instead (the generic rule), the arc shrinks at a low dial
    assert _corner_deviation_mm(0.25, scale_axis_speed=False) < 0.7 * full
