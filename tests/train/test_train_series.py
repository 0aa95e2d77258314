"""BiLSTM-R on dense series: learns a lagged response, saves and loads, refuses bad input."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.signal import lfilter

from feedlog.errors import ModelError
from feedlog.train.series import SeriesConfig, SeriesModel


def _frame(seed: int, n: int = 800) -> pd.DataFrame:
    """A commanded feed in steps and the actual feed: a first-order lag of it (time constant ~8 samples)."""
    rng = np.random.default_rng(seed)
    command = np.repeat(rng.uniform(500, 3000, n // 40), 40)
    actual = lfilter([0.12], [1.0, -0.88], command - command[0]) + command[0]
    return pd.DataFrame({"cmd_feed_mm_min": command, "feed_mm_min": actual})


def test_series_model_learns_a_lag_and_round_trips(tmp_path):
    cfg = SeriesConfig(inputs=("cmd_feed_mm_min",), target="feed_mm_min", hidden=12, window=64, stride=32,
                       epochs=25, patience=25, dropout=0.0, lr=0.01)
    model = SeriesModel(cfg).fit([_frame(i) for i in range(4)], progress=False)
    test = _frame(99)
    pred = model.predict(test)
    truth = test["feed_mm_min"].to_numpy()
    naive = np.sqrt(np.mean((test["cmd_feed_mm_min"].to_numpy() - truth) ** 2))  # "feed = command"
    learned = np.sqrt(np.mean((pred - truth) ** 2))
    assert pred.shape == truth.shape and learned < 0.7 * naive
    path = model.save(tmp_path / "feed.pt")
    assert np.allclose(SeriesModel.load(path).predict(test), pred, rtol=1e-5)
    with pytest.raises(ModelError, match="refusing to overwrite"):
        model.save(path)
    with pytest.raises(ModelError, match="lacks column.*cmd_feed_mm_min"):
        model.predict(test.drop(columns=["cmd_feed_mm_min"]))


def test_series_config_is_checked():
    with pytest.raises(ModelError, match="also an input"):
        SeriesConfig(inputs=("a", "y"), target="y")
    with pytest.raises(ModelError, match="stride"):
        SeriesConfig(inputs=("a",), target="y", window=8, stride=16)
    with pytest.raises(ModelError, match="not trained"):
        SeriesModel(SeriesConfig(inputs=("a",), target="y")).predict(pd.DataFrame({"a": [1.0]}))
