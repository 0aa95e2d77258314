"""Recorded lines against a program that is not, line for line, the one that ran.

A published program and the file the machine executed often differ by a few lines (a post-processor
run again, a header added, a block split): the recorded line numbers then drift against the program's.
Line times alone cannot place every extra line (a stretch of short blocks looks the same a few lines
on, and part programs repeat their passes), so `map_lines` claims only what the data pins down:

- the start: runs are taken at offset 0 until the first *mismatch*, a run of at least MISMATCH_S
  seconds (standstills taken out) on a feed-move line the program expects to take less than
  1 / MISMATCH_RATIO of that (not a rapid, which a rapid override slows, nor a line with M codes,
  where a machine may wait); the nearest program line within MAX_OFFSET that
  expects about that time is named as the likely place;
- anchors after it: each program tool change (M6) against the recorded tool change (a standstill on
  one line with the spindle stopped, `session_events`), and the program's last block against the last
  recorded line; when they agree, the runs from the first anchor on are mapped with that offset;
- between the first mismatch and the first anchor, the offset per stretch (`line_stretches`): placed
  where the line times establish it, the rest left out of block timing (their time still counts in the
  cycle); the report says which (`LineMap.as_dict`: `stretches`, `offset_changes`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from feedlog.align.line_numbering import EPS_S
from feedlog.align.line_stretches import stretch_offsets

MAX_OFFSET = 64       # lines the run program may be ahead of (or behind) the published one
MISMATCH_S = 0.5      # a run this long ...
MISMATCH_RATIO = 4.0  # ... on a line expected to take less than 1/4 of it is a mismatch


@dataclass
class LineMap:
    """Per run of the recorded stream: its offset (program line = recorded line - offset), or None where
    the data does not say (left out of block timing)."""

    offsets: list[int | None]
    first_mismatch: dict | None = None
    anchors: list[dict] = field(default_factory=list)
    stretches: list[dict] = field(default_factory=list)   # between the mismatch and the anchor (`line_stretches`)
    changes: list[dict] = field(default_factory=list)     # where the offset changes there

    @property
    def matches(self) -> bool:
        return self.first_mismatch is None and all(o == 0 for o in self.offsets)

    def program_lines(self, run_lines: np.ndarray) -> np.ndarray:
        """Program line per run (NaN where left out)."""
        off = np.array([np.nan if o is None else o for o in self.offsets], dtype=np.float64)
        return np.asarray(run_lines, dtype=np.float64) - off

    def as_dict(self) -> dict:
        left_out = sum(o is None for o in self.offsets)
        return {"matches": self.matches, "first_mismatch": self.first_mismatch, "anchors": self.anchors,
                "runs": len(self.offsets), "runs_left_out": left_out,
                "offsets": sorted({int(o) for o in self.offsets if o is not None}),
                "stretches": self.stretches, "offset_changes": self.changes}

    def warning(self, program_name: str) -> str | None:
        if self.first_mismatch is None:
            return None
        m = self.first_mismatch
        if m.get("found_by") == "anchor":
            text = (f"the recorded lines are not {program_name} line for line: the line times do not say where "
                    "they begin to differ")
        else:
            text = (f"the recorded lines are not {program_name} line for line: recorded line {m['recorded_line']} "
                    f"(at {m['t_s']:.2f} s) lasts {m['measured_s']:.2f} s where the program expects "
                    f"{m['expected_s']:.2f} s" + (f" (program line {m['likely_line']} expects "
                                             f"{m['likely_expected_s']:.2f} s: {m['recorded_line'] - m['likely_line']:+d} "
                                                 "lines?)" if m.get("likely_line") is not None else ""))
        if self.anchors:
            a = self.anchors[0]
            text += (f"; {a['what']} recorded on line {a['recorded_line']} is program line {a['program_line']} "
                     f"({a['offset']:+d})")
        placed = [st for st in self.stretches if st["established"]]
        if placed:
            text += "; placed between them by the line times: " + ", ".join(
                f"recorded {st['recorded_lines'][0]}-{st['recorded_lines'][1]} = program "
                f"{st['program_lines'][0]}-{st['program_lines'][1]} ({st['offset']:+d})" for st in placed)
        left = sum(o is None for o in self.offsets)
        return text + (f"; {left} of {len(self.offsets)} line runs between them are left out of block timing"
                       if left else "")


def map_lines(run_lines: np.ndarray, run_s: np.ndarray, run_t_s: np.ndarray, expected: pd.Series,
              event_lines: set[int], anchors: list[dict], still_s: np.ndarray | None = None,
              rapid_lines: set[int] = frozenset()) -> LineMap:
    """See the module docstring. `expected`: seconds per program line holding a block (0: no motion);
    `event_lines`: program lines with M codes; `still_s`: standstill time per run; `rapid_lines`: lines of rapids
    (a rapid override slows them, so they never count as a mismatch); `anchors`: dicts with `what`, `recorded_line`,
    `program_line` in execution order (tool changes, the program end)."""
    lines = np.asarray(run_lines, dtype=np.int64)
    dur = np.asarray(run_s, dtype=np.float64)
    n = len(lines)
    exp = expected.reindex(lines).to_numpy(np.float64)
    moving_s = dur - (0.0 if still_s is None else np.asarray(still_s, dtype=np.float64))  # standstills are events
    bad = ((moving_s >= MISMATCH_S) & np.isfinite(exp) & (exp > 0) & ((moving_s + EPS_S) > MISMATCH_RATIO * (exp + EPS_S))
           & ~np.isin(lines, list(event_lines | set(rapid_lines))))
    moved = [a for a in anchors if a["recorded_line"] != a["program_line"] and np.any(lines == a["recorded_line"])]
    if not bad.any() and not moved:
        return LineMap([0] * n)
    # no line time gives the place away: the first anchor off by some lines says the lines differ somewhere
    # before it, and nothing before it can be placed
    i = int(np.flatnonzero(bad)[0]) if bad.any() else int(np.flatnonzero(lines == moved[0]["recorded_line"])[0])
    first = {"run": i, "recorded_line": int(lines[i]), "t_s": float(run_t_s[i]), "measured_s": float(dur[i]),
             "expected_s": float(exp[i]) if np.isfinite(exp[i]) else None,
             "found_by": "line time" if bad.any() else "anchor"}
    if not bad.any():
        i = 0
    near = expected.reindex(np.arange(lines[i] - MAX_OFFSET, lines[i] + MAX_OFFSET + 1)).dropna()
    near = near[near > 0]
    if len(near):
        score = np.abs(np.log((dur[i] + EPS_S) / (near.to_numpy() + EPS_S))) + 1e-3 * np.abs(near.index - lines[i])
        j = int(np.argmin(score))
        if score[j] < np.log(2.0):
            first["likely_line"] = int(near.index[j])
            first["likely_expected_s"] = float(near.iloc[j])
    offsets: list[int | None] = [0] * i + [None] * (n - i)
    kept = []
    for a in anchors:
        a = {**a, "offset": int(a["recorded_line"] - a["program_line"])}
        hit = np.flatnonzero((lines == a["recorded_line"]) & (np.arange(n) >= i))
        a["run"] = int(hit[0]) if len(hit) else None
        kept.append(a)
    usable = [a for a in kept if a["run"] is not None and abs(a["offset"]) <= MAX_OFFSET]
    if usable and len({a["offset"] for a in usable}) == 1:   # the anchors agree: map from the first on
        off, r0 = usable[0]["offset"], usable[0]["run"]
        # the blocks just before the anchor that only switch things (M codes, no motion) are the
        # anchor's own: a tool change's M5, M1, M6 lines precede the spindle's restart
        while r0 - 1 >= i and int(lines[r0 - 1]) - off in event_lines:
            r0 -= 1
        for r in range(r0, n):
            offsets[r] = off
        if bad.any() and r0 - i >= 2:
            # between the mismatch and the anchor: the offset per stretch, where the line times establish it
            still = np.zeros(n) if still_s is None else np.asarray(still_s, dtype=np.float64)
            between, stretches, changes = stretch_offsets(lines, np.asarray(run_t_s, dtype=np.float64), still, expected,
                                                          i, r0, 0, off)
            offsets[i:r0] = between
            return LineMap(offsets, first, kept, stretches, changes)
    return LineMap(offsets, first, kept)


__all__ = ["LineMap", "MAX_OFFSET", "map_lines"]
