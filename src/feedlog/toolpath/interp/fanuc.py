"""Fanuc / Haas / Hurco programs with custom macro B, run on the interpreter's machine model.

    program = interpret_fanuc("part.nc", search_path=["subs/"])   # the same block table as interpret()

The front-end reads a program as a Fanuc-style control does (see docs/interpreter.md, "Fanuc / Haas /
Hurco"): variables (`#1`-`#33` local to a G65 call level, `#100`-`#199` and `#500`-`#999` common,
`#0` vacant, system variables for modal state, positions and work offsets), expressions, `IF`/`GOTO`/
`WHILE`/`DO`/`END`, `M98`/`M99` subprograms (in the file as `O` blocks or as `O####` files along the
search path), `G65` macro calls; NC blocks go to `machine.Machine` (the RS274/NGC machine model) after
the Fanuc meanings are mapped: `K` repeats of canned cycles, `P` dwell in milliseconds, `G54.1 P`,
`G68`/`G69` rotation, `G28`/`G53` when the machine's frame is unknown. Every row keeps the file, line
and call stack it came from.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from feedlog.toolpath.dialects import _highest_z
from feedlog.toolpath.interp.block import build, enhance, refuse
from feedlog.toolpath.interp.canon import K_NONE, Source
from feedlog.toolpath.interp.codes import CYCLES, M_GROUP
from feedlog.toolpath.interp.errors import InterpError
from feedlog.toolpath.interp.fanuc_syntax import FLine, parse_line
from feedlog.toolpath.interp.machine import INCH_PER_MM, MM_PER_INCH, build_machine, rotate
from feedlog.toolpath.interp.runner import Interpreter, SourceFile
from feedlog.toolpath.interp.tools import ToolTable
from feedlog.toolpath.program import Program
from feedlog.toolpath.source import read_source
from feedlog.toolpath.words import STOP_M

MAX_M98_LEVEL = 10           # Fanuc 0i: subprogram calls nest 10 deep
MAX_G65_LEVEL = 5            # Fanuc 0i: macro calls nest 5 deep (local variable levels 1-4 + main)
MAX_BLOCKS = 50_000_000      # executed blocks before a program counts as a runaway loop
SUFFIXES = ("", ".nc", ".NC", ".txt", ".TXT", ".tap", ".TAP", ".min", ".MIN", ".cnc", ".CNC", ".ngc")
# G65 arguments (specification I): letter -> local variable
ARGUMENTS = {"A": 1, "B": 2, "C": 3, "I": 4, "J": 5, "K": 6, "D": 7, "E": 8, "F": 9, "H": 11, "M": 13,
             "Q": 17, "R": 18, "S": 19, "T": 20, "U": 21, "V": 22, "W": 23, "X": 24, "Y": 25, "Z": 26}
# codes that change nothing the path simulation needs (look-ahead, smoothing, cancel modes): dropped, noted
DROPPED_G = {51: "G05.1 (AI contour / look-ahead)", 50: "G05 (high-speed machining mode)",
             80: "G08 (look-ahead)", 90: "G09 (exact stop check, one block)", 150: "G15 (polar off)",
             220: "G22 (stroke check)", 230: "G23 (stroke check off)", 500: "G50 (scaling off)",
             501: "G50.1 (mirror off)", 1030: "G103 (Haas look-ahead limit)", 1870: "G187 (Haas smoothing)",
             1310: "G131"}
REFUSED = {
    160: "G16 polar coordinates (Fanuc) are not read",
    270: "G27 reference position check goes to the machine's reference point: not simulated",
    290: "G29 return from the reference point is not simulated",
    310: "G31 skip function ends where a signal trips: the motion is not known from the program",
    370: "G37 tool length measurement ends where the probe trips: not simulated",
    390: "G39 corner offset circular interpolation is not read",
    440: "G44 (negative tool length offset) is not read",
    450: "G45-G48 tool position offsets are not read", 460: "G45-G48 tool position offsets are not read",
    470: "G45-G48 tool position offsets are not read", 480: "G45-G48 tool position offsets are not read",
    510: "G51 scaling is not read", 511: "G51.1 programmable mirror image is not read",
    600: "G60 single direction positioning is not read",
    661: "G66.1 (modal macro call for every block) is not read",
    870: "G87 back boring is not simulated",
    120: "G12 circular pocket (Haas) is not read", 130: "G13 circular pocket (Haas) is not read",
    950: "G95 feed per revolution depends on the spindle speed; not simulated",
}
_LABEL = re.compile(r"^\s*/?\s*[Nn]\s*([0-9]+)")
_PROGRAM = re.compile(r"^\s*[Oo:]\s*([0-9]+)\s*(?:\([^)]*\)\s*)*(?:;.*)?$")


@dataclass
class ProgramText:
    """A program (main or subprogram) inside a file: lines [start, end) of `file`."""

    number: int | None
    file: FanucFile
    start: int
    end: int
    labels: dict | None = None

    def label(self, n: int) -> int:
        if self.labels is None:
            self.labels = {}
            for i in range(self.start, self.end):
                m = _LABEL.match(self.file.lines[i])
                if m:
                    self.labels.setdefault(int(m.group(1)), i)
        index = self.labels.get(n)
        if index is None:
            raise InterpError(f"GOTO / M99 P: sequence number N{n} not found in "
                              f"{'O' + str(self.number) if self.number is not None else 'the program'}")
        return index


class FanucFile(SourceFile):
    """A file's lines, parsed on first use, and the programs it holds (split at `O` numbers)."""

    def __init__(self, name: str, text: str, path: Path | None) -> None:
        super().__init__(name, text, path)
        self.programs: list[ProgramText] = []
        starts = [(i, int(m.group(1))) for i, raw in enumerate(self.lines) if (m := _PROGRAM.match(raw))]
        if starts and any(raw.split("(")[0].split(";")[0].strip() not in ("", "%")
                          for raw in self.lines[:starts[0][0]]):
            self.programs.append(ProgramText(None, self, 0, starts[0][0]))
        elif not starts:
            self.programs.append(ProgramText(None, self, 0, len(self.lines)))
        for k, (i, number) in enumerate(starts):
            end = starts[k + 1][0] if k + 1 < len(starts) else len(self.lines)
            self.programs.append(ProgramText(number, self, i, end))

    def line(self, index: int) -> FLine:
        line = self.parsed[index]
        if line is None:
            line = self.parsed[index] = parse_line(self.lines[index], index + 1)
        return line


@dataclass
class Frame:
    kind: str                       # "main", "m98", "m97", "g65", "g66"
    program: ProgramText
    ret_program: ProgramText | None = None
    ret_index: int = 0
    call_line: int = 0
    call_file: str = ""
    repeats: int = 1
    start: int = 0                              # where a repeat starts again (M97: the N line)
    loops: list = field(default_factory=list)   # (id, index of the WHILE/DO line)


class Variables:
    """Macro variables: `get(i)` -> float or None (vacant); `set(i, value)`."""

    def __init__(self, interp: FanucInterpreter) -> None:
        self.it = interp
        self.locals: list[list] = [[None] * 34]
        self.common: dict[int, float | None] = {}
        self.extended: dict[int, float] = {}        # #7001-#7950: G54.1 P1-P48 (mm)

    def _index(self, i) -> int:
        if i is None:
            raise InterpError("variable number is vacant")
        n = round(i)
        if abs(n - i) > 1e-6:
            raise InterpError(f"variable number #{i:g} is not an integer")
        return int(n)

    def get(self, i) -> float | None:
        n = self._index(i)
        if 1 <= n <= 33:
            return self.locals[-1][n]
        if n == 0:
            return None
        if 100 <= n <= 199 or 500 <= n <= 999:
            return self.common.get(n)
        return self.it.system_get(n)

    def set(self, i, value) -> None:
        n = self._index(i)
        if value is not None and not math.isfinite(value):
            raise InterpError("calculation resulted in infinity or 'not a number'")
        if 1 <= n <= 33:
            self.locals[-1][n] = value
        elif 100 <= n <= 199 or 500 <= n <= 999:
            self.common[n] = value
        elif n == 0:
            raise InterpError("#0 (vacant) cannot be assigned")
        else:
            self.it.system_set(n, value)


class FanucInterpreter:
    """Run a Fanuc-style macro B program; `batches()` yields block-table batches; `metadata`, `warnings`."""

    def __init__(self, source: str | Path, *, name: str | None = None, search_path=(),
                 tool_table: ToolTable | str | Path | None = None, parameter_file: str | Path | None = None,
                 max_blocks: int = MAX_BLOCKS, arc_tolerance_mm: float | None = None,
                 arc_tolerance_inch: float | None = None) -> None:
        text, path, label = read_source(source, name)
        self.main = FanucFile(label, text, path)
        self.search = ([path.parent] if path is not None else []) + [Path(p) for p in search_path]
        self.m = build_machine(tool_table=tool_table, parameter_file=parameter_file,
                               arc_tolerance_mm=arc_tolerance_mm, arc_tolerance_inch=arc_tolerance_inch)
        self.tools, self.params, self.canon = self.m.tools, self.m.P, self.m.canon
        self.m.retract_r_plane = False          # Fanuc and Haas power up in G98 (LinuxCNC: G99)
        self.V = Variables(self)
        self.max_blocks = max_blocks
        self.files: dict[Path, FanucFile] = {}
        main = self.main.programs[0]
        self.frames = [Frame("main", main)]
        self.program = main
        self.file = self.main
        self.index = main.start
        self.seq = 0
        self.blocks = 0
        self.finished = False
        self.warnings: list[str] = []
        self.notes: dict[str, list[int]] = {}
        self.metadata: dict = {"file": label, "lines": len(self.main.lines), "percent_lines": [],
                               "dialect_front_end": "fanuc macro B"}
        if main.number is not None:
            self.metadata["program_number"] = main.number
        title = next((m.group(1).strip() for raw in self.main.lines if (m := re.search(r"\(([^()]*)\)", raw))), None)
        if title:
            self.metadata["title"] = title
        self.rotation: tuple | None = None          # G68: (saved origin, centre, angle)
        self.extended: int | None = None            # G54.1 P in force
        self.unknown_extended: set[int] = set()
        self.last = {"D": None, "H": None, "M": None, "N": None, "T": None, "B": None, "E": None}
        self.g01 = 0
        self.z_top = _highest_z(self.main.lines)   # the rule of the line translation (dialects.py) ...
        self._stack_key = -1
        self._stack_str = ""
        self.written_systems: set[int] = set()
        self.modal_call: tuple | None = None         # G66: (program, repeats, arguments)
        self._loop_ends: dict[tuple, int] = {}     # (program, WHILE/DO line) -> its END line

    # -- places ---------------------------------------------------------------------------------
    def _stack(self) -> str:
        key = len(self.frames)
        if self._stack_key != key:
            self._stack_key = key
            self._stack_str = " > ".join(f"{Path(f.call_file).name}:{f.call_line}" for f in self.frames[1:])
        return self._stack_str

    _error = Interpreter._error       # the error naming file, line and call stack, as the RS274/NGC loop

    def _note(self, what: str) -> None:
        self.notes.setdefault(what, []).append(self.seq)

    # -- system variables -----------------------------------------------------------------------
    def system_get(self, n: int) -> float | None:
        m = self.m
        if 4001 <= n <= 4022 or 4201 <= n <= 4222:
            group = n % 100
            motion = m.motion_mode
            table = {1: float(self.g01), 2: m.plane / 10.0, 3: 91.0 if m.incremental else 90.0, 4: 22.0,
                     5: 93.0 if m.feed_mode == 930 else 94.0, 6: 20.0 if m.inch else 21.0,
                     7: {0: 40.0, 1: 42.0, 2: 41.0}.get(m.comp.side or 0, 40.0), 8: 43.0 if m.tlo_on else 49.0,
                     9: motion / 10.0 if motion in CYCLES else 80.0, 10: 99.0 if m.retract_r_plane else 98.0,
                     11: 50.0, 12: 61.0 if m.control == 1 else 64.0, 13: 97.0,
                     14: 54.1 if self.extended else 53.0 + m.origin_index, 15: 40.0,
                     16: 68.0 if self.rotation else 69.0,
                     17: 15.0, 18: 40.1, 19: 25.0, 20: 160.0, 21: 50.1, 22: 54.2}
            return table.get(group)
        if 4101 <= n <= 4130 or 4301 <= n <= 4330:
            letter = {2: "B", 7: "D", 8: "E", 9: "F", 11: "H", 13: "M", 14: "N", 15: "O", 19: "S", 20: "T"}.get(n % 100)
            if letter == "F":
                return m.feed
            if letter == "S":
                return m.speed
            if letter == "O":
                return float(self.program.number) if self.program.number is not None else None
            if letter == "T":
                return float(m.selected_tool) if m.selected_tool >= 0 else self.last["T"]
            if letter is not None:
                return self.last.get(letter)
            raise InterpError(f"system variable #{n} is not simulated")
        if 5001 <= n <= 5006 or 5041 <= n <= 5046:
            return m.pos[n % 20 - 1] if n < 5040 else m.pos[n - 5041]
        if 5021 <= n <= 5026:
            return m._machine_position()[n - 5021]
        if 5081 <= n <= 5086:
            return m.tool_offset[n - 5081]
        if 5221 <= n <= 5326 and (n - 5221) % 20 < 6:
            k = (n - 5221) % 20
            return self.params.p[n] * (INCH_PER_MM if m.inch and k < 3 else 1.0)
        if 5201 <= n <= 5206:
            return 0.0
        if 7001 <= n <= 7950 and (n - 7001) % 20 < 6:
            value = self.V.extended.get(n)
            k = (n - 7001) % 20
            return None if value is None else value * (INCH_PER_MM if m.inch and k < 3 else 1.0)
        if n in (3001, 3002, 3011, 3012, 3901, 3902):
            return self.V.common.get(n, 0.0)
        raise InterpError(f"system variable #{n} is not simulated (or does not exist)")

    def system_set(self, n: int, value) -> None:
        m = self.m
        if n == 3000:
            raise InterpError(f"macro alarm #3000 = {value if value is None else f'{value:g}'} raised by the program")
        if n == 3006:
            self._note("#3006 (message stop) ignored: the program does not wait here")
            return
        if n in (3001, 3002, 3003, 3004, 3901, 3902):
            self.V.common[n] = value
            return
        if 5221 <= n <= 5326 and (n - 5221) % 20 < 6:
            k = (n - 5221) % 20
            system = (n - 5221) // 20 + 1
            if self.rotation is not None:
                raise InterpError("a work offset cannot be changed under G68 rotation (G69 first)")
            self.params.p[n] = (value or 0.0) * (MM_PER_INCH if m.inch and k < 3 else 1.0)
            if system == m.origin_index and self.extended is None:
                machine = m._machine_position()
                m.origin = [m._user_to_program(self.params.p[5201 + system * 20 + j], j) for j in range(6)]
                m.pos = m._relative(machine)
            self.written_systems.add(system)
            return
        if 7001 <= n <= 7950 and (n - 7001) % 20 < 6:
            k = (n - 7001) % 20
            self.V.extended[n] = None if value is None else value * (MM_PER_INCH if m.inch and k < 3 else 1.0)
            p = (n - 7001) // 20 + 1
            if self.extended == p:
                self._extended_offset(p)
            return
        if 5201 <= n <= 5206:
            if value:
                raise InterpError(f"#{n}: the external work offset is not simulated (only 0 can be written)")
            return
        raise InterpError(f"system variable #{n} cannot be written here (not simulated)")

    # -- files and programs ---------------------------------------------------------------------
    def _find_program(self, number: int) -> ProgramText:
        for f in [self.main, *self.files.values()]:
            for p in f.programs:
                if p.number == number:
                    return p
        names = [f"O{number:04d}", f"O{number}", f"o{number:04d}", f"o{number}", f"{number:04d}", f"{number}"]
        for folder in self.search:
            for base in dict.fromkeys(names):
                for suffix in SUFFIXES:
                    candidate = folder / f"{base}{suffix}"
                    if candidate.is_file():
                        key = candidate.resolve()
                        if key not in self.files:
                            text, path, _ = read_source(candidate, None)
                            self.files[key] = FanucFile(str(candidate), text, path)
                        f = self.files[key]
                        for p in f.programs:
                            if p.number in (number, None):
                                return p
                        raise InterpError(f"{candidate.name} does not hold program O{number}")
        where = ", ".join(str(s) for s in self.search) if self.search else "no folder (the program is text)"
        raise InterpError(f"program O{number} not found (in this file, nor as O{number:04d}[.nc] in {where})")

    # -- the loop -----------------------------------------------------------------------------------
    batches = Interpreter.batches      # the same batching of the block table as the RS274/NGC loop

    def _run(self, until_rows: int) -> None:
        rows = self.canon.rows
        while len(rows) < until_rows and not self.finished:
            prog = self.program
            if self.index >= prog.end:
                try:
                    self._end_of_program()
                except InterpError as exc:
                    self.seq = prog.end
                    raise self._error(str(exc)) from None
                continue
            f = prog.file
            self.file = f
            i = self.index
            self.index += 1
            self.seq = i + 1
            raw = f.lines[i]
            try:
                line = f.line(i)
                if line.kind in ("blank", "program"):
                    if line.comment and line.kind == "blank":
                        self._record(line, [])
                        self.m.emit_none()
                    continue
                if line.kind == "percent":
                    if i > prog.start and any(f.lines[j].strip() for j in range(prog.start, i)):
                        self.metadata["percent_lines"].append(i + 1)
                        self._end_of_program(percent=True)
                    continue
                self.blocks += 1
                if self.blocks > self.max_blocks:
                    raise InterpError(f"more than {self.max_blocks} blocks executed: a runaway loop? "
                                      "(the limit is interpreter option max_blocks)")
                if line.n is not None:
                    self.last["N"] = float(line.n)
                kind = line.kind
                if kind == "":
                    self._block(line)
                elif kind == "goto":
                    self._goto(line.target)
                elif kind == "if_goto":
                    if self._truth(line.test):
                        self._goto(line.target)
                elif kind == "if_then":
                    if self._truth(line.test):
                        self._assign(line)
                elif kind in ("while", "do"):
                    self._loop_start(line, i)
                elif kind == "end":
                    self._loop_end(line)
                elif kind == "output":
                    self._note(f"{line.target} (external output) ignored: it moves nothing")
            except InterpError as exc:
                raise self._error(str(exc), raw) from None

    def _value(self, v):
        return v(self.V) if callable(v) else v

    def _truth(self, test) -> bool:
        value = self._value(test)
        return value is not None and value != 0.0

    def _assign(self, line: FLine) -> None:
        for target, value in line.assigns:
            self.V.set(self._value(target), self._value(value))

    def _goto(self, target) -> None:
        n = self._value(target)
        if n is None:
            raise InterpError("GOTO to a vacant sequence number")
        if abs(n - round(n)) > 1e-6 or not 0 <= n <= 99999:
            raise InterpError(f"GOTO {n:g}: not a sequence number (0-99999)")
        index = self.program.label(int(round(n)))
        self._leave_loops(self.frames[-1], index)
        self.index = index

    def _leave_loops(self, frame: Frame, index: int) -> None:
        """A jump to line `index` leaves the loops it lands outside of (a GOTO may leave a loop)."""
        keep = []
        for m, at in frame.loops:
            key = (id(frame.program), at)
            end = self._loop_ends.get(key)
            if end is None:
                saved = self.program
                self.program = frame.program
                try:
                    end = self._loop_ends[key] = self._find_end(m, at)
                finally:
                    self.program = saved
            if at < index <= end:
                keep.append((m, at))
        frame.loops = keep

    def _loop_start(self, line: FLine, i: int) -> None:
        frame = self.frames[-1]
        m = line.target
        if line.kind == "while" and not self._truth(line.test):
            frame.loops = [(k, at) for k, at in frame.loops if at != i]
            self.index = self._find_end(m, i) + 1
            return
        if not frame.loops or frame.loops[-1] != (m, i):
            if any(k == m for k, _ in frame.loops):
                raise InterpError(f"DO {m} inside a loop that already uses DO {m}")
            if len(frame.loops) >= 3:
                raise InterpError("loops nest at most 3 deep (DO 1-3)")
            frame.loops.append((m, i))

    def _find_end(self, m: int, i: int) -> int:
        prog = self.program
        depth = 0
        for j in range(i + 1, prog.end):
            raw = prog.file.lines[j]
            if "END" not in raw.upper() and "DO" not in raw.upper():
                continue
            try:
                line = prog.file.line(j)
            except InterpError:
                continue
            if line.kind in ("while", "do") and line.target == m:
                depth += 1
            elif line.kind == "end" and line.target == m:
                if depth == 0:
                    return j
                depth -= 1
        raise InterpError(f"no END {m} for this DO {m}")

    def _loop_end(self, line: FLine) -> None:
        frame = self.frames[-1]
        m = line.target
        if not frame.loops:
            raise InterpError(f"END {m} without a DO {m}")
        if frame.loops[-1][0] != m:
            raise InterpError(f"END {m} does not match the innermost DO {frame.loops[-1][0]}")
        self.index = frame.loops[-1][1]       # back to the WHILE / DO line

    # -- program ends and returns ------------------------------------------------------------------
    def _end_of_program(self, percent: bool = False) -> None:
        frame = self.frames[-1]
        if frame.kind == "main":
            if not percent:
                what = ("the next program's O number" if self.program.end < len(self.program.file.lines)
                        else "the end of the file")
                self.warnings.append(f"{Path(self.file.name).name}: the main program reaches {what} at line "
                                     f"{self.program.end} without M30/M02: read to there")
            self._finish()
            return
        raise InterpError(f"subprogram O{frame.program.number} ends without M99")

    def _return(self, p_label) -> None:
        frame = self.frames[-1]
        if frame.kind == "main":
            self._note("M99 in the main program (it would restart the program endlessly) ends the program")
            self._finish()
            return
        if frame.repeats > 1:
            frame.repeats -= 1
            frame.loops = []
            self.index = frame.start
            return
        self.frames.pop()
        self._stack_key = -1
        if frame.kind in ("g65", "g66"):
            self.V.locals.pop()
        self.program = frame.ret_program
        self.file = self.program.file
        self.index = frame.ret_index
        if p_label is not None:
            self.index = self.program.label(int(round(p_label)))
            self._leave_loops(self.frames[-1], self.index)

    def _call(self, kind: str, number: int, repeats: int, args: dict | None) -> None:
        """M98 / G65 (program `number`) or M97 (Haas: sequence number `number` of this program)."""
        level = sum(1 for f in self.frames if f.kind in ("g65", "g66"))
        if len(self.frames) > MAX_M98_LEVEL:           # the main program's frame + 10 calls
            raise InterpError(f"subprogram / macro calls nested more than {MAX_M98_LEVEL} deep")
        if kind in ("g65", "g66") and level >= MAX_G65_LEVEL - 1:
            raise InterpError(f"G65 macro calls nested more than {MAX_G65_LEVEL - 1} deep (Fanuc's local levels)")
        if repeats < 1:
            return                                   # L0: the call is not made
        prog = self.program if kind == "m97" else self._find_program(number)
        start = prog.label(number) if kind == "m97" else prog.start
        frame = Frame(kind, prog, ret_program=self.program, ret_index=self.index, call_line=self.seq,
                      call_file=self.file.name, repeats=repeats, start=start)
        self.frames.append(frame)
        self._stack_key = -1
        if kind in ("g65", "g66"):
            local = [None] * 34
            for k, v in (args or {}).items():
                local[k] = v
            self.V.locals.append(local)
        self.program = prog
        self.file = prog.file
        self.index = start

    def _finish(self) -> None:
        self.finished = True
        m = self.m
        unknown = sorted(s for s in m.unknown_systems if s not in self.written_systems)
        if unknown:
            names = ", ".join(("G54", "G55", "G56", "G57", "G58", "G59")[s - 1] for s in unknown if s <= 6)
            self.warnings.append(f"{names} selected but neither a parameter file nor the program gives its offsets: "
                                 "taken as 0, so the program's coordinates are machine coordinates there")
        if self.unknown_extended:
            names = ", ".join(f"G54.1 P{p}" for p in sorted(self.unknown_extended))
            self.warnings.append(f"{names} selected but the program does not set its offsets (#7001-#7950 or "
                                 "G10 L20): taken as 0, so the program's coordinates are machine coordinates there")
        if self.tools.assumed_tools:
            used = ", ".join(f"T{t}" for t in self.tools.assumed_tools)
            self.warnings.append(f"no tool table given: {used} taken with zero length and diameter "
                                 "(G43 offsets 0); pass the machine's tool table to use theirs")
        for what, where in self.notes.items():
            more = f" (and {len(where) - 1} more blocks)" if len(where) > 1 else ""
            self.warnings.append(f"fanuc: line {where[0]}{more}: {what}")

    # -- NC blocks ----------------------------------------------------------------------------------
    def _record(self, line: FLine, m_codes: list) -> int:
        stack = self._stack()
        key = (self.file.name, stack, tuple(m_codes))
        src = line.sources.get(key)
        if src is None:
            mcodes = " ".join(f"M{c:g}" for c in m_codes)
            stop = any(c in STOP_M for c in m_codes)
            src = line.sources[key] = self.canon.source(Source(self.file.name, self.seq, stack, mcodes, line.comment,
                                                               line.n if line.n is not None else -1, stop))
        self.m.line_src = src
        return src

    def _block(self, line: FLine) -> None:
        V = self.V
        words: list = []
        for letter, raw, point in line.words:
            value = raw(V) if callable(raw) else raw
            if value is not None:
                words.append((letter, value, point))
        self._assign(line)
        if not words:
            if line.comment and not line.assigns:
                self._record(line, [])
                self.m.emit_none()
            return
        self._nc(line, words)

    def _nc(self, line: FLine, words: list) -> None:
        if self._fast(line, words):
            return
        g_codes = []
        letters: dict[str, float] = {}
        points: dict[str, bool] = {}
        m_codes = []
        for letter, value, point in words:
            if letter == "G":
                code = round(value * 10)
                if abs(code - value * 10) > 1e-3:
                    raise InterpError(f"G code out of range (G{value:g})")
                g_codes.append(code)
            elif letter == "M" and not _is_g65(words):
                if abs(value - round(value)) > 1e-6:
                    raise InterpError(f"non-integer M code (M{value:g})")
                m_codes.append(int(round(value)))
            elif letter == "M":
                m_codes.append(value)
            else:
                if letter in letters and not (letter in "IJK" and _is_g65(words)):
                    raise InterpError(f"multiple {letter} words on one block")
                letters[letter] = value
                points[letter] = point
        for letter in ("D", "H", "T", "B", "E"):
            if letter in letters:
                self.last[letter] = letters[letter]
        if m_codes:
            self.last["M"] = float(m_codes[-1])
        # macro calls and subprograms
        if 650 in g_codes or 660 in g_codes:
            code = 65 if 650 in g_codes else 66
            if len(g_codes) > 1:
                raise InterpError(f"G{code} must stand alone with its P, L and arguments")
            self._record(line, [])
            if "P" not in letters:
                raise InterpError(f"G{code} without P (the macro's program number)")
            number = _integer(letters.pop("P"), f"G{code} P")
            repeats = _integer(letters.pop("L", 1.0), f"G{code} L")
            if len(m_codes) > 1:
                raise InterpError(f"two M arguments on a G{code} block")
            if code == 65:
                self._call("g65", number, repeats, _arguments(words))
            else:                       # G66: the call is made after every later block that moves
                self._find_program(number)
                self.modal_call = (number, repeats, _arguments(words))
                self.m.emit_none()
            return
        if 670 in g_codes:
            g_codes.remove(670)
            self.modal_call = None
        moves = self.modal_call is not None and any(k in letters for k in "XYZABC")
        call = None
        returning = 99 in m_codes
        ret_label = None
        if 98 in m_codes or 97 in m_codes:
            code = 98 if 98 in m_codes else 97
            if 98 in m_codes and 97 in m_codes:
                raise InterpError("M97 and M98 on one block")
            if "P" not in letters:
                raise InterpError(f"M{code} without P (the {'subprogram' if code == 98 else 'sequence'} number)")
            p = _integer(letters.pop("P"), f"M{code} P")
            if "L" in letters:
                times = _integer(letters.pop("L"), f"M{code} L")
            elif p > 9999 and code == 98:       # Fanuc: M98 P0005 1234 = O1234 five times
                times, p = p // 10000, p % 10000
            else:
                times = 1
            call = (p, times, "m98" if code == 98 else "m97")
            m_codes.remove(code)
        if returning:
            ret_label = letters.pop("P", None)
            m_codes.remove(99)
        if g_codes or letters or m_codes or not (call or returning):
            self._machine_block(line, g_codes, letters, points, m_codes)
        else:
            self._record(line, [int(call[2][1:])] if call else [99])
            self.m.emit_none()
        if self.finished:
            return
        if moves and not any(f.kind == "g66" for f in self.frames):   # not from inside the called macro
            if call is not None or returning:
                raise InterpError("M98/M99 on a block that makes a G66 modal macro call")
            number, repeats, args = self.modal_call
            self._call("g66", number, repeats, dict(args))
            return
        if call is not None:
            self._call(call[2], call[0], call[1], None)
        elif returning:
            self._return(ret_label)

    def _fast(self, line: FLine, words: list) -> bool:
        """A block of at most one G0/G1, axis words X-C and F (what loops of moves are made of), with no
        modal macro call in force, runs in the machine's fast lane (the same checks and rows as the
        general path). False: the block takes the general path."""
        if self.modal_call is not None:
            return False
        motion = -1
        v = {}
        for letter, value, _point in words:
            if letter == "G":
                if motion != -1 or value not in (0.0, 1.0):
                    return False
                motion = int(value) * 10
            elif letter in _FAST_LETTERS and letter not in v:
                v[letter] = value
            else:
                return False
        if not self.m.fast_ok(motion) or not any(k != "F" for k in v):
            return False
        if motion != -1:
            self.g01 = motion // 10
        self._record(line, [])
        if "Z" in v and (motion in (0, 10) or self.m.motion_mode in (0, 10)):
            z = v["Z"] + (self.m.pos[2] if self.m.incremental else 0.0)
            self.z_top = z if self.z_top is None else max(self.z_top, z)
        self.m.fast_line(motion, {k.lower(): x for k, x in v.items()})
        return True

    def _machine_block(self, line: FLine, g_codes: list, letters: dict, points: dict, m_codes: list) -> None:
        m = self.m
        passed_m = []
        for c in m_codes:
            if c == 99:
                continue
            if c in M_GROUP and c not in (48, 49, 50, 51, 52, 53, 62, 63, 64, 65, 66, 67, 68, 70, 71, 72, 73) \
                    and c < 100:
                passed_m.append(c)
            else:
                self._note(f"M{c} (machine function) recorded, no motion")
        g = []
        dropped = False
        for code in g_codes:
            if code == 1540 or (1100 <= code <= 1290 and code % 10 == 0):
                # Haas: G154 P1-P99 and G110-G129 (= G154 P1-P20) select the extended offsets of G54.1
                if code != 1540:
                    if "P" in letters:
                        raise InterpError(f"G{code // 10} with a P word (it is G154 P{code // 10 - 109})")
                    letters["P"] = float(code // 10 - 109)
                code = 541
            if code in DROPPED_G:
                self._note(f"{DROPPED_G[code]} dropped: it does not move the programmed path")
                dropped = True
                continue
            if code in REFUSED:
                raise InterpError(REFUSED[code])
            g.append(code)
        if dropped and not any(c in (0, 10, 20, 30, 40, 100) or c in CYCLES or c == 760 for c in g):
            for k in "PQRE":            # the dropped code's own settings (G05.1 Q1, G08 P1, G187 P1 E0.01)
                letters.pop(k, None)
        motions = [c for c in g if c in (0, 10, 20, 30) or c in CYCLES or c == 800 or c == 760]
        if 800 in motions and len(motions) > 1:   # `G0 G80`: G80 cancels the cycle (another group in Fanuc)
            g.remove(800)
            motions.remove(800)
        cycle_motion = next((c for c in motions if c in CYCLES or c == 760), None)
        if cycle_motion is None and not motions and m.motion_mode in CYCLES:
            cycle_motion = m.motion_mode
        if 760 in g:            # Fanuc G76 fine boring: feed in, dwell, spindle orient, shift Q, rapid out
            g[g.index(760)] = 860
            cycle_motion = 860
            if "Q" in letters:
                letters.pop("Q")
            self._note("G76 fine boring read as G86 (feed in, dwell, rapid out): the Q shift at the bottom "
                       "is not simulated")
        for c in motions:
            if c in (0, 10, 20, 30):
                self.g01 = c // 10
        if 40 in g:             # dwell: X seconds, P milliseconds (a P with a decimal point: seconds)
            if "X" in letters:
                letters["P"] = letters.pop("X")
            elif "P" in letters and not points.get("P"):
                letters["P"] /= 1000.0
        if cycle_motion is not None and 40 not in g:
            if "K" in letters:
                k = letters.pop("K")
                if "L" in letters:
                    raise InterpError("both K and L repeats on a canned cycle block")
                letters["L"] = k
            if "P" in letters and not points.get("P"):
                letters["P"] /= 1000.0
            if letters.get("L") == 0:
                self._cycle_k0(line, g, letters, cycle_motion, passed_m)
                return
        if "D" in letters and not any(c in (410, 420) for c in g):
            letters.pop("D")
            self._note("D without G41/G42 (a new offset number under compensation) not read: the radius "
                       "given with G41/G42 stays")
        if "H" in letters and not any(c in (430,) for c in g):
            letters.pop("H")
            self._note("H without G43 not read")
        if "E" in letters:
            raise InterpError("E words are not read")
        if 541 in g or (540 in g and "P" in letters and cycle_motion is None and 40 not in g):
            self._select_extended(g, letters)
        if 680 in g or 690 in g:
            self._rotation(line, g, letters, passed_m)
            if not g and not letters and not passed_m:
                return
        if self.rotation is not None and any(c in g for c in (540, 550, 560, 570, 580, 590, 520, 920, 100)):
            raise InterpError("work offsets cannot change under G68 rotation (G69 first)")
        if self.extended is not None and any(c in g for c in (540, 550, 560, 570, 580, 590)):
            self._leave_extended()
        if 100 in g and letters.get("L") == 2:
            p = _integer(letters.get("P", 0.0), "G10 L2 P")
            if p == 0:
                raise InterpError("G10 L2 P0 (the external work offset) is not simulated")
            if not 1 <= p <= 6:
                raise InterpError(f"G10 L2 P{p}: P1-P6 (G54-G59)")
            if "R" in letters:
                raise InterpError("G10 L2 with R (rotation) is not a Fanuc offset")
            if (m.incremental and 900 not in g) or 910 in g:
                raise InterpError("G10 L2 in G91 (incremental offsets) is not read")
            self.written_systems.add(p)
        if 100 in g and letters.get("L") == 20:
            self._g10_l20(letters, (m.incremental and 900 not in g) or 910 in g)
            g.remove(100)
            letters.clear()
            if not g and not passed_m:
                self._record(line, m_codes)
                m.emit_none()
                return
        if 100 in g and letters.get("L", 2) not in (2, 20):
            raise InterpError(f"G10 L{letters['L']:g} (tool offset memory) is not read; G10 L2 and L20 are")
        if 280 in g or 300 in g or 530 in g:
            self._reference(line, g, letters, passed_m, m_codes)
            return
        self._execute(line, g, letters, passed_m, m_codes)

    def _execute(self, line, g, letters, passed_m, m_codes) -> None:
        words = [("g", c / 10.0) for c in g] + [("m", float(c)) for c in passed_m]
        words += [(k.lower(), v) for k, v in letters.items()]
        b = build(words, None)
        refuse(b)
        enhance(b, self.m.motion_mode, self.m.plane)
        self._record(line, m_codes)
        self._track_z(b)
        if b.motion in (20, 30) and "r" not in b.v and not self.m.comp.side:
            self._arc_radius_check(b)
        if self.m.execute(b):
            self.metadata.setdefault("end_line", self.seq)
            self._finish()

    def _arc_radius_check(self, b) -> None:
        """Fanuc's arc check (parameter 3410): the end radius may differ from the start radius by at most
        the tolerance, with no relative allowance (LinuxCNC also allows 0.1 %). The tolerance is the
        interpreter's (InterpOptions.arc_tolerance_mm / _inch; LinuxCNC's defaults, which accept
        4-decimal inch rounding)."""
        m = self.m
        u, w = {170: (0, 1), 180: (2, 0), 190: (1, 2)}[m.plane]
        if not m.incremental and b.g.get("nonmodal") == 530:
            return
        end = m._ends(b)
        offs = {0: b.v.get("i", 0.0), 1: b.v.get("j", 0.0), 2: b.v.get("k", 0.0)}
        cu, cw = m.pos[u] + offs[u], m.pos[w] + offs[w]
        r0 = math.hypot(m.pos[u] - cu, m.pos[w] - cw)
        r1 = math.hypot(end[u] - cu, end[w] - cw)
        tol = m.arc_tol_inch if m.inch else m.arc_tol_mm
        if abs(r1 - r0) > tol:
            unit = "in" if m.inch else "mm"
            raise InterpError(f"radius to end of arc differs from radius to start by {abs(r1 - r0):.5g} {unit} "
                              f"(r1={r0:.4f} r2={r1:.4f}; tolerance {tol:.4g} {unit}, settable: --arc-tolerance)")

    def _track_z(self, b) -> None:
        """... and the highest Z reached so far (Z words from variables are not in the text)."""
        if b.motion in (0, 10, 20, 30) and "z" in b.v:
            z = b.v["z"] + (self.m.pos[2] if self.m.incremental else 0.0)
            self.z_top = z if self.z_top is None else max(self.z_top, z)

    # -- Fanuc meanings ---------------------------------------------------------------------------
    def _cycle_k0(self, line, g, letters, motion, passed_m) -> None:
        """K0: the cycle's data are stored, nothing moves (Fanuc)."""
        m = self.m
        rest = [c for c in g if c not in CYCLES]
        keep = [(k.lower(), v) for k, v in letters.items() if k in "FST"]
        self._record(line, passed_m)
        if rest or passed_m or keep:
            b = build([("g", c / 10.0) for c in rest] + [("m", float(c)) for c in passed_m] + keep, None)
            enhance(b, -1, m.plane)
            m.execute(b)
        else:
            m.emit_none()
        if "R" in letters:
            m.cycle["r"] = letters["R"]
        axis = "XYZ"[{170: 2, 180: 1, 190: 0}[m.plane]]
        if axis in letters:
            m.cycle["cc"] = letters[axis]
        if "Q" in letters:
            m.cycle["q"] = letters["Q"]
        if "P" in letters:
            m.cycle["p"] = letters["P"]
        m.motion_mode = motion

    def _reference(self, line, g, letters, passed_m, m_codes) -> None:
        """G28 / G30 (via an intermediate point to the first / second reference position) and G53
        (machine coordinates, one block, at rapid; the modal motion code stays) when the machine's frame
        is not known: the intermediate move is made; Z goes up to the program's highest Z (the highest Z
        word of its text, as the line translation takes it, or the highest Z reached when that is
        higher: the retract both are written for); X, Y and rotary axes stay (noted). With a parameter
        file they go through the machine model (the machine's frame from the offsets, the reference
        positions from #5161-#5166 and #5181-#5186)."""
        m = self.m
        code = 280 if 280 in g else 300 if 300 in g else 530
        if code in (280, 300) and self.params.loaded:
            self._execute(line, g, letters, passed_m, m_codes)
            return
        if m.comp.side:
            raise InterpError(f"G{code // 10} with cutter radius compensation on")
        if code == 300 and "P" in letters and letters.pop("P") != 2:
            raise InterpError("G30 P3/P4 (third and fourth reference positions) are not read")
        rest = [c for c in g if c not in (280, 300, 530, 0, 10)]
        axes = {k: v for k, v in letters.items() if k in "XYZABC"}
        other = {k: v for k, v in letters.items() if k not in "XYZABC"}
        self._execute(line, rest, other, passed_m, m_codes)
        rows = self.canon.rows
        src = m.line_src
        if rows and rows[-1][0] == K_NONE and rows[-1][1] == src:
            rows.pop()
        if code in (280, 300) and axes:
            b = build([(k.lower(), v) for k, v in axes.items()], None)
            m.traverse(m._ends(b))
        if code == 530 and self.params.loaded:
            if axes:
                m.traverse(m._ends(build([("g", 53.0)] + [(k.lower(), v) for k, v in axes.items()], None)))
            else:
                m.emit_none()
            return
        if "Z" in axes:
            top = self.z_top if self.z_top is not None else m.pos[2]
            end = list(m.pos)
            end[2] = max(top, m.pos[2])
            m.traverse(end)
            self._note(f"G{code // 10} Z: the machine's reference / frame is not known (no parameter file): Z "
                       "retracts to the program's highest Z (its text's, or the highest reached), as a rapid")
        others = [a for a in axes if a != "Z"]
        if others:
            self._note(f"G{code // 10} {'/'.join(others)}: a place in the machine's frame the program does not "
                       "know: not moved")
        if len(rows) == 0 or rows[-1][1] != src:
            m.emit_none()

    def _select_extended(self, g: list, letters: dict) -> None:
        if "P" not in letters:
            raise InterpError("G54.1 without P (P1-P48)")
        p = _integer(letters.pop("P"), "G54.1 P")
        if not 1 <= p <= 48:
            raise InterpError(f"G54.1 P{p}: feedlog reads P1-P48")
        if self.rotation is not None:
            raise InterpError("work offsets cannot change under G68 rotation (G69 first)")
        if self.m.comp.side:
            raise InterpError("cannot change coordinate systems with cutter radius compensation on")
        for c in (541, 540):
            if c in g:
                g.remove(c)
        self._extended_offset(p)

    def _extended_offset(self, p: int) -> None:
        m = self.m
        base = 7001 + 20 * (p - 1)
        values = [self.V.extended.get(base + k) for k in range(6)]
        if all(v is None for v in values):
            self.unknown_extended.add(p)
        machine = m._machine_position()
        m.origin = [m._user_to_program(v or 0.0, k) for k, v in enumerate(values)]
        m.rotation = 0.0
        m.origin_index = 9 + p
        m.pos = m._relative(machine)
        self.extended = p

    def _leave_extended(self) -> None:
        m = self.m
        machine = m._machine_position()
        m.origin_index = 1
        m.origin = [m._user_to_program(self.params.p[5221 + k], k) for k in range(6)]
        m.rotation = self.params.p[5230]
        m.pos = m._relative(machine)
        self.extended = None          # the machine then selects the G5x code of the block

    def _g10_l20(self, letters: dict, incremental: bool) -> None:
        if "P" not in letters:
            raise InterpError("G10 L20 without P")
        p = _integer(letters["P"], "G10 L20 P")
        if not 1 <= p <= 48:
            raise InterpError(f"G10 L20 P{p}: feedlog reads P1-P48")
        f = MM_PER_INCH if self.m.inch else 1.0
        base = 7001 + 20 * (p - 1)
        for k, a in enumerate("XYZABC"):
            if a in letters:
                value = letters[a] * (f if k < 3 else 1.0)
                if incremental:             # G91: added to the offset in force (Fanuc)
                    value += self.V.extended.get(base + k) or 0.0
                self.V.extended[base + k] = value
        if self.extended == p:
            self._extended_offset(p)

    def _rotation(self, line, g: list, letters: dict, passed_m: list) -> None:
        """G68 X Y R: rotate the program about (X, Y) by R degrees (counter-clockwise, in G17); G69 off.
        Done with the machine's XY rotation of the coordinate system: the rows keep the program's
        coordinates and carry the rotation (`rot_deg`) and the shifted origin (`wx_mm`, `wy_mm`)."""
        m = self.m
        if 690 in g:
            g.remove(690)
            if self.rotation is not None:
                machine = m._machine_position()
                m.origin, m.rotation = list(self.rotation[0]), self.rotation[1]
                m.pos = m._relative(machine)
                self.rotation = None
            if 680 not in g:
                if not g and not letters and not passed_m:
                    self._record(line, [])
                    m.emit_none()
                return
        g.remove(680)
        if m.plane != 170 and 170 not in g:
            raise InterpError("G68 is read in the G17 plane only")
        if m.comp.side:
            raise InterpError("G68 with cutter radius compensation on")
        if self.rotation is not None:
            raise InterpError("G68 while G68 is already in force (G69 first)")
        cx = letters.pop("X", None)
        cy = letters.pop("Y", None)
        if cx is None or cy is None:
            here = m.pos
            cx = here[0] if cx is None else cx
            cy = here[1] if cy is None else cy
        angle = letters.pop("R", None)
        if angle is None:
            raise InterpError("G68 without R (the rotation angle)")
        for k in ("Z", "I", "J", "K"):
            letters.pop(k, None)
        machine = m._machine_position()
        saved = (list(m.origin), m.rotation)
        px, py = cx + m.g92[0], cy + m.g92[1]
        rx, ry = rotate(px, py, angle)
        m.origin[0] += px - rx
        m.origin[1] += py - ry
        m.rotation = m.rotation + angle
        m.pos = m._relative(machine)
        self.rotation = saved
        if not g and not letters and not passed_m:
            self._record(line, passed_m)
            m.emit_none()


def _is_g65(words: list) -> bool:
    return any(w[0] == "G" and abs(w[1] - 65.0) < 1e-6 for w in words)


def _arguments(words: list) -> dict[int, float]:
    """G65 arguments -> local variables, in the block's order. Specification I: A=#1 B=#2 C=#3 I=#4 ...
    Z=#26 (ARGUMENTS). Specification II: up to ten sets of I J K, the n-th set (n = 0..9) in
    #(4+3n), #(5+3n), #(6+3n); a set ends when a letter comes again or out of I, J, K order. The two may
    be mixed: an argument given later for the same variable wins (D of specification I is #7, as is I
    of the second set)."""
    args: dict[int, float] = {}
    pos = {"I": 0, "J": 1, "K": 2}
    group, last = 0, -1
    for letter, value, _ in words:
        if letter in ("G", "P", "L"):
            continue
        if letter in pos:
            if pos[letter] <= last:
                group += 1
                if group > 9:
                    raise InterpError("more than ten I J K argument sets on a G65 block")
            last = pos[letter]
            args[4 + 3 * group + pos[letter]] = value
            continue
        if letter not in ARGUMENTS:
            raise InterpError(f"{letter} is not a G65 argument address")
        args[ARGUMENTS[letter]] = value
    return args


def _integer(value: float, what: str) -> int:
    n = round(value)
    if abs(n - value) > 1e-4:
        raise InterpError(f"{what} must be an integer (got {value:g})")
    return int(n)


def interpret_fanuc(source: str | Path, *, name: str | None = None, options=None, base_dir: Path | None = None,
                    **kw) -> Program:
    """A Fanuc / Haas / Hurco macro B program through the front-end, as one block table (the columns of
    `interp.interpret`). `options`: an `InterpOptions` (search path for `O####` files, tool table,
    parameter file, arc tolerances, max_blocks)."""
    from feedlog.toolpath.interp.run import interpret
    program = interpret(source, name=name, options=options, base_dir=base_dir, engine=FanucInterpreter, **kw)
    program.metadata["interpreter"] = "feedlog.toolpath.interp.fanuc"
    return program


_FAST_LETTERS = frozenset("XYZABCF")
_MACRO = re.compile(r"#|\bIF\s*\[|\bGOTO|\bWHILE\s*\[|\bEND\s*[123]\b|\bDO\s*[123]\b|M\s*0*9[789](?!\d)|"
                    r"G\s*0*6[56](?![\d.])|G\s*0*54\s*\.\s*1|G\s*0*68(?![\d.])|"
                    # Haas codes the line translation does not read: look-ahead, smoothing, G154/G110-G129
                    r"G\s*0*(?:103|187|154|11\d|12\d)(?![\d.])|"
                    r"G\s*0*(?:7[346]|8[1-9])(?![\d.])", re.IGNORECASE)
_STRIP = re.compile(r"\([^)\n]*\)")


def needs_macro(text: str) -> bool:
    """Whether a Fanuc-style program uses what the line translation cannot read: variables, macro
    statements, subprogram and macro calls, canned cycles (Fanuc's K
    repeats and P in milliseconds), G54.1 (Haas: G154, G110-G129), G68 (a G69 alone, as in safety lines, is
    plain), Haas G103/G187."""
    return _MACRO.search(_STRIP.sub(" ", text)) is not None


_MACRO_ONLY = re.compile(r"\bIF\s*\[.*\]\s*(?:GOTO|THEN)|\bGOTO\s*[\d#\[]|\bWHILE\s*\[.*\]\s*DO\s*[123]|"
                         r"^\s*(?:N\d+\s*)?END\s*[123]\s*$|M\s*0*9[78]\s*P|G\s*0*6[56]\s*P|"
                         r"G\s*0*54\s*\.\s*1|G\s*0*68(?![\d.])",
                         re.IGNORECASE | re.MULTILINE)


_M98 = re.compile(r"M\s*0*9[78]\s*P", re.IGNORECASE)


def looks_macro_b(text: str, *, ngc: bool = False) -> bool:
    """Whether an undeclared program is Fanuc-style: macro B statements (`IF [..] GOTO`, `WHILE [..] DO 1`,
    `END 1`), `M98 P` / `G65 P` / `G66 P` calls, `G54.1`, `G68`. RS274/NGC has none of these (its O-words take a
    keyword: `o100 while`, `o<x> call`) but `M98 P`, which LinuxCNC reads in RS274/NGC too: in an `.ngc`
    file (`ngc`) an `M98 P` alone does not make a program Fanuc-style."""
    code = _STRIP.sub(" ", text)
    if not ngc:
        return _MACRO_ONLY.search(code) is not None
    return any(_M98.fullmatch(m.group(0)) is None for m in _MACRO_ONLY.finditer(code))


def use_front_end(text: str, dialect: str, detected: str, *, ngc: bool = False) -> bool:
    """Whether load_program reads `text` with the macro B front-end: a Fanuc / Hurco program (declared or
    detected) that uses what the line translation cannot read (`needs_macro`), or an undeclared program
    that is plainly macro B (`looks_macro_b`; `ngc`: the file is an `.ngc`)."""
    if dialect in ("fanuc", "hurco"):
        return needs_macro(text)
    if dialect != "auto":
        return False
    if detected == "fanuc":
        return needs_macro(text)
    return detected == "rs274ngc" and looks_macro_b(text, ngc=ngc)
