"""LinuxCNC's tool table (`.tbl`): `T<n> P<pocket> X.. Y.. Z.. A.. B.. C.. D<diameter> ;comment` per line,
values in machine units (mm here). G43 reads a tool's offsets, M6/M61 the tool in the spindle."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from feedlog.errors import ProgramError

_FIELDS = "XYZABC"


@dataclass(frozen=True)
class Tool:
    number: int
    pocket: int
    offset: tuple          # (6,) X Y Z A B C offsets, mm / deg
    diameter: float


class ToolTable:
    """Tools by number. Without a table (`assumed=True`) every tool exists with zero length and diameter,
    and the tools so assumed are listed in `assumed_tools` (the program's motion does not depend on them
    unless it uses G43 or cutter compensation, which the interpreter then reports)."""

    def __init__(self, tools: dict[int, Tool] | None = None, *, assumed: bool = False) -> None:
        self.tools = dict(tools or {})
        self.assumed = assumed
        self.assumed_tools: list[int] = []

    def get(self, number: int) -> Tool | None:
        tool = self.tools.get(number)
        if tool is None and self.assumed:
            tool = self.tools[number] = Tool(number=number, pocket=number, offset=(0.0,) * 6, diameter=0.0)
            self.assumed_tools.append(number)
        return tool

    @classmethod
    def of(cls, table: ToolTable | str | Path | None) -> ToolTable:
        """A table as given, read from a file, or (None) the assumed table of a program given none."""
        if isinstance(table, ToolTable):
            return table
        return cls.read(table) if table is not None else cls(assumed=True)

    @classmethod
    def read(cls, path: str | Path) -> ToolTable:
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8", errors="replace")
        except OSError as exc:
            raise ProgramError(f"cannot read tool table: {exc.strerror or exc}", file=str(path)) from None
        tools: dict[int, Tool] = {}
        for number, raw in enumerate(text.splitlines(), start=1):
            code = raw.split(";", 1)[0].strip()
            if not code:
                continue
            words: dict[str, float] = {}
            for token in code.split():
                letter, value = token[0].upper(), token[1:]
                try:
                    words[letter] = float(value)
                except ValueError:
                    raise ProgramError(f"bad tool table word {token!r}", file=str(path), line=number) from None
                if not math.isfinite(words[letter]):
                    raise ProgramError(f"non-finite tool table value {token!r}", file=str(path), line=number)
            if "T" not in words:
                raise ProgramError("tool table line without a T word", file=str(path), line=number)
            t = int(words["T"])
            tools[t] = Tool(number=t, pocket=int(words.get("P", t)),
                            offset=tuple(words.get(a, 0.0) for a in _FIELDS), diameter=words.get("D", 0.0))
        return cls(tools)
