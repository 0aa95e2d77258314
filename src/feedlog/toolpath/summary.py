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
    return _moving(_extents(program))


def _moving(box: dict[str, list[float]]) -> dict[str, list[float]]:
    """The linear axes, and the rotary ones that leave 0."""
    out = {}
    for j, name in enumerate(END_COLUMNS):
        if name in box and (j < 3 or box[name][0] != 0 or box[name][1] != 0):
            out[name] = box[name]
    return out


def _extents(program: Program) -> dict[str, list[float]]:
    """`extents` with every axis."""
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
    return {name: [float(lo[j]), float(hi[j])] for j, name in enumerate(END_COLUMNS)}


SYSTEM_NAMES = ("", "G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3")


def system_name(code: int) -> str:
    """The block table's `coord_system` as a G code (10 and up: Fanuc's G54.1 P1, P2, ...)."""
    return SYSTEM_NAMES[code] if 0 <= code < len(SYSTEM_NAMES) else f"G54.1 P{code - 9}"


def _offset_counts(program: Program) -> dict[tuple, int]:
    """Motion blocks per (work offset, coordinate system), in order of first use; empty when every
    offset is 0 or the table has none."""
    m = program.motion
    if not len(m) or not all(c in m.columns for c in WORK_OFFSET_COLUMNS) \
            or not m[list(WORK_OFFSET_COLUMNS)].to_numpy().any():
        return {}
    return {key: int(n) for key, n in m.groupby([*WORK_OFFSET_COLUMNS, "coord_system"], sort=False).size().items()}


def _offset_list(counts: dict[tuple, int]) -> list[dict[str, Any]]:
    return [{"coord_system": system_name(int(key[-1])),
             "offset": {c: float(v) for c, v in zip(WORK_OFFSET_COLUMNS, key[:-1]) if v != 0},
             "blocks": n} for key, n in counts.items()]


def work_offsets(program: Program) -> list[dict[str, Any]]:
    """The work offsets in force on motion blocks, in order of first use: coordinate system, offset per
    axis (only axes with one), number of blocks. Empty when every offset is 0 or the table has none."""
    return _offset_list(_offset_counts(program))


def _merge_box(box: dict[str, list[float]], more: dict[str, list[float]]) -> None:
    for name, (lo, hi) in more.items():
        old = box.setdefault(name, [lo, hi])
        old[0], old[1] = min(old[0], lo), max(old[1], hi)


class Summary:
    """`summarize` over the block table in batches (toolpath.ProgramReader): counts, sums, extents and
    ranges gathered batch by batch, so a program of any length is summarised in the memory of a batch.
    Sums over several batches may differ from one sum in the last bits."""

    def __init__(self, profile: MachineProfile, *, name: str) -> None:
        self.profile, self.name = profile, name
        self.rows = self.blocks = self.without_time = 0
        self.kinds: dict[str, int] = {}
        self.length = self.rapid_length = self.cam_time = self.rapid_time = self.dwell = 0.0
        self.run_time = 0.0                      # CAM time so far, for the 31.7-year check
        self.bbox: dict[str, list[float]] = {}
        self.bbox_machine: dict[str, list[float]] = {}
        self.feed: list[float] | None = None
        self.tol: list[float] | None = None
        self.modes: set[str] = set()
        self.units: set[str] = set()
        self.offsets: dict[tuple, int] = {}
        self.five_axis = False

    def add(self, blocks) -> None:
        """The next batch of rows of the block table."""
        program, b, profile = Program(blocks=blocks, metadata={"file": self.name}), blocks, self.profile
        check_axes(b, profile.axis_names, profile.name)
        feats = block_features(program, profile)
        self.run_time = _check_cam_time(program, feats, profile, before=self.run_time)
        for k, v in b["kind"].value_counts().items():
            self.kinds[str(k)] = self.kinds.get(str(k), 0) + int(v)
        rapid = feats["kind"].to_numpy() == RAPID
        feed = feats.loc[~rapid, "feed_mm_min"].to_numpy()
        feed = feed[np.isfinite(feed)]
        nominal = feats["nominal_time_s"].to_numpy()
        self.rows += len(b)
        self.blocks += len(feats)
        self.length += float(feats["length_mm"].sum())
        self.rapid_length += float(feats.loc[rapid, "length_mm"].sum())
        dwell_s = float(b["dwell_s"].sum())
        self.cam_time += float(np.nansum(nominal)) + dwell_s
        self.without_time += int(np.isnan(nominal).sum())
        self.rapid_time += float(feats.loc[rapid, "nominal_time_s"].sum())
        self.dwell += dwell_s
        _merge_box(self.bbox, _extents(program))
        if len(feed):
            self.feed = _range(self.feed, float(feed.min()), float(feed.max()))
        tol = feats["tol_mm"].to_numpy()
        if np.isfinite(tol).any():
            self.tol = _range(self.tol, float(np.nanmin(tol)), float(np.nanmax(tol)))
        self.modes |= {str(m) for m in program.motion["path_mode"].unique()}
        self.units |= {str(u) for u in b["units"].unique()}
        counts = _offset_counts(program)
        for key, n in counts.items():
            self.offsets[key] = self.offsets.get(key, 0) + n
        if counts:
            _merge_box(self.bbox_machine, _extents(Program(blocks=to_machine(b))))
        self.five_axis |= bool(b["ori_i"].notna().any() or (b[["a_deg", "b_deg", "c_deg"]] != 0).any(axis=None))

    def result(self, *, warnings, unsupported, metadata) -> dict[str, Any]:
        return {
            "file": self.name,
            "profile": self.profile.name,
            "rows": self.rows,
            "blocks": self.blocks,
            "kinds": {k: self.kinds.get(k, 0) for k in (*MOTION_KINDS, "dwell")},
            "length_mm": self.length,
            "rapid_length_mm": self.rapid_length,
            "cam_time_s": self.cam_time,
            "blocks_without_time": self.without_time,
            "rapid_time_s": self.rapid_time,
            "dwell_s": self.dwell,
            "bbox": _moving(self.bbox),
            "feed_mm_min": self.feed,
            "path_modes": sorted(self.modes),
            "tol_mm": None if self.tol is None else [_num(self.tol[0]), _num(self.tol[1])],
            "units": sorted(self.units),
            "work_offsets": _offset_list(self.offsets),
            "bbox_machine": _moving(self.bbox_machine) if self.offsets else None,
            "five_axis": self.five_axis,
            "warnings": list(warnings),
            "unsupported": [{"line": u.line, "code": u.code, "reason": u.reason} for u in unsupported],
            "metadata": {k: v for k, v in metadata.items() if k not in ("percent_lines",)},
        }


def _range(old: list[float] | None, lo: float, hi: float) -> list[float]:
    return [lo, hi] if old is None else [min(old[0], lo), max(old[1], hi)]


def summarize(program: Program, profile: MachineProfile) -> dict[str, Any]:
    """Summary of `program` on `profile`: CAM time is sum(L/F) over feed moves, rapids at the profile's
    rapid rate, plus dwells (no acceleration, no blending: what a CAM system estimates)."""
    summary = Summary(profile, name=program.name)
    summary.add(program.blocks)
    return summary.result(warnings=program.warnings, unsupported=program.unsupported, metadata=program.metadata)


def _check_cam_time(program: Program, feats, profile: MachineProfile, *, before: float = 0.0) -> float:
    """CAM time (rapids at the profile's rapid rate included) within what feedlog counts in int64 ns,
    after `before` seconds of earlier batches; returns the running total."""
    b = program.blocks
    seconds = b["dwell_s"].to_numpy(dtype=np.float64, copy=True)
    first = int(b["block"].iloc[0]) if len(b) else 0    # a batch's rows are numbered from the file's start
    seconds[feats["block"].to_numpy() - first] += np.nan_to_num(feats["nominal_time_s"].to_numpy(dtype=np.float64))
    kinds = b["kind"].astype(str).to_numpy()

    def fail(r: int, message: str, code: str) -> ProgramError:
        return ProgramError(message, file=program.name, line=int(b["line"].iloc[r]), code=code)

    return check_run_time(seconds, fail, what=f"CAM time on {profile.name}", code=lambda r: kinds[r], before=before)


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
    if s.get("profile_choice"):
        lines.append(f"  profile      {s['profile_choice']}")
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
