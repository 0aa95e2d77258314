"""What a line-level diagnosis prints and writes: the summary, diagnose.json, report.md, profile.toml.

`write_line_outputs` fills a staging folder and publishes it whole (`feedlog.storage.publish_dir`):
an output that cannot be written leaves nothing behind.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from feedlog.diagnose.line_level import BLIND, LineDiagnosis
from feedlog.storage import publish_dir

PROFILE = "profile.toml"


def _clean(v: Any) -> Any:
    """JSON-safe: numpy numbers as Python ones, NaN as None."""
    if isinstance(v, dict):
        return {str(k): _clean(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_clean(x) for x in v]
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return None if not np.isfinite(v) else float(v)
    if isinstance(v, np.bool_):
        return bool(v)
    return v


def to_json(ld: LineDiagnosis) -> dict[str, Any]:
    return _clean({"mode": "line stream only", "recording": ld.recording, "program": ld.program,
                   "profile": ld.profile.name, "figures": ld.figures, "fit": ld.fit, "session": ld.session.report,
                   "cannot_see_without_positions": list(BLIND), "warnings": ld.warnings})


def summary_lines(ld: LineDiagnosis) -> list[str]:
    f, fit = ld.figures, ld.fit
    n = ld.session.numbering
    out = [f"{ld.recording}: line stream only (no positions): block-level diagnosis against {ld.program}",
           f"  block numbers: {n.name} ({'stated' if n.stated else 'detected'})"]
    lm = ld.session.line_map
    if lm.first_mismatch is not None:
        out.append("  program mismatch: " + (lm.warning("the program") or ""))
    for st in f.get("stretches", []):
        if st["established"]:
            out.append(f"  placed after the mismatch: recorded {st['recorded_lines'][0]}-{st['recorded_lines'][1]} = program "
                       f"{st['program_lines'][0]}-{st['program_lines'][1]} ({st['offset']:+d}): {st['intervals']} "
                       f"stretches, {st['measured_s']:.2f} s measured, {st['simulated_s']:.2f} s simulated, "
                       f"{st['fitted_s']:.2f} s with the fitted factors")
    if "timed_per_block_s" in f:
        out.append(f"  timed between placed line changes: {f['timed_per_block_s']:.2f} s of the "
                   f"{f['motion_measured_s']:.2f} s of motion ({f['timed_per_block_pct']:.1f} %)")
    out.append(f"  cycle: measured {f['measured_cycle_s']:.2f} s, simulated {f['simulated_cycle_s']:.2f} s "
               f"({f['error_before_pct']:+.1f} %)")
    for kind, s in sorted(f["events_s"].items()):
        count = int((ld.session.events["kind"] == kind).sum())
        out.append(f"  {kind}: {count} x, {s:.2f} s ({100 * s / f['measured_cycle_s']:.1f} % of the cycle)")
    rd = f.get("rapid_override")
    if rd is not None and rd["min"] is not None:
        text = (f"  recorded rapid override: lowest {100 * rd['min']:.0f} %, below 100 % for {rd['below_full_s']:.2f} s"
                + (f" (at 100 % from {rd['full_from_s']:.2f} s on)" if rd["full_from_s"] is not None else ""))
        slow = [f"{e['kind']} at recorded line {e['recorded_line']} ({e['duration_s']:.2f} s, dial "
                f"{100 * e['rapid_override_mean']:.0f} % on average)" for e in rd["events_below_full"]]
        out.append(text + ("; during " + ", ".join(slow) if slow else "")
                   + (f"; rapid factor where it read 100 %: {fit['k_rapid_full_dial']:.3f}"
                      if fit.get("k_rapid_full_dial") is not None and np.isfinite(fit["k_rapid_full_dial"]) else ""))
    kf = ", ".join(f"tool section {s}: {k:.3f}" for s, k in zip(fit["sections"], fit["k_feed"]) if np.isfinite(k))
    out.append(f"  motion: {f['motion_measured_s']:.2f} s measured outside the events; time factors "
               f"(measured / simulated) feed {kf or 'n/a'}; rapid "
               + (f"{fit['k_rapid']:.3f}" if np.isfinite(fit["k_rapid"]) else "n/a"))
    out.append(f"  held out (every other stretch between line changes): error {fit['held_out_error_before_pct']:.1f} % "
               f"-> {fit['held_out_error_after_pct']:.1f} %")
    for key, value in fit["values"].items():
        out.append(f"  fitted {key} = {value}")
    out.append(f"  after: simulated {f['simulated_after_s']:.2f} s + {f['predicted_after_s'] - f['simulated_after_s']:.2f} s "
               f"of stops and waits the program does not time = {f['predicted_after_s']:.2f} s "
               f"({f['error_after_pct']:+.1f} % against measured)")
    why = [f"the line stream times a boundary to one sample ({f['line_period_s']:.3f} s)"]
    if f["unplaced_s"] > 0:
        why.append(f"{f['unplaced_s']:.2f} s ran on lines the data cannot place on the program (the program that "
                   "ran differs there), predicted with the factors fitted elsewhere")
    why.append("a factor is one median per kind, so an override turned for a while (slow first approaches) "
               "stays in the rest")
    if np.isfinite(fit["k_rapid"]):
        why.append("the rapid factor cannot tell a slower rapid rate from a rapid override")
    out.append(f"  remains: {f['remaining_s']:+.2f} s; why: " + "; ".join(why))
    out.append("  the block level cannot see: " + "; ".join(BLIND))
    return out


def report_md(ld: LineDiagnosis) -> str:
    lines = ["# feedlog diagnose: line stream only", "", f"Recording `{ld.recording}`, program `{ld.program}`, "
             f"profile `{ld.profile.name}`.", "", "```", *summary_lines(ld), "```", "", "## Events", "",
             "| kind | recorded line | program line | M codes | start (s) | duration (s) | spindle off |",
             "|---|---|---|---|---|---|---|"]
    t0 = int(ld.session.runs["t_start_ns"].iloc[0])
    for e in ld.session.events.to_dict("records"):
        lines.append(f"| {e['kind']} | {e['recorded_line']} | {e['program_line'] if e['program_line'] is not None else '?'} "
                     f"| {e['m_codes']} | {(e['t_start_ns'] - t0) / 1e9:.2f} | {e['duration_s']:.2f} | {e['spindle_off']} |")
    for st in ld.figures.get("stretches", []):
        if not st["established"]:
            continue
        lines += ["", f"## Placed after the mismatch: recorded {st['recorded_lines'][0]}-{st['recorded_lines'][1]} = "
                  f"program {st['program_lines'][0]}-{st['program_lines'][1]} ({st['offset']:+d})", "",
                  "| program lines | recorded line | measured (s) | simulated (s) |", "|---|---|---|---|"]
        lines += [f"| {b['from_line']}-{b['to_line']} | {b['recorded_from_line']} | {b['measured_s']:.3f} | "
                  f"{b['simulated_s']:.3f} |" for b in st["blocks"]]
    lines += ["", "## Warnings", ""] + [f"- {w}" for w in ld.warnings] + [""]
    return "\n".join(lines)


def profile_text(ld: LineDiagnosis) -> str:
    head = [f"# {ld.extended.name}: {ld.profile.name} extended by feedlog diagnose (line stream only) on "
            f"{ld.recording}"] + [f"#   {k} = {v}" for k, v in ld.fit["values"].items()]
    return "\n".join(head) + "\n" + ld.extended.to_toml()


def write_line_outputs(ld: LineDiagnosis, out: str | Path) -> None:
    with publish_dir(str(out)) as tmp:
        (tmp / "report.md").write_text(report_md(ld))
        (tmp / "diagnose.json").write_text(json.dumps(to_json(ld), indent=1, allow_nan=False) + "\n")
        (tmp / PROFILE).write_text(profile_text(ld))


__all__ = ["report_md", "summary_lines", "to_json", "write_line_outputs"]
