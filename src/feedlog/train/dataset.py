"""Training data: one `ProgramTable` per aligned recording, windows over long programs, fingerprints.

A `ProgramTable` is what align/ writes for one recording: `blocks` (one row per motion block with the
toolpath features and the measured `duration_s`) and optionally `points` (one row per CL point with
the measured feed). `program` names the part program (recordings of the same program with different
settings share it) and `split` says whether it is for training or held-out testing.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from feedlog.errors import ModelError
from feedlog.profile import MachineProfile

SPLITS = ("train", "test")
TARGET = "duration_s"


@dataclass(eq=False)
class ProgramTable:
    name: str
    blocks: pd.DataFrame
    program: str = ""
    split: str = "train"
    points: pd.DataFrame | None = None
    profile: MachineProfile | None = None
    program_text: str | None = None
    metadata: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.split not in SPLITS:
            raise ModelError(f"{self.name}: split must be one of {', '.join(SPLITS)}, got {self.split!r}")
        if not self.program:
            self.program = self.name
        if "block" in self.blocks.columns and len(self.blocks):
            order = self.blocks["block"].to_numpy()
            if np.any(np.diff(order) <= 0):
                self.blocks = self.blocks.sort_values("block", kind="stable").reset_index(drop=True)

    @property
    def has_target(self) -> bool:
        return TARGET in self.blocks.columns

    def durations(self) -> np.ndarray:
        if not self.has_target:
            raise ModelError(f"{self.name}: block table has no measured {TARGET!r} column")
        d = self.blocks[TARGET].to_numpy(np.float64)
        if not np.all(np.isfinite(d)) or np.any(d < 0):
            bad = int(np.flatnonzero(~np.isfinite(d) | (d < 0))[0])
            raise ModelError(f"{self.name}: block {int(self.blocks['block'].iloc[bad]) if 'block' in self.blocks else bad}"
                             f" has an invalid measured duration {d[bad]!r}")
        return d

    @property
    def measured_cycle_time_s(self) -> float:
        return float(self.durations().sum())

    @property
    def cam_time_s(self) -> float:
        """CAM's estimate: every block at its commanded feed (sum of L / F)."""
        if "nominal_time_s" not in self.blocks.columns:
            raise ModelError(f"{self.name}: block table has no 'nominal_time_s' column for the CAM time")
        return float(np.nansum(self.blocks["nominal_time_s"].to_numpy(np.float64)))


def fingerprint(tables: Sequence[ProgramTable], columns: Sequence[str]) -> str:
    """sha256 over the names and the used columns' values of the training tables (order-sensitive)."""
    h = hashlib.sha256()
    for t in tables:
        h.update(t.name.encode())
        cols = [c for c in columns if c in t.blocks.columns]
        h.update(",".join(cols).encode())
        if cols:
            h.update(pd.util.hash_pandas_object(t.blocks[cols], index=False).to_numpy().tobytes())
    return h.hexdigest()


def window_starts(n: int, length: int, stride: int) -> np.ndarray:
    """Starts of overlapping windows covering 0..n-1; the last one ends at n (one window if n <= length)."""
    if length < 1 or stride < 1:
        raise ModelError(f"window length and stride must be >= 1, got {length}, {stride}")
    if n <= length:
        return np.zeros(1, np.int64)
    starts = np.arange(0, n - length + 1, stride, dtype=np.int64)
    if starts[-1] != n - length:
        starts = np.append(starts, n - length)
    return starts


def make_windows(x: np.ndarray, y: np.ndarray | None, *, length: int, stride: int
                 ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Cut one program (rows x features) into windows: X (w, length, f), Y (w, length), mask (w, length).

    Programs shorter than `length` give one zero-padded window whose mask marks the real rows.
    """
    n = len(x)
    starts = window_starts(n, length, stride)
    if n < length:
        pad = length - n
        xw = np.concatenate([x, np.zeros((pad, x.shape[1]), x.dtype)])[None]
        yw = None if y is None else np.concatenate([y, np.zeros(pad, y.dtype)])[None]
        mask = np.zeros((1, length), bool)
        mask[0, :n] = True
        return xw, yw, mask
    idx = starts[:, None] + np.arange(length)[None, :]
    return x[idx], (None if y is None else y[idx]), np.ones(idx.shape, bool)


def stitch_windows(pred: np.ndarray, n: int, *, length: int, stride: int) -> np.ndarray:
    """Per-row values from overlapping window predictions: each row from the window whose centre is nearest."""
    starts = window_starts(n, length, stride)
    if len(starts) == 1:
        return pred[0, :n]
    rows = np.arange(n)
    centres = starts + (length - 1) / 2.0
    right = np.clip(np.searchsorted(centres, rows), 0, len(starts) - 1)
    left = np.clip(right - 1, 0, len(starts) - 1)
    pick = np.where(np.abs(centres[left] - rows) <= np.abs(centres[right] - rows), left, right)
    return pred[pick, rows - starts[pick]]


def tail_split(n: int, fraction: float) -> int:
    """Index where the validation tail of a program starts (the last `fraction` of its rows)."""
    if n < 2 or fraction <= 0:
        return n
    return max(1, int(round(n * (1.0 - fraction))))


def window_sums(values: np.ndarray, span: int) -> np.ndarray:
    """Sum over the rows k - span .. k + span (clipped at the ends)."""
    values = np.asarray(values, np.float64)
    c = np.concatenate([[0.0], np.cumsum(values)])
    k = np.arange(len(values))
    return c[np.minimum(k + span + 1, len(values))] - c[np.maximum(k - span, 0)]
