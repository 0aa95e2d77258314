"""What remains: a systematic residual that no registered hypothesis explains, where it lives, and a
learned correction for it.

After the accepted causes, is the timing residual still systematic? A linear model of the segment
residuals on the block classes (`attribution.CLASSES`: per class value, time lost per second spent
in it and per occurrence) is fitted without each held-out unit and scored on it. If it removes at
least `min_gain` of the held-out residual and the error drops by `min_effect_pct` points, the residual
is systematic: it is reported as *unexplained*, with the block classes the regression puts it in and
its signature (`signature`: where on the part, along which axis, at which programmed speeds the time
is lost), never as a cause: the report says the cause is unknown. A change found during a session
(`changes`) is applied to its recording first: what it explains is not unexplained. The fallback extension is then a learned correction, train/'s hybrid model (the
simulation's block times times a learned Bi-LSTM factor), trained on the recordings with the
extended profile and judged on the same held-out units; `learned_model` keeps it (trained on all).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd

from feedlog.diagnose.attribution import CLASSES, segment_table, where_text
from feedlog.errors import FeedlogError

RIDGE = 1e-3


def design(table: pd.DataFrame) -> tuple[np.ndarray, list[str]]:
    """Columns: per class value, the segment's measured duration (a rate) and 1 (a per-event time)."""
    cols, names = [], []
    dur = table["measured_s"].to_numpy(np.float64)
    for cls in CLASSES:
        if cls not in table.columns:
            continue
        values = table[cls].astype(str).to_numpy()
        for v in np.unique(values):
            ind = (values == v).astype(np.float64)
            if ind.sum() < 2:
                continue
            cols += [ind * dur, ind]
            names += [f"{v} (per s)", f"{v} (each)"]
    return (np.column_stack(cols) if cols else np.zeros((len(table), 0))), names


def ridge(x: np.ndarray, y: np.ndarray, lam: float = RIDGE) -> np.ndarray:
    if x.shape[1] == 0:
        return np.zeros(0)
    scale = np.sqrt((x ** 2).mean(axis=0)) + 1e-12
    xs = x / scale
    a = xs.T @ xs + lam * len(y) * np.eye(xs.shape[1])
    return np.linalg.solve(a, xs.T @ y) / scale


def systematic(table: pd.DataFrame, residual: np.ndarray, units: list[np.ndarray]) -> dict[str, Any]:
    """Held-out share of `residual` a class regression predicts, and its largest contributions."""
    x, names = design(table)
    pred = np.zeros_like(residual)
    for idx in units:
        train = np.setdiff1d(np.arange(len(residual)), idx)
        if len(train) < 2 or x.shape[1] == 0:
            continue
        pred[idx] = x[idx] @ ridge(x[train], residual[train])
    before = float(np.sum(residual ** 2))
    after = float(np.sum((residual - pred) ** 2))
    coef = ridge(x, residual) if x.shape[1] else np.zeros(0)
    contrib = np.abs(x * coef).sum(axis=0) if len(coef) else np.zeros(0)
    order = np.argsort(-contrib)[:4]
    total = float(np.abs(residual).sum())
    return {"gain": 1.0 - after / before if before > 0 else 0.0, "held_out_prediction": pred,
            "classes": [{"class": names[i], "time_s": round(float((x[:, i] * coef[i]).sum()), 6),
                         "share": round(float(contrib[i]) / total, 4) if total else 0.0} for i in order]}


def find_unexplained(dx, *, learned: bool, min_effect_pct: float, min_gain: float,
                     progress: Callable[[str], None] | None = None) -> list[dict[str, Any]]:
    scorer = dx.scorers.get("timing")
    if scorer is None:
        return []
    from feedlog.diagnose.engine import timing_error

    model = dx.selections["timing"].model if "timing" in dx.selections else {}
    stepped = {c.parameter for c in getattr(dx, "changes", [])}
    model = {k: v for k, v in model.items() if k not in stepped}
    res = list(scorer.residuals(model))
    for c in getattr(dx, "changes", []):      # the recording's two values, each on its side of the change
        i = next(k for k, case in enumerate(scorer.cases) if case.name == c.recording)
        r1, r2 = scorer.residuals({**model, c.parameter: c.before})[i], scorer.residuals({**model, c.parameter: c.after})[i]
        # the segment the change happened in is the two mixed, its time of change fitted to it: no residual
        res[i] = None if r1 is None or r2 is None else np.concatenate([r1[:c.segment], [0.0], r2[c.segment + 1:]])
    if any(r is None for r in res):
        return []
    tables = [segment_table(c, s) for c, s in zip(scorer.cases, scorer.segments)]
    table = pd.concat(tables, ignore_index=True)
    offsets = np.cumsum([0] + [len(r) for r in res])
    # segments without weight (sparse data's first and last: their ends are a model's) say nothing
    weight = np.concatenate(scorer.weights)
    residual = np.concatenate(res) * weight
    units = [np.arange(offsets[u.case] + u.lo, offsets[u.case] + u.hi) for u in scorer.units]
    sys = systematic(table, residual, units)
    err = timing_error(scorer)
    n = len(scorer.units)
    losses_before = np.array([float(np.sum(residual[idx] ** 2)) for idx in units])
    losses_after = np.array([float(np.sum((residual[idx] - sys["held_out_prediction"][idx]) ** 2)) for idx in units])
    e_before, e_after = err(losses_before, list(range(n))), err(losses_after, list(range(n)))
    excess = float(losses_before.sum() - scorer.floor.sum())
    gain = float(losses_before.sum() - losses_after.sum()) / excess if excess > 0 else 0.0
    if not (gain >= min_gain and e_before - e_after >= min_effect_pct):
        return []
    sys["gain"] = gain
    entry: dict[str, Any] = {
        "level": "timing", "error_pct": e_before, "cycle_error_pct": 100 * float(residual.sum()) / float(
            table["measured_s"].sum()),
        "systematic_share_pct": 100 * sys["gain"], "error_after_class_model_pct": e_after,
        "where": where_text(table, residual), "classes": sys["classes"], "signature": signature(table, residual),
        "cause": "unknown",
        "note": "cause unknown: systematic (a model of the block classes predicts it on held-out data) but no "
                "registered hypothesis explains it"}
    if learned:
        if progress:
            progress("timing: unexplained residual; fitting the learned correction (hybrid)")
        try:
            entry["learned_correction"] = learned_correction(dx)
        except FeedlogError as exc:
            entry["learned_correction"] = {"error": str(exc)}
    return [entry]


SIGNATURE_SHARE = 0.8   # the segments carrying this share of the lost (or gained) time make the place


def signature(table: pd.DataFrame, residual: np.ndarray) -> dict[str, Any]:
    """Where a residual lives: on the part (the program lines and the box of the block ends of the segments
    carrying `SIGNATURE_SHARE` of it), along which axis and at which programmed speeds (the dominant-axis
    and feed classes, each with its share of it)."""
    r = np.asarray(residual, dtype=np.float64)
    lost = r.sum() < 0
    part = np.clip(-r if lost else r, 0.0, None)
    total = float(part.sum())
    if not len(table) or total <= 0:
        return {}
    order = np.argsort(-part, kind="stable")
    keep = order[:int(np.searchsorted(np.cumsum(part[order]), SIGNATURE_SHARE * total)) + 1]
    out: dict[str, Any] = {"share": round(float(part[keep].sum()) / total, 4), "segments": int(len(keep)),
                           "of_segments": int(len(table))}
    lines = table.iloc[keep]
    out["lines"] = [int(lines[["first_line", "line"]].min().min()), int(lines["line"].max())]
    box = {a: [round(float(lines[f"{a}_end_mm"].min()), 3), round(float(lines[f"{a}_end_mm"].max()), 3)]
           for a in ("x", "y", "z") if f"{a}_end_mm" in lines.columns and lines[f"{a}_end_mm"].notna().any()}
    out["box_mm"] = box
    for name, cls in (("along", "dominant"), ("speeds", "feed")):
        if cls in table.columns:
            shares = pd.Series(part).groupby(table[cls].astype(str).to_numpy()).sum() / total
            shares = shares.sort_values(ascending=False)
            out[name] = [{"value": str(v), "share": round(float(x), 4)} for v, x in shares.head(2).items() if x > 0]
    place = ", ".join(f"{a.upper()} {lo:g} to {hi:g}" for a, (lo, hi) in box.items())
    along = ", ".join(f"{d['value'].removeprefix('along ')} {100 * d['share']:.0f} %" for d in out.get("along", []))
    speeds = ", ".join(f"{d['value']} {100 * d['share']:.0f} %" for d in out.get("speeds", []))
    out["text"] = (f"{100 * out['share']:.0f} % of it in {len(keep)} of {len(table)} segments, program lines "
                   f"{out['lines'][0]}-{out['lines'][1]}, on the part {place} mm; along {along}; at {speeds}")
    return out


def learned_correction(dx) -> dict[str, Any]:
    """train/'s hybrid model on the extended profile: held out per unit, then trained on everything."""
    from feedlog.train.dataset import TARGET, ProgramTable, fingerprint
    from feedlog.train.model_hybrid import attach_sim
    from feedlog.train.registry import make_model

    tables = []
    for case in dx.cases:
        blocks = case.alignment.blocks.copy()
        table = ProgramTable(case.name, blocks, profile=dx.extended, program_text=None)
        tables.append(attach_sim(table, program=case.program))
    parts = _unit_tables(dx, tables)
    rows = []
    for j, (name, held) in enumerate(parts):
        train = [t for k, (_, t) in enumerate(parts) if k != j]
        model = make_model("hybrid", preset="quick", seed=0)
        model.fit(train, progress=False)
        model.fingerprint = fingerprint(train, model.required_columns + [TARGET])
        pred = model.predict(held)
        meas = float(held.durations().sum())
        sim = float(held.blocks["sim_duration_s"].sum())
        rows.append({"name": name, "measured_s": meas, "error_before_pct": 100 * (sim / meas - 1),
                     "error_after_pct": 100 * (pred.cycle_time_s / meas - 1)})
    final = make_model("hybrid", preset="quick", seed=0)
    final.fit(tables, progress=False)
    final.fingerprint = fingerprint(tables, final.required_columns + [TARGET])
    dx.learned_model = final
    before = float(np.mean([abs(r["error_before_pct"]) for r in rows]))
    after = float(np.mean([abs(r["error_after_pct"]) for r in rows]))
    return {"model": "hybrid", "held_out": rows, "mean_abs_error_before_pct": before,
            "mean_abs_error_after_pct": after, "gain_pct": 100 * (1 - after / before) if before > 0 else 0.0}


def _unit_tables(dx, tables):
    """The held-out units as program tables: whole recordings, or halves of the one recording."""
    if len(tables) >= 2:
        return [(t.name, t) for t in tables]
    from feedlog.train.dataset import ProgramTable

    t = tables[0]
    half = len(t.blocks) // 2
    if half < 4:
        raise FeedlogError(f"{t.name}: too few blocks ({len(t.blocks)}) to hold part of them out for a learned "
                           "correction")
    out = []
    for k, rows in enumerate((slice(0, half), slice(half, None))):
        out.append((f"{t.name} half {k + 1}", ProgramTable(f"{t.name}#{k}", t.blocks.iloc[rows].reset_index(drop=True),
                                                           profile=t.profile, program_text=None)))
    return out
