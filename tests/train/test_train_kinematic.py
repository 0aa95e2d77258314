"""The local kinematic time the learners start from (train/kinematic.py) and its use as a base time."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feedlog.align import align_recording
from feedlog.errors import ModelError
from feedlog.ingest import read_recording
from feedlog.profile import load_profile
from feedlog.toolpath import parse_program
from feedlog.train import ProgramTable, make_model
from feedlog.train.features import build_inputs, kin_time, limited_time, profile_constants, with_program_columns
from feedlog.train.kinematic import blend_radius, junction_kink, kinematic_time, path_limits, trapezoid_time
from feedlog.manifest import read_manifest

A = 1000.0  # mm/s^2
CYCLE = 0.001


def _times(length, feed, tol, corner_end, *, rapid=None, rotary=None, acc=A, merge=None):
    n = len(length)
    return kinematic_time(np.asarray(length, float), np.full(n, feed), np.full(n, acc), np.full(n, np.inf),
                          np.full(n, tol), np.asarray(corner_end, float),
                          np.zeros(n, bool) if rapid is None else np.asarray(rapid), CYCLE,
                          rotary=None if rotary is None else np.asarray(rotary),
                          merge=None if merge is None else np.full(n, merge))


def test_trapezoid_from_rest_to_rest():
    # 100 mm at 50 mm/s: cruise 2 s plus v / a for the two ramps
    assert trapezoid_time(np.array([100.0]), 0.0, 0.0, 50.0, A)[0] == pytest.approx(2.05)
    # 0.5 mm never reaches 100 mm/s: a triangle, 2 sqrt(L / a)
    assert trapezoid_time(np.array([0.5]), 0.0, 0.0, 100.0, A)[0] == pytest.approx(2 * math.sqrt(0.5 / A))
    # an exit speed the length cannot reach is lowered to what it can reach
    assert trapezoid_time(np.array([0.5]), 0.0, 100.0, 100.0, A)[0] == pytest.approx(math.sqrt(2 * 0.5 / A))


def test_corners_stop_in_exact_stop_and_blend_within_the_tolerance():
    length, feed = [10.0, 10.0], 3000.0  # 50 mm/s
    straight = _times(length, feed, 0.01, [0.0, 180.0]).sum()
    assert straight == pytest.approx(20.0 / 50.0 + 50.0 / A)  # collinear: no stop between the blocks
    g61 = _times(length, feed, 0.0, [0.0, 180.0]).sum()
    assert g61 == pytest.approx(2 * (10.0 / 50.0 + 50.0 / A))  # G61: a stop at the junction
    corner = _times(length, feed, 0.1, [90.0, 180.0])
    radius = 0.1 * math.cos(math.pi / 4) / (1 - math.cos(math.pi / 4))
    v = math.sqrt(0.87 * A * radius)  # LinuxCNC's share of the acceleration across the path on a blend arc
    assert blend_radius(np.array([math.pi / 4]), 0.1)[0] == pytest.approx(radius)
    # the arc replaces R tan(45 deg) = R of each block by a quarter circle's half, R pi / 4, run at its
    # own speed: the first block is a 10 - R mm line from rest to v, then that half arc at v
    line = trapezoid_time(np.array([10.0 - radius]), 0.0, v, 50.0, A)[0]
    assert corner[0] == pytest.approx(line + radius * math.pi / 4 / v)
    assert corner[1] == pytest.approx(radius * math.pi / 4 / v + trapezoid_time(np.array([10.0 - radius]), v, 0.0,
                                                                                  50.0, A)[0])
    assert straight < corner.sum() < g61
    # a finer tolerance is a slower corner
    assert _times(length, feed, 0.01, [90.0, 180.0]).sum() > corner.sum()


def test_rapid_feed_junctions_stop_and_rotary_junctions_are_parabolic_blends():
    length = [10.0, 10.0]
    blended = _times(length, 3000.0, 0.1, [30.0, 180.0]).sum()
    mode_change = _times(length, 3000.0, 0.1, [30.0, 180.0], rapid=[True, False]).sum()
    assert mode_change == pytest.approx(2 * (10.0 / 50.0 + 50.0 / A))
    rotary = _times(length, 3000.0, 0.1, [30.0, 180.0], rotary=[True, True])
    assert rotary.sum() > blended
    # parabolic blend: the first block runs rest to rest at half acceleration, and the second starts
    # while it decelerates from the blend speed 2 sqrt(a/2 P / sin(corner / 2)) (under 50 mm/s here)
    v_blend = 2 * math.sqrt(A / 2 * 0.1 / math.sin(math.radians(15.0)))
    assert v_blend < 50.0
    assert rotary[0] == pytest.approx(10.0 / 50.0 + 50.0 / (A / 2) - v_blend / (A / 2))
    assert rotary[1] == pytest.approx(10.0 / 50.0 + 50.0 / A)
    # in G61 a rotary junction is a plain stop at full acceleration ...
    stop = 2 * (10.0 / 50.0 + 50.0 / A)
    assert _times(length, 3000.0, 0.0, [30.0, 180.0], rotary=[True, True]).sum() == pytest.approx(stop)
    # ... and a G61 corner without a rotary move keeps LinuxCNC's kink reduction: 90 % acceleration
    assert _times(length, 3000.0, 0.0, [30.0, 180.0]).sum() == pytest.approx(2 * (10.0 / 50.0 + 50.0 / (0.9 * A)))


def test_look_ahead_slows_a_block_so_that_the_next_can_stop():
    # 10 mm then 0.1 mm in line, then a stop: one 10.1 mm trapezoid, although the short block alone
    # could only shed sqrt(2 a 0.1 mm) = 14 mm/s of the 50 mm/s the first would reach
    t = _times([10.0, 0.1], 3000.0, 0.01, [0.0, 180.0])
    assert t.sum() == pytest.approx(10.1 / 50.0 + 50.0 / A)
    v = math.sqrt(2 * A * 0.1)
    assert t[0] == pytest.approx(trapezoid_time(np.array([10.0]), 0.0, v, 50.0, A)[0])


def test_blocks_covered_by_blend_arcs_accelerate_at_half_the_path_acceleration():
    # 50 blocks of 0.1 mm turning 1 deg each: the arcs cover every inner block (half of each end
    # block), so the 5 mm run is a trapezoid between those at A / 2 (0.2 s) and 3/4 A (0.167 s)
    t = _times([0.1] * 50, 3000.0, 0.1, [1.0] * 49 + [180.0]).sum()
    at = [trapezoid_time(np.array([5.0]), 0.0, 0.0, 50.0, a)[0] for a in (A / 2, 0.75 * A, A)]
    assert at[1] < t < at[0]
    assert t > 1.2 * at[2]  # what full acceleration would give


def test_a_moving_block_takes_at_least_its_segment_minimum():
    """LinuxCNC caps a segment's speed at its length per 1.02 servo cycles (TP_MIN_SEGMENT_CYCLES)."""
    t = _times([0.0001, 0.0], 3000.0, 0.01, [0.0, 180.0])  # a 0.63 ms triangle without the cap
    cap = 0.0001 / (1.02 * CYCLE)
    assert t[0] == pytest.approx(trapezoid_time(np.array([0.0001]), 0.0, 0.0, cap, A)[0]) and t[1] == 0.0
    assert t[0] > 1.02 * CYCLE


def _dense_run(turn_deg, n=200):
    """n blocks of 0.02 mm at F3000 in G64 P0.01 Q0, turning `turn_deg` at every other junction."""
    corners = [turn_deg if k % 2 == 0 else 0.0 for k in range(n - 1)] + [180.0]
    return np.asarray([0.02] * n), corners


def test_a_blend_arc_next_to_a_straight_junction_leaves_a_slow_rest_of_line():
    """dense002q0's regime: a 0.5 deg corner between 0.02 mm lines gets a blend arc that takes half of
    each line; the line after it keeps 0.01 mm up to the next (straight) junction, a segment of its own
    at under 0.01 mm / 1.02 ms. Every junction touches such a rest, so the run crawls at about 10 mm/s
    (2 ms per block; LinuxCNC ran dense002q0 at 1.67 ms per block)."""
    length, corners = _dense_run(0.5)
    t = _times(length, 3000.0, 0.01, corners)
    rest_speed = 0.01 / (1.02 * CYCLE)
    assert t[1:-1].sum() > (len(t) - 2) * 0.02 / (1.1 * rest_speed)
    assert t[1:-1].mean() == pytest.approx(2.0 * CYCLE, rel=0.1)


def test_a_tiny_corner_is_a_tangent_junction_without_an_arc():
    """A 0.05 deg corner needs under 10 % of the axis acceleration in one servo cycle at 20 mm/s
    (LinuxCNC tpSetupTangent): no arc, each 0.02 mm block is one segment of 1.02 servo cycles."""
    length, corners = _dense_run(0.05)
    t = _times(length, 3000.0, 0.01, corners)
    # the run is one trapezoid at that cap: 4 mm from rest to rest at 0.02 mm per 1.02 ms
    assert t.sum() == pytest.approx(trapezoid_time(np.array([4.0]), 0.0, 0.0, 0.02 / (1.02 * CYCLE), A)[0], rel=0.01)
    # the same corners as blend arcs would leave the slow rests of the test above
    length, corners = _dense_run(0.5)
    assert t[1:-1].mean() < 0.6 * _times(length, 3000.0, 0.01, corners)[1:-1].mean()


def test_merged_lines_are_not_held_to_the_segment_minimum():
    """With G64 Q > 0 the interpreter joins nearly collinear lines before the planner sees them: the
    program's blocks are shorter than LinuxCNC's segments, so no per-segment cap applies."""
    length, corners = _dense_run(0.5)
    merged = _times(length, 3000.0, 0.01, corners, merge=True)
    assert merged[1:-1].mean() < 0.6 * _times(length, 3000.0, 0.01, corners)[1:-1].mean()
    assert merged[1:-1].min() >= CYCLE  # still one servo period per block


def test_path_limits_come_from_the_slowest_axis():
    profile = load_profile("linuxcnc-xyzac")
    c = profile.axes["c"]
    source = pd.DataFrame({"length_mm": [10.0, 10.0], "x0_mm": [0.0, 0.0], "x_mm": [10.0, 10.0],
                           "c0_deg": [0.0, 0.0], "c_deg": [0.0, 30.0]})
    acc, vel = path_limits(source, profile)
    assert acc[0] == pytest.approx(profile.axes["x"].acc_max) and vel[0] == pytest.approx(profile.axes["x"].vel_max)
    share = 30.0 / 10.0  # deg of C per mm of path
    assert vel[1] == pytest.approx(min(profile.axes["x"].vel_max, c.vel_max / share))
    assert acc[1] == pytest.approx(min(profile.axes["x"].acc_max, c.acc_max / share))


def _blocks(n=6, **cols):
    data = {"block": np.arange(n), "kind": ["linear"] * n, "length_mm": np.full(n, 2.0),
            "feed_mm_min": np.full(n, 3000.0), "nominal_time_s": np.full(n, 2.0 / 50.0),
            "tol_mm": np.full(n, 0.01), "corner_end_deg": np.r_[np.full(n - 1, 45.0), 180.0],
            "duration_s": np.full(n, 0.06)}
    return pd.DataFrame({**data, **cols})


def test_kin_time_features_are_at_least_the_limited_cam_time():
    profile = load_profile("linuxcnc-xyz")
    blocks = _blocks()
    kin = kin_time(blocks, profile_constants(profile))
    assert np.all(kin >= limited_time(blocks)) and kin.sum() > limited_time(blocks).sum() * 1.05
    x = build_inputs(blocks, ("log_kin_time_s", "kin_ratio"), constants=profile_constants(profile))
    np.testing.assert_allclose(x[:, 1], kin / limited_time(blocks), rtol=1e-6)


def test_a_kinematic_base_needs_its_columns_and_a_known_base_is_required():
    with pytest.raises(ModelError, match="base must be one of"):
        make_model("bilstm-block", base="simulated")
    model = make_model("mlp", base="kinematic")
    assert {"feed_mm_min", "corner_end_deg", "tol_mm"} <= set(model.required_columns)
    table = ProgramTable("t", _blocks().drop(columns=["corner_end_deg"]), profile=load_profile("linuxcnc-xyz"))
    with pytest.raises(ModelError, match="corner_end_deg"):
        make_model("bilstm-final", base="kinematic").base_time(table)
    cam = make_model("bilstm-final", base="cam").base_time(table)
    np.testing.assert_allclose(cam, limited_time(table.blocks))


RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"


@pytest.mark.parametrize("name", ["rcl_f3000_g61", "freeform_f3000_p001", "rcl5ax_f3000_p01", "rcl5ax_f3000_g61"])
def test_on_linuxcnc_recordings_the_kinematic_time_is_far_closer_than_cam(name):
    """Training recordings (3-axis G61 and G64, five-axis G64 with parabolic blends and G61): the kinematic
    time is within 4 % of LinuxCNC's time and has at most a quarter of the limited CAM time's error."""
    entry = {e.name: e for e in read_manifest(RECORDINGS / "manifest.toml")}[name]
    assert entry["split"] == "train"
    profile = load_profile(entry["profile"])
    program = parse_program((RECORDINGS / entry["program"]).read_text(), name=entry["program"])
    aligned = align_recording(read_recording(RECORDINGS / entry["file"]), program, profile=profile)
    blocks = with_program_columns(aligned.blocks, program, profile)
    measured = blocks["duration_s"].sum()
    kin_err = kin_time(blocks, profile_constants(profile)).sum() / measured - 1
    cam_err = limited_time(blocks).sum() / measured - 1
    assert abs(kin_err) < 0.04 and abs(kin_err) < abs(cam_err) / 4, (kin_err, cam_err)


def test_junction_kink_weighs_each_axis_by_its_acceleration():
    """LinuxCNC's tangent check takes the largest per-axis share of the direction change: a corner
    split over two axes weighs less than the same turn on one axis; arcs are left to the corner angle."""
    profile = load_profile("linuxcnc-xyz")
    turn = math.radians(0.3)
    source = pd.DataFrame({"x0_mm": [0.0, 1.0, 1.0 + math.cos(turn), 0.0],
                           "x_mm": [1.0, 1.0 + math.cos(turn), 2.0, 0.0],
                           "y0_mm": [0.0, 0.0, math.sin(turn), 0.0], "y_mm": [0.0, math.sin(turn), 1.0, 0.0],
                           "z0_mm": [0.0] * 4, "z_mm": [0.0] * 4, "radius_mm": [np.nan, np.nan, 5.0, np.nan]})
    kink = junction_kink(source, profile)
    acc = profile.axes["y"].acc_max
    # X then 0.3 deg up: the change is almost all on Y
    assert kink[0] == pytest.approx(math.sin(turn) / acc, rel=1e-6)
    assert np.isnan(kink[1]) and np.isnan(kink[2]) and np.isnan(kink[3])  # an arc; no next move
    # the same turn at 45 deg between X and Y: each axis gets 1/sqrt(2) of it
    h, ang = math.sqrt(0.5), math.pi / 4 + turn
    diag = pd.DataFrame({"x0_mm": [0.0, h], "x_mm": [h, h + math.cos(ang)],
                         "y0_mm": [0.0, h], "y_mm": [h, h + math.sin(ang)]})
    assert junction_kink(diag, profile)[0] == pytest.approx(2 * math.sin(turn / 2) * math.sin(math.pi / 4 + turn / 2) / acc,
                                                            rel=1e-6)
