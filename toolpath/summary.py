"""What a part program holds, in numbers: blocks, motion kinds, length, CAM time, extents, feeds."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from feedlog.profile import MachineProfile
from feedlog.toolpath.features import block_features
from feedlog.toolpath.linearize import cl_points
from feedlog.toolpath.program import Program
from feedlog.toolpath.schema import MOTION_KINDS, RAPID

BBOX_CHORD_TOL_MM = 0.001


def _num(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def summarize(program: Program, profile: MachineProfile) -> dict[str, Any]:
    """Summary of `program` on `profile`: CAM time is sum(L/F) over feed moves, rapids at the profile's
    rapid rate, plus dwells (no acceleration, no blending: what a CAM system estimates)."""
    b = program.blocks
    feats = block_features(program, profile)
    kinds = b["kind"].value_counts()
    rapid = feats["kind"].to_numpy() == RAPID
    feed = feats.loc[~rapid, "feed_mm_min"].to_numpy()
    feed = feed[np.isfinite(feed)]
    dwell_s = float(b["dwell_s"].sum())
    pts = cl_points(program, chord_tol_mm=BBOX_CHORD_TOL_MM)
    bbox = {}
    for col in ("x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"):
        if len(pts) and (col[0] in "xyz" or (pts[col] != 0).any()):
            bbox[col] = [float(pts[col].min()), float(pts[col].max())]
    tol = feats["tol_mm"].to_numpy()
    return {
        "file": program.name,
        "profile": profile.name,
        "rows": int(len(b)),
        "blocks": int(len(feats)),
        "kinds": {k: int(kinds.get(k, 0)) for k in (*MOTION_KINDS, "dwell")},
        "length_mm": float(feats["length_mm"].sum()),
        "rapid_length_mm": float(feats.loc[rapid, "length_mm"].sum()),
        "cam_time_s": float(np.nansum(feats["nominal_time_s"].to_numpy())) + dwell_s,
        "blocks_without_time": int(np.isnan(feats["nominal_time_s"].to_numpy()).sum()),
        "rapid_time_s": float(feats.loc[rapid, "nominal_time_s"].sum()),
        "dwell_s": dwell_s,
        "bbox": bbox,
        "feed_mm_min": [float(feed.min()), float(feed.max())] if len(feed) else None,
        "path_modes": sorted(str(m) for m in program.motion["path_mode"].unique()),
        "tol_mm": [_num(np.nanmin(tol)), _num(np.nanmax(tol))] if np.isfinite(tol).any() else None,
        "units": sorted(str(u) for u in b["units"].unique()),
        "five_axis": bool(b["ori_i"].notna().any() or (b[["a_deg", "b_deg", "c_deg"]] != 0).any(axis=None)),
        "warnings": list(program.warnings),
        "unsupported": [{"line": u.line, "code": u.code, "reason": u.reason} for u in program.unsupported],
        "metadata": {k: v for k, v in program.metadata.items() if k not in ("percent_lines",)},
    }


def format_summary(s: dict[str, Any]) -> str:
    """Human-readable lines for `feedlog program`."""
    kinds = ", ".join(f"{v} {k}" for k, v in s["kinds"].items() if v and k != "dwell")
    dwells = f", {s['kinds']['dwell']} dwells" if s["kinds"].get("dwell") else ""
    lines = [
        f"{s['file']}: {s['blocks']} motion blocks ({kinds}){dwells} in {s['rows']} rows",
        f"  path length  {s['length_mm']:.3f} mm (rapids {s['rapid_length_mm']:.3f} mm)",
        f"  CAM time     {s['cam_time_s']:.3f} s (rapids {s['rapid_time_s']:.3f} s at the rapid rate of "
        f"{s['profile']}, dwell {s['dwell_s']:.3f} s)",
    ]
    for col, (lo, hi) in s["bbox"].items():
        lines.append(f"  {col:<12} {lo:.4f} .. {hi:.4f}")
    if s["feed_mm_min"]:
        lines.append(f"  feed         {s['feed_mm_min'][0]:g} .. {s['feed_mm_min'][1]:g} mm/min")
    tol = s["tol_mm"]
    lines.append(f"  path mode    {', '.join(s['path_modes']) or '-'}"
                 + (f"; G64 P {tol[0]:g} .. {tol[1]:g} mm" if tol else ""))
    lines.append(f"  units        {', '.join(s['units'])}")
    if s["blocks_without_time"]:
        lines.append(f"  {s['blocks_without_time']} blocks without a feed are left out of the CAM time")
    for w in s["warnings"]:
        lines.append(f"  warning: {w}")
    return "\n".join(lines)
