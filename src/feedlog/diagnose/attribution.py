"""Where the time goes: timing residuals attributed to the blocks and block classes that carry them.

Each timing segment (`residuals.Segments`) is described by the blocks it spans: its recording, move
kind (rapid, line, arc) and the kind of move before it, length class, the corner at its end, the dominant axis and the axis shares, programmed
feed, rotary motion, an axis reversal at its end, membership in a run of short blocks, an exact stop
at its end. `class_table` sums a residual over the segments of each class; `where_text` names the
class that carries most of it ("corners > 60 deg with a Y reversal carry 91 % of the lost time").
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from feedlog.diagnose.cases import Case
from feedlog.diagnose.residuals import Segments
from feedlog.toolpath.schema import AXIS_UNITS

SHORT_MM = 1.0
RUN = 5                   # blocks in a run of short blocks
SHARP_DEG = 60.0
CORNER_DEG = 2.0


def block_classes(case: Case) -> pd.DataFrame:
    """Per motion block of the program: its classes (one column each) and its line."""
    blocks = case.program.blocks
    kind = blocks["kind"].astype(str)
    rows = blocks[kind.isin(("rapid", "linear", "arc_cw", "arc_ccw"))].reset_index(drop=True)
    kind = rows["kind"].astype(str).to_numpy()
    length = rows["length_mm"].to_numpy(np.float64)
    axes = [a for a in ("x", "y", "z", "a", "b", "c") if f"{a}_{AXIS_UNITS[a]}" in rows.columns]
    delta = np.column_stack([np.nan_to_num(rows[f"{a}_{AXIS_UNITS[a]}"].to_numpy(np.float64)
                                           - rows[f"{a}0_{AXIS_UNITS[a]}"].to_numpy(np.float64)) for a in axes])
    lin = [i for i, a in enumerate(axes) if a in ("x", "y", "z")]
    rot = [i for i, a in enumerate(axes) if a not in ("x", "y", "z")]
    mag = np.abs(delta[:, lin])
    share = mag / np.maximum(mag.sum(axis=1, keepdims=True), 1e-12)
    dominant = np.array([axes[lin[i]] for i in np.argmax(mag, axis=1)]) if len(rows) else np.array([], str)
    rotary = (np.abs(delta[:, rot]) > 1e-6).any(axis=1) if rot else np.zeros(len(rows), bool)
    # direction change at the end of each block: the angle between this move and the next one
    d = delta[:, lin]
    nrm = np.linalg.norm(d, axis=1)
    u = d / np.maximum(nrm, 1e-12)[:, None]
    cos = np.einsum("ij,ij->i", u[:-1], u[1:]) if len(u) > 1 else np.zeros(0)
    corner = np.append(np.degrees(np.arccos(np.clip(cos, -1, 1))), 0.0)
    reversal = np.zeros((len(rows), len(lin)), bool)
    if len(rows) > 1:
        reversal[:-1] = (np.sign(d[:-1]) * np.sign(d[1:]) < 0) & (np.abs(d[:-1]) > 1e-4) & (np.abs(d[1:]) > 1e-4)
    short = length < SHORT_MM
    run = np.zeros(len(rows), bool)
    if len(rows):
        edges = np.flatnonzero(np.diff(np.concatenate([[0], short.astype(int), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):
            if b - a >= RUN:
                run[a:b] = True
    stop = rows["path_mode"].astype(str).to_numpy() != "continuous"
    move = np.where(kind == "rapid", "rapid", np.where(kind == "linear", "line", "arc"))
    table = pd.DataFrame({
        "block": rows["block"].to_numpy(np.int64), "line": rows["line"].to_numpy(np.int64),
        "move": move, "after": np.char.add("after a", np.concatenate([["t rest"], np.where(
            move[:-1] == "arc", "n arc", np.char.add(" ", move[:-1].astype(str)))]) if len(move) else np.array([], str)),
        "length": np.where(length < SHORT_MM, "< 1 mm", np.where(length < 10, "1-10 mm", ">= 10 mm")),
        "corner": np.where(corner < CORNER_DEG, "no corner", np.where(corner < SHARP_DEG, "corner < 60 deg",
                                                                       "corner >= 60 deg")),
        "dominant": np.char.add("along ", np.char.upper(dominant.astype(str))),
        "feed": np.where(kind == "rapid", "rapid", np.char.add("F", rows["feed_mm_min"].fillna(0).round().astype(int)
                                                                .astype(str).to_numpy())),
        "rotary": np.where(rotary, "rotary motion", "no rotary motion"),
        "reversal": [("reversal of " + "/".join(axes[lin[i]].upper() for i in np.flatnonzero(r))) if r.any()
                     else "no reversal" for r in reversal],
        "short_run": np.where(run, "in a run of short blocks", "not in a short run"),
        "stop": np.where(stop, "exact stop", "continuous"),
    })
    for j, i in enumerate(lin):
        table[f"share_{axes[i]}"] = share[:, j]
    for a in ("x", "y", "z"):   # where on the part the block ends (program frame)
        if f"{a}_mm" in rows.columns:
            table[f"{a}_end_mm"] = rows[f"{a}_mm"].to_numpy(np.float64)
    return table


CLASSES = ("recording", "move", "after", "length", "corner", "dominant", "feed", "rotary", "reversal", "short_run",
           "stop")


def segment_table(case: Case, segments: Segments) -> pd.DataFrame:
    """One row per segment: recording, lines spanned and the classes of its last (anchor) block."""
    classes = block_classes(case)
    anchors = segments.anchors.copy()
    if len(anchors):
        anchors[-1] = int(classes["block"].iloc[-1]) if len(classes) else -1
    pos = np.searchsorted(classes["block"].to_numpy(), anchors)
    pos = np.clip(pos, 0, max(len(classes) - 1, 0))
    rows = classes.iloc[pos].reset_index(drop=True) if len(classes) else pd.DataFrame(index=range(len(anchors)))
    first = np.concatenate([[classes["line"].iloc[0] if len(classes) else 0], rows["line"].to_numpy()[:-1]])
    rows.insert(0, "recording", f"recording {case.name}")
    rows.insert(1, "segment", np.arange(len(anchors)))
    rows["first_line"] = first
    rows["end_s"] = segments.end_s
    rows["measured_s"] = segments.measured_s
    return rows


def class_table(table: pd.DataFrame, residual: np.ndarray, *, lost: bool = False) -> pd.DataFrame:
    """Per class value: segments, residual sum (s) and its share of the total |residual| (or of the lost
    time, sim short of measured, with `lost`)."""
    r = -np.minimum(residual, 0.0) if lost else np.abs(residual)
    total = float(r.sum())
    out = []
    for cls in CLASSES:
        if cls not in table.columns:
            continue
        for value, idx in table.groupby(cls, sort=False).indices.items():
            part = float(r[idx].sum())
            out.append({"class": cls, "value": str(value), "segments": len(idx), "residual_s": float(residual[idx].sum()),
                        "share": part / total if total > 0 else 0.0})
    return pd.DataFrame(out).sort_values("share", ascending=False, kind="stable").reset_index(drop=True)


def where_text(table: pd.DataFrame, residual: np.ndarray, *, top: int = 2) -> str:
    """The classes that carry most of the residual, most specific first, as a phrase."""
    if not len(table) or not np.any(residual):
        return ""
    lost = residual.sum() < 0
    ct = class_table(table, residual, lost=lost)
    # a class value is informative when it carries more of the residual than of the segments
    n = len(table)
    ct["lift"] = ct["share"] / np.maximum(ct["segments"] / n, 1e-9)
    negative = ct["value"].str.startswith(("no ", "not ")) | (ct["value"] == "continuous")
    useful = ct[(ct["share"] >= 0.5) & (ct["lift"] > 1.15) & ~negative].sort_values(["lift", "share"],
                                                                                        ascending=False)
    useful = useful.drop_duplicates("value")  # two classes may name the same blocks alike ("rapid" move, F)
    what = "lost time" if lost else "excess time"
    if not len(useful):
        return f"the {what} is spread over the program (no block class carries half of it)"
    parts = [f"{row.value} ({100 * row.share:.0f} % of the {what} in {row.segments} of {n} segments)"
             for row in useful.head(top).itertuples()]
    return "; ".join(parts)


def top_segments(tables: Sequence[pd.DataFrame], residuals: Sequence[np.ndarray], n: int = 10) -> pd.DataFrame:
    """The segments with the largest |residual|, over all recordings."""
    frames = []
    for table, r in zip(tables, residuals):
        t = table[["recording", "segment", "first_line", "line", "move", "corner", "dominant", "reversal",
                   "measured_s"]].copy()
        t["residual_s"] = r
        frames.append(t)
    if not frames:
        return pd.DataFrame()
    allr = pd.concat(frames, ignore_index=True)
    return allr.reindex(allr["residual_s"].abs().sort_values(ascending=False).index).head(n).reset_index(drop=True)
