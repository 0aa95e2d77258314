"""Hybrid: the simulation's block times plus a learned residual (learning corrects the physics).

The residual learner is the block-by-block Bi-LSTM with one more input, the simulated block time
`sim_duration_s`; its target is `duration_s - sim_duration_s`. The simulated time comes from
`feedlog.sim.simulate(program, profile)` (`attach_sim`), or from a `sim_duration_s` column already in
the table.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import pandas as pd

from feedlog.errors import ModelError
from feedlog.train.dataset import ProgramTable
from feedlog.train.features import CHIEN_INPUTS
from feedlog.train.fitting import setup_torch
from feedlog.train.model_seq import SeqConfig, SeqModel
from feedlog.train.nets import BiLSTMSeq
from feedlog.train.registry import register_model

SIM_COLUMN = "sim_duration_s"


@dataclass(frozen=True)
class HybridConfig(SeqConfig):
    inputs: tuple[str, ...] = CHIEN_INPUTS + (SIM_COLUMN,)
    log_target: bool = False  # the residual can be negative

    presets: ClassVar[dict[str, dict[str, Any]]] = {"quick": {"epochs": 40, "patience": 8}}

    def __post_init__(self) -> None:
        super().__post_init__()
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
        from feedlog.toolpath import parse_program
    except ImportError as exc:
        raise ModelError(f"the hybrid model needs feedlog.sim and feedlog.toolpath: {exc}") from None
    if program is None:
        program = parse_program(table.program_text, name=table.name)
    result = simulate(program, table.profile)
    sim = result.blocks[["block", "duration_s"]].rename(columns={"duration_s": SIM_COLUMN})
    sim = sim.groupby("block", as_index=False)[SIM_COLUMN].sum()
    blocks = table.blocks.merge(sim, on="block", how="left")
    # blocks the simulation merged into a neighbour or skipped (zero length) take no time of their own
    missing = int(blocks[SIM_COLUMN].isna().sum())
    blocks[SIM_COLUMN] = blocks[SIM_COLUMN].fillna(0.0)
    metadata = dict(table.metadata)
    if missing:
        metadata["sim_blocks_without_time"] = str(missing)
    return ProgramTable(table.name, blocks, program=table.program, split=table.split, points=table.points,
                        profile=table.profile, program_text=table.program_text, metadata=metadata)


@register_model
class HybridModel(SeqModel):
    name = "hybrid"
    config_class = HybridConfig
    description = "simulated block times + a Bi-LSTM residual"

    def build_nets(self) -> None:
        setup_torch(self.config.seed)
        self.nets = {"net": BiLSTMSeq(len(self.inputs), self.config.hidden, self.config.layers)}

    def target(self, table: ProgramTable) -> np.ndarray:
        return table.durations() - self._sim(table)

    def to_durations(self, table: ProgramTable, values: np.ndarray) -> np.ndarray:
        return np.maximum(self._sim(table) + values, 0.0)

    def _sim(self, table: ProgramTable) -> np.ndarray:
        if SIM_COLUMN not in table.blocks.columns:
            raise ModelError(f"{table.name}: input lacks column {SIM_COLUMN!r} needed by hybrid "
                             "(call feedlog.train.model_hybrid.attach_sim first)")
        return pd.to_numeric(table.blocks[SIM_COLUMN]).to_numpy(np.float64)
