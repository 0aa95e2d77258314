"""bilstm-final: Chien §2.5's crop-length rule applied per predicted chunk over a range of lengths."""

from __future__ import annotations

import numpy as np
import pytest

from feedlog.errors import ModelError
from feedlog.train import ProgramTable, make_config
from feedlog.train.dataset import fingerprint
from feedlog.train.model_final import FinalBiLSTM
from feedlog.train.synthetic import synthetic_set

TINY = {"epochs": 2, "hidden": 8, "crops": 32, "crop_range": (16, 64)}


def _fit(tables: list[ProgramTable]) -> FinalBiLSTM:
    m = FinalBiLSTM(make_config("bilstm-final", **TINY))
    train = [t for t in tables if t.split == "train"]
    m.fit(train, progress=False)
    m.fingerprint = fingerprint(train, m.required_columns + ["duration_s"])
    return m


@pytest.fixture(scope="module")
def model() -> FinalBiLSTM:
    tables = synthetic_set(n_train=2, n_test=1, n_blocks=150, seed=3)
    m = _fit(tables)
    m.tables = tables  # type: ignore[attr-defined]
    return m


def test_range_mode_is_the_default_and_records_its_range(model):
    assert make_config("bilstm-final").crop_mode == "auto"
    assert model.params["crop_mode"] == "range"
    assert (model.params["min_blocks"], model.params["max_blocks"]) == (16, 64)


@pytest.mark.parametrize("n", [16, 40, 64, 65, 100, 129, 1000, 3143])
def test_every_chunk_of_a_long_program_lies_in_the_trained_range(model, n):
    parts = model.chunks(n)
    assert np.array_equal(np.concatenate(parts), np.arange(n))
    assert all(16 <= len(p) <= 64 for p in parts)
    assert len(parts) == -(-n // 64)  # as few passes as the range allows


def test_crop_lengths_cover_the_range_log_uniformly(model):
    lengths = model._crop_lengths(np.random.default_rng(0), 20000, 16, 64)
    assert lengths.min() == 16 and lengths.max() == 64
    # log-uniform: as many crops in 16-32 as in 32-64 blocks
    short, long_ = np.sum(lengths < 32), np.sum(lengths >= 32)
    assert abs(short - long_) < 0.05 * len(lengths)


def test_short_programs_are_flagged_and_long_ones_are_not(model):
    blocks = model.tables[0].blocks
    short = model.predict(ProgramTable("short", blocks.iloc[:10].reset_index(drop=True)))
    assert any("outside the trained length range 16-64" in n for n in short.notes)
    full = model.predict(ProgramTable("full", blocks))
    assert full.notes == [] and full.cycle_time_s > 0


def test_fit_is_deterministic(model):
    again = _fit(model.tables)
    table = model.tables[-1]
    assert again.predict(table).cycle_time_s == model.predict(table).cycle_time_s


@pytest.mark.parametrize("bad", [{"crop_range": (16, 20)}, {"crop_range": (1, 64)}, {"crop_mode": "median"}])
def test_bad_crop_settings_are_refused(bad):
    with pytest.raises(ModelError):
        make_config("bilstm-final", **bad)
