"""PNG plots: every overlay renders to a real PNG file."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from tests.viz import synthetic as syn
from matplotlib import image

from feedlog.viz.plots import plot_cycle_times, plot_view
from feedlog.viz.prepare import ViewInputs, prepare_view


def _is_png(path) -> bool:
    return path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plot_view_writes_four_pngs(tmp_path):
    series, blocks = syn.sim_result()
    data = prepare_view(ViewInputs(syn.recording(five_axis=True), name="sq", program_blocks=syn.program_blocks(),
                                   program_path=syn.cl_points(), sim_series=series, sim_blocks=blocks))
    paths = plot_view(data, tmp_path / "plots")
    assert set(paths) == {"feed", "axes", "path", "blocks"}
    for kind, path in paths.items():
        assert path.parent == tmp_path / "plots" and path.name == f"sq_{kind}.png"
        assert _is_png(path)
        pixels = image.imread(path)
        assert pixels.shape[0] > 300 and pixels.shape[1] > 300
        assert np.std(pixels[..., :3]) > 0.01  # not a blank canvas


def test_plots_without_predictions_still_render(tmp_path):
    paths = plot_view(prepare_view(ViewInputs(syn.recording(), name="bare")), tmp_path, kinds=("feed", "blocks"))
    assert sorted(paths) == ["blocks", "feed"] and all(_is_png(p) for p in paths.values())
    with pytest.raises(ValueError, match="unknown plot kinds"):
        plot_view(prepare_view(ViewInputs(syn.recording(), name="bare")), tmp_path, kinds=("feeds",))


def test_cycle_time_bars(tmp_path):
    table = pd.DataFrame({"program": ["a", "b"], "measured_s": [3.1, 4.0], "cam_s": [2.5, 3.3],
                          "sim_s": [3.0, np.nan], "mlp_s": [3.2, 4.1]})
    path = plot_cycle_times(table, tmp_path / "ct.png")
    assert _is_png(path)


def test_cycle_times_of_many_programs_stay_a_readable_size(tmp_path):
    from PIL import Image

    rng = np.random.default_rng(0)
    measured = rng.uniform(2, 20, 117)
    table = pd.DataFrame({"program": [f"p{k}" for k in range(117)], "measured_s": measured,
                          "cam_s": measured * 0.8, "sim_s": measured * 1.01})
    path = plot_cycle_times(table, tmp_path / "ct.png")
    width, height = Image.open(path).size
    assert width <= 1500 and height <= 1500
