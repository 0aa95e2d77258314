import numpy as np
import pandas as pd
import pytest

from align_synth import Motion, zigzag
from feedlog.align.blocks import blocks_from_geometry, blocks_from_lines, compare_blocks, line_runs, motion_span
from feedlog.align.match import MatchConfig, match_cl_points
from feedlog.errors import AlignmentError


@pytest.fixture(scope="module")
def motion():
    v = np.vstack([zigzag(passes=5, length=30.0, step=3.0), [[0.0, 12.0, 5.0], [20.0, 12.0, 5.0]]])
    return Motion(v, feed_mm_min=3000.0, acc_mm_s2=1000.0, lead_s=0.7, tail_s=0.4)


def _blocks(motion):
    n = len(motion.lengths)
    return pd.DataFrame({"block": np.arange(n) + 3, "line": np.arange(n) + 10})


def _line_stream(motion, rate_hz):
    t = motion.timestamps(rate_hz)
    k = np.searchsorted(motion.arrival_ns, t, side="right") - 1  # segment being executed
    line = np.where(k < 0, 4, k + 10)
    line = np.where(k >= len(motion.lengths), 0, line)  # idle after the end
    return t, line.astype(np.int64)


def test_motion_span_at_1khz(motion):
    ax = motion.axes(1000.0)
    span = motion_span(ax["t_ns"].to_numpy(), ax[["x_mm", "y_mm", "z_mm"]].to_numpy())
    assert span.duration_s == pytest.approx(motion.motion_s, abs=0.002)
    assert abs(span.t_start_ns - motion.arrival_ns[0]) <= 1_000_000


@pytest.mark.parametrize("phase_ms", [0, 63, 141])
def test_motion_span_at_5hz_within_half_percent(motion, phase_ms):
    ax = motion.axes(5.0, phase_ns=phase_ms * 1_000_000)
    p = ax[["x_mm", "y_mm", "z_mm"]].to_numpy()
    span = motion_span(ax["t_ns"].to_numpy(), p, acc_mm_s2=1000.0)
    assert span.duration_s == pytest.approx(motion.motion_s, rel=0.005)
    # without the sub-interval estimate the error would be up to two sample periods
    crude = (ax["t_ns"].iloc[span.last_index] - ax["t_ns"].iloc[span.first_index]) / 1e9
    assert crude >= span.duration_s


def test_motion_span_refuses_a_still_recording():
    t = np.arange(10, dtype=np.int64) * 1_000_000
    with pytest.raises(AlignmentError, match="never moves"):
        motion_span(t, np.zeros((10, 3)))


def test_blocks_from_lines(motion):
    t, line = _line_stream(motion, 1000.0)
    blocks = _blocks(motion)
    span = motion_span(t, motion.positions(t))
    got = blocks_from_lines(t, line, blocks, span=span)
    true_dur = motion.durations
    np.testing.assert_allclose(got["duration_s"], true_dur, atol=0.0011)
    assert got["seen"].all()
    assert got["t_start_ns"].iloc[0] >= span.t_start_ns and got["t_end_ns"].iloc[-1] <= span.t_end_ns
    # a block whose line never shows gets zero duration at its neighbour's boundary
    line2 = np.where(line == 13, 14, line)
    got2 = blocks_from_lines(t, line2, blocks, span=span)
    row = got2[got2["line"] == 13].iloc[0]
    assert not row["seen"] and row["duration_s"] == 0
    assert row["t_start_ns"] == got2[got2["line"] == 14]["t_start_ns"].iloc[0]
    with pytest.raises(AlignmentError, match="never shows"):
        blocks_from_lines(t, np.full(len(t), 999), blocks)


def test_line_runs():
    runs = line_runs(np.array([0, 1, 2, 3, 4]), np.array([5, 5, 7, 7, 5]))
    assert runs["line"].tolist() == [5, 7, 5]
    assert runs["t_start_ns"].tolist() == [0, 2, 4] and runs["t_end_ns"].tolist() == [2, 4, 4]


@pytest.mark.parametrize("rate_hz, tol_mm, max_median_s", [(1000.0, 0.01, 0.001), (5.0, 5.0, 0.1)])
def test_geometry_blocks_match_line_truth(motion, rate_hz, tol_mm, max_median_s):
    ax = motion.axes(rate_hz, phase_ns=0 if rate_hz > 100 else 91_000_000)
    t = ax["t_ns"].to_numpy()
    p = ax[["x_mm", "y_mm", "z_mm"]].to_numpy()
    span = motion_span(t, p, acc_mm_s2=1000.0)
    m = match_cl_points(motion.v, t, p, config=MatchConfig(tol_mm=tol_mm))
    blocks = _blocks(motion)
    geo = blocks_from_geometry(blocks, m.t_ns[1:], m.t_depart_ns[1:], span=span)
    tl, line = _line_stream(motion, 1000.0)
    truth = blocks_from_lines(tl, line, blocks, span=motion_span(tl, motion.positions(tl)))
    cmp = compare_blocks(truth, geo, servo_period_s=0.001)
    assert cmp["blocks"] == len(blocks)
    assert cmp["duration_err_median_s"] <= max_median_s
    assert (geo["t_end_ns"].iloc[-1] - geo["t_start_ns"].iloc[0]) / 1e9 == pytest.approx(motion.motion_s, rel=0.005)


# --- LinuxCNC planner moves (feedlog.align.moves) -----------------------------------------------------

def _blended_path(corners, radius_mm, speed_mm_per_sample):
    """Straight moves between `corners` (xy) joined by circular blends of `radius_mm` tangent to both
    moves (as LinuxCNC's blend arcs), sampled at a constant speed. Returns positions (n, 3), and per
    move the arc length where the tool arrives on and leaves its chord."""
    c = np.asarray(corners, dtype=float)
    u = np.diff(c, axis=0)
    u /= np.linalg.norm(u, axis=1)[:, None]
    pieces = []  # (kind, start, end or centre data, length)
    on = [(0.0, None)]
    s = 0.0
    pos = c[0]
    for i in range(1, len(c) - 1):
        half = np.arccos(np.clip(u[i - 1] @ u[i], -1, 1)) / 2       # half the turn
        trim = radius_mm * np.tan(half)
        p_in, p_out = c[i] - trim * u[i - 1], c[i] + trim * u[i]
        L = np.linalg.norm(p_in - pos)
        pieces.append(("line", pos, p_in, L))
        s += L
        on[-1] = (on[-1][0], s)
        turn = np.sign(u[i - 1][0] * u[i][1] - u[i - 1][1] * u[i][0])   # +1 left, -1 right
        normal = np.array([-u[i - 1][1], u[i - 1][0]]) * turn
        centre = p_in + radius_mm * normal
        sweep = 2 * half
        pieces.append(("arc", p_in, (centre, sweep, turn), radius_mm * sweep))
        s += radius_mm * sweep
        on.append((s, None))
        pos = p_out
    L = np.linalg.norm(c[-1] - pos)
    pieces.append(("line", pos, c[-1], L))
    on[-1] = (on[-1][0], s + L)
    total = s + L
    samples = np.arange(0.0, total + speed_mm_per_sample, speed_mm_per_sample)
    samples = np.minimum(samples, total)
    out = np.zeros((len(samples), 3))
    start = 0.0
    for kind, a, b, length in pieces:
        sel = (samples >= start) & (samples <= start + length)
        w = samples[sel] - start
        if kind == "line":
            out[sel, :2] = a + (b - a) * (w / max(length, 1e-12))[:, None]
        else:
            centre, sweep, turn = b
            r0 = a - centre
            ang = turn * w / radius_mm
            cs, sn = np.cos(ang), np.sin(ang)
            out[sel, 0] = centre[0] + cs * r0[0] - sn * r0[1]
            out[sel, 1] = centre[1] + sn * r0[0] + cs * r0[1]
        start += length
    return out, np.asarray(on)


def _leave(corners, *, radius=0.5, step=0.05, **kw):
    from feedlog.align.moves import move_leave_times
    p, on = _blended_path(corners, radius, step)
    t = np.arange(len(p), dtype=np.int64) * 1_000_000   # 1 kHz
    c = np.c_[np.asarray(corners, float), np.zeros(len(corners))]
    end_index = np.array([np.argmin(np.linalg.norm(p - e, axis=1)) for e in c[1:]], dtype=float)
    leave = move_leave_times(t, p, c[:-1], c[1:], end_index, np.arange(len(c) - 1), on_path_mm=1e-6, **kw)
    return leave, on / step  # chord run [arrive, leave] per move in samples


def test_move_leaves_its_chord_where_the_blend_begins():
    leave, on = _leave([[0, 0], [10, 0], [10, 10], [0, 10]])
    # moves 0 and 1 have long straight rests: the line switches one sample after the last on the chord
    for k in (0, 1):
        assert leave[k] / 1e6 == pytest.approx(np.floor(on[k, 1]) + 1, abs=1)
    assert leave[2] / 1e6 >= np.floor(on[2, 1])  # the last move stays on its chord to its end


def test_short_straight_rest_is_consumed_by_the_next_blend():
    """Move 1's straight rest (0.15 mm = 3 cycles at 0.05 mm per cycle) is shorter than 4 gap cycles:
    LinuxCNC's next blend arc consumes it, the line switches where the tool arrives on the chord."""
    corners = [[0, 0], [10, 0], [10, 1.15], [0, 1.15]]
    leave, on = _leave(corners)
    assert on[1, 1] - on[1, 0] == pytest.approx(3.0, abs=0.01)
    assert leave[1] / 1e6 == pytest.approx(np.ceil(on[1, 0]), abs=1)
    # the same rest with the gap check off (or with rotary moves, which blend without arcs): the leave
    long_leave, _ = _leave(corners, gap_cycles=0)
    assert long_leave[1] / 1e6 == pytest.approx(np.floor(on[1, 1]) + 1, abs=1)
    no_arcs, _ = _leave(corners, arc_blends=np.array([True, False, True]))
    assert no_arcs[1] == long_leave[1]
    assert leave[0] == long_leave[0]
    # a longer rest (0.5 mm = 10 cycles) is kept
    leave10, on10 = _leave([[0, 0], [10, 0], [10, 1.5], [0, 1.5]])
    assert leave10[1] / 1e6 == pytest.approx(np.floor(on10[1, 1]) + 1, abs=1)


def test_move_the_path_only_touches_ends_at_the_touching_point():
    """Move 1 is exactly as long as its two blends' trims: the blends meet on its chord."""
    leave, on = _leave([[0, 0], [10, 0], [10, 1.0], [0, 1.0]])
    assert on[1, 1] - on[1, 0] == pytest.approx(0.0, abs=1e-6)
    touch = on[1, 0]
    assert leave[1] / 1e6 == pytest.approx(touch, abs=1.0)
    assert leave[0] < leave[1]


def test_move_leave_times_rejects_inconsistent_moves():
    from feedlog.align.moves import move_leave_times
    t = np.arange(10, dtype=np.int64) * 1_000_000
    p = np.zeros((10, 3))
    seg = np.zeros((3, 3))
    with pytest.raises(AlignmentError, match="non-decreasing"):
        move_leave_times(t, p, seg, seg, np.zeros(3), np.array([0, 1, 0]))


def test_planner_moves_follow_linuxcnc_collinear_merge():
    """G64 P0.05 (Q = P): nearly collinear 0.2 mm segments are merged into one move (emccanon's chain);
    G61 and G64 P0.05 Q0 run every block alone; a corner always ends a move."""
    from feedlog.align.moves import planner_moves
    from feedlog.profile import load_profile
    from feedlog.toolpath import parse_program
    lines = [f"G1 X{0.2 * i:.3f} Y{0.002 * (i % 2):.4f}" for i in range(1, 11)] + ["G1 Y5", "G1 X0"]

    def moves(mode):
        text = "\n".join(["G21 G90 G17", mode, "G0 X0 Y0 Z0", "F3000"] + lines + ["M2"])
        return planner_moves(parse_program(text, name="merge.ngc"), load_profile("linuxcnc-xyz"))
    merged = moves("G64 P0.05")
    assert len(merged) == 13 and merged[0] == 0                  # the rapid is its own move
    assert (merged[1:11] == merged[1]).all()                     # the ten short segments: one move
    assert merged[11] != merged[10] and merged[12] != merged[11]   # corners
    for mode in ("G61", "G64 P0.05 Q0"):
        assert (np.diff(moves(mode)) == 1).all()
