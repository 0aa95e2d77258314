"""Simulated training programs (feedlog.sim on random toolpaths)."""

from __future__ import annotations

import numpy as np
import pytest

from feedlog.profile import load_profile
from feedlog.toolpath import block_features, parse_program
from feedlog.toolpath.schema import FEATURE_COLUMNS
from feedlog.train.augment import random_program_text, simulated_tables


def test_random_programs_parse_and_are_seeded():
    text = random_program_text(n_blocks=50, feed_mm_min=2000.0, tol_mm=0.05, seed=3)
    assert text == random_program_text(n_blocks=50, feed_mm_min=2000.0, tol_mm=0.05, seed=3)
    assert text != random_program_text(n_blocks=50, feed_mm_min=2000.0, tol_mm=0.05, seed=4)
    program = parse_program(text)
    assert (program.blocks["kind"] == "linear").sum() >= 50
    assert "G61" in random_program_text(n_blocks=5, feed_mm_min=1000.0, tol_mm=0.0, seed=0)


def test_simulated_tables_carry_features_and_simulated_times():
    prof = load_profile("linuxcnc-xyz")
    tables = simulated_tables(prof, n_programs=3, n_blocks=60, seed=1, feeds=(1500.0,), tols=(0.0, 0.02, 0.2))
    assert [t.split for t in tables] == ["train"] * 3 and tables[0].profile is prof
    for t in tables:
        assert set(FEATURE_COLUMNS) <= set(t.blocks.columns)
        d = t.durations()
        assert np.all(d >= 0) and d.sum() > 0
        # an acceleration-limited machine never beats L/F on the feed moves
        assert t.measured_cycle_time_s >= 0.99 * t.cam_time_s


def _sim_time(text: str, profile) -> float:
    from feedlog.sim import simulate

    return float(simulate(parse_program(text), profile).blocks["duration_s"].sum())


def test_one_seed_one_geometry_and_exact_stop_is_slower():
    prof = load_profile("linuxcnc-xyz")
    g61, blend = (random_program_text(n_blocks=80, feed_mm_min=3000.0, tol_mm=tol, seed=5) for tol in (0.0, 0.2))
    moves = [[ln.split(" Z")[0] for ln in text.splitlines() if ln.startswith("X")] for text in (g61, blend)]
    assert moves[0] == moves[1] and len(moves[0]) >= 80
    # exact path (G61) stops at every corner: slower than blending within 0.2 mm on the same path
    assert _sim_time(g61, prof) > 1.05 * _sim_time(blend, prof)


def test_five_axis_programs_turn_the_rotary_axes_and_hit_their_speed_limit():
    prof = load_profile("linuxcnc-xyzac")
    (table,) = simulated_tables(prof, n_programs=1, n_blocks=200, seed=2)
    assert " A" in table.program_text and " C" in table.program_text
    b = table.blocks
    limited = b["axis_time_s"] > 1.5 * b["nominal_time_s"]
    assert (b["rot_dist_deg"] > 0).mean() > 0.3 and limited.sum() >= 10
    # where a rotary axis sets the time, the simulated block is never faster than that axis allows
    assert np.all(b.loc[limited, "duration_s"].sum() >= 0.99 * b.loc[limited, "axis_time_s"].sum())
    (flat,) = simulated_tables(load_profile("linuxcnc-xyz"), n_programs=1, n_blocks=50, seed=2)
    assert " A" not in flat.program_text


def test_five_axis_programs_set_work_offsets_that_leave_the_planned_time():
    prof = load_profile("linuxcnc-xyzac")
    texts = [random_program_text(n_blocks=40, feed_mm_min=2000.0, tol_mm=0.01, seed=s, rotary=True) for s in range(30)]
    with_offset = [t for t in texts if "G10 L2 P1" in t]
    assert 4 <= len(with_offset) <= 20  # about four in ten
    assert not any("G10" in random_program_text(n_blocks=40, feed_mm_min=2000.0, tol_mm=0.01, seed=s)
                   for s in range(30))
    # the offset is the table's [Xo, Yo, Zo]; LinuxCNC plans the table-frame path (TCP kinematics), so the
    # offset does not change the time. (Until the model stopped between G0 and G1 it did, by 0.01-0.1 s:
    # the first rapid from the machine origin, blended into the first G1, changed with the offset.)
    seed = next(s for s, t in enumerate(texts) if "G10 L2 P1" in t)
    text = random_program_text(n_blocks=40, feed_mm_min=2000.0, tol_mm=0.01, seed=seed, rotary=True)
    offset_line = next(ln for ln in text.splitlines() if ln.startswith("G10"))
    xo = float(offset_line.split(" X")[1].split()[0])
    assert block_features(parse_program(text), prof)["xo_mm"].iloc[-1] == xo
    no_offset = "\n".join(ln for ln in text.splitlines() if not ln.startswith(("G10", "G54"))) + "\n"
    assert _sim_time(text, prof) == pytest.approx(_sim_time(no_offset, prof), abs=1e-6)
