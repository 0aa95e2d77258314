"""Where LinuxCNC 2.9 puts a blend arc between a line and an arc, or between two arcs.

Source: LinuxCNC 2.9 src/emc/tp/blendmath.c (`blendInit3FromLineArc`, `...ArcLine`, `...ArcArc`,
`blendLineArcPostProcess`, `blendArcLinePostProcess`, `blendArcArcPostProcess`, `findTrimAngle`) and
tp.c (`tpCreateLineArcBlend`, `tpCreateArcLineBlend`, `tpCreateArcArcBlend`), re-derived here in
vectorised form. Two steps:

1. **Arc sides** (`arc_sides`): the blend is first sized as if both sides were straight, along the
   junction tangents. On an arc side it may use a third of the next arc's sweep (two thirds of the
   previous arc's), at most the corner's half-angle where the arc bends away from the corner
   ("convex": then along the chord, sin(phi / 4) R, with the half-angle reduced by phi / 4) and a
   quarter turn where it bends into it (phi R).
2. **Placement** (`place_curved`): the blend circle of the planned radius R is moved until it touches
   both real sides: on a line side its centre is R from the line, on an arc side (centre C_a, radius
   r_a) it is r_a - R (convex) or r_a + R from C_a. This fixes where the line is cut (the distance
   d_L from the corner, the smaller root of a quadratic) and the angle cut off the arc (between the
   corner and the blend centre as seen from C_a). LinuxCNC gives up the blend (and falls back to the
   tangent or kink rule) where the sides are not coplanar with the blend, where no such circle exists,
   where it lies further than the tolerance from the corner, where the angle cut off an arc exceeds
   what step 1 allowed, and between two arcs where the half-angle is below 15 deg.

The blend arc then runs from the cut point on the first side to the cut point on the second; the sides
keep what is left of them (`feedlog.sim.corner_blend` inserts the pieces).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

ANGLE_EPS = 1e-6                 # TP_ANGLE_EPSILON: coplanarity of the blend plane and an arc's plane
ARC_ARC_THETA_MIN = math.pi / 12


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def _unit(a: np.ndarray) -> np.ndarray:
    n = np.sqrt(_dot(a, a))
    return a / np.where(n > 0, n, 1.0)[:, None]


@dataclass
class ArcSides:
    """Per junction: the half-angle the blend is planned with, the length it may take on each side,
    and for arc sides whether the arc bends away from the corner (convex) and the angle it may lose."""

    theta: np.ndarray
    side1: np.ndarray
    side2: np.ndarray
    convex1: np.ndarray
    convex2: np.ndarray
    phi1: np.ndarray     # NaN where the side is a line
    phi2: np.ndarray


def arc_sides(pc, u1, u2, theta, side1, side2, lin) -> ArcSides:
    """Where a junction's side is an arc, the blend length LinuxCNC allows on it and the corner half-angle
    it plans with (blendmath.c blendInit3FromLineArc / ArcLine / ArcArc): at most a third of the next
    arc's sweep (two thirds of the previous arc's), no more than the tangents' half-angle where the arc
    bends away from the corner (convex: along the chord, sin(phi / 4) R, and the half-angle reduced by
    phi / 4), a quarter turn where it bends into it (phi R)."""
    n = len(theta)
    theta_tan = theta
    out = ArcSides(theta=theta.copy(), side1=side1.copy(), side2=side2.copy(), convex1=np.zeros(n, bool),
                   convex2=np.zeros(n, bool), phi1=np.full(n, np.nan), phi2=np.full(n, np.nan))
    for first, u_other, sweep_share in ((True, u2, 2.0 / 3.0), (False, u1, 1.0 / 3.0)):
        side, convex_out, phi_out = (out.side1, out.convex1, out.phi1) if first else (out.side2, out.convex2, out.phi2)
        k = np.flatnonzero(pc.radius[:-1] > 0) if first else np.flatnonzero(pc.radius[1:] > 0)
        if not len(k):
            continue
        p = k if first else k + 1                    # the arc piece at junction k
        r = pc.radius[p]
        ang = pc.omega[p] * pc.length[p] if first else np.zeros(len(p))
        radial = (r[:, None] * (np.cos(ang)[:, None] * pc.e1[p] + np.sin(ang)[:, None] * pc.e2[p]))[:, lin]
        toward = np.einsum("ij,ij->i", radial, u_other[k]) < 0
        convex = toward if first else ~toward        # arcConvexTest(center, P, u, reverse) as LinuxCNC calls it
        sweep = np.abs(pc.omega[p] * pc.length[p])
        phi = np.minimum(sweep * sweep_share, np.where(convex, theta_tan[k], math.pi / 2))
        side[k] = np.where(convex, np.sin(phi / 4.0) * r, phi * r)
        out.theta[k] = np.where(convex, np.minimum(out.theta[k], theta_tan[k] - phi / 4.0), out.theta[k])
        convex_out[k] = convex
        phi_out[k] = phi
    return out


@dataclass
class Placement:
    """Blend arcs placed at junctions `j` (a subset of the junctions asked for, `ok` over those): the
    path length cut off the end of piece j and off the start of piece j + 1, the blend circle's centre
    (x, y, z) and radius, and the angle it turns through."""

    ok: np.ndarray
    j: np.ndarray
    trim_end: np.ndarray
    trim_start: np.ndarray
    centre: np.ndarray
    radius: np.ndarray
    angle: np.ndarray

    def keep(self, rows: np.ndarray) -> Placement:
        """The placed blends `rows` (a mask over `j`) only."""
        k = np.flatnonzero(rows)
        return Placement(ok=self.ok, j=self.j[k], trim_end=self.trim_end[k], trim_start=self.trim_start[k],
                         centre=self.centre[k], radius=self.radius[k], angle=self.angle[k])


def _arc_circle(pc, p: np.ndarray, at_end: bool, lin) -> tuple[np.ndarray, np.ndarray]:
    """Centre (x, y, z) of arc pieces p at their end (or start) and their plane's unit normal."""
    sigma = pc.length[p] if at_end else np.zeros(len(p))
    centre = (pc.p0[p] + pc.dir[p] * sigma[:, None] - pc.radius[p, None] * pc.e1[p])[:, lin]
    normal = np.cross(pc.e1[p][:, lin], pc.e2[p][:, lin])
    return centre, _unit(normal)


def _coplanar(binormal: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """pmUnitCartsColinear: parallel or anti-parallel within TP_ANGLE_EPSILON."""
    lim = ANGLE_EPS ** 2
    return (_dot(binormal - normal, binormal - normal) < lim) | (_dot(binormal + normal, binormal + normal) < lim)


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.arccos(np.clip(_dot(_unit(a), _unit(b)), -1.0, 1.0))


def _touch_line(corner, u_line, side_sign, binormal, centre_arc, dist, r_plan):
    """The blend centre R from a line (through the corner along u_line, the blend on the side of
    binormal x u_line) and `dist` from an arc's centre: the cut's distance from the corner along the
    line (the smaller root by magnitude, as LinuxCNC takes it) and the centre; NaN where none exists."""
    n_line = _unit(np.cross(binormal, u_line))
    rel = centre_arc - corner
    c_u, c_n = _dot(rel, u_line), _dot(rel, n_line)
    b = 2.0 * c_u
    c = c_u ** 2 - dist ** 2 + (r_plan - c_n) ** 2
    disc = b ** 2 - 4.0 * c
    root = np.sqrt(np.where(disc >= 0, disc, np.nan))
    d_line = np.minimum(np.abs((-b + root) / 2.0), np.abs((-b - root) / 2.0))
    centre = corner + side_sign * d_line[:, None] * u_line + r_plan[:, None] * n_line
    return d_line, centre


def _touch_two(c1, c2, d1, d2, binormal, normal, corner):
    """The point d1 from c1 and d2 from c2 in the blend plane, on the side of the corner's normal,
    the one nearer the corner (blendArcArcPostProcess); NaN where the circles do not meet."""
    base = c2 - c1
    gap = np.sqrt(_dot(base, base))
    safe = np.where(gap > 0, gap, np.nan)
    along = (d1 ** 2 - d2 ** 2 + gap ** 2) / (2.0 * safe)
    across = np.sqrt(np.maximum(d1 ** 2 - along ** 2, 0.0))
    uc = base / safe[:, None]
    nc = np.cross(binormal, uc)
    nc = _unit(np.where((_dot(normal, nc) < 0)[:, None], -nc, nc))
    plus = c1 + along[:, None] * uc + across[:, None] * nc
    minus = c1 + along[:, None] * uc - across[:, None] * nc
    near_minus = _dot(minus - corner, minus - corner) < _dot(plus - corner, plus - corner)
    return np.where(near_minus[:, None], minus, plus)


def place_curved(pc, jb: np.ndarray, u1, u2, sides: ArcSides, r_plan, tol, lin) -> Placement:
    """Blend arcs of radius `r_plan` at the line-arc, arc-line and arc-arc junctions `jb` (arrays over
    all junctions, as `BlendArcCorner._arcs` gives them), placed where LinuxCNC puts them."""
    lin = list(lin)
    t1, t2 = u1[jb], u2[jb]
    r = r_plan[jb]
    corner = pc.p0[jb + 1][:, lin]
    arc1, arc2 = pc.radius[jb] > 0, pc.radius[jb + 1] > 0
    binormal = _unit(np.cross(t1, t2))
    normal = _unit(t2 - t1)
    ok = np.ones(len(jb), bool)
    c1, n1 = _arc_circle(pc, jb, True, lin)
    c2, n2 = _arc_circle(pc, jb + 1, False, lin)
    ok &= ~arc1 | _coplanar(binormal, n1)
    ok &= ~arc2 | _coplanar(binormal, n2)
    r1 = np.sqrt(_dot(corner - c1, corner - c1))
    r2 = np.sqrt(_dot(corner - c2, corner - c2))
    d1 = np.where(sides.convex1[jb], r1 - r, r1 + r)   # blend centre to arc centre: inside or outside
    d2 = np.where(sides.convex2[jb], r2 - r, r2 + r)
    centre = np.full((len(jb), 3), np.nan)
    cut1 = np.zeros(len(jb))            # on a line: the length cut off; on an arc: the angle
    cut2 = np.zeros(len(jb))
    la = ~arc1 & arc2
    if la.any():
        d_line, c = _touch_line(corner[la], t1[la], -1.0, binormal[la], c2[la], d2[la], r[la])
        centre[la], cut1[la] = c, d_line
    al = arc1 & ~arc2
    if al.any():
        d_line, c = _touch_line(corner[al], t2[al], 1.0, binormal[al], c1[al], d1[al], r[al])
        centre[al], cut2[al] = c, d_line
    aa = arc1 & arc2
    if aa.any():
        centre[aa] = _touch_two(c1[aa], c2[aa], d1[aa], d2[aa], binormal[aa], normal[aa], corner[aa])
        ok[aa] &= sides.theta[jb[aa]] >= ARC_ARC_THETA_MIN
    cut1 = np.where(arc1, _angle(corner - c1, centre - c1), cut1)
    cut2 = np.where(arc2, _angle(corner - c2, centre - c2), cut2)
    ok &= np.isfinite(centre).all(axis=1) & np.isfinite(cut1) & np.isfinite(cut2)
    ok &= np.sqrt(_dot(centre - corner, centre - corner)) - r <= tol[jb]        # T_final within the tolerance
    ok &= ~arc1 | (cut1 <= sides.phi1[jb])
    ok &= ~arc2 | (cut2 <= sides.phi2[jb])
    # path length (the pieces' parameter) cut off each side: arcs turn omega per unit length
    trim_end = np.where(arc1, cut1 / np.where(arc1, pc.omega[jb], 1.0), cut1)
    trim_start = np.where(arc2, cut2 / np.where(arc2, pc.omega[jb + 1], 1.0), cut2)
    ok &= (trim_end < pc.length[jb]) & (trim_start < pc.length[jb + 1])
    # the blend turns through the angle between its ends as seen from its centre
    end1 = np.where(arc1[:, None], c1 + r1[:, None] * _unit(centre - c1), corner - cut1[:, None] * t1)
    end2 = np.where(arc2[:, None], c2 + r2[:, None] * _unit(centre - c2), corner + cut2[:, None] * t2)
    angle = _angle(end1 - centre, end2 - centre)
    ok &= angle > 1e-9
    k = np.flatnonzero(ok)
    return Placement(ok=ok, j=jb[k], trim_end=trim_end[k], trim_start=trim_start[k], centre=centre[k],
                     radius=r[k], angle=angle[k])


def arc_frames(pc, placed: Placement) -> dict[str, np.ndarray]:
    """The placed blend arcs as path pieces: from the cut on the first side to the cut on the second about
    the placed centre (start point, e1 = centre -> start, e2 = the tangent there, radius, length, omega),
    with what each cuts off its sides (`feedlog.sim.corner_blend` inserts them)."""
    j, k = placed.j, pc.p0.shape[1]
    start = pc.position(j, pc.length[j] - placed.trim_end)
    end = pc.position(j + 1, placed.trim_start)
    xyz = slice(0, 3)       # profiles list x, y, z first (feedlog.profile.MachineProfile.axis_names)
    e1 = np.zeros((len(j), k))
    e2 = np.zeros((len(j), k))
    e1[:, xyz] = _unit(start[:, xyz] - placed.centre)
    out2 = end[:, xyz] - placed.centre
    e2[:, xyz] = _unit(out2 - _dot(out2, e1[:, xyz])[:, None] * e1[:, xyz])
    arc_len = placed.radius * placed.angle
    return {"j": j, "trim_end": placed.trim_end, "trim_start": placed.trim_start, "start": start, "e1": e1,
            "e2": e2, "radius": placed.radius, "length": arc_len, "omega": placed.angle / arc_len}
