"""Per-axis MLP: Sun's Table 1 inputs, feeds within the axes' speed limits, the smoothed speed-ratio target."""

from __future__ import annotations

import numpy as np
import pytest

from feedlog.errors import ModelError
from feedlog.profile import load_profile
from feedlog.toolpath import block_features, parse_program
from feedlog.train.dataset import ProgramTable
from feedlog.train.features import sun_inputs, with_program_columns
from feedlog.train.model_mlp import PerAxisMLP, speed_ratio
from feedlog.train.registry import make_config
from feedlog.train.synthetic import synthetic_set

PROGRAM = """G21 G90 G94
G64 P0.01
F600
G0 X0 Y0 Z0 A0 C0
G1 X1
G1 X2 C30
G1 X3
M2
"""


def _table() -> ProgramTable:
    prof = load_profile("linuxcnc-xyzac")
    program = parse_program(PROGRAM)
    return ProgramTable("t", with_program_columns(block_features(program, prof), program, prof))


def test_no_extra_inputs_is_sun_table_1_exactly():
    model = PerAxisMLP(make_config("mlp", extra_inputs=()))
    for axis in ("x", "y", "z"):
        assert model.axis_inputs(axis) == sun_inputs(axis)
        assert len(model.axis_inputs(axis)) == 9  # angles, feeds, accelerations at n-1, n, n+1


def test_limited_feeds_slow_a_block_a_rotary_axis_times():
    t = _table()
    limited = PerAxisMLP(make_config("mlp", extra_inputs=(), base="cam"))
    programmed = PerAxisMLP(make_config("mlp", extra_inputs=(), limited_feeds=False))
    names = limited.axis_inputs("x")
    x_lim, _ = limited._axis_matrix(t, "x")
    x_nom, _ = programmed._axis_matrix(t, "x")
    v, v_prev, v_next = (names.index(c) for c in ("vx_nom_mm_min", "vx_nom_mm_min_prev", "vx_nom_mm_min_next"))
    # block 2 turns C 30 deg at 60 deg/s (0.5 s) for 1 mm at 600 mm/min (0.1 s): its X feed runs at 1/5
    assert x_nom[2, v] == pytest.approx(600.0)
    assert x_lim[2, v] == pytest.approx(120.0)
    assert x_lim[1, v_next] == pytest.approx(120.0) and x_lim[3, v_prev] == pytest.approx(120.0)
    # blocks the X feed times keep their programmed feed
    assert x_lim[1, v] == pytest.approx(x_nom[1, v]) and x_lim[3, v] == pytest.approx(x_nom[3, v])


def test_speed_ratio_spreads_a_time_align_put_on_the_wrong_side_of_a_boundary():
    nominal = np.array([0.0, 1.0, 1.0, 1.0, 1.0])
    # the corner between blocks 2 and 3 costs 0.4 s; align put it all on block 2
    duration = np.array([0.3, 1.0, 1.4, 1.0, 1.0])
    assert speed_ratio(nominal, duration, span=0)[1:].tolist() == pytest.approx([1.0, 1 / 1.4, 1.0, 1.0])
    smooth = speed_ratio(nominal, duration, span=1)
    assert smooth[2] == pytest.approx(3 / 3.4) and smooth[3] == pytest.approx(3 / 3.4)
    # the dwell/rapid block without nominal time does not count in its neighbour's window
    assert smooth[1] == pytest.approx(2 / 2.4)


def test_negative_target_span_is_refused():
    with pytest.raises(ModelError, match="target_span"):
        make_config("mlp", target_span=-1)


@pytest.mark.parametrize("target", ["feed", "log_ratio"])
def test_both_targets_train_and_predict_feeds_along_the_programmed_move(target):
    tables = synthetic_set(n_train=2, n_test=1, n_blocks=120, seed=5)
    model = PerAxisMLP(make_config("mlp", target=target, epochs=5))
    model.fit([t for t in tables if t.split == "train"], progress=False)
    model.fingerprint = "trained"
    test = tables[-1]
    feeds = model.axis_feeds(test)
    v = np.column_stack([test.blocks[f"v{a}_nom_mm_min"].to_numpy() for a in ("x", "y", "z")])
    if target == "log_ratio":  # the ratio scales the programmed feed: direction and proportions kept
        ratio = np.divide(feeds, v, out=np.full_like(feeds, np.nan), where=np.abs(v) > 1e-6)
        assert np.all(ratio[np.isfinite(ratio)] > 0)
    pred = model.predict(test)
    assert np.all(pred.durations_s > 0) and pred.cycle_time_s == pytest.approx(pred.durations_s.sum())


def test_unknown_target_is_refused():
    with pytest.raises(ModelError, match="target must be one of"):
        make_config("mlp", target="time")


def test_an_mlp_ensemble_averages_its_members_log_ratios():
    tables = synthetic_set(n_train=2, n_test=1, n_blocks=80, seed=3)
    train, test = tables[:2], tables[2]
    pair = PerAxisMLP(make_config("mlp", members=2, epochs=3))
    pair.fit(train, progress=False)
    pair.fingerprint = "synthetic"
    assert sorted(pair.nets) == ["x", "x1", "y", "y1", "z", "z1"]
    first = [next(iter(pair.nets[key].state_dict().values())) for key in ("x", "x1")]
    assert not np.allclose(first[0], first[1])  # the members have their own seeds
    feeds = []
    for k in ("", "1"):
        alone = PerAxisMLP(make_config("mlp", members=1, epochs=3))
        alone.norms, alone.constants, alone.fingerprint = pair.norms, pair.constants, "synthetic"
        alone.nets = {a: pair.nets[a + k] for a in "xyz"}
        feeds.append(np.abs(alone.axis_feeds(test)))
    # log-ratio outputs are averaged: the ensemble's feed is the members' geometric mean
    np.testing.assert_allclose(np.abs(pair.axis_feeds(test)), np.sqrt(feeds[0] * feeds[1]), rtol=1e-5)
    with pytest.raises(ModelError, match="members must be >= 1"):
        make_config("mlp", members=0)
