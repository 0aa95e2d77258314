"""What a recorded block number counts, read from the data against the program.

Controllers and their monitoring adapters report the executing block in different ways: the line of
the program file (LinuxCNC's `motion.program-line`; Hurco's MTConnect `Block_Number` counts the `%`
line as line 1), the file line not counting a leading `%` line, the block's N word, or a counter of
the blocks executed. `NUMBERINGS` names them; `program_line(values, program, numbering)` turns
recorded values into program file lines (NaN where a value names no block).

`detect` picks the numbering under which the recorded line changes fit the program best: each run of
a constant value is mapped to a program line, and its duration is compared with the time the program
expects on that line (`expected`, seconds per program line: a simulation or L / F). The score of a
numbering is the mean of |log((measured + eps) / (expected + eps))| over the first runs after the
median ratio is taken out (an unknown feed override or rapid rate does not favour one numbering), with
a fixed penalty for a value that names no motion line. The lowest score wins; all scores are reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from feedlog.errors import AlignmentError
from feedlog.toolpath import Program

NUMBERINGS = ("file-lines", "file-lines-no-percent", "n-words", "counter")
EPS_S = 0.15          # seconds added to both durations: line samples are ~0.1-0.2 s apart, shorter says little
UNKNOWN_COST = 3.0    # cost of a run whose value names no motion line (|log| of a 20x mismatch)
START_COST = 0.5     # a numbering under which the first recorded block is not the program's first motion
FIRST_RUNS = 120      # runs scored (the start of a program is where the published file and the run agree most)


def program_line(values: np.ndarray, program: Program, numbering: str) -> np.ndarray:
    """Program file lines (float, NaN: no such block) of recorded block values under `numbering`."""
    v = np.asarray(values, dtype=np.float64)
    blocks = program.blocks
    if numbering == "file-lines":
        return v.copy()
    if numbering == "file-lines-no-percent":
        return v + (1.0 if _leading_percent(program) else 0.0)
    if numbering == "n-words":
        words = blocks[blocks["n_word"] >= 0].drop_duplicates("n_word", keep="first") if "n_word" in blocks else blocks[:0]
        lookup = pd.Series(words["line"].to_numpy(np.float64), index=words["n_word"].to_numpy(np.int64)
                           if len(words) else np.empty(0, np.int64))
        out = np.full(len(v), np.nan)
        ok = np.isfinite(v)
        out[ok] = lookup.reindex(v[ok].astype(np.int64)).to_numpy()
        return out
    if numbering == "counter":
        lines = blocks["line"].drop_duplicates().to_numpy(np.float64)   # the k-th block (1-based)
        k = np.where(np.isfinite(v), v, 0).astype(np.int64)
        ok = (k >= 1) & (k <= len(lines))
        return np.where(ok, lines[np.clip(k - 1, 0, max(len(lines) - 1, 0))] if len(lines) else np.nan, np.nan)
    raise AlignmentError(f"unknown block numbering {numbering!r}; known: {', '.join(NUMBERINGS)}")


def _leading_percent(program: Program) -> bool:
    """Whether the program file starts with a `%` line (the first block then sits on line 2 or later)."""
    if program.path is None:
        return False
    try:
        with open(program.path, encoding="utf-8", errors="replace") as fh:
            return fh.readline().strip().startswith("%")
    except OSError:
        return False


@dataclass
class Numbering:
    name: str
    stated: bool
    scores: dict[str, float]

    def as_dict(self) -> dict:
        return {"numbering": self.name, "from": "stated" if self.stated else "detected from the data",
                "scores": {k: round(v, 4) for k, v in self.scores.items()}}


def run_cost(measured_s: np.ndarray, expected_s: np.ndarray) -> np.ndarray:
    """Per run: |log ratio| of measured to expected duration with the median ratio taken out
    (UNKNOWN_COST where nothing is expected)."""
    known = np.isfinite(expected_s)
    ratio = np.log((measured_s + EPS_S) / (np.where(known, expected_s, 0.0) + EPS_S))
    centre = float(np.median(ratio[known])) if known.any() else 0.0
    return np.where(known, np.abs(ratio - centre), UNKNOWN_COST)


def detect(run_values: np.ndarray, run_s: np.ndarray, program: Program, expected: pd.Series, *,
           stated: str | None = None) -> Numbering:
    """The numbering under which the runs (value, duration) fit `expected` (s per program line) best."""
    if stated not in (None, "auto"):
        if stated not in NUMBERINGS:
            raise AlignmentError(f"unknown block numbering {stated!r}; known: auto, {', '.join(NUMBERINGS)}")
        return Numbering(stated, True, {})
    values = np.asarray(run_values)[:FIRST_RUNS]
    dur = np.asarray(run_s, dtype=np.float64)[:FIRST_RUNS]
    keep = values > 0     # 0: no block (idle, reset)
    scores = {}
    moving = expected[expected > 0]
    first_motion = float(moving.index[0]) if len(moving) else np.nan
    for name in NUMBERINGS:
        lines = program_line(values[keep], program, name)
        exp = expected.reindex(lines).to_numpy(np.float64) if len(lines) else np.empty(0)
        scores[name] = float(run_cost(dur[keep], exp).mean()) if len(exp) else float(UNKNOWN_COST)
        if len(lines) and lines[0] != first_motion:   # a run from the start shows the first motion line first
            scores[name] += START_COST
    best = min(scores, key=lambda k: (scores[k], NUMBERINGS.index(k)))
    if scores[best] >= UNKNOWN_COST:
        raise AlignmentError(f"no block numbering fits the recorded block values to {program.name}: under "
                             f"each ({', '.join(NUMBERINGS)}) they name no motion line; wrong program?")
    return Numbering(best, False, scores)


__all__ = ["NUMBERINGS", "Numbering", "detect", "program_line", "run_cost"]
