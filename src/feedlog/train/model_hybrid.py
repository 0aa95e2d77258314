"""Hybrid: the simulation's block times plus a learned residual (learning corrects the physics).

The residual learner is the block-by-block Bi-LSTM with two more inputs, the simulated block time
`sim_duration_s` and its logarithm. Its target is the residual on a log scale,
r = log(duration_s + 0.1 ms) - log(sim_duration_s + 0.1 ms), so a prediction is (sim + 0.1 ms) e^r - 0.1 ms: a
correction factor, which cannot add seconds to a program of many short blocks the way an additive
residual can. The output layer starts at zero (the mean training residual) and training keeps the
untrained net unless it beats it on the validation tail, so where the simulation is already right
the hybrid stays with it. The ratio is measured over a window of neighbouring blocks
(`residual_span`), because align and the simulation may attribute a corner's time to different
sides of a block boundary. The simulated time comes from
`feedlog.sim.simulate(program, profile)` (`attach_sim`), or from a `sim_duration_s` column already in
the table.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import pandas as pd
import torch

from feedlog.errors import ModelError
from feedlog.train.dataset import ProgramTable, window_sums
from feedlog.train.features import CHIEN_INPUTS
from feedlog.train.fitting import setup_torch
from feedlog.train.model_seq import SeqConfig, SeqModel, validation_heads
from feedlog.train.nets import BiLSTMSeq
from feedlog.train.registry import register_model

SIM_COLUMN = "sim_duration_s"
RESIDUAL_FLOOR_S = 1e-4
# shares of the learned correction tried on the validation programs after training (0: the simulation)
SCALES = (0.0, 0.25, 0.5, 0.75, 1.0)


@dataclass(frozen=True)
class HybridConfig(SeqConfig):
    inputs: tuple[str, ...] = CHIEN_INPUTS + (SIM_COLUMN, "log_sim_duration_s")
    log_target: bool = False  # the residual is already a log ratio
    base: str = "cam"  # not used: the hybrid's output is a factor on the simulated time
    # the ratio is taken over sums of 2 x residual_span + 1 neighbouring blocks: align and the simulation
    # may split a corner's time differently between two blocks, which per-block ratios would learn
    residual_span: int = 8
    # keep the simulation unless the correction helps on whole programs the residual net has not seen
    val_by: str = "program"

    presets: ClassVar[dict[str, dict[str, Any]]] = {"quick": {"epochs": 40, "patience": 8}}

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.residual_span < 0:
            raise ModelError(f"HybridConfig.residual_span must be >= 0, got {self.residual_span}")
        if self.members != 1:
            raise ModelError(f"HybridConfig: the hybrid trains one net (members 1), got members {self.members}")
        if self.target_mode == "cam_sum":
            raise ModelError("HybridConfig: the hybrid learns its own residual target; target_mode 'cam_sum' "
                             "does not apply")
        if SIM_COLUMN not in self.inputs:
            raise ModelError(f"HybridConfig.inputs must include {SIM_COLUMN!r}, got {self.inputs}")


def attach_sim(table: ProgramTable, *, program: Any = None) -> ProgramTable:
    """Add the simulated block time `sim_duration_s` (one simulation of the table's program).

    `program` (a parsed toolpath Program) saves parsing `table.program_text` again.
    """
    if SIM_COLUMN in table.blocks.columns:
        return table
    if (program is None and table.program_text is None) or table.profile is None:
        raise ModelError(f"{table.name}: the hybrid model needs the program text and a machine profile to "
                         f"simulate, or a {SIM_COLUMN!r} column")
    try:
        from feedlog.sim import simulate
        from feedlog.toolpath import load_program
    except ImportError as exc:
        raise ModelError(f"the hybrid model needs feedlog.sim and feedlog.toolpath: {exc}") from None
    if program is None:
        program = load_program(table.program_text, name=table.name)
    result = simulate(program, table.profile)
    sim = result.blocks[["block", "duration_s"]].rename(columns={"duration_s": SIM_COLUMN})
    sim = sim.groupby("block", as_index=False)[SIM_COLUMN].sum()
    blocks = table.blocks.merge(sim, on="block", how="left")
    # blocks the simulation skipped (zero length) or merged into a later block (LinuxCNC joins short
    # segments; the group's time sits on its last block) share their group's time by length, as align
    # splits merged groups by geometry
    blocks[SIM_COLUMN] = spread_merged(blocks[SIM_COLUMN].fillna(0.0).to_numpy(np.float64),
                                       blocks["length_mm"].to_numpy(np.float64))
    return ProgramTable(table.name, blocks, program=table.program, split=table.split, points=table.points,
                        profile=table.profile, program_text=table.program_text,
                        metadata=dict(table.metadata))


def spread_merged(times: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Zero-time blocks before a block with time form its group; the group's time is split by length."""
    n = len(times)
    if n == 0:
        return times
    carrier = times > 0
    group = np.concatenate([[0], np.cumsum(carrier)[:-1]])  # a carrier closes its group
    total = np.bincount(group, weights=times, minlength=group.max() + 1)
    length = np.bincount(group, weights=lengths, minlength=group.max() + 1)
    count = np.bincount(group, minlength=group.max() + 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(length[group] > 0, lengths / length[group], 1.0 / count[group])
    return total[group] * share


@register_model
class HybridModel(SeqModel):
    name = "hybrid"
    config_class = HybridConfig
    description = "simulated block times + a Bi-LSTM residual"

    def build_nets(self) -> None:
        setup_torch(self.config.seed)
        net = BiLSTMSeq(len(self.inputs), self.config.hidden, self.config.layers)
        torch.nn.init.zeros_(net.head.weight)
        torch.nn.init.zeros_(net.head.bias)
        self.nets = {"net": net}

    def fit(self, tables, *, progress: bool = True) -> None:
        super().fit(tables, progress=progress)
        seen = np.concatenate([self.target(t) for t in tables])
        self.params["residual_range"] = [float(seen.min()), float(seen.max())]
        self.params["correction_scale"] = self._choose_scale(tables)

    def _choose_scale(self, tables) -> float:
        """The share of the learned correction that serves the validation parts best (0 = simulation alone).

        Per validation part (a held-out program, or a program's tail) the error of its total time;
        the scale in `SCALES` with the lowest mean |error| wins, the smaller one on a tie, so the
        hybrid never does worse than the simulation on data the net has not trained on.
        """
        cfg = self.config
        heads = validation_heads([len(t.blocks) for t in tables], fraction=cfg.val_fraction, by=cfg.val_by,
                                 seed=cfg.seed)
        parts = [(t, h) for t, h in zip(tables, heads) if h < len(t.blocks)]
        if not parts:
            return 1.0
        errors = np.zeros(len(SCALES))
        for t, h in parts:
            measured = t.durations()[h:].sum()
            sim = self._sim(t)[h:]
            values = self._net_values(t)[h:]
            for i, scale in enumerate(SCALES):
                pred = self._apply(sim, values * scale).sum()
                errors[i] += abs(pred - measured) / max(measured, 1e-9)
        self.report["correction_scale_errors_pct"] = [round(100 * e / len(parts), 4) for e in errors]
        return float(SCALES[int(np.argmin(np.round(errors / len(parts), 6)))])

    def target(self, table: ProgramTable) -> np.ndarray:
        span = self.config.residual_span
        measured = window_sums(table.durations(), span)
        simulated = window_sums(self._sim(table), span)
        return np.log(measured + RESIDUAL_FLOOR_S) - np.log(simulated + RESIDUAL_FLOOR_S)

    def to_durations(self, table: ProgramTable, values: np.ndarray) -> np.ndarray:
        return self._apply(self._sim(table), values * self.params.get("correction_scale", 1.0))

    def _apply(self, sim: np.ndarray, values: np.ndarray) -> np.ndarray:
        lo, hi = self.params.get("residual_range", (-np.inf, np.inf))
        values = np.clip(values, lo, hi)  # never a larger correction than training saw
        return np.maximum((sim + RESIDUAL_FLOOR_S) * np.exp(values) - RESIDUAL_FLOOR_S, 0.0)

    def _sim(self, table: ProgramTable) -> np.ndarray:
        if SIM_COLUMN not in table.blocks.columns:
            raise ModelError(f"{table.name}: input lacks column {SIM_COLUMN!r} needed by hybrid "
                             "(call feedlog.train.model_hybrid.attach_sim first)")
        return pd.to_numeric(table.blocks[SIM_COLUMN]).to_numpy(np.float64)
