"""Sinumerik 840D part-program lines -> `SLine` statements, values compiled to closures.

A line is read left to right at the character level: an optional block-skip `/`, an `N` (or `:`)
block number, an optional `LABEL:`, then either one control statement (`IF cond GOTOF L`, `IF cond`,
`ELSE`, `ENDIF`, `LOOP`, `ENDLOOP`, `FOR v = a TO b`, `ENDFOR`, `WHILE cond`, `ENDWHILE`, `REPEAT`,
`UNTIL cond`, `GOTOF/GOTOB/GOTO/GOTOC target`, `DEF type name[=value], ...`, `PROC NAME(type A, ...)`,
`RET`, `MCALL [call]`, `TRANS/ATRANS/ROT/AROT [words]`) or a block: address words (`G1`, `X10`,
`X=R1+5`, `X=IC(5)`, `CR=20`, `TURN=2`), assignments (`R1=R2*3`, `VAR=...`), `MSG(...)`, and at most one
subprogram call (`L123`, `NAME`, `NAME(args)`, `CYCLE81(...)`, with an optional `P` repeat count).
`;` starts a comment. Addresses may be written without blanks (`G1X10Y20`) as the control reads them.

Expressions follow the operator priorities of the Sinumerik programming manuals (highest first):
NOT B_NOT; * / DIV MOD; + -; B_AND; B_XOR; B_OR; AND; XOR; OR; << (string concatenation);
== <> < > <= >= (lowest: `(A==1) AND (B==2)` needs its brackets, as on the control). Angles of the
trigonometric functions are degrees. Evaluation errors (division by zero, SQRT of a negative, ...) raise
InterpError, which the interpreter turns into a ProgramError naming file and line.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from feedlog.toolpath.interp.errors import InterpError

# addresses that take a value written `X10` or `X=expr`
ADDRESSES = frozenset("ABCDEFGHIJKLMPQSTUVWXYZ")
# multi-letter addresses written `NAME=value`
EQ_ADDRESSES = frozenset(("CR", "TURN", "RPL", "AP", "RP", "AR", "RND", "RNDM", "CHF", "CHR", "ADIS", "ADISPOS",
                          "FA", "OVR", "SPOS", "SPOSA", "FRC", "FRCM"))
CONTROL = frozenset(("IF", "ELSE", "ENDIF", "LOOP", "ENDLOOP", "FOR", "ENDFOR", "WHILE", "ENDWHILE", "REPEAT",
                     "UNTIL", "GOTOF", "GOTOB", "GOTO", "GOTOC", "DEF", "PROC", "RET", "MCALL", "TRANS", "ATRANS",
                     "ROT", "AROT", "SCALE", "ASCALE", "MIRROR", "AMIRROR", "EXTERN", "CALL", "PCALL", "CASE",
                     "ENDPROC", "ASPLINE", "BSPLINE", "CSPLINE", "POLY"))
# words that set dynamics, look-ahead, transformations or the display: no effect on the programmed path
IGNORED = frozenset(("SOFT", "BRISK", "DRIVE", "FFWON", "FFWOF", "COMPCAD", "COMPCURV", "COMPSURF", "COMPOF",
                     "UPATH", "SPATH", "STOPRE", "CFC", "CFTCP", "CFIN", "FNORM", "FLIN", "FCUB", "SUPA", "DISPLOF",
                     "DISPLON", "SAVE", "G601", "G602", "G603", "G450", "G451", "TRAFOOF", "ORIWKS", "ORIMKS",
                     "ORIAXES", "ORIVECT", "WAITM", "WORKPIECE", "CYCLE832", "SBLOF", "SBLON", "ACC", "OFFN",
                     "CUT2D", "CUT2DF", "CDON", "CDOF", "CDOF2", "DIAMOF", "BTAN", "BAUTO", "BNAT", "ETAN",
                     "EAUTO", "ENAT", "G40", "TRAORI"))
# address words with no effect on the programmed path (look-ahead distances, overrides, spindle positioning)
IGNORED_WORDS = frozenset(("ADIS", "ADISPOS", "OVR", "SPOS", "SPOSA", "FA"))
FUNCTIONS = {
    "SIN": 1, "COS": 1, "TAN": 1, "ASIN": 1, "ACOS": 1, "ATAN2": 2, "SQRT": 1, "ABS": 1, "POT": 1, "TRUNC": 1,
    "ROUND": 1, "ROUNDUP": 1, "LN": 1, "EXP": 1, "MINVAL": 2, "MAXVAL": 2, "BOUND": 3,
}
TYPES = ("REAL", "INT", "BOOL", "CHAR", "STRING")
CALL_CYCLES = frozenset(("CYCLE81", "CYCLE82", "CYCLE83"))
_NUMBER = re.compile(r"(\d+\.?\d*|\.\d+)(?:EX([+-]?\d+))?")
_IDENT = re.compile(r"[A-Z_][A-Z0-9_]*")
_RPARAM = re.compile(r"R(\d+)$")
_LABEL = re.compile(r"[A-Z_][A-Z_][A-Z0-9_]*$")
MAX_R = 999


@dataclass(slots=True)
class Word:
    """`address` (upper case: X, G, CR, ...), `value` (float, str or function of the environment),
    `mode`: "" (the modal distance mode), "AC" or "IC"."""

    address: str
    value: object
    mode: str = ""


@dataclass(slots=True)
class SLine:
    """A parsed line. `control`: (keyword, ...) or None; `items`: in line order, ("word", Word),
    ("set", target, value) with target ("R", n) or ("V", name), ("msg", value); `call`: (name, args, P)
    or None (args: list of value-or-None for omitted ones); `error`: a deferred parse error."""

    number: int
    raw: str
    n: int | None = None
    label: str | None = None
    control: tuple | None = None
    items: list = field(default_factory=list)
    call: tuple | None = None
    comment: str = ""
    ignored: list = field(default_factory=list)
    error: str | None = None
    sources: dict = field(default_factory=dict)   # (file, call stack, M codes, comment) -> canon source index

    @property
    def empty(self) -> bool:
        return self.control is None and not self.items and self.call is None

    @property
    def plain(self) -> bool:
        """What the line-by-line translation reads too: constant words, MSG, no calls or control."""
        if self.control is not None or self.call is not None:
            return False
        for item in self.items:
            if item[0] == "set":
                return False
            if item[0] == "word" and (callable(item[1].value) or item[1].mode):
                return False
        return True


# -- values ---------------------------------------------------------------------------------------------

def finite(x: float) -> float:
    if isinstance(x, float) and not math.isfinite(x):
        raise InterpError("a calculation gave an infinite or undefined value")
    return x


def num(x) -> float:
    if isinstance(x, str):
        raise InterpError(f"a string ({x!r}) where a number is needed")
    return x


def _div(a, b):
    if num(b) == 0:
        raise InterpError("division by zero")
    return finite(num(a) / b)


def _idiv(a, b):
    if num(b) == 0:
        raise InterpError("division by zero (DIV)")
    return float(math.trunc(num(a) / b))


def _mod(a, b):
    if num(b) == 0:
        raise InterpError("division by zero (MOD)")
    return math.fmod(num(a), b)


def _eq(a, b):
    if isinstance(a, str) or isinstance(b, str):
        return float(str(a) == str(b))
    return float(a == b or abs(a - b) <= 1e-12 * max(abs(a), abs(b)))


def _round(x):
    x = num(x)
    return float(math.floor(abs(x) + 0.5)) * (1.0 if x >= 0 else -1.0)


def _sqrt(x):
    if num(x) < 0:
        raise InterpError(f"SQRT of a negative number ({x:g})")
    return math.sqrt(x)


def _ln(x):
    if num(x) <= 0:
        raise InterpError(f"LN of a number that is not positive ({x:g})")
    return math.log(x)


def _asin(x):
    if not -1.0 <= num(x) <= 1.0:
        raise InterpError(f"ASIN of {x:g} (outside -1..1)")
    return math.degrees(math.asin(x))


def _acos(x):
    if not -1.0 <= num(x) <= 1.0:
        raise InterpError(f"ACOS of {x:g} (outside -1..1)")
    return math.degrees(math.acos(x))


def _tan(x):
    r = math.cos(math.radians(num(x)))
    if abs(r) < 1e-15:
        raise InterpError(f"TAN of {x:g} degrees is infinite")
    return math.tan(math.radians(x))


def _exp(x):
    try:
        return math.exp(num(x))
    except OverflowError:
        raise InterpError(f"EXP({x:g}) overflows") from None


def _bits(x) -> int:
    x = num(x)
    if x != math.floor(x):
        raise InterpError(f"a bit operation on a non-integer ({x:g})")
    return int(x)


_FUNCS = {
    "SIN": lambda x: math.sin(math.radians(num(x))), "COS": lambda x: math.cos(math.radians(num(x))),
    "TAN": _tan, "ASIN": _asin, "ACOS": _acos,
    "ATAN2": lambda y, x: math.degrees(math.atan2(num(y), num(x))),
    "SQRT": _sqrt, "ABS": lambda x: abs(num(x)), "POT": lambda x: finite(num(x) * x),
    "TRUNC": lambda x: float(math.trunc(num(x))), "ROUND": _round,
    "ROUNDUP": lambda x: float(math.ceil(num(x))) if x >= 0 else float(math.floor(x)),
    "LN": _ln, "EXP": _exp, "MINVAL": lambda a, b: min(num(a), num(b)), "MAXVAL": lambda a, b: max(num(a), num(b)),
    "BOUND": lambda lo, hi, x: max(num(lo), min(num(hi), num(x))),
}


def _fmt(v) -> str:
    if isinstance(v, str):
        return v
    return f"{v:.6f}".rstrip("0").rstrip(".") if v != int(v) else str(int(v))


_BINARY = {
    "*": lambda a, b: finite(num(a) * num(b)), "/": _div, "DIV": _idiv, "MOD": _mod,
    "+": lambda a, b: finite(num(a) + num(b)), "-": lambda a, b: finite(num(a) - num(b)),
    "B_AND": lambda a, b: float(_bits(a) & _bits(b)), "B_XOR": lambda a, b: float(_bits(a) ^ _bits(b)),
    "B_OR": lambda a, b: float(_bits(a) | _bits(b)),
    "AND": lambda a, b: float(bool(num(a)) and bool(num(b))), "XOR": lambda a, b: float(bool(num(a)) != bool(num(b))),
    "OR": lambda a, b: float(bool(num(a)) or bool(num(b))),
    "<<": lambda a, b: _fmt(a) + _fmt(b),
    "==": _eq, "<>": lambda a, b: 1.0 - _eq(a, b),
    "<": lambda a, b: float(num(a) < num(b)), ">": lambda a, b: float(num(a) > num(b)),
    "<=": lambda a, b: float(num(a) <= num(b)), ">=": lambda a, b: float(num(a) >= num(b)),
}
# lowest priority first
_LEVELS = (("==", "<>", "<=", ">=", "<", ">"), ("<<",), ("OR",), ("XOR",), ("AND",), ("B_OR",), ("B_XOR",),
           ("B_AND",), ("+", "-"), ("*", "/", "DIV", "MOD"))
_WORD_OPS = frozenset(("OR", "XOR", "AND", "B_OR", "B_XOR", "B_AND", "DIV", "MOD", "NOT", "B_NOT"))


def _const(v):
    return v


def _apply2(op, a, b):
    fa, fb = callable(a), callable(b)
    if not fa and not fb:
        return op(a, b)
    if fa and fb:
        return lambda E: op(a(E), b(E))
    if fa:
        return lambda E: op(a(E), b)
    return lambda E: op(a, b(E))


def _apply(fn, args):
    if not any(callable(a) for a in args):
        return fn(*args)
    return lambda E: fn(*[a(E) if callable(a) else a for a in args])


class Cursor:
    """A character cursor over one line's code (upper case outside strings)."""

    def __init__(self, text: str, names: set[str]) -> None:
        self.text = text
        self.pos = 0
        self.names = names      # variables declared so far in this file (DEF, PROC parameters)

    def skip(self) -> None:
        t, p = self.text, self.pos
        while p < len(t) and t[p] in " \t":
            p += 1
        self.pos = p

    def peek(self, k: int = 1) -> str:
        self.skip()
        return self.text[self.pos:self.pos + k]

    def at_end(self) -> bool:
        self.skip()
        return self.pos >= len(self.text)

    def ident(self) -> str | None:
        self.skip()
        m = _IDENT.match(self.text, self.pos)
        return m.group(0) if m else None

    def take(self, s: str) -> bool:
        if self.peek(len(s)) == s:
            self.pos += len(s)
            return True
        return False

    def expect(self, s: str, what: str) -> None:
        if not self.take(s):
            got = self.text[self.pos:self.pos + 12] or "end of line"
            raise InterpError(f"'{s}' expected {what}, found {got!r}")

    # -- expressions ------------------------------------------------------------------------------------
    def expression(self, level: int = 0):
        if level == len(_LEVELS):
            return self.unary()
        left = self.expression(level + 1)
        while True:
            op = self._operator(_LEVELS[level])
            if op is None:
                return left
            right = self.expression(level + 1)
            left = _apply2(_BINARY[op], left, right)

    def _operator(self, ops: tuple):
        self.skip()
        t, p = self.text, self.pos
        for op in ops:
            if op in _WORD_OPS:
                m = _IDENT.match(t, p)
                if m and m.group(0) == op:
                    self.pos = m.end()
                    return op
            elif t.startswith(op, p):
                if op in ("<", ">") and t[p + 1:p + 2] in ("=", ">", "<"):
                    continue
                if op == "<" and t.startswith("<<", p):
                    continue
                self.pos = p + len(op)
                return op
        return None

    def unary(self):
        self.skip()
        if self.take("-"):
            v = self.unary()
            return _apply(lambda x: -num(x), [v])
        if self.take("+"):
            return self.unary()
        name = self.ident()
        if name in ("NOT", "B_NOT"):
            self.pos += len(name)
            v = self.unary()
            if name == "NOT":
                return _apply(lambda x: float(not num(x)), [v])
            return _apply(lambda x: float(~_bits(x)), [v])
        return self.primary()

    def primary(self):
        self.skip()
        t, p = self.text, self.pos
        if p >= len(t):
            raise InterpError("expression expected, found end of line")
        ch = t[p]
        if ch == "(":
            self.pos += 1
            v = self.expression()
            self.expect(")", "to close a bracket")
            return v
        if ch == '"':
            end = t.find('"', p + 1)
            if end < 0:
                raise InterpError("unclosed string")
            self.pos = end + 1
            return t[p + 1:end]
        if ch == "'":
            end = t.find("'", p + 1)
            if end < 0:
                raise InterpError("unclosed ' constant")
            body = t[p + 1:end]
            self.pos = end + 1
            try:
                if body[:1] == "H":
                    return float(int(body[1:], 16))
                if body[:1] == "B":
                    return float(int(body[1:], 2))
            except ValueError:
                pass
            raise InterpError(f"bad constant '{body}'")
        m = _NUMBER.match(t, p)
        if m:
            self.pos = m.end()
            v = float(m.group(1))
            if m.group(2) is not None:
                v = finite(v * 10.0 ** int(m.group(2)))
            return v
        if ch == "$":
            m = re.compile(r"\$[A-Z0-9_]*").match(t, p)
            raise InterpError(f"system variable {m.group(0)} is not known to feedlog (its value is machine state)")
        name = self.ident()
        if name is None:
            raise InterpError(f"unexpected character {ch!r} in an expression")
        self.pos += len(name)
        if name in ("TRUE", "FALSE"):
            return 1.0 if name == "TRUE" else 0.0
        if name == "PI" and name not in self.names:
            return math.pi
        if name in self.names:
            return lambda E, n=name: E.var(n)
        r = _RPARAM.match(name)
        if r:
            k = int(r.group(1))
            if k > MAX_R:
                raise InterpError(f"R parameter R{k} out of range (R0-R{MAX_R})")
            return lambda E, k=k: E.R[k]
        if name in FUNCTIONS:
            args = self.arguments(name)
            if len(args) != FUNCTIONS[name] or any(a is None for a in args):
                raise InterpError(f"{name} takes {FUNCTIONS[name]} argument(s)")
            return _apply(_FUNCS[name], args)
        raise InterpError(f"unknown name {name} in an expression (not a DEF variable, R parameter or function)")

    def arguments(self, name: str) -> list:
        """`(a, , c)`: a list of compiled values, None where an argument is left out."""
        self.expect("(", f"after {name}")
        args: list = []
        if self.take(")"):
            return args
        while True:
            self.skip()
            if self.peek() in (",", ")"):
                args.append(None)
            else:
                args.append(self.expression())
            if self.take(")"):
                return args
            self.expect(",", f"between the arguments of {name}")


# -- lines -------------------------------------------------------------------------------------------------

def split_comment(raw: str) -> tuple[str, str]:
    """(code, comment): `;` outside a string starts the comment."""
    in_str = False
    for i, ch in enumerate(raw):
        if ch == '"':
            in_str = not in_str
        elif ch == ";" and not in_str:
            return raw[:i], raw[i + 1:].strip()
    return raw, ""


def _upper(code: str) -> str:
    out, in_str = [], False
    for ch in code:
        if ch == '"':
            in_str = not in_str
        out.append(ch if in_str else ch.upper())
    return "".join(out)


def parse_line(raw: str, number: int, names: set[str]) -> SLine:
    """Parse one line; a syntax error is kept in `SLine.error` (raised when the line runs). `names` are
    the variables declared so far in the file; DEF and PROC lines add theirs."""
    code, comment = split_comment(raw)
    line = SLine(number=number, raw=raw.strip(), comment=comment)
    stripped = code.strip()
    if not stripped or stripped.startswith("%"):
        if stripped.startswith("%"):
            line.comment = stripped
        return line
    try:
        _parse(line, Cursor(_upper(code.replace("\t", " ")), names))
    except InterpError as exc:
        line.error = str(exc)
        line.control, line.items, line.call = None, [], None
    return line


def _parse(line: SLine, c: Cursor) -> None:
    c.take("/")
    c.skip()
    t = c.text
    m = re.compile(r"N(\d+)|:(\d+)").match(t, c.pos)
    if m:
        line.n = int(m.group(1) or m.group(2))
        c.pos = m.end()
    name = c.ident()
    if name is not None:
        after = c.pos + len(name)
        rest = t[after:].lstrip(" ")
        if rest.startswith(":") and not rest.startswith(":="):
            if not _LABEL.match(name):
                raise InterpError(f"label {name}: a label begins with two letters or underscores")
            line.label = name
            c.pos = t.index(":", after) + 1
            name = c.ident()
    if name in CONTROL:
        c.pos += len(name)
        line.control = _control(name, c, line)
        if not c.at_end():
            raise InterpError(f"unexpected {c.text[c.pos:c.pos + 16]!r} after {name}")
        return
    _block(line, c)


def _target(c: Cursor) -> str:
    name = c.ident()
    if name is None:
        raise InterpError("jump target (label or block number) expected")
    c.pos += len(name)
    return name


def _control(kw: str, c: Cursor, line: SLine) -> tuple:
    if kw == "IF":
        cond = c.expression()
        nxt = c.ident()
        if nxt in ("GOTOF", "GOTOB", "GOTO", "GOTOC"):
            c.pos += len(nxt)
            return ("IFGOTO", cond, nxt, _target(c))
        if not c.at_end():
            raise InterpError("IF condition followed by something other than GOTOF/GOTOB/GOTO "
                              "(a block IF ends its line; the branch follows on the next lines)")
        return ("IF", cond)
    if kw in ("WHILE", "UNTIL"):
        return (kw, c.expression())
    if kw in ("GOTOF", "GOTOB", "GOTO", "GOTOC"):
        return ("GOTO", kw, _target(c))
    if kw == "FOR":
        var = c.ident()
        if var is None:
            raise InterpError("FOR needs a counter variable")
        c.pos += len(var)
        if var not in c.names and not _RPARAM.match(var):
            raise InterpError(f"FOR counter {var} is not a DEF variable or R parameter")
        c.expect("=", "after the FOR counter")
        start = c.expression()
        if c.ident() != "TO":
            raise InterpError("FOR without TO")
        c.pos += 2
        return ("FOR", var, start, c.expression())
    if kw == "DEF":
        return _def(c)
    if kw == "PROC":
        return _proc(c)
    if kw == "EXTERN":
        c.pos = len(c.text)
        return ("NOP",)
    if kw == "MCALL":
        if c.at_end():
            return ("MCALL", None)
        name = c.ident()
        if name is None:
            raise InterpError("MCALL: subprogram name expected")
        c.pos += len(name)
        args = c.arguments(name) if c.peek() == "(" else []
        return ("MCALL", (name, args, None))
    if kw in ("TRANS", "ATRANS", "ROT", "AROT"):
        words = {}
        while not c.at_end():
            w = _word(c, c.ident() or c.peek())
            if w.address not in ("X", "Y", "Z", "RPL"):
                raise InterpError(f"{w.address} is not read with {kw} (X, Y, Z, RPL)")
            words[w.address] = w.value
        return ("FRAME", kw, words)
    if kw in ("SCALE", "ASCALE", "MIRROR", "AMIRROR"):
        raise InterpError(f"{kw} frames (scaling, mirroring) are not simulated")
    if kw in ("ASPLINE", "BSPLINE", "CSPLINE", "POLY"):
        raise InterpError(f"{kw} (spline or polynomial interpolation) is not simulated")
    if kw in ("CALL", "PCALL", "CASE"):
        raise InterpError(f"{kw} (indirect or computed calls) is not read")
    return (kw,)   # ELSE ENDIF LOOP ENDLOOP ENDFOR ENDWHILE REPEAT RET ENDPROC


def _def(c: Cursor) -> tuple:
    typ = c.ident()
    if typ not in TYPES:
        if typ in ("AXIS", "FRAME"):
            raise InterpError(f"DEF {typ} variables are not read")
        raise InterpError(f"DEF type expected (REAL, INT, BOOL, CHAR, STRING), found {typ}")
    c.pos += len(typ)
    if typ == "STRING":
        c.expect("[", "after STRING (its length)")
        c.expression()
        c.expect("]", "after the STRING length")
    out = []
    while True:
        name = c.ident()
        if name is None:
            raise InterpError("DEF: variable name expected")
        if _RPARAM.match(name) or name in FUNCTIONS or name in CONTROL:
            raise InterpError(f"DEF: {name} is a reserved name")
        c.pos += len(name)
        if c.peek() == "[":
            raise InterpError(f"DEF: array variables ({name}[...]) are not read")
        init = None
        if c.take("="):
            init = c.expression()
        c.names.add(name)
        out.append((name, typ, init))
        if not c.take(","):
            break
    return ("DEF", out)


def _proc(c: Cursor) -> tuple:
    name = c.ident()
    if name is None:
        raise InterpError("PROC: name expected")
    c.pos += len(name)
    params = []
    if c.take("("):
        if not c.take(")"):
            while True:
                ref = False
                typ = c.ident()
                if typ == "VAR":
                    ref = True
                    c.pos += 3
                    typ = c.ident()
                if typ not in TYPES:
                    raise InterpError(f"PROC {name}: parameter type expected, found {typ}")
                c.pos += len(typ)
                if typ == "STRING":
                    c.expect("[", "after STRING")
                    c.expression()
                    c.expect("]", "after the STRING length")
                pname = c.ident()
                if pname is None:
                    raise InterpError(f"PROC {name}: parameter name expected")
                c.pos += len(pname)
                c.names.add(pname)
                params.append((pname, typ, ref))
                if c.take(")"):
                    break
                c.expect(",", f"between the parameters of PROC {name}")
    attrs = []
    while not c.at_end():      # SAVE, DISPLOF, SBLOF, ...
        attr = c.ident()
        if attr is None:
            raise InterpError(f"unexpected {c.text[c.pos:c.pos + 12]!r} after PROC {name}")
        c.pos += len(attr)
        attrs.append(attr)
    return ("PROC", name, params, tuple(attrs))


def _value(c: Cursor, address: str):
    """The value after `ADDR=`: an expression, or AC(...)/IC(...) (DC/ACP/ACN read as AC)."""
    name = c.ident()
    if name in ("AC", "IC", "DC", "ACP", "ACN") and c.text[c.pos + len(name):].lstrip().startswith("("):
        c.pos += len(name)
        c.expect("(", f"after {name}")
        v = c.expression()
        c.expect(")", f"to close {name}(")
        return v, "IC" if name == "IC" else "AC"
    return c.expression(), ""


def _word(c: Cursor, name: str) -> Word:
    """An address word at the cursor (`name`: the identifier there)."""
    t = c.text
    if name in EQ_ADDRESSES or (len(name) == 1 and name in ADDRESSES):
        after = c.pos + len(name)
        rest = t[after:].lstrip(" ")
        if rest.startswith("=") and not rest.startswith("=="):
            c.pos = t.index("=", after) + 1
            value, mode = _value(c, name)
            return Word(name, value, mode)
    if name and name[0] in ADDRESSES:
        m = re.compile(r"\s*([+-]?)\s*(\d+\.?\d*|\.\d+)").match(t, c.pos + 1)
        if m:
            c.pos = m.end()
            v = float(m.group(2))
            return Word(name[0], -v if m.group(1) == "-" else v)
    raise InterpError(f"cannot read {t[c.pos:c.pos + 16]!r}: not an address word")


def _block(line: SLine, c: Cursor) -> None:
    t = c.text
    while not c.at_end():
        name = c.ident()
        if name is None:
            raise InterpError(f"unexpected {t[c.pos:c.pos + 16]!r}")
        after = c.pos + len(name)
        rest = t[after:].lstrip(" ")
        is_set = rest.startswith("=") and not rest.startswith("==")
        if name in c.names or _RPARAM.match(name):
            if not is_set:
                raise InterpError(f"{name} without an assignment (write {name}=value)")
            c.pos = t.index("=", after) + 1
            r = _RPARAM.match(name)
            if r and int(r.group(1)) > MAX_R:
                raise InterpError(f"R parameter {name} out of range (R0-R{MAX_R})")
            target = ("R", int(r.group(1))) if r else ("V", name)
            line.items.append(("set", target, c.expression()))
            continue
        if name == "MSG" and rest.startswith("("):
            c.pos = after
            args = c.arguments("MSG")
            if len(args) > 1 or (args and args[0] is None):
                raise InterpError("MSG takes one text")
            line.items.append(("msg", args[0] if args else ""))
            continue
        if name in IGNORED:
            c.pos = after
            if rest.startswith("("):      # their arguments are not read (CYCLE832(0.01,_FINISH,1))
                c.pos = _skip_brackets(t, t.index("(", after))
            line.ignored.append(name)
            continue
        if name == "T" and is_set and rest[1:].lstrip().startswith('"'):
            c.pos = t.index("=", after) + 1
            line.items.append(("word", Word("T", c.primary())))
            continue
        if name == "L" or (name[0] == "L" and name[1:].isdigit()):
            m = re.compile(r"L\s*(\d+)").match(t, c.pos)
            if m:
                _set_call(line, "L" + m.group(1), [])
                c.pos = m.end()
                continue
        if is_set or (name[0] in ADDRESSES and re.match(r"\s*[+-]?\s*[\d.]", t[c.pos + 1:])):
            if is_set and not (name in EQ_ADDRESSES or (len(name) == 1 and name in ADDRESSES)):
                raise InterpError(f"unknown name {name} (assignment to an undeclared variable?)")
            w = _word(c, name)
            if w.address in IGNORED_WORDS:
                line.ignored.append(w.address)
                continue
            if w.address == "P" and line.call is not None:
                if callable(w.value) or w.value < 1 or w.value != int(w.value):
                    raise InterpError("P repeat count must be a whole number 1 or more")
                line.call = (line.call[0], line.call[1], int(w.value))
                continue
            line.items.append(("word", w))
            continue
        # a subprogram (or cycle) call by name
        c.pos = after
        args = c.arguments(name) if rest.startswith("(") else []
        _set_call(line, name, args)
    # a P word before the call name: `P3 L10` is read as well
    for k, item in enumerate(line.items):
        if item[0] == "word" and item[1].address == "P" and line.call is not None and line.call[2] is None:
            v = item[1].value
            if callable(v) or v < 1 or v != int(v):
                raise InterpError("P repeat count must be a whole number 1 or more")
            line.call = (line.call[0], line.call[1], int(v))
            del line.items[k]
            break


def _skip_brackets(t: str, start: int) -> int:
    depth, in_str = 0, False
    for i in range(start, len(t)):
        ch = t[i]
        if ch == '"':
            in_str = not in_str
        elif not in_str and ch == "(":
            depth += 1
        elif not in_str and ch == ")":
            depth -= 1
            if depth == 0:
                return i + 1
    raise InterpError("unclosed bracket")


def _set_call(line: SLine, name: str, args: list) -> None:
    if line.call is not None:
        raise InterpError(f"two subprogram calls in one block ({line.call[0]} and {name})")
    line.call = (name, args, None)
