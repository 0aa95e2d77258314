"""RS274/NGC values -> Python code: numbers, parameters, [expressions] and functions, as LinuxCNC reads them.

A value on a line is read left to right from the line's lower-case, blank-free text (the way LinuxCNC
prepares a line): a number, `#n` / `##n` / `#[expr]` / `#<name>`, `[expression]`, a function
(`sin[...]`, `atan[a]/[b]`, `exists[#<name>]`), or a unary sign before any of these. Binary operators
have LinuxCNC's five levels (`**`; `* / mod`; `+ -`; `eq ne gt ge lt le`; `and or xor`), all left to
right. Angles are degrees; `eq`/`ne` compare within 0.0001; logical results are 1.0 or 0.0; `mod` is
never negative; division by zero, a negative base with a fractional power, and any NaN or infinity
are errors.

Each value becomes one Python expression over a context `C` (the interpreter's parameters); a line's
values are compiled once and run every time the line executes (loops run compiled code, not text).
"""

from __future__ import annotations

import math

from feedlog.toolpath.interp.errors import InterpError

TOLERANCE_EQUAL = 0.0001
_PREC = {"**": 6, "*": 5, "/": 5, "mod": 5, "+": 4, "-": 4,
         "eq": 3, "ne": 3, "gt": 3, "ge": 3, "lt": 3, "le": 3, "and": 2, "or": 2, "xor": 2}
_OPS = ("**", "*", "/", "+", "-", "]", "and", "mod", "or", "xor", "eq", "ne", "ge", "gt", "le", "lt")
_UNARY = ("abs", "acos", "asin", "atan", "cos", "exp", "exists", "fix", "fup", "ln", "round", "sin",
          "sqrt", "tan")
_NUMBER_CHARS = set("0123456789.")


def finite(x: float) -> float:
    if x != x:
        raise InterpError("calculation resulted in 'not a number'")
    if x in (math.inf, -math.inf):
        raise InterpError("calculation resulted in 'infinity'")
    return x


def div(a: float, b: float) -> float:
    if b == 0.0:
        raise InterpError("attempt to divide by zero")
    return a / b


def mod(a: float, b: float) -> float:
    try:
        r = math.fmod(a, b)
    except ValueError:
        raise InterpError("calculation resulted in 'not a number'") from None
    return r + abs(b) if r < 0.0 else r


def power(a: float, b: float) -> float:
    if a < 0.0 and math.floor(b) != b:
        raise InterpError("attempt to raise negative number to non-integer power")
    try:
        return math.pow(a, b)
    except (OverflowError, ValueError, ZeroDivisionError):
        raise InterpError("calculation resulted in 'infinity'") from None


def eq(a: float, b: float) -> float:
    return 1.0 if abs(a - b) < TOLERANCE_EQUAL else 0.0


def ne(a: float, b: float) -> float:
    return 1.0 if abs(a - b) >= TOLERANCE_EQUAL else 0.0


def _acos(x: float) -> float:
    if x < -1.0 or x > 1.0:
        raise InterpError("argument to acos out of range")
    return math.degrees(math.acos(x))


def _asin(x: float) -> float:
    if x < -1.0 or x > 1.0:
        raise InterpError("argument to asin out of range")
    return math.degrees(math.asin(x))


def _ln(x: float) -> float:
    if x <= 0.0:
        raise InterpError("zero or negative argument to ln")
    return math.log(x)


def _sqrt(x: float) -> float:
    if x < 0.0:
        raise InterpError("negative argument to sqrt")
    return math.sqrt(x)


def _exp(x: float) -> float:
    try:
        return math.exp(x)
    except OverflowError:
        raise InterpError("calculation resulted in 'infinity'") from None


INT_MIN, INT_MAX = -2**31, 2**31 - 1


def _round(x: float) -> float:
    """LinuxCNC's ROUND: (int)(x +- 0.5), a C int: beyond its range the x86 conversion gives INT_MIN."""
    v = x + (-0.5 if x < 0.0 else 0.5)
    if not INT_MIN <= v < INT_MAX + 1:
        return float(INT_MIN)
    return float(int(v))


FUNCTIONS = {
    "abs": abs, "acos": _acos, "asin": _asin, "cos": lambda x: math.cos(math.radians(x)),
    "exp": _exp, "fix": lambda x: float(math.floor(x)), "fup": lambda x: float(math.ceil(x)), "ln": _ln,
    "round": _round, "sin": lambda x: math.sin(math.radians(x)), "sqrt": _sqrt,
    "tan": lambda x: math.tan(math.radians(x)),
    "atan": lambda y, x: math.degrees(math.atan2(y, x)),
}
# names the compiled code sees
NAMESPACE = {"_f": finite, "_div": div, "_mod": mod, "_pow": power, "_eq": eq, "_ne": ne,
             **{f"_{k}": v for k, v in FUNCTIONS.items()}}
_BINARY = {"+": "({} + {})", "-": "({} - {})", "*": "({} * {})", "/": "_div({}, {})", "mod": "_mod({}, {})",
           "**": "_pow({}, {})", "eq": "_eq({}, {})", "ne": "_ne({}, {})",
           "gt": "(1.0 if {} > {} else 0.0)", "ge": "(1.0 if {} >= {} else 0.0)",
           "lt": "(1.0 if {} < {} else 0.0)", "le": "(1.0 if {} <= {} else 0.0)",
           "and": "(0.0 if ({} == 0.0) | ({} == 0.0) else 1.0)",
           "or": "(1.0 if ({} != 0.0) | ({} != 0.0) else 0.0)",
           "xor": "(1.0 if (({} != 0.0) != ({} != 0.0)) else 0.0)"}


class Reader:
    """Reads values from one prepared line (lower case, no blanks outside comments) at `pos`."""

    def __init__(self, text: str, pos: int = 0) -> None:
        self.text = text
        self.pos = pos

    def peek(self, k: int = 0) -> str:
        i = self.pos + k
        return self.text[i] if i < len(self.text) else ""

    def startswith(self, s: str) -> bool:
        return self.text.startswith(s, self.pos)

    def value(self) -> str:
        """Python code of one real value (read_real_value)."""
        c, c1 = self.peek(), self.peek(1)
        if not c:
            raise InterpError("no characters found in reading real value")
        if c == "[":
            return self.expression()
        if c == "#":
            return self.parameter()
        if c in "+-" and c1 and not c1.isdigit() and c1 != ".":
            self.pos += 1
            inner = self.value()
            return inner if c == "+" else f"(-{inner})"
        if "a" <= c <= "z":
            return self.unary()
        return repr(self.number())

    def number(self) -> float:
        start = self.pos
        i = start
        while i < len(self.text) and self.text[i] in "+-":
            i += 1
        while i < len(self.text) and self.text[i] in _NUMBER_CHARS:
            i += 1
        token = self.text[start:i]
        if i == start:
            raise InterpError(f"bad number format at {self.text[start:start + 10]!r}")
        try:
            v = float(token)
        except ValueError:
            raise InterpError(f"bad number format (conversion failed) parsing {token!r}") from None
        self.pos = i
        return finite(v)

    def expression(self) -> str:
        """`[ value op value ... ]` with LinuxCNC precedence, left to right."""
        self.pos += 1  # '['
        operands = [self.value()]
        ops: list[str] = []
        while True:
            op = self.operation()
            if op == "]":
                break
            while ops and _PREC[ops[-1]] >= _PREC[op]:
                right = operands.pop()
                operands[-1] = _BINARY[ops.pop()].format(operands[-1], right)
            ops.append(op)
            operands.append(self.value())
        while ops:
            right = operands.pop()
            operands[-1] = _BINARY[ops.pop()].format(operands[-1], right)
        return f"_f({operands[0]})"

    def operation(self) -> str:
        if self.pos >= len(self.text):
            raise InterpError("unclosed expression")
        for op in _OPS:
            if self.startswith(op):
                self.pos += len(op)
                return op
        c = self.peek()
        raise InterpError(f"unknown operation name starting with {c!r}" if c.isalpha() else "unknown operation")

    def unary(self) -> str:
        for name in _UNARY:
            if self.startswith(name):
                break
        else:
            raise InterpError(f"unknown word where unary operation could be: {self.text[self.pos:self.pos + 8]!r}")
        self.pos += len(name)
        if self.peek() != "[":
            raise InterpError("left bracket missing after unary operation name")
        if name == "exists":
            self.pos += 1
            if self.peek() != "#":
                raise InterpError("expected # reading parameter")
            self.pos += 1
            if self.peek() != "<":
                raise InterpError("EXISTS takes a named parameter")
            pname = self.name()
            if self.peek() != "]":
                raise InterpError("expected ] reading bracketed parameter")
            self.pos += 1
            return f"C.exists({pname!r})"
        arg = self.expression()
        if name == "atan":
            if self.peek() != "/":
                raise InterpError("slash missing after first atan argument")
            self.pos += 1
            if self.peek() != "[":
                raise InterpError("left bracket missing after slash with atan")
            return f"_f(_atan({arg}, {self.expression()}))"
        return f"_f(_{name}({arg}))"

    def name(self) -> str:
        """`<name>` -> name (the '<' at pos)."""
        end = self.text.find(">", self.pos + 1)
        if end < 0:
            raise InterpError("named parameter not terminated")
        name = self.text[self.pos + 1:end]
        self.pos = end + 1
        return name

    def parameter(self) -> str:
        """`#...` read as a value."""
        self.pos += 1
        if self.peek() == "<":
            return f"C.named({self.name()!r})"
        index = self.value()
        try:
            const = float(index)
        except ValueError:
            return f"C.numbered({index})"
        return f"C.numbered({const!r})"



def compile_value(code: str):
    """A float when `code` (from Reader.value) reads no parameter and evaluates without error, else a
    function C -> float (errors then surface when the line runs, as LinuxCNC reads a line only when it
    executes it)."""
    fn = eval(f"lambda C: {code}", dict(NAMESPACE))
    if "C." not in code:
        try:
            return fn(None)
        except InterpError:
            pass
    return fn


def as_int(value: float, what: str = "integer") -> int:
    """LinuxCNC's read_integer_value: within 0.0001 of an integer."""
    n = math.floor(value)
    if value - n > 0.9999:
        return int(math.ceil(value))
    if value - n > 0.0001:
        raise InterpError(f"non-integer value for {what}")
    return int(n)
