"""Short arcs as LinuxCNC 2.9 runs them (docs/sim.md, "Short arcs"): a programmed arc's tangential
acceleration share from its maximum speed (lookahead `arc_share_from_speed`), flat XY arcs in G64 run as
two lines through the naive-CAM merge (naive_cam `arcs_as_lines`), and near-tangent line-arc corners at
the blend speed (blend_arc `curved_blend_speed`). The expected figures are derived here from the rules."""

from __future__ import annotations

import math

import numpy as np
import pytest

from feedlog.errors import SimulationError
from feedlog.profile import load_profile
from feedlog.sim import simulate
from feedlog.sim.window import simulate_windowed
from feedlog.toolpath import load_program

PROFILE = load_profile("linuxcnc-xyz")
A = PROFILE.axes["x"].acc_max          # 1000 mm/s^2 on each axis
V_AXES = PROFILE.axes["x"].vel_max     # 100 mm/s


def _arc_time(radius: float, sweep: float, feed_mm_s: float, share: float) -> float:
    """From rest to rest along one arc: a trapezoid with tangential acceleration share * A."""
    length, a = radius * sweep, share * A
    if feed_mm_s ** 2 / a > length:                       # a triangle
        return 2.0 * math.sqrt(length / a)
    return length / feed_mm_s + feed_mm_s / a


@pytest.mark.parametrize("radius", [50.0, 20.0, 5.0])
def test_an_exact_stop_arc_accelerates_with_the_share_its_max_speed_leaves(radius):
    # a quarter circle from (radius, 0) about the origin, F1200 (20 mm/s), exact stop; a move follows it
    # (LinuxCNC works the share out when the next move is queued: the program's last arc keeps 0.5, below)
    text = f"G21 G90 G61.1 F1200\nG0 X{radius} Y0\nG3 X0 Y{radius} I{-radius} J0\nG0 Z5\nM2\n"
    program = load_program(text, name="arc.ngc")
    blocks = simulate(program, PROFILE).blocks
    took = float(blocks.loc[blocks["line"] == 3, "duration_s"].sum())
    # LinuxCNC: the canon's max speed v = min(axes, sqrt(a_n R)) with a_n = A sqrt(1 - 0.5^2); the planner
    # leaves sqrt(1 - (v^2 / R / A)^2) of A along the path, at least 0.5
    v_ini = min(V_AXES, math.sqrt(A * math.sqrt(0.75) * radius))
    share = max(0.5, math.sqrt(max(0.0, 1.0 - (v_ini ** 2 / radius / A) ** 2)))
    want = _arc_time(radius, math.pi / 2, 20.0, share)
    assert took == pytest.approx(want, abs=2e-3), (took, want, share)
    fixed = simulate(program, PROFILE, mechanisms={"lookahead": {"arc_share_from_speed": False}}).blocks
    took_fixed = float(fixed.loc[fixed["line"] == 3, "duration_s"].sum())
    assert took_fixed == pytest.approx(_arc_time(radius, math.pi / 2, 20.0, 0.5), abs=2e-3)
    last = load_program(text.replace("G0 Z5\n", ""), name="last.ngc")     # nothing queued after the arc
    took_last = float(simulate(last, PROFILE).blocks.set_index("line")["duration_s"][3])
    assert took_last == pytest.approx(_arc_time(radius, math.pi / 2, 20.0, 0.5), abs=2e-3)
    if radius > 12:      # a wide arc: the difference is the acceleration phases, 20/500 - 20/(share A) s
        assert took_fixed - took == pytest.approx(20 / 500 - 20 / (share * A), abs=2e-3)
        assert share > 0.85
    else:                # 5 mm: the centripetal cap binds, the share stays 0.5
        assert share == pytest.approx(0.5) and took == pytest.approx(took_fixed, abs=1e-9)


def _flat_arc_chain(n: int, radius: float, step_deg: float, mode: str, seed: int = 0) -> str:
    """n tangent arcs of alternating turn on a wavy path (each sweep step_deg, radius jittered)."""
    rng = np.random.default_rng(seed)
    x, y, heading = 0.0, 0.0, math.radians(30.0)
    out = [f"G21 G90 {mode} F3000", "G0 X0 Y0 Z0"]
    for k in range(n):
        r = radius * (0.7 + 0.6 * rng.random())
        turn = 1 if (k // 5) % 2 == 0 else -1              # five left, five right
        cx, cy = x - turn * r * math.sin(heading), y + turn * r * math.cos(heading)
        heading += turn * math.radians(step_deg)
        x, y = cx + turn * r * math.sin(heading), cy - turn * r * math.cos(heading)
        out.append(f"{'G3' if turn > 0 else 'G2'} X{x:.6f} Y{y:.6f} R{r:.6f}")
    out.append("M2")
    return "\n".join(out) + "\n"


def test_flat_arcs_in_g64_run_as_lines_through_their_midpoints():
    # 40 arcs of about 60 mm radius and 1 deg (1 mm long): sagitta 60 (1 - cos 0.5 deg) = 0.0023 mm
    arcs = _flat_arc_chain(40, 60.0, 1.0, "G64 P0.01")
    program = load_program(arcs, name="flat.ngc")
    res = simulate(program, PROFILE)
    assert res.notes["arcs_as_lines"] == 40
    # the same path written as G1 through each arc's midpoint and end: the same motion
    motion = program.motion
    moves = motion[motion["kind"].astype(str).str.startswith("arc")]
    lines = ["G21 G90 G64 P0.01 F3000", "G0 X0 Y0 Z0"]
    for _, row in moves.iterrows():
        cx, cy, r = row["cx_mm"], row["cy_mm"], row["radius_mm"]
        a0 = math.atan2(row["y0_mm"] - cy, row["x0_mm"] - cx)
        turn = 1.0 if str(row["kind"]) == "arc_ccw" else -1.0          # sweep_deg is unsigned
        mid = a0 + turn * math.radians(row["sweep_deg"]) / 2
        lines.append(f"G1 X{cx + r * math.cos(mid):.9f} Y{cy + r * math.sin(mid):.9f}")
        lines.append(f"G1 X{row['x_mm']:.9f} Y{row['y_mm']:.9f}")
    as_lines = simulate(load_program("\n".join(lines) + "\nM2\n", name="lines.ngc"), PROFILE)
    assert res.cycle_time_s == pytest.approx(as_lines.cycle_time_s, abs=2e-3)
    # switched off, or with Q below the sagitta, or outside G64, they stay arcs and run slower
    off = simulate(program, PROFILE, mechanisms={"naive_cam": {"arcs_as_lines": False}})
    tight = simulate(load_program(arcs.replace("P0.01", "P0.01 Q0.001"), name="q.ngc"), PROFILE)
    assert "arcs_as_lines" not in off.notes and "arcs_as_lines" not in tight.notes
    assert off.cycle_time_s > res.cycle_time_s + 0.01
    stop = simulate(load_program(arcs.replace("G64 P0.01", "G61.1"), name="g611.ngc"), PROFILE)
    assert "arcs_as_lines" not in stop.notes


def test_a_split_arc_keeps_one_block_row_and_windows_agree():
    # 300 arcs, a few too curved to be split: windows of several sizes give the whole run's block table
    program = load_program(_flat_arc_chain(300, 30.0, 3.0, "G64 P0.01", seed=3), name="mixed.ngc")
    whole = simulate(program, PROFILE)
    assert 50 < whole.notes["arcs_as_lines"] < 250
    table = whole.blocks
    assert not table["block"].duplicated().any()
    for size in (5, 17, 64):
        res, blocks, _ = simulate_windowed(program, PROFILE, window=size)
        assert res.cycle_time_s == pytest.approx(whole.cycle_time_s, abs=1e-9), size
        assert blocks["block"].tolist() == table["block"].tolist(), size
        assert np.allclose(blocks["t_end_ns"], table["t_end_ns"], atol=2), size


def test_a_near_tangent_line_arc_corner_keeps_its_speed():
    # a 10 mm line into a 40 mm radius arc whose start tangent is 1.5 deg off the line (G64 P0.01, F3000)
    kink = math.radians(1.5)
    r = 40.0
    cx, cy = 10.0 - r * math.sin(kink), r * math.cos(kink)     # the arc leaves (10, 0) at 1.5 deg, CCW
    end_a = -math.pi / 2 + kink + math.radians(20)
    ex, ey = cx + r * math.cos(end_a), cy + r * math.sin(end_a)
    text = (f"G21 G90 G64 P0.01 F3000\nG0 X0 Y0\nG1 X10 Y0\nG3 X{ex:.6f} Y{ey:.6f} I{cx - 10:.6f} J{cy:.6f}\n"
            f"G1 X{ex + 10 * math.cos(end_a + math.pi / 2):.6f} Y{ey + 10 * math.sin(end_a + math.pi / 2):.6f}\nM2\n")
    program = load_program(text, name="kink.ngc")

    def slowest_at_corner(res) -> float:
        s = res.series
        near = np.hypot(s["x_mm"] - 10.0, s["y_mm"]) < 0.5
        return float(s.loc[near, "feed_mm_min"].min()) / 60.0

    res = simulate(program, PROFILE)
    assert res.notes["curved_blends"] == 1
    assert slowest_at_corner(res) > 49.0         # the blend's speed: F3000 (50 mm/s) kept
    kinked = simulate(program, PROFILE, mechanisms={"blend_arc": {"curved_blend_speed": False,
                                                                  "parabolic_choice": False}})
    assert kinked.notes.get("curved_blends", 0) == 0
    assert slowest_at_corner(kinked) < 25.0       # the kink rule's speed: 1.5 deg at 50 mm/s is too much
    assert kinked.cycle_time_s > res.cycle_time_s + 0.02


def test_a_sharp_corner_into_a_tight_arc_is_left_to_the_kink_rule():
    # 90 deg from a line into a 2 mm arc: the blend would span much of the arc's turn, so it is not used
    text = "G21 G90 G64 P0.05 F3000\nG0 X0 Y0\nG1 X10 Y0\nG3 X12 Y2 I0 J2\nG1 X12 Y12\nM2\n"
    program = load_program(text, name="sharp.ngc")
    on, off = (simulate(program, PROFILE, mechanisms={"blend_arc": {"curved_blend_speed": flag}})
               for flag in (True, False))
    assert on.notes.get("curved_blends", 0) == 0
    assert on.cycle_time_s == pytest.approx(off.cycle_time_s, abs=1e-12)


def test_the_short_arc_switches_are_checked():
    program = load_program("G21 G90 G64 P0.01 F1200\nG0 X0 Y0\nG3 X2 Y2 I2 J0\nM2\n", name="check.ngc")
    with pytest.raises(SimulationError, match="curved_blend_turn must be >= 0, got -0.1"):
        simulate(program, PROFILE, mechanisms={"blend_arc": {"curved_blend_turn": -0.1}})
    with pytest.raises(SimulationError, match="arcs_as_lines"):
        simulate(program, PROFILE, mechanisms={"naive_cam": {"arcs_as_lines": 2.5}})


def test_arc_side_lengths_speed_up_sharp_line_arc_corners_only_and_windows_agree():
    # 90 deg corners between lines and arcs without P (plasmatest's star): the kink rule nearly stops
    # there; LinuxCNC's arc-side lengths blend them. Near-tangent spline corners (the splines
    # recordings) keep their speed either way.
    text = "G21 G90 G64\nG1 X0 Y0 F5000\n" + "".join(
        f"G1 X{40 * k + 30} Y0\nG2 X{40 * k + 40} Y10 I10 J0\nG1 Y40\nG0 Y0\n" for k in range(6)) + "M2\n"
    program = load_program(text, name="star.ngc")
    gate = {"blend_arc": {"arc_side_lengths": False}}
    sides = simulate(program, PROFILE)
    assert sides.cycle_time_s < simulate(program, PROFILE, mechanisms=gate).cycle_time_s - 0.05
    for size in (3, 11):
        res, blocks, _ = simulate_windowed(program, PROFILE, window=size)
        assert res.cycle_time_s == pytest.approx(sides.cycle_time_s, abs=1e-9), size
    spline = load_program(_flat_arc_chain(60, 30.0, 3.0, "G64 P0.01", seed=5), name="flat.ngc")
    unplaced = {"blend_arc": {"curved_blend_geometry": False}}     # the blend's speed alone (placed: test_blend_geometry)
    assert simulate(spline, PROFILE, mechanisms=unplaced).cycle_time_s == pytest.approx(
        simulate(spline, PROFILE, mechanisms=gate).cycle_time_s, rel=1e-12)
