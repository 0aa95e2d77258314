"""One RS274/NGC line -> a `Line`: its words, parameter settings, O-word and comments, values compiled.

The line is prepared as LinuxCNC prepares it (blanks outside comments dropped, letters lower-cased,
`( )` and `;` comments kept apart), then read item by item: an optional `/` and `N` number, then either
an O-word (`o<name> sub`, `o100 while [...]`, `o<x> call [1] [2]`, ...; nothing but comments may follow)
or words (`g1`, `x[#1*2]`, `@5`, `^90`), parameter settings (`#1=...`, `#<name>=...`) and comments.
Values are compiled by toolpath.interp.expr; a line is parsed once and its compiled form reused every
time it runs (loops, subroutines).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from feedlog.toolpath.interp.errors import InterpError
from feedlog.toolpath.interp.expr import Reader, compile_value

WORD_LETTERS = frozenset("abcdefghijklmpqrstuvwxyz@^$")
O_KEYWORDS = ("sub", "endsub", "call", "do", "while", "repeat", "if", "elseif", "else", "endif", "break",
              "continue", "endwhile", "endrepeat", "return")
MAX_LINE = 256 * 64  # characters on one line (LinuxCNC: 256; CAM comments run longer)


@dataclass(slots=True)
class OWord:
    """An O-word statement: `name` (label, lower case; digits for numbered ones), `kind` (sub, call,
    while, ..., "" for a bare Fanuc-style `O1234`, m98 / m99 for Fanuc-style calls and returns), `args`
    (call arguments; for m98 its P and L), `test` (if/elseif/while/repeat condition, return value)."""

    name: str
    kind: str
    args: list = field(default_factory=list)
    test: object = None
    scoped: dict = field(default_factory=dict)   # enclosing subroutine -> label name (LinuxCNC's "sub#label")


@dataclass(slots=True)
class Line:
    """A parsed line. `words`: (letter, value) in line order, value a float or a compiled function;
    `assigns`: (target, value) with target an int/function (numbered) or a str (named); `comment`: all
    comments joined; `last_comment`: the last one (LinuxCNC acts on the last: MSG, DEBUG, ...)."""

    number: int
    raw: str
    delete: bool = False
    n: float | None = None
    oword: OWord | None = None
    words: list = field(default_factory=list)
    assigns: list = field(default_factory=list)
    comment: str = ""
    last_comment: str = ""
    static: bool = True          # no parameter or function to evaluate: values are floats
    block: object = None         # the evaluated Block of a static line (built once)
    sources: dict = field(default_factory=dict)   # (call stack, M codes) -> canon source index
    simple: tuple | None = None  # (G code x10 or -1, [(letter, value)]) of a plain G0/G1 line (fast lane)

    @property
    def empty(self) -> bool:
        return self.oword is None and not self.words and not self.assigns


def prepare(raw: str) -> tuple[str, list[str]]:
    """(code, comments): `code` lower case without blanks, comments as `(text)` / `;text` kept in place
    as markers \x00k\x00 (k: index into comments)."""
    out: list[str] = []
    comments: list[str] = []
    i, n = 0, len(raw)
    while i < n:
        ch = raw[i]
        if ch == ";":
            comments.append(raw[i + 1:].strip())
            out.append(f"\x00{len(comments) - 1}\x00")
            break
        if ch == "(":
            end = raw.find(")", i + 1)
            if end < 0:
                raise InterpError("unclosed comment found")
            body = raw[i + 1:end]
            if "(" in body:
                raise InterpError("nested comment found")
            comments.append(body.strip())
            out.append(f"\x00{len(comments) - 1}\x00")
            i = end + 1
            continue
        if ch in " \t\r\n":
            i += 1
            continue
        out.append(ch.lower())
        i += 1
    return "".join(out), comments


def parse_line(raw: str, number: int) -> Line:
    """Parse one line (1-based `number`); raises InterpError with a message (the caller adds the place)."""
    if len(raw) > MAX_LINE:
        raise InterpError(f"line longer than {MAX_LINE} characters")
    if "\x00" in raw:
        raise InterpError("bad character '\\000' used")
    code, comments = prepare(raw)
    line = Line(number=number, raw=raw.strip())
    if comments:
        line.comment = " ".join(c for c in comments if c)
        line.last_comment = comments[-1]
    r = Reader(code)
    if r.peek() == "/":
        line.delete = True
        r.pos += 1
    if r.peek() == "n":
        r.pos += 1
        start = r.pos
        while r.peek().isdigit():
            r.pos += 1
        if r.pos == start:
            raise InterpError("bad format unsigned integer after N")
        if r.pos - start > 9:   # beyond +-1e9, as the vectorised parser bounds every number
            raise InterpError(f"N number out of range (beyond 1e9): N{code[start:start + 12]}...")
        value = float(code[start:r.pos])
        if r.peek() == ".":
            r.pos += 1
            while r.peek().isdigit():
                r.pos += 1
        line.n = value
    if r.peek() == "o":
        line.oword = _read_oword(r)
        _only_comments(r)
        line.static = False
        return line
    fanuc = _FANUC_SUB.match(code, r.pos)
    if fanuc is not None:     # LinuxCNC reads M98 / M99 at the start of a line as O-words (Fanuc-style subs)
        if fanuc.group(1) == "98":
            line.oword = _read_m98(r, code, fanuc.end())
            line.static = False
            return line
        if _COMMENTS_ONLY.fullmatch(code, fanuc.end()):
            line.oword = OWord(name="", kind="m99")
            line.static = False
            return line
    _read_items(r, code, line)
    line.simple = _simple(line)
    return line


def _simple(line: Line) -> tuple | None:
    """A line of only G0/G1, axis words X-C and F (what loops of moves are made of) runs in the fast lane."""
    if line.assigns or line.oword is not None or not line.words:
        return None
    motion = -1
    rest = []
    for letter, value in line.words:
        if letter == "g":
            if callable(value) or value not in (0.0, 1.0) or motion != -1:
                return None
            motion = int(value) * 10
        elif letter in "xyzabcf":
            if any(letter == seen for seen, _ in rest):
                return None
            rest.append((letter, value))
        else:
            return None
    if not any(letter != "f" for letter, _ in rest):
        return None
    return motion, rest


def _read_items(r: Reader, code: str, line: Line) -> None:
    while r.pos < len(code):
        c = r.peek()
        if c == "\x00":
            r.pos = code.index("\x00", r.pos + 1) + 1
            continue
        if c == "#":
            r.pos += 1
            if r.peek() == "<":
                target = r.name()
            else:
                target = compile_value(r.value())
            if r.peek() != "=":
                raise InterpError("equal sign missing in parameter setting")
            r.pos += 1
            line.assigns.append((target, compile_value(r.value())))
            line.static = False
            continue
        if c not in WORD_LETTERS:
            shown = c if c.isprintable() and not c.isspace() else f"\\{ord(c):03o}"
            raise InterpError(f"bad character '{shown}' used")
        r.pos += 1
        value = compile_value(r.value())
        if callable(value):
            line.static = False
        line.words.append((c, value))


_FANUC_SUB = re.compile(r"m0*(98|99)(?![0-9.])")
_COMMENTS_ONLY = re.compile("(?:\x00[0-9]+\x00)*")


def _read_m98(r: Reader, code: str, start: int) -> OWord:
    """`M98 P<program> [L<repeats>]`: the call's P and L (compiled); other words on the line are read
    and, as in LinuxCNC, not used."""
    r.pos = start
    words = Line(number=0, raw="")
    _read_items(r, code, words)
    given = dict(words.words)
    if "p" not in given:
        raise InterpError("found 'M98' code with no P word")
    return OWord(name="", kind="m98", args=[given["p"], given.get("l")])


def _only_comments(r: Reader) -> None:
    while r.pos < len(r.text):
        if r.peek() != "\x00":
            raise InterpError("unexpected character after O-word")
        r.pos = r.text.index("\x00", r.pos + 1) + 1


def _skip_comments(r: Reader) -> None:
    while r.peek() == "\x00":
        r.pos = r.text.index("\x00", r.pos + 1) + 1


def _read_oword(r: Reader) -> OWord:
    r.pos += 1  # 'o'
    if r.peek() == "<":
        name = r.name()
    else:
        value = compile_value(r.value())
        if callable(value):
            raise InterpError("an O-word number must be a constant here")
        from feedlog.toolpath.interp.expr import as_int
        name = str(as_int(value, "O-word number"))
    rest = r.text[r.pos:]
    kind = next((k for k in sorted(O_KEYWORDS, key=len, reverse=True) if rest.startswith(k)), None)
    if kind is None:
        if not rest or rest[0] == "\x00":
            return OWord(name=name, kind="")  # Fanuc-style program number / subprogram definition
        raise InterpError("unknown command in O line")
    r.pos += len(kind)
    ow = OWord(name=name, kind=kind)
    if kind == "call":
        while True:
            _skip_comments(r)
            if r.peek() != "[":
                break
            if len(ow.args) >= 30:
                raise InterpError("too many subroutine parameters (at most 30)")
            ow.args.append(compile_value(r.expression()))
    elif kind in ("while", "repeat", "if", "elseif"):
        if r.peek() != "[":
            raise InterpError(f"left bracket missing after '{kind}'")
        ow.test = compile_value(r.expression())
    elif kind in ("endsub", "return") and r.peek() == "[":
        ow.test = compile_value(r.expression())
    return ow
