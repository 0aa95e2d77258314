"""A recording of part of a program: which program lines it covers, and the program cut to them.

Machines are often logged per tool or per pass, so a recording may hold only some of the program's
blocks. Three sources say which, in this order:
1. the user: `--lines A:B` (program file lines, both included);
2. the recording's line stream: its `line` column (program lines), or its `block_number` column (the
   controller's N words, as MTConnect `LineLabel` reports them; the UMich sequence column is a counter),
   mapped to the program line holding that N word (`program_lines`);
3. nothing: the whole program.
A line stream that covers the program's feed moves changes nothing (rapids and short lead-ins before the
first line change often go unrecorded); one that leaves more than a tenth of the feed path out cuts the
program to the lines it saw (`auto_lines`). `slice_program` keeps the blocks of those lines with the modal state the
parse gave them (units, offsets, the start point of the first block), so CL points, features and block
tables are computed on the part the machine ran.
"""

from __future__ import annotations

import re
from dataclasses import replace

import numpy as np
import pandas as pd

from feedlog.errors import AlignmentError
from feedlog.recording import Recording
from feedlog.toolpath import Program
from feedlog.toolpath.schema import RAPID

LEFT_OUT_SHARE = 0.1   # feed path the line stream must leave out (share of the program's) to cut the program
_RANGE = re.compile(r"^\s*(\d+)\s*[:-]\s*(\d+)\s*$")


def parse_lines(text: str) -> tuple[int, int]:
    """`A:B` (or `A-B`) -> (A, B), program file lines, 1-based, A <= B."""
    m = _RANGE.match(text or "")
    if not m or not 1 <= int(m.group(1)) <= int(m.group(2)):
        raise AlignmentError(f"--lines wants FIRST:LAST program lines (1-based, FIRST <= LAST), got {text!r}")
    return int(m.group(1)), int(m.group(2))


def program_lines(recording: Recording, program: Program, *, stream: str = "line") -> Recording:
    """The recording with its line stream in program lines: a `block_number` column (N words) becomes a
    `line` column; N words the program does not hold are left out (counted in `metadata`). A recording
    that already has `line`, or has no line stream, comes back unchanged."""
    table = recording.streams.get(stream)
    if table is None or "line" in table.columns or "block_number" not in table.columns:
        return recording
    words = program.blocks[["n_word", "line"]]
    words = words[words["n_word"] >= 0].drop_duplicates("n_word", keep="first")
    lookup = pd.Series(words["line"].to_numpy(), index=words["n_word"].to_numpy())
    lines = lookup.reindex(table["block_number"].to_numpy()).to_numpy()
    known = ~np.isnan(lines)
    if not known.any():
        raise AlignmentError(f"{recording.source or 'recording'}: none of the recorded block numbers "
                             f"(N{', N'.join(str(int(n)) for n in pd.unique(table['block_number'])[:8])}) is an N "
                             f"word of {program.name}; wrong program?")
    mapped = table.loc[known, ["t_ns"]].assign(line=lines[known].astype(np.int64)).reset_index(drop=True)
    metadata = dict(recording.metadata)
    metadata["line_from"] = f"block_number (N words) -> program lines, {int((~known).sum())} samples unknown"
    return replace(recording, streams={**recording.streams, stream: mapped}, metadata=metadata)


def auto_lines(recording: Recording, program: Program, *, stream: str = "line") -> tuple[int, int] | None:
    """The program lines a recording covers when its line stream leaves feed moves out, else None."""
    table = recording.streams.get(stream)
    if table is None or "line" not in table.columns or not len(table):
        return None
    motion = program.motion
    seen = np.intersect1d(pd.unique(table["line"]), motion["line"].to_numpy())
    if not len(seen):
        return None
    first, last = int(seen.min()), int(seen.max())
    feed = (motion["kind"].astype(str) != RAPID).to_numpy()
    length = motion["length_mm"].fillna(0.0).to_numpy()
    left_out = (feed & ~motion["line"].between(first, last).to_numpy()) @ length
    return (first, last) if left_out > LEFT_OUT_SHARE * (feed @ length) else None


def slice_program(program: Program, lines: tuple[int, int]) -> Program:
    """The program's blocks on lines FIRST..LAST (with their parsed modal state)."""
    first, last = lines
    keep = program.blocks["line"].between(first, last)
    motion = program.motion
    if not motion["line"].between(first, last).any():
        have = motion["line"]
        raise AlignmentError(f"{program.name}: no motion on lines {first}:{last} (motion is on lines "
                             f"{int(have.min())}:{int(have.max())})" if len(have) else f"{program.name}: no motion")
    metadata = {**program.metadata, "lines": f"{first}:{last}"}
    return Program(blocks=program.blocks[keep], path=program.path, warnings=list(program.warnings),
                   unsupported=list(program.unsupported), metadata=metadata)
