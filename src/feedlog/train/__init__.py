"""feedlog.train: learn a machine's feed behaviour from aligned recordings and predict cycle times.

    tables = load_many(["aligned/"])                     # ProgramTable per recording, split from the manifest
    results = train_and_evaluate(tables, out_dir="models", models=["mlp", "bilstm-block"], preset="quick")
    prediction = predict_program("part.ngc", "models/bilstm-block.pt")   # .cycle_time_s, .blocks

Models (registry: `model_names()`, `make_model(name, preset=..., **overrides)`): `mlp` (Sun et al.
per-axis MLP), `bilstm-block` and `bilstm-final` (Chien et al. Fig. 7 and 8), `bilstm-r` (Lee et
al.), `hybrid` (simulation + learned residual). `SeriesModel` is BiLSTM-R on dense series (any target
channel per sample). See docs/train.md.
"""

from feedlog.train.checkpoint import load_checkpoint, save_checkpoint
from feedlog.train.dataset import ProgramTable, fingerprint
from feedlog.train.evaluate import DEFAULT_MODELS, format_results, train_and_evaluate
from feedlog.train.load import load_aligned, load_many
from feedlog.train.predict import Prediction, predict_program
from feedlog.train.registry import MODELS, Model, ModelConfig, make_config, make_model, model_names
from feedlog.train.series import SeriesConfig, SeriesModel

__all__ = ["DEFAULT_MODELS", "MODELS", "Model", "ModelConfig", "Prediction", "ProgramTable", "fingerprint",
           "format_results", "load_aligned", "load_checkpoint", "load_many", "make_config", "make_model",
           "model_names", "predict_program", "save_checkpoint", "SeriesConfig", "SeriesModel", "train_and_evaluate"]
