"""Per-block geometry features of Chien et al. (2024) and Sun et al. (2021/2022), vectorised.

One row per motion block (rapid, linear, arc), columns `schema.FEATURE_COLUMNS` plus
`corner_cos_end` (Sun Eq. 8). Definitions, with block k running from point P_{k-1} to P_k
(docs/program-table.md has the full text):

- `length_mm` L_k: TCP path length (Chien Eq. 1; arcs: true, helical arc length).
- `corner_start_deg` theta_TCP,k: angle between the TCP direction at the end of the previous block and
  at the start of block k (Chien Eq. 3-6; 0 = collinear, 180 = reversal). Arcs use their tangents.
  Blocks without TCP motion are skipped over (their own corners are 0). Where the machine is at rest
  (program start and end, around a dwell or a program stop M0/M1/M6/M60) the corner is 180, the
  same full stop as a reversal. `corner_end_deg` theta_TCP,k+1 is the next block's `corner_start_deg`.
- `ori_arc_deg` theta_k = acos(O_{k-1} . O_k) (Chien Eq. 2), O the unit tool orientation vector.
- `ori_corner_start_deg` / `ori_corner_end_deg` theta_ORI,k / theta_ORI,k+1: the same corner rule on
  the unit sphere, between great-circle directions of successive orientation moves.
- `sin_rot`: sin(A) (AC) or sin(B) (BC) at the block end, of the programmed rotary position (Chien
  Eq. 7-9); with I J K orientation vectors and no rotary words, sin(A) = sqrt(O_i^2 + O_j^2);
  0 for three-axis programs.
- `nominal_time_s` t_k = L_k / F_k (Sun Eq. 5): feed moves at their programmed feed (a move of rotary
  axes alone: rotary length in deg over F in deg/min, as LinuxCNC); rapids at the profile's rapid
  rate (rotary axes at their velocity limits, when the profile has them).
- `v?_nom_mm_min` f_x,k = (X_k - X_{k-1}) / t_k (Sun Eq. 6; arcs: chord over arc time, i.e. the mean
  axis velocity of the block). `a?_nom_mm_s2` a_x,k = (f_x,k - f_x,k-1) / t_k (Sun Eq. 7), in mm/s^2,
  with f_x = 0 before a block that starts from rest.
- `corner_cos_end` (Sun Eq. 8): (P_{k+1} - P_k).(P_{k-1} - P_k) / (|..| |..|) at the block's end point,
  i.e. -cos(theta_TCP,k+1): -1 for collinear blocks, +1 for a reversal or a stop.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from feedlog.profile import MachineProfile, load_profile
from feedlog.toolpath import arcs
from feedlog.toolpath.program import (K_ARC_CCW, K_ARC_CW, K_DWELL, K_RAPID, kind_codes,
                                      kind_column)
from feedlog.toolpath.offsets import WORK_OFFSET_COLUMNS
from feedlog.toolpath.schema import END_COLUMNS, FEATURE_COLUMNS, OFFSET_FEATURE_COLUMNS, START_COLUMNS

DEFAULT_PROFILE = "linuxcnc-xyz"
STOP_MCODES = ("M0", "M1", "M2", "M6", "M30", "M60")
_STOP_RE = r"\bM(?:" + "|".join(c[1:] for c in STOP_MCODES) + r")\b"
EPS = 1e-9


def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows of v scaled to unit length; NaN rows (and ok False) where the length is ~0."""
    norm = np.sqrt(np.einsum("ij,ij->i", v, v))
    ok = norm > EPS
    with np.errstate(divide="ignore", invalid="ignore"):
        out = v / norm[:, None]
    if not ok.all():
        out[~ok] = np.nan
    return out, ok


def _tangents(m: dict[str, np.ndarray], kind: np.ndarray, p0: np.ndarray,
              p1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit TCP direction (n, 3) at the start and at the end of each block (NaN without TCP motion)."""
    t0, _ = _unit(p1 - p0)
    t1 = t0.copy()
    arc = (kind == K_ARC_CW) | (kind == K_ARC_CCW)
    if arc.any():
        a = np.flatnonzero(arc)
        idx = arcs.plane_index(m["plane"][a])
        s = arcs.to_plane(p0[a], idx)
        e = arcs.to_plane(p1[a], idx)
        c = arcs.to_plane(np.column_stack([m["cx_mm"][a], m["cy_mm"][a], m["cz_mm"][a]]), idx)
        sgn = np.where(kind[a] == K_ARC_CCW, 1.0, -1.0)
        swept = np.radians(m["sweep_deg"][a])
        r0 = np.hypot(s[:, 0] - c[:, 0], s[:, 1] - c[:, 1])
        r1 = np.hypot(e[:, 0] - c[:, 0], e[:, 1] - c[:, 1])
        rise = (e[:, 2] - s[:, 2]) / swept
        for pt, r, out in ((s, r0, t0), (e, r1, t1)):
            ang = np.arctan2(pt[:, 1] - c[:, 1], pt[:, 0] - c[:, 0])
            d = np.column_stack([-sgn * r * np.sin(ang), sgn * r * np.cos(ang), rise])
            out[a] = arcs.from_plane(_unit(d)[0], idx)
    return t0, t1


def _corners(t0: np.ndarray, t1: np.ndarray, moving: np.ndarray, stop_before: np.ndarray,
             stop_angle: float = 180.0) -> tuple[np.ndarray, np.ndarray]:
    """Direction change entering and leaving each block, skipping blocks that do not move."""
    n = len(moving)
    seg = np.cumsum(stop_before)  # blocks j < k share a segment (no rest between) iff seg equal
    idx = np.where(moving, np.arange(n), -1)
    last = np.maximum.accumulate(idx)
    prev = np.r_[-1, last[:-1]]  # last moving block before k
    ok = moving & (prev >= 0)
    ok[ok] &= seg[prev[ok]] == seg[ok]
    start = np.where(moving, stop_angle, 0.0)
    if ok.any():
        dot = np.einsum("ij,ij->i", t1[prev[ok]], t0[ok])
        start[ok] = np.degrees(np.arccos(np.clip(dot, -1.0, 1.0)))
    nxt_idx = np.where(moving, np.arange(n), n)
    nxt = np.r_[np.minimum.accumulate(nxt_idx[::-1])[::-1][1:], n]  # next moving block after k
    okn = moving & (nxt < n)
    okn[okn] &= seg[np.minimum(nxt[okn], n - 1)] == seg[okn]
    end = np.where(moving, stop_angle, 0.0)
    end[okn] = start[nxt[okn]]
    return start, end


def _orientation(m: dict[str, np.ndarray], prefix: str, kin: str) -> np.ndarray:
    """Unit tool orientation (n, 3) from rotary positions (Chien Eq. 7); prefix "" (end) or "0" (start)."""
    a, b, c = (np.radians(m[f"{ax}{prefix}_deg"]) for ax in "abc")
    if kin == "ac":
        return np.column_stack([np.sin(a) * np.sin(c), np.sin(a) * np.cos(c), np.cos(a)])
    if kin == "bc":
        return np.column_stack([np.sin(b) * np.cos(c), np.sin(b) * np.sin(c), np.cos(b)])
    return np.tile([0.0, 0.0, 1.0], (len(a), 1))


class _Columns(dict):
    """Columns of the motion rows as numpy arrays, gathered on first use (three-axis programs never
    touch the rotary and orientation columns)."""

    def __init__(self, table: pd.DataFrame, rows: np.ndarray) -> None:
        super().__init__()
        self.table, self.rows = table, rows

    def __missing__(self, name: str) -> np.ndarray:
        values = self.table[name].to_numpy()[self.rows]
        self[name] = values
        return values


def _kinematics(table: pd.DataFrame, profile: MachineProfile | None) -> str:
    if profile is not None and profile.kinematics.type != "xyz":
        return {"xyzac-trt": "ac", "xyzbc-trt": "bc"}[profile.kinematics.type]
    moved = {ax: bool((table[f"{ax}_deg"].to_numpy() != 0).any()) for ax in "abc"}
    return "ac" if moved["a"] else "bc" if moved["b"] else "none"


def _work_offsets(table: pd.DataFrame, rows: np.ndarray) -> np.ndarray | None:
    """(len(rows), 6) work offsets of the motion rows; None when the table has none or all are 0."""
    if not all(c in table.columns for c in WORK_OFFSET_COLUMNS):
        return None
    cols = [table[c].to_numpy(dtype=np.float64) for c in WORK_OFFSET_COLUMNS]
    if not any(col.any() for col in cols):
        return None
    return np.column_stack([col[rows] for col in cols])


def block_features(program, profile: MachineProfile | str | None = None) -> pd.DataFrame:
    """Geometry features per motion block of `program` (a Program or its block table).

    `profile` (object, shipped name or TOML path) gives the rapid rate and the rotary kinematics;
    None uses the rapid rate of `linuxcnc-xyz` and infers AC/BC from the program's rotary words.
    """
    table = getattr(program, "blocks", program)
    if profile is None or isinstance(profile, str):
        prof = load_profile(profile or DEFAULT_PROFILE)
        kin_profile = None if profile is None else prof
    else:
        prof = kin_profile = profile
    kind_all = kind_codes(table["kind"])
    is_motion = (kind_all >= 0) & (kind_all <= K_ARC_CCW)
    # a rest between motion blocks: a dwell or a program stop (M0 M1 M2 M6 M30 M60) in between
    rest_row = kind_all == K_DWELL
    if "stop" in table.columns:
        rest_row |= table["stop"].to_numpy(dtype=bool)
    else:
        mc = table["mcodes"].fillna("").to_numpy(dtype=object)
        with_m = np.flatnonzero(mc != "")
        if len(with_m):
            rest_row[with_m] |= pd.Series(mc[with_m]).str.contains(_STOP_RE, regex=True).to_numpy()
    rest_count = np.cumsum(rest_row)
    mi = np.flatnonzero(is_motion)
    m = _Columns(table, mi)
    n = len(mi)
    work = _work_offsets(table, mi)
    if work is not None and work[:, 3:].any():  # rotary work offsets: orientation from machine angles
        for j, ax in enumerate("abc"):
            m[f"{ax}_deg"] = m[f"{ax}_deg"] + work[:, 3 + j]
            m[f"{ax}0_deg"] = m[f"{ax}0_deg"] + work[:, 3 + j]
    rc = rest_count[mi]
    stop_before = np.r_[True, rc[1:] != rc[:-1]] if n else np.zeros(0, bool)
    # a program stop on the block's own line happens after its motion
    own_stop = rest_row[mi] & (kind_all[mi] != K_DWELL)
    stop_before[1:] |= own_stop[:-1]

    p0 = np.column_stack([m[c] for c in START_COLUMNS[:3]])
    p1 = np.column_stack([m[c] for c in END_COLUMNS[:3]])
    length = m["length_mm"]
    kind = kind_all[mi]
    t0, t1 = _tangents(m, kind, p0, p1)
    tcp_moving = length > EPS
    corner_start, corner_end = _corners(t0, t1, tcp_moving, stop_before)

    # tool orientation: I J K where given, else rotary positions (Chien Eq. 7), else +Z
    kin = _kinematics(table, kin_profile)
    any_given = bool(table["ori_i"].notna().any())
    given = np.column_stack([m["ori_i"], m["ori_j"], m["ori_k"]]) if any_given else np.full((n, 3), np.nan)
    has_given = ~np.isnan(given).any(axis=1) if any_given else np.zeros(n, dtype=bool)
    if kin == "none" and not has_given.any():  # three-axis: the tool never turns
        ori_arc = ori_start = ori_end = np.zeros(n)
    else:
        o1 = _orientation(m, "", kin)
        o0 = _orientation(m, "0", kin)
        if has_given.any():
            o1 = np.where(has_given[:, None], given, o1)
            prev_given = np.vstack([given[:1], given[:-1]])
            o0 = np.where(has_given[:, None], np.where(np.isnan(prev_given), given, prev_given), o0)
        cos_arc = np.clip(np.einsum("ij,ij->i", o0, o1), -1.0, 1.0)
        ori_arc = np.degrees(np.arccos(cos_arc))
        g0, ok0 = _unit(o1 - cos_arc[:, None] * o0)   # great-circle direction leaving O_{k-1}
        g1, _ = _unit(cos_arc[:, None] * o1 - o0)     # ... arriving at O_k
        ori_moving = ok0 & (ori_arc > 1e-9)
        ori_start, ori_end = _corners(g0, g1, ori_moving, stop_before)

    if kin == "ac":
        sin_rot = np.sin(np.radians(m["a_deg"]))
    elif kin == "bc":
        sin_rot = np.sin(np.radians(m["b_deg"]))
    else:
        sin_rot = np.zeros(n)
    if has_given.any() and kin == "none":
        sin_rot = np.where(has_given, np.hypot(given[:, 0], given[:, 1]), sin_rot)

    # nominal time and Sun's nominal axis feeds / accelerations
    feed = m["feed_mm_min"]
    with np.errstate(divide="ignore", invalid="ignore"):
        t_rapid = length / prof.rapid_mm_min * 60.0
        time_len = length
        if any((table[f"{ax}_deg"].to_numpy() != 0).any() for ax in "abc"):
            rot = np.column_stack([m[f"{ax}_deg"] - m[f"{ax}0_deg"] for ax in "abc"])
            time_len = np.where(tcp_moving, length, np.sqrt(np.einsum("ij,ij->i", rot, rot)))
            for j, ax in enumerate("abc"):
                vmax = prof.axes[ax].vel_max if ax in prof.axes else prof.rapid_mm_min / 60.0
                t_rapid = np.maximum(t_rapid, np.abs(rot[:, j]) / vmax)
        t_feed = time_len / feed * 60.0
    t = np.where(kind == K_RAPID, t_rapid, t_feed)
    t = np.where(time_len > EPS, t, 0.0)
    dt = np.where(t > 0, t, np.inf)
    v = (p1 - p0) / dt[:, None] * 60.0  # mm/min
    v_prev = np.vstack([np.zeros((1, 3)), v[:-1]]) if n else v
    v_prev[stop_before] = 0.0
    acc = (v - v_prev) / 60.0 / dt[:, None]

    out = pd.DataFrame({
        "block": m["block"], "line": m["line"], "kind": kind_column(kind),
        "length_mm": length,
        "ori_arc_deg": ori_arc,
        "corner_start_deg": corner_start, "corner_end_deg": corner_end,
        "ori_corner_start_deg": ori_start, "ori_corner_end_deg": ori_end,
        "sin_rot": sin_rot,
        "feed_mm_min": feed, "tol_mm": m["tol_mm"],
        "nominal_time_s": t,
        "vx_nom_mm_min": v[:, 0], "vy_nom_mm_min": v[:, 1], "vz_nom_mm_min": v[:, 2],
        "ax_nom_mm_s2": acc[:, 0], "ay_nom_mm_s2": acc[:, 1], "az_nom_mm_s2": acc[:, 2],
        "corner_cos_end": -np.cos(np.radians(corner_end)),
        **{c: (work[:, j] if work is not None else np.zeros(n)) for j, c in enumerate(OFFSET_FEATURE_COLUMNS)},
    })
    assert tuple(out.columns[:len(FEATURE_COLUMNS)]) == FEATURE_COLUMNS
    return out
