"""One suite over every registered model: train, predict, checkpoint round trip, determinism, refusals."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from feedlog.errors import ModelError
from feedlog.train import (ProgramTable, load_checkpoint, make_config, make_model, model_names, save_checkpoint,
                           train_and_evaluate)
from feedlog.train.dataset import fingerprint
from feedlog.train.model_final import FinalBiLSTM
from feedlog.train.synthetic import synthetic_set

TINY = {"mlp": {"epochs": 8}, "bilstm-block": {"epochs": 4, "hidden": 8, "window": 32, "stride": 16},
        "bilstm-final": {"epochs": 3, "hidden": 8, "crops": 24, "crop_blocks": 40},
        "bilstm-r": {"epochs": 3, "hidden": 8, "window": 32, "stride": 16},
        "hybrid": {"epochs": 4, "hidden": 8, "window": 32, "stride": 16}}


@pytest.fixture(scope="module")
def data() -> list[ProgramTable]:
    return synthetic_set(n_train=2, n_test=1, n_blocks=120, seed=7)


def _fit(name: str, tables: list[ProgramTable]):
    model = make_model(name, **TINY[name])
    train = [t for t in tables if t.split == "train"]
    model.fit(train, progress=False)
    model.fingerprint = fingerprint(train, model.required_columns + ["duration_s"])
    return model


def test_registry_lists_every_model():
    assert set(model_names()) >= {"mlp", "bilstm-block", "bilstm-final", "bilstm-r", "hybrid"}
    with pytest.raises(ModelError, match="unknown model .lstm.; known: .*mlp"):
        make_model("lstm")
    with pytest.raises(ModelError, match="unknown config field.*hiden"):
        make_config("bilstm-block", hiden=3)
    with pytest.raises(ModelError, match="stride <= window"):
        make_config("bilstm-block", window=8, stride=9)
    with pytest.raises(ModelError, match="unknown preset"):
        make_config("mlp", preset="fast")
    assert make_config("bilstm-block", preset="quick").epochs < make_config("bilstm-block").epochs


@pytest.mark.parametrize("name", sorted(TINY))
def test_model_trains_predicts_round_trips_and_is_deterministic(name, data, tmp_path):
    test = next(t for t in data if t.split == "test")
    a = _fit(name, data)
    pred = a.predict(test)
    assert np.isfinite(pred.cycle_time_s) and pred.cycle_time_s > 0
    if pred.durations_s is not None:
        assert pred.durations_s.shape == (len(test.blocks),) and np.all(pred.durations_s >= 0)
        assert pred.cycle_time_s == pytest.approx(pred.durations_s.sum())

    path = save_checkpoint(a, tmp_path / f"{name}.pt")
    with pytest.raises(ModelError, match="refusing to overwrite"):
        save_checkpoint(a, path)
    b = load_checkpoint(path)
    assert (b.name, b.fingerprint, b.inputs, b.config) == (a.name, a.fingerprint, a.inputs, a.config)
    assert b.predict(test).cycle_time_s == pytest.approx(pred.cycle_time_s, rel=1e-6)

    again = _fit(name, data)  # same seed, same data -> same weights
    for key, net in a.nets.items():
        for (k, p), q in zip(net.state_dict().items(), again.nets[key].state_dict().values()):
            assert torch.equal(p, q), f"{name}.{key}.{k} differs between two seeded runs"

    needed = a.required_columns[0]
    lacking = ProgramTable(test.name, test.blocks.drop(columns=[needed]))
    with pytest.raises(ModelError, match=f"lacks column.*{needed}"):
        b.predict(lacking)


def test_untrained_and_broken_checkpoints(tmp_path):
    model = make_model("mlp")
    with pytest.raises(ModelError, match="not trained"):
        save_checkpoint(model, tmp_path / "m.pt")
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"not a checkpoint")
    with pytest.raises(ModelError, match="junk.pt: not a feedlog model checkpoint"):
        load_checkpoint(junk)
    with pytest.raises(ModelError, match="checkpoint not found"):
        load_checkpoint(tmp_path / "absent.pt")


def _saved_mlp(data, tmp_path):
    """A trained MLP saved to tmp_path / m.pt, and its raw checkpoint dict to edit."""
    path = save_checkpoint(_fit("mlp", data), tmp_path / "m.pt")
    return path, torch.load(path, weights_only=True)


def test_newer_checkpoint_format_is_refused(data, tmp_path):
    path, raw = _saved_mlp(data, tmp_path)
    raw["format_version"] = 99
    torch.save(raw, path)
    with pytest.raises(ModelError, match="format version 99 is not supported"):
        load_checkpoint(path)


def test_a_version_1_checkpoint_keeps_the_cam_base_it_was_trained_with(data, tmp_path):
    path, raw = _saved_mlp(data, tmp_path)
    assert load_checkpoint(path).config.base == "kinematic"
    raw["format_version"] = 1
    del raw["config"]["base"]
    torch.save(raw, path)
    assert load_checkpoint(path).config.base == "cam"


@pytest.mark.parametrize("version", [2, 3, 4])
def test_an_older_kinematic_model_is_refused_and_a_cam_one_loads(data, tmp_path, version):
    """Versions 2 to 4 learned their factors on earlier kinematic base times: predicting with them would be wrong."""
    path, raw = _saved_mlp(data, tmp_path)
    raw["format_version"] = version
    torch.save(raw, path)
    with pytest.raises(ModelError, match=f"m.pt: .*kinematic base time of checkpoint format {version}.*retrain"):
        load_checkpoint(path)
    raw["config"]["base"] = "cam"
    torch.save(raw, path)
    assert load_checkpoint(path).config.base == "cam"


def test_final_model_chunks_long_programs(data):
    model = _fit("bilstm-final", data)
    assert model.params["crop_blocks"] == 40 and model.params["min_blocks"] == 38
    parts = model.chunks(205)
    assert len(parts) == 5 and sum(len(p) for p in parts) == 205
    short = ProgramTable("short", data[0].blocks.iloc[:10].reset_index(drop=True))
    assert any("outside the trained length range" in n for n in model.predict(short).notes)


def test_final_model_takes_its_crop_length_from_the_targets(data):
    model = FinalBiLSTM(make_config("bilstm-final", **{**TINY["bilstm-final"], "crop_blocks": 0,
                                                          "crop_mode": "fixed"}),
                        target_lengths=[50, 60, 70])
    model.fit([t for t in data if t.split == "train"], progress=False)
    assert model.params["crop_blocks"] == 60


def test_learning_beats_cam_on_held_out_programs(tmp_path):
    """On programs whose block times follow a known kinematic law, the learners beat L/F (CAM)."""
    tables = synthetic_set(n_train=4, n_test=2, n_blocks=300, seed=1, noise=0.002, feeds=(3000.0, 6000.0))
    results = train_and_evaluate(tables, out_dir=tmp_path, models=["bilstm-block", "hybrid"], preset="quick",
                                 progress=False, log=lambda m: None)
    cam = np.abs(results["cam_err_pct"]).mean()
    assert cam > 5.0  # the law is far from L/F ...
    assert np.abs(results["bilstm-block_err_pct"]).mean() < cam / 2  # ... and learnable
    # the hybrid corrects a simulation whose acceleration is 50 % too high
    assert np.abs(results["hybrid_err_pct"]).mean() < np.abs(results["sim_err_pct"]).mean()
    assert (tmp_path / "results.md").read_text().count("|") > 10
    assert (tmp_path / "predictions" / "test-4.parquet").is_file()


def test_spread_merged_shares_a_group_time_by_length():
    from feedlog.train.model_hybrid import spread_merged

    times = np.array([0.0, 0.0, 3.0, 1.0, 0.0, 0.0])  # blocks 0-2 merged into 2; 4-5 trail with no time
    lengths = np.array([1.0, 2.0, 3.0, 5.0, 1.0, 1.0])
    out = spread_merged(times, lengths)
    assert np.allclose(out, [0.5, 1.0, 1.5, 1.0, 0.0, 0.0])
    assert out.sum() == pytest.approx(times.sum())


def test_validation_heads():
    from feedlog.train.model_seq import validation_heads

    by_program = validation_heads([10, 20, 30, 40, 50], fraction=0.2, by="program", seed=0)
    assert sorted(by_program).count(0) == 1 and set(by_program) - {0} <= {10, 20, 30, 40, 50}
    assert validation_heads([10, 20], fraction=0.2, by="program", seed=0) == [8, 16]  # too few programs
    assert validation_heads([10, 20, 30], fraction=0.2, by="tail", seed=0) == [8, 16, 24]


def test_inputs_are_clipped_to_the_training_range():
    from feedlog.train.features import Normaliser

    n = Normaliser.fit(np.array([[0.0], [1.0], [2.0]]))
    assert n.apply(np.array([[100.0]]))[0, 0] == pytest.approx(n.apply(np.array([[2.0]]))[0, 0])
    assert Normaliser.fit(np.array([[0.0], [2.0]]), bounds=False).lo is None


def test_hybrid_skips_only_the_recordings_it_cannot_simulate(tmp_path):
    tables = synthetic_set(n_train=2, n_test=2, n_blocks=80, seed=2)
    lost = tables[-1]
    tables[-1] = ProgramTable(lost.name, lost.blocks.drop(columns=["sim_duration_s"]), split="test")
    notes: list[str] = []
    results = train_and_evaluate(tables, out_dir=tmp_path, models=["hybrid"], preset="quick",
                                 overrides={"hybrid": TINY["hybrid"]}, progress=False, log=notes.append)
    assert np.isfinite(results["hybrid_err_pct"].iloc[0]) and np.isnan(results["hybrid_err_pct"].iloc[1])
    assert any("simulation unavailable for test-3" in n for n in notes)
    assert "test-3: not predicted (no simulation)" in results.attrs["summary"]["hybrid"]["notes"]
