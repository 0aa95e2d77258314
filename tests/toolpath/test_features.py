"""Geometry features on closed-form cases; CL points and linearisation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from feedlog.profile import load_profile
from feedlog.toolpath import block_features, cl_points, linearize, parse_program
from feedlog.toolpath.schema import FEATURE_COLUMNS


def feats(text: str, profile=None):
    return block_features(parse_program(text), profile)


def test_right_angle_corner_and_sun_nominal_feeds():
    f = feats("G21 G90 G64 P0.02\nG1 X10 F600\nG1 Y10\n")
    assert tuple(f.columns[:len(FEATURE_COLUMNS)]) == FEATURE_COLUMNS
    assert f["length_mm"].tolist() == [10, 10]
    assert f["corner_start_deg"].tolist() == pytest.approx([180, 90])  # from rest, then the corner
    assert f["corner_end_deg"].tolist() == pytest.approx([90, 180])
    assert f["nominal_time_s"].tolist() == pytest.approx([1.0, 1.0])
    assert f["vx_nom_mm_min"].tolist() == pytest.approx([600, 0])
    assert f["vy_nom_mm_min"].tolist() == pytest.approx([0, 600])
    # Sun Eq. 7: (f_n - f_{n-1}) / t_n, from rest: 10 mm/s in 1 s
    assert f["ax_nom_mm_s2"].tolist() == pytest.approx([10, -10])
    assert f["ay_nom_mm_s2"].tolist() == pytest.approx([0, 10])
    assert f["corner_cos_end"].tolist() == pytest.approx([0, 1], abs=1e-12)
    assert f["tol_mm"].tolist() == [0.02, 0.02]
    assert (f["ori_arc_deg"] == 0).all() and (f["sin_rot"] == 0).all()


def test_collinear_blocks_have_no_corner():
    f = feats("G1 X10 F600\nX20\nX35\n")
    assert f["corner_start_deg"].tolist() == pytest.approx([180, 0, 0], abs=1e-6)
    assert f["corner_end_deg"].tolist() == pytest.approx([0, 0, 180], abs=1e-6)
    assert f["corner_cos_end"].tolist()[:2] == pytest.approx([-1, -1])
    assert f["ax_nom_mm_s2"].tolist() == pytest.approx([10, 0, 0])


def test_reversal_dwell_and_tangent_arc():
    f = feats("G1 X10 F600\nX0\nG4 P1\nX10\nG3 X10 Y10 I0 J5\n")
    assert f["corner_start_deg"].tolist() == pytest.approx([180, 180, 180, 0], abs=1e-6)
    assert f["corner_end_deg"].tolist() == pytest.approx([180, 180, 0, 180], abs=1e-6)


def test_helical_arc_tangent_corner():
    # line along +x, then a CCW helix starting tangent to +x in XY but rising: corner = atan(rise slope)
    f = feats("G1 X10 F600\nG3 X10 Y10 Z1 I0 J5\n")
    slope = 1.0 / (5 * math.pi)
    assert f["corner_start_deg"][1] == pytest.approx(math.degrees(math.atan(slope)))
    assert f["length_mm"][1] == pytest.approx(math.hypot(5 * math.pi, 1))


def test_orientation_swing_through_the_pole_from_ijk_and_from_ac():
    s10, c10 = math.sin(math.radians(10)), math.cos(math.radians(10))
    ijk = feats(f"G1 X0 Y0 Z0 I{s10:.12f} J0 K{c10:.12f} F600\nX1 I0 J0 K1\nX2 I{-s10:.12f} J0 K{c10:.12f}\n")
    ac = feats("G1 X0 Y0 Z0 A10 C90 F600\nX1 A0 C90\nX2 A10 C270\n", "linuxcnc-xyzac")
    for f in (ijk, ac):
        assert f["ori_arc_deg"].tolist()[1:] == pytest.approx([10, 10])
        # a great circle through the pole: no orientation corner, though C turns 180 deg
        assert f["ori_corner_start_deg"][2] == pytest.approx(0, abs=1e-6)
        assert f["ori_corner_end_deg"][1] == pytest.approx(0, abs=1e-6)
        assert f["ori_corner_end_deg"][2] == 180  # program end: rest
        assert abs(f["sin_rot"][1]) == pytest.approx(0, abs=1e-12)
        assert abs(f["sin_rot"][2]) == pytest.approx(s10)
    # AC: block 0 tilts away from the pole (A0 -> A10), block 1 comes back: an orientation reversal
    assert ac["ori_arc_deg"][0] == pytest.approx(10)
    assert ac["ori_corner_start_deg"].tolist()[:2] == pytest.approx([180, 180])
    assert ijk["ori_arc_deg"][0] == 0 and ijk["ori_corner_start_deg"][0] == 0  # no motion, no corner


def test_orientation_right_angle_turn_on_the_sphere():
    s, c = math.sin(math.radians(5)), math.cos(math.radians(5))
    f = feats(f"G1 X0 I0 J0 K1 F600\nX1 I{s:.12f} J0 K{c:.12f}\nX2 I{s * c:.12f} J{s:.12f} K{c * c:.12f}\n")
    assert f["ori_arc_deg"][1] == pytest.approx(5)
    assert f["ori_corner_start_deg"][2] == pytest.approx(90, abs=0.3)


def test_nominal_time_for_rapids_inverse_time_and_rotary_only_moves():
    prof = load_profile("linuxcnc-xyz")
    f = feats("G0 X100\nG93 G1 X110 F30\nG94 G1 A90 F900\n", prof)
    assert f["nominal_time_s"].tolist() == pytest.approx([100 / prof.rapid_mm_min * 60, 2.0, 6.0])
    assert f["feed_mm_min"][1] == pytest.approx(300)
    c_only = feats("G1 C180 F3600\nG0 C0\n", prof)  # no A/B: no orientation, but C takes time
    assert c_only["nominal_time_s"].tolist() == pytest.approx([3.0, 180 / prof.rapid_mm_min * 60])


def test_cl_points_on_a_helical_circle_stay_within_the_chord_tolerance():
    tol = 0.001
    p = parse_program("G0 X10 Y0 Z0\nG3 X10 Y0 Z-2 I-10 J0 F600\n")
    pts = cl_points(p, chord_tol_mm=tol)
    assert pts["block"].iloc[0] == -1 and pts["kind"].iloc[0] == "start"
    arc = pts[pts["block"] == 1]
    r = np.hypot(arc["x_mm"], arc["y_mm"])
    assert np.allclose(r, 10, atol=1e-12)
    # chord sag: r (1 - cos(dphi / 2)) <= tol
    phi = np.unwrap(np.arctan2(arc["y_mm"], arc["x_mm"]))
    assert (np.diff(phi) > 0).all()  # CCW
    assert (10 * (1 - np.cos(np.diff(phi) / 2)) <= tol + 1e-12).all()
    assert np.allclose(np.diff(arc["z_mm"]) / np.diff(phi), -2 / (2 * np.pi))  # linear rise
    assert (arc.iloc[-1][["x_mm", "y_mm", "z_mm"]].to_numpy() == [10, 0, -2]).all()
    assert pts["s_mm"].iloc[-1] == pytest.approx(10 + math.hypot(20 * math.pi, 2), rel=1e-4)
    assert pts["s_mm"].is_monotonic_increasing


def test_linearize_keeps_blocks_lines_and_the_g18_arc_direction():
    p = parse_program("G1 X0 Y0 Z0 F100\nG18 G2 X10 Z0 I5 K0\nG1 X20\n")
    lin = linearize(p, 0.01)
    m = lin.motion
    assert set(m["kind"]) == {"linear"}
    arc = m[m["line"] == 2]
    assert arc["block"].nunique() == 1 and arc["segment"].tolist() == list(range(len(arc)))
    # G18 (u, v) = (z, x): CW seen from +Y goes through z = -5
    assert arc["z_mm"].min() == pytest.approx(-5, abs=0.01)
    assert arc["length_mm"].sum() == pytest.approx(5 * math.pi, rel=1e-3)
    assert lin.blocks[["x0_mm", "z0_mm"]].iloc[1:].to_numpy() == pytest.approx(
        lin.blocks[["x_mm", "z_mm"]].iloc[:-1].to_numpy())
    assert linearize(p.blocks, 0.01).blocks.equals(lin.blocks)  # a bare block table works too
    lines_only = parse_program("G1 X1 F1\nY1\n")
    assert linearize(lines_only, 0.01).blocks.drop(columns="segment").equals(lines_only.blocks)


def test_bad_chord_tolerance_is_refused():
    from feedlog.errors import FeedlogError
    with pytest.raises(FeedlogError):
        cl_points(parse_program("G1 X1 F1\n"), chord_tol_mm=0)
