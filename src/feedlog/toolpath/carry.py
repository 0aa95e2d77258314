"""What one chunk of a part program hands to the next: the modal state at the chunk's end.

The parser reads a program in chunks of whole lines (toolpath.stream) and parses each with the same
vectorised code. Everything a line inherits from the lines before it is here: the modal G groups,
feed, tolerances, spindle speed, tool orientation, the position (as the parser sums it, so that a
program parsed in chunks has the positions of the same program parsed at once, to the bit), the work
offsets, the running program time, and where the chunk sits in the file (line and row offsets).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# modal G groups (G code x 10) at the program start: G17 G21 G90 G91.1 G94 G64, no motion mode
MODAL_DEFAULTS = {"motion": -1, "plane": 170, "units": 210, "distance": 900, "arc_distance": 911,
                  "feed_mode": 940, "path": 640}


@dataclass
class PositionCarry:
    """Per axis X Y Z A B C: the running sum of incremental moves (`cs`), the forward-filled term
    `machine - cs` at the last absolute word (`term`), so machine = cs + term, and the machine
    position at the end of the last row (`machine`)."""

    cs: np.ndarray = field(default_factory=lambda: np.zeros(6))
    term: np.ndarray = field(default_factory=lambda: np.zeros(6))
    machine: np.ndarray = field(default_factory=lambda: np.zeros(6))
    incremental: bool = False      # an incremental (G91) row was seen: cs may be non-zero


@dataclass
class OffsetCarry:
    """Work offsets (toolpath.offsets): the coordinate-system table (P1..P9), the G92 offset, the
    active system and the G54.. selection code; `used` once a G10/G92 was seen."""

    table: np.ndarray = field(default_factory=lambda: np.zeros((10, 6)))
    g92: np.ndarray = field(default_factory=lambda: np.zeros(6))
    active: int = 1
    selected: int = 540            # G54 x 10
    used: bool = False

    @property
    def total(self) -> np.ndarray:
        return self.table[self.active] + self.g92


@dataclass
class ParseState:
    """The modal state after the rows parsed so far (the start state before the first chunk)."""

    modal: dict[str, int] = field(default_factory=lambda: dict(MODAL_DEFAULTS))
    feed_mm_min: float = float("nan")     # modal F in mm/min (NaN: none yet)
    feed_mode_before: int | None = None   # feed mode of the last row (None before the first row)
    tol_mm: float = float("nan")
    merge_tol_mm: float = float("nan")
    spindle_rpm: float = 0.0
    ori: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    position: PositionCarry = field(default_factory=PositionCarry)
    offsets: OffsetCarry = field(default_factory=OffsetCarry)
    run_time_s: float = 0.0               # sum of feed and dwell times so far (toolpath.limits)
    first_line: int = 0                   # 0-based index of the chunk's first line in the file
    first_row: int = 0                    # block number of the chunk's first row
