"""The interpreter behind the streaming interface of toolpath.stream.ProgramReader: block-table batches
as the program runs, with the same attributes (rows, chars, metadata, warnings, ...), so that the
commands that stream a program (`feedlog program --stream`, window-by-window simulation) read programs
with loops and subroutines in bounded memory for the output (the program's text is held whole)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pandas as pd

from feedlog.toolpath.interp.run import InterpOptions
from feedlog.toolpath.interp.runner import BATCH_ROWS, Interpreter
from feedlog.toolpath.schema import MOTION_KINDS


class InterpretedReader:
    def __init__(self, source: str | Path, *, name: str | None = None, interp: InterpOptions | None = None,
                 batch_rows: int = BATCH_ROWS) -> None:
        o = interp or InterpOptions()
        extra = {} if o.max_blocks is None else {"max_blocks": o.max_blocks}
        self._it = Interpreter(source, name=name, search_path=list(o.search_path), tool_table=o.tool_table,
                               parameter_file=o.parameter_file, arc_tolerance_mm=o.arc_tolerance_mm,
                               arc_tolerance_inch=o.arc_tolerance_inch, **extra)
        self.path = self._it.main.path
        self.name = self._it.main.name
        self.batch_rows = batch_rows
        self.rows = self.batches = self.motion_rows = 0
        self.done = False
        self.unsupported: list = []
        self._size = sum(len(line) + 1 for line in self._it.main.lines)

    def __enter__(self) -> InterpretedReader:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        pass

    @property
    def chars(self) -> int:
        """Characters of the main file passed so far (a loop may pass the same ones again)."""
        it = self._it
        if self.done:
            return self._size
        if it.file is not it.main:
            return min(self._size, sum(len(s) + 1 for s in it.main.lines[:it.frames[1].ret_index]))
        return min(self._size, sum(len(s) + 1 for s in it.main.lines[:it.index]))

    def __iter__(self) -> Iterator[pd.DataFrame]:
        if self.rows or self.done:
            raise RuntimeError("a reader is read once")
        for blocks in self._it.batches(self.batch_rows):
            self.rows += len(blocks)
            self.batches += 1
            self.motion_rows += int(blocks["kind"].isin(MOTION_KINDS).sum())
            yield blocks
        self.done = True

    @property
    def metadata(self) -> dict[str, Any]:
        return {**self._it.metadata, "interpreter": "feedlog.toolpath.interp", "blocks_executed": self._it.blocks}

    @property
    def warnings(self) -> list[str]:
        return list(self._it.warnings)
