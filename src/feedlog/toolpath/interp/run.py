"""`interpret()`: a program through the interpreter into a Program (block table + metadata), and the
rule that decides which programs need it.

Plain programs (words and comments only: what CAM posts write) are read by the vectorised parser
(toolpath.parser), which is many times faster and gives the same block table; anything else
(parameters, expressions, O-words, canned cycles, polar coordinates, tool length offsets, G28/G30,
G52, G53, G92.x) goes through the interpreter.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from feedlog.toolpath.interp.runner import Interpreter
from feedlog.toolpath.program import Program

# what the vectorised parser does not read: # [ ] < > @ ^ =, O words, and G/M codes beyond its list
_NEEDS = re.compile(rb"[#\[\]<>@^=]|"
                    rb"o\s*[0-9]+\s*(?:sub|endsub|call|do|while|repeat|if|elseif|else|endif|break|continue|"
                    rb"endwhile|endrepeat|return)|"
                    rb"g\s*0*(?:28|30|33|38|4[1-3]|5[23]|5[5-9]|7[36]|8[1-9]|92\s*\.\s*[23]|5(?:\s*\.\s*[0-3])?)(?![0-9])|"
                    rb"g\s*0*10(?![0-9.])[^\n]*(?:r|l\s*0*1(?![0-9]))|m\s*0*(?:61|98|99)(?![0-9])|"
                    # I/J/K on a line without axis words: a full circle back to where the tool is
                    rb"^(?![^\n]*[xyzabc]\s*[-+.0-9])[^\n]*[ijk]\s*[-+.0-9]",
                    re.IGNORECASE | re.MULTILINE)
_COMMENT = re.compile(rb"\([^)\n]*\)|;[^\n]*")


@dataclass(frozen=True)
class InterpOptions:
    """What the interpreter reads besides the program: folders searched for `o<name> call` files (after
    the program's own folder), LinuxCNC's tool table (`.tbl`, mm) and parameter file (`.var`: work
    offsets, G28/G30 homes, mm), the arc end-radius tolerances (LinuxCNC's INI
    CENTER_ARC_RADIUS_TOLERANCE_MM/_INCH; None: LinuxCNC's defaults) and the runaway-loop limit."""

    search_path: tuple = ()
    tool_table: str | Path | None = None
    parameter_file: str | Path | None = None
    arc_tolerance_mm: float | None = None
    arc_tolerance_inch: float | None = None
    max_blocks: int | None = None
    extra: dict = field(default_factory=dict)

    @classmethod
    def from_ini(cls, ini: str | Path, **overrides) -> InterpOptions:
        """The [RS274NGC] SUBROUTINE_PATH, PARAMETER_FILE, CENTER_ARC_RADIUS_TOLERANCE_* and
        [EMCIO] TOOL_TABLE of a LinuxCNC INI file (paths relative to the INI's folder)."""
        from feedlog.toolpath.interp.ini import read_ini
        return read_ini(ini, cls, **overrides)


def needs_interpreter(text: str | bytes) -> bool:
    """Whether a program uses anything the vectorised parser does not read (comments ignored)."""
    data = text.encode("utf-8", "surrogateescape") if isinstance(text, str) else text
    return _NEEDS.search(_COMMENT.sub(b" ", data)) is not None


def interpret(source: str | Path, *, name: str | None = None, options: InterpOptions | None = None,
              base_dir: Path | None = None, engine=Interpreter, **kw) -> Program:
    """The whole program through the interpreter, as one block table. `options` (or the same names as
    keywords: search_path, tool_table, parameter_file, ...) say what else it reads; `base_dir` is searched
    for subroutine files first when the program is text (a file's own folder always is). `engine`: the
    front-end that reads the program (interp.fanuc.FanucInterpreter for Fanuc macro B)."""
    o = options or InterpOptions(**{k: (tuple(v) if k == "search_path" else v) for k, v in kw.items()})
    search = ([base_dir] if base_dir is not None else []) + list(o.search_path)
    extra = {} if o.max_blocks is None else {"max_blocks": o.max_blocks}
    it = engine(source, name=name, search_path=search, tool_table=o.tool_table,
                     parameter_file=o.parameter_file, arc_tolerance_mm=o.arc_tolerance_mm,
                     arc_tolerance_inch=o.arc_tolerance_inch, **extra)
    batches = list(it.batches())
    blocks = batches[0] if len(batches) == 1 else pd.concat(batches, ignore_index=True)
    meta = dict(it.metadata)
    meta["interpreter"] = "feedlog.toolpath.interp"
    meta["blocks_executed"] = it.blocks
    return Program(blocks=blocks, path=it.main.path, warnings=list(it.warnings), metadata=meta)
