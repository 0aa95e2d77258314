"""The parsed part program: the block table plus what the parser learned on the way."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from feedlog.toolpath.schema import MOTION_KINDS


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
