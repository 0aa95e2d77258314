"""The Sinumerik 840D front-end: runs a program with R parameters, DEF variables, control flow,
subprograms (`.spf` along a search path), drilling cycles CYCLE81/82/83 (also modal with MCALL) and
programmable frames (TRANS/ATRANS/ROT/AROT) on the interpreter's machine model (`machine.Machine`),
and returns the same block table as the RS274/NGC interpreter (`file`, `line`, `stack` per row).

    program = interpret_sinumerik("part.mpf", search_path=["subs/"])

Choices (docs/interpreter.md, "Sinumerik"): settable frames G54-G57/G505-G599 have values the program
does not give: taken as zero with a warning; tool lengths (D) are unknown: zero, warned; G64x rounding
tolerances are machine data: the rows carry no tolerance; cutter radius compensation, SCALE/MIRROR,
polar coordinates and other cycles are refused with file and line.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from feedlog.errors import ProgramError
from feedlog.toolpath.interp.block import Block
from feedlog.toolpath.interp.canon import K_DWELL, Source
from feedlog.toolpath.interp.errors import InterpError
from feedlog.toolpath.interp.machine import (INCH_PER_MM, MM_PER_INCH, PATH_CONTINUOUS, PATH_EXACT_STOP,
                                             build_machine, rotate)
from feedlog.toolpath.interp.runner import Interpreter
from feedlog.toolpath.interp.sinumerik_syntax import CALL_CYCLES, SLine, num, parse_line
from feedlog.toolpath.program import Program
from feedlog.toolpath.source import read_source
from feedlog.toolpath.words import STOP_M

MAX_LEVELS = 16                 # program levels, main program included (SINUMERIK 840D sl)
MAX_BLOCKS = 50_000_000         # executed lines before a program counts as a runaway loop
SUFFIXES = (".SPF", ".MPF")
_OPEN = {"IF": "ENDIF", "WHILE": "ENDWHILE", "LOOP": "ENDLOOP", "FOR": "ENDFOR", "REPEAT": "UNTIL"}
_CLOSE = {v: k for k, v in _OPEN.items()}
_AXES = "XYZABC"
_FAST_ADDRESSES = frozenset("XYZABCF")
_PLANE_AXIS = {170: 2, 180: 1, 190: 0}   # the tool (drilling) axis of each plane
_MODAL_M = {0: "stop", 1: "stop", 2: "stop", 30: "stop", 3: "spindle", 4: "spindle", 5: "spindle",
            6: "toolchange"}


_SIMPLE_LINE = re.compile(r"\s*(?:/?\s*N\d+\s*)?(?:[GMXYZABCIJKFSTDHE]\s*=?\s*[-+]?(?:\d+\.?\d*|\.\d+)\s*)*(?:;.*)?\r?",
                          re.IGNORECASE)


class SFile:
    """A program file, parsed whole when first used, with its labels, block numbers and the matching
    lines of its control structures."""

    def __init__(self, name: str, text: str, path: Path | None) -> None:
        self.name = name
        self.path = path
        raw = text.split("\n")
        if raw and raw[-1] == "":
            raw.pop()
        names: set[str] = set()
        self.lines: list[SLine] = [parse_line(r.rstrip("\r"), i + 1, names) for i, r in enumerate(raw)]
        self.labels: dict[str, list[int]] = {}
        self.numbers: dict[int, list[int]] = {}
        self.match: dict[int, int] = {}      # opening line -> its end; end -> opening; IF -> ELSE
        self.else_of: dict[int, int] = {}
        self.proc: tuple | None = None        # ("PROC", name, params)
        self.start = 0
        self.error: tuple[int, str] | None = None
        for i, line in enumerate(self.lines):
            if line.label is not None:
                self.labels.setdefault(line.label, []).append(i)
            if line.n is not None:
                self.numbers.setdefault(line.n, []).append(i)
        for i, line in enumerate(self.lines):
            if line.control is not None and line.control[0] == "PROC":
                self.proc, self.start = line.control, i + 1
                break
            if not line.empty or line.error:
                break
        self._structure()

    def _structure(self) -> None:
        stack: list[tuple[str, int]] = []
        first_error = next((ln for ln in self.lines if ln.error), None)

        def fail(i: int, message: str) -> None:
            if first_error is not None and first_error.number <= i + 1:
                self.error = (first_error.number, first_error.error)
            else:
                self.error = (i + 1, message)

        for i, line in enumerate(self.lines):
            kw = line.control[0] if line.control else None
            if kw in _OPEN:
                stack.append((kw, i))
            elif kw == "ELSE":
                if not stack or stack[-1][0] != "IF" or stack[-1][1] in self.else_of:
                    return fail(i, "ELSE without its IF")
                self.else_of[stack[-1][1]] = i
            elif kw in _CLOSE:
                if not stack or stack[-1][0] != _CLOSE[kw]:
                    what = f"{kw} without its {_CLOSE[kw]}"
                    if stack:
                        what += f" ({stack[-1][0]} of line {stack[-1][1] + 1} is still open)"
                    return fail(i, what)
                _, j = stack.pop()
                self.match[j], self.match[i] = i, j
                if j in self.else_of:
                    self.match[self.else_of[j]] = i
            elif kw == "PROC" and i + 1 != self.start:
                return fail(i, "PROC must be the first statement of a subprogram file")
        if stack:
            kw, j = stack[-1]
            if first_error is not None:   # a line that could not be read may be the structure's end
                self.error = (first_error.number, first_error.error)
                return
            fail(j, f"{kw} without its {_OPEN[kw]} (the file ends first)")


@dataclass
class Frame:
    file: SFile
    name: str = ""
    ret_file: SFile | None = None
    ret_index: int = 0
    call_line: int = 0
    repeat_left: int = 0
    args: list = field(default_factory=list)
    vars: dict = field(default_factory=dict)
    types: dict = field(default_factory=dict)
    for_end: dict = field(default_factory=dict)
    saved: tuple | None = None       # the caller's modal state, for PROC ... SAVE


class SinumerikInterpreter:
    """Runs a Sinumerik program on the machine model; `run()` returns the block table."""

    def __init__(self, source: str | Path, *, name: str | None = None, search_path=(),
                 subprograms: dict[str, str] | None = None, max_blocks: int | None = None,
                 tool_table=None) -> None:
        text, path, label = read_source(source, name)
        self.main = SFile(label, text, path)
        self.search = ([path.parent] if path is not None else []) + [Path(p) for p in search_path]
        self.subprograms = {k.upper(): v for k, v in (subprograms or {}).items()}
        self.max_blocks = MAX_BLOCKS if max_blocks is None else max_blocks
        self.m = build_machine(tool_table=tool_table)
        self.tools, self.canon = self.m.tools, self.m.canon
        self.R = [0.0] * 1000
        self.frames = [Frame(file=self.main, name=Path(label).name)]
        self.file = self.main
        self.index = 0
        self.seq = 0
        self.blocks = 0
        self.motion: int | None = None   # the initial motion code is machine data: warned, then G0
        self.incremental = False
        self.metric_feed_only = False    # G70/G71: geometry in the unit, feeds stay in mm
        self.trans = [0.0, 0.0, 0.0]     # programmable frame, mm
        self.rot = 0.0
        self.settable = 500
        self.mcall: tuple | None = None
        self.warnings: list[str] = []
        self._warned: set[str] = set()
        self.files: dict[str, SFile] = {}
        self.finished = False
        self.metadata: dict = {"file": label, "lines": len(self.main.lines)}

    # -- the environment expressions read ------------------------------------------------------
    def var(self, name: str):
        frame = self.frames[-1]
        if name not in frame.vars:
            raise InterpError(f"variable {name} is not defined in {frame.name} (DEF it first)")
        return frame.vars[name]

    def _assign(self, target: tuple, value) -> None:
        if target[0] == "R":
            self.R[target[1]] = float(num(value))
            return
        frame = self.frames[-1]
        name = target[1]
        if name not in frame.types:
            raise InterpError(f"variable {name} is not defined in {frame.name} (DEF it first)")
        frame.vars[name] = _convert(value, frame.types[name], name)

    # -- places and errors --------------------------------------------------------------------------
    def _stack(self) -> str:
        return " > ".join(f"{Path(f.ret_file.name).name}:{f.call_line}" for f in self.frames[1:]
                          if f.ret_file is not None)

    _error = Interpreter._error       # the error naming file, line and call stack, as the RS274/NGC loop

    def _warn(self, key: str, message: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self.warnings.append(message)

    # -- the loop ---------------------------------------------------------------------------------
    def run(self):
        if self.main.error:
            self.seq = self.main.error[0]
            raise self._error(self.main.error[1])
        if self.main.proc is not None:
            self.index = self.main.start
            self._enter_vars(self.frames[0], self.main.proc, [])
        while not self.finished:
            f = self.file
            if self.index >= len(f.lines):
                self._end_of_file()
                continue
            line = f.lines[self.index]
            self.index += 1
            self.seq = line.number
            try:
                self._line(line)
            except InterpError as exc:
                raise self._error(str(exc), line.raw) from None
            except RecursionError:
                raise self._error("expression nested too deeply", line.raw) from None
        return self.canon.table((0.0,) * 6)

    def _line(self, line: SLine) -> None:
        if line.error:
            raise InterpError(line.error)
        if line.ignored:
            self._ignored(line.ignored)
        if line.empty:
            if line.comment:
                self._record(line, [], line.comment)
                self.m.emit_none()
            return
        self.blocks += 1
        if self.blocks > self.max_blocks:
            raise InterpError(f"more than {self.max_blocks} blocks executed: a runaway loop? "
                              "(the limit is interpreter option max_blocks)")
        if line.control is not None:
            self._control(line)
        else:
            self._block(line)

    def _ignored(self, words: list) -> None:
        if words:
            for word in words:
                if word == "TRAORI":
                    self._warn("ignored:TRAORI", "TRAORI (5-axis transformation) ignored: the axes are read as "
                               "programmed, as the line translation reads them")
                    continue
                self._warn(f"ignored:{word}", f"{word} (dynamics, look-ahead, override or display setting) does not "
                           "change the programmed path: ignored (the machine profile models the dynamics)")

    def _end_of_file(self) -> None:
        if len(self.frames) > 1:
            self._return()
            return
        self.warnings.append(f"{Path(self.file.name).name} ends at line {len(self.file.lines)} without M30/M2: "
                             "read to its end")
        self._finish()

    def _finish(self) -> None:
        self.finished = True
        if self.tools.assumed_tools:
            used = ", ".join(f"T{t}" for t in self.tools.assumed_tools)
            self.warnings.append(f"no tool data: {used} taken with zero length (the D offsets of the machine are "
                                 "not in the program)")

    # -- control flow ---------------------------------------------------------------------------------
    def _jump(self, kind: str, target: str) -> None:
        f, here = self.file, self.index - 1
        if target[0] == "N" and target[1:].isdigit():
            places = f.numbers.get(int(target[1:]), [])
        else:
            places = f.labels.get(target, [])
        forward = [i for i in places if i > here]
        backward = [i for i in places if i < here]
        if kind == "GOTOF":
            dest = forward[0] if forward else None
        elif kind == "GOTOB":
            dest = backward[-1] if backward else (here if here in places else None)
        else:   # GOTO, GOTOC: forward first, then backward
            dest = forward[0] if forward else (backward[-1] if backward else (here if here in places else None))
        if dest is None:
            if kind == "GOTOC":
                return
            where = {"GOTOF": "after", "GOTOB": "before"}.get(kind, "in")
            raise InterpError(f"jump target {target} not found {where} this line in {Path(f.name).name}")
        self.index = dest

    def _control(self, line: SLine) -> None:
        c = line.control
        kw = c[0]
        i = self.index - 1
        f = self.file
        if kw == "IFGOTO":
            if _truth(_value(c[1], self)):
                self._jump(c[2], c[3])
        elif kw == "GOTO":
            self._jump(c[1], c[2])
        elif kw == "IF":
            if not _truth(_value(c[1], self)):
                self.index = f.else_of.get(i, f.match[i]) + 1
        elif kw == "ELSE":
            self.index = f.match[i] + 1
        elif kw == "WHILE":
            if not _truth(_value(c[1], self)):
                self.index = f.match[i] + 1
        elif kw in ("ENDWHILE",):
            self.index = f.match[i]
        elif kw == "ENDLOOP":
            self.index = f.match[i] + 1
        elif kw == "UNTIL":
            if not _truth(_value(c[1], self)):
                self.index = f.match[i] + 1
        elif kw == "FOR":
            var, start, end = c[1], _value(c[2], self), _value(c[3], self)
            target = ("R", int(var[1:])) if var not in self.frames[-1].types and var[0] == "R" else ("V", var)
            self._assign(target, start)
            self.frames[-1].for_end[i] = (target, float(num(end)))
            if self._read(target) > self.frames[-1].for_end[i][1]:
                self.index = f.match[i] + 1
        elif kw == "ENDFOR":
            j = f.match[i]
            state = self.frames[-1].for_end.get(j)
            if state is None:
                raise InterpError("ENDFOR reached without its FOR having run")
            target, end = state
            self._assign(target, self._read(target) + 1)
            if self._read(target) <= end:
                self.index = j + 1
        elif kw == "DEF":
            frame = self.frames[-1]
            for name, typ, init in c[1]:
                frame.types[name] = typ
                value = _value(init, self) if init is not None else ("" if typ == "STRING" else 0.0)
                frame.vars[name] = _convert(value, typ, name)
        elif kw == "RET":
            self._end_sub(line)
        elif kw == "MCALL":
            if c[1] is None:
                self.mcall = None
            else:
                name, args, _ = c[1]
                self.mcall = (name, [None if a is None else _value(a, self) for a in args])
        elif kw == "FRAME":
            self._frame(c[1], {k: float(num(_value(v, self))) for k, v in c[2].items()})
            self._record(line, [], line.comment)
            self.m.emit_none()
        elif kw == "PROC":
            raise InterpError("PROC must be the first statement of a subprogram file")
        elif kw == "ENDPROC":
            self._end_sub(line)
        # ENDIF, LOOP, REPEAT, NOP: nothing to do

    def _read(self, target: tuple) -> float:
        return self.R[target[1]] if target[0] == "R" else self.var(target[1])

    # -- subprograms --------------------------------------------------------------------------------
    def _find(self, name: str) -> SFile | None:
        key = name.upper()
        if key in self.files:
            return self.files[key]
        if key in self.subprograms:
            self.files[key] = SFile(f"{key}.SPF", self.subprograms[key], None)
            return self.files[key]
        for folder in self.search:
            try:
                entries = sorted(folder.iterdir())
            except OSError:
                continue
            for entry in entries:
                upper = entry.name.upper()
                if (entry.suffix.upper() in SUFFIXES and entry.stem.upper() == key) or \
                        upper in (f"_N_{key}_SPF", f"_N_{key}_SPF.SPF"):
                    if entry.is_file():
                        text, path, _ = read_source(entry, None)
                        self.files[key] = SFile(str(entry), text, path)
                        return self.files[key]
        return None

    def _call(self, name: str, args: list, repeat: int | None, line: SLine | None) -> None:
        if name in CALL_CYCLES:
            if repeat is not None:
                raise InterpError(f"P repeat count with {name} is not read")
            self._cycle(name, args)
            return
        if name.startswith("CYCLE"):
            raise InterpError(f"{name} is not simulated (feedlog reads the drilling cycles CYCLE81, CYCLE82, "
                              "CYCLE83)")
        sub = self._find(name)
        if sub is None:
            where = ", ".join(str(s) for s in self.search) or "no folder: the program is text"
            raise InterpError(f"subprogram {name} not found ({name}.SPF looked for in {where})")
        if sub.error:
            self.file, self.seq = sub, sub.error[0]
            raise InterpError(sub.error[1])
        if len(self.frames) >= MAX_LEVELS:
            raise InterpError(f"too many nested subprogram calls (at most {MAX_LEVELS} program levels)")
        frame = Frame(file=sub, name=name, ret_file=self.file, ret_index=self.index, call_line=self.seq,
                      repeat_left=(repeat or 1) - 1, args=args)
        if sub.proc is None and args:
            raise InterpError(f"{name} is called with arguments but has no PROC line with parameters")
        if sub.proc is not None and "SAVE" in sub.proc[3]:
            frame.saved = self._modal()
        self._enter_vars(frame, sub.proc, args)
        self.frames.append(frame)
        self.file, self.index = sub, sub.start

    def _enter_vars(self, frame: Frame, proc, args: list) -> None:
        frame.vars, frame.types, frame.for_end = {}, {}, {}
        params = proc[2] if proc is not None else []
        if len(args) > len(params):
            raise InterpError(f"{frame.name} takes {len(params)} parameter(s), called with {len(args)}")
        for k, (pname, typ, ref) in enumerate(params):
            if ref:
                raise InterpError(f"VAR (call by reference) parameter {pname} of {frame.name} is not read")
            value = args[k] if k < len(args) and args[k] is not None else ("" if typ == "STRING" else 0.0)
            frame.types[pname] = typ
            frame.vars[pname] = _convert(value, typ, pname)

    def _end_sub(self, line: SLine) -> None:
        if len(self.frames) == 1:
            self._record(line, [], line.comment)
            self.m.emit_none()
            self._finish()
            return
        self._return()

    def _return(self) -> None:
        frame = self.frames[-1]
        if frame.repeat_left > 0:
            frame.repeat_left -= 1
            self._enter_vars(frame, frame.file.proc, frame.args)
            self.index = frame.file.start
            return
        self.frames.pop()
        self.file, self.index = frame.ret_file, frame.ret_index
        if frame.saved is not None:
            self._restore(frame.saved)

    def _modal(self) -> tuple:
        m = self.m
        return (self.motion, self.incremental, m.plane, m.inch, self.metric_feed_only, m.control, m.feed_mode,
                list(self.trans), self.rot, self.settable, m.origin_index)

    def _restore(self, saved: tuple) -> None:
        """PROC ... SAVE: the modal G functions and the frame of the caller come back at the return."""
        m = self.m
        (self.motion, self.incremental, m.plane, inch, self.metric_feed_only, m.control, m.feed_mode,
         self.trans, self.rot, self.settable, m.origin_index) = saved
        m._units(inch)
        self._frame_to_machine()

    # -- blocks ---------------------------------------------------------------------------------------
    def _record(self, line: SLine, m_list: list, comment: str) -> None:
        stack = self._stack()
        key = (self.file.name, stack, tuple(m_list), comment)
        src = line.sources.get(key)
        if src is None:
            mcodes = " ".join(f"M{c}" for c in m_list)
            stop = any(c in STOP_M for c in m_list)
            src = line.sources[key] = self.canon.source(Source(self.file.name, self.seq, stack, mcodes, comment,
                                                               -1 if line.n is None else line.n, stop))
        self.m.line_src = src

    def _block(self, line: SLine) -> None:
        m = self.m
        words: dict[str, tuple] = {}
        gs: list[int] = []
        ms: list[int] = []
        msgs: list[str] = []
        for item in line.items:
            if item[0] == "set":
                self._assign(item[1], _value(item[2], self))
            elif item[0] == "msg":
                v = _value(item[1], self)
                if v != "":        # MSG() clears the message
                    msgs.append(v if isinstance(v, str) else _fmt_num(v))
            else:
                w = item[1]
                v = _value(w.value, self)
                if w.address == "G":
                    gs.append(_int_code(v, "G"))
                elif w.address == "M":
                    ms.append(_int_code(v, "M"))
                else:
                    if w.address in words:
                        raise InterpError(f"address {w.address} programmed twice in one block")
                    words[w.address] = (v, w.mode)
        if (not ms and not msgs and line.call is None and self.mcall is None and len(gs) <= 1
                and self._fast(line, gs, words)):
            return
        comment = " ".join([line.comment] * bool(line.comment) + [f"MSG {t}" for t in msgs])
        if not gs and not ms and not words:
            if line.call is not None:
                self._record(line, [], comment)
                self._call_from(line)
            elif comment:
                self._record(line, [], comment)
                m.emit_none()
            return
        self._record(line, ms, comment)
        before = len(self.canon.rows)
        g = self._g_codes(gs, words)
        for a, (v, mode) in words.items():
            if a not in ("T",) and isinstance(v, str):
                raise InterpError(f"address {a} given a text ({v!r})")
        if g.get("dwell"):
            self._dwell(words, gs)
            moved = False
            ends = False
        else:
            moved, ends = self._execute(g, words, ms)
        if self.mcall is not None and moved and not ends:
            self._call(self.mcall[0], self.mcall[1], None, line)
        if len(self.canon.rows) == before:
            m.emit_none()
        if ends:
            self._program_end(ms)
            return
        if line.call is not None:
            self._call_from(line)

    def _fast(self, line: SLine, gs: list, words: dict) -> bool:
        """A block of at most one G0/G1 and axis words X-C (absolute, AC or IC) with or without F runs in the
        machine's fast lane (the general path's checks and rows). False: the general path takes it."""
        m = self.m
        if gs and gs[0] not in (0, 1):
            return False
        motion = gs[0] if gs else self.motion
        if motion is None or not words or not words.keys() <= _FAST_ADDRESSES or words.keys() == {"F"} \
                or not m.fast_ok(motion * 10):
            return False
        v = {}
        for a, (val, mode) in words.items():
            if isinstance(val, str):
                return False            # the general path names the error
            if a == "F":
                f = float(num(val))
                if f < 0:
                    raise InterpError("negative F value")
                v["f"] = f * INCH_PER_MM if m.inch and self.metric_feed_only else f
            else:
                v[a.lower()] = self._axis_value(_AXES.index(a), float(num(val)), mode)
        self.motion = motion
        self._record(line, [], line.comment)
        m.fast_line(motion * 10, v)
        return True

    def _call_from(self, line: SLine) -> None:
        name, args, repeat = line.call
        self._call(name, [None if a is None else _value(a, self) for a in args], repeat, line)

    def _program_end(self, ms: list) -> None:
        if len(self.frames) > 1:
            self._return()
        else:
            self.metadata.setdefault("end_line", self.seq)
            self._finish()

    def _g_codes(self, gs: list, words: dict) -> dict:
        m = self.m
        out: dict = {}
        groups: dict[str, int] = {}

        def group(name: str, code: int) -> None:
            groups[name] = code     # two of one group in a block: the last one holds (`G500 G54`, real programs)

        for code in gs:
            if code in (0, 1, 2, 3):
                group("motion", code)
            elif code == 4:
                group("nonmodal", code)
                out["dwell"] = True
            elif code in (17, 18, 19):
                group("plane", code)
            elif code in (90, 91):
                group("distance", code)
            elif code in (70, 71, 700, 710):
                group("units", code)
            elif code in (9, 60, 64, 641, 642, 643, 644, 645):
                group("path" if code != 9 else "exact", code)
            elif code in (93, 94):
                group("feed", code)
            elif code == 95:
                raise InterpError("G95 (feed per revolution) depends on the spindle: not simulated")
            elif code in (500, 54, 55, 56, 57) or 505 <= code <= 599:
                group("settable", code)
            elif code in (53, 153):
                group("suppress", code)
            elif code == 40:
                pass
            elif code in (41, 42):
                raise InterpError(f"G{code} (tool radius compensation) is not simulated: the tool radius is not in "
                                  "the program")
            elif code in (110, 111, 112):
                raise InterpError(f"G{code} (polar coordinates) is not read")
            elif code in (601, 602, 603, 450, 451, 97):
                pass
            elif code in (25, 26):
                raise InterpError(f"G{code} (working area / spindle speed limit) is not read")
            elif code in (33, 34, 35, 331, 332, 63):
                raise InterpError(f"G{code} (thread cutting / tapping) is spindle-synchronised: not simulated")
            elif code == 96:
                raise InterpError("G96 (constant cutting rate) is not simulated")
            else:
                raise InterpError(f"G{code} is not read by feedlog's Sinumerik front-end")
        if "units" in groups:
            code = groups["units"]
            inch = code in (70, 700)
            m._units(inch)
            self.metric_feed_only = code in (70, 71)
            self._frame_to_machine()
        if "plane" in groups:
            m.plane = {17: 170, 18: 180, 19: 190}[groups["plane"]]
        if "distance" in groups:
            self.incremental = groups["distance"] == 91
        if "path" in groups:
            m.control = PATH_EXACT_STOP if groups["path"] == 60 else PATH_CONTINUOUS
            m.tolerance = m.naive = math.nan
            if groups["path"] in (641, 642, 643, 644, 645):
                self._warn("g64x", "G641..G645 (smoothing): the machine's rounding tolerance is machine data, not in "
                           "the program; the rows carry no tolerance")
        if "feed" in groups:
            fm = 930 if groups["feed"] == 93 else 940
            if fm != m.feed_mode and 930 in (fm, m.feed_mode):
                m.feed = 0.0
            m.feed_mode = fm
        if "settable" in groups:
            code = groups["settable"]
            self.settable = code
            m.origin_index = {54: 1, 55: 2, 56: 3, 57: 4}.get(code, 1)
            if code != 500:
                self._warn(f"settable:{code}", f"G{code} selected: its zero offset is machine data, not in the program; "
                           "taken as zero (the program's coordinates are machine coordinates there)")
        if "motion" in groups:
            self.motion = groups["motion"]
        out["exact"] = "exact" in groups
        out["suppress"] = groups.get("suppress")
        return out

    def _dwell(self, words: dict, gs: list) -> None:
        if set(words) - {"F", "S"} or len(gs) > 1:
            raise InterpError("G4 (dwell) must be programmed in its own block, with F (seconds) or S (revolutions)")
        if "F" in words:
            t = float(num(words["F"][0]))
        elif "S" in words:
            rpm = self.m.speed
            if rpm <= 0:
                raise InterpError("G4 S (dwell in spindle revolutions) without a spindle speed")
            t = float(num(words["S"][0])) * 60.0 / rpm
        else:
            raise InterpError("G4 (dwell) without F (seconds) or S (revolutions)")
        if t < 0:
            raise InterpError("negative dwell time")
        self.m.emit(K_DWELL, self.m.pos, dwell=t)

    def _axis_value(self, k: int, v: float, mode: str) -> float:
        if mode == "IC" or (mode == "" and self.incremental):
            return self.m.pos[k] + v
        return v

    def _execute(self, g: dict, words: dict, ms: list) -> tuple[bool, bool]:
        m = self.m
        b = Block()
        v = b.v
        for a in ("F", "S"):
            if a in words:
                val = float(num(words[a][0]))
                if val < 0:
                    raise InterpError(f"negative {a} value")
                if a == "F" and m.inch and self.metric_feed_only:
                    val *= INCH_PER_MM
                v[a.lower()] = val
        if "T" in words:
            t = words["T"][0]
            if isinstance(t, str):
                self._warn("tname", 'tools selected by name (T="...") have no length here: zero')
            else:
                v["t"] = float(_int_code(t, "T"))
        if "D" in words:
            self._warn("dword", "D (tool offset) values are machine data, not in the program: tool lengths taken as 0")
        for code in ms:
            b.m_list.append(code)
            grp = _MODAL_M.get(code)
            if grp is not None and code not in (2, 30) or (grp is not None and len(self.frames) == 1):
                if grp in b.m:
                    raise InterpError(f"M{b.m[grp]} and M{code} of the same group in one block")
                b.m[grp] = code
        ends = any(c in (2, 30, 17) for c in ms)
        unknown = set(words) - set(_AXES) - {"F", "S", "T", "D", "I", "J", "K", "CR", "TURN", "H", "E"}
        if unknown:
            raise InterpError(f"address {sorted(unknown)[0]} is not read by feedlog's Sinumerik front-end")
        axes = [a for a in _AXES if a in words]
        arc_words = [a for a in ("I", "J", "K", "CR", "TURN") if a in words]
        moved = False
        if axes or arc_words:
            if self.motion is None:
                self._warn("initial-motion", "axes moved before any G0/G1/G2/G3: the initial motion code is machine "
                           "data; taken as G0")
                self.motion = 0
            motion = self.motion
            if arc_words and motion not in (2, 3):
                raise InterpError(f"{arc_words[0]} with G{motion} (I, J, K, CR and TURN belong to G2/G3)")
            suppress = g.get("suppress")
            if suppress is not None:
                if motion not in (0, 1):
                    raise InterpError(f"G{suppress} needs G0 or G1")
                b.g["nonmodal"] = 530
                for a in axes:
                    val, mode = words[a]
                    if mode == "IC" or (mode == "" and self.incremental):
                        raise InterpError(f"G{suppress} with an incremental {a}")
                    v[a.lower()] = float(num(val))
            else:
                for a in axes:
                    k = _AXES.index(a)
                    val, mode = words[a]
                    v[a.lower()] = self._axis_value(k, float(num(val)), mode)
            if motion in (2, 3):
                self._arc_words(words, v)
            b.motion = motion * 10
            moved = True
        if g.get("exact"):
            saved = m.control
            m.control = PATH_EXACT_STOP
            end = m.execute(b)
            m.control = saved
        else:
            end = m.execute(b)
        return moved, ends or end

    def _arc_words(self, words: dict, v: dict) -> None:
        m = self.m
        if "CR" in words:
            if any(a in words for a in "IJK"):
                raise InterpError("CR= and I/J/K in one arc block")
            cr, mode = words["CR"]
            v["r"] = float(num(cr))
        else:
            u, w, n = {170: (0, 1, 2), 180: (2, 0, 1), 190: (1, 2, 0)}[m.plane]
            letters = "IJK"
            if letters[n] in words:
                raise InterpError(f"{letters[n]} given for an arc in the G{m.plane // 10} plane")
            if not any(letters[k] in words for k in (u, w)):
                raise InterpError("arc without its centre (I, J, K) or radius (CR=)")
            for k in (u, w):
                if letters[k] in words:
                    val, mode = words[letters[k]]
                    val = float(num(val))
                    v[letters[k].lower()] = val - m.pos[k] if mode == "AC" else val
        if "TURN" in words:
            turns = float(num(words["TURN"][0]))
            if turns < 0 or turns != int(turns):
                raise InterpError("TURN= must be a whole number 0 or more")
            v["p"] = turns + 1

    # -- frames --------------------------------------------------------------------------------------
    def _frame_to_machine(self) -> None:
        m = self.m
        mach = m._machine_of(m.pos, m._offsets())
        f = INCH_PER_MM if m.inch else 1.0
        for k in range(3):
            m.origin[k] = self.trans[k] * f
        m.rotation = self.rot
        m.pos = m._relative(mach)

    def _frame(self, kw: str, vals: dict) -> None:
        m = self.m
        f = MM_PER_INCH if m.inch else 1.0
        if kw in ("ROT", "AROT"):
            if m.plane != 170 and "RPL" in vals:
                raise InterpError(f"{kw} RPL= in the G{m.plane // 10} plane (a rotation about another axis than Z) "
                                  "is not simulated")
            if "X" in vals or "Y" in vals:
                raise InterpError(f"{kw} about X or Y is not simulated (rotations in the XY plane only)")
            if "RPL" in vals and "Z" in vals:
                raise InterpError(f"{kw} with both RPL= and Z=")
            angle = vals.get("RPL", vals.get("Z", 0.0))
            if kw == "ROT":
                self.trans, self.rot = [0.0, 0.0, 0.0], angle
            else:
                self.rot += angle
        else:
            x, y, z = (vals.get(a, 0.0) * f for a in "XYZ")
            if kw == "TRANS":
                self.trans, self.rot = [x, y, z], 0.0
            else:
                dx, dy = rotate(x, y, self.rot)
                self.trans = [self.trans[0] + dx, self.trans[1] + dy, self.trans[2] + z]
        self._frame_to_machine()

    # -- drilling cycles -------------------------------------------------------------------------------
    def _cycle(self, name: str, args: list) -> None:
        limits = {"CYCLE81": 5, "CYCLE82": 6, "CYCLE83": 12}
        vals = [0.0 if a is None else float(num(a)) for a in args]
        if len(vals) > limits[name]:
            extra = vals[limits[name]:]
            if name != "CYCLE83" or len(vals) > 17 or any(extra):
                raise InterpError(f"{name} takes at most {limits[name]} parameters here ({len(vals)} given)")
        vals += [0.0] * (12 - len(vals))
        rtp, rfp, sdis, dp, dpr = vals[:5]
        m = self.m
        n = _PLANE_AXIS[m.plane]
        d = 1.0 if rtp >= rfp else -1.0
        safe = rfp + d * abs(sdis)
        depth = rfp - d * abs(dpr) if dpr != 0 else dp
        if d * (rfp - depth) < 0:
            raise InterpError(f"{name}: the final drilling depth {depth:g} lies above the reference plane {rfp:g}")
        if d * (rtp - safe) < 0:
            raise InterpError(f"{name}: the retraction plane {rtp:g} lies below the safety plane {safe:g}")
        f = MM_PER_INCH if m.inch else 1.0
        feed = m.feed * f
        if m.feed_mode != 940 or feed <= 0:
            raise InterpError(f"{name} without a feed (program F in mm/min before the cycle)")

        def to(value: float, rapid: bool, feed_mm: float | None = None) -> None:
            end = list(m.pos)
            end[n] = value
            if rapid:
                m.traverse(end)
            else:
                m.feed_to(end, feed_mm if feed_mm is not None else feed)

        def dwell(t: float) -> None:
            if t < 0:
                if m.speed <= 0:
                    raise InterpError(f"{name}: a dwell in revolutions without a spindle speed")
                t = -t * 60.0 / m.speed
            if t > 0:
                m.emit(K_DWELL, m.pos, dwell=t)

        to(safe, True)
        if name in ("CYCLE81", "CYCLE82"):
            to(depth, False)
            if name == "CYCLE82":
                dwell(vals[5])
            to(rtp, True)
            return
        fdep, fdpr, dam, dtb, dts, frf, vari = vals[5:12]
        first = rfp - d * abs(fdpr) if fdpr != 0 else fdep
        if fdpr == 0 and fdep == 0:
            raise InterpError("CYCLE83: first drilling depth (FDEP or FDPR) missing")
        if d * (rfp - first) <= 0:
            raise InterpError(f"CYCLE83: the first drilling depth {first:g} does not lie below the reference plane")
        if d * (first - depth) < 0:
            first = depth
        if frf == 0:
            frf = 1.0
        if not 0.001 <= frf <= 1.0:
            raise InterpError(f"CYCLE83: FRF={frf:g} outside 0.001..1")
        if vari not in (0.0, 1.0):
            raise InterpError(f"CYCLE83: VARI={vari:g} (0 chip breaking, 1 swarf removal)")
        step = d * (rfp - first)
        dam = abs(dam)
        current = first
        to(current, False, feed * frf)
        dwell(dtb)
        strokes = 0
        while d * (current - depth) > 1e-9:
            strokes += 1
            if strokes > 100_000:
                raise InterpError("CYCLE83: more than 100000 strokes")
            step = max(step - dam, dam) if dam > 0 else step
            nxt = current - d * step
            if d * (nxt - depth) < 0:
                nxt = depth
            if vari == 1:
                to(safe, True)
                dwell(dts)
                reached = d * (rfp - current) * f          # mm
                ahead = min(0.6, reached / 50.0) if reached < 30.0 else 0.6
                to(current + d * ahead / f, True)
            else:
                to(current + d * 1.0 / f, False)
            to(nxt, False)
            dwell(dtb)
            current = nxt
        to(rtp, True)


def _value(v, env):
    return v(env) if callable(v) else v


def _truth(v) -> bool:
    return bool(num(v))


def _fmt_num(v: float) -> str:
    return str(int(v)) if v == int(v) else f"{v:.6f}".rstrip("0")


def _int_code(v, letter: str) -> int:
    v = float(num(v))
    if v < 0 or v != math.floor(v):
        if letter == "G" or letter == "M" or v < 0:
            raise InterpError(f"{letter}{v:g}: not a whole number 0 or more")
    return int(v)


def _convert(value, typ: str, name: str):
    if typ == "STRING":
        if not isinstance(value, str):
            raise InterpError(f"{name} is a STRING: a number cannot be assigned")
        return value
    value = float(num(value))
    if typ == "INT":
        return float(math.floor(abs(value) + 0.5)) * (1.0 if value >= 0 else -1.0)
    if typ == "BOOL":
        return 1.0 if value else 0.0
    return value


def interpret_sinumerik(source: str | Path, *, name: str | None = None, options=None, base_dir: Path | None = None,
                        search_path=(), subprograms: dict[str, str] | None = None,
                        max_blocks: int | None = None) -> Program:
    """A Sinumerik program (path or text) through the front-end, as one block table. Subprograms are
    looked for as NAME.SPF (any case) in the program's folder, `base_dir`, `search_path` and
    `options.search_path`, or given as text in `subprograms`."""
    search = ([base_dir] if base_dir is not None else []) + list(search_path)
    tools = None
    if options is not None:
        search += list(options.search_path)
        if max_blocks is None:
            max_blocks = options.max_blocks
        tools = options.tool_table
    it = SinumerikInterpreter(source, name=name, search_path=search, subprograms=subprograms,
                              max_blocks=max_blocks, tool_table=tools)
    blocks = it.run()
    meta = dict(it.metadata)
    meta["interpreter"] = "feedlog.toolpath.interp.sinumerik"
    meta["blocks_executed"] = it.blocks
    return Program(blocks=blocks, path=it.main.path, warnings=list(it.warnings), metadata=meta)


# an address given a value that is not a plain number (`X=SIN(30)`, `Y=2*R1`), outside strings
_COMPUTED_WORD = re.compile(r"=\s*(?![-+]?(?:\d+\.?\d*|\.\d+)(?:\s|$))\S")
_QUOTED = re.compile(r'"[^"]*"')
_SPLINE = re.compile(r"\s*(?:/?\s*N\d+\s*)?(?:ASPLINE|BSPLINE|CSPLINE|POLY)\b", re.IGNORECASE)


def needs_sinumerik_interpreter(text: str) -> bool:
    """Whether a Sinumerik program uses what the line-by-line translation does not read: parameters,
    variables, control flow, calls, cycles, frames, AC/IC."""
    names: set[str] = set()
    for i, raw in enumerate(text.split("\n")):
        if _SIMPLE_LINE.fullmatch(raw):
            continue        # address letters with numbers and a comment: plain, without parsing
        line = parse_line(raw, i + 1, names)
        if line.error is not None and _SPLINE.match(raw):
            return True     # the front-end names what it refuses; the translation would misread it
        if line.error is None and line.plain and _COMPUTED_WORD.search(_QUOTED.sub("0", raw.split(";", 1)[0])):
            return True     # `X=SIN(30)`: the parser folds it to a number, the translation cannot
        if line.error is None and not line.plain:
            if line.control is None and line.call is not None and line.call[0].startswith("CYCLE") \
                    and line.call[0] not in CALL_CYCLES and all(item[0] != "set" for item in line.items):
                continue     # other cycles: the translation drops them with a note, as before
            return True
    return False


def sinumerik_program(text: str, path: Path | None, label: str, *, interp=None,
                      lenient: bool = False) -> tuple[Program | None, str | None]:
    """load_program's hook: (program, None) when the program needs the front-end and it read it;
    (None, None) when the line-by-line translation reads it (plain programs); (None, note) when the
    front-end refused it and `lenient` asks for the translation's reading instead."""
    if not needs_sinumerik_interpreter(text):
        return None, None
    try:
        program = interpret_sinumerik(path if path is not None else text, name=label, options=interp)
    except ProgramError as exc:
        if not lenient:
            raise
        return None, (f"the Sinumerik front-end refused it ({exc}); read leniently line by line, skipping what "
                      "that cannot read")
    program.metadata["dialect"] = "sinumerik"
    return program, None
