"""A block table back to plain RS274/NGC: the flattened motion of a program (loops unrolled, subroutines
inlined, cycles and compensation resolved), one line per move, each tagged with where it came from.

    text = expand(load_program("part.ngc"))     # `feedlog program part.ngc --expand flat.ngc`

Lines are absolute, in mm, with full-precision numbers; work offsets and XY rotation become
`G10 L2 P1 ... R` + `G54`, tool length offsets `G43.1`, path modes `G61/G61.1/G64 P Q`, arcs keep absolute
centres (`G90.1`) and turns (`P`), dwells `G4 P`. The tag comment is `(file:line)` or
`(file:line < called from main.ngc:12)`. Reading the result gives the same motion as the program
(tests/toolpath/test_expand.py).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from feedlog.toolpath.schema import END_COLUMNS, MOTION_KINDS

_PATH = {"exact_path": "G61", "exact_stop": "G61.1"}
_PLANE_WORDS = {17: ("G17", "IJ"), 18: ("G18", "KI"), 19: ("G19", "JK")}
_AXES = ("X", "Y", "Z", "A", "B", "C")
_TOOL = ("tool_x_mm", "tool_y_mm", "tool_z_mm", "tool_a_deg", "tool_b_deg", "tool_c_deg")
_WORK = ("wx_mm", "wy_mm", "wz_mm", "wa_deg", "wb_deg", "wc_deg")


def _num(v: float) -> str:
    """The shortest decimal (no exponent: G-code has none) that reads back as the same float."""
    text = np.format_float_positional(float(v), trim="-")
    return "0" if text in ("0", "-0") else text


def expand(program) -> str:
    """The flattened RS274/NGC text of a Program (or block table)."""
    blocks: pd.DataFrame = getattr(program, "blocks", program)
    name = str(getattr(program, "name", ""))
    lines = [f"(flattened by feedlog from {Path(name).name or 'a program'}: one line per move, mm, absolute)",
             "G21 G90 G90.1 G94 G40 G49 G80 G17 G54"]
    state: dict[str, object] = {}

    def change(key: str, value, text: str) -> None:
        if state.get(key) != value:
            state[key] = value
            lines.append(text)

    cols = blocks.columns
    for row in blocks.itertuples(index=False):
        kind = str(row.kind)
        if kind not in MOTION_KINDS and kind != "dwell":
            if row.mcodes:
                lines.append(f"({row.mcodes} at {_tag(row)})")
            continue
        work = tuple(float(getattr(row, c)) if c in cols else 0.0 for c in _WORK)
        rot = float(row.rot_deg) if "rot_deg" in cols else 0.0
        words = " ".join(f"{a}{_num(w)}" for a, w in zip(_AXES, work))
        change("work", (work, rot), f"G10 L2 P1 {words}" + (f" R{_num(rot)}" if rot else ""))
        tool = tuple(float(getattr(row, c)) if c in cols else 0.0 for c in _TOOL)
        change("tool", tool, "G43.1 " + " ".join(f"{a}{_num(t)}" for a, t in zip(_AXES, tool)) if any(tool)
               else "G49")
        mode = str(row.path_mode)
        if mode == "continuous":
            tol = "" if math.isnan(row.tol_mm) else f" P{_num(row.tol_mm)}"
            merge = "" if math.isnan(row.merge_tol_mm) else f" Q{_num(row.merge_tol_mm)}"
            change("mode", (mode, tol, merge), f"G64{tol}{merge}")
        else:
            change("mode", (mode,), _PATH[mode])
        if kind == "dwell":
            lines.append(f"G4 P{_num(row.dwell_s)} ({_tag(row)})")
            continue
        end = [float(getattr(row, c)) for c in END_COLUMNS]
        target = " ".join(f"{a}{_num(v)}" for a, v in zip(_AXES, end))
        if kind == "rapid":
            lines.append(f"G0 {target} ({_tag(row)})")
            continue
        feed = f" F{_num(row.feed_mm_min)}"
        if kind == "linear":
            lines.append(f"G1 {target}{feed} ({_tag(row)})")
            continue
        plane = int(row.plane)
        code, letters = _PLANE_WORDS[plane]
        change("plane", plane, code)
        centre = {"I": row.cx_mm, "J": row.cy_mm, "K": row.cz_mm}
        ijk = " ".join(f"{letter}{_num(centre[letter])}" for letter in letters)
        turns = f" P{int(row.turns)}" if int(row.turns) > 1 else ""
        lines.append(f"{'G3' if kind == 'arc_ccw' else 'G2'} {target} {ijk}{turns}{feed} ({_tag(row)})")
    lines.append("M2")
    return "\n".join(lines) + "\n"


def _tag(row) -> str:
    where = f"{Path(str(row.file)).name}:{int(row.line)}"
    stack = str(getattr(row, "stack", "") or "")
    return f"{where} < called from {stack}" if stack else where


def motion_equal(a, b, *, atol: float = 1e-9) -> bool:
    """Whether two programs move the same (kinds, end points, centres, feeds)."""
    ma, mb = a.motion, b.motion
    if len(ma) != len(mb) or not (ma["kind"].astype(str).to_numpy() == mb["kind"].astype(str).to_numpy()).all():
        return False
    cols = list(END_COLUMNS) + ["cx_mm", "cy_mm", "feed_mm_min"]
    return all(np.allclose(ma[c].to_numpy(float), mb[c].to_numpy(float), atol=atol, equal_nan=True) for c in cols)
