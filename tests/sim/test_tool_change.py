"""The tool change mechanism: time_s per M6 between two moves, nothing before the first move, off by default."""

from __future__ import annotations

import pytest

from feedlog.errors import SimulationError
from feedlog.profile import load_profile
from feedlog.sim import simulate
from feedlog.toolpath import parse_program

TWO_CHANGES = """G21 G90
T1 M6
G0 X0 Y0
G1 X10 F600
M5
T2 M6
M3 S1000
G1 X20
T3 M6
G1 X30
M30
"""


def test_each_m6_between_moves_adds_its_time_and_none_before_the_first_move():
    prog = parse_program(TWO_CHANGES)
    profile = load_profile("generic-xyz")
    base = simulate(prog, profile)
    timed = simulate(prog, profile, mechanisms={"tool_change": {"time_s": 3.25}})
    # two changes between moves (T2, T3), each a stop and 3.25 s; T1 comes before the first move
    stops = simulate(prog, profile, mechanisms={"tool_change": {"time_s": 0.0}}).cycle_time_s
    assert timed.cycle_time_s - stops == pytest.approx(2 * 3.25, abs=1e-6)
    assert stops >= base.cycle_time_s
    assert simulate(prog, profile).cycle_time_s == base.cycle_time_s      # off unless asked for


def test_a_profile_switches_it_on_and_a_negative_time_is_refused():
    prog = parse_program(TWO_CHANGES)
    on = load_profile("generic-xyz").to_toml() + "\n[sim.tool_change]\nenabled = true\ntime_s = 2.0\n"
    from feedlog.profile import MachineProfile

    profile = MachineProfile.from_toml(on, source="test")
    off = simulate(prog, load_profile("generic-xyz"), mechanisms={"tool_change": {"time_s": 0.0}}).cycle_time_s
    assert simulate(prog, profile).cycle_time_s - off == pytest.approx(4.0, abs=1e-6)
    with pytest.raises(SimulationError, match="time_s must be a time from 0"):
        simulate(prog, profile, mechanisms={"tool_change": {"time_s": -1.0}})
