"""Session events with positions: a dwell and a standstill hidden in a simulated run are found from the
line stream and the positions' speed (no feed stream) and reported by align; nothing where none is."""

from __future__ import annotations

import pandas as pd
import pytest

from feedlog.align import align_recording
from feedlog.profile import load_profile
from feedlog.recording import Recording
from feedlog.sim import simulate
from feedlog.toolpath import parse_program

PROGRAM = """G21 G90 G64 P0.01
G0 X0 Y0 Z5
G1 Z0 F600
G1 X20 F1200
G4 P{dwell}
G1 Y20
G1 X0
G1 Y0
M30
"""


def run(dwell: float, hold_s: float) -> tuple[Recording, object]:
    """Positions and the line stream of the program every 10 ms, with the feed held `hold_s` on line 6."""
    prog = parse_program(PROGRAM.format(dwell=dwell))
    sim = simulate(prog, load_profile("generic-xyz"), dt_s=0.01)
    s = sim.series[["t_ns", "x_mm", "y_mm", "z_mm", "line"]].copy()
    if hold_s:   # a feed hold halfway along line 6: the positions stand, the line stays
        mid = s.index[s["line"] == 6][len(s.index[s["line"] == 6]) // 2]
        held = pd.concat([s.loc[[mid]]] * int(round(hold_s / 0.01)), ignore_index=True)
        after = s.loc[mid + 1:].copy()
        held["t_ns"] = s.loc[mid, "t_ns"] + 10_000_000 * (1 + held.index.to_numpy())
        after["t_ns"] += int(round(hold_s / 0.01)) * 10_000_000
        s = pd.concat([s.loc[:mid], held, after], ignore_index=True)
    s["t_ns"] += 1_000_000_000
    rec = Recording(streams={"axes": s[["t_ns", "x_mm", "y_mm", "z_mm"]].reset_index(drop=True),
                             "line": s[["t_ns", "line"]].astype({"line": "int64"}).reset_index(drop=True)},
                    source="sim")
    return rec, prog


@pytest.mark.parametrize("dwell,hold_s", [(2.0, 3.0), (1.5, 0.0)])
def test_dwell_and_feed_hold_are_reported_with_their_times(dwell, hold_s):
    rec, prog = run(dwell, hold_s)
    a = align_recording(rec, prog, profile="generic-xyz")
    events = {e["kind"]: e for e in a.report["events"]}
    assert events["dwell"]["program_line"] == 5 and events["dwell"]["duration_s"] == pytest.approx(dwell, abs=0.05)
    if hold_s:
        assert events["standstill"]["program_line"] == 6
        assert events["standstill"]["duration_s"] == pytest.approx(hold_s, abs=0.15)
    else:
        assert "standstill" not in events


def test_no_events_where_none_happen():
    rec, prog = run(0.0, 0.0)
    assert align_recording(rec, prog, profile="generic-xyz").report["events"] == []
