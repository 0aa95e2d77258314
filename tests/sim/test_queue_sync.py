"""Words the controller executes only at rest (sim/queue_sync.py): which rows are such words, and the
move before one planned as LinuxCNC plans it with nothing queued after it (blend_arc `sync_stop`): it
ends at rest with half its acceleration, also where a rapid/feed switch would have stopped it anyway.
The expected times are derived here from the rule (rest to rest, acceleration A or A / 2)."""

from __future__ import annotations

import math

import pytest

from feedlog.profile import load_profile
from feedlog.sim import simulate
from feedlog.sim.queue_sync import sync_rows, syncs_after
from feedlog.sim.window import simulate_windowed
from feedlog.toolpath import load_program

PROFILE = load_profile("linuxcnc-xyz")
A = PROFILE.axes["x"].acc_max      # 1000 mm/s^2
V = PROFILE.axes["x"].vel_max      # 100 mm/s
OFF = {"blend_arc": {"sync_stop": False}}


def _rest_to_rest(length: float, v: float, a: float) -> float:
    if v * v / a > length:
        return 2.0 * math.sqrt(length / a)
    return length / v + v / a


def _lines(program) -> dict[int, str]:
    table = program.blocks
    return {int(line): str(kind) for line, kind in zip(table["line"], table["kind"].astype(str))}


def test_the_words_executed_at_rest_are_found_and_the_others_not():
    text = ("G21 G90 G64\nG1 X1 F600\nM3 S1000\nG1 X2\nM62 P1\nM48\n(a plain comment)\nG1 X3\nM8\n"
            "G1 X4\nS2000\nG1 X5\nG54\nG1 X6\nG55\nG1 X7\n(MSG, look)\nG1 X8\nG1 X9 S3000\nM100\nG1 X10\nM5 M30\n")
    program = load_program(text, name="words.ngc")
    table = program.blocks
    found = sorted(int(table["line"].iloc[i]) for i in sync_rows(table))
    # M3 S1000 (3), M8 (9), S2000 (11), G55 (15: G54 is already in force), MSG (17), S3000 on a move (19),
    # M100 (20), M5 (22); not M62 (5: synchronised with motion), M48 (6), the plain comment (7)
    assert found == [3, 9, 11, 15, 17, 19, 20, 22]
    motion = [i for i, k in enumerate(table["kind"].astype(str)) if k in ("linear", "rapid")]
    per_move = dict(zip((int(table["line"].iloc[i]) for i in motion), syncs_after(table, motion)))
    # each word counts for the move before it; S3000 on line 19 runs before that line's own move
    assert per_move == {2: 1, 4: 0, 8: 1, 10: 1, 12: 0, 14: 1, 16: 1, 18: 1, 19: 1, 21: 1}


@pytest.mark.parametrize("word", ["M8", "M5", "S500", "(MSG, next)"])
def test_the_move_before_such_a_word_ends_at_rest_with_half_its_acceleration(word):
    program = load_program(f"G21 G90 G64\nG1 X30 F6000\n{word}\nG1 X60\nM2\n", name="sync.ngc")
    on = simulate(program, PROFILE).blocks.set_index("line")["duration_s"]
    off = simulate(program, PROFILE, mechanisms=OFF).blocks.set_index("line")["duration_s"]
    # rest to rest at A / 2: 30 mm at 100 mm/s, 0.4 s (at A it would be 0.4 - 0.1 = 0.3 s, and blended
    # into the next, collinear move, less still)
    assert on[2] == pytest.approx(_rest_to_rest(30.0, V, A / 2), abs=0.002)
    assert off[2] < on[2] - 0.09
    # the last move of the program: rest to rest at A / 2 either way
    assert on[4] == pytest.approx(_rest_to_rest(30.0, V, A / 2), abs=0.002)


def test_a_rapid_between_m5_and_m3_runs_at_half_acceleration_where_a_mode_switch_would_not():
    text = "G21 G90 G64\nG1 X10 F3000\nM5\nG0 X60\nM3\nG1 X70\nM2\n"
    program = load_program(text, name="rapid.ngc")
    on = simulate(program, PROFILE).blocks.set_index("line")["duration_s"]
    off = simulate(program, PROFILE, mechanisms=OFF).blocks.set_index("line")["duration_s"]
    # without the words the feed/rapid switches stop the rapid too, but at full acceleration
    assert off[4] == pytest.approx(_rest_to_rest(50.0, V, A), abs=0.002)
    assert on[4] == pytest.approx(_rest_to_rest(50.0, V, A / 2), abs=0.002)


def test_exact_stop_moves_keep_their_acceleration_and_windows_agree():
    # G61.1: the move stops anyway with its full acceleration (LinuxCNC's STOP end condition)
    program = load_program("G21 G90 G61.1\nG1 X30 F6000\nM8\nG1 X60\nM2\n", name="g611.ngc")
    on = simulate(program, PROFILE).blocks.set_index("line")["duration_s"]
    assert on[2] == pytest.approx(_rest_to_rest(30.0, V, A), abs=0.002)
    # a long program with words every few moves: windows give the whole run's block table
    body = "".join(f"G1 X{(i % 7) * 3 + 1} Y{(i % 5) * 2} F{2400 + 300 * (i % 4)}\n" + ("M8\n" if i % 3 == 0 else "")
                   + (f"S{1000 + i}\n" if i % 5 == 0 else "") for i in range(120))
    program = load_program("G21 G90 G64 P0.05\n" + body + "M2\n", name="many.ngc")
    whole = simulate(program, PROFILE)
    assert whole.cycle_time_s > simulate(program, PROFILE, mechanisms=OFF).cycle_time_s + 0.5
    for size in (4, 19, 50):
        res, blocks, _ = simulate_windowed(program, PROFILE, window=size)
        assert res.cycle_time_s == pytest.approx(whole.cycle_time_s, abs=1e-9), size
        assert blocks["block"].tolist() == whole.blocks["block"].tolist(), size
