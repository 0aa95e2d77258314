"""G-code words -> one row per program line: codes checked, modal G groups, one value per letter.

The lexer (toolpath.lexer) yields (line, letter, value) words. Here G and M codes are checked against
what feedlog reads (unsupported ones raise, or in lenient mode are listed and skipped with the
geometry words of their line), G codes go to their modal group column, and every other letter to a
rows x letters matrix `W` (NaN where a line has no such word). The parser (toolpath.parser) turns
these into the block table.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.errors import ProgramError
from feedlog.toolpath.lexer import Tokens, lex
from feedlog.toolpath.offsets import G10
from feedlog.toolpath.program import Unsupported

# G code (x10, so G90.1 -> 901) -> modal group. Codes not listed are unsupported.
G_GROUPS: dict[int, str] = {
    0: "motion", 10: "motion", 20: "motion", 30: "motion", 800: "motion",
    170: "plane", 180: "plane", 190: "plane",
    200: "units", 210: "units",
    900: "distance", 910: "distance",
    901: "arc_distance", 911: "arc_distance",
    930: "feed_mode", 940: "feed_mode",
    610: "path", 611: "path", 640: "path",
    # non-modal (RS274/NGC group 0): dwell, coordinate system data, axis offsets
    40: "nonmodal", 100: "nonmodal", 920: "nonmodal", 921: "nonmodal",
    # work coordinate system selection (toolpath.offsets)
    540: "coords", 550: "coords", 560: "coords", 570: "coords", 580: "coords", 590: "coords",
    591: "coords", 592: "coords", 593: "coords",
    # accepted, no effect on the programmed path in program coordinates
    400: "cutter_comp", 430: "tool_length", 490: "tool_length",
    970: "spindle_mode", 980: "retract", 990: "retract",
}
_GROUP_NAMES = sorted(set(G_GROUPS.values()))
_GROUP_LUT = np.full(1000, -1, dtype=np.int64)
for _g, _name in G_GROUPS.items():
    _GROUP_LUT[_g] = _GROUP_NAMES.index(_name)
# M codes kept as block metadata: program stop/end, spindle, tool change, coolant, overrides, pallet,
# digital/analog outputs, user M100-M199.
M_CODES = frozenset([0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 30, 48, 49, 50, 51, 52, 53, 60, 61,
                     62, 63, 64, 65, 66, 67, 68, 70, 71, 72, 73] + list(range(100, 200)))
PROGRAM_END = (2, 30)
STOP_M = (0, 1, 2, 6, 30, 60)  # the machine comes to rest: program stop/end, tool change, pallet
LETTERS = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
L = {ch: i for i, ch in enumerate(LETTERS)}
ACCEPTED_LETTERS = set("ABCFGHIJKMNOPQRSTXYZ")
_ACCEPTED_LUT = np.array([c in ACCEPTED_LETTERS for c in LETTERS])
_GEO_LUT = np.array([c in "XYZABCIJKRPQL" for c in LETTERS])
_M_LUT = np.array([m in M_CODES for m in range(200)] + [False])


class _Rows:
    """Words scattered into a per-row table, with strict/lenient reporting."""

    def __init__(self, tok: Tokens, file: str, lenient: bool, first_line: int = 0) -> None:
        self.tok, self.file, self.lenient, self.first_line = tok, file, lenient, first_line
        self.rows = tok.rows
        self.n = len(tok.rows)
        row_of_line = np.full(tok.n_lines, -1, dtype=np.int64)
        row_of_line[tok.rows] = np.arange(self.n)
        self.row_of = row_of_line[tok.line]
        self.unsupported: list[Unsupported] = [Unsupported(i + 1 + first_line, c, r) for i, c, r in tok.unsupported]
        self.dirty_rows = np.zeros(self.n, dtype=bool)  # rows with a skipped code (lenient)

    def error(self, row: int, message: str, code: str) -> ProgramError:
        return ProgramError(message, file=self.file, line=int(self.rows[row]) + 1 + self.first_line, code=code)

    def reject(self, mask: np.ndarray, message: str, code_of, *, taints_line: bool = False) -> np.ndarray:
        """Words in `mask` are unsupported: raise on the first, or (lenient) list and drop them.
        `taints_line`: the code could change the meaning of the line's other words (a G code), so
        the line's geometry words are dropped too."""
        if not mask.any():
            return np.ones(len(mask), dtype=bool)
        hits = np.flatnonzero(mask)
        if not self.lenient:
            k = hits[np.argmin(self.row_of[hits])]
            raise self.error(self.row_of[k], message, code_of(k))
        for k in hits:
            self.unsupported.append(Unsupported(int(self.rows[self.row_of[k]]) + 1 + self.first_line, code_of(k),
                                                message))
        if taints_line:
            self.dirty_rows[self.row_of[hits]] = True
        return ~mask


def _check_g10(letter: np.ndarray, value: np.ndarray, row_of: np.ndarray, g10: np.ndarray,
               n: int) -> tuple[np.ndarray, object]:
    """G10 words that are not `G10 L2|L20 Pn` (n = 0..9) without R: the tool table (L1, L10, L11),
    rotation (R) and the rest stay unsupported. Returns the mask over words and a code function."""
    at = np.flatnonzero(g10 == G10)
    bad = np.zeros(len(letter), dtype=bool)
    if not len(at):
        return bad, None
    per_row = {}
    for ch in "LPR":
        col = np.full(n, np.nan)
        sel = letter == L[ch]
        col[row_of[sel]] = value[sel]
        per_row[ch] = col[row_of[at]]
    lw, pw, rw = per_row["L"], per_row["P"], per_row["R"]
    ok = np.isin(lw, (2, 20)) & (pw >= 0) & (pw <= 9) & (pw == np.rint(pw)) & np.isnan(rw)
    bad[at] = ~ok
    words = {int(k): " ".join(["G10"] + [_word(L[ch], float(v)) for ch, v in zip("LPR", (lw[i], pw[i], rw[i]))
                                         if not np.isnan(v)])
             for i, k in enumerate(at)}
    return bad, words.__getitem__


def _word(letter: int, value: float) -> str:
    text = f"{value:.4f}".rstrip("0").rstrip(".")
    return f"{LETTERS[letter]}{text}"

@dataclass
class Words:
    """The rows of a chunk of program text: `W[S[letter], row]` word values (NaN: absent), `has` where
    present, `groups[name][row]` the G code (x 10) of each modal group given on the row (-1: none),
    M codes (`m_rows`, `m_codes`), the tokens (`tok`) and the row bookkeeping (`R`)."""

    R: _Rows
    tok: Tokens
    W: np.ndarray
    has: np.ndarray
    S: dict
    groups: dict
    m_rows: np.ndarray
    m_codes: np.ndarray


def scatter(text: str, *, file: str, lenient: bool, first_line: int = 0) -> Words:
    """The words of `text` (whole lines) checked and scattered into one row per line that holds
    anything; unsupported codes raise (or, lenient, are listed and skipped)."""
    tok = lex(text, file=file, lenient=lenient, first_line=first_line)
    R = _Rows(tok, file, lenient, first_line)
    n = R.n
    letter, value, row_of = tok.letter, tok.value, R.row_of
    code_of = lambda k: _word(int(letter[k]), float(value[k]))  # noqa: E731

    is_g, is_m = letter == L["G"], letter == L["M"]
    g_idx, m_idx = np.flatnonzero(is_g), np.flatnonzero(is_m)
    g10f = np.rint(value[g_idx] * 10)
    g_ok = (g10f >= 0) & (g10f < 1000) & (np.abs(value[g_idx] * 10 - g10f) < 1e-6)
    g_ok[g_ok] = _GROUP_LUT[g10f[g_ok].astype(np.int64)] >= 0
    mf = value[m_idx]
    m_ok = (mf >= 0) & (mf < 200) & (mf == np.rint(mf))
    m_ok[m_ok] = _M_LUT[mf[m_ok].astype(np.int64)]
    g10 = np.full(len(letter), -1, dtype=np.int16)  # G code x 10 (G90.1 -> 901); -1 elsewhere
    g10[g_idx] = np.where(g_ok, g10f, -1)
    m_int = np.full(len(letter), -1, dtype=np.int16)
    m_int[m_idx] = np.where(m_ok, mf, -1)
    bad_letter = ~_ACCEPTED_LUT[letter]
    has_g10 = bool((g10 == G10).any())
    if not (g_ok.all() and m_ok.all() and not bad_letter.any()) or has_g10:
        bad_g = np.zeros(len(letter), dtype=bool)
        bad_g[g_idx[~g_ok]] = True
        bad_m = np.zeros(len(letter), dtype=bool)
        bad_m[m_idx[~m_ok]] = True
        bad_g10, g10_code = _check_g10(letter, value, row_of, g10, n)
        if has_g10:  # L words belong to G10
            bad_letter &= ~((letter == L["L"]) & np.isin(row_of, row_of[g10 == G10]))
        checks = [(bad_g, "unsupported G code", True, code_of),
                  (bad_g10, "unsupported G10 form (supported: G10 L2 or L20 with P0-P9, no R)", True,
                   g10_code),
                  (bad_letter, "unsupported word", False, code_of),
                  (bad_m, "unsupported M code", False, code_of)]
        if not lenient:  # report the earliest line first
            firsts = [(int(row_of[c[0]].min()), i) for i, c in enumerate(checks) if c[0].any()]
            checks = [checks[i] for _, i in sorted(firsts)]
        keep = np.ones(len(letter), dtype=bool)
        for mask, message, taints, code_fn in checks:
            keep &= R.reject(mask & keep, message, code_fn, taints_line=taints)
        if R.dirty_rows.any():  # a line with a skipped G code: drop its geometry words too
            keep &= ~(_GEO_LUT[letter] & R.dirty_rows[row_of])
        letter, value, row_of, g10, m_int = letter[keep], value[keep], row_of[keep], g10[keep], m_int[keep]
        is_g, is_m = letter == L["G"], letter == L["M"]
        code_of = lambda k: _word(int(letter[k]), float(value[k]))  # noqa: E731

    # -- modal groups of G codes -----------------------------------------------------------------
    g_rows, g_codes = row_of[is_g], g10[is_g]
    group = _GROUP_LUT[g_codes]
    groups: dict[str, np.ndarray] = {}
    for gi, gname in enumerate(_GROUP_NAMES):
        sel = group == gi
        col = np.full(n, -1, dtype=np.int16)
        if sel.any():
            counts = np.bincount(g_rows[sel], minlength=n)
            if counts.max() > 1:
                r = int(np.flatnonzero(counts > 1)[0])
                codes = " ".join(f"G{c / 10:g}" for c in g_codes[sel][g_rows[sel] == r])
                raise R.error(r, "two G codes of the same modal group on one line", codes)
            col[g_rows[sel]] = g_codes[sel]
        groups[gname] = col

    # -- other words: one per letter and line ------------------------------------------------------
    other = ~is_g & ~is_m
    # letter-major, one contiguous row per letter that occurs; S maps a letter to its row (letters that
    # never occur share the last row, all NaN)
    present = np.flatnonzero(np.bincount(letter[other], minlength=26))
    slot = np.full(26, len(present), dtype=np.int64)
    slot[present] = np.arange(len(present))
    S = {ch: int(slot[i]) for i, ch in enumerate(LETTERS)}
    W = np.full((len(present) + 1, n), np.nan)
    W[slot[letter[other]], row_of[other]] = value[other]
    has = ~np.isnan(W)
    if np.count_nonzero(has) < np.count_nonzero(other):  # a letter twice on one line
        counts = np.bincount(row_of[other] * 26 + letter[other], minlength=n * 26)
        k = int(np.flatnonzero(counts > 1)[0])
        raise R.error(k // 26, "word repeated on one line", LETTERS[k % 26])

    m_rows, m_codes = row_of[is_m], m_int[is_m]
    # the word arrays are in W now: let them go (million-block programs)
    del letter, value, row_of, g10, m_int, is_g, is_m, other
    tok.line = tok.letter = tok.value = R.row_of = None
    return Words(R=R, tok=tok, W=W, has=has, S=S, groups=groups, m_rows=m_rows, m_codes=m_codes)
