"""The parsed part program: the block table plus what the parser learned on the way."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from feedlog.toolpath.schema import KINDS, MOTION_KINDS

# codes of kind_codes(): indices into schema.KINDS
K_RAPID, K_LINEAR, K_ARC_CW, K_ARC_CCW, K_DWELL, K_NONE = range(6)


def kind_codes(kind: pd.Series) -> np.ndarray:
    """The `kind` column as int8 indices into schema.KINDS (-1 for unknown), without going through
    per-row strings (motion kinds are 0..3)."""
    if isinstance(kind.dtype, pd.CategoricalDtype):
        lut = np.array([KINDS.index(c) if c in KINDS else -1 for c in kind.cat.categories] + [-1],
                       dtype=np.int8)
        return lut[kind.cat.codes.to_numpy()]
    return pd.Categorical(kind, categories=list(KINDS)).codes.astype(np.int8)


def kind_column(codes: np.ndarray) -> pd.Categorical:
    return pd.Categorical.from_codes(codes, categories=list(KINDS))


@dataclass(frozen=True)
class Unsupported:
    """A code the parser did not interpret (lenient mode): 1-based line, the code, and why."""

    line: int
    code: str
    reason: str


@dataclass
class Program:
    """A part program as a block table (see toolpath/schema.py) and its context.

    `blocks`: one row per source line holding a block or comment; `path`: the source file (None for
    text); `warnings`: things worth telling a user; `unsupported`: codes skipped in lenient mode;
    `metadata`: program number, title comment, counts.
    """

    blocks: pd.DataFrame
    path: Path | None = None
    warnings: list[str] = field(default_factory=list)
    unsupported: list[Unsupported] = field(default_factory=list)
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return str(self.metadata.get("file", self.path or "<string>"))

    @property
    def motion(self) -> pd.DataFrame:
        """Only the motion rows (rapid, linear, arcs), in program order."""
        return self.blocks[self.blocks["kind"].isin(MOTION_KINDS)]

    def __len__(self) -> int:
        return len(self.blocks)
