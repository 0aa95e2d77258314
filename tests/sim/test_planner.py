"""Look-ahead planner: closed-form cases, the vectorised passes, invariants."""

from __future__ import annotations

import math

import numpy as np
import pytest

from feedlog.sim import simulate
from feedlog.sim.motion import plan_speeds
from feedlog.sim.path import Pieces

F3000 = 50.0  # mm/s


def test_one_long_block_is_a_trapezoid(plain, gcode):
    res = simulate(gcode("G21 G90 G61\nG1 X100 F3000\n"), plain, mechanisms=["lookahead"])
    # accelerate to F, cruise, decelerate: L / v + v / a
    assert res.cycle_time_s == pytest.approx(100 / F3000 + F3000 / 1000, abs=1e-6)
    assert res.series["feed_mm_min"].max() == pytest.approx(3000, rel=1e-6)
    assert res.cam_time_s == pytest.approx(2.0)


def test_short_block_never_reaches_feed(plain, gcode):
    res = simulate(gcode("G21 G90 G61\nG1 X1 F3000\n"), plain, mechanisms=["lookahead"])
    assert res.cycle_time_s == pytest.approx(2 * math.sqrt(1 / 1000), abs=1e-6)
    peak = res.series["feed_mm_min"].max() / 60
    assert peak == pytest.approx(math.sqrt(1000 * 1.0), rel=0.02)  # v_peak = sqrt(a L), sampled at 1 ms
    assert peak < F3000


def test_diagonal_block_uses_projected_axis_limits(plain, gcode):
    res = simulate(gcode("G21 G90 G61\nG1 X30 Y30 F99999\n"), plain, mechanisms=["lookahead"])
    length = 30 * math.sqrt(2)
    v, a = 50 * math.sqrt(2), 1000 * math.sqrt(2)  # each axis at its own limit
    assert res.cycle_time_s == pytest.approx(length / v + v / a, abs=1e-6)


@pytest.mark.parametrize("law", ["blend_arc", "junction_deviation"])
def test_right_angle_corner_exact_stop_vs_continuous(plain, law, gcode):
    g61 = simulate(gcode("G21 G90 G61\nG1 X20 F3000\nG1 Y20\n"), plain, mechanisms=["lookahead", law])
    # the last block in G61 in both, so only the corner differs (LinuxCNC halves the acceleration of a
    # G64 block that ends the program, see test_last_continuous_block_runs_at_half_acceleration)
    g64 = simulate(gcode("G21 G90 G64 P0.05\nG1 X20 F3000\nG61\nG1 Y20\n"), plain, mechanisms=["lookahead", law])
    # two full stops; LinuxCNC's blend law keeps its 10 % kink acceleration reduction on G61 corners
    acc = 900.0 if law == "blend_arc" else 1000.0
    one = 20 / F3000 + F3000 / acc
    assert g61.cycle_time_s == pytest.approx(2 * one, abs=1e-6)
    assert g64.cycle_time_s < g61.cycle_time_s - 0.002
    corner = g64.series.loc[(g64.series["x_mm"] > 19.0) & (g64.series["y_mm"] < 1.0), "feed_mm_min"]
    assert corner.min() > 0  # never stops in the corner
    assert g61.trajectory.plan.v1[0] == 0.0  # stops at the corner
    near = g61.series["feed_mm_min"].iloc[int(one / 0.001) - 1: int(one / 0.001) + 2]
    assert near.min() < 0.002 * acc * 60


def test_junction_deviation_corner_speed_is_closed_form(plain, gcode):
    res = simulate(gcode("G21 G90 G64 P0.05\nG1 X40 F6000\nG1 Y40\n"), plain,
                   mechanisms=["lookahead", "junction_deviation"])
    s = res.series
    at_corner = s.iloc[int(np.argmin(np.hypot(s["x_mm"] - 40, s["y_mm"])))]
    sin_half = math.sin(math.pi / 4)
    v = math.sqrt(1000 * 0.05 * sin_half / (1 - sin_half))  # grbl, 90 degree corner
    assert at_corner["feed_mm_min"] / 60 == pytest.approx(v, rel=0.05)


def test_arc_speed_limited_by_centripetal_acceleration(make_machine, gcode):
    prof = make_machine(vel=500.0)
    res = simulate(gcode("G21 G90 G17 G61\nG0 X5 Y0\nG3 X5 Y0 I-5 J0 F30000\n"), prof, mechanisms=["lookahead"])
    s = res.series[res.series["block"] == 2]
    v_normal = math.sqrt(1000 * math.sqrt(0.75) * 5)
    assert s["feed_mm_min"].max() / 60 == pytest.approx(v_normal, rel=0.01)
    r = np.hypot(s["x_mm"], s["y_mm"])
    assert np.allclose(r, 5.0, atol=1e-9)  # stays on the circle


def _naive_plan(length, vmax, acc, v_end, lookahead):
    """Straightforward loop version of the backward/forward passes, for comparison."""
    m = len(length)
    cap = np.minimum(np.minimum(v_end, vmax), np.append(vmax[1:], 0.0)) ** 2
    cap[-1] = 0.0
    d = 2 * acc * length
    for j in range(m):
        cap[j] = min(cap[j], d[j + 1:j + 1 + lookahead].sum())
    w = cap.copy()
    for j in range(m - 2, -1, -1):
        w[j] = min(w[j], w[j + 1] + d[j + 1])
    u = np.zeros(m)
    prev = 0.0
    for j in range(m):
        u[j] = min(w[j], prev + d[j])
        prev = u[j]
    return np.sqrt(u)


def test_vectorised_passes_match_a_naive_loop():
    rng = np.random.default_rng(3)
    m = 400
    length = rng.uniform(0.01, 5.0, m)
    vmax = rng.uniform(5, 80, m)
    acc = rng.uniform(200, 2000, m)
    v_end = np.where(rng.random(m) < 0.1, 0.0, rng.uniform(0, 80, m))
    zero = np.zeros(m)
    k = 3
    pieces = Pieces(block=np.arange(m), length=length, p0=np.zeros((m, k)), dir=np.zeros((m, k)),
                    e1=np.zeros((m, k)), e2=np.zeros((m, k)), radius=zero, omega=zero, v_max=vmax, a_max=acc,
                    v_end=v_end, hold_s=zero, blend=zero.astype(bool), overlap=zero.astype(bool), clamp_len=length)
    plan = plan_speeds(pieces, lookahead=7)
    assert np.allclose(plan.v1, _naive_plan(length, vmax, acc, v_end, 7), rtol=1e-9, atol=1e-9)
    # every piece's profile is feasible: it covers its length within its limits
    assert np.all(plan.vp <= vmax + 1e-9)
    covered = (plan.v0 + plan.vp) / 2 * plan.t_acc + plan.vp * plan.t_cru + (plan.vp + plan.v1) / 2 * plan.t_dec
    assert np.allclose(covered, length, rtol=1e-7)


def _zigzag(n=40, seed=0) -> str:
    rng = np.random.default_rng(seed)
    pts = np.cumsum(rng.uniform(-3, 3, (n, 3)) * [1, 1, 0.3], axis=0)
    lines = [f"G1 X{x:.4f} Y{y:.4f} Z{z:.4f}" for x, y, z in pts]
    return "G21 G90 G64 P{tol}\nF{feed}\n" + "\n".join(lines) + "\n"


def test_axes_never_exceed_their_limits(plain, gcode):
    text = _zigzag().format(tol=0.05, feed=3000)
    res = simulate(gcode(text), plain, mechanisms=["lookahead", "blend_arc"])
    s = res.series
    dt = 0.001
    pos = s[["x_mm", "y_mm", "z_mm"]].to_numpy()
    vel = np.diff(pos, axis=0) / dt
    acc = np.diff(vel, axis=0) / dt
    assert np.abs(vel).max() <= 50 * 1.001
    # the acceleration of sampled data carries discretisation spikes of O(v^2 dt / R): allow 5 %
    assert np.abs(acc).max() <= 1000 * 1.05


def test_path_ends_at_the_programs_end_point(plain, gcode):
    text = _zigzag(seed=4).format(tol=0.1, feed=2400)
    prog = gcode(text)
    for mechs in (["lookahead", "blend_arc"], ["lookahead", "junction_deviation"], ["fir"], ["cam"]):
        res = simulate(prog, plain, mechanisms=mechs)
        end = prog.blocks.iloc[-1][["x_mm", "y_mm", "z_mm"]].to_numpy(float)
        assert np.allclose(res.series[["x_mm", "y_mm", "z_mm"]].iloc[-1].to_numpy(), end, atol=1e-6), mechs


@pytest.mark.parametrize("law", ["blend_arc", "junction_deviation"])
def test_cycle_time_never_increases_with_tolerance_or_feed(plain, law, gcode):
    times_tol = [simulate(gcode(_zigzag(seed=2).format(tol=tol, feed=3000)), plain,
                          mechanisms=["lookahead", law]).cycle_time_s for tol in (0.001, 0.01, 0.05, 0.2)]
    assert all(b <= a + 1e-9 for a, b in zip(times_tol, times_tol[1:])), times_tol
    times_f = [simulate(gcode(_zigzag(seed=2).format(tol=0.05, feed=f)), plain,
                        mechanisms=["lookahead", law]).cycle_time_s for f in (600, 1200, 2400, 4800)]
    assert all(b <= a + 1e-9 for a, b in zip(times_f, times_f[1:])), times_f


def test_shorter_lookahead_is_never_faster(plain, gcode):
    prog = gcode("G21 G90 G64 P0.1\nF3000\n" + "\n".join(f"G1 X{0.2 * i:.1f}" for i in range(1, 200)) + "\n")
    long = simulate(prog, plain, mechanisms={"lookahead": {"lookahead_blocks": 100}, "blend_arc": False,
                                             "junction_deviation": True})
    short = simulate(prog, plain, mechanisms={"lookahead": {"lookahead_blocks": 2}, "blend_arc": False,
                                              "junction_deviation": True})
    assert short.cycle_time_s > long.cycle_time_s + 0.01
    # collinear 0.2 mm blocks with a long window: one trapezoid over 39.8 mm
    assert long.cycle_time_s == pytest.approx(39.8 / 50 + 50 / 1000, rel=0.01)


def test_block_table_columns_and_times(plain, gcode):
    res = simulate(gcode("G21 G90 G61\nG1 X10 F3000\nG4 P0.5\nG1 Y10\n"), plain, mechanisms=["lookahead"])
    b = res.blocks
    assert list(b.columns) == ["block", "line", "t_start_ns", "t_end_ns", "duration_s"]
    assert (b["t_end_ns"] >= b["t_start_ns"]).all()
    assert b["duration_s"].iloc[1] == pytest.approx(0.5)  # the dwell
    assert res.cycle_time_s == pytest.approx(2 * (10 / 50 + 50 / 1000) + 0.5, abs=1e-6)


def test_blend_arc_stays_inside_the_tolerance(plain, gcode):
    res = simulate(gcode("G21 G90 G64 P0.05\nG1 X20 F3000\nG1 Y20\n"), plain, mechanisms=["lookahead", "blend_arc"])
    s = res.series
    # distance from the programmed corner path (the two legs)
    dev = np.minimum(np.abs(s["y_mm"]).where(s["x_mm"] <= 20, np.inf), np.abs(s["x_mm"] - 20))
    assert dev.max() <= 0.05 + 1e-9
    assert dev.max() > 0.01  # the corner is really cut


def test_last_continuous_block_runs_at_half_acceleration(plain, gcode):
    """LinuxCNC keeps the 'parabolic' end condition on a G64 block that is not blended into a next
    one, which halves its acceleration (tc.c tcGetOverallMaxAccel); G61 does not."""
    g64 = simulate(gcode("G21 G90 G64 P0.05\nG1 X100 F3000\n"), plain, mechanisms=["lookahead", "blend_arc"])
    g61 = simulate(gcode("G21 G90 G61\nG1 X100 F3000\n"), plain, mechanisms=["lookahead", "blend_arc"])
    assert g64.cycle_time_s == pytest.approx(100 / 50 + 50 / 500, abs=1e-6)
    assert g61.cycle_time_s == pytest.approx(100 / 50 + 50 / 1000, abs=1e-6)


def test_rapid_and_feed_moves_are_never_blended(make_machine, gcode):
    """LinuxCNC stops between a rapid and a feed move (tp.c handleModeChange: STOP end condition, so
    the rapid keeps its full acceleration); found on five-axis recordings whose first move is a G0
    turning A by 20 deg, which LinuxCNC made 0.1 s faster than a parabolic blend at half acceleration."""
    prof = make_machine(five_axis=True)
    text = "G21 G90 G64 P0.05\nF3000\nG0 Z2 A-20\nG1 X5 Z2.1 A-21.5\nG1 X10 Z2.2 A-23\n"
    stop = simulate(gcode(text), prof, mechanisms=["lookahead", "blend_arc"])
    blend = simulate(gcode(text), prof, mechanisms={"blend_arc": {"rapid_feed_stop": False}})
    assert blend.notes["parabolic_blends"] == 2 and stop.notes["parabolic_blends"] == 1
    # the G0 turns A 20 deg at 60 deg/s with its full 600 deg/s^2: 20 / 60 + 60 / 600 s
    rapid = stop.blocks.iloc[0]
    assert rapid["duration_s"] == pytest.approx(20 / 60 + 60 / 600, abs=2e-3)
    assert blend.blocks.iloc[0]["duration_s"] > rapid["duration_s"] + 0.05
    def slowest_a_near_junction(res):  # deg/s of A within 3 ms of the end of the G0
        s = res.series
        va = np.abs(np.gradient(s["a_deg"].to_numpy(), s["t_ns"].to_numpy() / 1e9))
        near = np.abs(s["t_ns"].to_numpy() - int(res.blocks.iloc[0]["t_end_ns"])) <= 3_000_000
        return va[near].min()

    assert slowest_a_near_junction(stop) < 1.0 < 10.0 < slowest_a_near_junction(blend)  # standstill vs blend


def test_block_rate_floor_does_not_make_g61_kinks_tangent(make_machine, gcode):
    """LinuxCNC's tangent check (tpSetupTangent) sees the feed, the axis caps and one servo cycle, not
    the rate at which the task process feeds blocks: 0.023 mm G61 segments turning 0.4 deg each stop
    at every junction with or without the block-time floor. Found on the G61 random mixes with dense
    runs (mix_009: LinuxCNC 9-10 ms per short block, the model 1.7 ms while the floor made them tangent)."""
    prof = make_machine(vel=100.0)
    rows, x, y, ang = [], 0.0, 0.0, 0.0
    for _ in range(30):
        ang += math.radians(0.4)
        x, y = x + 0.023 * math.cos(ang), y + 0.023 * math.sin(ang)
        rows.append(f"G1 X{x:.5f} Y{y:.5f}")
    prog = gcode("G21 G90 G61\nF1500\n" + "\n".join(rows) + "\n")
    plain = simulate(prog, prof, mechanisms=["lookahead", "blend_arc"])
    floored = simulate(prog, prof, mechanisms={"block_time": {"min_block_time_s": 0.00167}})
    assert plain.notes["tangent_junctions"] == floored.notes["tangent_junctions"] == 0
    assert floored.cycle_time_s == pytest.approx(plain.cycle_time_s, rel=1e-9)
    # each block stops: a triangle at 90 % of 1000 mm/s^2 (the G61 kink reduction) over 0.023 mm
    assert floored.cycle_time_s == pytest.approx(30 * 2 * math.sqrt(0.023 / 900.0), rel=0.03)


def test_block_after_a_parabolic_blend_stops_at_full_acceleration(make_machine, gcode):
    """A rotary move entered through a parabolic blend and ending before a rapid (a stop) decelerates
    with its full acceleration: mix5ax_023's last G1 (C +94 deg) took 1662 ms in LinuxCNC, the model
    1762 ms while it halved that block for the blend at its start (`halve_after_blend`)."""
    prof = make_machine(five_axis=True)
    prog = gcode("G21 G90 G64 P0.05\nF3000\nG1 X5 C10\nG1 X10 C100\nG0 Z5\n")
    full = simulate(prog, prof, mechanisms=["lookahead", "blend_arc"])
    half = simulate(prog, prof, mechanisms={"blend_arc": {"halve_after_blend": True}})
    assert full.notes["parabolic_blends"] == half.notes["parabolic_blends"] == 1
    t_full, t_half = (r.blocks.iloc[1]["duration_s"] for r in (full, half))
    # C accelerates out of the blend to 60 deg/s and stops before the G0: each ramp costs v / (2 a) more
    # time than cruising, 0.05 s at 600 deg/s^2 and 0.1 s at 300, so 0.1 s for the two
    assert t_half - t_full == pytest.approx(0.1, abs=0.01)


def test_parabolic_blends_keep_the_path_continuous_and_within_limits(make_machine, gcode):
    """Rotary motion: LinuxCNC's parabolic blends overlap two blocks; positions stay continuous,
    axis speeds within limits, and the path still ends at the program's end point."""
    prof = make_machine(five_axis=True)
    rows = "\n".join(f"G1 X{2 * i} Y{(i % 2) * 2} C{10 * i}" for i in range(1, 15))
    res = simulate(gcode("G21 G90 G64 P0.05\nF3000\n" + rows + "\n"), prof, mechanisms=["lookahead", "blend_arc"])
    assert res.trajectory.plan.overlap_s.max() > 0.005  # the blends really overlap
    s = res.series
    vel = np.abs(np.diff(s[["x_mm", "y_mm", "z_mm", "a_deg", "c_deg"]].to_numpy(), axis=0)) / 0.001
    limits = np.array([50, 50, 50, 60, 60])
    assert (vel <= limits * 1.001).all()
    assert s[["x_mm", "y_mm", "c_deg"]].iloc[-1].to_numpy() == pytest.approx([28.0, 0.0, 140.0])
    # blocks follow each other without gaps or overlaps in the block table
    b = res.blocks
    assert (b["t_start_ns"].to_numpy()[1:] == b["t_end_ns"].to_numpy()[:-1]).all()


def test_consumed_short_line_runs_at_arc_speed(plain, gcode):
    """A line shorter than a few servo cycles between two blend arcs is consumed (LinuxCNC
    blendCheckConsume): it runs at the blend speed and takes no separate servo-cycle minimum."""
    prog = gcode("G21 G90 G64 P0.5\nF3000\nG1 X20\nG1 X20.3 Y0.3\nG1 X40 Y0.3\n")
    res = simulate(prog, plain, mechanisms=["lookahead", "blend_arc"])
    assert res.cycle_time_s < simulate(gcode("G21 G90 G61\nF3000\nG1 X20\nG1 X20.3 Y0.3\nG1 X40 Y0.3\n"), plain,
                                       mechanisms=["lookahead", "blend_arc"]).cycle_time_s
    assert res.notes["blend_arcs"] == 2 and res.notes["consumed_lines"] == 1
    mid = res.series[(res.series["x_mm"] > 19.5) & (res.series["x_mm"] < 21.0)]
    assert mid["feed_mm_min"].min() > 300  # never crawls through the short middle block


@pytest.mark.parametrize("mechs", [["lookahead", "blend_arc"], ["fir"], ["lookahead", "jerk_filter"], ["cam"]])
def test_block_durations_add_up_to_the_cycle_time(plain, gcode, mechs):
    res = simulate(gcode(_zigzag(seed=5).format(tol=0.05, feed=3000)), plain, mechanisms=mechs)
    b = res.blocks
    assert b["duration_s"].sum() == pytest.approx(res.cycle_time_s, abs=1e-6)
    assert (b["t_start_ns"].to_numpy()[1:] == b["t_end_ns"].to_numpy()[:-1]).all()


def test_line_piece_left_next_to_a_blend_arc_is_clamped_by_its_own_length(make_machine, gcode):
    """LinuxCNC caps a segment's speed at its length per 1.02 servo cycles, the length being what the
    blend arcs left of the line (tcFinalizeLength): 0.02 mm blocks turning 0.5 deg at every other
    junction keep 0.01 mm pieces of line next to their arcs, run at under 10 mm/s. With the cap on the
    untrimmed length dense002q0 came out 38 % fast."""
    prof = make_machine(vel=100.0)
    rows, x, y, ang = [], 0.0, 0.0, 0.0
    for i in range(200):
        ang += math.radians(0.5) if i % 2 == 0 else 0.0
        x, y = x + 0.02 * math.cos(ang), y + 0.02 * math.sin(ang)
        rows.append(f"G1 X{x:.6f} Y{y:.6f}")
    res = simulate(gcode("G21 G90 G64 P0.01\nF3000\n" + "\n".join(rows) + "\n"), prof,
                   mechanisms=["lookahead", "blend_arc"])
    assert res.notes["blend_arcs"] >= 80 and res.notes["tangent_junctions"] >= 80
    # every 0.01 mm piece of line is a segment of its own: the run averages well under 0.02 mm per ms
    mean_speed = 200 * 0.02 / res.cycle_time_s
    assert mean_speed < 15.0
    # and no faster than a 0.03 mm segment (arc plus consumed line) in 1.02 cycles anywhere
    assert res.series["feed_mm_min"].max() / 60 < 0.03 / 0.00102 + 1e-6


def test_lookahead_counts_queue_entries_not_consumed_lines():
    """A line consumed by its blend arc is part of the arc's queue entry in LinuxCNC: the stopping
    distance within `lookahead` entries reaches past it (longdense_003 was +8.2 % while the window
    counted consumed lines as entries)."""
    from feedlog.sim.motion import junction_caps
    from feedlog.sim.path import with_columns

    m = 6
    ones = np.ones(m)
    pieces = Pieces(block=np.arange(m), length=ones, p0=np.zeros((m, 3)), dir=np.tile([1.0, 0, 0], (m, 1)),
                    e1=np.zeros((m, 3)), e2=np.zeros((m, 3)), radius=np.zeros(m), omega=np.zeros(m),
                    v_max=np.full(m, 1e3), a_max=np.full(m, 100.0), v_end=np.full(m, 1e3), hold_s=np.zeros(m),
                    blend=np.zeros(m, bool), overlap=np.zeros(m, bool), clamp_len=ones.copy())
    entries = junction_caps(pieces, lookahead=2)
    consumed = junction_caps(with_columns(pieces, clamp_len=np.array([1, 0, 1, 0, 1, 1.0])), lookahead=2)
    # piece 0 may still stop within the next 2 entries: 2 pieces, or 4 when two of them ride with arcs
    assert entries[0] == pytest.approx(2 * 100 * 2)
    assert consumed[0] == pytest.approx(2 * 100 * 4)


@pytest.mark.parametrize("program,profile", [("corners_f3000_p001", "linuxcnc-xyz"), ("circle_f3000_p001", "generic-xyz"),
                                             ("mix_010", "linuxcnc-xyzac")])
def test_single_grid_rows_are_the_rows_of_the_whole_grid(program, profile):
    """`Trajectory.sample_at` (diagnose samples only where motion starts and ends) gives the rows the whole
    grid has there, to the last bit, blends and arcs included; a trajectory a filter passed over has none."""
    from pathlib import Path

    from feedlog.toolpath import parse_program

    path = Path(__file__).resolve().parents[2] / "recordings" / "programs" / f"{program}.ngc"
    traj = simulate(parse_program(path), profile).trajectory
    n, dt = traj.grid
    assert n == len(traj.t_s) and dt == pytest.approx(traj.t_s[1] - traj.t_s[0])
    idx = np.unique(np.r_[0, n - 1, np.random.default_rng(3).integers(0, n, 400)])
    t, pos = traj.sample_at(idx)
    assert np.array_equal(t, traj.t_s[idx]) and np.array_equal(pos, traj.pos[idx])
    assert np.ptp(pos[:, 0]) > 1.0  # the rows move: not a grid of rests compared with itself
    assert traj.map(lambda *s: s).grid is None
