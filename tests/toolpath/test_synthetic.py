"""The synthetic program pieces are real G-code: an arc leaves along the heading and turns by its sweep."""

from __future__ import annotations

import math

import pytest

from feedlog.toolpath import parse_program
from feedlog.toolpath.synthetic import tangent_arc


@pytest.mark.parametrize("heading, sweep", [(0.0, math.pi / 2), (1.0, -0.7), (-2.5, 2.0)])
def test_tangent_arc_turns_by_its_sweep_from_the_heading(heading, sweep):
    line, ex, ey, end_heading = tangent_arc(1.0, 2.0, heading, 3.0, sweep)
    assert end_heading == pytest.approx(heading + sweep)
    # the chord from start to end is at half the sweep from the heading, of length 2 R sin(|sweep| / 2)
    chord = math.hypot(ex - 1.0, ey - 2.0)
    assert chord == pytest.approx(2 * 3.0 * math.sin(abs(sweep) / 2), rel=1e-9)
    assert math.atan2(ey - 2.0, ex - 1.0) == pytest.approx(heading + sweep / 2, abs=1e-9)
    prog = parse_program(f"G21 G90 G17\nG0 X1 Y2\n{line} F1000\n")
    arc = prog.blocks[prog.blocks["kind"].str.startswith("arc")]
    assert len(arc) == 1 and arc["kind"].iloc[0] == ("arc_ccw" if sweep > 0 else "arc_cw")
