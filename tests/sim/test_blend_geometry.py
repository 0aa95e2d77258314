"""Blend arcs at line-arc and arc-arc corners placed where LinuxCNC 2.9 puts them (blend_arc
`curved_blend_geometry`, feedlog.sim.blend_geometry, docs/sim.md "Blend geometry"): the sides are cut
where the blend circle touches them, the arc runs under the next line. The expected geometry is derived
here from the circles themselves."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feedlog.profile import load_profile
from feedlog.sim import simulate
from feedlog.sim.context import Context
from feedlog.sim.mechanism import resolve_mechanisms
from feedlog.sim.path import build_pieces, prepare_blocks
from feedlog.sim.window import simulate_windowed
from feedlog.toolpath import load_program

PROFILE = load_profile("linuxcnc-xyz")
UNPLACED = {"blend_arc": {"curved_blend_geometry": False}}


def _pieces(text: str, mechanisms=None):
    """The executed path after the corner law: the pieces and the block table rows they belong to."""
    program = load_program(text, name="corner.ngc")
    chain = resolve_mechanisms(PROFILE, mechanisms)
    ctx = Context(profile=PROFILE, blocks=prepare_blocks(program, PROFILE))
    for mech in chain:
        mech.limit(ctx)
    pieces = build_pieces(ctx.blocks)
    ctx.pieces = pieces.take(np.flatnonzero(pieces.length > 0))
    for mech in chain:
        if mech.kind == "corner":
            mech.corner(ctx)
    return ctx.pieces, ctx.blocks


def _centre(pc, i: int) -> np.ndarray:
    return (pc.p0[i] - pc.radius[i] * pc.e1[i])[:2]


def _end(pc, i: int) -> np.ndarray:
    return pc.position(np.array([i]), np.array([pc.length[i]]))[0, :2]


def _convex_blend(phi: float) -> tuple[float, float]:
    """At the 90 deg corner (20, 0) between the X axis and the circle of radius R_ARC about (10, 0), a
    blend allowed `phi` of the arc (which bends away from the corner): LinuxCNC plans it along the chord,
    sin(phi / 4) R_ARC, at the half-angle 45 deg - phi / 4, so its radius is tan(half-angle) times that.
    It touches the X axis (centre R above it) and the circle from inside (centre R_ARC - R from (10, 0));
    of the two such circles, the one near the corner. Returns the radius and the centre's x."""
    radius = math.tan(math.pi / 4 - phi / 4) * math.sin(phi / 4) * R_ARC
    return radius, 10.0 + math.sqrt((R_ARC - radius) ** 2 - radius ** 2)


# a 20 mm line along +X into a quarter circle of radius 10 turning left (centre (10, 0)): a 90 deg
# corner, no G64 P; then a tangent line back along -X
R_ARC = 10.0
LINE_ARC = "G21 G90 G64 F3000\nG0 X0 Y0\nG1 X20 Y0\nG3 X10 Y10 I-10 J0\nG1 X-10 Y10\nM2\n"


def test_a_line_arc_blend_touches_the_line_and_the_circle_where_linuxcnc_cuts_them():
    pc, blocks = _pieces(LINE_ARC)
    blend = np.flatnonzero(pc.blend)
    assert len(blend) == 1
    i = int(blend[0])
    # the arc side bounds the blend (blendInit3FromLineArc): phi = min(sweep / 3, 45 deg) = 30 deg
    radius, cx = _convex_blend(math.pi / 6)
    assert pc.radius[i] == pytest.approx(radius, rel=1e-9)
    assert _centre(pc, i) == pytest.approx([cx, radius], abs=1e-9)
    # the line is cut where the blend leaves it, the arc where the blend joins it
    assert _end(pc, i - 1) == pytest.approx([cx, 0.0], abs=1e-9)
    assert pc.p0[i, :2] == pytest.approx([cx, 0.0], abs=1e-9)
    join = np.array([10.0, 0.0]) + R_ARC * np.array([cx - 10.0, radius]) / math.hypot(cx - 10.0, radius)
    assert _end(pc, i) == pytest.approx(join, abs=1e-9)
    assert pc.p0[i + 1, :2] == pytest.approx(join, abs=1e-9)
    cut = math.atan2(radius, cx - 10.0)                       # the angle the arc loses
    assert pc.length[i + 1] == pytest.approx(R_ARC * (math.pi / 2 - cut), abs=1e-9)
    assert _end(pc, i + 1) == pytest.approx([10.0, 10.0], abs=1e-9)   # its end stays where it was
    # the blend runs under the arc's line; the line's block ends where the tool leaves the line
    assert blocks.line[pc.block[i]] == 4 and blocks.line[pc.block[i - 1]] == 3
    res = simulate(load_program(LINE_ARC, name="corner.ngc"), PROFILE, dt_s=1e-4)
    s = res.series
    on_arc = s["line"].to_numpy() == 4
    first = int(np.flatnonzero(on_arc)[0])
    assert s["x_mm"].iloc[first - 1] <= cx + 1e-9 < s["x_mm"].iloc[first] + 0.01
    # unplaced, the line ran to the corner (the arc's speed at the junction only)
    old = simulate(load_program(LINE_ARC, name="corner.ngc"), PROFILE, mechanisms=UNPLACED, dt_s=1e-4).series
    first_old = int(np.flatnonzero(old["line"].to_numpy() == 4)[0])
    assert old["x_mm"].iloc[first_old] == pytest.approx(20.0, abs=0.01)


def test_an_arc_line_blend_cuts_the_arc_and_runs_under_the_line():
    # the same corner driven backwards: the quarter circle, then the line along -X from (20, 0)
    text = "G21 G90 G64 F3000\nG0 X10 Y10\nG2 X20 Y0 I0 J-10\nG1 X0 Y0\nM2\n"
    pc, blocks = _pieces(text)
    i = int(np.flatnonzero(pc.blend)[0])
    # the previous arc may lose two thirds of its sweep (60 deg), capped at the half-angle (45 deg)
    radius, cx = _convex_blend(math.pi / 4)
    assert pc.radius[i] == pytest.approx(radius, rel=1e-9)
    assert _centre(pc, i) == pytest.approx([cx, radius], abs=1e-9)
    assert pc.p0[i + 1, :2] == pytest.approx([cx, 0.0], abs=1e-9)
    assert blocks.line[pc.block[i]] == 4


# random corners between lines and arcs in the XY plane
@st.composite
def corners(draw):
    heading = draw(st.floats(-math.pi, math.pi))
    turn = draw(st.floats(0.3, 2.6)) * draw(st.sampled_from([-1, 1]))   # the tangent kink at the corner
    radius = draw(st.floats(2.0, 60.0))
    sweep = draw(st.floats(0.3, 2.5))
    ccw = draw(st.booleans())
    tol = draw(st.sampled_from(["", " P0.05", " P0.5"]))
    first_arc = draw(st.booleans())
    return heading, turn, radius, sweep, ccw, tol, first_arc


def _corner_program(heading, turn, radius, sweep, ccw, tol, first_arc) -> str:
    """A 15 mm line and an arc meeting at (0, 0) with the tangent turning by `turn` (or the arc first)."""
    sign = 1.0 if ccw else -1.0
    g = "G3" if ccw else "G2"
    if not first_arc:        # line into the arc: the arc leaves (0, 0) along heading + turn
        start = (-15 * math.cos(heading), -15 * math.sin(heading))
        h2 = heading + turn
        c = (-sign * radius * math.sin(h2), sign * radius * math.cos(h2))
        a0 = math.atan2(-c[1], -c[0])
        end = (c[0] + radius * math.cos(a0 + sign * sweep), c[1] + radius * math.sin(a0 + sign * sweep))
        return (f"G21 G90 G64{tol} F3000\nG0 X{start[0]:.6f} Y{start[1]:.6f}\nG1 X0 Y0\n"
                f"{g} X{end[0]:.6f} Y{end[1]:.6f} I{c[0]:.6f} J{c[1]:.6f}\nM2\n")
    # the arc ends at (0, 0) along heading, the line leaves along heading + turn
    c = (-sign * radius * math.sin(heading), sign * radius * math.cos(heading))
    a1 = math.atan2(-c[1], -c[0])
    a0 = a1 - sign * sweep
    start = (c[0] + radius * math.cos(a0), c[1] + radius * math.sin(a0))
    h2 = heading + turn
    return (f"G21 G90 G64{tol} F3000\nG0 X{start[0]:.6f} Y{start[1]:.6f}\n"
            f"{g} X0 Y0 I{c[0] - start[0]:.6f} J{c[1] - start[1]:.6f}\n"
            f"G1 X{15 * math.cos(h2):.6f} Y{15 * math.sin(h2):.6f}\nM2\n")


@settings(max_examples=60, deadline=None, derandomize=True)
@given(corners())
def test_placed_blends_join_their_sides_tangentially_within_the_tolerance(corner):
    text = _corner_program(*corner)
    pc, blocks = _pieces(text, {"naive_cam": {"arcs_as_lines": False}})   # a flat arc stays an arc
    # the path stays in one piece: each piece starts where the last ended (to the program's 6 decimals,
    # which leave an arc's end up to 1e-6 mm off its circle)
    for i in range(len(pc) - 1):
        assert pc.p0[i + 1, :2] == pytest.approx(_end(pc, i), abs=1e-5), (i, text)
    lin = blocks.linear_index
    for i in np.flatnonzero(pc.blend):    # and turns smoothly into and out of every blend arc
        t_in = pc.tangent_xyz(np.array([i - 1]), np.array([pc.length[i - 1]]), lin)[0]
        t_blend0 = pc.tangent_xyz(np.array([i]), np.array([0.0]), lin)[0]
        t_blend1 = pc.tangent_xyz(np.array([i]), np.array([pc.length[i]]), lin)[0]
        t_out = pc.tangent_xyz(np.array([i + 1]), np.array([0.0]), lin)[0]
        assert float(t_in @ t_blend0) > 1 - 1e-9 and float(t_blend1 @ t_out) > 1 - 1e-9, text
        # the blend circle passes the corner (0, 0) within the tolerance LinuxCNC blends in
        gap = math.hypot(*_centre(pc, i)) - pc.radius[i]
        tol = blocks.tol[pc.block[i]]
        limit = min(tol if tol > 0 else np.inf, 0.25 * float(blocks.length[pc.block[i - 1]]),
                    0.25 * float(blocks.length[pc.block[i]]))
        assert 0 < gap <= limit + 1e-9, text
        assert pc.block[i] == pc.block[i + 1]     # run under the next line


def test_windows_give_the_whole_runs_block_table_with_placed_blends():
    # plasmatest-like star corners and a chain of tangent and kinked arcs
    text = "G21 G90 G64\nG1 X0 Y0 F5000\n" + "".join(
        f"G1 X{40 * k + 30} Y0\nG2 X{40 * k + 40} Y10 I10 J0\nG3 X{40 * k + 50} Y20 I10 J0\nG1 Y40\nG0 Y0\n"
        for k in range(6)) + "M2\n"
    program = load_program(text, name="star.ngc")
    whole = simulate(program, PROFILE)
    assert whole.notes["curved_blends"] >= 12
    table = whole.blocks
    for size in (3, 7, 16):
        res, blocks, _ = simulate_windowed(program, PROFILE, window=size)
        assert res.cycle_time_s == pytest.approx(whole.cycle_time_s, abs=1e-9), size
        assert np.allclose(blocks["t_end_ns"], table["t_end_ns"], atol=2), size


def _arc_into_line(radius: float) -> str:
    """A quarter circle from rest (after a rapid) turning left into an 18.4 mm line down: a 90 deg corner
    (plasmatest's cut-in: radius 0.922 mm, F5840)."""
    return (f"G21 G90 G64\nG0 X{radius} Y0\nG3 X0 Y{radius} I{-radius} J0 F5840\nG1 X0 Y{radius - 18.4}\nM2\n")


@pytest.mark.parametrize("radius", [0.922, 10.0])
def test_linuxcnc_takes_a_parabolic_blend_where_it_rates_it_above_the_blend_arc(radius):
    a, feed = 1000.0, 5840 / 60
    arc_len, line_len = math.pi / 2 * radius, 18.4
    # the blend arc (blendInit3FromArcLine): the arc bends away from the corner, phi = min(2/3 sweep,
    # 45 deg), its length along the chord sin(phi / 4) r, the half-angle 45 deg - phi / 4, within the
    # default tolerance (a quarter of the shorter move) for both radii here
    phi = min(2 / 3 * math.pi / 2, math.pi / 4)
    theta = math.pi / 4 - phi / 4
    r_blend = math.tan(theta) * math.sin(phi / 4) * radius
    v_arc = min(math.sqrt(a * math.sqrt(0.75) * r_blend), feed)
    # the parabolic blend (estimateParabolicBlendPerformance): the kink share off (0.9), halved by the
    # parabolic end condition, the unfinalized arc's tangential share 0.5; each move's triangle speed
    # over half its length, one blend time, half the net speed at the 45 deg half-angle
    acc1, acc2 = a * 0.9 * 0.5 * 0.5, a * 0.9 * 0.5
    v1 = min(math.sqrt(acc1 * arc_len / 2), math.sqrt(a * math.sqrt(0.75) * radius), feed)
    v2 = min(math.sqrt(acc2 * line_len / 2), feed)
    t_blend = min(arc_len / v1, line_len / v2, max(v1 / acc1, v2 / acc2))
    perf = math.sin(math.pi / 4) * (min(v1, t_blend * acc1) + min(v2, t_blend * acc2)) / 4
    program = load_program(_arc_into_line(radius), name="cut_in.ngc")
    res = simulate(program, PROFILE)
    arc_only = simulate(program, PROFILE, mechanisms={"blend_arc": {"parabolic_choice": False}})
    assert arc_only.notes["curved_blends"] == 1 and arc_only.notes["parabolic_blends"] == 0
    if radius < 1:       # the tight cut-in arc: 11.9 mm/s parabolic against a 10.2 mm/s blend arc
        assert perf > v_arc, (perf, v_arc)
        assert res.notes["parabolic_blends"] == 1 and res.notes["curved_blends"] == 0
    else:                # a wide arc leaves room for a fast blend arc
        assert v_arc > perf, (perf, v_arc)
        assert res.notes["curved_blends"] == 1 and res.notes["parabolic_blends"] == 0
        assert res.cycle_time_s == arc_only.cycle_time_s
