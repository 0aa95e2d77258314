"""Sequence-to-sequence models over a program's blocks: Bi-LSTM block by block (Chien Fig. 7) and BiLSTM-R.

Long programs are cut into overlapping windows (`window` blocks, every `stride`) for training. Early
stopping watches `val_fraction` of the training programs held out whole (`val_by="program"`; the default
"auto" does so from 8 training programs on), or else the last `val_fraction` of every training program. Prediction uses longer
windows (`predict_window`, default 4 x window) overlapping by 2 x `predict_context`; each block's
value comes from the window whose centre is nearest, so every block sees at least `predict_context`
blocks on both sides (except at the program's ends) while few blocks are computed twice.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import torch

from feedlog.errors import ModelError
from feedlog.train.dataset import ProgramTable, make_windows, stitch_windows, tail_split, window_sums
from feedlog.train.features import CHIEN_INPUTS, Normaliser, build_inputs, profile_constants
from feedlog.train.fitting import masked_mse, setup_torch, train_net
from feedlog.train.nets import BiLSTMR, BiLSTMSeq
from feedlog.train.registry import Model, ModelConfig, TablePrediction, register_model

BASES = ("cam", "kinematic")

PREDICT_BATCH = 4096  # windows per forward pass at prediction time
LOG_FLOOR_S = 1e-3    # added to block times before the log target
VAL_BY = ("auto", "program", "tail")
AUTO_PROGRAMS = 8     # val_by="auto" holds out whole programs from this many training tables on
RATIO_FLOOR_S = 1e-4  # added to both sums of the CAM-ratio target
TARGET_MODES = ("cam_ratio", "cam_sum", "log")


@dataclass(frozen=True)
class SeqConfig(ModelConfig):
    inputs: tuple[str, ...] = CHIEN_INPUTS
    hidden: int = 20
    layers: int = 1
    window: int = 64
    stride: int = 32
    batch_size: int = 16
    epochs: int = 150
    patience: int = 20
    log_target: bool = True  # with target_mode "log": learn log(time + 1 ms), block times span four decades
    # "cam_ratio": learn r = log(measured / CAM time), CAM time = max(L / F, the axes' speed-limited time), both summed over 2 x ratio_span + 1 neighbouring
    # blocks, and predict CAM time x e^r per block (an untrained net is CAM; align may put a corner's
    # time on either side of a block boundary, which per-block targets would have to learn as noise);
    # "log": learn each block's own log time (Chien's per-block target)
    # "cam_sum": the net gives each block its own log factor on the CAM time, trained so that the predicted
    # block times summed over the same 2 x ratio_span + 1 neighbouring blocks match the measured sums (log
    # error): the factors may differ block by block (a short block after a long line), and the per-block
    # predictions add up to what the loss saw, which a smoothed "cam_ratio" target does not guarantee
    target_mode: str = "cam_ratio"
    ratio_span: int = 8
    # the time "CAM" stands for in the two modes above: "cam" (the limited CAM time) or "kinematic"
    # (`features.kin_time`: a trapezoid per block at the axes' limits, stopping or blending at corners,
    # joined by look-ahead, blend arcs as pieces; on 21 held-out training recordings bilstm-block 1.07 /
    # 1.25 % mean |error| with it (seeds 0 / 1), 5.13 % with "cam" (an earlier run), docs/train.md)
    base: str = "kinematic"
    # nets trained with seeds seed, seed + 1, ...; their per-block outputs are averaged
    members: int = 1
    # prediction runs longer windows (0: 4 x window) that overlap by 2 x predict_context blocks, so every
    # block still sees at least predict_context blocks on each side but few blocks are computed twice
    predict_window: int = 0
    predict_context: int = 16
    # early stopping on the tail of every training program ("tail"), on held-out whole programs
    # ("program", with >= 3 training tables: how the model does on programs it has not seen), or
    # "auto": whole programs when there are >= AUTO_PROGRAMS training tables, else tails
    val_by: str = "auto"

    presets: ClassVar[dict[str, dict[str, Any]]] = {"quick": {"epochs": 40, "patience": 8}}

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.inputs:
            raise ModelError(f"{type(self).__name__}.inputs must name at least one column")
        if self.hidden < 1 or self.layers < 1:
            raise ModelError(f"{type(self).__name__}: hidden and layers must be >= 1, got {self.hidden}, {self.layers}")
        if not 1 <= self.stride <= self.window:
            raise ModelError(f"{type(self).__name__}: need 1 <= stride <= window, got stride {self.stride}, "
                             f"window {self.window}")
        if self.target_mode not in TARGET_MODES or self.ratio_span < 0:
            raise ModelError(f"{type(self).__name__}: target_mode must be one of {', '.join(TARGET_MODES)} and "
                             f"ratio_span >= 0, "
                             f"got {self.target_mode!r}, {self.ratio_span}")
        if self.base not in BASES:
            raise ModelError(f"{type(self).__name__}.base must be one of {', '.join(BASES)}, got {self.base!r}")
        if self.members < 1:
            raise ModelError(f"{type(self).__name__}.members must be >= 1, got {self.members}")
        if self.val_by not in VAL_BY:
            raise ModelError(f"{type(self).__name__}.val_by must be one of {', '.join(VAL_BY)}, got {self.val_by!r}")
        if self.predict_context < 0 or 2 * self.predict_context >= self.prediction_window:
            raise ModelError(f"{type(self).__name__}: need 0 <= 2 x predict_context < prediction window, got "
                             f"predict_context {self.predict_context}, window {self.prediction_window}")

    @property
    def prediction_window(self) -> int:
        return self.predict_window or 4 * self.window


def validation_heads(lengths: Sequence[int], *, fraction: float, by: str, seed: int) -> list[int]:
    """Per table, the row where its validation part starts (0: the whole table validates)."""
    n = len(lengths)
    if by == "auto":
        by = "program" if n >= AUTO_PROGRAMS else "tail"
    if by == "program" and n >= 3 and fraction > 0:
        k = max(1, int(round(n * fraction)))
        held = set(np.random.default_rng(seed).choice(n, size=k, replace=False).tolist())
        return [0 if i in held else length for i, length in enumerate(lengths)]
    return [tail_split(length, fraction) for length in lengths]


def window_sum_loss(log_factor: torch.Tensor, measured: torch.Tensor, cam: torch.Tensor, mask: torch.Tensor,
                    *, span: int) -> torch.Tensor:
    """Mean squared log error of block times summed over 2 x span + 1 neighbours (within each window).

    Predicted block time = cam x e^log_factor; padded steps (mask 0) add nothing to either sum.
    """
    m = mask.to(cam.dtype)
    pred = cam * torch.exp(log_factor) * m
    meas = measured * m
    n = pred.shape[1]
    k = torch.arange(n)
    hi, lo = torch.clamp(k + span + 1, max=n), torch.clamp(k - span, min=0)

    def sums(v: torch.Tensor) -> torch.Tensor:
        c = torch.nn.functional.pad(torch.cumsum(v, dim=1), (1, 0))
        return c[:, hi] - c[:, lo]

    diff = torch.log(sums(pred) + RATIO_FLOOR_S) - torch.log(sums(meas) + RATIO_FLOOR_S)
    return (diff * diff * m).sum() / m.sum().clamp_min(1.0)


class SeqModel(Model):
    """Shared windowing, normalisation and training for per-block sequence models."""

    config: SeqConfig

    @property
    def inputs(self) -> tuple[str, ...]:
        return tuple(self.config.inputs)

    def target(self, table: ProgramTable) -> np.ndarray:
        """Per-block training target: the log ratio to CAM time over neighbouring blocks, or the block time."""
        if self.config.target_mode == "cam_ratio":
            span = self.config.ratio_span
            measured = window_sums(table.durations(), span)
            cam = window_sums(self.base_time(table), span)
            return np.log(measured + RATIO_FLOOR_S) - np.log(cam + RATIO_FLOOR_S)
        return table.durations()

    def to_durations(self, table: ProgramTable, values: np.ndarray) -> np.ndarray:
        """Per-block predicted target -> per-block time."""
        if self.config.target_mode == "cam_ratio":
            cam = self.base_time(table)
            return np.maximum((cam + RATIO_FLOOR_S) * np.exp(values) - RATIO_FLOOR_S, 0.0)
        if self.config.target_mode == "cam_sum":
            return self.base_time(table) * np.exp(values)
        return np.maximum(values, 0.0)

    def _encode(self, y: np.ndarray) -> np.ndarray:
        log = self.config.log_target and self.config.target_mode == "log"
        return np.log(np.maximum(y, 0.0) + LOG_FLOOR_S) if log else y

    def _decode(self, y: np.ndarray) -> np.ndarray:
        log = self.config.log_target and self.config.target_mode == "log"
        return np.exp(y) - LOG_FLOOR_S if log else y

    def _matrix(self, table: ProgramTable) -> np.ndarray:
        return build_inputs(table.blocks, self.inputs, constants=self.table_constants(table), what=self.name,
                            source=table.name)

    def fit(self, tables: Sequence[ProgramTable], *, progress: bool = True) -> None:
        cfg = self.config
        if not tables:
            raise ModelError(f"{self.name}: no training tables")
        self.constants = profile_constants(tables[0].profile)
        xs = [self._matrix(t) for t in tables]
        summed = cfg.target_mode == "cam_sum"
        ys = [self._encode(self.target(t)) for t in tables]
        heads = validation_heads([len(y) for y in ys], fraction=cfg.val_fraction, by=cfg.val_by, seed=cfg.seed)
        self.norms["x"] = Normaliser.fit(np.concatenate([x[:h] for x, h in zip(xs, heads)]))
        # cam_sum: the net's output is the log factor itself (an untrained net is about CAM)
        self.norms["y"] = (Normaliser((0.0,), (1.0,)) if summed else
                           Normaliser.fit(np.concatenate([y[:h] for y, h in zip(ys, heads)]), bounds=False))
        cams = [self.base_time(t) if summed else None for t in tables]
        parts: dict[str, list[tuple[np.ndarray, ...]]] = {"train": [], "val": []}
        for x, y, h, cam in zip(xs, ys, heads, cams):
            xn, yn = self.norms["x"].apply(x), self.norms["y"].apply(y[:, None])[:, 0]
            for split, rows in (("train", slice(0, h)), ("val", slice(h, len(y)))):
                if rows.start >= rows.stop:
                    continue
                w = make_windows(xn[rows], yn[rows], length=cfg.window, stride=cfg.stride)
                if summed:
                    w = w + (make_windows(xn[rows], cam[rows], length=cfg.window, stride=cfg.stride)[1],)
                parts[split].append(w)
        width = 4 if summed else 3
        data = {k: tuple(torch.from_numpy(np.concatenate([p[i] for p in v]).astype(np.float32))
                         for i in range(width)) if v else None for k, v in parts.items()}
        self.build_nets()
        span = cfg.ratio_span

        def loss_fn(net, idx, split):
            batch = data[split]
            if idx is not None:
                batch = tuple(b[idx] for b in batch)
            if summed:
                xb, yb, mb, cb = batch
                return window_sum_loss(net(xb), yb, cb, mb, span=span)
            xb, yb, mb = batch
            return masked_mse(net(xb), yb, mb)

        # one net, or an ensemble of nets that differ only in their seed (their outputs are averaged)
        for k, (key, net) in enumerate(self.nets.items()):
            self.report[key] = train_net(
                net, loss_fn, n_train=len(data["train"][0]),
                n_val=0 if data["val"] is None else len(data["val"][0]), seed=cfg.seed + k, epochs=cfg.epochs,
                lr=cfg.lr, batch_size=cfg.batch_size, patience=cfg.patience, desc=f"{self.name} {key}",
                progress=progress)

    def make_net(self) -> torch.nn.Module:
        """One network of the model (an ensemble builds `members` of them)."""
        raise NotImplementedError

    def build_nets(self) -> None:
        cfg = self.config
        self.nets = {}
        for k in range(cfg.members):
            setup_torch(cfg.seed + k)
            self.nets["net" if k == 0 else f"net{k}"] = self.make_net()

    def predict_values(self, table: ProgramTable) -> np.ndarray:
        """Per-block predicted target (in target units)."""
        self.check_trained()
        return self._net_values(table)

    def _net_values(self, table: ProgramTable) -> np.ndarray:
        """`predict_values` without the trained check (for validation inside `fit`)."""
        setup_torch()
        cfg = self.config
        x = self.norms["x"].apply(self._matrix(table))
        if len(x) == 0:
            return np.zeros(0)
        length = cfg.prediction_window
        stride = length - 2 * cfg.predict_context
        xw, _, _ = make_windows(x, None, length=length, stride=stride)
        nets = [net.eval() for net in self.nets.values()]
        with torch.no_grad():
            out = np.concatenate([
                np.mean([net(torch.from_numpy(xw[i:i + PREDICT_BATCH])).numpy() for net in nets], axis=0)
                for i in range(0, len(xw), PREDICT_BATCH)])
        per_row = stitch_windows(out, len(x), length=length, stride=stride)
        return self._decode(self.norms["y"].invert(per_row[:, None])[:, 0])

    def predict(self, table: ProgramTable) -> TablePrediction:
        durations = self.to_durations(table, self.predict_values(table))
        return TablePrediction(float(durations.sum()), durations)


@dataclass(frozen=True)
class BlockSeqConfig(SeqConfig):
    """bilstm-block's defaults: the sum-consistent CAM factor, batches of 64 windows, patience 40.

    Chosen on sim-timed random programs (train on 2 x 100, score 2 x 40 other ones and the training
    recordings' programs timed by the simulation): mean |error| 0.93 % / 3.3 %, against 1.46 % / 5.5 %
    ("cam_ratio", batch 16, patience 20) and 1.99 % / 5.6 % ("cam_ratio", batch 64, patience 40).
    """

    target_mode: str = "cam_sum"
    batch_size: int = 64
    patience: int = 40
    # sums over 65 blocks: on 21 held-out training recordings with the second kinematic base (seeds 0 / 1)
    # 0.93 / 0.76 % mean |error|, against 1.32 / 1.06 % over 17 blocks (span 8), 1.13 / 0.79 % (16)
    # and 1.10 / 1.26 % (64)
    ratio_span: int = 32
    # five nets (`members`): one net's result depends on its seed (20 held-out training recordings, seeds
    # 0-2: 15.7 % (one program +210 %), 5.5 %, 7.6 % mean |error|); five averaged gave 6.1 % and 6.2 %
    # (seeds 0, 1), worst program 21-27 %
    members: int = 5

    # quick (the demo, a few hundred windows): one net, batches of 16 give 4x the optimiser steps per epoch
    presets: ClassVar[dict[str, dict[str, Any]]] = {"quick": {"epochs": 40, "patience": 8, "batch_size": 16,
                                                              "members": 1}}


@register_model
class BlockBiLSTM(SeqModel):
    name = "bilstm-block"
    config_class = BlockSeqConfig
    description = "Bi-LSTM sequence to sequence, each block's time (Chien Fig. 7)"

    config: BlockSeqConfig

    def make_net(self) -> torch.nn.Module:
        return BiLSTMSeq(len(self.inputs), self.config.hidden, self.config.layers)


@dataclass(frozen=True)
class BiLSTMRConfig(SeqConfig):
    hidden: int = 32
    units: int = 2
    dropout: float = 0.3
    window: int = 128
    stride: int = 64
    lr: float = 0.002
    # 65-block sums: 0.72 / 0.88 % on the held-out training recordings (seeds 0 / 1; second kinematic
    # base), against 1.99 / 0.97 %
    # (span 8), 1.44 / 1.02 % (16) and 0.66 / 1.09 % (64); dropout 0.5 gave 2.01 / 1.54 %
    ratio_span: int = 32
    # one net: five averaged did better on 21 held-out training recordings (seeds 0 / 1 / 2: 2.37 / 2.96 /
    # 3.81 % mean |error| with one, 2.14 / 1.54 / 2.52 % with five) but predict a 100k-block program in
    # 2.0 s, over the 1 s the prediction must take (benchmarks/bench_train.py)
    members: int = 1

    presets: ClassVar[dict[str, dict[str, Any]]] = {"quick": {"epochs": 30, "patience": 6, "hidden": 24}}

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.units < 1 or not 0 <= self.dropout < 1:
            raise ModelError(f"BiLSTMRConfig: need units >= 1 and dropout in [0, 1), got {self.units}, {self.dropout}")


@register_model
class BiLSTMRModel(SeqModel):
    """Lee et al.'s BiLSTM-R (two residual BiLSTM units with layer norm and dropout, Eq. 4-7).

    Lee predict a dense signal (cutting force at 12.8 kHz) from 128-sample windows; here the same
    network regresses each block's time over windows of 128 blocks.
    """

    name = "bilstm-r"
    config_class = BiLSTMRConfig
    description = "stacked residual BiLSTM with layer norm and dropout (Lee et al.), per-block time"
    config: BiLSTMRConfig

    def make_net(self) -> torch.nn.Module:
        cfg = self.config
        return BiLSTMR(len(self.inputs), cfg.hidden, cfg.units, cfg.dropout)
