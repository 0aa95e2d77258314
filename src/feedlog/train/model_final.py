"""Bi-LSTM direct final cycle time (Chien Fig. 8): sequence to last, trained on whole-sequence times only.

The "stopwatch" strategy: the network never sees a block time, only the total time of a stretch of
blocks. Chien §2.5: the training sequences must lie within `length_tolerance` (5 %) of the length
of the sequence predicted. Programs range from tens to thousands of blocks, so one crop length cannot
serve them all; the rule is applied per predicted *chunk* (`crop_mode`):

- "range" (default): crop lengths are drawn log-uniformly from `crop_range` = (lo, hi) blocks (64-512), so
  every length in the range has training crops within +-5 % of it (about `crops` x 0.1 / ln(hi / lo)
  of them). A program of N <= hi blocks is predicted in one pass (the paper's); a longer one in
  k = ceil(N / hi) consecutive near-equal chunks, each of hi / 2 .. hi blocks, so inside the trained
  range, whose predicted totals are summed. A program shorter than lo is predicted whole and flagged.
- "fixed": crops within +-5 % of one length `crop_blocks` (0: the median length of the programs the
  caller names as targets, `target_lengths`, e.g. the test programs, or else of the training
  programs); a program is predicted in round(N / crop_blocks) near-equal chunks.
- "auto": "fixed" when `crop_blocks` > 0, else "range".

Chunks outside the trained length range are flagged in the prediction's notes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import torch

from feedlog.errors import ModelError
from feedlog.train.dataset import ProgramTable
from feedlog.train.features import CHIEN_INPUTS, Normaliser, build_inputs, profile_constants
from feedlog.train.fitting import setup_torch, train_net
from feedlog.train.nets import BiLSTMLast
from feedlog.train.model_seq import AUTO_PROGRAMS, BASES, validation_heads
from feedlog.train.registry import Model, ModelConfig, TablePrediction, register_model

PREDICT_BATCH = 1024
CROP_MODES = ("auto", "range", "fixed")
CAM_FLOOR_S = 1e-3  # added to a stretch's measured and CAM totals before the log ratio


@dataclass(frozen=True)
class FinalConfig(ModelConfig):
    inputs: tuple[str, ...] = CHIEN_INPUTS
    hidden: int = 50
    layers: int = 1
    crop_mode: str = "auto"
    crop_range: tuple[int, int] = (64, 512)  # (16, 256): crops of 16-60 blocks, whose totals hinge on the
    # speed they are entered at, doubled the error on held-out sim-timed programs (21 % vs 10 %)
    crop_blocks: int = 0
    length_tolerance: float = 0.05
    crops: int = 512
    # the label of a crop is its measured total T; the net learns log(T / CAM total of the crop), so a
    # prediction is CAM x e^out and does not depend on the crop's length (False: T itself, z-scored)
    cam_ratio: bool = True
    # the time that ratio is taken to: "cam" (limited CAM time) or "kinematic" (`features.kin_time`: one
    # trapezoid per block at the axes' limits, stopping or blending at corners; 21 held-out training
    # recordings: 2.94 % mean |error| against 8.76 % with "cam")
    base: str = "kinematic"
    batch_size: int = 32
    # batches of similar-length crops (drawn at random, with replacement), instead of random crops
    # padded to the longest: with crops of 16-256 blocks training runs several times faster
    length_batches: bool = True
    epochs: int = 30
    patience: int = 6

    presets: ClassVar[dict[str, dict[str, Any]]] = {"quick": {"epochs": 15, "patience": 5, "crops": 96,
                                                              "hidden": 16}}

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.hidden < 1 or self.layers < 1 or self.crops < 2:
            raise ModelError(f"FinalConfig: need hidden, layers >= 1 and crops >= 2, got {self.hidden}, "
                             f"{self.layers}, {self.crops}")
        if self.crop_blocks < 0 or not 0 <= self.length_tolerance < 1:
            raise ModelError(f"FinalConfig: need crop_blocks >= 0 and length_tolerance in [0, 1), got "
                             f"{self.crop_blocks}, {self.length_tolerance}")
        if self.base not in BASES:
            raise ModelError(f"FinalConfig.base must be one of {', '.join(BASES)}, got {self.base!r}")
        if self.crop_mode not in CROP_MODES:
            raise ModelError(f"FinalConfig.crop_mode must be one of {', '.join(CROP_MODES)}, got {self.crop_mode!r}")
        if len(self.crop_range) != 2 or not 2 <= self.crop_range[0] <= self.crop_range[1] // 2:
            raise ModelError(f"FinalConfig.crop_range needs (lo, hi) with 2 <= lo and 2 x lo <= hi (a long "
                             f"program's chunks span hi / 2 .. hi), got {self.crop_range}")

    @property
    def mode(self) -> str:
        """The crop mode in effect ("auto" resolved)."""
        if self.crop_mode == "auto":
            return "fixed" if self.crop_blocks > 0 else "range"
        return self.crop_mode


def _padded(seqs: Sequence[np.ndarray]) -> tuple[torch.Tensor, torch.Tensor]:
    lengths = np.array([len(s) for s in seqs])
    out = np.zeros((len(seqs), int(lengths.max()), seqs[0].shape[1]), np.float32)
    for i, s in enumerate(seqs):
        out[i, :len(s)] = s
    return torch.from_numpy(out), torch.from_numpy(lengths)


@register_model
class FinalBiLSTM(Model):
    name = "bilstm-final"
    config_class = FinalConfig
    description = "Bi-LSTM sequence to last, whole-stretch times only (Chien Fig. 8, stopwatch strategy)"
    config: FinalConfig

    def __init__(self, config: FinalConfig | None = None, *, target_lengths: Sequence[int] = ()) -> None:
        super().__init__(config)
        self.target_lengths = list(target_lengths)

    @property
    def inputs(self) -> tuple[str, ...]:
        return tuple(self.config.inputs)

    def build_nets(self) -> None:
        setup_torch(self.config.seed)
        self.nets = {"net": BiLSTMLast(len(self.inputs), self.config.hidden, self.config.layers)}

    def _matrix(self, table: ProgramTable) -> np.ndarray:
        return build_inputs(table.blocks, self.inputs, constants=self.table_constants(table), what=self.name,
                            source=table.name)

    def _crop_length(self, tables: Sequence[ProgramTable]) -> int:
        if self.config.crop_blocks:
            return self.config.crop_blocks
        lengths = self.target_lengths or [len(t.blocks) for t in tables]
        return max(2, int(np.median(lengths)))

    def _length_range(self, tables: Sequence[ProgramTable]) -> tuple[int, int]:
        """Sets params (crop mode and the trained length range) and returns the crop length range."""
        cfg = self.config
        if cfg.mode == "range":
            lo, hi = int(cfg.crop_range[0]), int(cfg.crop_range[1])
            self.params = {"crop_mode": "range", "min_blocks": lo, "max_blocks": hi}
            return lo, hi
        crop = self._crop_length(tables)
        lo = max(1, int(np.floor(crop * (1 - cfg.length_tolerance))))
        hi = int(np.ceil(crop * (1 + cfg.length_tolerance)))
        self.params = {"crop_mode": "fixed", "crop_blocks": crop, "min_blocks": lo, "max_blocks": hi}
        return lo, hi

    def _crop_lengths(self, rng: np.random.Generator, n: int, lo: int, hi: int) -> np.ndarray:
        if self.config.mode == "range":  # log-uniform: as many crops near 20 blocks as near 200
            return np.floor(np.exp(rng.uniform(np.log(lo), np.log(hi + 1), n))).astype(np.int64).clip(lo, hi)
        return rng.integers(lo, hi + 1, n)

    def _sample(self, rng: np.random.Generator, pool: Sequence[int], n: int, xs: Sequence[np.ndarray],
                ds: Sequence[np.ndarray], cams: Sequence[np.ndarray], lo: int, hi: int
                ) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
        """`n` random stretches of the programs in `pool` (chosen by size): inputs, totals, CAM totals."""
        sizes = np.array([len(xs[i]) for i in pool], np.float64)
        which = np.asarray(pool)[rng.choice(len(pool), size=n, p=sizes / sizes.sum())]
        lengths = self._crop_lengths(rng, n, lo, hi)
        seqs, totals, cam_totals = [], np.empty(n), np.empty(n)
        for k, (i, want) in enumerate(zip(which, lengths)):
            length = min(len(xs[i]), int(want))  # a program shorter than the crop is used whole
            start = int(rng.integers(0, len(xs[i]) - length + 1))
            seqs.append(xs[i][start:start + length])
            totals[k] = ds[i][start:start + length].sum()
            cam_totals[k] = cams[i][start:start + length].sum()
        return seqs, totals, cam_totals

    def fit(self, tables: Sequence[ProgramTable], *, progress: bool = True) -> None:
        cfg = self.config
        if not tables:
            raise ModelError(f"{self.name}: no training tables")
        self.constants = profile_constants(tables[0].profile)
        xs = [self._matrix(t) for t in tables]
        ds = [t.durations() for t in tables]
        cams = [self.base_time(t) for t in tables]
        lo, hi = self._length_range(tables)
        rng = np.random.default_rng(cfg.seed)
        n_val = int(round(cfg.crops * cfg.val_fraction))
        # early stopping on crops of whole held-out training programs when there are enough programs
        # (how the net does on a program it has not seen), else on held-out crops of all of them
        heads = validation_heads([len(x) for x in xs], fraction=cfg.val_fraction, by="auto", seed=cfg.seed)
        held = [i for i, h in enumerate(heads) if h == 0]
        if held and n_val and len(held) < len(xs) and len(xs) >= AUTO_PROGRAMS:
            kept = [i for i in range(len(xs)) if i not in held]
            seqs, totals, cam_totals = self._sample(rng, kept, cfg.crops - n_val, xs, ds, cams, lo, hi)
            v_seqs, v_totals, v_cams = self._sample(rng, held, n_val, xs, ds, cams, lo, hi)
            seqs += v_seqs
            totals, cam_totals = np.concatenate([totals, v_totals]), np.concatenate([cam_totals, v_cams])
            train_idx, val_idx = np.arange(cfg.crops - n_val), np.arange(cfg.crops - n_val, cfg.crops)
        else:
            seqs, totals, cam_totals = self._sample(rng, range(len(xs)), cfg.crops, xs, ds, cams, lo, hi)
            order = rng.permutation(cfg.crops)
            val_idx, train_idx = order[:n_val], order[n_val:]
        # training crops ordered by length: a batch is the run of similar-length crops that holds the
        # example the shuffled order names first, so little time goes into padded steps
        train_idx = np.asarray(train_idx)[np.argsort([len(seqs[i]) for i in train_idx], kind="stable")]
        self.params["crops_trained"] = int(len(train_idx))
        totals_arr = self._encode(totals, cam_totals)
        self.norms["x"] = Normaliser.fit(np.concatenate([seqs[i] for i in train_idx]))
        self.norms["y"] = Normaliser.fit(totals_arr[train_idx], bounds=False)
        norm_seqs = [self.norms["x"].apply(s) for s in seqs]
        y = torch.from_numpy(self.norms["y"].apply(totals_arr[:, None])[:, 0])
        x_all, len_all = _padded(norm_seqs)
        data = {"train": (x_all[train_idx], len_all[train_idx], y[train_idx]),
                "val": (x_all[val_idx], len_all[val_idx], y[val_idx])}
        self.build_nets()

        bs = cfg.batch_size

        def loss_fn(net, idx, split):
            xb, lb, yb = data[split]
            if idx is not None:
                if split == "train" and cfg.length_batches:
                    first = int(idx[0]) // bs * bs
                    idx = torch.arange(first, min(first + bs, len(lb)))
                xb, lb, yb = xb[idx], lb[idx], yb[idx]
                width = int(lb.max())  # the batch's longest crop: no time spent on all-padding steps
                xb = xb[:, :width]
            return torch.mean((net(xb, lb) - yb) ** 2)

        self.report["net"] = train_net(
            self.nets["net"], loss_fn, n_train=len(train_idx), n_val=len(val_idx), seed=cfg.seed,
            epochs=cfg.epochs, lr=cfg.lr, batch_size=cfg.batch_size, patience=cfg.patience,
            desc=self.name, progress=progress)

    def _encode(self, totals: np.ndarray, cam: np.ndarray) -> np.ndarray:
        if self.config.cam_ratio:
            return np.log(totals + CAM_FLOOR_S) - np.log(cam + CAM_FLOOR_S)
        return totals

    def _decode(self, values: np.ndarray, cam: np.ndarray) -> np.ndarray:
        if self.config.cam_ratio:
            return (cam + CAM_FLOOR_S) * np.exp(values) - CAM_FLOOR_S
        return values

    def chunks(self, n: int) -> list[np.ndarray]:
        """Row index chunks a program of n blocks is predicted in (each inside the trained range if it can be)."""
        if self.params.get("crop_mode", "fixed") == "range":
            k = max(1, int(np.ceil(n / self.params["max_blocks"])))
        else:
            k = max(1, int(round(n / self.params["crop_blocks"])))
        return np.array_split(np.arange(n), k)

    def predict(self, table: ProgramTable) -> TablePrediction:
        self.check_trained()
        setup_torch()
        x = self.norms["x"].apply(self._matrix(table))
        cam_rows = self.base_time(table)
        if len(x) == 0:
            return TablePrediction(0.0, None)
        parts = self.chunks(len(x))
        outside = [len(p) for p in parts if not self.params["min_blocks"] <= len(p) <= self.params["max_blocks"]]
        net = self.nets["net"].eval()
        total = 0.0
        with torch.no_grad():
            for i in range(0, len(parts), PREDICT_BATCH):
                xb, lb = _padded([x[p] for p in parts[i:i + PREDICT_BATCH]])
                out = self.norms["y"].invert(net(xb, lb).numpy()[:, None])[:, 0]
                cam = np.array([cam_rows[p].sum() for p in parts[i:i + PREDICT_BATCH]])
                total += float(self._decode(out, cam).sum())
        notes = [f"{len(outside)} of {len(parts)} chunk(s) outside the trained length range "
                 f"{self.params['min_blocks']}-{self.params['max_blocks']} blocks (e.g. {outside[0]})"] if outside else []
        return TablePrediction(max(total, 0.0), None, notes)
