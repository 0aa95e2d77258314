"""Property tests: random valid programs parse to the expected geometry; garbage only raises ProgramError."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from feedlog.errors import ProgramError
from feedlog.toolpath import cl_points, parse_program
from feedlog.toolpath.summary import extents

coord = st.decimals(min_value=-500, max_value=500, places=3, allow_nan=False, allow_infinity=False)


@st.composite
def linear_programs(draw):
    """G0/G1 moves in random distance modes and units, with random spacing, case, N words, comments;
    returns (text, expected end positions in mm, expected lengths)."""
    lines, pos, ends, lengths = [], [0.0, 0.0, 0.0], [], []
    inch = draw(st.booleans())
    scale = 25.4 if inch else 1.0
    lines.append(("G20" if inch else "G21") + " F100")
    for k in range(draw(st.integers(1, 25))):
        incremental = draw(st.booleans())
        axes = draw(st.lists(st.sampled_from("XYZ"), min_size=1, max_size=3, unique=True))
        words = [("G91" if incremental else "G90"), draw(st.sampled_from(["G0", "G1", "g01", "G00"]))]
        new = list(pos)
        for ax in axes:
            v = draw(coord)
            i = "XYZ".index(ax)
            new[i] = pos[i] + float(v) * scale if incremental else float(v) * scale
            words.append(f"{draw(st.sampled_from([ax, ax.lower()]))}{v}")
        if draw(st.booleans()):
            words.insert(0, f"N{10 * (k + 1)}")
        sep = draw(st.sampled_from([" ", "", "  ", "\t"]))
        text = sep.join(words)
        if draw(st.booleans()):
            text += draw(st.sampled_from([" (comment)", " ; note", "(x)"]))
        lines.append(text)
        lengths.append(math.dist(pos, new))
        pos = new
        ends.append(list(pos))
    return "\n".join(lines) + "\n", np.array(ends), np.array(lengths)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(linear_programs())
def test_random_linear_programs_parse_to_the_expected_positions(case):
    text, ends, lengths = case
    m = parse_program(text).motion
    assert len(m) == len(ends)
    assert np.allclose(m[["x_mm", "y_mm", "z_mm"]].to_numpy(), ends, atol=1e-9)
    assert np.allclose(m["length_mm"].to_numpy(), lengths, atol=1e-9)


@st.composite
def arc_programs(draw):
    """One arc from a random start around a random centre to a random end angle, in a random plane."""
    plane = draw(st.sampled_from([17, 18, 19]))
    u_ax, v_ax, w_ax = {17: "XYZ", 18: "ZXY", 19: "YZX"}[plane]
    off = {ax: word for ax, word in zip("XYZ", "IJK")}
    start = {ax: float(draw(coord)) for ax in "XYZ"}
    cu, cv = float(draw(coord)), float(draw(coord))
    r = math.hypot(start[u_ax] - cu, start[v_ax] - cv)
    if r < 0.5:
        cu += 1.0
        r = math.hypot(start[u_ax] - cu, start[v_ax] - cv)
    a0 = math.atan2(start[v_ax] - cv, start[u_ax] - cu)
    a1 = draw(st.floats(-math.pi, math.pi, allow_nan=False))
    end = dict(start)
    end[u_ax] = cu + r * math.cos(a1)
    end[v_ax] = cv + r * math.sin(a1)
    end[w_ax] = start[w_ax] + float(draw(coord)) / 10
    ccw = draw(st.booleans())
    words = [f"G{plane}", "G3" if ccw else "G2"] + [f"{ax}{end[ax]:.6f}" for ax in "XYZ"]
    words += [f"{off[u_ax]}{cu - start[u_ax]:.6f}", f"{off[v_ax]}{cv - start[v_ax]:.6f}"]
    text = "G0 " + " ".join(f"{ax}{start[ax]}" for ax in "XYZ") + "\nF300\n" + " ".join(words) + "\n"
    # expected sweep with the printed (rounded) end point
    eu, ev = round(end[u_ax], 6), round(end[v_ax], 6)
    a1r = math.atan2(ev - cv, eu - cu)
    sweep = ((a1r - a0) if ccw else (a0 - a1r)) % (2 * math.pi)
    if sweep < 1e-9:
        sweep = 2 * math.pi
    return text, (cu, cv), r, sweep, round(end[w_ax], 6) - start[w_ax], plane


@settings(max_examples=120, deadline=None)
@given(arc_programs())
def test_random_arcs_have_the_expected_centre_sweep_and_length(case):
    text, (cu, cv), r, sweep, rise, plane = case
    p = parse_program(text)
    arc = p.motion.iloc[1]
    names = {17: ("cx_mm", "cy_mm"), 18: ("cz_mm", "cx_mm"), 19: ("cy_mm", "cz_mm")}[plane]
    assert (arc[names[0]], arc[names[1]]) == pytest.approx((cu, cv), abs=1e-5)
    assert math.radians(arc.sweep_deg) == pytest.approx(sweep, abs=1e-5)
    assert arc.length_mm == pytest.approx(math.hypot(r * sweep, rise), rel=1e-5, abs=1e-5)
    pts = cl_points(p, chord_tol_mm=0.01)
    on_arc = pts[pts["block"] == arc.block]
    centre = {17: ("x_mm", "y_mm"), 18: ("z_mm", "x_mm"), 19: ("y_mm", "z_mm")}[plane]
    radii = np.hypot(on_arc[centre[0]] - cu, on_arc[centre[1]] - cv)
    assert np.allclose(radii, r, atol=1e-4)
    # the summary's extents: the arc's true extreme points, as dense chords approach them
    box = extents(p)
    dense = cl_points(p, chord_tol_mm=1e-4)
    for col in ("x_mm", "y_mm", "z_mm"):
        assert box[col][0] <= dense[col].min() + 1e-9 and box[col][1] >= dense[col].max() - 1e-9
        assert box[col][0] == pytest.approx(dense[col].min(), abs=2e-4)
        assert box[col][1] == pytest.approx(dense[col].max(), abs=2e-4)


garbage_chars = st.sampled_from(list("GXYZABCIJKFMNPQRSTOUgxyz0123456789.-+ ()%;#[]=/\n\t\r") + ["é", "\x00"])


@settings(max_examples=300, deadline=None)
@given(st.lists(garbage_chars, max_size=80).map("".join))
def test_garbage_only_ever_raises_program_error(text):
    for lenient in (False, True):
        try:
            parse_program(text, lenient=lenient)
        except ProgramError as exc:
            assert exc.line is not None or exc.file is not None


@settings(max_examples=100, deadline=None)
@given(st.text(max_size=60))
def test_any_text_only_ever_raises_program_error(text):
    try:
        parse_program(text + "\n")
    except ProgramError:
        pass


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(linear_programs(), st.data())
def test_lenient_mode_lists_every_unsupported_code_and_keeps_the_rest(case, data):
    text, ends, _ = case
    lines = text.splitlines()
    extra = data.draw(st.lists(st.tuples(st.integers(1, len(lines)),
                                         st.sampled_from(["M98 P100", "G28", "U5", "#5=1", "G41 D1"])),
                               max_size=4, unique_by=lambda t: t[0]))
    out = list(lines)
    for at, code in sorted(extra, reverse=True):
        out.insert(at, code)  # on a line of its own: the moves stay as they were
    p = parse_program("\n".join(out) + "\n", lenient=True)
    listed = {u.line for u in p.unsupported}
    inserted_lines = sorted(at for at, _ in extra)
    expected = {at + 1 + sum(1 for other in inserted_lines if other < at) for at in inserted_lines}
    assert listed == expected
    assert np.allclose(p.motion[["x_mm", "y_mm", "z_mm"]].to_numpy(), ends, atol=1e-9)
    if extra:
        with pytest.raises(ProgramError):
            parse_program("\n".join(out) + "\n")
