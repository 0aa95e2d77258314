"""prepare_view: measured feed, active blocks, block times, residuals, time origin, orientation."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from tests.viz import synthetic as syn

from feedlog.errors import FeedlogError
from feedlog.ingest.recording import Recording
from feedlog.viz.prepare import (ModelPrediction, ViewInputs, axis_velocities, prepare_view,
                                 tool_orientation)


def _true_block_durations(accel=500.0):
    t, _, _, block = syn.motion(rate_hz=1000.0, accel_mm_s2=accel)
    # block k lasts from its first sample to the first sample of block k+1 (last: to its last sample)
    starts = np.array([t[block == k][0] for k in range(4)] + [t[-1]])
    return np.diff(starts) / 1e9


def test_block_times_from_line_stream_match_the_motion():
    data = prepare_view(ViewInputs(syn.recording(), program_blocks=syn.program_blocks()))
    assert list(data.blocks["block"]) == [0, 1, 2, 3]
    np.testing.assert_allclose(data.blocks["measured_s"], _true_block_durations(), atol=2e-3)
    assert list(data.blocks["line"]) == [10, 11, 12, 13]


def test_time_origin_is_the_first_block_start():
    lead_s = 0.2
    data = prepare_view(ViewInputs(syn.recording(lead_s=lead_s), program_blocks=syn.program_blocks()))
    m = data.measured
    first = m.index[m["block"] >= 0][0]
    assert m["t_rel_ns"].iloc[first] == 0
    assert m["t_rel_ns"].iloc[0] == pytest.approx(-lead_s * 1e9, abs=1e6)
    assert (m["block"].iloc[:first] == -1).all()


def test_feed_derived_from_positions_when_there_is_no_feed_stream():
    with_feed = prepare_view(ViewInputs(syn.recording(with_feed=True)))
    derived = prepare_view(ViewInputs(syn.recording(with_feed=False)))
    assert any("derived from axis positions" in n for n in derived.notes)
    assert not any("derived" in n for n in with_feed.notes)
    # same feed away from the corners (central differences smear one sample at each kink)
    cruise = np.abs(with_feed.measured["feed_mm_min"].to_numpy() - syn.FEED_MM_MIN) < 1e-6
    np.testing.assert_allclose(derived.measured["feed_mm_min"].to_numpy()[cruise], syn.FEED_MM_MIN, rtol=1e-2)


def test_axis_velocities_handle_duplicate_time_stamps():
    t = np.array([0, 1_000_000, 1_000_000, 2_000_000, 3_000_000], dtype=np.int64)
    pos = np.array([[0.0], [1.0], [1.0], [2.0], [3.0]])  # 1 mm per ms = 60000 mm/min
    v = axis_velocities(t, pos)
    assert np.all(np.isfinite(v))
    np.testing.assert_allclose(v[:, 0], 60000.0)


def test_residual_is_zero_for_a_perfect_prediction_and_not_for_a_wrong_one():
    exact_series, exact_blocks = syn.sim_result(accel_mm_s2=500.0)
    data = prepare_view(ViewInputs(syn.recording(), program_blocks=syn.program_blocks(),
                                   sim_series=exact_series, sim_blocks=exact_blocks))
    r = data.residuals["sim"]
    assert np.nanmax(np.abs(r)) < 1e-6
    slow = exact_series.assign(feed_mm_min=exact_series["feed_mm_min"] * 0.9)
    data = prepare_view(ViewInputs(syn.recording(), program_blocks=syn.program_blocks(),
                                   sim_series=slow, sim_blocks=exact_blocks,
                                   models=[ModelPrediction("mlp", series=slow[["t_ns", "feed_mm_min"]])]))
    assert set(data.residuals) == {"sim", "mlp"}
    cruise = np.abs(data.measured["feed_mm_min"].to_numpy() - syn.FEED_MM_MIN) < 1e-6
    np.testing.assert_allclose(data.residuals["mlp"][cruise], 0.1 * syn.FEED_MM_MIN, rtol=1e-6)


def test_block_table_joins_measured_sim_and_model_times():
    series, blocks = syn.sim_result(accel_mm_s2=800.0)
    model = ModelPrediction("lstm", blocks=pd.DataFrame({"block": [0, 1, 2, 3], "duration_s": [1.0, 0.5, 1.0, 0.5]}))
    data = prepare_view(ViewInputs(syn.recording(), program_blocks=syn.program_blocks(), sim_series=series,
                                   sim_blocks=blocks, models=[model]))
    assert {"measured_s", "sim_s", "lstm_s"} <= set(data.blocks.columns)
    np.testing.assert_allclose(data.blocks["sim_s"], blocks["duration_s"])
    np.testing.assert_allclose(data.blocks["lstm_s"], [1.0, 0.5, 1.0, 0.5])
    assert (data.blocks["sim_s"] < data.blocks["measured_s"]).all()  # higher acceleration: shorter blocks


def test_align_blocks_take_precedence_over_the_line_stream():
    rec = syn.recording(lead_s=0.0)
    t = rec.streams["axes"]["t_ns"].to_numpy()
    aligned = pd.DataFrame({"block": [0, 1], "t_start_ns": [t[0], t[1000]], "t_end_ns": [t[1000], t[2000]]})
    aligned["duration_s"] = (aligned["t_end_ns"] - aligned["t_start_ns"]) / 1e9
    data = prepare_view(ViewInputs(rec, program_blocks=syn.program_blocks(), measured_blocks=aligned))
    assert list(data.blocks["block"]) == [0, 1]
    np.testing.assert_allclose(data.blocks["measured_s"], [1.0, 1.0])
    assert (data.measured["block"].iloc[:1000] == 0).all()
    assert (data.measured["block"].iloc[2001:] == -1).all()


def test_commanded_feed_follows_the_active_block_and_rapids_use_the_profile_rate():
    blocks = syn.program_blocks()
    blocks["kind"] = pd.Categorical(["rapid", "linear", "linear", "linear"])
    blocks.loc[2, "feed_mm_min"] = 600.0
    data = prepare_view(ViewInputs(syn.recording(), program_blocks=blocks, rapid_mm_min=6000.0))
    m = data.measured
    assert (m.loc[m["block"] == 0, "commanded_feed_mm_min"] == 6000.0).all()
    assert (m.loc[m["block"] == 2, "commanded_feed_mm_min"] == 600.0).all()
    assert m.loc[m["block"] == -1, "commanded_feed_mm_min"].isna().all()


def test_tool_orientation_of_an_ac_table():
    ori = tool_orientation(np.array([0.0, 90.0, 90.0]), np.array([45.0, 0.0, 90.0]))
    np.testing.assert_allclose(ori, [[0, 0, 1], [0, 1, 0], [1, 0, 0]], atol=1e-12)
    data = prepare_view(ViewInputs(syn.recording(five_axis=True), arrow_every=100))
    assert data.axes == ("x", "y", "z", "a", "c")
    assert len(data.orientation) == int(np.ceil(len(data.measured) / 100))
    np.testing.assert_allclose(np.linalg.norm(data.orientation[["i", "j", "k"]], axis=1), 1.0)


def test_bad_inputs_raise_our_errors():
    rec = syn.recording()
    no_z = Recording(streams={"axes": rec.streams["axes"].drop(columns="z_mm")}, source="bad.mcap")
    with pytest.raises(FeedlogError, match=r"bad.mcap: stream 'axes' needs x_mm, y_mm and z_mm"):
        prepare_view(ViewInputs(no_z))
    with pytest.raises(FeedlogError, match="no stream 'axes'"):
        prepare_view(ViewInputs(Recording(streams={}, source="empty.mcap")))
    with pytest.raises(FeedlogError, match="needs 'block' and 'duration_s'"):
        ModelPrediction("m", blocks=pd.DataFrame({"block": [0]}))
    with pytest.raises(FeedlogError, match="unique and not 'sim'"):
        ViewInputs(rec, models=[ModelPrediction("sim")])
    with pytest.raises(FeedlogError, match="arrow_every"):
        ViewInputs(rec, arrow_every=0)
