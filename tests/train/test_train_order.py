"""The same recordings and seed train the same models whatever order the tables come in: `feedlog train`
(folders in the shell's order) and `feedlog demo` (manifest order) then report the same numbers."""

from __future__ import annotations

import pandas as pd

from feedlog.train.evaluate import train_and_evaluate
from feedlog.train.synthetic import synthetic_set


def _run(tables, out):
    results = train_and_evaluate(tables, out_dir=out, models=["mlp"], preset="quick", seed=3, progress=False,
                                 overrides={"mlp": {"epochs": 4}}, log=lambda _: None)
    return results.sort_values("recording").reset_index(drop=True), results.attrs["summary"]["mlp"]["fingerprint"]


def test_table_order_does_not_change_the_trained_model(tmp_path):
    tables = synthetic_set(n_train=4, n_test=1, n_blocks=60, seed=7, sim_acc_factor=None)
    a, fa = _run(tables, tmp_path / "a")
    b, fb = _run(list(reversed(tables)), tmp_path / "b")
    assert fa == fb
    pd.testing.assert_frame_equal(a, b)
    assert a["mlp_s"].notna().all()
