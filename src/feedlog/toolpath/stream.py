"""Reading a part program in chunks: block batches with the modal state carried across them.

A mould program from CAM can hold tens of millions of lines. `ProgramReader` reads the file a few
MiB at a time (toolpath.source), parses each chunk of whole lines with the vectorised parser starting
from the modal state the previous chunk left (toolpath.carry), and yields the chunk's rows of the
block table. Memory is bounded by the chunk, not the file; the rows are the rows `parse_program`
gives for the whole file (the same floats: running sums continue across chunks).

    with ProgramReader("part.ngc") as reader:
        for batch in reader:            # DataFrames, block table columns (toolpath.schema)
            ...
        reader.metadata, reader.warnings, reader.unsupported   # complete once the file is read

`parse_program` is `ProgramReader(...).program()`: all batches in one table.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pandas as pd

from feedlog.toolpath.carry import ParseState
from feedlog.toolpath.parser import ChunkFacts, parse_chunk
from feedlog.toolpath.program import Program, Unsupported
from feedlog.toolpath.source import CHUNK_BYTES, open_source


class ProgramReader:
    """Block batches of a part program (a path, or G-code text), one per chunk of about `chunk_bytes`
    of text. Iterating parses; `metadata`, `warnings` and `unsupported` are complete once the
    iteration has ended. A context manager (closes the file when left early)."""

    def __init__(self, source: str | Path, *, lenient: bool = False, name: str | None = None,
                 chunk_bytes: int = CHUNK_BYTES) -> None:
        self.lenient = lenient
        self.path, self.name, self._chunks = open_source(source, name, chunk_bytes=chunk_bytes)
        self.state = ParseState()
        self.rows = 0                  # rows yielded so far
        self.batches = 0               # batches yielded so far
        self.chars = 0                 # characters of text parsed so far (bytes, for ASCII G-code)
        self.motion_rows = 0
        self.done = False
        self.unsupported: list[Unsupported] = []
        self._lines = 0
        self._percent: list[int] = []
        self._block_delete: list[int] = []
        self._meta: dict[str, Any] = {}
        self._after_end = self._after_percent = 0
        self._no_feed: tuple[int, int] | None = None

    def __enter__(self) -> ProgramReader:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        close = getattr(self._chunks, "close", None)
        if close is not None:
            close()

    def __iter__(self) -> Iterator[pd.DataFrame]:
        if self.rows or self.done:
            raise RuntimeError("a ProgramReader is read once")
        for text in self._chunks:
            blocks, facts, self.state = parse_chunk(text, self.state, file=self.name, lenient=self.lenient)
            self._gather(facts)
            end = self._program_end()
            if end is not None and len(blocks) and int(blocks["line"].iat[-1]) > end:
                blocks = blocks[blocks["line"].to_numpy() <= end].reset_index(drop=True)
            self.chars += len(text)
            self.rows += len(blocks)
            self.batches += 1
            yield blocks
        self.done = True

    def _gather(self, f: ChunkFacts) -> None:
        if "end_line" in self._meta:
            self._after_end += f.motion_rows
        elif f.end_line is not None:
            self._meta["end_line"] = f.end_line
            self._after_end += f.motion_after(f.end_line)
        if len(self._percent) >= 2:
            self._after_percent += f.motion_rows
        elif len(self._percent) + len(f.percent_lines) >= 2:
            closing = f.percent_lines[1 - len(self._percent)]
            self._after_percent += f.motion_after(closing)
        self._percent += f.percent_lines
        self._block_delete += f.block_delete_lines
        if f.program_number is not None:
            self._meta.setdefault("program_number", f.program_number)
        if f.title is not None:
            self._meta.setdefault("title", f.title)
        if f.no_feed is not None:
            count, line = f.no_feed
            self._no_feed = (count + (self._no_feed[0] if self._no_feed else 0),
                             self._no_feed[1] if self._no_feed else line)
        self.unsupported += sorted(f.unsupported, key=lambda u: u.line)  # syntax and codes of a line together
        self._lines += f.lines
        end = self._program_end()
        self.motion_rows += f.motion_rows - (f.motion_after(end) if end is not None else 0)  # rows a controller runs

    def _program_end(self) -> int | None:
        """The line a controller stops reading at: the first M2/M30 or the closing '%', if seen yet."""
        ends = [self._meta["end_line"]] if "end_line" in self._meta else []
        if len(self._percent) >= 2:
            ends.append(self._percent[1])
        return min(ends) if ends else None

    @property
    def metadata(self) -> dict[str, Any]:
        """file, lines, percent_lines, program_number (O word), title (first comment), end_line (first
        M2/M30), block_delete_lines: as `Program.metadata`."""
        meta: dict[str, Any] = {"file": self.name, "lines": self._lines + 1, "percent_lines": list(self._percent)}
        for key in ("program_number", "title", "end_line"):
            if key in self._meta:
                meta[key] = self._meta[key]
        if self._block_delete:
            meta["block_delete_lines"] = list(self._block_delete)
        return meta

    @property
    def warnings(self) -> list[str]:
        out: list[str] = []
        if self._no_feed is not None:
            out.append(f"{self._no_feed[0]} feed moves without a feed rate (first at line {self._no_feed[1]})")
        if self._after_end:
            out.append(f"{self._after_end} motion blocks after the program end (M2/M30) at line "
                       f"{self._meta['end_line']}: not run (a controller stops there)")
        if self._after_percent:
            out.append(f"{self._after_percent} motion blocks after the closing '%' at line {self._percent[1]}; "
                       "not run (a controller stops there)")
        if self._block_delete:
            out.append(f"{len(self._block_delete)} lines start with '/' (block delete); kept as if the "
                       "block-delete switch were off")
        out += [f"line {u.line}: skipped {u.code} ({u.reason})" for u in self.unsupported]
        return out

    def program(self) -> Program:
        """The whole program in one block table (reads what is left)."""
        batches = list(self)
        blocks = batches[0] if len(batches) == 1 else pd.concat(batches, ignore_index=True)
        return Program(blocks=blocks, path=self.path, warnings=self.warnings, unsupported=list(self.unsupported),
                       metadata=self.metadata)


def open_program_reader(source: str | Path, *, lenient: bool = False, name: str | None = None,
                        chunk_bytes: int = CHUNK_BYTES, interp=None):
    """A streaming reader of a program: the vectorised ProgramReader, or, for a program that needs the
    interpreter (toolpath.interp: parameters, O-words, cycles, ...; found by scanning the text chunk by
    chunk), an InterpretedReader with the same interface."""
    from feedlog.toolpath.interp.reader import InterpretedReader  # interp imports this module: imported when used
    from feedlog.toolpath.interp.run import needs_interpreter

    _, _, chunks = open_source(source, name, chunk_bytes=chunk_bytes)
    try:
        needs = any(needs_interpreter(chunk) for chunk in chunks)
    finally:
        close = getattr(chunks, "close", None)
        if close is not None:
            close()
    if needs:
        return InterpretedReader(source, name=name, interp=interp)
    return ProgramReader(source, lenient=lenient, name=name, chunk_bytes=chunk_bytes)
