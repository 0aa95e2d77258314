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
from feedlog.toolpath.limits import MAX_WORD, out_of_range, sci

_LF = 10
_OPEN, _CLOSE, _SEMI, _PERCENT, _SLASH = ord("("), ord(")"), ord(";"), ord("%"), ord("/")
_A, _Z, _D0 = ord("A"), ord("Z"), ord("0")
_DOT, _PLUS, _MINUS = ord("."), ord("+"), ord("-")
_COMMENT = re.compile(rb"\(([^()\n]*)\)|;([^\n]*)")
_BLANKS = b" \t\r\v\f"
_MAX_DIGITS = 15  # exact integer mantissa in float64; longer numbers take the slow path
_MAX_WIDTH = 20
_NUMBER = re.compile(r"[-+]?([0-9]+\.?[0-9]*|\.[0-9]+)")
# byte classes; number characters are the classes <= _SIGN, special characters >= _PCT_C
_DIGIT, _DOTC, _SIGN, _LETTER, _NEWLINE, _PCT_C, _SLASH_C, _OTHER, _END = 1, 2, 3, 4, 5, 6, 7, 8, 9
_CLASS = np.full(256, _OTHER, dtype=np.uint8)
_CLASS[_LF] = _NEWLINE
_CLASS[_PERCENT] = _PCT_C
_CLASS[_SLASH] = _SLASH_C
_CLASS[_A:_Z + 1] = _LETTER
_CLASS[_D0:_D0 + 10] = _DIGIT
_CLASS[_DOT] = _DOTC
_CLASS[[_PLUS, _MINUS]] = _SIGN
_POW10 = 10.0 ** np.arange(64)
_UPPER = bytes.maketrans(bytes(range(ord("a"), ord("z") + 1)), bytes(range(_A, _Z + 1)))
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
    comment_lines: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # sorted, unique
    comment_text: pa.Array = field(default_factory=lambda: pa.array([], pa.string()))  # one per line
    percent: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # lines holding `%`
    block_delete: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    unsupported: list[tuple[int, str, str]] = field(default_factory=list)  # (line index, code, why)


def lex(text: str, *, file: str, lenient: bool = False, first_line: int = 0) -> Tokens:
    """Split `text` into words. Malformed text raises ProgramError; unsupported constructs raise
    too unless `lenient`, which lists them in `Tokens.unsupported` and skips their line. Line
    indices are within `text`; `first_line` (0-based, in the file) only numbers the error messages."""
    data = text.encode("utf-8", errors="surrogateescape")
    source_lines: list[str] = []

    def line_text(i: int) -> str:
        if not source_lines:
            source_lines.extend(text.split("\n"))
        return source_lines[int(i)].strip()

    def fail(i: int, message: str, code: str | None = None) -> ProgramError:
        return ProgramError(message, file=file, line=int(i) + 1 + first_line, code=code or line_text(i)[:40])

    data, comment_lines, comment_text = _strip_comments(data)

    # -- code: upper case, no blanks; lines keep their newline ------------------------------------
    b = np.frombuffer(data.translate(_UPPER, _BLANKS), dtype=np.uint8)
    nl = np.flatnonzero(b == _LF)
    n_lines = len(nl) + 1
    line_start = np.r_[0, nl + 1]
    code_len = np.r_[nl, len(b)] - line_start
    has_code = code_len > 0
    has_code[comment_lines] = True
    rows = np.flatnonzero(has_code)
    # number characters: + - . 0-9 (bytes 43..57 except , and /)
    is_num = (b - np.uint8(_PLUS) <= _D0 + 9 - _PLUS) & (b != ord(",")) & (b != _SLASH)
    bnd = np.flatnonzero(~is_num)      # letters, newlines and special characters end a number
    digits = b[is_num]
    del is_num
    bcls = _CLASS[b[bnd]]
    unsupported: list[tuple[int, str, str]] = []
    skip: list[int] = []

    # rare characters: `%` lines, `/` (block delete) at the start of a line, anything else
    special = bnd[bcls >= _PCT_C]
    pct_lines = bd_lines = np.zeros(0, dtype=np.int64)
    if len(special):
        s_line = np.searchsorted(nl, special)
        s_cls = _CLASS[b[special]]
        pct_lines = np.unique(s_line[s_cls == _PCT_C])
        if (code_len[pct_lines] != 1).any():
            raise fail(pct_lines[code_len[pct_lines] != 1][0], "'%' must stand alone on its line", "%")
        slash = s_cls == _SLASH_C
        at_start = special == line_start[s_line]
        bd_lines = s_line[slash & at_start]
        other = (s_cls == _OTHER) | (slash & ~at_start)
        for i in np.unique(s_line[other]).tolist():
            code = b[special[other & (s_line == i)][0]]
            char = chr(code) if code < 128 else "non-ASCII"
            why = _WHY.get(char, f"character {char!r}")
            if char in "()" or not lenient:
                raise fail(i, f"unsupported syntax: {why}" if char not in "()" else why)
            unsupported.append((i, line_text(i)[:40], f"unsupported syntax: {why}"))
            skip.append(i)

    # -- words: every letter starts one; its number is the run of number characters after it ----
    k_letter = np.flatnonzero(bcls == _LETTER)
    wstart = bnd[k_letter]
    wend = np.r_[bnd, len(b)][k_letter + 1]
    length = wend - wstart - 1
    if length.sum() != len(b) - len(bnd):  # number characters that follow no letter
        starts = np.r_[-1, bnd]
        runs = np.r_[bnd, len(b)] - starts - 1
        lonely = np.ones(len(starts), dtype=bool)
        lonely[k_letter + 1] = False
        lines = np.setdiff1d(np.searchsorted(nl, starts[lonely & (runs > 0)] + 1), skip)
        if len(lines):
            raise fail(lines[0], "number without a word letter")
        # only on skipped lines (lenient): keep just the words' own number characters
        first = np.cumsum(length) - length
        digits = b[np.repeat(wstart + 1 - first, length) + np.arange(int(length.sum()))]
    is_nl = bcls == _NEWLINE
    wline = (np.cumsum(is_nl) - is_nl)[k_letter]  # newlines before each letter
    wletter = (b[wstart] - _A).astype(np.uint8)
    values = _numbers(digits, length, b, wstart)
    del digits
    bad_value = np.isnan(values)

    flow = np.zeros(0, dtype=np.int64)
    if bad_value.any():
        # O-word control flow (o100 sub, o100 if ...) shows up as letters without numbers after an O
        # word with one (a bare O, as in "X4O" for X40, is a malformed word)
        o_lines = np.unique(wline[(wletter == ord("O") - _A) & ~bad_value])
        flow = np.setdiff1d(np.intersect1d(o_lines, wline[bad_value]), skip)
        for i in flow.tolist():
            if not lenient:
                raise fail(i, "unsupported O-word control flow")
            unsupported.append((i, line_text(i)[:40], "unsupported O-word control flow"))
        bad_lines = np.setdiff1d(np.unique(wline[bad_value]), np.r_[flow, skip])
        if len(bad_lines):
            i = bad_lines[0]
            k = np.flatnonzero(bad_value & (wline == i))[0]
            word = bytes(b[wstart[k]:wend[k]]).decode("ascii", "replace")
            oh = "; the letter O where a zero was meant?" if word[:1] in "Oo" else ""
            raise fail(i, f"malformed word (a letter needs a decimal number{oh})", word)
    big = out_of_range(values, MAX_WORD)
    if big.any():
        big &= ~np.isin(wline, np.r_[flow, skip])
    if big.any():
        k = int(np.flatnonzero(big)[0])
        word = bytes(b[wstart[k]:wend[k]]).decode("ascii", "replace")
        raise fail(wline[k], f"number out of range (beyond +-{sci(MAX_WORD)})", word[:24] + "..." * (len(word) > 24))
    if len(flow) or skip:
        keep = ~np.isin(wline, np.r_[flow, skip])
        wline, wletter, values = wline[keep], wletter[keep], values[keep]

    return Tokens(n_lines=n_lines, rows=rows, line=wline.astype(np.int64), letter=wletter,
                  value=values, comment_lines=comment_lines, comment_text=comment_text, percent=pct_lines.astype(np.int64),
                  block_delete=bd_lines.astype(np.int64), unsupported=unsupported)


def _numbers(digits: np.ndarray, length: np.ndarray, b: np.ndarray, wstart: np.ndarray) -> np.ndarray:
    """The number after each word letter as float64 (NaN where malformed).

    Fast path: `digits` holds all number characters in order, word after word (`length` each), so
    it is an Arrow string array without copying per word, and Arrow's C++ cast parses them all. It
    refuses the whole array if one is malformed; then the numpy path below finds which.
    """
    n_words = len(wstart)
    if not n_words:
        return np.zeros(0)
    offsets = np.zeros(n_words + 1, dtype=np.int32)
    np.cumsum(length, out=offsets[1:])
    arr = pa.StringArray.from_buffers(n_words, pa.py_buffer(offsets), pa.py_buffer(np.ascontiguousarray(digits)))
    try:
        return pc.cast(arr, pa.float64()).to_numpy(zero_copy_only=False)
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
        return _parse_numbers(b, _CLASS[b], wstart, length)


def _strip_comments(data: bytes) -> tuple[bytes, np.ndarray, pa.Array]:
    """Blank out comments (same length, so positions and lines stay). Returns the blanked text, the
    lines holding comments (sorted) and their comment text (several on a line joined by a space).

    Programs whose comments are all `( ... )`, one or more per line, are handled with array
    operations; `;` comments or malformed parentheses go line by line (bytes.find, then a regex on
    the lines that hold a mark)."""
    if b"(" not in data and b";" not in data and b")" not in data:
        return data, np.zeros(0, np.int64), pa.array([], pa.string())
    if b";" not in data:
        fast = _paren_comments(data)
        if fast is not None:
            return fast
    marks = (b"(", b";", b")")
    nxt = [data.find(m) for m in marks]
    comments: dict[int, str] = {}
    pieces: list[bytes] = []
    cursor = line_no = counted_to = 0
    while True:
        live = [p for p in nxt if p >= 0]
        if not live:
            break
        pos = min(live)
        lo = data.rfind(b"\n", 0, pos) + 1
        hi = data.find(b"\n", pos)
        hi = len(data) if hi < 0 else hi
        line_no += data.count(b"\n", counted_to, lo)
        counted_to = lo
        for m in _COMMENT.finditer(data, lo, hi):
            raw = m.group(1) if m.group(1) is not None else m.group(2)
            piece = raw.decode("utf-8", "replace").strip()
            comments[line_no] = f"{comments[line_no]} {piece}" if line_no in comments else piece
            pieces += [data[cursor:m.start()], b" " * (m.end() - m.start())]
            cursor = m.end()
        nxt = [p if p < 0 or p >= hi else data.find(mark, hi) for p, mark in zip(nxt, marks)]
    pieces.append(data[cursor:])
    lines = np.fromiter(comments.keys(), dtype=np.int64, count=len(comments))
    return b"".join(pieces), lines, pa.array(list(comments.values()), pa.string())


def _paren_comments(data: bytes) -> tuple[bytes, np.ndarray, pa.Array] | None:
    """Array path for `( ... )` comments: None unless every `(` has its `)` on the same line with no
    parenthesis in between (anything else goes the line-by-line way, which reports errors)."""
    src = np.frombuffer(data, dtype=np.uint8)
    opens, closes = np.flatnonzero(src == _OPEN), np.flatnonzero(src == _CLOSE)
    if len(opens) != len(closes) or not (opens < closes).all() or not (closes[:-1] < opens[1:]).all():
        return None
    nl = np.flatnonzero(src == _LF)
    line = np.searchsorted(nl, opens)
    if not (np.searchsorted(nl, closes) == line).all():
        return None
    length = closes - opens - 1
    delta = np.zeros(len(src) + 1, dtype=np.int8)
    delta[opens + 1] += 1
    delta[closes] -= 1
    inside = np.cumsum(delta[:-1], dtype=np.int8) > 0
    offsets = np.zeros(len(opens) + 1, dtype=np.int32)
    np.cumsum(length, out=offsets[1:])
    text = pa.StringArray.from_buffers(len(opens), pa.py_buffer(offsets), pa.py_buffer(src[inside].tobytes()))
    try:
        text.validate(full=True)  # UTF-8 check; comments could cut a character in odd input
    except pa.ArrowInvalid:
        return None
    text = pc.utf8_trim_whitespace(text)
    if len(line) > 1 and (line[1:] == line[:-1]).any():  # several comments on a line: join them
        joined: dict[int, str] = {}
        for i, piece in zip(line.tolist(), text.to_pylist()):
            joined[i] = f"{joined[i]} {piece}" if i in joined else piece
        line = np.fromiter(joined.keys(), dtype=np.int64, count=len(joined))
        text = pa.array(list(joined.values()), pa.string())
    blanked = src.copy()
    blanked[inside] = ord(" ")
    blanked[opens] = blanked[closes] = ord(" ")
    return blanked.tobytes(), line.astype(np.int64), text


def _parse_numbers(cb: np.ndarray, cls: np.ndarray, wstart: np.ndarray, length: np.ndarray) -> np.ndarray:
    """The number after each word letter, `[+-]digits[.digits]`, as float64; NaN where malformed.

    Horner's scheme over the words' character columns gives an exact integer mantissa and the count
    of fraction digits; one division then gives the same correctly rounded value as float() for up
    to 15 significant digits. Longer numbers go through float().
    """
    nw, n = len(wstart), len(cb)
    out = np.full(nw, np.nan)
    if not nw:
        return out
    width = int(min(max(length.max(), 1), _MAX_WIDTH))
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
