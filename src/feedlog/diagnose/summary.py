"""A diagnosis as words and as JSON: the few lines a user reads first, and the stable `--json` object.

`summary_lines(dx)` puts the answer first: how far the simulation is off, each cause with its fitted
value, evidence and where the time went, the extended profile's error (and held out), then what
stays unexplained. `to_json(dx)` is the `--json` contract of docs/diagnose.md: `profile`,
`recordings`, `error_before_pct`, `error_after_pct`, `feedback_rms_before_mm`, `feedback_rms_after_mm`,
`held_out`, `levels`, `findings`, `unexplained`, `profile_out`, plus `evidence`, `noise_floor`,
`rejected` and `timings_s`. Every number is finite or null.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd


def _fmt(v: Any, unit: str = "") -> str:
    if isinstance(v, bool) or v is None:
        return str(v).lower() if isinstance(v, bool) else "off"
    if isinstance(v, (int, np.integer)):
        text = f"{int(v)}"
    elif isinstance(v, (float, np.floating)):
        text = "unlimited" if math.isinf(v) else f"{float(v):.4g}"
    else:
        text = str(v)
    return f"{text} {unit}".rstrip() if unit and text not in ("unlimited",) else text


def _signed(pct: float | None) -> str:
    if pct is None or not math.isfinite(pct):
        return "n/a"
    return f"{abs(pct):.2f} % {'long' if pct > 0 else 'short'}" if abs(pct) >= 0.005 else "0.00 %"


def summary_lines(dx) -> list[str]:
    cyc = dx.levels["cycle"]
    n = len(dx.cases)
    lines = [f"simulation {_signed(cyc['error_before_pct'])} on {n} recording{'s' if n != 1 else ''} "
             f"({cyc['measured_s']:.3f} s measured, {cyc['simulated_before_s']:.3f} s simulated)"]
    for i, f in enumerate(dx.findings, 1):
        profile = "off" if f.profile_value is None else _fmt(f.profile_value, f.unit)
        what = f"{f.parameter} = {_fmt(f.fitted_value, f.unit)} ({'switched on; was off' if f.kind == 'mechanism' else 'profile ' + profile})"
        extra = [x for x in (f.evidence, f.where and f"where: {f.where}") if x]
        alts = "; or equally " + ", ".join(f"{a['parameter']} = {_fmt(a['fitted_value'], a['unit'])}"
                                          for a in f.alternatives) if f.alternatives else ""
        lines.append(f"cause {i}: {what}{': ' if extra else ''}{'; '.join(extra)}{alts}")
        if f.alternatives:
            sep = f.separated_by
            lines.append(f"  to tell them apart record: {sep['program']} (predicted {sep['cycle_s'][0]:.3f} s "
                         f"against {sep['cycle_s'][1]:.3f} s)" if sep else
                         "  no calibration air-cut tells them apart: record other kinds of programs")
    if dx.calibration is not None:
        lines += calibration_lines(dx.calibration)
    held = dx.held_out or {}
    held_text = ""
    if held.get("recordings"):
        held_text = " (held out: " + ", ".join(f"{r['name']} {_signed(r['error_after_pct'])}"
                                              for r in held["recordings"]) + ")"
    fb = dx.levels.get("feedback")
    fb_text = ""
    if fb and fb.get("rms_before_mm") is not None:
        fb_text = f"; feedback RMS {fb['rms_before_mm'] * 1e3:.2f} -> {fb['rms_after_mm'] * 1e3:.2f} um"
    if dx.changes and not dx.findings and dx.calibration is None:
        lines.append("no single value explains the data: a parameter changed during a session (below); the "
                     "profile keeps its value for it")
    elif dx.findings or dx.calibration is not None:
        target = dx.profile_out or "(not written; pass -o DIR)"
        lines.append(f"extended profile {target}: error {_signed(cyc['error_before_pct'])} -> "
                     f"{_signed(cyc['error_after_pct'])}{held_text}{fb_text}")
    else:
        lines.append("no cause found: no registered hypothesis removes a material, repeatable share of the "
                     "held-out residual" + (f" (noise floor {dx.noise_floor['timing_pct']:.2f} %)"
                                           if dx.noise_floor.get("timing_pct") is not None else ""))
    lines += [c.text() for c in dx.changes]
    for u in dx.unexplained:
        text = (f"unexplained ({u['level']}), cause unknown: {u['error_pct']:.2f} % of the time misplaced, "
                f"{u['systematic_share_pct']:.0f} % of it systematic; {u['where']}")
        if (u.get("signature") or {}).get("text"):
            text += f"; signature: {u['signature']['text']}"
        if u.get("error_after_class_model_pct") is not None:
            text += (f"; learned correction (block classes): held-out error {u['error_pct']:.2f} % -> "
                     f"{u['error_after_class_model_pct']:.2f} %")
        lc = u.get("learned_correction") or {}
        if "gain_pct" in lc:
            text += (f"; learned correction (hybrid): held-out error {lc['mean_abs_error_before_pct']:.2f} % -> "
                     f"{lc['mean_abs_error_after_pct']:.2f} %" + ("" if lc["gain_pct"] > 0 else " (does not generalise)"))
        lines.append(text)
    return lines


def calibration_lines(cal) -> list[str]:
    """Per calibrated parameter: its value and whether the recordings constrain it."""
    out = []
    for p in cal.parameters:
        axis, limit = p.key.split(".")[1:]
        seen = cal.axes.get(axis, {})
        obs = seen.get("vel_observed" if limit == "vel_max" else "acc_observed")
        obs_text = "" if obs is None else f"; seen up to {obs:.4g}"
        if p.constrained:
            out.append(f"calibrated {p.key} = {p.fitted_value:.4g} (profile {p.profile_value:.4g}), constrained: "
                       f"{p.interval[0]:.4g} .. {p.interval[1]:.4g}{obs_text}")
        elif p.pair:
            out.append(f"calibrated {p.key} = {p.fitted_value:.4g}: NOT constrained on its own, a pair with "
                       f"{p.pair} (below){obs_text}")
        else:
            low = "" if p.interval[0] is None else f" at least {p.interval[0]:.4g}"
            out.append(f"calibrated {p.key} = {p.fitted_value:.4g}: NOT constrained by these recordings{low}"
                       f"{obs_text}; record a program that drives it (feedlog program --calibration)")
    for r in cal.pairs:
        (v, a), ends = r.keys, (r.low, r.high)
        reach = ["" if not o else (" or lower" if i == 0 else " or higher") for i, o in enumerate(r.open_ends)]
        out.append(f"pair {v} and {a}: these recordings fit as well with {ends[0][v]:.4g}{reach[0]} and {ends[0][a]:.4g} "
                   f"as with {ends[1][v]:.4g}{reach[1]} and {ends[1][a]:.4g} (fitted {r.fitted[v]:.4g} and "
                   f"{r.fitted[a]:.4g}): the pair is pinned, each alone is not")
        sep = r.separated_by
        out.append(f"  to tell them apart record: {sep['program']} (predicted {sep['cycle_s'][0]:.3f} s against "
                   f"{sep['cycle_s'][1]:.3f} s at the two ends)" if sep else
                   "  no calibration air-cut tells them apart: record other kinds of programs")
    for h in cal.held_out:
        out.append(f"  held out {h['recording']}: {_signed(h['error_before_pct'])} -> {_signed(h['error_after_pct'])}")
    return out


def clean(obj: Any) -> Any:
    """JSON-ready: numpy to Python, non-finite floats to None, DataFrames dropped."""
    if isinstance(obj, dict):
        return {str(k): clean(v) for k, v in obj.items() if not isinstance(v, pd.DataFrame)}
    if isinstance(obj, (list, tuple)):
        return [clean(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return clean(obj.tolist())
    return obj


def to_json(dx) -> dict[str, Any]:
    cyc = dx.levels["cycle"]
    fb = dx.levels.get("feedback") or {}
    rejected = []
    for level, sel in dx.selections.items():
        for j in sel.rejected[:5]:
            rejected.append({"level": level, "parameter": j.key, "fitted_value": j.held.value,
                             "gain_pct": 100 * j.held.gain, "reasons": j.reasons})
    levels = {k: v for k, v in dx.levels.items()}
    return clean({
        "profile": dx.profile.name, "recordings": dx.recordings,
        "error_before_pct": cyc["error_before_pct"], "error_after_pct": cyc["error_after_pct"],
        "feedback_rms_before_mm": fb.get("rms_before_mm"), "feedback_rms_after_mm": fb.get("rms_after_mm"),
        "held_out": dx.held_out, "levels": levels,
        "findings": [f.as_dict() for f in dx.findings], "unexplained": dx.unexplained,
        "changes": [c.as_dict() for c in dx.changes],
        "profile_out": dx.profile_out, "profile_diff": [{"key": k, "before": a, "after": b} for k, a, b in dx.diff],
        "evidence": dx.evidence.as_dict(), "noise_floor": dx.noise_floor, "rejected": rejected,
        "where": {k: v for k, v in dx.where.items() if k in ("before", "after", "classes_before", "top_segments")},
        "notes": {c.name: c.notes for c in dx.cases if c.notes},
        "holds": {c.name: [{"kind": h["kind"], "line": h["line"], "block": h["block"],
                            "t_s": (h["t_start_ns"] - c.t0_ns) / 1e9, "duration_s": h["duration_s"],
                            "removed": bool(h["removed"])} for h in c.holds.to_dict("records")]
                  for c in dx.cases if c.holds is not None and len(c.holds)},
        "summary": summary_lines(dx), "timings_s": dx.timings_s,
        **({"calibration": dx.calibration.as_dict()} if dx.calibration is not None else {})})
