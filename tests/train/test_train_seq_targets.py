"""Targets of the block-by-block sequence models: the sum-consistent CAM factor ("cam_sum")."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from feedlog.errors import ModelError
from feedlog.train import make_config, make_model
from feedlog.train.dataset import window_sums
from feedlog.train.features import limited_time
from feedlog.train.model_seq import RATIO_FLOOR_S, window_sum_loss
from feedlog.train.synthetic import synthetic_set


def test_window_sum_loss_is_the_log_error_of_neighbour_sums():
    rng = np.random.default_rng(3)
    factor, measured, cam = rng.normal(0, 0.3, 40), rng.uniform(0.01, 0.5, 40), rng.uniform(0.01, 0.5, 40)
    span = 3
    pred = cam * np.exp(factor)
    diff = np.log(window_sums(pred, span) + RATIO_FLOOR_S) - np.log(window_sums(measured, span) + RATIO_FLOOR_S)
    t = lambda a: torch.tensor(a[None, :], dtype=torch.float64)  # noqa: E731
    full = window_sum_loss(t(factor), t(measured), t(cam), torch.ones(1, 40, dtype=torch.float64), span=span)
    assert float(full) == pytest.approx(np.mean(diff ** 2), rel=1e-9)

    # padding (mask 0) is left out of both sums and of the mean: whatever it holds changes nothing
    mask = np.r_[np.ones(30), np.zeros(10)]
    noisy = measured.copy()
    noisy[30:] = 99.0
    head = window_sum_loss(t(factor), t(noisy), t(cam), t(mask), span=span)
    d30 = (np.log(window_sums(pred[:30], span) + RATIO_FLOOR_S)
           - np.log(window_sums(measured[:30], span) + RATIO_FLOOR_S))
    assert float(head) == pytest.approx(np.mean(d30 ** 2), rel=1e-9)
    # a perfect factor has zero loss
    exact = np.log(measured / cam)
    assert float(window_sum_loss(t(exact), t(measured), t(cam), t(np.ones(40)), span=span)) == pytest.approx(0, abs=1e-20)


def test_target_mode_is_checked():
    with pytest.raises(ModelError, match="target_mode must be one of cam_ratio, cam_sum, log"):
        make_config("bilstm-block", target_mode="sum")
    with pytest.raises(ModelError, match="hybrid learns its own residual"):
        make_config("hybrid", target_mode="cam_sum")
    with pytest.raises(ModelError, match="hybrid trains one net"):
        make_config("hybrid", members=3)
    with pytest.raises(ModelError, match="members must be >= 1"):
        make_config("bilstm-r", members=0)
    assert make_config("bilstm-block").target_mode == "cam_sum"
    assert make_config("bilstm-block", target_mode="cam_ratio").batch_size == 64


def test_cam_sum_learns_block_times_that_add_up():
    """Trained on a known kinematic law, the CAM-factor model beats CAM on unseen programs (the CAM base:
    the default kinematic base starts close to that law)."""
    tables = synthetic_set(n_train=4, n_test=2, n_blocks=300, seed=1, noise=0.002, feeds=(3000.0, 6000.0))
    train = [t for t in tables if t.split == "train"]
    test = [t for t in tables if t.split == "test"]
    model = make_model("bilstm-block", preset="quick", target_mode="cam_sum", base="cam")
    untrained = make_model("bilstm-block", preset="quick", target_mode="cam_sum", base="cam", epochs=1, patience=1,
                           lr=1e-9)
    model.fit(train, progress=False)
    untrained.fit(train, progress=False)
    model.fingerprint = untrained.fingerprint = "synthetic"
    for t in test:
        cam = limited_time(t.blocks, name=t.name, needed_by="test").sum()
        # an (almost) untrained net predicts about CAM: its factors start near 1
        assert untrained.predict(t).cycle_time_s == pytest.approx(cam, rel=0.15)
        pred = model.predict(t)
        assert pred.cycle_time_s == pytest.approx(pred.durations_s.sum())
        err = abs(pred.cycle_time_s / t.measured_cycle_time_s - 1)
        cam_err = abs(cam / t.measured_cycle_time_s - 1)
        assert cam_err > 0.05 and err < cam_err / 2, (t.name, err, cam_err)


def test_an_ensemble_averages_its_members_and_round_trips(tmp_path):
    from feedlog.train import load_checkpoint, save_checkpoint

    tables = synthetic_set(n_train=2, n_test=1, n_blocks=120, seed=7)
    train = [t for t in tables if t.split == "train"]
    test = next(t for t in tables if t.split == "test")
    small = {"epochs": 3, "hidden": 6, "window": 32, "stride": 16}
    with pytest.raises(ModelError, match="members must be >= 1"):
        make_config("bilstm-block", members=0)
    one = make_model("bilstm-block", members=1, **small)
    three = make_model("bilstm-block", members=3, **small)
    for m in (one, three):
        m.fit(train, progress=False)
        m.fingerprint = "synthetic"
    assert sorted(three.nets) == ["net", "net1", "net2"] and set(three.report) >= {"net", "net1", "net2"}
    # member 0 is the single model's net; the others differ (their own seeds)
    for p, q in zip(one.nets["net"].state_dict().values(), three.nets["net"].state_dict().values()):
        assert torch.equal(p, q)
    assert not torch.equal(three.nets["net"].head.weight, three.nets["net1"].head.weight)
    # the ensemble's log factors are the mean of its members'
    singles = []
    for key in ("net", "net1", "net2"):
        alone = make_model("bilstm-block", members=1, **small)
        alone.norms, alone.constants, alone.fingerprint = three.norms, three.constants, "synthetic"
        alone.nets = {"net": three.nets[key]}
        singles.append(alone.predict_values(test))
    assert np.allclose(three.predict_values(test), np.mean(singles, axis=0), atol=1e-6)
    back = load_checkpoint(save_checkpoint(three, tmp_path / "ens.pt"))
    assert back.predict(test).cycle_time_s == pytest.approx(three.predict(test).cycle_time_s, rel=1e-6)
