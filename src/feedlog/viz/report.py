"""The demo's outputs: the cycle-time table (DataFrame, JSON rows, Markdown) and the report page.

The table has one row per recording: `program`, `recording`, `split`, `measured_s`, `cam_s`,
`sim_s`, one `<model>_s` per trained model, and `<source>_err_pct` = (predicted - measured) /
measured in percent. Missing values stay missing (None in JSON, "n/a" in Markdown): nothing is filled in.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

BASE_COLUMNS = ("program", "recording", "split", "measured_s", "cam_s", "sim_s")


@dataclass
class TableRow:
    program: str
    recording: str
    split: str = ""
    measured_s: float | None = None
    cam_s: float | None = None
    sim_s: float | None = None
    models: dict[str, float | None] = field(default_factory=dict)


def cycle_time_table(rows: Sequence[TableRow], *, model_names: Sequence[str] = ()) -> pd.DataFrame:
    """Rows -> table with one `<model>_s` column per model and the error columns."""
    names = list(dict.fromkeys([*model_names, *(m for r in rows for m in r.models)]))
    records = []
    for r in rows:
        rec = {"program": r.program, "recording": r.recording, "split": r.split, "measured_s": r.measured_s,
               "cam_s": r.cam_s, "sim_s": r.sim_s}
        rec.update({f"{m}_s": r.models.get(m) for m in names})
        records.append(rec)
    table = pd.DataFrame.from_records(records, columns=[*BASE_COLUMNS, *(f"{m}_s" for m in names)])
    value_cols = [c for c in table.columns if c.endswith("_s")]
    table[value_cols] = table[value_cols].astype(np.float64)
    measured = table["measured_s"].to_numpy()
    for col in value_cols:
        if col == "measured_s":
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            table[f"{col[:-2]}_err_pct"] = (table[col].to_numpy() - measured) / measured * 100.0
    return table


def _plain(value):
    if isinstance(value, (float, np.floating)):
        return None if not math.isfinite(value) else round(float(value), 6)
    if isinstance(value, np.integer):
        return int(value)
    return value


def table_json(table: pd.DataFrame) -> str:
    """The table as a JSON list of rows; missing numbers are null."""
    rows = [{k: _plain(v) for k, v in row.items()} for row in table.to_dict(orient="records")]
    return json.dumps(rows, indent=2)


def _fmt(value, *, pct: bool = False) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    if pct:
        return "0.0 %" if round(float(value), 1) == 0 else f"{value:+.1f} %"   # never "-0.0 %"
    return f"{value:.3f}"


def table_markdown(table: pd.DataFrame) -> str:
    """The table in Markdown: times in seconds, then each prediction's error against the measurement."""
    time_cols = [c for c in table.columns if c.endswith("_s")]
    err_cols = [c for c in table.columns if c.endswith("_err_pct")]
    header = ["program", "recording", "split", *(c[:-2] + " (s)" for c in time_cols),
              *(c[:-8] + " err" for c in err_cols)]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for _, row in table.iterrows():
        cells = [str(row["program"]), str(row["recording"]), str(row["split"] or "")]
        cells += [_fmt(row[c]) for c in time_cols] + [_fmt(row[c], pct=True) for c in err_cols]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def error_summary(table: pd.DataFrame, *, split: str | None = None) -> dict[str, float]:
    """Mean absolute error in percent per prediction source (over `split` rows when given)."""
    rows = table if split is None else table[table["split"] == split]
    out = {}
    for col in (c for c in table.columns if c.endswith("_err_pct")):
        values = rows[col].to_numpy(dtype=np.float64)
        values = values[np.isfinite(values)]
        if len(values):
            out[col[:-8]] = float(np.mean(np.abs(values)))
    return out


@dataclass
class ReportSection:
    title: str
    lines: list[str] = field(default_factory=list)
    images: list[tuple[str, Path]] = field(default_factory=list)  # (caption, path)


def headline(table: pd.DataFrame) -> list[str]:
    """The answer in a few lines: how far each estimate of the cycle time is from the measured one
    (mean absolute error; held-out rows separately when there are any), best first."""
    measured = int(np.isfinite(table["measured_s"].to_numpy(dtype=np.float64)).sum()) if len(table) else 0
    overall = error_summary(table)
    if not overall:
        return [f"{len(table)} recording(s), {measured} with a measured cycle time; no estimate to compare."]
    held_out = error_summary(table, split="test")
    lines = [f"{len(table)} recordings, {measured} with a measured cycle time. Mean absolute cycle-time error "
             "(lower is better):"]
    for name, value in sorted(overall.items(), key=lambda kv: kv[1]):
        test = f", held-out {held_out[name]:.1f} %" if name in held_out else ""
        lines.append(f"- {name}: {value:.1f} %{test}")
    return lines


def write_report(path: Path, *, title: str, intro: Sequence[str], table: pd.DataFrame,
                 sections: Sequence[ReportSection], answer: Sequence[str] = (),
                 front: Sequence[ReportSection] = ()) -> Path:
    """Markdown report next to its images (image links are relative to the report): the answer first
    (`answer` sentences, then the `headline`), then the `front` sections (the diagnosis, the overview
    plot), then `intro` and the long cycle-time table, then the per-recording `sections`."""
    out = [f"# {title}", "", "## The answer", "", *answer, "", "## Summary", "", *headline(table), ""]
    for section in front:
        out += _section(section, path)
    out += [*intro, "", "## Cycle times", "", table_markdown(table), ""]
    summary = error_summary(table)
    if summary:
        out.append("Mean absolute cycle-time error over all rows: "
                   + ", ".join(f"{k} {v:.1f} %" for k, v in summary.items()) + ".")
        held_out = error_summary(table, split="test")
        if held_out:
            out.append("On held-out (test) recordings only: "
                       + ", ".join(f"{k} {v:.1f} %" for k, v in held_out.items()) + ".")
        out.append("")
    for section in sections:
        out += _section(section, path)
    path.write_text("\n".join(out))
    return path


def _section(section: ReportSection, path: Path) -> list[str]:
    out = [f"## {section.title}", "", *section.lines, ""]
    for caption, image in section.images:
        rel = Path(image).relative_to(path.parent) if Path(image).is_relative_to(path.parent) else Path(image)
        out += [f"![{caption}]({rel.as_posix()})", ""]
    return out
