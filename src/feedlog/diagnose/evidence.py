"""Evidence from the data itself, independent of any simulation.

From the measured positions alone: per-axis peak velocity and acceleration (Savitzky-Golay
derivatives, `scipy.signal.savgol_filter`, and the *sustained* peak: the largest value held for
`SUSTAIN_S`, so a noise spike or a blend's instant does not count as a limit), the path speed
ceiling, speed plateaus of long feed moves against their programmed F, the number of stops, the
feedback's delay behind the command (least squares of the following error on the speed, per joint)
and how far the path leaves the program's corners (align's match distances against G64 P).

Each hypothesis family reads this for its own keys (`Family.describe`, `suggest`, `contradicts` in its
`hyp_*.py`): a fitted axis limit above the profile's needs the axis to have been seen going beyond the
profile's limit; one below it must not be exceeded by what was seen (`against_limit`). Evidence that
5 Hz data cannot carry (accelerations) is left out.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.signal import savgol_filter

from feedlog.diagnose.cases import Case, position_columns
from feedlog.profile import LINEAR_AXES, MachineProfile

SUSTAIN_S = 0.008        # a peak must be held this long
WINDOW_S = 0.021         # Savitzky-Golay window for velocities and accelerations (1 kHz: 21 samples)
MAX_PERIOD_ACC_S = 0.01  # accelerations only from data sampled at least this densely
MARGIN = 0.10            # relative margin when evidence decides against a fitted limit
PLATEAU_MIN_SAMPLES = 10


@dataclass
class AxisEvidence:
    axis: str
    unit: str                    # mm or deg
    peak_vel: float              # sustained peak |velocity| (unit/s)
    peak_acc: float | None       # sustained peak |acceleration| (unit/s^2); None when not observable
    travel: float                # total distance moved


@dataclass
class Evidence:
    axes: dict[str, AxisEvidence] = field(default_factory=dict)
    path_speed_ceiling_mm_s: float | None = None
    plateau_ratio: float | None = None          # median speed / programmed F on long feed moves
    plateau_blocks: int = 0
    stops: int = 0
    feedback_delay_s: dict[str, float] = field(default_factory=dict)
    blend_deviation_mm: float | None = None     # largest corner distance of the path from the program
    blend_tolerance_mm: float | None = None     # the largest G64 P of those corners
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return {"axes": {a: {"peak_vel": round(e.peak_vel, 4), "peak_acc": None if e.peak_acc is None else
                             round(e.peak_acc, 2), "unit": e.unit, "travel": round(e.travel, 3)}
                         for a, e in self.axes.items()},
                "path_speed_ceiling_mm_s": _round(self.path_speed_ceiling_mm_s, 4),
                "plateau_ratio": _round(self.plateau_ratio, 4), "plateau_blocks": self.plateau_blocks,
                "stops": self.stops, "feedback_delay_ms": {k: round(v * 1e3, 4) for k, v in self.feedback_delay_s.items()},
                "blend_deviation_mm": _round(self.blend_deviation_mm, 5),
                "blend_tolerance_mm": _round(self.blend_tolerance_mm, 5), "notes": self.notes}


def _round(v: float | None, n: int) -> float | None:
    return None if v is None or not np.isfinite(v) else round(float(v), n)


def sustained_peak(values: np.ndarray, n: int) -> float:
    """The largest level |values| stays at or above for n consecutive samples."""
    a = np.abs(np.asarray(values, dtype=np.float64))
    if len(a) < n or n <= 1:
        return float(a.max()) if len(a) else 0.0
    from numpy.lib.stride_tricks import sliding_window_view

    return float(sliding_window_view(a, n).min(axis=1).max())


def _derivatives(t_s: np.ndarray, pos: np.ndarray, period: float) -> tuple[np.ndarray, np.ndarray | None]:
    n = len(t_s)
    win = int(round(WINDOW_S / period)) | 1
    if period <= MAX_PERIOD_ACC_S and n > win >= 5:
        vel = savgol_filter(pos, win, 2, deriv=1, delta=period, axis=0)
        acc = savgol_filter(pos, win, 2, deriv=2, delta=period, axis=0)
        return vel, acc
    vel = np.gradient(pos, t_s, axis=0) if n > 2 else np.zeros_like(pos)
    return vel, None


def _motion(case: Case, profile: MachineProfile) -> tuple[np.ndarray, np.ndarray, list[str]]:
    axes = case.recording.streams["axes"]
    cols = [c for c in position_columns(profile) if c in axes.columns]
    t = axes["t_ns"].to_numpy(np.int64)
    span = case.alignment.report["motion"]
    keep = (t >= span["t_start_ns"] - int(0.05e9)) & (t <= span["t_end_ns"] + int(0.05e9))
    return (t[keep] - t[keep][0]) / 1e9, axes[cols].to_numpy(np.float64)[keep], cols


def gather(cases: list[Case], profile: MachineProfile) -> Evidence:
    """Evidence over all recordings of one machine."""
    ev = Evidence()
    peaks: dict[str, list[tuple[float, float | None, float]]] = {}
    ceilings, ratios, stops = [], [], 0
    for case in cases:
        t, pos, cols = _motion(case, profile)
        if len(t) < 3:
            continue
        vel, acc = _derivatives(t, pos, case.period_s)
        n = max(1, int(round(SUSTAIN_S / case.period_s))) if acc is not None else 1
        for i, col in enumerate(cols):
            axis = col.split("_")[0]
            peaks.setdefault(axis, []).append((sustained_peak(vel[:, i], n),
                                               None if acc is None else sustained_peak(acc[:, i], n),
                                               float(np.abs(np.diff(pos[:, i])).sum())))
        lin = [i for i, c in enumerate(cols) if c.split("_")[0] in LINEAR_AXES]
        speed = np.sqrt((vel[:, lin] ** 2).sum(axis=1))
        ceilings.append(sustained_peak(speed, n))
        stops += _stops(speed, case.period_s)
        ratios += _plateaus(case, t, speed)
        ev.feedback_delay_s.update(_feedback_delay(case))
    for axis, rows in peaks.items():
        accs = [r[1] for r in rows if r[1] is not None]
        ev.axes[axis] = AxisEvidence(axis=axis, unit="deg" if axis not in LINEAR_AXES else "mm",
                                     peak_vel=max(r[0] for r in rows), peak_acc=max(accs) if accs else None,
                                     travel=sum(r[2] for r in rows))
    ev.path_speed_ceiling_mm_s = max(ceilings) if ceilings else None
    if ratios:
        ev.plateau_ratio, ev.plateau_blocks = float(np.median(ratios)), len(ratios)
    ev.stops = stops
    ev.blend_deviation_mm, ev.blend_tolerance_mm = _blend_deviation(cases)
    if any(c.period_s > MAX_PERIOD_ACC_S for c in cases):
        ev.notes.append("accelerations are not observable at this sampling rate; acceleration evidence "
                        "comes from the densely sampled recordings only" if any(
                            c.period_s <= MAX_PERIOD_ACC_S for c in cases) else
                        "accelerations are not observable at this sampling rate")
    return ev


def _stops(speed: np.ndarray, period: float) -> int:
    moving = speed > max(0.02 * float(np.median(speed[speed > 0])) if (speed > 0).any() else 0.0, 1e-3)
    if not moving.any():
        return 0
    inner = moving[np.flatnonzero(moving)[0]:np.flatnonzero(moving)[-1] + 1]
    starts = np.flatnonzero(~inner[1:] & inner[:-1])
    return int(len(starts))


def _plateaus(case: Case, t: np.ndarray, speed: np.ndarray) -> list[float]:
    """Median path speed over the middle third of each long feed block / its programmed feed."""
    blocks = case.alignment.blocks
    need = {"t_start_ns", "t_end_ns", "feed_mm_min", "kind"}
    if not need <= set(blocks.columns):
        return []
    t0 = case.alignment.report["motion"]["t_start_ns"] - int(0.05e9)
    out = []
    for row in blocks.itertuples():
        if str(row.kind) not in ("linear", "arc_cw", "arc_ccw") or not np.isfinite(row.feed_mm_min):
            continue
        a, b = (row.t_start_ns - t0) / 1e9, (row.t_end_ns - t0) / 1e9
        lo, hi = a + (b - a) / 3, b - (b - a) / 3
        sel = (t >= lo) & (t <= hi)
        if sel.sum() >= PLATEAU_MIN_SAMPLES and row.feed_mm_min > 0:
            out.append(float(np.median(speed[sel])) * 60.0 / float(row.feed_mm_min))
    return out


def _feedback_delay(case: Case) -> dict[str, float]:
    """Per joint: the time the feedback trails the command, from the following error on the speed."""
    fb = case.feedback
    if fb is None:
        return {}
    err = fb.cmd - fb.fb
    v = np.gradient(fb.cmd, fb.dt_s, axis=0)
    out = {}
    for i, axis in enumerate(fb.axes):
        den = float(np.sum(v[:, i] ** 2))
        if den > 0:
            out[axis] = float(np.sum(err[:, i] * v[:, i]) / den)
    return out


def _blend_deviation(cases: list[Case]) -> tuple[float | None, float | None]:
    worst, tol = None, None
    for case in cases:
        pts = case.alignment.points
        if "dist_mm" not in pts.columns:
            continue
        d = pts["dist_mm"].to_numpy(np.float64)
        kind = pts["kind"].astype(str).to_numpy() if "kind" in pts.columns else np.full(len(d), "linear")
        feed = (kind != "rapid") & (kind != "start") & np.isfinite(d)
        if not feed.any():
            continue
        k = int(np.argmax(np.where(feed, d, -np.inf)))
        if worst is None or d[k] > worst:
            worst = float(d[k])
            blk = case.program.blocks.set_index("block")
            p = blk["tol_mm"].get(int(pts["block"].iloc[k]), np.nan) if "block" in pts.columns else np.nan
            tol = None if not np.isfinite(p) else float(p)
    return worst, tol


def against_limit(seen: float | None, profile_value: Any, fitted: Any) -> str | None:
    """How what was seen rules out a fitted limit: 'above' (a limit above the profile's, but nothing was
    seen beyond the profile's), 'below' (a limit below the profile's, but something was seen far beyond
    it) or None. The families of limits word it (`hyp_axes`, `hyp_path`)."""
    if seen is None or not (isinstance(fitted, (int, float)) and isinstance(profile_value, (int, float))):
        return None
    if fitted > profile_value * (1 + MARGIN) and seen < profile_value * (1 + MARGIN):
        return "above"
    if fitted < profile_value and seen > fitted * (1 + 5 * MARGIN):
        return "below"
    return None


def seed(seen: float | None) -> tuple[float, ...]:
    """A value the data points at as a search seed: () when there is none (missing, not finite, not positive)."""
    if seen is None or not np.isfinite(seen) or seen <= 0:
        return ()
    return (float(seen),)
