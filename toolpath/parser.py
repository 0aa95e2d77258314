"""RS274/NGC part program -> block table, vectorised.

The lexer yields (line, letter, value) words. Here they are scattered into one row per source line,
modal state (units, distance mode, plane, motion mode, feed, path mode, ...) is propagated with a
vectorised forward fill, absolute positions come from a cumulative sum of incremental moves reset at
every absolute word, and arcs are resolved for all rows at once (toolpath.arcwords).

Order of execution within a line follows RS274/NGC: feed mode and F, S, M codes, dwell, plane, units,
path control, distance modes, then motion; so `G20 G91 G1 X1 F10` moves 25.4 mm at 254 mm/min.

Tool orientation vectors: on a line in linear or rapid mode (G0/G1), I J K are the tool orientation
vector of five-axis CL data (normalised; modal once given); in arc mode (G2/G3) they are the arc
centre. LinuxCNC itself rejects I/J/K on G0/G1, so the two meanings never collide.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa

from feedlog.errors import ProgramError
from feedlog.toolpath.arcwords import ArcWords, resolve_arcs
from feedlog.toolpath.lexer import Tokens, lex
from feedlog.toolpath.limits import check_positions, check_run_time
from feedlog.toolpath.offsets import G10, G92_1
from feedlog.toolpath.positions import AXIS_LETTERS, SYSTEM_LUT, ffill, offset_positions, positions
from feedlog.toolpath.program import Program, Unsupported
from feedlog.toolpath.source import read_source
from feedlog.toolpath.schema import (ARC_CCW, ARC_CW, BLOCK_COLUMNS, CONTINUOUS, DWELL, END_COLUMNS,
                                     EXACT_PATH, EXACT_STOP, KINDS, LINEAR, NONE, OFFSET_COLUMNS, PATH_MODES,
                                     RAPID, START_COLUMNS)
from feedlog.units import MM_PER_INCH

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
DEFAULTS = {"motion": -1, "plane": 170, "units": 210, "distance": 900, "arc_distance": 911,
            "feed_mode": 940, "path": 640}
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
PATH_MODE_OF = {610: EXACT_PATH, 611: EXACT_STOP, 640: CONTINUOUS}
KIND_OF_MOTION = {0: RAPID, 10: LINEAR, 20: ARC_CW, 30: ARC_CCW}


def _strings(n: int, rows=None, values=None, *, fill: str = "") -> pd.api.extensions.ExtensionArray:
    """A pandas "string" column of `fill` with `values` at `rows`, built in Arrow (no per-row objects)."""
    codes = np.zeros(n, dtype=np.int32)
    dictionary = [fill]
    if values is not None and len(values):
        uniq, inverse = np.unique(np.asarray(values, dtype=object).astype(str), return_inverse=True)
        dictionary += uniq.tolist()
        codes[rows] = inverse + 1
    arr = pa.DictionaryArray.from_arrays(pa.array(codes), pa.array(dictionary, pa.string()))
    return pd.array(arr.cast(pa.string()), dtype="string")


class _Rows:
    """Words scattered into a per-row table, with strict/lenient reporting."""

    def __init__(self, tok: Tokens, file: str, lenient: bool) -> None:
        self.tok, self.file, self.lenient = tok, file, lenient
        self.rows = tok.rows
        self.n = len(tok.rows)
        row_of_line = np.full(tok.n_lines, -1, dtype=np.int64)
        row_of_line[tok.rows] = np.arange(self.n)
        self.row_of = row_of_line[tok.line]
        self.unsupported: list[Unsupported] = [Unsupported(i + 1, c, r) for i, c, r in tok.unsupported]
        self.dirty_rows = np.zeros(self.n, dtype=bool)  # rows with a skipped code (lenient)

    def error(self, row: int, message: str, code: str) -> ProgramError:
        return ProgramError(message, file=self.file, line=int(self.rows[row]) + 1, code=code)

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
            self.unsupported.append(Unsupported(int(self.rows[self.row_of[k]]) + 1, code_of(k), message))
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


def parse_program(source: str | Path, *, lenient: bool = False, name: str | None = None) -> Program:
    """Parse a part program (a path, or G-code text) into a Program with its block table.

    Unsupported codes raise ProgramError naming file, line and code; with `lenient=True` they are
    listed in `Program.unsupported` (and a warning) and skipped. Malformed text always raises.
    """
    text, path, file = read_source(source, name)
    tok = lex(text, file=file, lenient=lenient)
    R = _Rows(tok, file, lenient)
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

    # -- modal state -------------------------------------------------------------------------------
    modal = {g: ffill(groups[g], groups[g] >= 0, DEFAULTS[g]) for g in DEFAULTS}
    unit = np.where(modal["units"] == 200, MM_PER_INCH, 1.0)
    motion_mode = np.where(modal["motion"] == 800, -1, modal["motion"])
    nonmodal = groups["nonmodal"]
    is_dwell = nonmodal == 40
    offset_row = (nonmodal == G10) | (nonmodal >= 920)  # G10, G92, G92.1: axis words are not a move
    any_offset = bool(offset_row.any())
    axis_cols = [S[c] for c in AXIS_LETTERS]
    has_axis = has[axis_cols].any(axis=0)
    if any_offset:
        offset_words = has_axis & offset_row
        has_axis = has_axis & ~offset_row
    has_ijk = has[[S["I"], S["J"], S["K"]]].any(axis=0)
    linear_mode = (motion_mode == 0) | (motion_mode == 10)
    arc_mode = (motion_mode == 20) | (motion_mode == 30)
    orient = has_ijk & linear_mode & ~is_dwell & ~offset_row
    is_motion = (has_axis | orient) & (motion_mode >= 0) & ~is_dwell

    def first(mask: np.ndarray, message: str, letters: str) -> None:
        if mask.any():
            r = int(np.flatnonzero(mask)[0])
            code = next((c for c in letters if c in S and has[S[c], r]), letters)
            raise R.error(r, message, code)

    first(has_axis & is_dwell, "axis words with G4 dwell", AXIS_LETTERS)
    first(has_axis & (motion_mode < 0) & ~is_dwell, "axis words without an active motion mode (G0-G3)",
          AXIS_LETTERS)
    first(arc_mode & has_ijk & ~has_axis & ~is_dwell, "arc without an end point (no axis words)", "IJK")
    first(has_ijk & ~(is_motion & (arc_mode | orient)), "I/J/K without an arc or a five-axis move", "IJK")
    first(has[S["R"]] & ~(is_motion & arc_mode), "R word without an arc", "R")
    first(is_dwell & ~has[S["P"]], "G4 dwell needs a P word (seconds)", "G4")
    if any_offset:
        first((nonmodal == 920) & ~offset_words, "G92 needs axis words", "G92")
        first((nonmodal == G92_1) & offset_words, "axis words with G92.1", AXIS_LETTERS)

    kind_code = np.full(n, KINDS.index(NONE), dtype=np.int8)
    for mode, kind in KIND_OF_MOTION.items():
        kind_code[is_motion & (motion_mode == mode)] = KINDS.index(kind)
    kind_code[is_dwell] = KINDS.index(DWELL)
    is_arc = is_motion & arc_mode

    # -- positions ---------------------------------------------------------------------------------
    incremental = modal["distance"] == 910
    coords = groups["coords"]
    if any_offset:  # work offsets that change (G10, G92): positions through machine coordinates
        start, end, work, system = offset_positions(W, has, S, unit, is_motion, incremental, coords,
                                                     nonmodal, offset_row)
    else:
        start, end = positions(W, has, S, unit, is_motion, incremental)
        work = None
        system = (np.ones(n, dtype=np.int8) if not (coords >= 0).any() else
                  SYSTEM_LUT[ffill(coords, coords >= 0, 540)])
    check_positions(start, end, is_motion, R.error)

    # -- arcs --------------------------------------------------------------------------------------
    centre = np.full((3, n), np.nan)
    radius = np.full(n, np.nan)
    sweep_deg = np.full(n, np.nan)
    turns = np.zeros(n, dtype=np.int16)
    d = end[:3] - start[:3]
    length = np.sqrt(np.einsum("ij,ij->j", d, d))
    plane = modal["plane"] // 10
    if is_arc.any():
        a = np.flatnonzero(is_arc)
        ijk_rows = [S["I"], S["J"], S["K"]]
        words = ArcWords(start=start[:3, a].T, end=end[:3, a].T, plane=plane[a], ccw=motion_mode[a] == 30,
                         ijk=W[np.ix_(ijk_rows, a)].T * unit[a, None], radius=W[S["R"], a] * unit[a],
                         turns=W[S["P"], a], absolute_centre=modal["arc_distance"][a] == 901)
        geo = resolve_arcs(words, lambda k, message, code: R.error(a[k], message, code))
        turns[a] = geo.turns
        length[a] = geo.length
        centre[:, a] = geo.centre.T
        radius[a] = geo.radius
        sweep_deg[a] = np.degrees(geo.sweep)

    # -- orientation vectors (five-axis CL data) ---------------------------------------------------
    ori = np.full((n, 3), np.nan)
    if orient.any():
        o = np.nan_to_num(W[[S["I"], S["J"], S["K"]]][:, orient].T)
        norm = np.linalg.norm(o, axis=1)
        if (norm <= 1e-12).any():
            raise R.error(np.flatnonzero(orient)[norm <= 1e-12][0], "tool orientation vector of length 0", "IJK")
        given = np.zeros((n, 3))
        given[orient] = o / norm[:, None]
        for j in range(3):
            ori[:, j] = ffill(given[:, j], orient, np.nan)

    # -- feed ---------------------------------------------------------------------------------------
    f_here = has[S["F"]]
    first(f_here & (W[S["F"]] < 0), "negative feed rate", "F")
    inverse_time = modal["feed_mode"] == 930
    f_mm = W[S["F"]] * unit
    # LinuxCNC forgets the feed when the feed mode changes: G93 -> G94 needs a new F
    mode_change = np.r_[False, modal["feed_mode"][1:] != modal["feed_mode"][:-1]]
    modal_feed = ffill(np.where(f_here, f_mm, np.nan), (f_here | mode_change) & ~inverse_time, np.nan)
    feed_move = is_motion & (motion_mode != 0)
    lin_len = length
    rot_len = np.sqrt(((end[3:] - start[3:]) ** 2).sum(axis=0)) if has[[S[c] for c in "ABC"]].any() \
        else np.zeros(n)
    time_len = np.where(lin_len > 1e-12, lin_len, rot_len)  # LinuxCNC: F applies to XYZ, else to ABC
    feed = np.where(inverse_time, time_len * W[S["F"]], modal_feed)
    feed = np.where(feed_move, feed, np.nan)
    warnings: list[str] = []
    missing_it = feed_move & inverse_time & ~f_here
    if missing_it.any():
        raise R.error(int(np.flatnonzero(missing_it)[0]), "G93 inverse time needs F on every feed move", "F")
    no_feed = feed_move & ~inverse_time & ~(modal_feed > 0)
    if no_feed.any():
        r = int(np.flatnonzero(no_feed)[0])
        if not lenient:
            raise R.error(r, "feed move without a feed rate (F)", "F")
        warnings.append(f"{no_feed.sum()} feed moves without a feed rate (first at line {R.rows[r] + 1})")

    # -- path control, dwell, spindle, M codes, comments -----------------------------------------
    path_here = groups["path"] >= 0
    p_val = W[S["P"]] * unit
    q_val = W[S["Q"]] * unit
    g64 = groups["path"] == 640
    tol_here = np.where(g64, p_val, 0.0)
    merge_here = np.where(g64, np.where(has[S["Q"]], q_val, p_val), np.nan)
    tol = ffill(tol_here, path_here, np.nan)
    merge = ffill(merge_here, path_here, np.nan)
    path_code = np.select([modal["path"] == g for g in PATH_MODE_OF],
                          [PATH_MODES.index(m) for m in PATH_MODE_OF.values()], -1).astype(np.int8)
    dwell = np.where(is_dwell, W[S["P"]], 0.0)
    if (dwell < 0).any():
        raise R.error(int(np.flatnonzero(dwell < 0)[0]), "negative dwell time", "P")
    with np.errstate(divide="ignore", invalid="ignore"):
        feed_s = np.where(feed_move, time_len / feed * 60.0, 0.0)
    check_run_time(feed_s + dwell, R.error, what="feed too slow or dwell too long",
                   code=lambda r: f"P{dwell[r]:g}" if is_dwell[r] else f"F{W[S['F'], r] if f_here[r] else feed[r]:g}")
    spindle = ffill(W[S["S"]], has[S["S"]], 0.0)
    mcodes = _strings(n)
    stop = np.zeros(n, dtype=bool)
    if len(m_rows):
        ms = pd.Series([f"M{int(v)}" for v in m_codes]).groupby(m_rows).agg(" ".join)
        mcodes = _strings(n, ms.index.to_numpy(), ms.to_numpy())
        stop[m_rows[np.isin(m_codes, STOP_M)]] = True
    comment = _strings(n)
    if len(tok.comment_lines):
        codes = np.zeros(n, dtype=np.int32)
        codes[np.searchsorted(tok.rows, tok.comment_lines)] = np.arange(1, len(tok.comment_lines) + 1)
        texts = pa.concat_arrays([pa.array([""], pa.string()), tok.comment_text])
        comment = pd.array(texts.take(pa.array(codes)), dtype="string")

    blocks = pd.DataFrame({
        "file": _strings(n, fill=file),
        "line": (tok.rows + 1).astype(np.int32),
        "block": np.arange(n, dtype=np.int32),
        "kind": pd.Categorical.from_codes(kind_code, categories=list(KINDS)),
        **{c: start[j] for j, c in enumerate(START_COLUMNS)},
        **{c: end[j] for j, c in enumerate(END_COLUMNS)},
        "plane": plane.astype(np.int8),
        "cx_mm": centre[0], "cy_mm": centre[1], "cz_mm": centre[2],
        "turns": turns,
        "feed_mm_min": feed,
        "inverse_time": inverse_time,
        "dwell_s": dwell,
        "path_mode": pd.Categorical.from_codes(path_code, categories=list(PATH_MODES)),
        "tol_mm": tol,
        "merge_tol_mm": merge,
        "ori_i": ori[:, 0], "ori_j": ori[:, 1], "ori_k": ori[:, 2],
        "units": pd.Categorical.from_codes((modal["units"] == 200).astype(np.int8), categories=["mm", "in"]),
        "spindle_rpm": spindle,
        "mcodes": mcodes,
        "comment": comment,
        **{c: (work[j] if work is not None else np.zeros(n)) for j, c in enumerate(list(OFFSET_COLUMNS)[:6])},
        "coord_system": system,
        # added columns
        "length_mm": np.where(is_motion, length, 0.0),
        "radius_mm": radius,
        "sweep_deg": sweep_deg,
        "n_word": np.where(has[S["N"]], W[S["N"]], -1).astype(np.int64),
        "stop": stop,
    })
    assert list(blocks.columns[:len(BLOCK_COLUMNS)]) == list(BLOCK_COLUMNS)
    metadata = _metadata(tok, W[S["O"]], has[S["O"]], m_codes, m_rows, is_motion, R, file,
                         warnings)
    for u in R.unsupported:
        warnings.append(f"line {u.line}: skipped {u.code} ({u.reason})")
    return Program(blocks=blocks, path=path, warnings=warnings, unsupported=R.unsupported,
                   metadata=metadata)


def _metadata(tok: Tokens, o_value, o_has, m_codes, m_rows, is_motion, R: _Rows, file: str,
              warnings: list[str]) -> dict:
    meta: dict = {"file": file, "lines": tok.n_lines, "percent_lines": (tok.percent + 1).tolist()}
    o_rows = np.flatnonzero(o_has)
    if len(o_rows):
        meta["program_number"] = int(o_value[o_rows[0]])
    if len(tok.comment_lines):
        meta["title"] = tok.comment_text[0].as_py()
    ends = m_rows[np.isin(m_codes, PROGRAM_END)]
    if len(ends):
        meta["end_line"] = int(R.rows[ends.min()]) + 1
        after = is_motion[ends.min() + 1:].sum()
        if after:
            warnings.append(f"{after} motion blocks after the program end (M2/M30) at line "
                            f"{meta['end_line']}; a controller would not run them")
    if len(tok.percent) >= 2:  # the second `%` ends the program (RS274/NGC)
        closing = int(np.searchsorted(R.rows, tok.percent[1]))
        after = is_motion[closing + 1:].sum()
        if after:
            warnings.append(f"{after} motion blocks after the closing '%' at line {tok.percent[1] + 1}; "
                            "a controller would not run them")
    if len(tok.block_delete):
        meta["block_delete_lines"] = (tok.block_delete + 1).tolist()
        warnings.append(f"{len(tok.block_delete)} lines start with '/' (block delete); kept as if the "
                        "block-delete switch were off")
    return meta
