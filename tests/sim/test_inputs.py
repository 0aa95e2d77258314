"""Bad and unusual input: our errors naming file and line, empty programs, arcs, units, rotary moves."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from feedlog.errors import ProgramError, SimulationError
from feedlog.sim import simulate


def test_axis_missing_on_the_machine_names_file_and_line(plain, gcode):
    with pytest.raises(ProgramError, match=r"test\.ngc:3: the program moves axis A") as info:
        simulate(gcode("G21 G90\nF3000\nG1 X1 A30\n"), plain)
    assert info.value.line == 3 and info.value.code == "A"


def test_feed_move_without_feed_names_the_line(plain):
    from feedlog.toolpath import parse_program

    prog = parse_program("G21 G90\nG1 X10\n", name="nofeed.ngc", lenient=True)
    with pytest.raises(SimulationError, match=r"nofeed\.ngc:2: feed move with no feed rate"):
        simulate(prog, plain)


def test_not_a_block_table_is_rejected(plain):
    with pytest.raises(SimulationError, match="block table"):
        simulate(pd.DataFrame({"x": [1.0]}), plain)
    with pytest.raises(SimulationError, match="Program or a block table"):
        simulate("G1 X1", plain)


@pytest.mark.parametrize("interp", ["lookahead", "fir", "cam"])
def test_empty_program_has_no_motion(plain, gcode, interp):
    res = simulate(gcode("G21\nM2\n"), plain, mechanisms=[interp])
    assert res.cycle_time_s == 0.0 and len(res.blocks) == 0
    assert len(res.series) >= 1


def test_arcs_helix_and_units(plain, gcode):
    res = simulate(gcode("G20 G90 G17 G61\nF100\nG2 X0 Y0 Z-0.1 I0.2 J0 P2\n"), plain)
    s = res.series
    r = np.hypot(s["x_mm"] - 0.2 * 25.4, s["y_mm"])
    assert np.allclose(r, 0.2 * 25.4, atol=1e-6)  # two turns on the circle, in mm
    assert s["z_mm"].iloc[-1] == pytest.approx(-2.54) and s["z_mm"].is_monotonic_decreasing
    length = np.hypot(2 * 2 * np.pi * 5.08, 2.54)
    assert res.cam_time_s == pytest.approx(length / (100 * 25.4 / 60), rel=1e-6)


def test_rotary_only_move_uses_degrees(make_machine, gcode):
    prof = make_machine(five_axis=True)
    res = simulate(gcode("G21 G90 G61\nF1800\nG1 C90\n"), prof, mechanisms=["lookahead"])
    # 90 deg at min(30 deg/s programmed, 60 deg/s axis), 600 deg/s^2
    assert res.cycle_time_s == pytest.approx(90 / 30 + 30 / 600, abs=1e-6)
    assert res.series["c_deg"].iloc[-1] == pytest.approx(90.0)
