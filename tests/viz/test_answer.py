"""The demo's answer sentences (`viz.answer`) and the plots that must show what they mean."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib import image

from feedlog.colors import source_color
from feedlog.viz.answer import hybrid_equals_sim, summary_sentences
from feedlog.viz.plots import plot_cycle_times, spans_decades
from feedlog.viz.report import cycle_time_table, table_markdown, TableRow


def _table(hybrid_factor: float, n: int = 40) -> pd.DataFrame:
    rng = np.random.default_rng(3)
    measured = rng.uniform(3, 30, n)
    rows = []
    for i, m in enumerate(measured):
        sim = m * (1 + rng.normal(0, 0.002))
        rows.append(TableRow(program=f"p{i}", recording=f"r{i}", split="test" if i % 4 == 0 else "train",
                             measured_s=m, cam_s=m * 0.6, sim_s=sim,
                             models={"mlp": m * (1 + rng.normal(0, 0.02)), "hybrid": sim * hybrid_factor}))
    return cycle_time_table(rows, model_names=["mlp", "hybrid"])


def test_the_summary_explains_a_hybrid_that_equals_the_simulation_and_only_then():
    same = _table(1.0)
    assert hybrid_equals_sim(same) == 1.0
    lines = summary_sentences(same, run_time_s=12.34, models=["mlp", "hybrid"])
    assert lines[0] == "40 recordings, 40 with a measured cycle time (10 held out for testing)."
    assert "The CAM time misses it by 40.0 % (held out: 40.0 %)" in lines[2]
    assert "learned almost none here, so it equals the simulation within 0.1 % on 100 % of the recordings" in lines[3]
    assert lines[3].startswith("Best learned model on held-out recordings: hybrid, 0.2 % mean error")
    assert "Without the simulation underneath: mlp, " in lines[3]
    assert lines[-1] == "The demo ran for 12.3 s."
    apart = _table(1.01)
    assert hybrid_equals_sim(apart) == 0.0
    assert not any("learned almost none" in line for line in summary_sentences(apart, models=["mlp", "hybrid"]))


def test_the_table_prints_no_minus_zero():
    text = table_markdown(cycle_time_table([TableRow("p", "r", measured_s=10.0, sim_s=9.999, cam_s=10.001)]))
    assert "-0.0 %" not in text and "| 0.0 % | 0.0 % |" in text


def _sim_pixels(table: pd.DataFrame, path) -> int:
    pixels = image.imread(plot_cycle_times(table, path))[..., :3]
    sim = np.array(source_color("sim", 1)) / 255
    return int(np.all(np.abs(pixels - sim) < 0.06, axis=-1).sum())


def test_sim_points_stay_visible_under_an_identical_hybrid(tmp_path):
    """117 programs where the hybrid equals the simulation: most of the simulation's colour must still
    show compared with the same plot without a hybrid (the hybrid is drawn as rings; filled dots drawn
    over them left none)."""
    with_hybrid = _sim_pixels(_table(1.0, n=117), tmp_path / "a.png")
    without = _sim_pixels(_table(1.0, n=117).drop(columns=["hybrid_s", "hybrid_err_pct"]), tmp_path / "b.png")
    assert without > 1000 and with_hybrid > 0.3 * without, (with_hybrid, without)


def test_block_times_over_decades_get_log_axes():
    assert spans_decades(np.array([0.001, 0.002, 0.2]))          # dense002q0: 1 ms blocks and a 0.2 s one
    assert not spans_decades(np.array([0.5, 1.0, 2.0, np.nan, 0.0]))
