"""G2/G3 words -> arc geometry for all arc blocks at once, with the checks LinuxCNC makes.

Centre format (I J K, incremental from the start or absolute with G90.1) or radius format (R > 0: at
most 180 deg, R < 0: the longer way); P gives the number of turns. The offset word along the plane's
normal, both formats on one line, neither, a radius shorter than half the chord are errors, and so is a
centre whose end radius differs from its start radius beyond LinuxCNC's limit: more than 100 x T, or more
than T and 0.1 %, where T is CENTER_ARC_RADIUS_TOLERANCE (0.0283 mm in mm programs, 0.00283 in in inch
programs). LinuxCNC runs such slightly spiral arcs (4-decimal inch rounding makes them), and so does
feedlog.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from feedlog.toolpath import arcs
from feedlog.toolpath.limits import MAX_ARC_TURNS

MM_PER_INCH = 25.4
# LinuxCNC's CENTER_ARC_RADIUS_TOLERANCE_INCH / _MM (INI settable there) and its relative limit
CENTER_ARC_RADIUS_TOLERANCE_INCH = 2 * 0.001 * np.sqrt(2)
CENTER_ARC_RADIUS_TOLERANCE_MM = 2 * 0.01 * np.sqrt(2)
SPIRAL_RELATIVE_TOLERANCE = 0.001


def spiral_too_large(r0, r1, tolerance):
    """LinuxCNC's test of a centre-format arc's end radius r1 against its start radius r0 (same units
    as `tolerance`): True where the arc is refused."""
    abs_err = np.abs(r1 - r0)
    rel_err = abs_err / np.maximum(r0, r1)
    return (abs_err > tolerance * 100.0) | ((rel_err > SPIRAL_RELATIVE_TOLERANCE) & (abs_err > tolerance))


@dataclass
class ArcWords:
    """The words of m arc blocks, lengths in mm; NaN where a word is absent."""

    start: np.ndarray            # (m, 3) xyz
    end: np.ndarray              # (m, 3) xyz
    plane: np.ndarray            # (m,) 17, 18, 19
    ccw: np.ndarray              # (m,) G3
    ijk: np.ndarray              # (m, 3) I J K
    radius: np.ndarray           # (m,) R
    turns: np.ndarray            # (m,) P
    absolute_centre: np.ndarray  # (m,) G90.1
    inch: np.ndarray | None = None  # (m,) bool: the arc's line is in inches (its tolerance is the inch one)


@dataclass
class ArcGeometry:
    centre: np.ndarray   # (m, 3) xyz; the normal coordinate is the start's
    radius: np.ndarray   # start radius
    sweep: np.ndarray    # swept angle (rad, > 0), turns included
    turns: np.ndarray    # int16
    length: np.ndarray   # helical arc length


def resolve_arcs(w: ArcWords, fail: Callable[[int, str, str], Exception]) -> ArcGeometry:
    """Centres, radii, sweeps and lengths; `fail(k, message, code)` builds the error for arc k."""
    p = w.turns
    bad = ~np.isnan(p) & ((p < 1) | (p != np.rint(p)) | (p > MAX_ARC_TURNS))
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise fail(k, f"arc P (turns) must be a whole number from 1 to {MAX_ARC_TURNS}", f"P{p[k]:g}")
    turns = np.where(np.isnan(p), 1, p).astype(np.int16)
    idx = arcs.plane_index(w.plane)
    s = arcs.to_plane(w.start, idx)
    e = arcs.to_plane(w.end, idx)
    has_uvw = arcs.to_plane(~np.isnan(w.ijk), idx)
    off = arcs.to_plane(np.nan_to_num(w.ijk), idx)
    use_r = ~np.isnan(w.radius)
    in_plane = has_uvw[:, :2].any(axis=1)

    def first(mask: np.ndarray, message: str, code) -> None:
        if mask.any():
            k = int(np.flatnonzero(mask)[0])
            raise fail(k, message, code(k) if callable(code) else code)

    first(use_r & in_plane, "arc with both R and I/J/K", "R")
    first(has_uvw[:, 2], "the offset word along the normal of the arc's plane",
          lambda k: f"{'IJK'[int(idx[k, 2])]} in G{w.plane[k]}")
    first(~use_r & ~in_plane, "arc needs R or centre words", "G2/G3")
    c = np.where(w.absolute_centre[:, None], off[:, :2], s[:, :2] + off[:, :2])
    if use_r.any():
        c_r, ok = arcs.centre_from_radius(s[use_r, :2], e[use_r, :2], w.radius[use_r], w.ccw[use_r])
        bad_r = np.zeros(len(use_r), dtype=bool)
        bad_r[np.flatnonzero(use_r)[~ok]] = True
        first(bad_r, "arc radius is shorter than half the chord (or start equals end)",
              lambda k: f"R{w.radius[k]:g}")
        c[use_r] = c_r
    r0 = np.hypot(s[:, 0] - c[:, 0], s[:, 1] - c[:, 1])
    r1 = np.hypot(e[:, 0] - c[:, 0], e[:, 1] - c[:, 1])
    first(r0 <= 0, "arc of zero radius", "G2/G3")
    tol_mm = np.where(w.inch if w.inch is not None else False, CENTER_ARC_RADIUS_TOLERANCE_INCH * MM_PER_INCH,
                      CENTER_ARC_RADIUS_TOLERANCE_MM)
    mism = ~use_r & spiral_too_large(r0, r1, tol_mm)
    if mism.any():
        k = int(np.flatnonzero(mism)[0])
        raise fail(k, f"arc end radius {r1[k]:.4f} differs from start radius {r0[k]:.4f} mm",
                   "G3" if w.ccw[k] else "G2")
    swept = arcs.sweep(s[:, :2], e[:, :2], c, w.ccw, turns)
    return ArcGeometry(centre=arcs.from_plane(np.column_stack([c, s[:, 2]]), idx), radius=r0, sweep=swept,
                       turns=turns, length=arcs.arc_length(r0, r1, swept, e[:, 2] - s[:, 2]))
