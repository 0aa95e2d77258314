"""Inputs, normalisation, windows and fingerprints of feedlog.train."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feedlog.errors import ModelError
from feedlog.train.dataset import ProgramTable, fingerprint, make_windows, stitch_windows, tail_split, window_starts
from feedlog.train.features import (CHIEN_INPUTS, NO_TOLERANCE_MM, Normaliser, build_inputs, effective_feed,
                                    profile_constants, raw_columns, sun_inputs)
from feedlog.train.synthetic import synthetic_program


@pytest.fixture
def table() -> ProgramTable:
    return synthetic_program(30, seed=3, feed_mm_min=1200.0, tol_mm=0.05)


def test_sun_context_columns_shift_within_the_program(table):
    x = build_inputs(table.blocks, sun_inputs("x"))
    vx = table.blocks["vx_nom_mm_min"].to_numpy(np.float32)
    assert np.allclose(x[:, 4], vx)
    assert np.allclose(x[1:, 3], vx[:-1]) and x[0, 3] == 0.0          # n-1, at rest before the start
    assert np.allclose(x[:-1, 5], vx[1:]) and x[-1, 5] == 0.0         # n+1, at rest after the end
    corner_end = table.blocks["corner_end_deg"].to_numpy(np.float32)
    assert np.allclose(x[:-1, 2], corner_end[1:])                     # corner at CL point n+1


def test_missing_feature_is_named(table):
    blocks = table.blocks.drop(columns=["corner_end_deg"])
    with pytest.raises(ModelError, match="corner_end_deg.*needed by mlp"):
        build_inputs(blocks, sun_inputs("y"), what="mlp", source="prog.ngc")


def test_non_finite_input_names_column_and_block(table):
    blocks = table.blocks.copy()
    blocks.loc[7, "length_mm"] = np.nan
    with pytest.raises(ModelError, match=r"'length_mm' is not finite at row 7 \(block 7\)"):
        build_inputs(blocks, CHIEN_INPUTS)


def test_derived_inputs(table):
    blocks = table.blocks.copy()
    blocks["kind"] = ["rapid"] + ["linear"] * (len(blocks) - 1)
    blocks.loc[0, "feed_mm_min"] = np.nan
    blocks.loc[0, "nominal_time_s"] = blocks.loc[0, "length_mm"] / 6000.0 * 60.0
    blocks.loc[1, "tol_mm"] = np.nan
    feed = effective_feed(blocks)
    assert feed[0] == pytest.approx(6000.0) and feed[1] == pytest.approx(1200.0)
    x = build_inputs(blocks, ("tol_eff_mm", "xo_mm", "ori_tol_deg"), constants={"xo_mm": 12.5, "ori_tol_deg": 2.0})
    assert x[1, 0] == NO_TOLERANCE_MM and x[0, 0] == pytest.approx(0.05)
    assert np.all(x[:, 1] == 12.5) and np.all(x[:, 2] == 2.0)
    assert "xo_mm" not in raw_columns(CHIEN_INPUTS) and "tol_mm" in raw_columns(CHIEN_INPUTS)


def test_profile_constants_read_the_workpiece_offset():
    from feedlog.profile import load_profile

    prof = load_profile("chien-ac")
    c = profile_constants(prof)
    assert (c["xo_mm"], c["yo_mm"], c["zo_mm"]) == tuple(prof.kinematics.workpiece_offset_mm)
    assert profile_constants(None)["xo_mm"] == 0.0


def test_normaliser_round_trip_and_constant_columns():
    rng = np.random.default_rng(0)
    m = np.column_stack([rng.normal(5, 3, 100), np.full(100, 7.0)])
    n = Normaliser.fit(m)
    z = n.apply(m)
    assert abs(z[:, 0].mean()) < 1e-5 and abs(z[:, 0].std() - 1) < 1e-4
    assert np.all(z[:, 1] == 0.0)
    assert np.allclose(n.invert(z), m, atol=1e-4)
    assert Normaliser.from_dict(n.to_dict()) == n
    with pytest.raises(ModelError, match="malformed"):
        Normaliser.from_dict({"mean": [1.0]})


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 300), length=st.integers(1, 40), stride_frac=st.floats(0.1, 1.0))
def test_windows_cover_and_stitch_back_exactly(n, length, stride_frac):
    stride = max(1, int(length * stride_frac))
    x = np.arange(n, dtype=np.float32)[:, None] * np.ones((1, 2), np.float32)
    xw, yw, mask = make_windows(x, x[:, 0], length=length, stride=stride)
    assert xw.shape[1:] == (length, 2) and mask.sum(axis=1).min() >= 1
    starts = window_starts(n, length, stride)
    assert starts[0] == 0 and (n <= length or starts[-1] == n - length)
    # the identity "model": each window predicts its own row index
    back = stitch_windows(yw, n, length=length, stride=stride)
    assert np.array_equal(back, np.arange(n, dtype=np.float32))


def test_window_arguments_are_checked():
    with pytest.raises(ModelError, match="window length and stride"):
        window_starts(10, 0, 1)


def test_tail_split():
    assert tail_split(10, 0.2) == 8
    assert tail_split(1, 0.5) == 1 and tail_split(10, 0.0) == 10


def test_fingerprint_follows_the_data(table):
    cols = ["length_mm", "duration_s"]
    a = fingerprint([table], cols)
    assert a == fingerprint([table], cols)
    changed = ProgramTable(table.name, table.blocks.assign(duration_s=table.blocks["duration_s"] * 1.001))
    assert fingerprint([changed], cols) != a
    assert fingerprint([table], ["length_mm"]) != a


def test_program_table_checks():
    blocks = pd.DataFrame({"block": [2, 1], "duration_s": [1.0, -1.0], "nominal_time_s": [0.5, 0.5]})
    t = ProgramTable("rec", blocks)
    assert list(t.blocks["block"]) == [1, 2] and t.cam_time_s == 1.0
    with pytest.raises(ModelError, match="block 1 has an invalid measured duration"):
        t.durations()
    with pytest.raises(ModelError, match="split must be one of"):
        ProgramTable("rec", blocks, split="validation")


def test_align_output_glob_gives_the_recordings_not_the_dataset(tmp_path):
    """`feedlog train aligned/*`: the shell passes align's dataset/ too; it repeats the recordings' tables."""
    import pytest

    from feedlog.errors import ModelError
    from feedlog.train.load import expand_aligned

    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "blocks.parquet").write_bytes(b"")
    (tmp_path / "dataset" / "blocks" / "recording=a").mkdir(parents=True)
    assert expand_aligned(sorted(tmp_path.iterdir())) == [tmp_path / "a", tmp_path / "b"]
    assert expand_aligned([tmp_path]) == [tmp_path / "a", tmp_path / "b"]
    with pytest.raises(ModelError, match="align's partitioned dataset; pass the folder align wrote"):
        expand_aligned([tmp_path / "dataset"])
    (tmp_path / "c").mkdir()
    with pytest.raises(ModelError, match="holds no aligned recordings"):
        expand_aligned([tmp_path / "a", tmp_path / "c"])
