"""What a part program holds, in numbers: blocks, motion kinds, length, CAM time, extents, feeds."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from feedlog.errors import ProgramError
from feedlog.profile import MachineProfile
from feedlog.toolpath.features import block_features
from feedlog.toolpath import arcs
from feedlog.toolpath.limits import check_axes, check_run_time
from feedlog.toolpath.offsets import WORK_OFFSET_COLUMNS, to_machine
from feedlog.toolpath.program import K_ARC_CCW, K_ARC_CW, Program, kind_codes
from feedlog.toolpath.schema import END_COLUMNS, MOTION_KINDS, RAPID, START_COLUMNS


def _num(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def extents(program: Program) -> dict[str, list[float]]:
    """[min, max] per axis over the programmed path (arcs by their extreme points, not their ends);
    rotary axes only when they move."""
    m = program.motion
    if not len(m):
        return {}
    lo = np.minimum(m[list(START_COLUMNS)].to_numpy().min(axis=0), m[list(END_COLUMNS)].to_numpy().min(axis=0))
    hi = np.maximum(m[list(START_COLUMNS)].to_numpy().max(axis=0), m[list(END_COLUMNS)].to_numpy().max(axis=0))
    kind = kind_codes(m["kind"])
    arc = np.flatnonzero((kind == K_ARC_CW) | (kind == K_ARC_CCW))
    if len(arc):
        idx = arcs.plane_index(m["plane"].to_numpy()[arc])
        s = arcs.to_plane(m[list(START_COLUMNS[:3])].to_numpy()[arc], idx)
        c = arcs.to_plane(m[["cx_mm", "cy_mm", "cz_mm"]].to_numpy()[arc], idx)
        e = arcs.to_plane(m[list(END_COLUMNS[:3])].to_numpy()[arc], idx)
        r0 = np.hypot(s[:, 0] - c[:, 0], s[:, 1] - c[:, 1])
        r1 = np.hypot(e[:, 0] - c[:, 0], e[:, 1] - c[:, 1])
        a0 = np.arctan2(s[:, 1] - c[:, 1], s[:, 0] - c[:, 0])
        swept = np.radians(m["sweep_deg"].to_numpy()[arc])
        ccw = kind[arc] == K_ARC_CCW
        for q in range(4):  # the circle's extreme points at 0, 90, 180, 270 deg
            ang = q * np.pi / 2
            to_q = np.where(ccw, ang - a0, a0 - ang) % arcs.TWO_PI
            on = to_q <= swept
            if not on.any():
                continue
            frac = to_q[on] / swept[on]  # radius and rise vary linearly along the arc
            r = r0[on] + (r1[on] - r0[on]) * frac
            uv = np.zeros((on.sum(), 3))
            uv[:, 0] = c[on, 0] + r * np.cos(ang)
            uv[:, 1] = c[on, 1] + r * np.sin(ang)
            uv[:, 2] = s[on, 2] + (e[on, 2] - s[on, 2]) * frac
            xyz = arcs.from_plane(uv, idx[on])
            lo[:3] = np.minimum(lo[:3], xyz.min(axis=0))
            hi[:3] = np.maximum(hi[:3], xyz.max(axis=0))
    names = [c for c in END_COLUMNS]
    return {name: [float(lo[j]), float(hi[j])] for j, name in enumerate(names)
            if j < 3 or lo[j] != 0 or hi[j] != 0}


SYSTEM_NAMES = ("", "G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3")


def work_offsets(program: Program) -> list[dict[str, Any]]:
    """The work offsets in force on motion blocks, in order of first use: coordinate system, offset per
    axis (only axes with one), number of blocks. Empty when every offset is 0 or the table has none."""
    m = program.motion
    if not len(m) or not all(c in m.columns for c in WORK_OFFSET_COLUMNS) \
            or not m[list(WORK_OFFSET_COLUMNS)].to_numpy().any():
        return []
    cols = [*WORK_OFFSET_COLUMNS, "coord_system"]
    counts = m.groupby(cols, sort=False).size()
    return [{"coord_system": SYSTEM_NAMES[int(key[-1])],
             "offset": {c: float(v) for c, v in zip(WORK_OFFSET_COLUMNS, key[:-1]) if v != 0},
             "blocks": int(n)} for key, n in counts.items()]


def summarize(program: Program, profile: MachineProfile) -> dict[str, Any]:
    """Summary of `program` on `profile`: CAM time is sum(L/F) over feed moves, rapids at the profile's
    rapid rate, plus dwells (no acceleration, no blending: what a CAM system estimates)."""
    b = program.blocks
    check_axes(b, profile.axis_names, profile.name)
    feats = block_features(program, profile)
    _check_cam_time(program, feats, profile)
    kinds = b["kind"].value_counts()
    rapid = feats["kind"].to_numpy() == RAPID
    feed = feats.loc[~rapid, "feed_mm_min"].to_numpy()
    feed = feed[np.isfinite(feed)]
    dwell_s = float(b["dwell_s"].sum())
    bbox = extents(program)
    offsets = work_offsets(program)
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
        "work_offsets": offsets,
        "bbox_machine": extents(Program(blocks=to_machine(b))) if offsets else None,
        "five_axis": bool(b["ori_i"].notna().any() or (b[["a_deg", "b_deg", "c_deg"]] != 0).any(axis=None)),
        "warnings": list(program.warnings),
        "unsupported": [{"line": u.line, "code": u.code, "reason": u.reason} for u in program.unsupported],
        "metadata": {k: v for k, v in program.metadata.items() if k not in ("percent_lines",)},
    }


def _check_cam_time(program: Program, feats, profile: MachineProfile) -> None:
    """CAM time (rapids at the profile's rapid rate included) within what feedlog counts in int64 ns."""
    b = program.blocks
    seconds = b["dwell_s"].to_numpy(dtype=np.float64, copy=True)
    seconds[feats["block"].to_numpy()] += np.nan_to_num(feats["nominal_time_s"].to_numpy(dtype=np.float64))
    kinds = b["kind"].astype(str).to_numpy()

    def fail(r: int, message: str, code: str) -> ProgramError:
        return ProgramError(message, file=program.name, line=int(b["line"].iloc[r]), code=code)

    check_run_time(seconds, fail, what=f"CAM time on {profile.name}", code=lambda r: kinds[r])


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
    for w in s.get("work_offsets") or []:
        axes = " ".join(f"{c[1].upper()}{v:g}" for c, v in w["offset"].items())
        lines.append(f"  work offset  {w['coord_system']} {axes} ({w['blocks']} blocks)")
    for col, (lo, hi) in (s.get("bbox_machine") or {}).items():
        lines.append(f"  machine {col[0]:<4} {lo:.4f} .. {hi:.4f}")
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
