"""The hybrid keeps as much of its learned correction as helps on validation programs (none: the simulation)."""

from __future__ import annotations

import numpy as np
import torch

from feedlog.train import ProgramTable, make_model
from feedlog.train.model_hybrid import SCALES, SIM_COLUMN
from feedlog.train.synthetic import synthetic_set

FAST = {"epochs": 6, "hidden": 8, "window": 32, "stride": 16, "val_by": "program"}


def _fit(tables: list[ProgramTable]):
    model = make_model("hybrid", **FAST)
    model.fit([t for t in tables if t.split == "train"], progress=False)
    model.fingerprint = "test"
    return model


def test_a_correction_that_helps_is_kept():
    # the simulation's acceleration is 50 % too high: its times are systematically short
    tables = synthetic_set(n_train=6, n_test=1, n_blocks=200, seed=3, noise=0.002, feeds=(3000.0, 6000.0),
                           sim_acc_factor=1.5)
    model = _fit(tables)
    errors = model.report["correction_scale_errors_pct"]
    assert len(errors) == len(SCALES) and model.params["correction_scale"] > 0
    assert min(errors) < errors[0]  # some correction beats the simulation on the held-out programs
    test = tables[-1]
    sim = test.blocks[SIM_COLUMN].sum()
    assert abs(model.predict(test).cycle_time_s - test.measured_cycle_time_s) < abs(sim - test.measured_cycle_time_s)


def test_a_correction_that_does_not_help_is_dropped():
    # the simulation is exact; a net that has learned a spurious +50 % correction must not be used
    tables = synthetic_set(n_train=6, n_test=1, n_blocks=120, seed=4, noise=0.0, sim_acc_factor=1.0)
    train = [t for t in tables if t.split == "train"]
    model = _fit(tables)
    with torch.no_grad():
        model.nets["net"].head.bias.fill_(float(np.log(1.5) / model.norms["y"].std[0]))
    model.params["residual_range"] = [-1.0, 1.0]  # (training saw only 0: the clip alone would hide it)
    assert model._choose_scale(train) == 0.0
    errors = model.report["correction_scale_errors_pct"]
    assert errors[0] < 1e-6 and all(e > 5.0 for e in errors[1:])
    model.params["correction_scale"] = 0.0
    test = tables[-1]
    assert np.isclose(model.predict(test).cycle_time_s, test.blocks[SIM_COLUMN].sum(), rtol=1e-9)
