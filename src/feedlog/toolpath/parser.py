"""RS274/NGC part program -> block table, vectorised, one chunk of whole lines at a time.

The lexer yields (line, letter, value) words; toolpath.words scatters them into one row per source
line. Here modal state (units, distance mode, plane, motion mode, feed, path mode, ...) is propagated
with a vectorised forward fill that starts from the state the previous chunk left (toolpath.carry),
absolute positions come from a cumulative sum of incremental moves reset at every absolute word, and
arcs are resolved for all rows at once (toolpath.arcwords). toolpath.stream reads a program chunk by
chunk; `parse_program` is that stream gathered into one table.

Order of execution within a line follows RS274/NGC: feed mode and F, S, M codes, dwell, plane, units,
path control, distance modes, then motion; so `G20 G91 G1 X1 F10` moves 25.4 mm at 10 mm/min when
the program was in mm before that line (F is read before G20 takes effect), as LinuxCNC does.

Tool orientation vectors: on a line in linear or rapid mode (G0/G1), I J K are the tool orientation
vector of five-axis CL data (normalised; modal once given); in arc mode (G2/G3) they are the arc
centre. LinuxCNC itself rejects I/J/K on G0/G1, so the two meanings never collide.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa

from feedlog.toolpath.arcwords import ArcWords, resolve_arcs
from feedlog.toolpath.carry import MODAL_DEFAULTS, ParseState
from feedlog.toolpath.limits import check_positions, check_run_time
from feedlog.toolpath.offsets import G10, G92_1
from feedlog.toolpath.positions import AXIS_LETTERS, SYSTEM_LUT, ffill, offset_positions, positions
from feedlog.toolpath.program import Program, Unsupported
from feedlog.toolpath.schema import (ARC_CCW, ARC_CW, BLOCK_COLUMNS, CONTINUOUS, DWELL, END_COLUMNS,
                                     EXACT_PATH, EXACT_STOP, KINDS, LINEAR, NONE, OFFSET_COLUMNS, PATH_MODES,
                                     RAPID, START_COLUMNS)
from feedlog.toolpath.words import PROGRAM_END, STOP_M, scatter
from feedlog.units import MM_PER_INCH

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


@dataclass
class ChunkFacts:
    """What a chunk tells about the whole program (toolpath.stream gathers them into Program.metadata
    and warnings). Lines are 1-based, in the file."""

    lines: int                                   # line ends in the chunk's text
    percent_lines: list[int] = field(default_factory=list)
    block_delete_lines: list[int] = field(default_factory=list)
    program_number: int | None = None
    title: str | None = None
    end_line: int | None = None                  # first M2/M30
    motion_rows: int = 0
    motion_after: object = None                  # callable: line -> motion rows of the chunk after it
    no_feed: tuple[int, int] | None = None       # (count, first line) of feed moves without F (lenient)
    unsupported: list[Unsupported] = field(default_factory=list)


def parse_chunk(text: str, state: ParseState, *, file: str, lenient: bool = False
                ) -> tuple[pd.DataFrame, ChunkFacts, ParseState]:
    """Parse `text` (whole lines, the chunk that starts at `state.first_line`) with the modal state the
    lines before it left. Returns its rows of the block table, what it tells about the program, and
    the state after its last line."""
    words = scatter(text, file=file, lenient=lenient, first_line=state.first_line)
    R, tok, W, has, S, groups = words.R, words.tok, words.W, words.has, words.S, words.groups
    m_rows, m_codes = words.m_rows, words.m_codes
    n = R.n
    new = replace(state)

    # -- modal state -------------------------------------------------------------------------------
    modal = {g: ffill(groups[g], groups[g] >= 0, state.modal[g]) for g in MODAL_DEFAULTS}
    if n:
        new.modal = {g: int(modal[g][-1]) for g in MODAL_DEFAULTS}
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
    if any_offset or state.offsets.used:  # work offsets (G10, G92): positions through machine coordinates
        start, end, work, system, new.position, new.offsets = offset_positions(
            W, has, S, unit, is_motion, incremental, coords, nonmodal, offset_row, state.position, state.offsets)
    else:
        start, end, new.position = positions(W, has, S, unit, is_motion, incremental, state.position)
        work = None
        selected = ffill(coords, coords >= 0, state.offsets.selected)
        system = SYSTEM_LUT[selected] if n else np.zeros(0, np.int8)
        if n:
            # the active system too: a G10 L2 P0 in a later chunk writes to it
            new.offsets = replace(state.offsets, selected=int(selected[-1]), active=int(system[-1]))
    check_positions(start, end, is_motion, R.error)

    # -- arcs --------------------------------------------------------------------------------------
    centre = np.full((3, n), np.nan)
    radius = np.full(n, np.nan)
    sweep_deg = np.full(n, np.nan)
    turns = np.zeros(n, dtype=np.int16)
    d = end[:3] - start[:3]
    length = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])  # per row, whatever the chunk size (einsum over
    # the leading axis rounds differently on short arrays)
    plane = modal["plane"] // 10
    if is_arc.any():
        a = np.flatnonzero(is_arc)
        ijk_rows = [S["I"], S["J"], S["K"]]
        arc_words = ArcWords(start=start[:3, a].T, end=end[:3, a].T, plane=plane[a], ccw=motion_mode[a] == 30,
                             ijk=W[np.ix_(ijk_rows, a)].T * unit[a, None], radius=W[S["R"], a] * unit[a],
                             turns=W[S["P"], a], absolute_centre=modal["arc_distance"][a] == 901,
                             inch=modal["units"][a] == 200)
        geo = resolve_arcs(arc_words, lambda k, message, code: R.error(a[k], message, code))
        turns[a] = geo.turns
        length[a] = geo.length
        centre[:, a] = geo.centre.T
        radius[a] = geo.radius
        sweep_deg[a] = np.degrees(geo.sweep)

    # -- orientation vectors (five-axis CL data) ---------------------------------------------------
    ori = np.full((n, 3), np.nan)
    if orient.any() or not np.isnan(state.ori).all():
        o = np.nan_to_num(W[[S["I"], S["J"], S["K"]]][:, orient].T)
        norm = np.linalg.norm(o, axis=1)
        if (norm <= 1e-12).any():
            raise R.error(np.flatnonzero(orient)[norm <= 1e-12][0], "tool orientation vector of length 0", "IJK")
        given = np.zeros((n, 3))
        given[orient] = o / norm[:, None]
        for j in range(3):
            ori[:, j] = ffill(given[:, j], orient, state.ori[j])
        if n:
            new.ori = ori[-1].copy()

    # -- feed ---------------------------------------------------------------------------------------
    f_here = has[S["F"]]
    first(f_here & (W[S["F"]] < 0), "negative feed rate", "F")
    inverse_time = modal["feed_mode"] == 930
    # F is set before the line's G20/G21 (LinuxCNC's order of execution): it is in the units in force before
    units_before = np.r_[state.modal["units"], modal["units"][:-1]] if n else modal["units"]
    f_mm = W[S["F"]] * np.where(units_before == 200, MM_PER_INCH, 1.0)
    # LinuxCNC forgets the feed when the feed mode changes: G93 -> G94 needs a new F
    mode_change = np.zeros(n, dtype=bool)
    if n:
        before = modal["feed_mode"][0] if state.feed_mode_before is None else state.feed_mode_before
        mode_change = modal["feed_mode"] != np.r_[before, modal["feed_mode"][:-1]]
    modal_feed = ffill(np.where(f_here, f_mm, np.nan), (f_here | mode_change) & ~inverse_time, state.feed_mm_min)
    if n:
        new.feed_mm_min, new.feed_mode_before = float(modal_feed[-1]), int(modal["feed_mode"][-1])
    feed_move = is_motion & (motion_mode != 0)
    lin_len = length
    rot_len = np.sqrt(((end[3:] - start[3:]) ** 2).sum(axis=0)) if has[[S[c] for c in "ABC"]].any() \
        else np.zeros(n)
    time_len = np.where(lin_len > 1e-12, lin_len, rot_len)  # LinuxCNC: F applies to XYZ, else to ABC
    # G93: the block takes 1/F minutes, but LinuxCNC never feeds slower than 0.1 program units/min
    feed = np.where(inverse_time, np.maximum(0.1 * unit, time_len * W[S["F"]]), modal_feed)
    feed = np.where(feed_move, feed, np.nan)
    missing_it = feed_move & inverse_time & ~f_here
    if missing_it.any():
        raise R.error(int(np.flatnonzero(missing_it)[0]), "G93 inverse time needs F on every feed move", "F")
    no_feed = feed_move & ~inverse_time & ~(modal_feed > 0)
    no_feed_fact = None
    if no_feed.any():
        r = int(np.flatnonzero(no_feed)[0])
        if not lenient:
            raise R.error(r, "feed move without a feed rate (F)", "F")
        no_feed_fact = (int(no_feed.sum()), int(R.rows[r]) + 1 + state.first_line)

    # -- path control, dwell, spindle, M codes, comments -----------------------------------------
    path_here = groups["path"] >= 0
    p_val = W[S["P"]] * unit
    q_val = W[S["Q"]] * unit
    g64 = groups["path"] == 640
    tol_here = np.where(g64, p_val, 0.0)
    merge_here = np.where(g64, np.where(has[S["Q"]], q_val, p_val), np.nan)
    tol = ffill(tol_here, path_here, state.tol_mm)
    merge = ffill(merge_here, path_here, state.merge_tol_mm)
    path_code = np.select([modal["path"] == g for g in PATH_MODE_OF],
                          [PATH_MODES.index(m) for m in PATH_MODE_OF.values()], -1).astype(np.int8)
    dwell = np.where(is_dwell, W[S["P"]], 0.0)
    if (dwell < 0).any():
        raise R.error(int(np.flatnonzero(dwell < 0)[0]), "negative dwell time", "P")
    with np.errstate(divide="ignore", invalid="ignore"):
        feed_s = np.where(feed_move, time_len / feed * 60.0, 0.0)
    new.run_time_s = check_run_time(
        feed_s + dwell, R.error, what="feed too slow or dwell too long", before=state.run_time_s,
        code=lambda r: f"P{dwell[r]:g}" if is_dwell[r] else f"F{W[S['F'], r] if f_here[r] else feed[r]:g}")
    spindle = ffill(W[S["S"]], has[S["S"]], state.spindle_rpm)
    if n:
        new.tol_mm, new.merge_tol_mm, new.spindle_rpm = float(tol[-1]), float(merge[-1]), float(spindle[-1])
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
        "line": (tok.rows + 1 + state.first_line).astype(np.int32),
        "block": np.arange(state.first_row, state.first_row + n, dtype=np.int32),
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
    facts = _facts(tok, W[S["O"]], has[S["O"]], m_codes, m_rows, is_motion, R.rows, state.first_line)
    facts.no_feed = no_feed_fact
    facts.unsupported = R.unsupported
    new.first_line = state.first_line + tok.n_lines - 1
    new.first_row = state.first_row + n
    return blocks, facts, new


def _facts(tok, o_value, o_has, m_codes, m_rows, is_motion, rows, first_line: int) -> ChunkFacts:
    """Program number, title, program end, `%` and block-delete lines, motion rows: per chunk."""
    facts = ChunkFacts(lines=tok.n_lines - 1, percent_lines=(tok.percent + 1 + first_line).tolist(),
                       block_delete_lines=(tok.block_delete + 1 + first_line).tolist(),
                       motion_rows=int(is_motion.sum()))
    o_rows = np.flatnonzero(o_has)
    if len(o_rows):
        facts.program_number = int(o_value[o_rows[0]])
    if len(tok.comment_lines):
        facts.title = tok.comment_text[0].as_py()
    ends = m_rows[np.isin(m_codes, PROGRAM_END)]
    if len(ends):
        facts.end_line = int(rows[ends.min()]) + 1 + first_line

    def motion_after(line: int) -> int:
        """Motion rows of the chunk below 1-based file line `line`."""
        return int(is_motion[np.searchsorted(rows, line - 1 - first_line, side="right"):].sum())

    facts.motion_after = motion_after
    return facts


def parse_program(source: str | Path, *, lenient: bool = False, name: str | None = None) -> Program:
    """Parse a part program (a path, or G-code text) into a Program with its block table.

    Unsupported codes raise ProgramError naming file, line and code; with `lenient=True` they are
    listed in `Program.unsupported` (and a warning) and skipped. Malformed text always raises.
    The program is read in chunks (toolpath.stream.ProgramReader), gathered into one table here.
    """
    from feedlog.toolpath.stream import ProgramReader  # the reader builds on this module

    with ProgramReader(source, lenient=lenient, name=name) as reader:
        return reader.program()
