"""Simulated training programs (feedlog.sim on random toolpaths)."""

from __future__ import annotations

import numpy as np

from feedlog.profile import load_profile
from feedlog.toolpath import parse_program
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
    # exact path (G61) stops at every corner: slower than blending within 0.2 mm
    assert tables[0].measured_cycle_time_s / tables[0].cam_time_s > tables[2].measured_cycle_time_s / tables[2].cam_time_s
