"""The interpreter's output: one record per canonical motion (and per executed line without one), kept
compact while interpreting and turned into the block table (toolpath.schema) at the end of a batch.

A record holds what changes per move (kind, end point, arc centre and turns, feed, dwell) and two
indices: the executed line (`Source`: file, line, call stack, M codes, comment) and the modal context
(`Context`: path mode and tolerances, units, spindle, work offset, rotation, tool offset, ...), which
change rarely and are stored once each. Positions are program coordinates in mm and degrees.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from feedlog.toolpath import arcs
from feedlog.toolpath.parser import _strings
from feedlog.toolpath.schema import (BLOCK_COLUMNS, END_COLUMNS, KINDS, OFFSET_COLUMNS, PATH_MODES,
                                     START_COLUMNS)

K_RAPID, K_LINEAR, K_ARC_CW, K_ARC_CCW, K_DWELL, K_NONE = range(6)


@dataclass(frozen=True)
class Source:
    file: str
    line: int
    stack: str          # call stack, outermost first: "main.ngc:12 > sub.ngc:4" ("" at the top level)
    mcodes: str
    comment: str
    n_word: int
    stop: bool


@dataclass(frozen=True)
class Context:
    path_mode: int      # index into schema.PATH_MODES
    tol_mm: float
    merge_tol_mm: float
    plane: int
    units: int          # 0 mm, 1 inch
    spindle_rpm: float
    inverse_time: bool
    work: tuple         # (6,) machine = R(rot) * program + work (+ tool), mm / deg
    coord_system: int
    rot_deg: float
    tool: tuple         # (6,) tool length offset, mm / deg


class Canon:
    """Collects records; `table()` returns the block table of what was collected so far and clears."""

    def __init__(self) -> None:
        self.sources: dict[Source, int] = {}
        self.source_list: list[Source] = []
        self.contexts: dict[Context, int] = {}
        self.context_list: list[Context] = []
        self.rows: list[tuple] = []
        self.first_row = 0

    def source(self, s: Source) -> int:
        k = self.sources.get(s)
        if k is None:
            k = self.sources[s] = len(self.source_list)
            self.source_list.append(s)
        return k

    def context(self, c: Context) -> int:
        k = self.contexts.get(c)
        if k is None:
            k = self.contexts[c] = len(self.context_list)
            self.context_list.append(c)
        return k

    def table(self, start: tuple) -> pd.DataFrame:
        """The block table of the collected rows; `start` is the position before the first of them
        (mm, deg). Clears the rows (sources and contexts stay: later batches refer to them)."""
        rows = self.rows
        self.rows = []
        n = len(rows)
        cols = list(zip(*rows)) if n else [()] * 16
        kind = np.asarray(cols[0], dtype=np.int8)
        src = np.asarray(cols[1], dtype=np.int64)
        ctx = np.asarray(cols[2], dtype=np.int64)
        end = np.asarray(cols[3:9], dtype=np.float64).reshape(6, n)
        centre = np.asarray(cols[9:12], dtype=np.float64).reshape(3, n)
        turns = np.asarray(cols[12], dtype=np.int16)
        feed = np.asarray(cols[13], dtype=np.float64)
        dwell = np.asarray(cols[14], dtype=np.float64)
        is_motion = kind <= K_ARC_CCW
        start_pos = np.empty((6, n))
        if n:
            start_pos[:, 0] = start
            start_pos[:, 1:] = end[:, :-1]
        sources, contexts = self.source_list, self.context_list
        s_file = np.array([s.file for s in sources], dtype=object)
        s_line = np.array([s.line for s in sources], dtype=np.int32)
        s_stack = np.array([s.stack for s in sources], dtype=object)
        s_m = np.array([s.mcodes for s in sources], dtype=object)
        s_c = np.array([s.comment for s in sources], dtype=object)
        s_n = np.array([s.n_word for s in sources], dtype=np.int64)
        s_stop = np.array([s.stop for s in sources], dtype=bool)

        def cget(attr, dtype):
            return np.array([getattr(c, attr) for c in contexts], dtype=dtype)[ctx] if n else np.zeros(0, dtype)

        plane = cget("plane", np.int8)
        work = np.array([c.work for c in contexts], dtype=np.float64).reshape(-1, 6)[ctx].T if n else np.zeros((6, 0))
        tool = np.array([c.tool for c in contexts], dtype=np.float64).reshape(-1, 6)[ctx].T if n else np.zeros((6, 0))
        is_arc = (kind == K_ARC_CW) | (kind == K_ARC_CCW)
        d = end[:3] - start_pos[:3]
        with np.errstate(over="ignore", invalid="ignore"):   # beyond feedlog's bounds: checked by the runner
            length = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        radius = np.full(n, np.nan)
        sweep_deg = np.full(n, np.nan)
        if is_arc.any():
            a = np.flatnonzero(is_arc)
            idx = arcs.plane_index(plane[a])
            s = arcs.to_plane(start_pos[:3, a].T, idx)
            e = arcs.to_plane(end[:3, a].T, idx)
            c = arcs.to_plane(centre[:, a].T, idx)[:, :2]
            r0 = np.hypot(s[:, 0] - c[:, 0], s[:, 1] - c[:, 1])
            r1 = np.hypot(e[:, 0] - c[:, 0], e[:, 1] - c[:, 1])
            sw = arcs.sweep(s[:, :2], e[:, :2], c, kind[a] == K_ARC_CCW, turns[a])
            length[a] = arcs.arc_length(r0, r1, sw, e[:, 2] - s[:, 2])
            radius[a] = r0
            sweep_deg[a] = np.degrees(sw)
        centre[:, ~is_arc] = np.nan
        block = np.arange(self.first_row, self.first_row + n, dtype=np.int32)
        self.first_row += n
        frame = pd.DataFrame({
            "file": _strings(n, np.arange(n), s_file[src]) if n else _strings(0),
            "line": s_line[src] if n else np.zeros(0, np.int32),
            "block": block,
            "kind": pd.Categorical.from_codes(kind, categories=list(KINDS)),
            **{col: start_pos[j] for j, col in enumerate(START_COLUMNS)},
            **{col: end[j] for j, col in enumerate(END_COLUMNS)},
            "plane": plane,
            "cx_mm": centre[0], "cy_mm": centre[1], "cz_mm": centre[2],
            "turns": np.where(is_arc, turns, 0).astype(np.int16),
            "feed_mm_min": np.where(is_motion & (kind != K_RAPID), feed, np.nan),
            "inverse_time": cget("inverse_time", bool),
            "dwell_s": dwell,
            "path_mode": pd.Categorical.from_codes(cget("path_mode", np.int8), categories=list(PATH_MODES)),
            "tol_mm": cget("tol_mm", np.float64),
            "merge_tol_mm": cget("merge_tol_mm", np.float64),
            "ori_i": np.full(n, np.nan), "ori_j": np.full(n, np.nan), "ori_k": np.full(n, np.nan),
            "units": pd.Categorical.from_codes(cget("units", np.int8), categories=["mm", "in"]),
            "spindle_rpm": cget("spindle_rpm", np.float64),
            "mcodes": _strings(n, np.arange(n), s_m[src]) if n else _strings(0),
            "comment": _strings(n, np.arange(n), s_c[src]) if n else _strings(0),
            **{col: work[j] for j, col in enumerate(list(OFFSET_COLUMNS)[:6])},
            "coord_system": cget("coord_system", np.int8),
            "length_mm": np.where(is_motion, length, 0.0),
            "radius_mm": radius,
            "sweep_deg": sweep_deg,
            "n_word": s_n[src] if n else np.zeros(0, np.int64),
            "stop": s_stop[src] if n else np.zeros(0, bool),
            "rot_deg": cget("rot_deg", np.float64),
            **{f"tool_{a}": tool[j] for j, a in enumerate(("x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"))},
            "stack": _strings(n, np.arange(n), s_stack[src]) if n else _strings(0),
        })
        assert list(frame.columns[:len(BLOCK_COLUMNS)]) == list(BLOCK_COLUMNS)
        return frame
