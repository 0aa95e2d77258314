"""G5 (cubic), G5.1 (quadratic) splines and G5.2/G5.3 NURBS in the XY plane as LinuxCNC 2.9's motion
controller runs them.

LinuxCNC's interpreter hands a spline to its canon as a NURBS of 4 (G5) or 3 (G5.1) control points with
unit weights and a clamped knot vector: with that few points the curve is the Bezier curve of its
control points over u in [0, 1]. What the canon then makes of it differs between LinuxCNC's two canons:

- the motion controller's canon (`emccanon`, what the machine executes) samples the curve at
  4 x (control points) equal steps of u and joins each pair of samples by a biarc (two tangent circular
  arcs, or a line where an arc is flatter than 1e-6 program units) that meets the curve's tangents at
  both samples; the tangent is a central difference of the curve over u +- 1e-5;
- the `gcode` module (AXIS's preview, feedlog's reference harness) draws 15 x (control points) straight
  chords instead.

feedlog follows the motion controller, as it does for a units change under a tool offset: a G5 is 16
rows (8 biarcs), a G5.1 24 rows (12 biarcs). Where a biarc cannot be fitted (the two tangents are the
same direction: the span is straight, and LinuxCNC's fit divides by zero), the span is refused with
the line; inverse time (G93) splines are refused (each of LinuxCNC's segments takes the whole 1/F).
"""

from __future__ import annotations

import math

from feedlog.toolpath.interp.canon import K_ARC_CCW, K_ARC_CW, K_LINEAR
from feedlog.toolpath.interp.errors import InterpError

SPANS_PER_POINT = 4          # emccanon: 4 biarcs per control point
TANGENT_DU = 1e-5            # the central difference step of the tangent (in u)
FLAT = 1e-6                  # an arc flatter than this (program units) is a line


def convert_spline(m, motion: int, b) -> None:
    """Run G5 (`motion` 50) or G5.1 (51) of block `b` on machine `m` (toolpath.interp.machine.Machine),
    with LinuxCNC's checks in its order."""
    v = b.v
    if m.comp.side:
        raise InterpError("cannot convert spline with cutter radius compensation")
    if m.feed_mode == 940 and m.feed == 0.0:
        raise InterpError("cannot make arc with zero feed rate")
    if m.feed_mode == 930:
        if "f" not in v:
            raise InterpError("F word missing with inverse time arc move")
        raise InterpError("splines in inverse time (G93) are not simulated")
    if m.plane != 170:
        raise InterpError("splines must be in the XY plane")
    if any(a in v for a in "zabc"):
        raise InterpError("splines may not have motion in Z, A, B, or C")
    x0, y0 = m.pos[0], m.pos[1]
    if motion == 51:
        if "i" not in v or "j" not in v:
            raise InterpError("must specify both I and J with G5.1")
        control = [(x0, y0), (x0 + v["i"], y0 + v["j"])]
        end = m._ends(b)
        control.append((end[0], end[1]))
    else:
        if "i" in v and "j" in v:
            i, j = v["i"], v["j"]
        elif "i" in v or "j" in v:
            raise InterpError("must specify both I and J, or neither")
        else:   # the previous G5's end tangent, mirrored (0, 0 before any)
            i, j = m.spline_ij
        end = m._ends(b)
        if "p" not in v or "q" not in v:
            raise InterpError("must specify both P and Q with G5")
        control = [(x0, y0), (x0 + i, y0 + j), (end[0] + v["p"], end[1] + v["q"]), (end[0], end[1])]
        m.spline_ij = (-v["p"], -v["q"])
    m.motion_mode = motion
    m.cycle_il = None
    _run(m, biarcs(control), control[-1])


def _run(m, moves, end) -> None:
    """Emit the moves in the XY plane at the tool's Z; the interpreter's point ends at `end` (x, y)."""
    z = m.pos[2]
    for kind, (ex, ey), centre in moves:
        target = [ex, ey, z, m.pos[3], m.pos[4], m.pos[5]]
        if kind == K_LINEAR:
            m.emit(K_LINEAR, target)
        else:
            m.emit(kind, target, (centre[0], centre[1], z), turns=1)
        m.pos = target
    m.pos[0], m.pos[1] = end[0], end[1]


def point(control, u: float) -> tuple[float, float]:
    """The Bezier curve of `control` (3 or 4 points) at u in [0, 1]."""
    w = 1.0 - u
    if len(control) == 3:
        basis = (w * w, 2.0 * u * w, u * u)
    else:
        basis = (w * w * w, 3.0 * u * w * w, 3.0 * u * u * w, u * u * u)
    return (sum(c[0] * k for c, k in zip(control, basis)), sum(c[1] * k for c, k in zip(control, basis)))


def tangent(control, u: float) -> tuple[float, float]:
    """The unit tangent at u, as LinuxCNC takes it: the chord from u - 1e-5 to u + 1e-5 (clipped to 0..1)."""
    lo, hi = max(0.0, u - TANGENT_DU), min(1.0, u + TANGENT_DU)
    (ax, ay), (bx, by) = point(control, lo), point(control, hi)
    dx, dy = (bx - ax) / (hi - lo), (by - ay) / (hi - lo)
    return _unit(dx, dy)


def _unit(x: float, y: float) -> tuple[float, float]:
    h = math.hypot(x, y)
    return (x / h, y / h) if h != 0.0 else (x, y)


def biarcs(control):
    """The motion controller's moves for one spline: (kind, end point, centre or None) in order."""
    spans = SPANS_PER_POINT * len(control)
    p0, t0 = point(control, 0.0), tangent(control, 0.0)
    out = []
    for k in range(1, spans + 1):
        u = k / spans
        p1, t1 = point(control, u), tangent(control, u)
        out += _biarc(p0, t0, p1, t1)
        p0, t0 = p1, t1
    return out


def _biarc(p0, ts, p4, te):
    """Two arcs from p0 (tangent ts) to p4 (tangent te) meeting at a point where their tangents agree,
    the first and second arc's tangent lengths equal (LinuxCNC's biarc with ratio 1)."""
    vx, vy = p0[0] - p4[0], p0[1] - p4[1]
    c = vx * vx + vy * vy
    b = 2.0 * (vx * (ts[0] + te[0]) + vy * (ts[1] + te[1]))
    a = 2.0 * (ts[0] * te[0] + ts[1] * te[1] - 1.0)
    if a >= 0.0:
        raise InterpError("spline span is straight or empty: LinuxCNC's biarc fit of it divides by zero "
                          "(not simulated)")
    root = math.sqrt(b * b - 4.0 * a * c)     # a < 0 < c: always real, one root of each sign
    beta = max((-b - root) / 2.0 / a, (-b + root) / 2.0 / a)
    p1 = (p0[0] + beta * ts[0], p0[1] + beta * ts[1])
    p3 = (p4[0] - beta * te[0], p4[1] - beta * te[1])
    mid = ((p1[0] + p3[0]) / 2.0, (p1[1] + p3[1]) / 2.0)
    tm = _unit(p3[0] - mid[0], p3[1] - mid[1])
    return [_arc(p0, mid, ts), _arc(mid, p4, tm)]


def _arc(start, end, t):
    """The circle from `start` with tangent `t` through `end` (a line when it is flatter than FLAT)."""
    x, y = end[0] - start[0], end[1] - start[1]
    den = 2.0 * (y * t[0] - x * t[1])
    if abs(den) <= FLAT:
        return K_LINEAR, end, None
    r = -(x * x + y * y) / den
    centre = (start[0] + t[1] * r, start[1] - t[0] * r)
    return (K_ARC_CCW if r < 0 else K_ARC_CW), end, centre


# -- G5.2 / G5.3 NURBS --------------------------------------------------------------------------------

def nurbs_point_line(m, b) -> None:
    """A G5.2 line (`motion` 52): LinuxCNC's checks, then the line's control point (X Y, weight P) joins the
    list that G5.3 runs; order L (above 3; 3 unless given)."""
    v = b.v
    if ("x" in v) != ("y" in v):
        raise InterpError("you must specify both X and Y coordinates for control points")
    p = v.get("p", -1.0)
    if "x" not in v and p > 0 and m.nurbs_points:
        raise InterpError("can specify P without X and Y only for the first control point")
    if p <= 0 and m.nurbs_points:
        raise InterpError("must specify positive weight P for every control point")
    if m.feed_mode == 940 and m.feed == 0.0:
        raise InterpError("cannot make a NURBS with 0 feedrate")
    if m.comp.side:
        raise InterpError("NURBS (G5.2) with cutter radius compensation on are not simulated")
    if m.plane != 170:
        raise InterpError("NURBS (G5.2) outside the XY plane are not simulated (LinuxCNC runs them in X and Y)")
    if m.feed_mode == 930:
        raise InterpError("NURBS (G5.2) in inverse time (G93) are not simulated")
    if m.motion_mode != 52:
        m.nurbs_points = []
    if not m.nurbs_points:
        m.nurbs_order = 3
        m.nurbs_points.append((m.pos[0], m.pos[1], p if ("x" not in v and p > 0) else 1.0))
    if "l" in v and v["l"] > 3:
        m.nurbs_order = int(v["l"])
    if "x" in v:
        end = m._ends(b)
        m.nurbs_points.append((end[0], end[1], p))
    m.motion_mode = 52


def nurbs_end(m) -> None:
    """G5.3: the NURBS of the control points so far runs (the motion controller's biarcs)."""
    if m.motion_mode != 52:
        raise InterpError("cannot use G5.3 without G5.2 first")
    points, order = m.nurbs_points, m.nurbs_order
    if len(points) < order:
        raise InterpError(f"you must specify a number of control points at least equal to the order L = {order}")
    _run(m, nurbs_biarcs(points, order), points[-1])
    m.nurbs_points = []
    m.motion_mode = -1


def nurbs_biarcs(points, order: int):
    """The motion controller's moves for a NURBS of `points` (x, y, weight) and `order`: 4 biarcs per
    control point, u in 0..(n - order + 2) over LinuxCNC's clamped integer knots."""
    import numpy as np
    from scipy.interpolate import BSpline

    n = len(points) - 1
    umax = n - order + 2
    knots = [0.0] * order + [float(i - order + 1) for i in range(order, n + 1)] + [float(umax)] * order
    c = np.array([(x * w, y * w, w) for x, y, w in points], float)
    curve = BSpline(np.array(knots), c, order - 1)
    spans = SPANS_PER_POINT * len(points)
    u = umax * np.arange(spans + 1) / spans
    lo, hi = np.maximum(0.0, u - TANGENT_DU), np.minimum(float(umax), u + TANGENT_DU)
    with np.errstate(divide="ignore", invalid="ignore"):
        at, a, b = (h[:, :2] / h[:, 2:] for h in (curve(u), curve(lo), curve(hi)))
        d = (b - a) / (hi - lo)[:, None]
    if not (np.isfinite(at).all() and np.isfinite(d).all()):
        raise InterpError("NURBS weights make the curve undefined (a weight sum of 0): not simulated")
    out = []
    for k in range(spans):
        out += _biarc(tuple(at[k]), _unit(*d[k]), tuple(at[k + 1]), _unit(*d[k + 1]))
    return out
