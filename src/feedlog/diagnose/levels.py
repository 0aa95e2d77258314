"""Before and after, at every level the data supports.

- **cycle**: measured vs simulated cycle time per recording (the simulation's motion span taken as
  the recording's was, `residuals.sim_span`; on sparse data from the first to the last moving sample,
  `sampled_cycle`);
- **timing**: the segment residuals (`residuals`), as an RMS in ms and as misplaced time (%);
- **samples**: per axis, positions, velocities and (dense data) accelerations over time since motion
  start, measured against simulated; and the path speed along the program (`progress_curves`:
  both trajectories mapped onto program arc length through the segment anchors, so the speed at a
  place is compared with the speed at the same place even where the timing differs);
- **feedback**: feedback positions predicted from the recording's own command against measured.

`held_out` re-scores every held-out unit with the values fitted without it; `where` attributes the
timing residuals to block classes (`attribution`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from feedlog.diagnose.attribution import class_table, segment_table, top_segments, where_text
from feedlog.diagnose.cases import Case, position_columns
from feedlog.diagnose.evidence import _derivatives
from feedlog.diagnose.residuals import (feedback_residual, geometry_residual, rms, sample_bounds, sim_span, simulated_segments,
                                        timing_residual)
from feedlog.profile import LINEAR_AXES, MachineProfile
from feedlog.toolpath.schema import AXIS_UNITS

GRID = 2000   # points along the program for the speed profiles


def simulate_all(cases: list[Case], profile: MachineProfile) -> list[Any]:
    from feedlog.sim import simulate

    return [simulate(c.sim_input, profile) for c in cases]


def _sim_positions(case: Case, sim, t_rel: np.ndarray, cols: list[str]) -> np.ndarray:
    """Simulated positions (machine frame) at times since the simulation's motion start."""
    start, _ = sim_span(case, sim)
    traj = sim.trajectory
    t, pos = traj.t_s - start, traj.pos
    names = [f"{a}_{AXIS_UNITS[a]}" for a in sim.profile.axis_names]
    out = np.column_stack([np.interp(t_rel, t, pos[:, names.index(c)]) for c in cols])
    offsets = [c for c in ("wx_mm", "wy_mm", "wz_mm") if c in case.program.blocks.columns]
    if len(offsets) == 3:
        w = case.program.blocks[offsets].to_numpy(np.float64)
        if np.nan_to_num(w).any():
            ids = sim._ctx_blocks.block.take(traj.row)
            per = pd.DataFrame(np.nan_to_num(w), index=case.program.blocks["block"].to_numpy()).reindex(ids).to_numpy()
            add = np.column_stack([np.interp(t_rel, t, per[:, i]) for i in range(3)])
            for i, c in enumerate(("x_mm", "y_mm", "z_mm")):
                if c in cols:
                    out[:, cols.index(c)] += add[:, i]
    return out


def _measured(case: Case, profile: MachineProfile) -> tuple[np.ndarray, np.ndarray, list[str]]:
    axes = case.recording.streams["axes"]
    cols = [c for c in position_columns(profile) if c in axes.columns]
    raw = (axes["t_ns"].to_numpy(np.int64) - case.t0_ns) / 1e9
    t = case.compared_s(raw)         # feed holds taken out, as the comparison has them
    keep = (t >= 0) & (t <= case.cycle_s) & ~case.in_hold(raw)
    return t[keep], axes[cols].to_numpy(np.float64)[keep], cols


def measured_cycle(case: Case, profile: MachineProfile) -> float:
    """The recording's cycle time, measured again with `profile` where measuring needs a model: at 5 Hz
    align places motion start and end inside their sampling intervals with a simulation of the profile,
    which the extended profile does better."""
    if not case.sparse:
        return case.cycle_s
    from feedlog.align import align_recording
    from feedlog.errors import FeedlogError

    try:
        return float(align_recording(case.recording, case.program, profile=profile).cycle_time_s)
    except FeedlogError:
        return case.cycle_s


def sampled_cycle(case: Case, before, after) -> tuple[float, float, float] | None:
    """Sparse data: (measured, simulated before, simulated after) time from the first to the last sample
    that shows the tool moving, the simulations cut alike (`residuals.sample_bounds`). Motion start and
    end fall between samples, where only a model could place them; this span no model placed, and the
    timing segments add up to it. None on dense data or where a side is not known."""
    span = case.span_samples if case.sparse else None
    if span is None or span[0] is None or span[1] is None or not span[1][0] > span[0][0]:
        return None
    (fb, lb), (fa, la) = sample_bounds(case, before), sample_bounds(case, after)
    return span[1][0] - span[0][0], lb - fb, la - fa


def sample_residuals(case: Case, profile: MachineProfile, sim) -> dict[str, dict[str, float | None]]:
    """Per axis RMS of simulated minus measured position, velocity and acceleration over time."""
    t, pos, cols = _measured(case, profile)
    if len(t) < 3:
        return {}
    spos = _sim_positions(case, sim, t, cols)
    mv, ma = _derivatives(t, pos, case.period_s)
    sv, sa = _derivatives(t, spos, case.period_s)
    out = {}
    for i, c in enumerate(cols):
        axis = c.split("_")[0]
        out[axis] = {"position": rms(spos[:, i] - pos[:, i]), "velocity": rms(sv[:, i] - mv[:, i]),
                     "acceleration": None if ma is None else rms(sa[:, i] - ma[:, i])}
    return out


def _path_length(pos: np.ndarray, lin: list[int]) -> np.ndarray:
    step = np.sqrt((np.diff(pos[:, lin], axis=0) ** 2).sum(axis=1)) if lin else np.zeros(len(pos) - 1)
    return np.concatenate([[0.0], np.cumsum(step)])


def _anchor_progress(case: Case, anchors: np.ndarray) -> np.ndarray:
    """Program arc length at the end of each anchor block (the last anchor: the whole program)."""
    blocks = case.program.blocks
    length = blocks["length_mm"].fillna(0.0).to_numpy(np.float64)
    cum = pd.Series(np.cumsum(length), index=blocks["block"].to_numpy())
    s = cum.reindex(anchors[:-1]).to_numpy(np.float64)
    return np.append(s, cum.iloc[-1] if len(cum) else 0.0)


def progress_curves(case: Case, profile: MachineProfile, segments, sims: dict[str, Any]) -> pd.DataFrame | None:
    """Path speed (mm/min) and time along the program (s_mm) for the recording and each simulation."""
    from feedlog.diagnose.evidence import _derivatives as derivs

    t, pos, cols = _measured(case, profile)
    lin = [i for i, c in enumerate(cols) if c.split("_")[0] in LINEAR_AXES]
    if len(t) < 3 or len(segments) < 1:
        return None
    s_anchor = np.concatenate([[0.0], _anchor_progress(case, segments.anchors)])
    if not np.all(np.isfinite(s_anchor)) or s_anchor[-1] <= 0:
        return None
    vel, _ = derivs(t, pos, case.period_s)
    speed = np.sqrt((vel[:, lin] ** 2).sum(axis=1)) * 60.0
    feed = case.recording.streams.get("feed")
    if feed is not None and "feed_mm_min" in feed.columns and len(feed) > 2:
        ft = (feed["t_ns"].to_numpy(np.int64) - case.t0_ns) / 1e9
        fk = ~case.in_hold(ft)
        speed = np.interp(t, case.compared_s(ft)[fk], feed["feed_mm_min"].to_numpy(np.float64)[fk])
    grid = np.linspace(0.0, s_anchor[-1], GRID)
    out = {"s_mm": grid}
    t_anchor = np.concatenate([[0.0], segments.end_s])
    out["t_measured_s"], out["v_measured_mm_min"] = _along(t, pos, lin, speed, t_anchor, s_anchor, grid)
    for label, sim in sims.items():
        traj = sim.trajectory
        start, _ = sim_span(case, sim)
        st = traj.t_s - start
        ends = np.concatenate([[0.0], np.cumsum(simulated_segments(case, segments, sim))])
        out[f"t_{label}_s"], out[f"v_{label}_mm_min"] = _along(st, traj.pos, lin, traj.speed * 60.0, ends, s_anchor, grid)
    return pd.DataFrame(out)


def _along(t, pos, lin, speed, t_anchor, s_anchor, grid) -> tuple[np.ndarray, np.ndarray]:
    """Time and speed at program arc lengths `grid`: each trajectory's own path length mapped onto the
    program's between anchors (where both say the same block ended)."""
    ell = _path_length(pos, lin)
    ell_anchor = np.interp(t_anchor, t, ell)
    ell_anchor = np.maximum.accumulate(ell_anchor)
    keep = np.concatenate([[True], np.diff(ell_anchor) > 1e-9])
    s_of_t = np.interp(ell, ell_anchor[keep], s_anchor[keep])
    s_of_t = np.maximum.accumulate(s_of_t)
    uniq = np.concatenate([[True], np.diff(s_of_t) > 1e-9])
    t_at = np.interp(grid, s_of_t[uniq], t[uniq])
    return t_at, np.interp(t_at, t, speed)


def measure_levels(dx) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
    cases, prof, ext = dx.cases, dx.profile, dx.extended
    timing = dx.scorers.get("timing")
    # the scorer's baseline is the given profile's, unless a calibration came first (then its own is generic)
    before = timing.baseline_sims if timing is not None and timing.profile is prof else simulate_all(cases, prof)
    after = simulate_all(cases, ext)
    cyc = []
    for c, b, a in zip(cases, before, after):
        bounded = sampled_cycle(c, b, a)
        if bounded is not None:
            meas, dur_b, dur_a = bounded
        else:
            (sb, eb), (sa, ea) = sim_span(c, b), sim_span(c, a)
            meas, dur_b, dur_a = (measured_cycle(c, ext) if dx.diff else c.cycle_s), eb - sb, ea - sa
        cyc.append({"name": c.name, "measured_s": meas, "simulated_before_s": dur_b, "simulated_after_s": dur_a,
                    "error_before_pct": 100 * (dur_b / meas - 1), "error_after_pct": 100 * (dur_a / meas - 1),
                    "span": "motion" if bounded is None else "moving samples"})
    meas = sum(r["measured_s"] for r in cyc)
    levels: dict[str, Any] = {"cycle": {
        "recordings": cyc, "measured_s": meas, "simulated_before_s": sum(r["simulated_before_s"] for r in cyc),
        "simulated_after_s": sum(r["simulated_after_s"] for r in cyc),
        "error_before_pct": 100 * (sum(r["simulated_before_s"] for r in cyc) / meas - 1),
        "error_after_pct": 100 * (sum(r["simulated_after_s"] for r in cyc) / meas - 1)}}
    where: dict[str, Any] = {}
    held: dict[str, Any] = {}
    scorer = dx.scorers.get("timing")
    if scorer is not None:
        # weightless segments (sparse data's first and last: their ends are a model's) are left out
        rb = [timing_residual(c, s, b) * s.weight for c, s, b in zip(cases, scorer.segments, before)]
        ra = [timing_residual(c, s, a) * s.weight for c, s, a in zip(cases, scorer.segments, after)]
        n = sum(len(r) for r in rb)
        total = sum(float(s.measured_s.sum()) for s in scorer.segments)
        flat_b, flat_a = np.concatenate(rb), np.concatenate(ra)
        levels["timing"] = {"segments": n, "rms_before_ms": 1e3 * rms(flat_b), "rms_after_ms": 1e3 * rms(flat_a),
                            "misplaced_before_pct": 100 * float(np.abs(flat_b).sum()) / total,
                            "misplaced_after_pct": 100 * float(np.abs(flat_a).sum()) / total,
                            "min_segment_s": float(min(s.measured_s[:-1].min() if len(s) > 1 else s.measured_s[0]
                                                       for s in scorer.segments))}
        tables = [segment_table(c, s) for c, s in zip(cases, scorer.segments)]
        seg = pd.concat(tables, ignore_index=True)
        where = {"before": where_text(seg, flat_b), "after": where_text(seg, flat_a),
                 "classes_before": class_table(seg, flat_b, lost=flat_b.sum() < 0).head(12).to_dict(orient="records"),
                 "top_segments": top_segments(tables, rb).to_dict(orient="records"),
                 "segments": seg.assign(residual_before_s=flat_b, residual_after_s=flat_a)}
        _finding_where(dx, seg)
        held = _held_out(dx, scorer)
    samples = {}
    for c, b, a in zip(cases, before, after):
        samples[c.name] = {"before": sample_residuals(c, prof, b), "after": sample_residuals(c, ext, a)}
    levels["samples"] = samples
    fb_b = [feedback_residual(c, prof) for c in cases]
    fb_a = [feedback_residual(c, ext) for c in cases]
    levels["feedback"] = None
    if any(r is not None for r in fb_b):
        def lin_rms(rs):
            parts = [r[:, c.feedback.linear] for r, c in zip(rs, cases) if r is not None and c.feedback.linear]
            return rms(np.concatenate([p.ravel() for p in parts])) if parts else None
        levels["feedback"] = {"rms_before_mm": lin_rms(fb_b), "rms_after_mm": lin_rms(fb_a),
                              "recordings": [c.name for c in cases if c.feedback is not None]}
    geo_b = [geometry_residual(c, prof) for c in cases]
    levels["geometry"] = None
    if any(r is not None for r in geo_b):
        geo_a = [geometry_residual(c, ext) for c in cases]
        levels["geometry"] = {"rms_before_mm": rms(np.concatenate([r.ravel() for r in geo_b if r is not None])),
                              "rms_after_mm": rms(np.concatenate([r.ravel() for r in geo_a if r is not None])),
                              "recordings": [c.name for c in cases if c.geometry is not None]}
    if scorer is not None:
        where["curves"] = {c.name: progress_curves(c, prof, s, {"before": b, "after": a})
                           for c, s, b, a in zip(cases, scorer.segments, before, after)}
    dx.sims = {"before": before, "after": after}
    return levels, held, where


def _finding_where(dx, seg: pd.DataFrame) -> None:
    """Each timing finding: the block classes its change of the residual sits in."""
    sel = dx.selections.get("timing")
    scorer = dx.scorers.get("timing")
    if sel is None or scorer is None:
        return
    model: dict[str, Any] = {}
    for step, finding in zip(sel.steps, [f for f in dx.findings if f.level == "timing"]):
        prev = np.concatenate(scorer.residuals(model))
        model = {**model, **step.chosen.held.hyp.values(sel.model.get(step.chosen.key, step.chosen.held.value))}
        now = np.concatenate(scorer.residuals(model))
        finding.where = where_text(seg, prev - now) if np.all(np.isfinite(now)) else ""


def _held_out(dx, scorer) -> dict[str, Any]:
    """Each recording's time error with every held-out stretch scored with the values fitted without it."""
    sel = dx.selections.get("timing")
    base = scorer.residuals({})
    per_case: dict[int, dict[str, float]] = {}
    for j, u in enumerate(scorer.units):
        model: dict[str, Any] = {}
        if sel is not None:
            for step in sel.steps:
                model.update(step.chosen.held.hyp.values(step.chosen.held.fold_values[j]))
        after = scorer.residuals(model)[u.case]
        row = per_case.setdefault(u.case, {"measured_s": 0.0, "before_s": 0.0, "after_s": 0.0})
        row["measured_s"] += float(scorer.segments[u.case].measured_s[u.lo:u.hi].sum())
        row["before_s"] += float(base[u.case][u.lo:u.hi].sum())
        row["after_s"] += float("nan") if after is None else float(after[u.lo:u.hi].sum())
    rows = [{"name": scorer.cases[i].name, "measured_s": r["measured_s"],
             "error_before_pct": 100 * r["before_s"] / r["measured_s"],
             "error_after_pct": 100 * r["after_s"] / r["measured_s"]} for i, r in per_case.items()]
    meas = sum(r["measured_s"] for r in rows)
    schemes = sorted({s.chosen.held.extra.get("scheme", "") for s in sel.steps}) if sel is not None else []
    return {"scheme": ", ".join(schemes) or ("leave one recording out" if len(rows) > 1 else "held-out stretches"),
            "units": len(scorer.units), "recordings": rows,
            "error_before_pct": sum(r["error_before_pct"] * r["measured_s"] for r in rows) / meas if meas else None,
            "error_after_pct": sum(r["error_after_pct"] * r["measured_s"] for r in rows) / meas if meas else None}
