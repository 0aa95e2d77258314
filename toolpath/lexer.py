"""G-code text -> a flat token table, in one vectorised pass over the bytes of the whole program.

A per-line Python loop with a few regex calls manages ~50-100 k lines/s; here every step is a numpy
operation over the program's bytes: blanks go (bytes.translate), every letter starts a word, and all
word values are converted at once (integer mantissa per word from its digits, then one division).
Only rare constructs (comments, error reporting) touch Python per item.

Grammar accepted (RS274/NGC as CAM posts and LinuxCNC users write it): words are a letter followed by
a decimal number (`G1`, `X-1.5`, `F.5`), case-insensitive, spaces anywhere between; comments are
`( ... )` (not nested, not spanning lines) and `;` to the end of the line; `%` lines delimit the
program; a leading `/` marks an optional (block-delete) line. Anything else (parameters `#1`,
expressions `[...]`, O-word control flow) is reported as unsupported, never guessed at.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from feedlog.errors import ProgramError

_LF = 10
_OPEN, _CLOSE, _SEMI, _PERCENT, _SLASH = ord("("), ord(")"), ord(";"), ord("%"), ord("/")
_A, _Z, _D0 = ord("A"), ord("Z"), ord("0")
_DOT, _PLUS, _MINUS = ord("."), ord("+"), ord("-")
_COMMENT = re.compile(rb"\(([^()\n]*)\)|;([^\n]*)")
_BLANKS = b" \t\r\v\f"
_MAX_DIGITS = 15  # exact integer mantissa in float64; longer numbers take the slow path
_MAX_WIDTH = 20
_NUMBER = re.compile(r"[-+]?([0-9]+\.?[0-9]*|\.[0-9]+)")
# byte classes
_OTHER, _LETTER, _DIGIT, _DOTC, _SIGN, _END = 0, 1, 2, 3, 4, 5
_CLASS = np.zeros(256, dtype=np.uint8)
_CLASS[_A:_Z + 1] = _LETTER
_CLASS[_D0:_D0 + 10] = _DIGIT
_CLASS[_DOT] = _DOTC
_CLASS[[_PLUS, _MINUS]] = _SIGN
_POW10 = 10.0 ** np.arange(64)
_WHY = {"#": "parameters (#)", "[": "expressions ([...])", "]": "expressions ([...])",
        "<": "named O-words", "=": "parameter assignment", "(": "unbalanced or nested comment",
        ")": "unbalanced or nested comment"}


@dataclass
class Tokens:
    """The words of a program. Line indices are 0-based; `line` columns elsewhere are 1-based."""

    n_lines: int
    rows: np.ndarray          # 0-based indices of the lines that hold anything (code or comment)
    line: np.ndarray          # int64, line index of each word
    letter: np.ndarray        # uint8, 0..25 for A..Z
    value: np.ndarray         # float64
    comments: dict[int, str] = field(default_factory=dict)   # line index -> comment text
    percent: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # lines holding `%`
    block_delete: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    unsupported: list[tuple[int, str, str]] = field(default_factory=list)  # (line index, code, why)


def lex(text: str, *, file: str, lenient: bool = False) -> Tokens:
    """Split `text` into words. Malformed text raises ProgramError; unsupported constructs raise
    too unless `lenient`, which lists them in `Tokens.unsupported` and skips their line."""
    data = text.encode("utf-8", errors="surrogateescape")
    source_lines: list[str] = []

    def line_text(i: int) -> str:
        if not source_lines:
            source_lines.extend(text.split("\n"))
        return source_lines[int(i)].strip()

    def fail(i: int, message: str, code: str | None = None) -> ProgramError:
        return ProgramError(message, file=file, line=int(i) + 1, code=code or line_text(i)[:40])

    # -- comments (per comment, only on the lines that hold one): blank them out, keep their text --
    comments: dict[int, str] = {}
    if b"(" in data or b";" in data or b")" in data:
        src = np.frombuffer(data, dtype=np.uint8)
        nl_src = np.flatnonzero(src == _LF)
        marks = np.flatnonzero((src == _OPEN) | (src == _SEMI) | (src == _CLOSE))
        line_ends = np.r_[nl_src, len(src)]
        blanked = bytearray(data)
        for i in np.unique(np.searchsorted(nl_src, marks)).tolist():
            lo = int(nl_src[i - 1]) + 1 if i else 0
            for m in _COMMENT.finditer(data, lo, int(line_ends[i])):
                raw = m.group(1) if m.group(1) is not None else m.group(2)
                piece = raw.decode("utf-8", "replace").strip()
                comments[i] = f"{comments[i]} {piece}" if i in comments else piece
                blanked[m.start():m.end()] = b" " * (m.end() - m.start())
        data = bytes(blanked)

    # -- code: upper case, no blanks; lines keep their newline ------------------------------------
    b = np.frombuffer(data.upper().translate(None, _BLANKS), dtype=np.uint8)
    nl = np.flatnonzero(b == _LF)
    n_lines = len(nl) + 1
    line_start = np.r_[0, nl + 1]
    code_len = np.r_[nl, len(b)] - line_start
    cb = b[b != _LF] if len(nl) else b
    cl = np.repeat(np.arange(n_lines, dtype=np.int32), code_len)
    has_code = code_len > 0
    if comments:
        has_code[list(comments)] = True
    rows = np.flatnonzero(has_code)

    # `%` lines, and `/` (block delete) at the start of a line
    pct = cb == _PERCENT
    pct_lines = np.unique(cl[pct])
    if len(pct_lines) and (code_len[pct_lines] != 1).any():
        raise fail(pct_lines[code_len[pct_lines] != 1][0], "'%' must stand alone on its line", "%")
    starts_code = line_start - np.arange(n_lines)  # index of each line's first byte in cb
    bd_lines = np.flatnonzero((code_len > 0) & (cb[np.minimum(starts_code, len(cb) - 1)] == _SLASH)
                              if len(cb) else np.zeros(0, bool))
    if len(pct_lines) or len(bd_lines):
        drop = pct.copy()
        drop[starts_code[bd_lines]] = True
        cb, cl = cb[~drop], cl[~drop]

    cls = _CLASS[cb]
    unsupported: list[tuple[int, str, str]] = []
    other = cls == _OTHER
    if other.any():
        skip = []
        for i in np.unique(cl[other]):
            char = chr(cb[other & (cl == i)][0]) if cb[other & (cl == i)][0] < 128 else "non-ASCII"
            why = _WHY.get(char, f"character {char!r}")
            if char in "()" or not lenient:
                raise fail(i, f"unsupported syntax: {why}" if char not in "()" else why)
            unsupported.append((int(i), line_text(i)[:40], f"unsupported syntax: {why}"))
            skip.append(int(i))
        keep = ~np.isin(cl, skip)
        cb, cl, cls = cb[keep], cl[keep], cls[keep]

    # -- words: every letter starts one; its number runs to the next letter on the same line -----
    # -- words: every letter starts one; its number runs to the next letter ----------------------
    # (every line's code starts with a letter, so a number never runs into the next line)
    first = np.r_[0, np.flatnonzero(cl[1:] != cl[:-1]) + 1] if len(cl) else cl
    orphan = cls[first] != _LETTER
    if orphan.any():
        raise fail(cl[first[orphan][0]], "number without a word letter")
    wstart = np.flatnonzero(cls == _LETTER)
    wline = cl[wstart]
    wletter = (cb[wstart] - _A).astype(np.uint8)
    values = _numbers(cb, cls, wstart)
    bad_value = np.isnan(values)

    if bad_value.any():
        # O-word control flow (o100 sub, o100 if ...) shows up as letters without numbers
        o_lines = np.unique(wline[wletter == ord("O") - _A])
        flow = np.intersect1d(o_lines, wline[bad_value])
        for i in flow:
            if not lenient:
                raise fail(i, "unsupported O-word control flow")
            unsupported.append((int(i), line_text(i)[:40], "unsupported O-word control flow"))
        bad_lines = np.setdiff1d(np.unique(wline[bad_value]), flow)
        if len(bad_lines):
            i = bad_lines[0]
            k = np.flatnonzero(bad_value & (wline == i))[0]
            end = wstart[k + 1] if k + 1 < len(wstart) else len(cb)
            word = bytes(cb[wstart[k]:end]).decode("ascii", "replace")
            raise fail(i, "malformed word (a letter needs a decimal number)", word)
        keep = ~np.isin(wline, flow)
        wline, wletter, values = wline[keep], wletter[keep], values[keep]

    return Tokens(n_lines=n_lines, rows=rows, line=wline.astype(np.int64), letter=wletter,
                  value=values, comments=comments, percent=pct_lines.astype(np.int64),
                  block_delete=bd_lines.astype(np.int64), unsupported=unsupported)


def _numbers(cb: np.ndarray, cls: np.ndarray, wstart: np.ndarray) -> np.ndarray:
    """The number after each word letter as float64 (NaN where malformed).

    Fast path: the number characters already lie between the letters, so dropping the letters gives
    an Arrow string array without copying per word, and Arrow's C++ cast parses them all. It refuses
    the whole array if one is malformed; then the numpy path below finds which.
    """
    n_words = len(wstart)
    if not n_words:
        return np.zeros(0)
    length = np.r_[wstart[1:], len(cb)] - wstart - 1
    offsets = np.zeros(n_words + 1, dtype=np.int32)
    np.cumsum(length, out=offsets[1:])
    digits = np.ascontiguousarray(cb[cls != _LETTER])
    arr = pa.StringArray.from_buffers(n_words, pa.py_buffer(offsets), pa.py_buffer(digits))
    try:
        return pc.cast(arr, pa.float64()).to_numpy(zero_copy_only=False)
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
        return _parse_numbers(cb, cls, wstart)


def _parse_numbers(cb: np.ndarray, cls: np.ndarray, wstart: np.ndarray) -> np.ndarray:
    """The number after each word letter, `[+-]digits[.digits]`, as float64; NaN where malformed.

    Horner's scheme over the words' character columns gives an exact integer mantissa and the count
    of fraction digits; one division then gives the same correctly rounded value as float() for up
    to 15 significant digits. Longer numbers go through float().
    """
    nw, n = len(wstart), len(cb)
    out = np.full(nw, np.nan)
    if not nw:
        return out
    length = np.r_[wstart[1:], n] - wstart - 1
    width = int(min(length.max(), _MAX_WIDTH))
    mant = np.zeros(nw, dtype=np.int64)
    frac = np.zeros(nw, dtype=np.int64)
    n_digit = np.zeros(nw, dtype=np.int64)
    seen_dot = np.zeros(nw, dtype=bool)
    bad = length > _MAX_WIDTH
    neg = np.zeros(nw, dtype=bool)
    for j in range(width):
        at = np.minimum(wstart + 1 + j, n - 1)
        c = cb[at]
        k = np.where(length > j, _CLASS[c], _END)
        digit = k == _DIGIT
        mant = np.where(digit, mant * 10 + (c.astype(np.int64) - _D0), mant)
        frac += digit & seen_dot
        n_digit += digit
        dot = k == _DOTC
        bad |= dot & seen_dot
        seen_dot |= dot
        sign = k == _SIGN
        if j == 0:
            neg = sign & (c == _MINUS)
        else:
            bad |= sign
        bad |= (k == _OTHER) | (k == _LETTER)
    bad |= n_digit == 0
    slow = ~bad & (n_digit > _MAX_DIGITS)
    fast = ~bad & ~slow
    val = mant / _POW10[np.minimum(frac, len(_POW10) - 1)]
    out[fast] = np.where(neg, -val, val)[fast]
    for k in np.flatnonzero(slow | ((length > _MAX_WIDTH) & (n_digit > 0))):
        try:  # rare: very long numbers, exact via float()
            text = bytes(cb[wstart[k] + 1:wstart[k] + 1 + length[k]]).decode("ascii")
            out[k] = float(text) if _NUMBER.fullmatch(text) else np.nan
        except (UnicodeDecodeError, ValueError):
            out[k] = np.nan
    return out
