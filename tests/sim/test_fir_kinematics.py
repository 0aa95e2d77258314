"""FIR-filter interpolation (Chien Eq. 3) and the AC trunnion kinematics (Chien Eq. 7, 9, 10)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from feedlog.sim import simulate
from feedlog.sim.fir import corner_feed, moving_average
from feedlog.sim.kinematics import rotary_from_orientation, trunnion_joints

T1, T2 = 0.070, 0.010


def fir(**params):
    return {"fir": {"t1_s": T1, "t2_s": T2, **params}, "lookahead": False, "blend_arc": False}


def test_moving_average_is_causal_and_preserves_the_end_value():
    x = np.concatenate([np.zeros(5), np.ones(20)])[:, None]
    y = moving_average(x, 10)
    assert y[4, 0] == 0.0 and y[14, 0] == pytest.approx(1.0) and y[9, 0] == pytest.approx(0.5)


def test_single_block_takes_length_over_feed_plus_filter_delay(plain, gcode):
    res = simulate(gcode("G21 G90 G64\nG1 X100 F3000\n"), plain, mechanisms=fir())
    assert res.cycle_time_s == pytest.approx(100 / 50 + T1 + T2, abs=2e-3)
    s = res.series
    acc = np.diff(s["feed_mm_min"].to_numpy() / 60) / 0.001
    assert np.abs(acc).max() <= 50 / T1 * 1.02  # F / T1


def test_corner_blend_error_stays_within_tolerance(plain, gcode):
    tol = 0.02
    res = simulate(gcode("G21 G90 G64\nG1 X30 F3000\nG1 Y30\n"), plain, mechanisms=fir(tolerance_mm=tol))
    s = res.series
    dist = np.hypot(s["x_mm"] - 30, s["y_mm"])  # distance to the corner point
    err = dist.min() * math.sin(math.pi / 4)  # deviation of the closest point, measured on the bisector
    assert err <= tol * 1.2
    f_star = corner_feed(np.array([math.pi / 2]), np.array([tol]), T1, T2)[0]
    assert f_star == pytest.approx(24 * T1 * tol / ((3 * T1 ** 2 + T2 ** 2) * math.sqrt(2)))
    loose = simulate(gcode("G21 G90 G64\nG1 X30 F3000\nG1 Y30\n"), plain, mechanisms=fir(tolerance_mm=0.2))
    assert loose.cycle_time_s < res.cycle_time_s  # a larger eps_TCP means a smaller feed drop


def test_short_segments_blend_globally(plain, gcode):
    # 0.1 mm segments on a gentle arc: the pulses overlap and the feed stays near F
    pts = [(20 * math.sin(i / 200), 20 - 20 * math.cos(i / 200)) for i in range(1, 201)]
    text = "G21 G90 G64\nF1200\n" + "\n".join(f"G1 X{x:.5f} Y{y:.5f}" for x, y in pts) + "\n"
    res = simulate(gcode(text), plain, mechanisms=fir(tolerance_mm=0.01))
    mid = res.series["feed_mm_min"].iloc[len(res.series) // 3: 2 * len(res.series) // 3]
    assert mid.min() > 0.9 * 1200


def test_orientation_to_rotary_axes_eq7():
    ori = np.array([[0.0, 1.0, 1.0], [1.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    a, c = rotary_from_orientation(ori)
    assert a[:2] == pytest.approx([45.0, 45.0]) and a[2] == pytest.approx(0.0)
    assert c[0] == pytest.approx(0.0) and c[1] == pytest.approx(90.0)
    assert c[2] == pytest.approx(90.0)  # held through the singular point


def test_trunnion_joints_eq10():
    p = np.array([[10.0, 0.0, 0.0], [0.0, 10.0, 0.0]])
    # C = 90 turns x onto y; A = 90 turns y onto z
    q = trunnion_joints(p, np.array([0.0, 90.0]), np.array([90.0, 0.0]), workpiece_offset_mm=(0, 0, 0),
                        rotary_offset_mm=(0, 0, 0))
    assert q[0] == pytest.approx([0.0, 10.0, 0.0], abs=1e-9)
    assert q[1] == pytest.approx([0.0, 0.0, 10.0], abs=1e-9)


def _cl_program(offset: float, n: int = 60) -> str:
    """A straight TCP line while the tool axis sweeps along a line that passes `offset` from the pole
    (CL data with I J K): the orientation arc is about the same, but near the pole C must swing ~180 deg."""
    rows = []
    for i in range(n + 1):
        s = -0.3 + 0.6 * i / n
        o = np.array([s, offset, 1.0])
        o /= np.linalg.norm(o)
        rows.append(f"G1 X{0.5 * i:.3f} I{o[0]:.6f} J{o[1]:.6f} K{o[2]:.6f}")
    return "G21 G90 G64 P0.01\nF3000\n" + "\n".join(rows) + "\n"


def test_feed_drops_near_the_singularity(make_machine, gcode):
    """Chien Eq. 9: dC/dt = (1 / sin A) d(theta_h)/dt, so passing close to the pole is slow."""
    prof = make_machine(five_axis=True)
    near = simulate(gcode(_cl_program(0.01)), prof, mechanisms=["trunnion", "lookahead", "junction_deviation"])
    far = simulate(gcode(_cl_program(0.3)), prof, mechanisms=["trunnion", "lookahead", "junction_deviation"])
    assert near.cycle_time_s > 1.5 * far.cycle_time_s
    c = near.series["c_deg"].to_numpy()
    assert np.ptp(c) > 150  # C swings through ~180 deg near the pole
    assert near.joints is not None and list(near.joints.columns)[:2] == ["t_ns", "j0_pos"]


def test_workpiece_offset_slows_a_rotary_move(make_machine, gcode):
    prof = make_machine(five_axis=True)
    text = "G21 G90 G61\nF3000\n" + "\n".join(f"G1 X{0.5 * i:.2f} C{3 * i}" for i in range(1, 40)) + "\n"
    times = [simulate(gcode(text), prof, mechanisms={"trunnion": {"workpiece_offset_mm": (0, off, 0)}}).cycle_time_s
             for off in (0.0, 150.0, 400.0)]
    assert times[0] < times[1] < times[2]


def test_jerk_filter_bounds_jerk_and_adds_its_window(plain, gcode):
    prog = gcode("G21 G90 G61\nG1 X60 F3000\n")
    base = simulate(prog, plain, mechanisms=["lookahead"])
    smooth = simulate(prog, plain, mechanisms=["lookahead", "jerk_filter"])  # default 10 ms window
    assert smooth.cycle_time_s == pytest.approx(base.cycle_time_s + 0.010, abs=1e-9)
    dt = 0.001
    v = smooth.series["x_mm"].diff().to_numpy()[1:] / dt
    a = np.diff(v) / dt
    jerk = np.abs(np.diff(a)) / dt
    assert jerk.max() <= 1000 / 0.010 * 1.05          # a_max / T_j
    assert np.abs(a).max() <= 1000 * 1.01
    assert smooth.series["x_mm"].iloc[-1] == pytest.approx(60.0)
    raw_jerk = np.abs(np.diff(np.diff(base.series["x_mm"].diff().to_numpy()[1:] / dt) / dt)) / dt
    assert raw_jerk.max() > 4 * jerk.max()             # the plain trapezoid has acceleration steps


def test_jerk_filter_defaults_from_profile_jerk_limits(make_machine):
    from feedlog.sim import resolve_mechanisms

    prof = make_machine()
    assert "jerk_filter" not in {m.name for m in resolve_mechanisms(prof)}
    axes = {k: v.__class__(vel_max=v.vel_max, acc_max=v.acc_max, jerk_max=50000.0) for k, v in prof.axes.items()}
    jerky = prof.replace(axes=axes)
    mech = {m.name: m for m in resolve_mechanisms(jerky)}
    assert mech["jerk_filter"].jerk_time_s == pytest.approx(1000 / 50000)
