"""The interpreter loop: reads lines as LinuxCNC does (file by file, line by line, O-words steering
where the next line comes from), evaluates them and runs them on the machine model.

Control flow follows LinuxCNC's own rules, including their corners: an O-word skips forward to a line
with its label (`if` false, `while` false, `break`), jumps back to where a label was seen (`endwhile`,
`endrepeat`, `continue`), labels inside a subroutine belong to it; `o<name> call` jumps to a
subroutine defined earlier in the program or opens `name.ngc` along the search path (the program's
folder, then the given folders); arguments land in #1-#30 and `return`/`endsub [value]` sets
`#<_value>`. A line is parsed once and cached, so loops and subroutines run compiled lines.

Limits: at most MAX_CALL_LEVEL nested calls (LinuxCNC's 10 levels) and `max_blocks` executed blocks (a
runaway loop stops with an error naming the line, never hangs).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from feedlog.errors import ProgramError
from feedlog.toolpath.interp import fanuc_subs
from feedlog.toolpath.interp.block import build, enhance, refuse
from feedlog.toolpath.interp.canon import Source
from feedlog.toolpath.interp.errors import InterpError
from feedlog.toolpath.interp.machine import build_machine
from feedlog.toolpath.interp.syntax import parse_line
from feedlog.toolpath.interp.tools import ToolTable
from feedlog.toolpath.limits import check_positions, check_run_time
from feedlog.toolpath.source import read_source
from feedlog.toolpath.words import STOP_M

MAX_CALL_LEVEL = 10          # LinuxCNC: INTERP_SUB_ROUTINE_LEVELS
MAX_BLOCKS = 20_000_000      # executed lines before a program counts as a runaway loop (about 2 min)
BATCH_ROWS = 1 << 16         # rows per block-table batch when streaming
SUFFIXES = (".ngc", ".nc")


class SourceFile:
    """A program file's lines, parsed on first use."""

    def __init__(self, name: str, text: str, path: Path | None) -> None:
        self.name = name
        self.path = path
        self.lines = text.split("\n")
        if self.lines and self.lines[-1] == "":
            self.lines.pop()
        self.parsed: list = [None] * len(self.lines)
        self.percent = False
        self.first = 0
        for i, raw in enumerate(self.lines):   # LinuxCNC: the first non-blank line may be a lone '%'
            if raw.strip():
                if raw.strip() == "%":
                    self.percent, self.first = True, i + 1
                break


@dataclass
class Label:
    kind: str
    file: SourceFile
    index: int                 # 0-based index of the O-word's line
    repeat: int = -1


@dataclass
class Frame:
    name: str = ""
    ret_file: SourceFile | None = None
    ret_index: int = 0
    call_line: int = 0
    saved: list = field(default_factory=list)
    kind: str = "call"         # "call" (o<name> call) or "m98" (Fanuc-style: M98 P.. L.., back with M99)
    repeats: int = 0           # M98 L: calls still to make after this one


class Interpreter:
    """Run a part program; `batches()` yields block-table batches, `metadata`/`warnings` after."""

    def __init__(self, source: str | Path, *, name: str | None = None, search_path: list[str | Path] = (),
                 tool_table: ToolTable | str | Path | None = None, parameter_file: str | Path | None = None,
                 max_blocks: int = MAX_BLOCKS, arc_tolerance_mm: float | None = None,
                 arc_tolerance_inch: float | None = None) -> None:
        text, path, label = read_source(source, name)
        self.main = SourceFile(label, text, path)
        self.search = ([path.parent] if path is not None else []) + [Path(p) for p in search_path]
        self.m = build_machine(tool_table=tool_table, parameter_file=parameter_file, lookup=self._predefined,
                               arc_tolerance_mm=arc_tolerance_mm, arc_tolerance_inch=arc_tolerance_inch)
        self.tools, self.params, self.canon = self.m.tools, self.m.P, self.m.canon
        self.max_blocks = max_blocks
        self.labels: dict[str, Label] = {}
        self.frames: list[Frame] = [Frame()]
        self.files: dict[Path, SourceFile] = {}
        self.skipping: str | None = None
        self.skipping_to_sub: str | None = None
        self.defining_sub = False
        self.sub_name: str | None = None
        self.executed_if = False
        self.doing_break = False
        self.doing_continue = False
        self.return_value = 0.0
        self.value_returned = 0.0
        self.file = self.main
        self.index = self.main.first
        self.seq = 0
        self.blocks = 0
        self.warnings: list[str] = []
        self.metadata: dict = {"file": label, "lines": len(self.main.lines), "percent_lines": []}
        title = _first_comment(self.main.lines)
        if title:
            self.metadata["title"] = title
        self.finished = False
        self._stack_key = -1
        self._stack_str = ""

    # -- predefined named parameters ------------------------------------------------------------------
    def _predefined(self, name: str) -> float | None:
        m = self.m
        pos = m.pos
        simple = {
            "_x": 0, "_y": 1, "_z": 2, "_a": 3, "_b": 4, "_c": 5,
        }
        if name in simple:
            return pos[simple[name]]
        if name.startswith("_abs_") and name[5:] in "xyzabc" and len(name) == 6:
            return m._machine_position()["xyzabc".index(name[5])]
        table = {
            "_vmajor": 2.9, "_vminor": 0.0, "_task": 0.0, "_line": float(self.seq),
            "_motion_mode": float(max(m.motion_mode, 0)), "_plane": float(m.plane), "_ccomp": 400.0,
            "_metric": 0.0 if m.inch else 1.0, "_imperial": 1.0 if m.inch else 0.0,
            "_absolute": 0.0 if m.incremental else 1.0, "_incremental": 1.0 if m.incremental else 0.0,
            "_inverse_time": 1.0 if m.feed_mode == 930 else 0.0,
            "_units_per_minute": 1.0 if m.feed_mode == 940 else 0.0,
            "_units_per_rev": 1.0 if m.feed_mode == 950 else 0.0,
            "_coord_system": float({1: 540, 2: 550, 3: 560, 4: 570, 5: 580, 6: 590, 7: 591, 8: 592,
                                    9: 593}[m.origin_index]),
            "_tool_offset": 1.0 if m.tlo_on else 0.0,
            "_retract_r_plane": 0.0 if m.retract_r_plane else 1.0,
            "_retract_old_z": 1.0 if m.retract_r_plane else 0.0,
            "_spindle_rpm_mode": 1.0, "_spindle_css_mode": 0.0,
            "_ijk_absolute_mode": 1.0 if m.ijk_absolute else 0.0,
            "_lathe_diameter_mode": 0.0, "_lathe_radius_mode": 0.0,
            "_spindle_on": 1.0 if m.spindle in (3, 4) else 0.0, "_spindle_cw": 1.0 if m.spindle == 3 else 0.0,
            "_mist": 0.0, "_flood": 0.0, "_speed_override": 1.0, "_feed_override": 1.0, "_adaptive_feed": 0.0,
            "_feed_hold": 0.0, "_feed": m.feed, "_rpm": m.speed,
            "_current_tool": float(m.current_tool), "_current_pocket": float(m.current_tool),
            "_selected_tool": float(m.selected_tool), "_selected_pocket": float(m.selected_tool),
            "_value": self.return_value, "_value_returned": self.value_returned,
            "_call_level": float(len(self.frames) - 1), "_remap_level": 0.0, "_metric_machine": 1.0,
        }
        return table.get(name)

    # -- files ------------------------------------------------------------------------------------------
    def _find_sub_file(self, name: str) -> SourceFile | None:
        for folder in self.search:
            for suffix in SUFFIXES:
                candidate = folder / f"{name}{suffix}"
                if candidate.is_file():
                    key = candidate.resolve()
                    if key not in self.files:
                        text, path, label = read_source(candidate, None)
                        self.files[key] = SourceFile(str(candidate), text, path)
                    return self.files[key]
        return None

    # -- errors and places ----------------------------------------------------------------------------
    def _stack(self) -> str:
        key = len(self.frames)
        if self._stack_key == key:
            return self._stack_str
        self._stack_key = key
        self._stack_str = " > ".join(f"{Path(f.ret_file.name).name}:{f.call_line}" for f in self.frames[1:]
                          if f.ret_file is not None)
        return self._stack_str

    def _error(self, message: str, raw: str | None = None) -> ProgramError:
        stack = self._stack()
        if stack:
            message = f"{message} (called from {stack})"
        return ProgramError(message, file=self.file.name, line=self.seq, code=(raw or "").strip()[:40] or None)

    # -- the loop ---------------------------------------------------------------------------------------
    def batches(self, batch_rows: int = BATCH_ROWS) -> Iterator:
        """Block-table batches (DataFrames) as the program runs."""
        start = (0.0,) * 6
        run_time = 0.0
        while not self.finished:
            self._run(batch_rows)
            if self.canon.rows or self.finished:
                first_end = self.canon.rows[-1][3:9] if self.canon.rows else None
                table = self.canon.table(start)
                if first_end is not None:
                    start = tuple(first_end)
                run_time = _check_bounds(table, run_time)
                if len(table) or self.finished:
                    yield table

    def _run(self, until_rows: int) -> None:
        canon_rows = self.canon.rows
        while len(canon_rows) < until_rows:
            f = self.file
            if self.index >= len(f.lines):
                self._end_of_file()
                return
            raw = f.lines[self.index]
            self.index += 1
            self.seq = self.index
            if f.percent and raw.strip() == "%" and self.index - 1 >= f.first:
                self.metadata["percent_lines"].append(self.index)
                self._finish()
                return
            line = f.parsed[self.index - 1]
            if line is None:
                try:
                    line = f.parsed[self.index - 1] = parse_line(raw, self.index)
                except InterpError as exc:
                    if (self.skipping is not None or self.skipping_to_sub is not None) and not _o_line(raw):
                        continue   # LinuxCNC does not read the words of lines it skips
                    raise self._error(str(exc), raw) from None
            try:
                if line.oword is not None:
                    if self._control(line):
                        self._finish()
                        return
                    continue
                if self.skipping is not None or self.skipping_to_sub is not None:
                    continue
                if line.empty:
                    if line.comment:
                        self._record(line, ())
                        self.m.emit_none()
                    continue
                self.blocks += 1
                if self.blocks > self.max_blocks:
                    raise InterpError(f"more than {self.max_blocks} blocks executed: a runaway loop? "
                                      "(the limit is interpreter option max_blocks)")
                if self._execute(line):
                    self._finish()
                    return
            except InterpError as exc:
                raise self._error(str(exc), raw) from None

    def _record(self, line, m_list) -> None:
        stack = self._stack()
        key = (stack, tuple(m_list), self.file.name)
        src = line.sources.get(key)
        if src is None:
            mcodes = " ".join(f"M{c}" for c in m_list)
            stop = any(c in STOP_M for c in m_list)
            n_word = int(line.n) if line.n is not None else -1
            src = line.sources[key] = self.canon.source(Source(self.file.name, self.seq, stack, mcodes,
                                                               line.comment, n_word, stop))
        self.m.line_src = src

    def _execute(self, line) -> bool:
        m = self.m
        P = self.params
        simple = line.simple
        if simple is not None and m.fast_ok(simple[0]):
            if not line.static:
                p = P.p
                p[5420], p[5421], p[5422], p[5423], p[5424], p[5425] = m.pos
                values = {k: (v(P) if callable(v) else v) for k, v in simple[1]}
            else:
                values = dict(simple[1])
            self._record(line, ())
            m.fast_line(simple[0], values)
            return False
        if not line.static:
            p = P.p
            p[5420], p[5421], p[5422], p[5423], p[5424], p[5425] = m.pos
        if not line.words:      # parameter settings only
            self._assign(line)
            if line.comment:
                self._record(line, ())
                m.emit_none()
            return False
        if line.static and line.block is not None:
            b = line.block
        else:
            b = build(line.words, P)
            refuse(b)
            if line.static:
                line.block = b
        if line.assigns:
            self._assign(line)
        if not b.g and not b.m and not b.v:
            if line.comment:
                self._record(line, ())
                m.emit_none()
            return False
        enhance(b, m.motion_mode, m.plane)
        if 99 in b.m_list:
            fanuc_subs.check_m99_in_line(self)
        self._record(line, b.m_list)
        end = m.execute(b)
        if end:
            self.metadata.setdefault("end_line", self.seq)
        return end

    def _assign(self, line) -> None:
        """A line's parameter settings: all values read first, then numbered ones set, then named ones."""
        P = self.params
        values = []
        for target, raw in line.assigns:
            value = raw(P) if callable(raw) else raw
            if isinstance(target, str):
                values.append((target, value))
            else:
                values.append((target(P) if callable(target) else target, value))
        for target, value in values:
            if not isinstance(target, str):
                P.set_numbered(target, value)
        for target, value in values:
            if isinstance(target, str):
                P.set_named(target, value)

    def _finish(self) -> None:
        self.finished = True
        if self.m.unknown_systems:
            names = ", ".join(("G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3")[s - 1]
                              for s in sorted(self.m.unknown_systems))
            self.warnings.append(f"{names} selected but no parameter file gives its offsets: taken as 0, so the "
                                 "program's coordinates are machine coordinates there; pass the machine's .var "
                                 "file (or its INI) for the real offsets")
        if self.tools.assumed_tools:
            used = ", ".join(f"T{t}" for t in self.tools.assumed_tools)
            self.warnings.append(f"no tool table given: {used} taken with zero length and diameter "
                                 "(G43 offsets 0); pass the machine's tool table to use theirs")

    def _end_of_file(self) -> None:
        if self.skipping_to_sub is not None:     # named at the call (LinuxCNC names the file's end)
            name = self.skipping_to_sub
            where = (f"no {name}.ngc in " + ", ".join(str(s) for s in self.search) + ", and ") if self.search else ""
            frame = self.frames.pop()
            self._stack_key = -1
            self.file, self.seq = frame.ret_file, frame.call_line
            raise self._error(f"subroutine o<{name}> not found: {where}no definition further down "
                              f"{Path(self.file.name).name} (end of file seeking o-word o<{name}> sub)")
        if self.skipping is not None and self.defining_sub:
            raise self._error(f"end of file inside the definition of o<{self.sub_name}>: no endsub")
        if len(self.frames) > 1:
            raise self._error("file ended inside a subroutine call (no endsub or return)")
        what = "a closing '%'" if self.file.percent else "a program end (M2/M30) or '%' lines"
        self.warnings.append(f"{Path(self.file.name).name} ends at line {len(self.file.lines)} without {what}: "
                             "LinuxCNC refuses such a file; read to its end")
        self._finish()

    # -- O-words ------------------------------------------------------------------------------------
    def _scoped(self, ow) -> str:
        if ow.kind in ("sub", "endsub", "call", "return", ""):
            return ow.name
        if len(self.frames) > 1:
            scope = self.frames[-1].name
        elif self.defining_sub:
            scope = self.sub_name
        else:
            scope = ""
        cache = ow.scoped
        name = cache.get(scope)
        if name is None:
            name = cache[scope] = f"{scope}#{ow.name}"
        return name

    def _save_label(self, name: str, kind: str) -> None:
        old = self.labels.get(name)
        here = (self.file, self.index - 1)
        if old is not None:
            if (old.file, old.index) == here:
                return
            raise InterpError(f"o-word label o<{name.split('#')[-1]}> already defined in "
                              f"{Path(old.file.name).name}:{old.index + 1}")
        self.labels[name] = Label(kind=kind, file=self.file, index=self.index - 1)

    def _label(self, name: str) -> Label | None:
        return self.labels.get(name)

    def _back_to(self, label: Label) -> None:
        self.file = label.file
        self.index = label.index

    def _control(self, line) -> bool:
        """Run an O-word line; True when it ends the program (M99 in the main program)."""
        ow = line.oword
        kind = ow.kind
        if kind in ("m98", "m99"):
            return fanuc_subs.control(self, line)
        name = self._scoped(ow)
        P = self.params
        # values are read at read time, and not at all while skipping past them
        if kind in ("endsub", "return"):
            if self.skipping is not None and self.skipping != name:
                return
            if ow.test is not None:
                self.return_value = ow.test(P) if callable(ow.test) else ow.test
                self.value_returned = 1.0
            else:
                self.return_value, self.value_returned = 0.0, 0.0
        elif self.defining_sub and kind not in ("sub", ""):
            return
        elif kind == "call":
            if self.skipping is not None:
                return
            args = [a(P) if callable(a) else a for a in ow.args]
        test = None
        if kind in ("while", "repeat", "if", "elseif"):
            if self.skipping is not None and self.skipping != name:
                return
            test = ow.test(P) if callable(ow.test) else ow.test
        if self.skipping is not None and self.skipping != name:
            return
        if self.skipping_to_sub is not None and kind not in ("sub", ""):
            return
        if kind in ("sub", ""):
            fanuc_subs.check_definition(self, kind)
            if self.skipping is not None:
                self._save_label(name, kind)
                self.skipping = None
            self.skipping_to_sub = None
            if kind == "":
                if len(self.frames) == 1:
                    self.metadata.setdefault("program_number", int(name) if name.isdigit() else name)
                return
            if len(self.frames) > 1:
                return   # the sub line of a call
            if self.defining_sub:
                raise InterpError("nested subroutine definition")
            old = self._label(name)
            if old is not None and (old.file, old.index) == (self.file, self.index - 1):
                # the main program runs into a definition it has already met (one found by a call above)
                raise InterpError(f"sub o<{ow.name}> found in illegal location (already defined here; put "
                                  "subroutines before their calls or after the program's end)")
            self._save_label(name, kind)
            self.skipping = name
            self.defining_sub = True
            self.sub_name = name
        elif kind in ("endsub", "return"):
            if len(self.frames) == 1:
                if self.sub_name is None:
                    raise InterpError(f"not in a subroutine definition: o<{ow.name}> {kind}")
                if kind == "endsub":
                    if not self.defining_sub:
                        raise InterpError("not in a subroutine definition")
                    self.skipping = None
                    self.defining_sub = False
                    self.sub_name = None
                return
            if self.skipping is not None and kind == "endsub":
                self.skipping = None
            if self.frames[-1].kind == "m98":
                raise InterpError("Fanuc-style 'O....' subprogram definition must end with 'M99'")
            frame = self.frames.pop()
            self._stack_key = -1
            P.pop(frame.saved)
            self.file = frame.ret_file
            self.index = frame.ret_index
            self.seq = frame.call_line
        elif kind == "call":
            if len(self.frames) >= MAX_CALL_LEVEL:
                raise InterpError(f"too many nested subroutine calls (LinuxCNC allows {MAX_CALL_LEVEL - 1})")
            self.value_returned = 0.0
            frame = Frame(name=name, ret_file=self.file, ret_index=self.index, call_line=self.seq)
            frame.saved = P.push(args)
            self.frames.append(frame)
            self._stack_key = -1
            P.frames[-1]["n_args"] = float(len(args))
            label = self._label(name)
            if label is not None:
                self._back_to(label)
                return
            sub = self._find_sub_file(name)
            if sub is not None:
                self.file = sub
                self.index = 0
            # else, as LinuxCNC: look for its definition further down the file being read (after M2)
            self.skipping = name
            self.skipping_to_sub = name
        elif kind == "do":
            self.skipping = None
            if self._label(name) is None:
                self._save_label(name, kind)
        elif kind == "repeat":
            label = self._label(name)
            if label is not None and (label.file, label.index) != (self.file, self.index - 1):
                raise InterpError(f"duplicate O-word label o{ow.name}")
            if label is None:
                self._save_label(name, kind)
                label = self._label(name)
            self.skipping = None
            if label.repeat == -1:
                label.repeat = int(test + (0.5 if test >= 0 else -0.5))
            if label.repeat > 0:
                label.repeat -= 1
            else:
                self.skipping = name
                label.repeat = -1
        elif kind == "while":
            label = self._label(name)
            if label is not None and label.kind != "do" and (label.file, label.index) != (self.file, self.index - 1):
                raise InterpError(f"duplicate O-word label o{ow.name}")
            if label is None:
                self._save_label(name, kind)
                label = self._label(name)
            self.skipping = None
            if label.kind == "while":
                if test == 0.0:
                    self.skipping = name
            else:   # the end of a do loop
                if test != 0.0 and not self.doing_break:
                    self._back_to(label)
                else:
                    self.doing_break = False
        elif kind == "if":
            label = self._label(name)
            if label is not None and (label.file, label.index) != (self.file, self.index - 1):
                raise InterpError(f"duplicate O-word label o{ow.name}")
            if label is None:
                self._save_label(name, kind)
            if test != 0.0:
                self.skipping = None
                self.executed_if = True
            else:
                self.skipping = name
                self.executed_if = False
        elif kind == "elseif":
            self._expect(name, ("if",), ow)
            if self.executed_if:
                self.skipping = name
                return
            if test != 0.0:
                self.skipping = None
                self.executed_if = True
        elif kind == "else":
            self._expect(name, ("if",), ow)
            if self.executed_if:
                self.skipping = name
                return
            if self.skipping == name:
                self.executed_if = True
                self.skipping = None
        elif kind == "endif":
            self._expect(name, ("if",), ow)
            self.skipping = None
            self.executed_if = True
        elif kind == "break":
            self._expect(name, ("while", "do"), ow)
            self.skipping = name
            self.doing_break = True
        elif kind == "continue":
            self._expect(name, ("while", "do"), ow)
            if self.skipping == name:
                return
            self.skipping = name
            self.doing_continue = True
        elif kind in ("endwhile", "endrepeat"):
            self._expect(name, ("while",) if kind == "endwhile" else ("repeat",), ow)
            if self.skipping == name:
                self.skipping = None
                if self.doing_continue:
                    self.doing_continue = False
                    self._back_to(self._label(name))
                else:
                    self.doing_break = False
                return
            self._back_to(self._label(name))

    def _expect(self, name: str, kinds: tuple, ow) -> None:
        label = self._label(name)
        if label is None:
            raise InterpError(f"undefined O-word label o{ow.name} ({ow.kind} without its opening line)")
        if label.kind not in kinds:
            raise InterpError(f"no matching {'/'.join(kinds)} for o{ow.name} {ow.kind} (found {label.kind} at "
                              f"line {label.index + 1})")


def _o_line(raw: str) -> bool:
    """Whether a line is an O-word line (after an optional '/' and N number), without parsing it."""
    code = "".join(raw.split("(")[0].split(";")[0].split()).lower()
    code = code.lstrip("/")
    if code.startswith("n"):
        code = code[1:].lstrip("0123456789.")
    return code.startswith("o")


_COMMENT = re.compile(r"\(([^()]*)\)|;(.*)")


def _first_comment(lines: list[str]) -> str | None:
    """The program's title as the vectorised parser takes it: the first comment of the file."""
    for raw in lines:
        m = _COMMENT.search(raw)
        if m:
            return (m.group(1) if m.group(1) is not None else m.group(2)).strip()
    return None


def _check_bounds(table, before: float) -> float:
    """feedlog's bounds on a batch (toolpath.limits, as the vectorised parser applies them): positions
    within 1e9 mm, the program's feed and dwell time within 1e9 s. Returns the time so far."""
    n = len(table)
    if not n:
        return before
    files, lines = table["file"].astype(str).to_numpy(), table["line"].to_numpy()

    def fail(r: int, message: str, code: str) -> ProgramError:
        return ProgramError(message, file=files[r], line=int(lines[r]), code=code)

    kind = table["kind"].astype(str).to_numpy()
    moving = np.isin(kind, ("rapid", "linear", "arc_cw", "arc_ccw"))
    start = table[["x0_mm", "y0_mm", "z0_mm", "a0_deg", "b0_deg", "c0_deg"]].to_numpy(float).T
    end = table[["x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"]].to_numpy(float).T
    check_positions(start, end, moving, fail)
    feed = table["feed_mm_min"].to_numpy(float)
    with np.errstate(divide="ignore", invalid="ignore"):
        seconds = np.where(moving & (kind != "rapid") & (feed > 0), table["length_mm"].to_numpy(float) / feed * 60.0,
                           0.0) + table["dwell_s"].to_numpy(float)
    return check_run_time(seconds, fail, what="feed too slow or dwell too long", before=before,
                          code=lambda r: f"F{feed[r]:g}" if kind[r] != "dwell" else "G4")
