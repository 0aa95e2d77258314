"""Program lines seen in a recorded line stream, matched in execution order when lines repeat.

LinuxCNC's `motion.program-line` is the line number in the file being executed: inside a subroutine
file it is that file's line (it says nothing of the file), and a loop or a subroutine called again shows
the same lines again. A line number therefore names a block only together with where the stream is in
the program. Consecutive blocks of one (file, line) (a canned cycle's moves, a loop around one line)
are one group, as the stream shows them as one run; groups are matched to the stream's runs in order:
a group takes the first run with its line within the next `WINDOW` runs, unless the next group's line
comes first (then this group's block was too short to show). Runs of lines that are no motion block
(line 0 at the end, a line the planner merged away) are passed over.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

WINDOW = 64   # runs looked ahead for a group's line


def repeats_lines(motion_blocks: pd.DataFrame) -> bool:
    """Whether a program line (or line number of different files) names more than one run of blocks."""
    keys = _group_keys(motion_blocks)
    first = np.r_[True, keys[1:] != keys[:-1]] if len(keys) else np.zeros(0, bool)
    lines = motion_blocks["line"].to_numpy(dtype=np.int64)[first]
    return len(np.unique(lines)) < len(lines)


def shares_next_run(motion_blocks: pd.DataFrame) -> np.ndarray:
    """Per motion block: whether the next block comes from the same file and line (one run of the stream)."""
    keys = _group_keys(motion_blocks)
    return np.r_[keys[:-1] == keys[1:], False] if len(keys) else np.zeros(0, bool)


def _group_keys(motion_blocks: pd.DataFrame) -> np.ndarray:
    lines = motion_blocks["line"].astype(str).to_numpy()
    if "file" not in motion_blocks.columns:
        return lines.astype(object)
    return (motion_blocks["file"].astype(str).to_numpy().astype(object) + ":" + lines.astype(object))


def match_runs(run_lines: np.ndarray, motion_blocks: pd.DataFrame) -> np.ndarray:
    """Per motion block: the index of the line run it executed in, -1 when it never showed."""
    keys = _group_keys(motion_blocks)
    n = len(keys)
    out = np.full(n, -1, dtype=np.int64)
    if n == 0:
        return out
    starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    ends = np.r_[starts[1:], n]
    glines = motion_blocks["line"].to_numpy(dtype=np.int64)[starts]
    runs = np.asarray(run_lines, dtype=np.int64)
    p = 0
    for g in range(len(starts)):
        window = runs[p:p + WINDOW]
        hit = np.flatnonzero(window == glines[g])
        if not len(hit):
            continue
        r = int(hit[0])
        if g + 1 < len(starts) and glines[g + 1] != glines[g]:
            nxt = np.flatnonzero(window[:r] == glines[g + 1])
            if len(nxt):
                continue  # the next group shows first: this one was too short to show
        out[starts[g]:ends[g]] = p + r
        p += r + 1
    return out


def blocks_from_line_sequence(runs: pd.DataFrame, motion_blocks: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """(start, end) per motion block, NaN where the block never showed, from `runs` (line, t_start_ns,
    t_end_ns; align.blocks.line_runs) matched in execution order."""
    idx = match_runs(runs["line"].to_numpy(), motion_blocks)
    seen = idx >= 0
    start = np.full(len(idx), np.nan)
    end = np.full(len(idx), np.nan)
    start[seen] = runs["t_start_ns"].to_numpy(dtype=np.float64)[idx[seen]]
    end[seen] = runs["t_end_ns"].to_numpy(dtype=np.float64)[idx[seen]]
    return start, end


__all__ = ["WINDOW", "blocks_from_line_sequence", "match_runs", "repeats_lines", "shares_next_run"]
