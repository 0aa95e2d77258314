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


def test_models_trained_side_by_side_on_workers_are_the_ones_trained_one_after_the_other(tmp_path):
    """Each model is seeded and trains on one thread, so two worker processes give the weights, and the
    test figures, that training them here one after the other gives."""
    from feedlog.execution import task_runner

    tables = synthetic_set(n_train=4, n_test=2, n_blocks=60, seed=11, sim_acc_factor=None)
    kw = dict(models=["mlp", "bilstm-block", "bilstm-final"], preset="quick", seed=5, progress=False,
              overrides={m: {"epochs": 3} for m in ("mlp", "bilstm-block", "bilstm-final")}, log=lambda _: None)
    with task_runner(jobs=1, progress=False) as here:
        one = train_and_evaluate(tables, out_dir=tmp_path / "one", runner=here, **kw)
    with task_runner(jobs=2, progress=False) as two:
        assert two.name == "processes"
        side = train_and_evaluate(tables, out_dir=tmp_path / "two", runner=two, **kw)
    pd.testing.assert_frame_equal(one, side, check_exact=True)
    for name in kw["models"]:
        assert one.attrs["summary"][name]["fingerprint"] == side.attrs["summary"][name]["fingerprint"]
        assert one[f"{name}_s"].notna().all()
