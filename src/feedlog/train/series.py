"""BiLSTM-R on dense time series (Lee et al.): any target channel from any input channels, per sample.

Lee et al. predict the cutting force at every sample (12.8 kHz) from 128-sample windows of monitoring
channels. `SeriesModel` does that for feedlog's tables: e.g. the measured feed per CL point from
align's `points.parquet` (`inputs=("programmed_feed_mm_min", "corner_start_deg", ...)`,
`target="feed_meas_mm_min"`), or a recording stream resampled onto one time base. Frames are
sequences in row order; each is cut into overlapping windows for training and stitched back per
sample for prediction (the window centred nearest to a sample gives its value).

    model = SeriesModel(SeriesConfig(inputs=("a", "b"), target="y")).fit(frames)
    y_hat = model.predict(frame)            # one value per row
    model.save("feed.series.pt"); SeriesModel.load("feed.series.pt")
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch

from feedlog.errors import ModelError
from feedlog.train.dataset import make_windows, stitch_windows, tail_split
from feedlog.train.features import Normaliser, require
from feedlog.train.fitting import masked_mse, setup_torch, train_net
from feedlog.train.nets import BiLSTMR

FORMAT = "feedlog-series-model"
FORMAT_VERSION = 1


@dataclass(frozen=True)
class SeriesConfig:
    inputs: tuple[str, ...]
    target: str
    hidden: int = 32
    units: int = 2
    dropout: float = 0.3
    window: int = 128
    stride: int = 64
    epochs: int = 60
    lr: float = 0.002
    batch_size: int = 32
    patience: int = 10
    val_fraction: float = 0.2
    seed: int = 0

    def __post_init__(self) -> None:
        if not self.inputs or not self.target:
            raise ModelError(f"SeriesConfig needs input columns and a target, got {self.inputs!r}, {self.target!r}")
        if self.target in self.inputs:
            raise ModelError(f"SeriesConfig: the target {self.target!r} is also an input")
        if min(self.hidden, self.units, self.epochs, self.batch_size, self.patience) < 1 or not 0 <= self.dropout < 1:
            raise ModelError(f"SeriesConfig: hidden, units, epochs, batch_size, patience must be >= 1 and dropout "
                             f"in [0, 1), got {self.hidden}, {self.units}, {self.epochs}, {self.batch_size}, "
                             f"{self.patience}, {self.dropout}")
        if not 1 <= self.stride <= self.window:
            raise ModelError(f"SeriesConfig: need 1 <= stride <= window, got {self.stride}, {self.window}")


class SeriesModel:
    def __init__(self, config: SeriesConfig) -> None:
        self.config = config
        setup_torch(config.seed)
        self.net = BiLSTMR(len(config.inputs), config.hidden, config.units, config.dropout)
        self.norms: dict[str, Normaliser] = {}
        self.report: dict[str, Any] = {}

    def _matrix(self, frame: pd.DataFrame, columns: Sequence[str], source: str) -> np.ndarray:
        require(frame, columns, what=f"series model ({self.config.target})", source=source)
        m = frame[list(columns)].to_numpy(np.float64)
        bad = ~np.isfinite(m)
        if bad.any():
            row, col = np.argwhere(bad)[0]
            raise ModelError(f"{source + ': ' if source else ''}column {columns[col]!r} is not finite at row {row}")
        return m

    def fit(self, frames: Sequence[pd.DataFrame], *, progress: bool = True) -> SeriesModel:
        cfg = self.config
        if not frames:
            raise ModelError("series model: no training frames")
        xs = [self._matrix(f, cfg.inputs, f"frame {i}") for i, f in enumerate(frames)]
        ys = [self._matrix(f, (cfg.target,), f"frame {i}")[:, 0] for i, f in enumerate(frames)]
        heads = [tail_split(len(y), cfg.val_fraction) for y in ys]
        self.norms = {"x": Normaliser.fit(np.concatenate([x[:h] for x, h in zip(xs, heads)])),
                      "y": Normaliser.fit(np.concatenate([y[:h] for y, h in zip(ys, heads)]), bounds=False)}
        parts: dict[str, list] = {"train": [], "val": []}
        for x, y, h in zip(xs, ys, heads):
            xn, yn = self.norms["x"].apply(x), self.norms["y"].apply(y[:, None])[:, 0]
            parts["train"].append(make_windows(xn[:h], yn[:h], length=cfg.window, stride=cfg.stride))
            if h < len(y):
                parts["val"].append(make_windows(xn[h:], yn[h:], length=cfg.window, stride=cfg.stride))
        data = {k: tuple(torch.from_numpy(np.concatenate([p[i] for p in v]).astype(np.float32)) for i in range(3))
                if v else None for k, v in parts.items()}

        def loss_fn(net, idx, split):
            xb, yb, mb = data[split]
            if idx is not None:
                xb, yb, mb = xb[idx], yb[idx], mb[idx]
            return masked_mse(net(xb), yb, mb)

        self.report = train_net(self.net, loss_fn, n_train=len(data["train"][0]),
                                n_val=0 if data["val"] is None else len(data["val"][0]), seed=cfg.seed,
                                epochs=cfg.epochs, lr=cfg.lr, batch_size=cfg.batch_size, patience=cfg.patience,
                                desc=f"bilstm-r {cfg.target}", progress=progress)
        return self

    def predict(self, frame: pd.DataFrame, *, source: str = "") -> np.ndarray:
        if not self.norms:
            raise ModelError("series model is not trained")
        setup_torch()
        cfg = self.config
        x = self.norms["x"].apply(self._matrix(frame, cfg.inputs, source))
        if len(x) == 0:
            return np.zeros(0)
        xw, _, _ = make_windows(x, None, length=cfg.window, stride=cfg.stride)
        self.net.eval()
        with torch.no_grad():
            out = np.concatenate([self.net(torch.from_numpy(xw[i:i + 2048])).numpy() for i in range(0, len(xw), 2048)])
        return self.norms["y"].invert(stitch_windows(out, len(x), length=cfg.window, stride=cfg.stride)[:, None])[:, 0]

    def save(self, path: str | Path, *, overwrite: bool = False) -> Path:
        path = Path(path)
        if path.exists() and not overwrite:
            raise ModelError(f"{path} exists; refusing to overwrite it")
        if not self.norms:
            raise ModelError("series model is not trained")
        config = {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(self.config).items()}
        torch.save({"format": FORMAT, "format_version": FORMAT_VERSION, "config": config,
                    "norms": {k: v.to_dict() for k, v in self.norms.items()}, "net": self.net.state_dict()}, path)
        return path

    @classmethod
    def load(cls, path: str | Path) -> SeriesModel:
        path = Path(path)
        try:
            data = torch.load(path, map_location="cpu", weights_only=True)
        except Exception as exc:  # torch raises many kinds for a file that is not a checkpoint
            raise ModelError(f"{path}: not a feedlog series model ({type(exc).__name__}: {exc})") from None
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise ModelError(f"{path}: not a feedlog series model")
        if int(data.get("format_version", 0)) > FORMAT_VERSION:
            raise ModelError(f"{path}: series model format version {data['format_version']} is not supported")
        config = {k: (tuple(v) if isinstance(v, list) else v) for k, v in data["config"].items()}
        model = cls(SeriesConfig(**config))
        model.norms = {k: Normaliser.from_dict(v) for k, v in data["norms"].items()}
        model.net.load_state_dict(data["net"])
        model.net.eval()
        return model
