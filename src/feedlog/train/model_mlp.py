"""Per-axis MLP (Sun et al. 2022): one small tanh network per axis, resultant feed (Eq. 9), time (Eq. 10).

Inputs per axis are Sun Table 1: corner angles at CL points n-1, n, n+1 and the axis' nominal feed and
acceleration at n-1, n, n+1 (`features.sun_inputs`). The target is the axis' *mean* feed over the
segment ending at CL point n, `v_axis_nom * nominal_time_s / duration_s`: Sun takes the measured feed
at the CL point itself, but Eq. 10 integrates the time over each segment, and the segment's mean feed
makes that integral exact (at a sharp corner the instantaneous feed is near zero and Eq. 10 would
explode). Eq. 9 gives the resultant f = sqrt(fx^2 + fy^2 + fz^2); Eq. 10 gives each block's time as
its nominal time scaled by |v_nom| / f (= L / f for lines).

Departures from Sun, each configurable (`MLPConfig`): `extra_inputs` (tolerances, segment length, axis
limit ratio; `()` is Sun's Table 1 exactly), `limited_feeds` (feeds and nominal times within the axes'
speed limits, for five-axis blocks a rotary axis times), `target_span` (the speed ratio of the target
taken over neighbouring blocks), `mirror` (blocks mirrored to + travel).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import torch

from feedlog.errors import ModelError
from feedlog.train.dataset import ProgramTable, window_sums
from feedlog.train.features import AXES3, Normaliser, build_inputs, profile_constants, sun_inputs
from feedlog.train.fitting import setup_torch, train_net
from feedlog.train.nets import AxisMLP
from feedlog.train.model_seq import BASES, VAL_BY, validation_heads
from feedlog.train.registry import Model, ModelConfig, TablePrediction, register_model


MLP_TARGETS = ("feed", "log_ratio")
RATIO_FLOOR = 1e-3  # speed ratios floored here before the log


@dataclass(frozen=True)
class MLPConfig(ModelConfig):
    # Sun's nets are tanh 5-10; 32-32 reproduces simulator-timed programs it has not seen far better
    # (held-out sim programs, mean |error|: 7.8 % with 5-10, 4.7 % with 32-32 and batches of 1024)
    hidden: tuple[int, ...] = (32, 32)
    axes: tuple[str, ...] = AXES3
    lr: float = 0.01
    batch_size: int = 1024
    epochs: int = 300
    patience: int = 30
    min_feed_ratio: float = 0.02  # predicted resultant feed floored at this fraction of the nominal one
    # beyond Sun Table 1: the path tolerance P and merge tolerance Q (fixed in Sun's trials, varied across
    # our recordings), the segment length (Sun's CL points were evenly spaced; ours span 0.02-30 mm, and
    # a short segment never reaches its nominal feed) and the ratio of the axis-speed-limited time to
    # L / F (five-axis blocks whose time a rotary axis' speed sets)
    extra_inputs: tuple[str, ...] = ("tol_eff_mm", "exact_stop", "merge_tol_eff_mm", "log_length_mm",
                                       "limit_ratio")
    # mirror every block so its axis moves in + (axis feeds and accelerations at n-1, n, n+1 and the
    # target times sign(v_axis,n)): the machine's axes behave alike in both directions, and the small
    # tanh nets then learn one feed magnitude instead of a function that is odd in the feed
    mirror: bool = True
    # feeds in the axes' speed limits: each block's nominal axis feeds scaled by L/F / limited time
    # (`features.limited_time`), so a five-axis block whose time a rotary axis' speed sets enters (and is
    # timed by Eq. 10) at the feed its axes can actually run; False: the programmed feeds (Sun)
    limited_feeds: bool = True
    # the time those feeds are scaled to: "cam" (`features.limited_time`, above) or "kinematic"
    # (`features.kin_time`: one trapezoid per block at the axes' limits, stopping or blending at corners),
    # so the net learns what that trapezoid misses (21 held-out training recordings: 3.34 % mean |error|
    # against 11.46 % with "cam")
    base: str = "kinematic"
    # the target's speed ratio (nominal / measured time) is taken over the 2 x target_span + 1 blocks
    # around n: align may put a corner's time on either side of a block boundary, and a per-block ratio
    # (target_span 0, Sun's) carries that noise into 1 / duration
    target_span: int = 1
    # what each axis net learns: "feed", the axis' mean feed (Sun), or "log_ratio", the log of the block's
    # speed ratio (nominal / measured time) seen by that axis, the net's output times the axis' nominal
    # feed giving the feed; its loss is weighted by the axis' share (v_axis / |v|)^2 of the resultant, so
    # an axis that hardly moves does not teach its net. A small tanh net then need not multiply its
    # feed input by a ratio: the feed enters Eq. 9 exactly, and the error is relative (a time error)
    target: str = "log_ratio"
    # nets per axis trained with seeds seed, seed + 1, ...; their outputs are averaged (21 held-out training
    # recordings, seeds 0 / 1 / 2: one net 3.34 / 2.97 / 4.31 % mean |error|, five 3.17 / 2.71 / 3.64 %)
    members: int = 5
    # early stopping on whole held-out training programs ("program"), the tail of each ("tail"), or
    # "auto" (whole programs from 8 training programs on)
    val_by: str = "auto"

    presets: ClassVar[dict[str, dict[str, Any]]] = {"quick": {"epochs": 60, "patience": 12, "members": 1}}

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.hidden or any(h < 1 for h in self.hidden):
            raise ModelError(f"MLPConfig.hidden needs positive layer sizes, got {self.hidden}")
        if not self.axes or any(a not in AXES3 for a in self.axes):
            raise ModelError(f"MLPConfig.axes must be a subset of {AXES3}, got {self.axes}")
        if self.val_by not in VAL_BY:
            raise ModelError(f"MLPConfig.val_by must be one of {', '.join(VAL_BY)}, got {self.val_by!r}")
        if self.target not in MLP_TARGETS:
            raise ModelError(f"MLPConfig.target must be one of {', '.join(MLP_TARGETS)}, got {self.target!r}")
        if self.base not in BASES:
            raise ModelError(f"MLPConfig.base must be one of {', '.join(BASES)}, got {self.base!r}")
        if self.members < 1:
            raise ModelError(f"MLPConfig.members must be >= 1, got {self.members}")
        if self.target_span < 0:
            raise ModelError(f"MLPConfig.target_span must be >= 0, got {self.target_span}")
        if not 0 < self.min_feed_ratio < 1:
            raise ModelError(f"MLPConfig.min_feed_ratio must be in (0, 1), got {self.min_feed_ratio}")




def speed_ratio(nominal: np.ndarray, duration: np.ndarray, *, span: int) -> np.ndarray:
    """Each block's nominal / measured time, both summed over the moving blocks n - span .. n + span."""
    moving = nominal > 0
    return window_sums(nominal, span) / np.maximum(window_sums(np.where(moving, duration, 0.0), span), 1e-9)


def _key(axis: str, member: int) -> str:
    """The net of one axis and ensemble member ("x", "x1", "x2", ...)."""
    return axis if member == 0 else f"{axis}{member}"


@register_model
class PerAxisMLP(Model):
    name = "mlp"
    config_class = MLPConfig
    description = "per-axis MLP on Sun Table 1 features; resultant feed (Eq. 9), cycle time (Eq. 10)"
    config: MLPConfig

    def _nominal(self, table: ProgramTable) -> tuple[np.ndarray, np.ndarray]:
        """Axis feeds (rows x axes, mm/min) and block times (s): nominal, or scaled to the base time."""
        b = table.blocks
        v = np.nan_to_num(np.column_stack([b[f"v{a}_nom_mm_min"].to_numpy(np.float64) for a in self.config.axes]))
        if not self.config.limited_feeds:
            return v, np.nan_to_num(b["nominal_time_s"].to_numpy(np.float64))
        lim, scale = self._limits(table)
        return v * scale[:, None], lim

    def _limits(self, table: ProgramTable) -> tuple[np.ndarray, np.ndarray]:
        """Block base times (`config.base`) and the factor (L/F over that time, 1 where it is 0) that
        brings the nominal axis feeds to them."""
        nominal = np.nan_to_num(table.blocks["nominal_time_s"].to_numpy(np.float64))
        lim = self.base_time(table)
        with np.errstate(divide="ignore", invalid="ignore"):
            return lim, np.where(lim > 0, nominal / lim, 1.0)

    def axis_inputs(self, axis: str) -> tuple[str, ...]:
        return sun_inputs(axis) + tuple(self.config.extra_inputs)

    @property
    def inputs(self) -> tuple[str, ...]:
        out: list[str] = []
        for a in self.config.axes:
            out += [c for c in self.axis_inputs(a) if c not in out]
        return tuple(out) + tuple(c for c in ("nominal_time_s",) if c not in out)

    def _axis_matrix(self, table: ProgramTable, axis: str) -> tuple[np.ndarray, np.ndarray]:
        """One axis' input matrix (mirrored to + travel when configured) and the sign it was mirrored by."""
        names = self.axis_inputs(axis)
        x = build_inputs(table.blocks, names, what="mlp", source=table.name)
        v = np.nan_to_num(table.blocks[f"v{axis}_nom_mm_min"].to_numpy(np.float64))
        if self.config.limited_feeds:  # axis feeds at n-1, n, n+1 within the axes' speed limits
            _, scale = self._limits(table)
            shifted = {"": scale, "_prev": np.concatenate([[1.0], scale[:-1]]),
                       "_next": np.concatenate([scale[1:], [1.0]])}
            for j, n in enumerate(names):
                if n.startswith(f"v{axis}_nom_mm_min"):
                    x[:, j] *= shifted[n[len(f"v{axis}_nom_mm_min"):]].astype(np.float32)
        sign = np.where(v < 0, -1.0, 1.0) if self.config.mirror else np.ones(len(v))
        signed = [j for j, n in enumerate(names) if n.startswith((f"v{axis}_nom", f"a{axis}_nom"))]
        x[:, signed] *= sign[:, None].astype(np.float32)
        return x, sign

    def build_nets(self) -> None:
        cfg = self.config
        self.nets = {}
        for k in range(cfg.members):
            setup_torch(cfg.seed + k)
            self.nets |= {_key(a, k): AxisMLP(len(self.axis_inputs(a)), cfg.hidden) for a in cfg.axes}

    def fit(self, tables: Sequence[ProgramTable], *, progress: bool = True) -> None:
        cfg = self.config
        if not tables:
            raise ModelError("mlp: no training tables")
        self.constants = profile_constants(tables[0].profile)
        xs: dict[str, list[np.ndarray]] = {a: [] for a in cfg.axes}
        ys: dict[str, list[np.ndarray]] = {a: [] for a in cfg.axes}
        ws: dict[str, list[np.ndarray]] = {a: [] for a in cfg.axes}
        is_val: list[np.ndarray] = []
        heads = validation_heads([len(t.blocks) for t in tables], fraction=cfg.val_fraction, by=cfg.val_by,
                                 seed=cfg.seed)
        for t, head in zip(tables, heads):
            v, nominal = self._nominal(t)
            d = t.durations()
            ratio = speed_ratio(nominal, d, span=cfg.target_span)
            keep = (nominal > 0) & (d > 0) & (np.abs(v).sum(axis=1) > 0)
            val = np.zeros(len(d), bool)
            val[head:] = True
            is_val.append(val[keep])
            v_res = np.sqrt((v * v).sum(axis=1))
            for i, a in enumerate(cfg.axes):
                x, sign = self._axis_matrix(t, a)
                xs[a].append(x[keep])
                if cfg.target == "feed":
                    ys[a].append((sign * v[:, i] * ratio)[keep])
                    ws[a].append(np.ones(int(keep.sum())))
                else:
                    ys[a].append(np.log(np.maximum(ratio, RATIO_FLOOR))[keep])
                    ws[a].append((v[:, i] / np.where(v_res > 0, v_res, 1.0))[keep] ** 2)
        val_mask = np.concatenate(is_val)
        if (~val_mask).sum() < 2:
            raise ModelError("mlp: fewer than 2 usable training blocks (need nominal time and duration > 0)")
        self.build_nets()
        for a in cfg.axes:
            x, y, w = np.concatenate(xs[a]), np.concatenate(ys[a]), np.concatenate(ws[a])
            self.norms[f"x_{a}"] = Normaliser.fit(x[~val_mask])
            self.norms[f"y_{a}"] = Normaliser.fit(y[~val_mask], bounds=False)
            xn = torch.from_numpy(self.norms[f"x_{a}"].apply(x))
            yn = torch.from_numpy(self.norms[f"y_{a}"].apply(y[:, None])[:, 0])
            wn = torch.from_numpy((w / max(float(w[~val_mask].mean()), 1e-12)).astype(np.float32))
            tr, va = torch.from_numpy(~val_mask), torch.from_numpy(val_mask)
            data = {"train": (xn[tr], yn[tr], wn[tr]), "val": (xn[va], yn[va], wn[va])}

            def loss_fn(net, idx, split, data=data):
                xb, yb, wb = data[split]
                if idx is not None:
                    xb, yb, wb = xb[idx], yb[idx], wb[idx]
                return torch.mean(wb * (net(xb) - yb) ** 2)

            for k in range(cfg.members):
                key = _key(a, k)
                self.report[key] = train_net(self.nets[key], loss_fn, n_train=int((~val_mask).sum()),
                                             n_val=int(val_mask.sum()), seed=cfg.seed + k, epochs=cfg.epochs,
                                             lr=cfg.lr, batch_size=cfg.batch_size, patience=cfg.patience,
                                             desc=f"mlp {key}", progress=progress)

    def axis_feeds(self, table: ProgramTable) -> np.ndarray:
        """Predicted mean axis feeds (rows x axes, mm/min)."""
        self.check_trained()
        setup_torch()
        out, signs = [], []
        with torch.no_grad():
            for a in self.config.axes:
                x, sign = self._axis_matrix(table, a)
                signs.append(sign)
                xn = torch.from_numpy(self.norms[f"x_{a}"].apply(x))
                # an ensemble averages its members' outputs (log ratios or feeds)
                pred = np.mean([self.nets[_key(a, k)](xn).numpy() for k in range(self.config.members)], axis=0)
                out.append(self.norms[f"y_{a}"].invert(pred[:, None])[:, 0])
        if self.config.target == "feed":
            return np.column_stack(out) * np.column_stack(signs)
        v, _ = self._nominal(table)
        return v * np.exp(np.column_stack(out))

    def predict(self, table: ProgramTable) -> TablePrediction:
        f = self.axis_feeds(table)
        v, nominal = self._nominal(table)
        v_res = np.sqrt((v * v).sum(axis=1))
        f_res = np.maximum(np.sqrt((f * f).sum(axis=1)), self.config.min_feed_ratio * v_res)  # Eq. 9
        with np.errstate(divide="ignore", invalid="ignore"):
            durations = np.where(v_res > 0, nominal * v_res / f_res, nominal)  # Eq. 10, per segment
        return TablePrediction(float(durations.sum()), durations)
