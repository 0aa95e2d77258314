"""A session is more than motion: tool changes, stops, dwells, waits and standstills in the data.

Read from the line stream, the feed (else the positions' speed) and the spindle:

- a *standstill* is a stretch of at least MIN_STILL_S where the recorded feed (held until the next
  sample) is at most STILL_MM_MIN; the spindle is *off* where its speed is at most SPINDLE_OFF_RPM;
- each recorded line run that holds a standstill (or that stands on a program line with no motion at
  all and lasts MIN_STILL_S) is an event, named by what the program asks on that line: `tool change`
  (M6), `program stop` (M0), `optional stop` (M1), `dwell` (G4), `wait on M codes` (M3/M4/M5/M7/M8/M9:
  spindle and coolant), else `standstill` (a feed hold or a wait the program does not ask for);
- an event's time is the run's whole duration on a line without motion, else the standstill inside
  the run (the motion the program asks for stays in the motion comparison).

`anchors` pins the recorded line numbers to the program where the data itself says which block ran:
the spindle starting again after it was off is the program's first M3/M4 after an M6, and the last
recorded line, when past the program's last move, is a block after it (M2/M30): at most its last.
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd

from feedlog.align.blocks import line_runs
from feedlog.recording import Recording
from feedlog.toolpath import Program
from feedlog.toolpath.schema import DWELL, MOTION_KINDS

STILL_MM_MIN = 6.0       # feed at or below this (mm/min, 0.1 mm/s) is standing still
MIN_STILL_S = 1.0        # shorter standstills are part of motion (reversals, exact stops)
SPINDLE_OFF_RPM = 1.0
SPEED_WINDOW_S = 0.1     # positions: speed over this window (noise at rest stays below STILL_MM_MIN)
SPINDLE_ON_S = 1.0       # a restart: the spindle stays on this long (not an orientation blip)
_M = re.compile(r"M0*(\d+)")
KINDS = {6: "tool change", 0: "program stop", 1: "optional stop"}
WAIT_CODES = {3, 4, 5, 7, 8, 9}


def line_codes(program: Program) -> pd.DataFrame:
    """Per program line (index): `codes` (the set of its M-code numbers), `moves`, `dwell`. Only the rows
    with M codes are parsed (most have none)."""
    b = program.blocks
    lines = b["line"].to_numpy(np.int64)
    kinds = b["kind"].astype(str)
    frame = pd.DataFrame({"moves": kinds.isin(MOTION_KINDS).to_numpy(), "dwell": (kinds == DWELL).to_numpy()})
    out = frame.groupby(lines).any()
    mc = b["mcodes"].fillna("").astype(str) if "mcodes" in b.columns else pd.Series("", index=b.index)
    some = np.flatnonzero(mc.str.len().to_numpy() > 0)
    found: dict[int, set[int]] = {}
    for ln, text in zip(lines[some], mc.to_numpy()[some]):
        found.setdefault(int(ln), set()).update(int(m) for m in _M.findall(text.upper()))
    empty = frozenset()
    out["codes"] = [found.get(int(ln), empty) for ln in out.index]
    return out


def _held(table: pd.DataFrame | None, column: str, t_ns: np.ndarray) -> np.ndarray:
    """The stream's last value at each of `t_ns` (NaN before its first sample or without the stream)."""
    if table is None or column not in table.columns or not len(table):
        return np.full(len(t_ns), np.nan)
    ts = table["t_ns"].to_numpy(np.int64)
    idx = np.searchsorted(ts, t_ns, side="right") - 1
    v = table[column].to_numpy(np.float64)
    return np.where(idx >= 0, v[np.clip(idx, 0, len(v) - 1)], np.nan)


def motion_feed(recording: Recording) -> pd.DataFrame | None:
    """The path speed the data gives (t_ns, feed_mm_min): the recorded feed, else the positions' speed
    over SPEED_WINDOW_S (a window long enough that position noise at rest reads as standing still)."""
    feed = recording.streams.get("feed")
    if feed is not None and "feed_mm_min" in feed.columns and len(feed):
        return feed
    axes = recording.streams.get("axes")
    cols = [c for c in ("x_mm", "y_mm", "z_mm") if axes is not None and c in axes.columns]
    if not cols or len(axes) < 2:
        return None
    t = axes["t_ns"].to_numpy(np.int64)
    pos = axes[cols].to_numpy(np.float64)
    j = np.minimum(np.searchsorted(t, t + int(SPEED_WINDOW_S * 1e9)), len(t) - 1)
    dt = (t[j] - t) / 6e10    # minutes
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.where(dt > 0, np.linalg.norm(pos[j] - pos, axis=1) / dt, 0.0)
    return pd.DataFrame({"t_ns": t, "feed_mm_min": np.nan_to_num(speed)})


def still_ns(feed: pd.DataFrame | None, t0: int, t1: int, *, step_ns: int = 10_000_000) -> int:
    """Nanoseconds within [t0, t1) where the feed (`motion_feed`) stands still (held-value, 10 ms grid)."""
    if t1 <= t0:
        return 0
    grid = np.arange(t0, t1, step_ns, dtype=np.int64)
    return int(np.count_nonzero(_held(feed, "feed_mm_min", grid) <= STILL_MM_MIN) * step_ns)


def find_events(recording: Recording, runs: pd.DataFrame, program_line: np.ndarray, program: Program,
                *, span_ns: tuple[int, int]) -> pd.DataFrame:
    """Events (one row per recorded line run that holds one; columns: kind, recorded_line, program_line,
    t_start_ns, t_end_ns, duration_s, spindle_off) inside `span_ns` (the motion span). `runs`: line,
    t_start_ns, t_end_ns; `program_line`: per run (NaN: unknown, then the event is a `standstill`)."""
    cols = ["kind", "recorded_line", "program_line", "m_codes", "t_start_ns", "t_end_ns", "duration_s", "spindle_off"]
    lo = np.maximum(runs["t_start_ns"].to_numpy(np.int64), span_ns[0])
    hi = np.minimum(runs["t_end_ns"].to_numpy(np.int64), span_ns[1])
    long = np.flatnonzero(hi - lo >= MIN_STILL_S * 1e9)       # only runs this long can hold an event
    if not len(long):
        return pd.DataFrame([], columns=cols)
    info = line_codes(program)
    feed = None          # the path speed, computed when a run first needs it
    rows = []
    for k in long:
        r = runs.iloc[k]
        t0, t1 = int(lo[k]), int(hi[k])
        p = program_line[k]
        known = np.isfinite(p) and int(p) in info.index
        codes = info.at[int(p), "codes"] if known else set()
        moves = bool(info.at[int(p), "moves"]) if known else True
        if not (known and not moves) and feed is None:
            feed = motion_feed(recording)
        still = (t1 - t0) if known and not moves else still_ns(feed, t0, t1)
        if still < MIN_STILL_S * 1e9:
            continue
        kind = next((KINDS[c] for c in (6, 0, 1) if c in codes), None)
        if kind is None:
            kind = ("dwell" if known and bool(info.at[int(p), "dwell"]) else
                    "wait on M codes" if codes & WAIT_CODES else "standstill")
        grid = np.arange(t0, t1, 10_000_000, dtype=np.int64)
        spindle = _held(recording.streams.get("spindle"), "spindle_rpm", grid)
        rows.append({"kind": kind, "recorded_line": int(r["line"]), "program_line": int(p) if known else None,
                     "m_codes": " ".join(f"M{c}" for c in sorted(codes)), "t_start_ns": t0, "t_end_ns": t1,
                     "duration_s": still / 1e9,
                     "spindle_off": bool(np.any(spindle <= SPINDLE_OFF_RPM))})
    return pd.DataFrame(rows, columns=cols)


def events_report(recording: Recording, stream: str, program: Program, span_ns: tuple[int, int]) -> list[dict] | None:
    """A recording with positions and a line stream (its values program lines): its events as report
    rows (kind, lines, M codes, start from the span's start and duration in s, spindle off), or None
    without a line stream. Reported only: the motion comparison there is the geometric one."""
    table = recording.streams.get(stream)
    if table is None or "line" not in table.columns or len(table) < 2:
        return None
    runs = line_runs(table["t_ns"].to_numpy(np.int64), table["line"].to_numpy())
    lines = runs["line"].to_numpy(np.float64)
    events = find_events(recording, runs, np.where(lines > 0, lines, np.nan), program, span_ns=span_ns)
    return [{"kind": e["kind"], "recorded_line": e["recorded_line"], "program_line": e["program_line"],
             "m_codes": e["m_codes"], "t_s": (e["t_start_ns"] - span_ns[0]) / 1e9, "duration_s": e["duration_s"],
             "spindle_off": e["spindle_off"]} for e in events.to_dict("records")]


def anchors(recording: Recording, runs: pd.DataFrame, program: Program, expected: pd.Series) -> list[dict]:
    """Recorded lines the data ties to program lines: the spindle's restart after each M6 inside the
    motion (the program's first M3/M4 line after it), and the program end (its last block's line against
    the last recorded). A restart is the spindle turning on and staying on for SPINDLE_ON_S after being off
    inside the motion span; `expected`: seconds per program line (the first line > 0 starts the motion)."""
    info = line_codes(program)
    out = []
    spindle = recording.streams.get("spindle")
    moving = expected[expected > 0]
    if spindle is not None and "spindle_rpm" in spindle.columns and len(runs) and len(moving):
        t = spindle["t_ns"].to_numpy(np.int64)
        on = spindle["spindle_rpm"].to_numpy(np.float64) > SPINDLE_OFF_RPM
        edge = np.flatnonzero(on[1:] != on[:-1]) + 1          # sample indices where on/off changes
        t_edge = np.r_[t[edge], np.iinfo(np.int64).max]
        restarts = [t[k] for j, k in enumerate(edge) if on[k] and j > 0 and t[edge[j - 1]] >= runs["t_start_ns"].iloc[0]
                    and t_edge[j + 1] - t[k] >= SPINDLE_ON_S * 1e9]
        m6 = [int(ln) for ln, c in info["codes"].items() if 6 in c and ln > moving.index[0]]
        starts = [int(ln) for ln, c in info["codes"].items() if c & {3, 4}]
        for tool_line, t_on in zip(m6, restarts):
            after = [s for s in starts if s > tool_line]
            k = int(np.searchsorted(runs["t_start_ns"].to_numpy(np.int64), t_on, side="right") - 1)
            if after and k >= 0:
                out.append({"what": f"the spindle restart after the tool change (program line {tool_line})",
                            "recorded_line": int(runs["line"].iloc[k]), "program_line": after[0],
                            "tool_change_line": tool_line})
    if len(runs) and len(program.blocks) and len(moving):
        # the stream ends on the last move or on a block after it (M30 shows on some controllers, not others)
        # (a stream that stops on or before the last move says nothing: the recording may end early)
        last, end = int(runs["line"].iloc[-1]), int(program.blocks["line"].max())
        if last > int(moving.index[-1]):
            out.append({"what": "the program end", "recorded_line": last, "program_line": min(last, end)})
    return out


__all__ = ["KINDS", "MIN_STILL_S", "STILL_MM_MIN", "anchors", "events_report", "find_events", "line_codes",
           "motion_feed", "still_ns"]
