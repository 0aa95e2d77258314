"""`feedlog diagnose REC` with no program: what the recorded data alone says about the machine.

Without the part program nothing can be simulated, so nothing can be compared; what the data holds
by itself is measured (`measure(recordings) -> DataOnly`):

- **per axis**: the peak speed and acceleration, and the highest level each was *held* at (a
  plateau: a run of samples staying within a band for a minimum time). Speeds are Savitzky-Golay
  derivatives of the positions (window 10 ms / 20 ms for the acceleration, at least 5 / 7 samples);
  a recording sampled slower than `SPARSE_S` gives no acceleration, and its speeds between samples
  are averages (the `velocity` stream's axis speeds are used where the recording has one);
- **feed plateaus**: the path speeds held longest (the `feed` stream, else the speed of the linear
  axes), and the time at standstill inside the motion;
- **the envelope**: each axis's travelled range;
- **a generic profile where the data constrains it**: an axis's `acc_max` where it held its top
  acceleration accelerating alone (a controller accelerates at its limit; a planner may use a share of
  it). Speeds are never claimed as limits: a speed plateau is the programmed F or a limit, and only the
  program tells which (on the bundled `mix_*` recordings every axis holds 49.9 mm/s alone, their F3000,
  under a 100 mm/s limit). Every other value is a lower bound (the machine can do at least this).

`DataOnly.would_add` lists what a program would add. The recording's own warnings (unit checks,
gaps) are carried along. `no_program_report` prints and writes the result.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from feedlog.recording import PROGRAM_ATTACHMENT, Recording

SPARSE_S = 0.05            # a sample period above this: no acceleration from positions
VEL_WINDOW_S, ACC_WINDOW_S = 0.010, 0.020
VEL_REL, ACC_REL, FEED_REL = 0.01, 0.02, 0.01       # plateau bands (share of the level)
VEL_MIN_S, ACC_MIN_S, FEED_MIN_S = 0.05, 0.012, 0.1  # shortest plateau counted
ALONE = 0.02               # other axes below this share of the axis's level: it moved (accelerated) alone
REST = 0.05                # plateaus below this share of the peak are rest, not a held speed or acceleration
LINEAR, ROTARY = ("x", "y", "z", "u", "v", "w"), ("a", "b", "c")

WOULD_ADD = (
    "the simulated cycle and every block's simulated time beside the measured one, and the share of the "
    "difference each cause takes",
    "whether a speed plateau is the programmed F or a limit (the program says what was asked for), "
    "hence the axes' speed limits",
    "which limit slows each block down: axis speed or acceleration, jerk, look-ahead, corner tolerance, "
    "block-time floor, override",
    "held-out fits of the profile's values and mechanisms (what `feedlog diagnose --program` does), "
    "instead of the lower bounds above",
    "the line stream matched to the program's blocks (durations per block, tool changes, dwells)",
)


@dataclass
class Held:
    """The highest level a signal was held at: `value` (duration-weighted), its plateaus and their time."""

    value: float
    count: int
    seconds: float
    alone: bool = False        # (speeds) one of its plateaus had every other axis at rest


@dataclass
class AxisFacts:
    axis: str
    unit: str                  # mm or deg
    minimum: float
    maximum: float
    peak_speed: float | None = None           # unit/s
    held_speed: Held | None = None
    peak_acc: float | None = None             # unit/s^2
    held_acc: Held | None = None
    speed_from: str = "positions"             # positions | velocity stream | positions (averages between samples)
    acc_limit: bool = False                   # the data constrains acc_max (see the module docstring)

    @property
    def range(self) -> float:
        return self.maximum - self.minimum


@dataclass
class DataOnly:
    recordings: list[str]
    duration_s: float
    period_s: float | None
    axes: dict[str, AxisFacts] = field(default_factory=dict)
    feed_source: str = ""                     # feed stream | linear axes | ""
    peak_feed_mm_min: float | None = None
    plateaus: list[dict[str, float]] = field(default_factory=list)   # level_mm_min, seconds, count
    motion_s: float = 0.0
    standstill_s: float = 0.0
    lines: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    would_add: tuple[str, ...] = WOULD_ADD

    def profile_values(self) -> dict[str, float]:
        """Dotted profile keys the data constrains -> value (see the module docstring)."""
        out = {}
        for a in self.axes.values():
            if a.acc_limit and a.held_acc is not None:
                out[f"axes.{a.axis}.acc_max"] = round(float(a.held_acc.value), 1)
        return out


def carries_program(path: str | Path) -> bool:
    """Whether a recording file carries a program (read from its attachment index; True when that
    cannot be told: the ordinary path then reads the file and says what is wrong with it)."""
    try:
        from mcap.reader import make_reader

        with open(path, "rb") as f:
            return any(a.name == PROGRAM_ATTACHMENT for a in make_reader(f).iter_attachments())
    except Exception:  # noqa: BLE001 - any doubt: the ordinary diagnosis decides
        return True


# -- signals ------------------------------------------------------------------------------------------
def _window(period_s: float, span_s: float, minimum: int) -> int:
    n = max(minimum, int(round(span_s / period_s)))
    return n + 1 - n % 2


def derivatives(t_ns: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, float]:
    """Speed and acceleration of positions `p` (None: too sparse for an acceleration) and the period."""
    from scipy.signal import savgol_filter

    dt = np.diff(t_ns) / 1e9
    period = float(np.median(dt)) if len(dt) else 0.0
    if len(p) < 3 or period <= 0:
        return np.zeros(len(p)), None, period
    regular = float(np.std(dt)) <= 0.05 * period
    nv, na = _window(period, VEL_WINDOW_S, 5), _window(period, ACC_WINDOW_S, 7)
    if period > SPARSE_S or not regular or len(p) < na:
        t = t_ns / 1e9
        v = np.gradient(p, t)
        return v, (None if period > SPARSE_S or len(p) < na else np.gradient(v, t)), period
    return (savgol_filter(p, nv, 2, deriv=1, delta=period),
            savgol_filter(p, na, 2, deriv=2, delta=period), period)


def plateaus(values: np.ndarray, t_ns: np.ndarray, *, rel: float, floor: float, min_s: float) -> list[tuple]:
    """Runs of samples that stay within `rel` of their running mean (or `floor`) for at least `min_s`:
    (level, start index, end index (exclusive), seconds). A run lasts until the next sample after it."""
    out = []
    n = len(values)
    i = 0
    while i < n:
        total, k, j = float(values[i]), 1, i + 1
        while j < n and abs(values[j] - total / k) <= max(rel * abs(total / k), floor):
            total += float(values[j])
            k += 1
            j += 1
        seconds = (t_ns[min(j, n - 1)] - t_ns[i]) / 1e9
        if seconds >= min_s and k >= 2:
            out.append((total / k, i, j, seconds))
        i = j
    return out


def top_held(runs: list[tuple], alone: list[bool], *, rel: float, minimum: float = 0.0) -> Held | None:
    """The highest plateau level (plateaus below `minimum` are rest, not held): its duration-weighted
    value, the plateaus within `rel` of it, their time, and whether one of them had the other axes (of
    its kind) still (`alone`, one flag per run)."""
    if not runs or max(abs(r[0]) for r in runs) <= minimum:
        return None
    top = max(abs(r[0]) for r in runs)
    group = [k for k, r in enumerate(runs) if abs(abs(r[0]) - top) <= rel * top]
    seconds = sum(runs[k][3] for k in group)
    value = sum(abs(runs[k][0]) * runs[k][3] for k in group) / seconds
    return Held(float(value), len(group), round(float(seconds), 4), any(alone[k] for k in group))


def cluster(runs: list[tuple], rel: float) -> list[dict[str, float]]:
    """Plateau levels merged within `rel`, longest total time first."""
    out: list[dict[str, float]] = []
    for level, _, _, seconds in sorted(runs, key=lambda r: -r[3]):
        for c in out:
            if abs(level - c["level"]) <= rel * max(abs(c["level"]), 1e-9):
                c["seconds"] += seconds
                c["count"] += 1
                break
        else:
            out.append({"level": level, "seconds": seconds, "count": 1})
    return sorted(out, key=lambda c: -c["seconds"])


# -- the measurement ------------------------------------------------------------------------------------
def _axis_columns(table: pd.DataFrame, suffixes: tuple[str, ...]) -> dict[str, tuple[str, str]]:
    """axis letter -> (column, unit) for columns named like x_mm, a_deg (or x_mm_s with suffix _s)."""
    out = {}
    for col in table.columns:
        for suffix in suffixes:
            head, sep, unit = col.partition("_")
            if sep and unit == suffix and head in LINEAR + ROTARY:
                out[head] = (col, "mm" if head in LINEAR else "deg")
    return out


class _Axis:
    """What is gathered for one axis over every recording."""

    def __init__(self, axis: str, unit: str) -> None:
        self.axis, self.unit = axis, unit
        self.lo, self.hi = np.inf, -np.inf
        self.peak_v = 0.0
        self.peak_a: float | None = None
        self.v_runs: list[tuple] = []
        self.alone: list[bool] = []
        self.a_runs: list[tuple] = []
        self.a_alone: list[bool] = []
        self.speed_from = "positions"


def _speeds(rec: Recording, gathered: dict[str, _Axis], notes: list[str]) -> tuple[float | None, np.ndarray | None,
                                                                                     np.ndarray | None]:
    """Speeds and accelerations of one recording into `gathered`; its period and linear path speed."""
    axes = rec.streams.get("axes")
    if axes is not None:
        axes = _distinct_times(axes)
    if axes is None or len(axes) < 3:
        return None, None, None
    t = axes["t_ns"].to_numpy(np.int64)
    columns = _axis_columns(axes, ("mm", "deg"))
    velocity = rec.streams.get("velocity")
    if velocity is not None:
        velocity = _distinct_times(velocity)
    vcols = _axis_columns(velocity, ("mm_s", "deg_s")) if velocity is not None and len(velocity) >= 3 else {}
    speeds: dict[str, np.ndarray] = {}
    accs: dict[str, np.ndarray] = {}
    period = None
    for axis, (col, unit) in columns.items():
        p = axes[col].to_numpy(float)
        g = gathered.setdefault(axis, _Axis(axis, unit))
        g.lo, g.hi = min(g.lo, float(p.min())), max(g.hi, float(p.max()))
        v, a, period = derivatives(t, p)
        if period > SPARSE_S:
            g.speed_from = "positions (averages between samples)"
        if a is not None:
            g.peak_a = max(g.peak_a or 0.0, float(np.abs(a).max()))
            accs[axis] = a
        speeds[axis] = v
    for axis, a in accs.items():
        g = gathered[axis]
        runs = [r for r in plateaus(np.abs(a), t, rel=ACC_REL, floor=0.0, min_s=ACC_MIN_S) if r[0] > 0]
        g.a_runs += runs
        g.a_alone += [_alone(accs, axis, i, j, level) for level, i, j, _s in runs]
    if vcols:   # an axis speed the controller reports beats averages between sparse positions
        tv = velocity["t_ns"].to_numpy(np.int64)
        for axis, (col, _unit) in vcols.items():
            if axis in gathered and (period or 0) > SPARSE_S:
                g = gathered[axis]
                g.speed_from = "velocity stream"
                v = velocity[col].to_numpy(float)
                g.peak_v = max(g.peak_v, float(np.abs(v).max()))
                g.v_runs += plateaus(np.abs(v), tv, rel=VEL_REL, floor=0.0, min_s=VEL_MIN_S)
                g.alone += [False] * (len(g.v_runs) - len(g.alone))   # (no time base shared with the others)
    for axis, v in speeds.items():
        g = gathered[axis]
        if g.speed_from == "velocity stream":
            continue
        g.peak_v = max(g.peak_v, float(np.abs(v).max()))
        runs = [r for r in plateaus(np.abs(v), t, rel=VEL_REL, floor=0.0, min_s=VEL_MIN_S) if r[0] > 0]
        g.alone += [_alone(speeds, axis, i, j, level) for level, i, j, _s in runs]
        g.v_runs += runs
    if period is not None and period > SPARSE_S:
        notes.append(f"{Path(rec.source).name or 'recording'}: positions every {period:.3g} s: no acceleration "
                     "from them, speeds between samples are averages")
    linear = [speeds[a] for a in speeds if a in LINEAR]
    path = np.sqrt(np.sum(np.square(linear), axis=0)) * 60.0 if linear else None
    return period, t, path


def _distinct_times(table: pd.DataFrame) -> pd.DataFrame:
    """Samples sharing a time (a source that stamps in bunches): the last one holds."""
    if len(table) < 2:
        return table
    return table[np.append(np.diff(table["t_ns"].to_numpy(np.int64)) > 0, True)]


def _alone(signals: dict[str, np.ndarray], axis: str, i: int, j: int, level: float) -> bool:
    """Whether every other axis of the same kind (linear, rotary) stayed below ALONE x `level` in i..j."""
    kind = LINEAR if axis in LINEAR else ROTARY
    return all(float(np.abs(s[i:j]).max()) < ALONE * level for o, s in signals.items() if o != axis and o in kind)


def _feed(rec: Recording, t: np.ndarray | None, path: np.ndarray | None) -> tuple[str, np.ndarray, np.ndarray] | None:
    feed = rec.streams.get("feed")
    if feed is not None and "feed_mm_min" in feed.columns and len(feed) >= 2:
        return "feed stream", feed["t_ns"].to_numpy(np.int64), feed["feed_mm_min"].to_numpy(float)
    if path is not None and t is not None:
        return "linear axes", t, path
    return None


def feed_check(tf: np.ndarray, f: np.ndarray, t: np.ndarray, path: np.ndarray, *, tol: float = 0.05) -> str:
    """The feed stream against the path speed of the linear axes' positions: a sentence when their median
    ratio over moving samples is off by more than `tol` (a unit, a scale or a clock that is off), else ""."""
    at = np.interp(tf, t, path)
    moving = (at > 0.05 * at.max()) & (f > 0.05 * max(float(f.max()), 1e-9)) if len(at) and at.max() > 0 else []
    if np.count_nonzero(moving) < 10:
        return ""
    ratio = float(np.median(f[moving] / at[moving]))
    if abs(ratio - 1.0) <= tol:
        return ""
    return (f"the feed stream reads {ratio:.3f} x the path speed of the positions (median over "
            f"{int(np.count_nonzero(moving))} moving samples): a unit, a scale or a clock that is off? The feed "
            "plateaus above are the stream's")


def measure(recordings: Sequence[Recording]) -> DataOnly:
    """What the recordings alone say (see the module docstring); recordings of one machine."""
    from feedlog.diagnose.cases import DiagnoseError

    gathered: dict[str, _Axis] = {}
    notes: list[str] = []
    warnings: list[str] = []
    feed_runs: list[tuple] = []
    feed_sources: set[str] = set()
    peak_feed = None
    motion_s = standstill_s = duration_s = 0.0
    periods = []
    line_changes = 0
    line_values: set[int] = set()
    held_lines: dict[int, float] = {}
    for rec in recordings:
        name = Path(rec.source).name or "recording"
        duration_s += rec.duration_s
        for key in ("unit_check", "program_lines", "position_jumps"):
            if rec.metadata.get(key):
                warnings.append(f"{name}: {key}: {rec.metadata[key]}")
        if rec.dropped_frames:
            warnings.append(f"{name}: {rec.dropped_frames} samples or observations were lost while recording")
        period, t, path = _speeds(rec, gathered, notes)
        if period is not None:
            periods.append(period)
        found = _feed(rec, t, path)
        if found is not None and found[0] == "feed stream" and path is not None and (period or 1.0) <= SPARSE_S:
            check = feed_check(found[1], found[2], t, path)
            if check:
                warnings.append(f"{name}: {check}")
        if found is not None:
            source, tf, f = found
            feed_sources.add(source)
            peak_feed = max(peak_feed or 0.0, float(np.max(np.abs(f))))
            feed_runs += [r for r in plateaus(f, tf, rel=FEED_REL, floor=0.5, min_s=FEED_MIN_S) if r[0] >= 1.0]
            moving = np.abs(f) >= max(1.0, 0.005 * float(np.max(np.abs(f))))
            if moving.any():
                first, last = np.argmax(moving), len(moving) - 1 - np.argmax(moving[::-1])
                dt = np.diff(tf[first:last + 1]) / 1e9
                motion_s += float(dt.sum())
                standstill_s += float(dt[~moving[first:last]].sum())
        line = rec.streams.get("line")
        if line is not None and "line" in line.columns and len(line):
            values = line["line"].to_numpy(np.int64)
            tl = line["t_ns"].to_numpy(np.int64)
            change = np.flatnonzero(np.diff(values) != 0) + 1
            line_changes += len(change)
            line_values.update(int(v) for v in np.unique(values))
            starts = np.concatenate(([0], change))
            ends = np.concatenate((change, [len(values) - 1]))
            for s, e in zip(starts, ends):
                held_lines[int(values[s])] = held_lines.get(int(values[s]), 0.0) + (tl[e] - tl[s]) / 1e9
    if not gathered and not feed_sources and not line_values:
        names = ", ".join(Path(r.source).name for r in recordings)
        raise DiagnoseError(f"{names}: no positions, feed or line stream: nothing to measure without a program")
    out = DataOnly([r.source for r in recordings], round(duration_s, 3), min(periods) if periods else None,
                   notes=notes, warnings=warnings)
    _axis_facts(out, gathered)
    if not gathered:
        out.notes.append("no positions: axis speeds, accelerations and the working envelope are unknown")
    out.feed_source = " + ".join(sorted(feed_sources))
    out.peak_feed_mm_min = peak_feed
    out.plateaus = [{"level_mm_min": round(c["level"], 2), "seconds": round(c["seconds"], 3), "count": c["count"]}
                    for c in cluster(feed_runs, FEED_REL)[:8]]
    out.motion_s, out.standstill_s = round(motion_s, 3), round(standstill_s, 3)
    if line_values:
        longest = sorted(held_lines.items(), key=lambda kv: -kv[1])[:5]
        out.lines = {"distinct": len(line_values), "changes": line_changes, "first": min(line_values),
                     "last": max(line_values), "longest": [{"line": k, "seconds": round(v, 3)} for k, v in longest]}
    return out


def _axis_facts(out: DataOnly, gathered: dict[str, _Axis]) -> None:
    for axis in sorted(gathered, key=lambda a: (LINEAR + ROTARY).index(a)):
        g = gathered[axis]
        facts = AxisFacts(axis, g.unit, round(float(g.lo), 6), round(float(g.hi), 6), round(float(g.peak_v), 4),
                          top_held(g.v_runs, g.alone, rel=VEL_REL, minimum=REST * g.peak_v),
                          None if g.peak_a is None else round(float(g.peak_a), 2),
                          top_held(g.a_runs, g.a_alone, rel=ACC_REL, minimum=REST * (g.peak_a or 0.0)), g.speed_from)
        facts.acc_limit = facts.held_acc is not None and facts.held_acc.alone
        out.axes[axis] = facts


def read_all(paths: Sequence[str | Path]) -> list[Recording]:
    from feedlog.ingest import read_recording

    return [read_recording(p) for p in paths]
