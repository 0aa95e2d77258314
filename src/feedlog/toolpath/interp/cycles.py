"""Canned cycles G73, G81-G89 as LinuxCNC runs them, in any of the three planes.

In the plane's own axes (u, v in the plane, w the drilling axis): with L repeats, each hole moves
(u, v) by the X/Y increment in G91 (or once to X/Y in G90), rapids to the clear level and the R level,
then runs its cycle; R and Z are absolute in G90 and relative (R to the initial level, Z to R) in
G91; the tool retracts to R (G99) or to the initial level (G98) when that is higher. The cycle runs in
exact-path mode, and the path mode in force comes back after it (LinuxCNC does the same, which makes a
drilled hole slower than the same moves written out under G64).
"""

from __future__ import annotations

import math

from feedlog.toolpath.interp.errors import InterpError

_PLANES = {170: (0, 1, 2), 180: (2, 0, 1), 190: (1, 2, 0)}
G83_RAPID_DELTA_INCH = 0.010
_AXIS_NAME = "XYZ"


def convert_cycle(m, motion: int, b) -> None:
    """Run cycle `motion` (x10) of block `b` on machine `m` (toolpath.interp.machine.Machine)."""
    from feedlog.toolpath.interp.machine import PATH_EXACT_PATH

    v = b.v
    if m.feed == 0.0:
        raise InterpError("cannot feed with zero feed rate")
    if m.feed_mode == 930:
        raise InterpError("cannot use inverse time feed with canned cycles")
    if m.comp.side:
        raise InterpError("cannot use canned cycles with cutter compensation on")
    cyc = m.cycle
    if "r" in v:
        r_word = v["r"]
    elif m.motion_mode == motion:
        r_word = cyc["r"]
    else:
        raise InterpError("R clearance plane unspecified in canned cycle")
    repeats = int(v.get("l", 1))
    if "l" in v and repeats == 0:
        raise InterpError("cannot do zero repeats of a canned cycle")
    u, w, n = _PLANES[m.plane]
    letters = "xyz"
    if m.motion_mode != motion and letters[n] not in v:
        raise InterpError(f"{letters[n].upper()} value unspecified in {_plane_name(m.plane)} plane canned cycle")
    depth_word = v.get(letters[n], cyc["cc"])
    pos = m.pos
    current_cc = pos[n]
    if m.cycle_il is None:
        m.cycle_il = current_cc
    old_cc = m.cycle_il
    inc_u = inc_v = inc_radius = inc_theta = 0.0
    if not m.incremental:
        r = r_word
        cc = depth_word
        if "@" in v or "^" in v:
            radius = v.get("@", math.hypot(pos[1], pos[0]))
            theta = math.radians(v["^"]) if "^" in v else math.atan2(pos[1], pos[0])
            aa, bb = radius * math.cos(theta), radius * math.sin(theta)
        else:
            aa = v.get(letters[u], pos[u])
            bb = v.get(letters[w], pos[w])
    else:
        inc_u = v.get(letters[u], 0.0)
        inc_v = v.get(letters[w], 0.0)
        inc_radius = v.get("@", 0.0)
        inc_theta = math.radians(v["^"]) if "^" in v else 0.0
        r = r_word + old_cc
        cc = r + depth_word
        aa, bb = pos[u], pos[w]
    if r < cc:
        raise InterpError(f"R less than {letters[n].upper()} in cycle in {_plane_name(m.plane)} plane")

    def point(a1: float, a2: float, a3: float) -> list[float]:
        p = list(m.pos)
        p[u], p[w], p[n] = a1, a2, a3
        return p

    if old_cc < r:
        p = list(m.pos)
        p[n] = r
        m.traverse(p)
        old_cc = r
        current_cc = old_cc
    clear_cc = r if m.retract_r_plane else old_cc
    saved = (m.control, m.tolerance, m.naive)
    if m.control != PATH_EXACT_PATH:
        m.control, m.tolerance, m.naive = PATH_EXACT_PATH, 0.0, math.nan
    if motion in (820, 860, 880, 890, 840, 740):
        if m.motion_mode != motion and "p" not in v and motion not in (840, 740):
            raise InterpError(f"dwell time P word missing with {_g(motion)}")
        dwell = v.get("p", cyc["p"])
        cyc["p"] = dwell
    if motion in (730, 830):
        if m.motion_mode != motion and "q" not in v:
            raise InterpError(f"Q word missing with {_g(motion)}")
        delta = v.get("q", cyc["q"])
        cyc["q"] = delta
    if motion in (840, 740):
        want = 4 if motion == 740 else 3
        if m.spindle != want:
            raise InterpError(f"spindle not turning {'counter' if want == 4 else ''}clockwise in {_g(motion)}")
    if motion in (860, 880, 870) and m.spindle not in (3, 4):
        raise InterpError(f"spindle not turning in {_g(motion)}")
    if motion == 870:
        raise InterpError("G87 back boring is not simulated")
    for repeat in range(repeats, 0, -1):
        aa += inc_u
        bb += inc_v
        if inc_radius:
            if aa == 0 and bb == 0:
                raise InterpError("incremental motion with polar coordinates is indeterminate when at the origin")
            t = math.atan2(bb, aa)
            rad = math.hypot(bb, aa) + inc_radius
            aa, bb = rad * math.cos(t), rad * math.sin(t)
        if inc_theta:
            if aa == 0 and bb == 0:
                raise InterpError("incremental motion with polar coordinates is indeterminate when at the origin")
            t = math.atan2(bb, aa) + inc_theta
            rad = math.hypot(bb, aa)
            aa, bb = rad * math.cos(t), rad * math.sin(t)
        if repeat == repeats and current_cc > r:
            m.traverse(point(aa, bb, current_cc))
            m.traverse(point(aa, bb, r))
        else:
            m.traverse(point(aa, bb, clear_cc))
            if clear_cc > r:
                m.traverse(point(aa, bb, r))
        _one_cycle(m, motion, point, aa, bb, r, clear_cc, cc, cyc)
    p = m.pos
    p[u], p[w], p[n] = aa, bb, clear_cc
    cyc["cc"] = depth_word
    if saved[0] != PATH_EXACT_PATH:
        m.control, m.tolerance, m.naive = saved
    cyc["r"] = r_word
    m.motion_mode = motion


def _one_cycle(m, motion, point, aa, bb, r, clear_cc, cc, cyc) -> None:
    from feedlog.toolpath.interp.canon import K_DWELL

    def dwell(seconds: float) -> None:
        m.emit(K_DWELL, m.pos, dwell=seconds)

    if motion == 810:
        m.feed_to(point(aa, bb, cc))
        m.traverse(point(aa, bb, clear_cc))
    elif motion == 820:
        m.feed_to(point(aa, bb, cc))
        dwell(cyc["p"])
        m.traverse(point(aa, bb, clear_cc))
    elif motion in (730, 830):
        delta = cyc["q"]
        if delta <= 0.0:
            raise InterpError("negative or zero Q value used")
        rapid_delta = G83_RAPID_DELTA_INCH * (1.0 if m.inch else 25.4)
        depth = r - delta
        while depth > cc:
            m.feed_to(point(aa, bb, depth))
            if motion == 830:
                m.traverse(point(aa, bb, r))
            m.traverse(point(aa, bb, depth + rapid_delta))
            depth -= delta
        m.feed_to(point(aa, bb, cc))
        m.traverse(point(aa, bb, clear_cc))
    elif motion in (840, 740):
        m.feed_to(point(aa, bb, cc))
        dwell(cyc["p"])
        m.feed_to(point(aa, bb, clear_cc))
    elif motion == 850:
        m.feed_to(point(aa, bb, cc))
        m.feed_to(point(aa, bb, r))
        m.traverse(point(aa, bb, clear_cc))
    elif motion == 860:
        m.feed_to(point(aa, bb, cc))
        dwell(cyc["p"])
        m.traverse(point(aa, bb, clear_cc))
    elif motion == 880:
        m.feed_to(point(aa, bb, cc))
        dwell(cyc["p"])
    elif motion == 890:
        m.feed_to(point(aa, bb, cc))
        dwell(cyc["p"])
        m.feed_to(point(aa, bb, clear_cc))


def _g(code: int) -> str:
    return f"G{code // 10}"


def _plane_name(plane: int) -> str:
    return {170: "XY", 180: "XZ", 190: "YZ"}[plane]
