"""One Fanuc / Haas / Hurco (custom macro B) line -> a `FLine`: its statement and its words, values compiled.

A line is read as the controllers read a block: blanks are ignored outside comments, letters are
case-insensitive, `( ... )` is a comment and `;` ends the block (the manuals print it as the end of
block). After an optional `/` and `N` sequence number (an `O`/`:` number starts a program), a block is
one of:

- a macro statement: `IF [cond] GOTO n`, `IF [cond] THEN #i = expr`, `GOTO n`, `WHILE [cond] DO m` (or `WH`),
  `DO m`, `END m`, or one or more assignments `#i = expr`;
- NC words: a letter and a value, the value a number, `#i`, `-#i`, `#[expr]` or `[expr]`.

Expressions have the macro B operators with its four precedence levels (functions; `* / AND MOD`;
`+ - OR XOR`; `EQ NE GT GE LT LE`), left to right, and its functions (`SIN COS TAN ASIN ACOS ATAN
SQRT ABS ROUND FIX FUP LN EXP POW BIN BCD`; degrees; `ATAN[a]/[b]` and `ATAN[a,b]`). Values may be
vacant (`#0`, a variable never set): a vacant value is `None` in the compiled code. Arithmetic takes a
vacant operand as 0; `EQ`/`NE` tell vacant from 0 (`#1 EQ #0` is true only when #1 is vacant), the
other comparisons take it as 0; a word whose value is vacant is as if it were not written.

Each value compiles to a Python function of the variable store `V` (`V.get(i)`), run each time the
line executes.
"""

from __future__ import annotations

import math
import operator
from dataclasses import dataclass, field

from feedlog.toolpath.interp.errors import InterpError
from feedlog.toolpath.interp.expr import div, finite

MAX_LINE = 256 * 64


def _digit(c: str) -> bool:
    return len(c) == 1 and "0" <= c <= "9"


def _z(x):
    return 0.0 if x is None else x


def _veq(a, b) -> float:
    if a is None or b is None:
        return 1.0 if a is None and b is None else 0.0
    return 1.0 if abs(a - b) < 1e-9 * max(1.0, abs(a), abs(b)) else 0.0


def _int_bits(x: float, what: str) -> int:
    n = round(x)
    if abs(n - x) > 1e-6:
        raise InterpError(f"{what} needs integer operands (got {x:g})")
    return int(n)


def _and(a, b):
    return float(_int_bits(_z(a), "AND") & _int_bits(_z(b), "AND"))


def _or(a, b):
    return float(_int_bits(_z(a), "OR") | _int_bits(_z(b), "OR"))


def _xor(a, b):
    return float(_int_bits(_z(a), "XOR") ^ _int_bits(_z(b), "XOR"))


def _mod(a, b):
    a, b = _z(a), _z(b)
    if b == 0.0:
        raise InterpError("attempt to divide by zero (MOD)")
    return math.fmod(a, b)


def _pow(a, b):
    a, b = _z(a), _z(b)
    if a < 0.0 and b != math.floor(b):
        raise InterpError("POW of a negative number to a non-integer power")
    if a == 0.0 and b < 0.0:
        raise InterpError("attempt to divide by zero (POW)")
    try:
        return math.pow(a, b)
    except OverflowError:
        raise InterpError("calculation resulted in 'infinity'") from None


def _sqrt(x):
    x = _z(x)
    if x < 0.0:
        raise InterpError("SQRT of a negative number")
    return math.sqrt(x)


def _ln(x):
    x = _z(x)
    if x <= 0.0:
        raise InterpError("LN of zero or a negative number")
    return math.log(x)


def _exp(x):
    try:
        return math.exp(_z(x))
    except OverflowError:
        raise InterpError("calculation resulted in 'infinity'") from None


def _asin(x):
    x = _z(x)
    if not -1.0 <= x <= 1.0:
        raise InterpError("ASIN argument out of range (-1 to 1)")
    d = math.degrees(math.asin(x))
    return d + 360.0 if d < 0.0 else d          # Fanuc's default range 270..90 (parameter NAT = 0)


def _acos(x):
    x = _z(x)
    if not -1.0 <= x <= 1.0:
        raise InterpError("ACOS argument out of range (-1 to 1)")
    return math.degrees(math.acos(x))


def _atan2(y, x):
    y, x = _z(y), _z(x)
    if y == 0.0 and x == 0.0:
        raise InterpError("ATAN[0]/[0] is undefined")
    d = math.degrees(math.atan2(y, x))
    return d + 360.0 if d < 0.0 else d           # Fanuc's default range 0..360 (parameter NAT = 0)


def _atan1(x):
    d = math.degrees(math.atan(_z(x)))
    return d + 360.0 if d < 0.0 else d


def _round(x):
    x = _z(x)
    return float(math.floor(abs(x) + 0.5)) * (1.0 if x >= 0 else -1.0)


def _fix(x):                                       # fractions discarded (toward zero)
    x = _z(x)
    return float(math.trunc(x))


def _fup(x):                                       # fractions raised (away from zero)
    x = _z(x)
    t = math.trunc(x)
    return float(t) if t == x else float(t + (1 if x > 0 else -1))


def _tan(x):
    x = _z(x)
    if abs(math.fmod(abs(x), 180.0) - 90.0) < 1e-12:
        raise InterpError(f"TAN[{x:g}] is infinite")
    return math.tan(math.radians(x))


def _bin(x):                                       # BCD -> binary
    n = _int_bits(_z(x), "BIN")
    out, scale = 0, 1
    while n:
        out += (n & 15) * scale
        n >>= 4
        scale *= 10
    return float(out)


def _bcd(x):                                       # binary -> BCD
    n = _int_bits(_z(x), "BCD")
    out, shift = 0, 0
    for ch in reversed(str(abs(n))):
        out |= int(ch) << shift
        shift += 4
    return float(out)


def _compare(op):
    """GT GE LT LE: a vacant operand counts as 0."""
    return lambda a, b: 1.0 if op(_z(a), _z(b)) else 0.0


def _div(a, b):
    return div(_z(a), _z(b))


NAMESPACE = {"_z": _z, "_f": finite, "_div": _div, "_mod": _mod, "_pow": _pow, "_and": _and, "_or": _or,
             "_xor": _xor, "_eq": _veq, "_ne": lambda a, b: 1.0 - _veq(a, b),
             "_lt": _compare(operator.lt), "_le": _compare(operator.le), "_gt": _compare(operator.gt),
             "_ge": _compare(operator.ge), "_atan2": _atan2,
             "_SIN": lambda x: math.sin(math.radians(_z(x))), "_COS": lambda x: math.cos(math.radians(_z(x))),
             "_TAN": _tan, "_ASIN": _asin, "_ACOS": _acos, "_ATAN": _atan1, "_SQRT": _sqrt, "_SQR": _sqrt,
             "_ABS": lambda x: abs(_z(x)), "_ROUND": _round, "_RND": _round, "_FIX": _fix, "_FUP": _fup,
             "_LN": _ln, "_EXP": _exp, "_BIN": _bin, "_BCD": _bcd}
FUNCTIONS = ("ROUND", "ATAN", "ASIN", "ACOS", "SQRT", "SIN", "COS", "TAN", "ABS", "FIX", "FUP", "EXP", "POW",
             "BIN", "BCD", "SQR", "RND", "ATN", "LN")
_LEVEL = {"*": 3, "/": 3, "AND": 3, "MOD": 3, "+": 2, "-": 2, "OR": 2, "XOR": 2,
          "EQ": 1, "NE": 1, "GT": 1, "GE": 1, "LT": 1, "LE": 1}
_CODE = {"*": "(_z({}) * _z({}))", "/": "_div({}, {})", "AND": "_and({}, {})", "MOD": "_mod({}, {})",
         "+": "(_z({}) + _z({}))", "-": "(_z({}) - _z({}))", "OR": "_or({}, {})", "XOR": "_xor({}, {})",
         "EQ": "_eq({}, {})", "NE": "_ne({}, {})", "GT": "_gt({}, {})", "GE": "_ge({}, {})",
         "LT": "_lt({}, {})", "LE": "_le({}, {})"}
_OPERATORS = ("AND", "MOD", "XOR", "OR", "EQ", "NE", "GT", "GE", "LT", "LE", "*", "/", "+", "-")
NC_LETTERS = frozenset("ABCDEFGHIJKLMPQRSTUVWXYZ")


class Text:
    """A prepared block (upper case, no blanks) read from `pos`."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.pos = 0

    def peek(self, k: int = 0) -> str:
        i = self.pos + k
        return self.text[i] if i < len(self.text) else ""

    def at(self, word: str) -> bool:
        return self.text.startswith(word, self.pos)

    def expect(self, ch: str, what: str) -> None:
        if self.peek() != ch:
            raise InterpError(f"'{ch}' expected {what}")
        self.pos += 1

    # -- values -------------------------------------------------------------------------------------
    def number(self) -> float:
        start = self.pos
        if self.peek() in "+-":
            self.pos += 1
        digits = 0
        while _digit(self.peek()) or self.peek() == ".":
            self.pos += 1
            digits += 1
        token = self.text[start:self.pos]
        if not any(_digit(ch) for ch in token) or token.count(".") > 1:
            raise InterpError(f"bad number {self.text[start:start + 10] or '(nothing)'!r}")
        try:
            return float(token)
        except ValueError:
            raise InterpError(f"bad number {token!r}") from None

    def variable(self) -> str:
        """`#` at pos: `#12`, `#[expr]`, `##1` -> code of its value (may be vacant)."""
        self.pos += 1
        c = self.peek()
        if c == "[":
            return f"V.get({self.bracket()})"
        if c == "#":
            return f"V.get({self.variable()})"
        if _digit(c) or c == ".":
            return f"V.get({self.number()!r})"
        raise InterpError("variable number expected after '#'")

    def bracket(self) -> str:
        self.expect("[", "")
        code = self.expression()
        self.expect("]", "to close '['")
        return code

    def operand(self) -> str:
        c = self.peek()
        if c == "[":
            return self.bracket()
        if c == "#":
            return self.variable()
        if c == "-":
            self.pos += 1
            return f"(-_z({self.operand()}))"
        if c == "+":
            self.pos += 1
            return self.operand()
        if _digit(c) or c == ".":
            return repr(self.number())
        if c.isalpha():
            return self.function()
        raise InterpError("value expected" + (f" at {self.text[self.pos:self.pos + 8]!r}" if c else " (line ends)"))

    def function(self) -> str:
        name = next((f for f in FUNCTIONS if self.at(f)), None)
        if name is None:
            raise InterpError(f"unknown function or word in expression: {self.text[self.pos:self.pos + 8]!r}")
        self.pos += len(name)
        if self.peek() != "[":
            raise InterpError(f"'[' missing after {name}")
        self.pos += 1
        first = self.expression()
        second = None
        if self.peek() == ",":
            self.pos += 1
            second = self.expression()
        self.expect("]", f"to close {name}[")
        if name in ("ATAN", "ATN"):
            if second is None and self.peek() == "/":
                self.pos += 1
                if self.peek() != "[":
                    raise InterpError("'[' missing after ATAN[a]/")
                second = self.bracket()
            return f"_f(_atan2({first}, {second}))" if second is not None else f"_f(_ATAN({first}))"
        if name == "POW":
            if second is None:
                raise InterpError("POW takes two arguments: POW[a,b]")
            return f"_f(_pow({first}, {second}))"
        if second is not None:
            raise InterpError(f"{name} takes one argument")
        return f"_f(_{name}({first}))"

    def expression(self) -> str:
        operands = [self.operand()]
        ops: list[str] = []
        while True:
            op = next((o for o in _OPERATORS if self.at(o)), None)
            if op is None:
                break
            self.pos += len(op)
            while ops and _LEVEL[ops[-1]] >= _LEVEL[op]:
                right = operands.pop()
                operands[-1] = _CODE[ops.pop()].format(operands[-1], right)
            ops.append(op)
            operands.append(self.operand())
        while ops:
            right = operands.pop()
            operands[-1] = _CODE[ops.pop()].format(operands[-1], right)
        code = operands[0]
        return code if code.startswith("V.get(") or code.startswith("_f(") else f"_f({code})"

    def word_value(self) -> str:
        """A word's value: number, [expr], #var, -#var, -[expr]."""
        c = self.peek()
        if c == "#":
            return self.variable()
        if c == "[":
            return self.bracket()
        if c in "+-" and self.peek(1) in ("#", "["):
            self.pos += 1
            inner = self.word_value()
            return inner if c == "+" else f"_neg({inner})"
        return repr(self.number())


def _neg(x):
    return None if x is None else -x


NAMESPACE["_neg"] = _neg


def compile_code(code: str):
    """A float for a constant, else a function V -> float | None."""
    fn = eval(f"lambda V: {code}", dict(NAMESPACE))  # code generated from tokens by Text, never user text
    if "V." not in code:
        try:
            return fn(None)
        except InterpError:
            return fn
    return fn


@dataclass(slots=True)
class FLine:
    """A parsed block. `kind`: "" (NC words and/or assignments), "if_goto", "if_then", "goto", "while",
    "do", "end", "program" (an O number), "percent", "blank", "output" (POPEN PCLOS DPRNT BPRNT)."""

    number: int
    kind: str = ""
    n: int | None = None
    program: int | None = None
    words: list = field(default_factory=list)     # (letter, value, has_point)
    assigns: list = field(default_factory=list)   # (index, value)
    test: object = None                           # condition of IF / WHILE
    target: object = None                         # GOTO label (value), DO/END id
    comment: str = ""
    sources: dict = field(default_factory=dict)   # (file, call stack, M codes) -> canon source index


def prepare(raw: str) -> tuple[str, str]:
    """(code upper case without blanks, comments joined)."""
    out, comments = [], []
    i, n = 0, len(raw)
    while i < n:
        ch = raw[i]
        if ch == ";":
            break
        if ch == "(":
            end = raw.find(")", i + 1)
            if end < 0:
                raise InterpError("unclosed comment '('")
            comments.append(raw[i + 1:end].strip())
            i = end + 1
            continue
        if ch in " \t\r\n":
            i += 1
            continue
        out.append(ch.upper())
        i += 1
    return "".join(out), " ".join(c for c in comments if c)


def parse_line(raw: str, number: int) -> FLine:
    """Parse one block (1-based `number`); raises InterpError with the message."""
    if len(raw) > MAX_LINE:
        raise InterpError(f"line longer than {MAX_LINE} characters")
    code, comment = prepare(raw)
    line = FLine(number=number, comment=comment)
    if code.startswith("%"):
        if code.strip("%"):
            raise InterpError("characters after '%'")
        line.kind = "percent"
        return line
    t = Text(code)
    if t.peek() == "/":
        t.pos += 1
    if t.peek() in ("O", ":") and (_digit(t.peek(1))):
        t.pos += 1
        line.kind = "program"
        line.program = int(t.number())
        if t.pos < len(code):   # `O1000 G0 X0` is not read: a program number stands alone
            raise InterpError("an O program number must stand alone on its line")
        return line
    if t.peek() == "N" and _digit(t.peek(1)):
        t.pos += 1
        start = t.pos
        while _digit(t.peek()):
            t.pos += 1
        line.n = int(code[start:t.pos])
    if t.pos >= len(code):
        line.kind = "blank"
        return line
    if any(t.at(word) for word in ("POPEN", "PCLOS", "DPRNT", "BPRNT")):
        line.kind = "output"              # external output commands: nothing the machine moves
        line.target = code[t.pos:t.pos + 5]
        return line
    if t.at("IF[") or t.at("IF#"):
        t.pos += 2
        if t.peek() != "[":
            raise InterpError("'[' expected after IF")
        line.test = compile_code(t.bracket())
        if t.at("GOTO"):
            t.pos += 4
            line.kind = "if_goto"
            line.target = compile_code(t.word_value())
        elif t.at("THEN"):
            t.pos += 4
            line.kind = "if_then"
            _assignments(t, line)
            if not line.assigns:
                raise InterpError("an assignment #i = ... expected after THEN")
        else:
            raise InterpError("GOTO or THEN expected after IF [...]")
        _end(t)
        return line
    if t.at("GOTO"):
        t.pos += 4
        line.kind = "goto"
        line.target = compile_code(t.word_value())
        _end(t)
        return line
    if t.at("WHILE") or t.at("WH["):    # WH: the abbreviation real 0i-MD macros use
        t.pos += 5 if t.at("WHILE") else 2
        if t.peek() != "[":
            raise InterpError("'[' expected after WHILE")
        line.test = compile_code(t.bracket())
        if not t.at("DO"):
            raise InterpError("DO expected after WHILE [...]")
        t.pos += 2
        line.kind = "while"
        line.target = _loop_id(t)
        _end(t)
        return line
    for word in ("DO", "END"):
        if t.at(word) and _digit(t.peek(len(word))):
            t.pos += len(word)
            line.kind = word.lower()
            line.target = _loop_id(t)
            _end(t)
            return line
    while t.pos < len(code):
        c = t.peek()
        if c == "#":
            _assignments(t, line)
            continue
        if c == ",":
            raise InterpError("',C' / ',R' corner chamfer and rounding are not read")
        if c not in NC_LETTERS:
            raise InterpError(f"bad character {c!r}")
        t.pos += 1
        start = t.pos
        value = t.word_value()
        line.words.append((c, compile_code(value), "." in code[start:t.pos]))
    return line


def _assignments(t: Text, line: FLine) -> None:
    while t.peek() == "#":
        t.pos += 1
        c = t.peek()
        if c == "[":
            index = t.bracket()
        elif c == "#":
            index = t.variable()
        else:
            index = repr(t.number())
        t.expect("=", "in the assignment #i = ...")
        line.assigns.append((compile_code(index), compile_code(t.expression())))


def _loop_id(t: Text) -> int:
    start = t.pos
    while _digit(t.peek()):
        t.pos += 1
    if t.pos == start:
        raise InterpError("loop number expected after DO / END")
    m = int(t.text[start:t.pos])
    if m not in (1, 2, 3):
        raise InterpError(f"DO/END number must be 1, 2 or 3 (got {m})")
    return m


def _end(t: Text) -> None:
    if t.pos < len(t.text):
        raise InterpError(f"unexpected {t.text[t.pos:t.pos + 10]!r} after the macro statement")
