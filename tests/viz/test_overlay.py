"""The saved .rrd, read back with Rerun's own RRD reader: entity paths, sample counts, timelines."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import rerun as rr
from tests.viz.conftest import column_values, rrd_content
from rerun.chunk import RrdReader
from tests.viz import synthetic as syn

from feedlog.viz.overlay import TIMELINE_BLOCK, TIMELINE_PATH, TIMELINE_TIME, log_view, save_view
from feedlog.viz.prepare import ModelPrediction, ViewInputs, prepare_view


@pytest.fixture(scope="module")
def full_view():
    series, blocks = syn.sim_result(accel_mm_s2=700.0)
    model_blocks = blocks.assign(duration_s=blocks["duration_s"] * 1.05)
    model = ModelPrediction("mlp", blocks=model_blocks[["block", "duration_s"]],
                            series=series[["t_ns", "feed_mm_min"]].assign(feed_mm_min=series["feed_mm_min"] * 0.95))
    inputs = ViewInputs(syn.recording(five_axis=True), name="square", program_blocks=syn.program_blocks(),
                        program_path=syn.cl_points(), sim_series=series, sim_blocks=blocks, models=[model],
                        arrow_every=100)
    return prepare_view(inputs)


def test_rrd_holds_every_overlay_with_its_sample_count_and_timelines(tmp_path, full_view):
    rr.set_strict_mode(True)
    path = tmp_path / "square.rrd"
    counts = save_view(full_view, path)
    content = rrd_content(path)
    n = len(full_view.measured)
    n_sim = len(full_view.sim)
    expected_rows = {
        "/path/tool": n, "/feed/measured": n, "/feed/sim": n_sim, "/feed/mlp": n_sim,
        "/axes/x/measured": n, "/axes/a/measured": n, "/axes/c/measured": n, "/axes/y/sim": n_sim,
        "/blocks/measured": 4, "/blocks/sim": 4, "/blocks/mlp": 4,
        "/feed/commanded": int((full_view.measured["block"] >= 0).sum()),
    }
    for entity, rows in expected_rows.items():
        assert content[entity]["rows"] == rows, entity
        assert counts[entity.lstrip("/")] == rows
    # residuals: only where the prediction covers the measured sample
    assert content["/residual/sim"]["rows"] == int(np.isfinite(full_view.residuals["sim"]).sum())
    assert 0 < content["/residual/mlp"]["rows"] <= n
    # static 3D overlays
    for entity in ("/path/programmed", "/path/measured", "/path/residual", "/path/orientation"):
        assert content[entity]["rows"] == 0 and content[entity]["static"], entity
    # timelines: measured samples carry time, block and path length; model series only time
    assert content["/feed/measured"]["timelines"] == {TIMELINE_TIME, TIMELINE_BLOCK, TIMELINE_PATH}
    assert content["/feed/mlp"]["timelines"] == {TIMELINE_TIME}
    assert content["/axes/x/measured"]["timelines"] == {TIMELINE_TIME}
    assert content["/residual/sim"]["timelines"] == {TIMELINE_TIME, TIMELINE_BLOCK}
    assert content["/blocks/measured"]["timelines"] == {TIMELINE_TIME, TIMELINE_BLOCK}
    # no entity logged sample by sample: each temporal series arrives in a single chunk
    assert len([c for c in content["/feed/measured"]["chunks"] if not c.is_static]) == 1
    # a blueprint travels with the recording
    assert len(RrdReader(path).blueprints()) == 1


def test_rrd_values_round_trip(tmp_path, full_view):
    path = tmp_path / "square.rrd"
    save_view(full_view, path)
    content = rrd_content(path)
    m = full_view.measured
    np.testing.assert_array_equal(column_values(content["/feed/measured"], TIMELINE_BLOCK), m["block"])
    np.testing.assert_array_equal(column_values(content["/feed/measured"], TIMELINE_TIME), m["t_rel_ns"])
    np.testing.assert_allclose(column_values(content["/feed/measured"], "Scalars:scalars"), m["feed_mm_min"])
    path_um = column_values(content["/feed/measured"], TIMELINE_PATH)
    assert path_um[-1] == round(m["s_mm"].iloc[-1] * 1000) and np.all(np.diff(path_um) >= 0)
    np.testing.assert_allclose(column_values(content["/blocks/mlp"], "Scalars:scalars"),
                               full_view.blocks["mlp_s"])
    np.testing.assert_array_equal(column_values(content["/blocks/sim"], TIMELINE_BLOCK), [0, 1, 2, 3])
    # the orientation arrows: one per arrow_every samples
    o = content["/path/orientation"]["chunks"][0].to_record_batch()
    vectors = o.column(o.schema.get_field_index("Arrows3D:vectors")).to_pylist()[0]
    assert len(vectors) == len(full_view.orientation)


def test_only_what_is_given_is_logged(tmp_path):
    data = prepare_view(ViewInputs(syn.recording(), name="bare"))
    path = tmp_path / "bare.rrd"
    save_view(data, path)
    content = rrd_content(path)
    assert not any(e.startswith(("/residual", "/path/residual", "/path/programmed", "/feed/sim", "/path/orientation"))
                   for e in content)
    assert {"/feed/measured", "/path/tool", "/path/measured", "/axes/z/measured"} <= set(content)
    assert "/axes/a/measured" not in content
    # block times come from the line stream mapped through the program: no program, no block times
    assert "/blocks/measured" not in content


def test_log_view_goes_to_any_recording_stream():
    stream = rr.RecordingStream("feedlog-test", recording_id="mem")
    memory = stream.memory_recording()
    counts = log_view(prepare_view(ViewInputs(syn.recording(), program_blocks=syn.program_blocks())), stream)
    stream.flush()
    assert counts["feed/measured"] > 3000
    assert counts["blocks/measured"] == 4
    assert len(memory.drain_as_bytes()) > 0


def test_a_block_shorter_than_a_sample_still_gets_its_block_time(tmp_path):
    rec = syn.recording(lead_s=0.0)
    t = rec.streams["axes"]["t_ns"].to_numpy()
    # block 1 lasts 0.4 ms, between two samples 1 ms apart: no sample is ever inside it
    starts = [t[0], t[1000] + 300_000, t[1000] + 700_000]
    ends = [starts[1], starts[2], t[2000]]
    aligned = pd.DataFrame({"block": [0, 1, 2], "t_start_ns": starts, "t_end_ns": ends})
    aligned["duration_s"] = (aligned["t_end_ns"] - aligned["t_start_ns"]) / 1e9
    data = prepare_view(ViewInputs(rec, measured_blocks=aligned))
    assert not (data.measured["block"] == 1).any()
    save_view(data, tmp_path / "short.rrd")
    entry = rrd_content(tmp_path / "short.rrd")["/blocks/measured"]
    np.testing.assert_array_equal(column_values(entry, TIMELINE_BLOCK), [0, 1, 2])
    np.testing.assert_array_equal(column_values(entry, TIMELINE_TIME), np.array(starts) - starts[0])
    np.testing.assert_allclose(column_values(entry, "Scalars:scalars"), aligned["duration_s"])
