"""G-code dialects -> the RS274/NGC the parser reads, one output line per input line.

The parser reads RS274/NGC as LinuxCNC does. Programs from other controllers differ in a handful of
constructs; `translate(text, dialect)` rewrites those, line by line, and keeps every line where it was
(error messages, the line stream of a recording and align all count lines of the original file). What
was changed, and what could only be approximated, goes to `Translation.notes` (the program's warnings).

Fanuc / Hurco (`fanuc`; `hurco` is the same):
- `G80` (cancel canned cycle, as in `G0G80G90`) is dropped: feedlog runs no canned cycles.
- `G28` (return to the machine's reference point) and `G53` (machine coordinates for one block) go to
  places the program does not know (the machine's frame): Z goes to the program's highest Z (the
  retract both are used for) as a rapid, in the distance mode in force; X, Y and rotary axes stay.
  The line after one that needed `G0` gets its modal motion code back when it relies on it.
- `G4 X1.5` (seconds) and `G4 P1500` (milliseconds: a Fanuc P has no decimal point) become `G4 P1.5`;
  a P with a decimal point is seconds, as RS274/NGC reads it.
- `G05.1`/`G5.1`/`G08`/`G8` (look-ahead and smoothing modes) and `G15`/`G69` (cancel polar, rotation),
  `M19` (spindle orientation) are dropped: they do not move the programmed path (noted).
Sinumerik 840D (`sinumerik`; .mpf/.spf):
- `;` comments (the lexer reads them), `%_N_NAME_MPF` headers become comments.
- `G710`/`G71` -> `G21`, `G700`/`G70` -> `G20`; `G500` (no settable frame) -> `G54`; `G60` -> `G61`;
  `G641`..`G645` -> `G64` (the machine's rounding tolerance is not in the program: noted); `CR=` -> `R`,
  `TURN=n` -> `P(n+1)`; `X=10` -> `X10`; `MSG("...")` -> a comment; `M17` -> `M2`.
- Keywords that set dynamics or transformations (`SOFT`, `BRISK`, `FFWON`, `COMPCAD`, `CYCLE832(...)`,
  `TRAORI`, `G9`, `G601`, `ADIS=`, `D1`, `T="NAME"`, ...) are dropped and noted: the simulation models
  the machine's dynamics through its profile, not through these.
Anything else (parameters, `IF`/`GOTO`, `AC()`/`IC()`) is left as it is, for the parser to report
(or skip with --lenient).

`detect(text, name)` picks the dialect: `.mpf`/`.spf` or Sinumerik-only words -> sinumerik; Fanuc-only
constructs (`G28`, `G53`, `G0G80`, `G05.1 Q`, `G4 X`, Haas `G103`/`G187`/`G154`) -> fanuc; else rs274ngc, which leaves the text alone
(a LinuxCNC program with a lone `G80` or `G4 P0.5` is RS274/NGC and read unchanged). Sinumerik words count
only outside `( )` comments (Fusion 360 writes `(T1 D=6. CR=0. - ZMIN=...)` into every header; a
`MSG(`/`CYCLE832(` call and `%_N_`/`; $PATH` headers count anywhere); an `.ngc` file, or a program with
LinuxCNC-only words (`o<name>`, `#<name>`), is rs274ngc even where it uses `G28`/`G53`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

DIALECTS = ("auto", "rs274ngc", "fanuc", "hurco", "sinumerik")
AXES = "XYZABC"

_WORD = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
_COMMENT = re.compile(r"\([^()\n]*\)|;.*$")
_SEMICOLON = re.compile(r";.*$")
# Sinumerik calls and headers (anywhere: a call's brackets are no comment there) and words (outside `( )`)
_SINUMERIK_CALLS = re.compile(r"\bMSG\s*\(|\bCYCLE\d{3}\s*\(|%_N_|;\s*\$PATH", re.IGNORECASE)
_SINUMERIK_HINTS = re.compile(r"\bG7[01]0\b|\bTRAORI\b|\bG64[1-5]\b|\bCR\s*=|\bSOFT\b|\bBRISK\b|\bG500\b",
                              re.IGNORECASE)
_PAREN_COMMENT = re.compile(r"\([^()\n]*\)")
# LinuxCNC-only words: O-word subroutines, named parameters (a Hurco writes `G64 P` too)
_RS274_HINTS = re.compile(r"\bo\s*<|#\s*<", re.IGNORECASE)
# Fanuc-only constructs: G28/G53 (the parser reads neither), G05.1 Q (without Q: LinuxCNC's G5.1 spline), G4 X, and G80 beside a motion code
# (`G0G80`: two motion codes to RS274/NGC, a cycle cancel beside G0 to Fanuc). A lone G80 is RS274/NGC too.
_FANUC_HINTS = re.compile(r"G\s*0*28(?![.\d])|G\s*0*53(?![.\d])|G\s*0?5\.1[^\n;(]*Q|G\s*0?4\s*X|"
                          r"G\s*0*(?:103|187|154)(?![.\d])|"   # Haas look-ahead, smoothing, extended offsets
                          r"G\s*0*[0-3](?![.\d])[^\n;(]*G\s*80(?![.\d])|G\s*80(?![.\d])[^\n;(]*G\s*0*[0-3](?![.\d])",
                          re.IGNORECASE)


@dataclass
class Translation:
    text: str
    dialect: str
    notes: list[str] = field(default_factory=list)
    changed_lines: int = 0


class _Notes:
    """What was done, once per kind of change: the first line and how many lines."""

    def __init__(self) -> None:
        self.kinds: dict[str, list[int]] = {}

    def add(self, line: int, what: str) -> None:
        self.kinds.setdefault(what, []).append(line)

    def lines(self, dialect: str) -> list[str]:
        out = []
        for what, where in self.kinds.items():
            more = f" (and {len(where) - 1} more lines)" if len(where) > 1 else ""
            out.append(f"{dialect} dialect: line {where[0]}{more}: {what}")
        return out


def detect(text: str, name: str | Path | None = None) -> str:
    """The dialect of a program (see the module docstring)."""
    suffix = Path(str(name)).suffix.lower() if name else ""
    if suffix in (".mpf", ".spf") or _SINUMERIK_CALLS.search(text):
        return "sinumerik"
    uncommented = _PAREN_COMMENT.sub(" ", text) if "(" in text else text
    if _SINUMERIK_HINTS.search(uncommented):
        return "sinumerik"
    code = _COMMENT.sub("", text) if "(" in text or ";" in text else text
    if suffix == ".ngc" or _RS274_HINTS.search(code):
        return "rs274ngc"
    if _FANUC_HINTS.search(code):
        return "fanuc"
    return "rs274ngc"


def translate(text: str, dialect: str = "auto", *, name: str | Path | None = None) -> Translation:
    """`text` in RS274/NGC with the same number of lines (see the module docstring)."""
    if dialect not in DIALECTS:
        raise ValueError(f"unknown dialect {dialect!r}; known: {', '.join(DIALECTS)}")
    chosen = detect(text, name) if dialect == "auto" else ("fanuc" if dialect == "hurco" else dialect)
    if chosen == "rs274ngc":
        return Translation(text, chosen)
    lines = text.split("\n")
    notes = _Notes()
    out = _sinumerik(lines, notes) if chosen == "sinumerik" else lines
    out = _fanuc(out, notes, ms_dwell=chosen == "fanuc")
    changed = sum(a != b for a, b in zip(lines, out))
    return Translation("\n".join(out), chosen, notes.lines(chosen), changed)


def _split(line: str, *, parens: bool = True) -> list[tuple[bool, str]]:
    """A line as (is_code, text) pieces: comments `( ... )` (unless `parens` is False: Sinumerik calls
    take arguments in parentheses) and `; ...` are not code."""
    pieces, pos = [], 0
    for m in (_COMMENT if parens else _SEMICOLON).finditer(line):
        if m.start() > pos:
            pieces.append((True, line[pos:m.start()]))
        pieces.append((False, m.group(0)))
        pos = m.end()
    if pos < len(line):
        pieces.append((True, line[pos:]))
    return pieces


def _code_of(line: str) -> str:
    return "".join(t for is_code, t in _split(line) if is_code)


def _words(code: str) -> list[tuple[str, float, int, int]]:
    """(letter, value, start, end) of each word of a code piece (upper case)."""
    return [(m.group(1), float(m.group(2)), m.start(), m.end()) for m in _WORD.finditer(code.upper())]


def _word_text(words, i: int, pieces) -> str:
    """The source text of word i of a line's code (to tell `P500` from `P0.5`)."""
    code = "".join(t for c, t in pieces if c)
    return code.upper()[words[i][2]:words[i][3]]


def _fmt(value: float) -> str:
    text = f"{value:.6f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


# ---- Fanuc / Hurco --------------------------------------------------------------------------------

_DROP_G = {80.0: "G80 (cancel canned cycle) dropped: feedlog runs no canned cycles",
           5.1: "G05.1 (look-ahead / smoothing mode) dropped: the profile models the look-ahead",
           8.0: "G08 (look-ahead mode) dropped: the profile models the look-ahead",
           15.0: "G15 (cancel polar coordinates) dropped", 69.0: "G69 (cancel coordinate rotation) dropped"}
_DROP_M = {19.0: "M19 (spindle orientation) dropped: no path motion"}


def _fanuc(lines: list[str], notes: _Notes, *, ms_dwell: bool) -> list[str]:
    z_top = _highest_z(lines)
    out: list[str] = []
    motion: float | None = None         # the program's modal motion code (0, 1, 2, 3)
    parser_motion: float | None = None  # what the parser will hold after the rewritten lines
    incremental = False
    pos = {a: 0.0 for a in AXES}
    for number, line in enumerate(lines, start=1):
        pieces = _split(line)
        words = _words("".join(t for c, t in pieces if c))
        if not words:
            out.append(line)
            continue
        g = [v for letter, v, _, _ in words if letter == "G"]
        special = next((v for v in g if v in (28.0, 53.0)), None)
        drop: list[int] = []   # indices of words removed
        extra = ""
        for i, (letter, value, _, _) in enumerate(words):
            if letter == "G" and value in _DROP_G:
                drop.append(i)
                notes.add(number, _DROP_G[value])
            elif letter == "M" and value in _DROP_M:
                drop.append(i)
                notes.add(number, _DROP_M[value])
        if 90.0 in g:
            incremental = False
        if 91.0 in g:
            incremental = True
        dwell = 4.0 in g
        if dwell:  # X seconds, or P milliseconds (Fanuc)
            for i, (letter, value, _, _) in enumerate(words):
                if letter == "X":
                    drop.append(i)
                    extra += f" P{_fmt(value)}"
                    notes.add(number, "G4 X (dwell in seconds) -> G4 P")
                elif letter == "P" and ms_dwell and "." not in _word_text(words, i, pieces):
                    drop.append(i)
                    extra += f" P{_fmt(value / 1000.0)}"
                    notes.add(number, "G4 P in milliseconds (Fanuc) -> G4 P in seconds")
        motion_here = next((v for v in g if v in (0.0, 1.0, 2.0, 3.0)), None)
        axes_here = {letter: value for letter, value, _, _ in words if letter in AXES}
        if special is not None:
            drop += [i for i, (letter, value, _, _) in enumerate(words)
                     if letter in AXES or (letter == "G" and value in (28.0, 53.0, 0.0, 1.0))]
            kind = "G28 (reference point)" if special == 28.0 else "G53 (machine coordinates)"
            if "Z" in axes_here and z_top is not None:
                extra += f" G0 Z{_fmt(z_top - pos['Z'] if incremental else z_top)}"
                notes.add(number, f"{kind}: Z retracts to the program's highest Z ({_fmt(z_top)}) as a rapid; the "
                                  "machine's own reference point is not in the program")
                pos["Z"] = z_top
                parser_motion = 0.0
            others = [a for a in axes_here if a != "Z"]
            if others:
                notes.add(number, f"{kind}: {'/'.join(others)} not moved (a place in the machine's frame the "
                                  "program does not know)")
            motion = motion_here if motion_here is not None else motion
        else:
            if (motion_here is None and axes_here and not dwell and motion is not None
                    and parser_motion != motion and not set(g) & {10.0, 92.0}):
                extra = f"G{_fmt(motion)} " + extra
                notes.add(number, "modal motion code restated after a G28/G53 line that needed G0")
            if motion_here is not None:
                motion = motion_here
            parser_motion = motion
            if not dwell and not set(g) & {10.0, 92.0}:
                for a, v in axes_here.items():
                    pos[a] = pos[a] + v if incremental else v
        if not drop and not extra:
            out.append(line)
            continue
        out.append(_rewrite(pieces, words, drop, extra))
    return out


def _rewrite(pieces: list[tuple[bool, str]], words, drop: list[int], extra: str) -> str:
    """The line with the `drop` words removed from its code and `extra` appended to it (comments kept)."""
    code = "".join(t for c, t in pieces if c)
    upper = code.upper()
    keep, last = [], 0
    for i in sorted(set(drop)):
        _, _, start, end = words[i]
        keep.append(upper[last:start])
        last = end
    keep.append(upper[last:])
    new_code = re.sub(r"\s+", " ", "".join(keep)).strip()
    if extra.strip():
        new_code = (new_code + " " + extra.strip()).strip()
    comments = " ".join(t for c, t in pieces if not c)
    return (new_code + (" " + comments if comments else "")).strip()


def _highest_z(lines: list[str]) -> float | None:
    """The highest Z the program's own moves reach (G28/G53 lines left out), in program units."""
    incremental, z, top = False, 0.0, None
    for line in lines:
        words = _words(_code_of(line))
        g = [v for letter, v, _, _ in words if letter == "G"]
        incremental = (incremental or 91.0 in g) and 90.0 not in g if (90.0 in g or 91.0 in g) else incremental
        if 28.0 in g or 53.0 in g or 4.0 in g or 10.0 in g or 92.0 in g:
            continue
        for letter, value, _, _ in words:
            if letter == "Z":
                z = z + value if incremental else value
                top = z if top is None else max(top, z)
    return top


# ---- Sinumerik -------------------------------------------------------------------------------------

_SIN_G = {"G710": "G21", "G71": "G21", "G700": "G20", "G70": "G20", "G500": "G54", "G60": "G61",
          "G641": "G64", "G642": "G64", "G643": "G64", "G644": "G64", "G645": "G64"}
_SIN_G_NOTES = {"G500": "G500 (no settable frame) -> G54 (the program's work offset, zero unless set)",
                "G641": "G641..G645 (smoothing) -> G64: the machine's rounding tolerance (machine data) is not "
                        "in the program", "G60": "G60 (exact stop) -> G61"}
_SIN_DROP = re.compile(r"\b(SOFT|BRISK|DRIVE|FFWON|FFWOF|COMPCAD|COMPCURV|COMPSURF|COMPOF|TRAORI|TRAFOOF|ORIWKS|"
                       r"ORIMKS|ORIAXES|ORIVECT|UPATH|SPATH|STOPRE|CFC|CFTCP|CFIN|FNORM|FLIN|FCUB|G9|G601|G602|"
                       r"G603|G450|G451|G40|G17|WAITM\([^)]*\)|CYCLE\d{3}\([^)]*\)|WORKPIECE\([^)]*\)|"
                       r"ADIS\s*=\s*[-+\d.]+|ADISPOS\s*=\s*[-+\d.]+|D\d+|T\s*=\s*\"[^\"]*\")(?![\w=(])",
                       re.IGNORECASE)
_SIN_KEEP = {"G40", "G17"}   # RS274/NGC reads these alike: kept, not dropped


def _sinumerik(lines: list[str], notes: _Notes) -> list[str]:
    out = []
    for number, line in enumerate(lines, start=1):
        stripped = line.strip()
        if stripped.startswith("%") and stripped != "%":
            out.append(f"({stripped.lstrip('%').replace('(', '[').replace(')', ']')})")
            notes.add(number, "program header -> comment")
            continue
        new_pieces = []
        trailing = []
        for is_code, text in _split(line, parens=False):
            if not is_code:
                new_pieces.append(text)
                continue
            msg = re.search(r"MSG\s*\(\s*\"([^\"]*)\"\s*\)", text, re.IGNORECASE)
            if msg:
                trailing.append(f"; MSG {msg.group(1)}")
                text = text[:msg.start()] + text[msg.end():]
                notes.add(number, "MSG(...) -> comment")
            text = _sinumerik_code(text, number, notes)
            new_pieces.append(text)
        new = " ".join(p.strip() for p in new_pieces if p.strip())
        if trailing:
            new = (new + " " + " ".join(trailing)).strip()
        out.append(new if new != line.strip() else line)
    return out


def _sinumerik_code(code: str, number: int, notes: _Notes) -> str:
    def drop(m: re.Match) -> str:
        word = m.group(1).upper()
        if word in _SIN_KEEP:
            return m.group(0)
        notes.add(number, f"{re.sub(r'[(=].*', '', word)} dropped: not modelled (the profile sets the dynamics)")
        return " "

    code = _SIN_DROP.sub(drop, code)
    code = re.sub(r"\bCR\s*=\s*", "R", code, flags=re.IGNORECASE)
    turn = re.search(r"\bTURN\s*=\s*(\d+)", code, re.IGNORECASE)
    if turn:
        code = code[:turn.start()] + f"P{int(turn.group(1)) + 1}" + code[turn.end():]
        notes.add(number, "TURN=n -> P(n+1)")
    code = re.sub(r"\b([XYZABCIJKF])\s*=\s*(?=[-+\d.])", r"\1", code, flags=re.IGNORECASE)

    def gcode(m: re.Match) -> str:
        word = m.group(0).upper()
        new = _SIN_G.get(word)
        if new is None:
            return m.group(0)
        key = "G641" if word.startswith("G64") else word
        notes.add(number, _SIN_G_NOTES.get(key, f"{word} -> {new}"))
        return new

    code = re.sub(r"\bG\d{2,3}\b", gcode, code, flags=re.IGNORECASE)
    code = re.sub(r"\bM17\b", "M2", code, flags=re.IGNORECASE)
    seen: set[str] = set()

    def once(m: re.Match) -> str:  # `G500 G54` -> `G54 G54`: one is enough
        word = m.group(0).upper()
        if word in seen:
            return ""
        seen.add(word)
        return m.group(0)

    return re.sub(r"\bG\d+(?:\.\d)?\b", once, code, flags=re.IGNORECASE)
