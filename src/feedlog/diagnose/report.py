"""`report.md` of a diagnosis: the answer first, then tables and PNG plots (matplotlib, Agg).

Plots: the feed profile along the program (measured, simulated with the given profile, with the
extended one) per recording; residual time per block class before and after; segment residuals over
time before and after; the evidence (peak axis speeds and accelerations against the profile's limits).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np

from feedlog.colors import source_color
from feedlog.controller_names import with_names
from feedlog.diagnose.attribution import class_table
from feedlog.diagnose.plain import answer, glossary, noise_floor_text, timings_text
from feedlog.diagnose.summary import _fmt, summary_lines

DPI = 100
MAX_PROFILE_PLOTS = 4
COLORS = {"measured": source_color("measured"), "before": source_color("sim"), "after": (44, 160, 44)}


def _rgb(name: str) -> tuple[float, float, float]:
    return tuple(v / 255 for v in COLORS[name])


def _save(fig, path: Path) -> str:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path.name


def plot_profiles(dx, out: Path) -> list[str]:
    names = []
    curves = dx.where.get("curves", {})
    for name, df in list(curves.items())[:MAX_PROFILE_PLOTS]:
        if df is None or not len(df):
            continue
        fig, ax = plt.subplots(figsize=(10, 3.6))
        ax.plot(df["s_mm"], df["v_measured_mm_min"], color=_rgb("measured"), lw=1.2, label="measured")
        ax.plot(df["s_mm"], df["v_before_mm_min"], color=_rgb("before"), lw=1.0, label="simulated, given profile")
        ax.plot(df["s_mm"], df["v_after_mm_min"], color=_rgb("after"), lw=1.0, ls="--", label="simulated, extended")
        ax.set_xlabel("along the program (mm)")
        ax.set_ylabel("path speed (mm/min)")
        ax.set_title(f"{name}: feed profile before and after")
        ax.legend(loc="lower right", fontsize=8)
        names.append(_save(fig, out / f"profile_{name}.png"))
    return names


def plot_classes(dx, out: Path) -> str | None:
    seg = dx.where.get("segments")
    if seg is None or not len(seg):
        return None
    before = class_table(seg, seg["residual_before_s"].to_numpy())
    after = class_table(seg, seg["residual_after_s"].to_numpy())
    top = before[before["segments"] < len(seg)].head(12)  # a class every segment is in says nothing
    key = top["class"] + ": " + top["value"]
    merged = after.set_index(after["class"] + ": " + after["value"])["residual_s"].reindex(key).fillna(0.0)
    fig, ax = plt.subplots(figsize=(10, 4.2))
    y = np.arange(len(top))
    ax.barh(y - 0.2, top["residual_s"], height=0.4, color=_rgb("before"), label="given profile")
    ax.barh(y + 0.2, merged.to_numpy(), height=0.4, color=_rgb("after"), label="extended profile")
    ax.set_yticks(y, key, fontsize=8)
    ax.invert_yaxis()
    ax.axvline(0, color="k", lw=0.6)
    ax.set_xlabel("simulated - measured time (s), summed over the segments of the class")
    ax.set_title("residual time per block class")
    ax.legend(fontsize=8)
    return _save(fig, out / "residual_per_class.png")


def plot_segments(dx, out: Path) -> str | None:
    seg = dx.where.get("segments")
    if seg is None or not len(seg):
        return None
    fig, ax = plt.subplots(figsize=(10, 3.4))
    offset = 0.0
    for name, part in seg.groupby("recording", sort=False):
        t = offset + part["end_s"].to_numpy()
        ax.plot(t, 1e3 * part["residual_before_s"], ".", ms=4, color=_rgb("before"))
        ax.plot(t, 1e3 * part["residual_after_s"], ".", ms=4, color=_rgb("after"))
        offset = float(t.max()) + 0.5
        ax.axvline(offset - 0.25, color="0.8", lw=0.6)
    ax.plot([], [], ".", color=_rgb("before"), label="given profile")
    ax.plot([], [], ".", color=_rgb("after"), label="extended profile")
    ax.axhline(0, color="k", lw=0.6)
    ax.set_xlabel("time (s), recordings one after another")
    ax.set_ylabel("segment residual (ms)")
    ax.set_title("simulated - measured time per segment")
    ax.legend(fontsize=8)
    return _save(fig, out / "segment_residuals.png")


def plot_evidence(dx, out: Path) -> str | None:
    ev = dx.evidence
    axes = [a for a in dx.profile.axis_names if a in ev.axes]
    if not axes:
        return None
    fig, (av, aa) = plt.subplots(1, 2, figsize=(10, 3.4))
    x = np.arange(len(axes))
    av.bar(x - 0.2, [ev.axes[a].peak_vel for a in axes], 0.4, color=_rgb("measured"), label="seen (sustained)")
    av.bar(x + 0.2, [dx.profile.axes[a].vel_max for a in axes], 0.4, color="0.7", label="profile limit")
    av.set_xticks(x, [a.upper() for a in axes])
    av.set_title("peak axis speed (mm/s, deg/s)")
    av.legend(fontsize=8)
    accs = [ev.axes[a].peak_acc for a in axes]
    if any(v is not None for v in accs):
        aa.bar(x - 0.2, [v or 0.0 for v in accs], 0.4, color=_rgb("measured"), label="seen (sustained)")
        aa.bar(x + 0.2, [dx.profile.axes[a].acc_max for a in axes], 0.4, color="0.7", label="profile limit")
        aa.legend(fontsize=8)
    else:
        aa.text(0.5, 0.5, "not observable at this sampling rate", ha="center", va="center", transform=aa.transAxes)
    aa.set_xticks(x, [a.upper() for a in axes])
    aa.set_title("peak axis acceleration (mm/s^2, deg/s^2)")
    return _save(fig, out / "evidence.png")


def _table(rows: list[dict[str, Any]], columns: list[tuple[str, str]]) -> list[str]:
    head = "| " + " | ".join(title for _, title in columns) + " |"
    sep = "|" + "|".join("---" for _ in columns) + "|"
    body = ["| " + " | ".join(_cell(r.get(key)) for key, _ in columns) + " |" for r in rows]
    return [head, sep, *body]


def _cell(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, (list, tuple)):
        return ", ".join(_cell(x) for x in v)
    return "" if v is None else str(v).replace("|", "/")


def write_report(dx, out: Path) -> Path:
    plots = out / "plots"
    figures = {"profiles": plot_profiles(dx, plots), "classes": plot_classes(dx, plots),
               "segments": plot_segments(dx, plots), "evidence": plot_evidence(dx, plots)}
    controller = getattr(dx.profile, "controller", "") or ""
    lines = ["# feedlog diagnose", "", "## The answer", "", *answer(dx), "",
             "The same in short (as `feedlog diagnose` prints it; errors are simulated against measured time, "
             "\"short\": the simulation predicts less time than the machine took):", "",
             "```", *summary_lines(dx), "```", "", "Terms used below:", "", *glossary(), ""]
    lines += [f"Profile diagnosed: `{dx.profile.name}`; recordings: " + ", ".join(f"`{c.name}`" for c in dx.cases), ""]
    lines += [f"- note on {c.name}: {n}" for c in dx.cases for n in c.notes] + ([""] if any(c.notes for c in dx.cases) else [])
    lines += ["## Findings", ""]
    if dx.findings:
        lines += _table([{"parameter": with_names(f.parameter, controller), "profile": "off" if f.profile_value is None else
                          _fmt(f.profile_value, f.unit), "fitted": _fmt(f.fitted_value, f.unit),
                          "interval": None if f.interval is None else f"{f.interval[0]:.4g} - {f.interval[1]:.4g}",
                          "gain": f"{f.gain_pct:.1f} %", "kind": f.kind, "evidence": f.evidence, "where": f.where,
                          "held_out": f.scheme} for f in dx.findings],
                        [("parameter", "parameter"), ("profile", "profile"), ("fitted", "fitted"),
                         ("interval", "interval"), ("gain", "held-out gain"), ("kind", "kind"),
                         ("evidence", "evidence from the data"), ("where", "where its change acts"),
                         ("held_out", "held out")])
    else:
        lines.append("No cause: no registered hypothesis removes a material, repeatable share of the held-out "
                     "residual.")
    if dx.diff:
        lines += ["", "Extended profile (`profile.toml`), changes from the given one:", ""]
        lines += _table([{"key": with_names(k, controller), "before": a, "after": b} for k, a, b in dx.diff],
                        [("key", "key"), ("before", "given"), ("after", "extended")])
    rejected = [(lvl, j) for lvl, sel in dx.selections.items() for j in sel.rejected[:5]]
    if rejected:
        lines += ["", "Candidates considered last and not taken:", ""]
        lines += _table([{"level": lvl, "parameter": f"`{j.key}`", "fitted": _fmt(j.held.value, j.held.hyp.unit),
                          "gain": f"{100 * j.held.gain:.1f} %", "why": "; ".join(j.reasons)} for lvl, j in rejected],
                        [("level", "level"), ("parameter", "parameter"), ("fitted", "fitted"), ("gain", "held-out gain"),
                         ("why", "why not")])
    if dx.changes:
        lines += ["", "## Changes during a session", "",
                  "A parameter that took one value, then another (a step: a dial turned; a drift: a machine "
                  "that warms up), not averaged into one value (the extended profile keeps the profile's "
                  "value for it).", ""]
        lines += _table([{"rec": c.recording, "parameter": f"`{c.parameter}`", "before": _fmt(c.before, c.unit),
                          "after": _fmt(c.after, c.unit), "at": _when(c),
                          "single": _fmt(c.single_value, c.unit),
                          "error": f"{c.error_single_pct:.2f} % -> {c.error_change_pct:.2f} %"} for c in dx.changes],
                        [("rec", "recording"), ("parameter", "parameter"), ("before", "before"), ("after", "after"),
                         ("at", "when (from motion start)"), ("single", "one value would be"),
                         ("error", "timing error")])
    if dx.unexplained:
        lines += ["", "## Unexplained", ""]
        for u in dx.unexplained:
            lines.append(f"- {u['level']}, **cause unknown**: {u['error_pct']:.2f} % of the time misplaced, "
                         f"{u['systematic_share_pct']:.0f} % of it systematic (a model of the block classes predicts "
                         f"it on held-out data); {u['where']}.")
            if (u.get("signature") or {}).get("text"):
                lines.append(f"  Signature: {u['signature']['text']}.")
            if u.get("error_after_class_model_pct") is not None:
                lines.append(f"  Learned correction (the block-class model, fitted without each held-out stretch): "
                             f"held-out error {u['error_pct']:.2f} % -> {u['error_after_class_model_pct']:.2f} %.")
            lc = u.get("learned_correction") or {}
            if "held_out" in lc:
                lines.append(f"  Learned correction (train's hybrid model on the extended profile): held-out mean "
                             f"|error| {lc['mean_abs_error_before_pct']:.2f} % -> {lc['mean_abs_error_after_pct']:.2f} %"
                             + (" (kept as `learned.pt`)" if lc["gain_pct"] > 0 else " (does not generalise; not kept)"))
            elif "error" in lc:
                lines.append(f"  No learned correction: {lc['error']}")
    lines += ["", "## Before and after", ""]
    cyc = dx.levels["cycle"]["recordings"]
    lines += _table([{**r, "measured_s": r["measured_s"], "simulated_before_s": r["simulated_before_s"],
                      "simulated_after_s": r["simulated_after_s"]} for r in cyc],
                    [("name", "recording"), ("measured_s", "measured (s)"), ("simulated_before_s", "given (s)"),
                     ("error_before_pct", "error (%)"), ("simulated_after_s", "extended (s)"),
                     ("error_after_pct", "error (%)")])
    t = dx.levels.get("timing")
    if t:
        lines += ["", f"Segments ({t['segments']}, at least {t['min_segment_s']:.3g} s each): RMS residual "
                  f"{t['rms_before_ms']:.2f} -> {t['rms_after_ms']:.2f} ms; misplaced time "
                  f"{t['misplaced_before_pct']:.2f} -> {t['misplaced_after_pct']:.2f} %."]
    held = dx.held_out or {}
    if held.get("recordings"):
        lines += ["", f"Held out ({held['scheme']}):", ""]
        lines += _table(held["recordings"], [("name", "recording"), ("error_before_pct", "error before (%)"),
                                             ("error_after_pct", "error after, fitted without it (%)")])
    fb = dx.levels.get("feedback")
    if fb and fb.get("rms_before_mm") is not None:
        lines += ["", f"Feedback positions (from the recordings' own command): RMS {fb['rms_before_mm'] * 1e3:.3f} -> "
                  f"{fb['rms_after_mm'] * 1e3:.3f} um."]
    rows = []
    for name, s in dx.levels.get("samples", {}).items():
        for axis, b in s["before"].items():
            a = s["after"].get(axis, {})
            rows.append({"recording": name, "axis": axis.upper(), "pos_b": b["position"], "pos_a": a.get("position"),
                         "vel_b": b["velocity"], "vel_a": a.get("velocity"), "acc_b": b["acceleration"],
                         "acc_a": a.get("acceleration")})
    if rows:
        lines += ["", "Per sample, simulated - measured over time since motion start (RMS; mm, mm/s, mm/s^2; "
                  "deg for rotary axes):", ""]
        lines += _table(rows, [("recording", "recording"), ("axis", "axis"), ("pos_b", "position given"),
                               ("pos_a", "position extended"), ("vel_b", "velocity given"), ("vel_a", "velocity extended"),
                               ("acc_b", "acceleration given"), ("acc_a", "acceleration extended")])
    lines += ["", "## Where the time goes", "",
              f"Where the given profile loses time: {dx.where.get('before') or 'n/a'} (a cause's \"where its "
              "change acts\" counts the time its change moves, so its shares can differ by a point or two).", ""]
    top = dx.where.get("top_segments") or []
    if top:
        lines += _table([{**r, "residual_ms": 1e3 * r["residual_s"], "lines": f"{r['first_line']}-{r['line']}"}
                         for r in top[:10]],
                        [("recording", "recording"), ("lines", "lines"), ("move", "move"), ("corner", "corner"),
                         ("dominant", "axis"), ("reversal", "reversal"), ("residual_ms", "residual (ms)")])
    lines += ["", "## Evidence from the data (no simulation)", ""]
    ev = dx.evidence.as_dict()
    lines += _table([{"axis": a.upper(), **v} for a, v in ev["axes"].items()],
                    [("axis", "axis"), ("peak_vel", "peak speed /s"), ("peak_acc", "peak acceleration /s^2"),
                     ("travel", "travel")])
    lines += ["", f"Path speed ceiling {ev['path_speed_ceiling_mm_s']} mm/s; long feed moves at "
              f"{ev['plateau_ratio']} x F ({ev['plateau_blocks']} moves); {ev['stops']} stops; feedback delay "
              f"{ev['feedback_delay_ms'] or 'n/a'} ms; largest corner deviation {ev['blend_deviation_mm']} mm.", ""]
    lines += ["## Plots", ""]
    for name in figures["profiles"]:
        lines.append(f"![{name}](plots/{name})")
    for key in ("classes", "segments", "evidence"):
        if figures[key]:
            lines.append(f"![{figures[key]}](plots/{figures[key]})")
    lines += ["", noise_floor_text(dx.noise_floor), timings_text(dx.timings_s), ""]
    path = out / "report.md"
    path.write_text("\n".join(lines))
    return path


def _when(change) -> str:
    """When a change happened: a step's time, a drift's start and end and its rate, an approach's
    start, time constant and 95 % time."""
    line = f" (line {change.line})" if change.line else ""
    still = " (not levelled off)" if change.open_end else ""
    if change.shape == "drift":
        return (f"drift {change.at_s:.2f} s{line} to {change.until_s:.2f} s{still}, "
                f"{change.rate_per_min:+.4g}{(' ' + change.unit) if change.unit else ''} per minute")
    if change.shape == "approach":
        return (f"approach from {change.at_s:.2f} s{line}, time constant {change.tau_s:.3g} s, "
                f"95 % at {change.until_s:.2f} s{still}")
    return f"{change.at_s:.2f} s{line}"
