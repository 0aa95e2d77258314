import numpy as np
import pytest

from align_synth import Motion, repeated_zigzag, zigzag
from feedlog.align.match import MatchConfig, match_cl_points
from feedlog.errors import AlignmentError


def densify(vertices: np.ndarray, step_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """CL points every ~step_mm along the polyline, and the vertex each one lies on/after."""
    pts, seg = [vertices[:1]], [np.array([0])]
    for k in range(len(vertices) - 1):
        n = max(1, int(np.ceil(np.linalg.norm(vertices[k + 1] - vertices[k]) / step_mm)))
        f = np.arange(1, n + 1) / n
        pts.append(vertices[k] + f[:, None] * (vertices[k + 1] - vertices[k]))
        seg.append(np.full(n, k))
    return np.vstack(pts), np.concatenate(seg)


@pytest.fixture(scope="module")
def motion():
    # every line of the zig-zag is traced three times (forward, back, forward)
    return Motion(repeated_zigzag(2), feed_mm_min=3000.0)


def test_repeated_passes_match_the_right_pass_at_1khz(motion):
    ax = motion.axes(1000.0, jitter_ns=100_000)
    m = match_cl_points(motion.v, ax["t_ns"].to_numpy(), ax[["x_mm", "y_mm", "z_mm"]].to_numpy(),
                        config=MatchConfig(tol_mm=0.01))
    err = (m.t_ns - motion.arrival_ns)[1:] / 1e6
    assert np.abs(err).max() <= 1.0  # every vertex arrival within one sample, in the right pass
    assert np.all(np.diff(m.t_ns) >= 0)
    assert m.dist_mm.max() < 1e-3
    # departure from the first point is motion start
    assert abs(m.t_depart_ns[0] - motion.arrival_ns[0]) <= 1_000_000


@pytest.mark.parametrize("whole", [{}, {"whole_cells": 200_000}, {"sparse_whole": "off"}],
                         ids=["whole-program", "in-groups", "chunks-only"])
def test_far_fewer_measured_than_cl_points_5hz(motion, whole):
    # Sun Fig. 11: ~900 measured vs ~5400 CL points; here 5 Hz vs CL points every 0.1 mm; the whole
    # program matched at once, in groups of points (a long recording), or by the chunk search alone
    cl, vertex = densify(motion.v, 0.1)
    ax = motion.axes(5.0, phase_ns=77_000_000)
    assert len(cl) > 5 * len(ax)
    m = match_cl_points(cl, ax["t_ns"].to_numpy(), ax[["x_mm", "y_mm", "z_mm"]].to_numpy(),
                        config=MatchConfig(tol_mm=5.0, **whole))
    assert np.all(np.diff(m.t_ns) >= 0)
    # each CL point matched inside the time its own segment of its own pass was travelled (+- 1 sample)
    t_seg0 = motion.arrival_ns[vertex]
    t_seg1 = motion.arrival_ns[np.minimum(vertex + 1, len(motion.v) - 1)]
    inside = (m.t_ns >= t_seg0 - 200_000_000) & (m.t_ns <= t_seg1 + 200_000_000)
    assert inside[1:].all()


def test_far_more_measured_than_cl_points(motion):
    ax = motion.axes(1000.0)
    cl = motion.v[[0, 3, 8, 15, -1]]  # a handful of vertices, one of them passed three times
    m = match_cl_points(cl, ax["t_ns"].to_numpy(), ax[["x_mm", "y_mm", "z_mm"]].to_numpy(),
                        s_mm=np.concatenate([[0], np.cumsum(motion.lengths)])[[0, 3, 8, 15, -1]],
                        config=MatchConfig(tol_mm=0.01))
    np.testing.assert_allclose(m.t_ns[1:], motion.arrival_ns[[3, 8, 15, -1]], atol=1_000_000)


def test_nearest_without_progress_would_pick_the_wrong_pass(motion):
    """The unconstrained nearest sample of a repeated vertex is often in another pass: the constraint matters."""
    ax = motion.axes(1000.0)
    p = ax[["x_mm", "y_mm", "z_mm"]].to_numpy()
    t = ax["t_ns"].to_numpy()
    d = np.linalg.norm(p[None, :, :] - motion.v[:, None, :], axis=2)
    naive = t[np.argmin(d, axis=1)]
    wrong = np.abs(naive - motion.arrival_ns) > 50_000_000
    assert wrong.sum() >= 5
    m = match_cl_points(motion.v, t, p, config=MatchConfig(tol_mm=0.01))
    assert np.abs(m.t_ns - motion.arrival_ns)[1:].max() <= 1_000_000


def test_tolerance_violation_lists_worst_cases(motion):
    ax = motion.axes(1000.0)
    cl = motion.v.copy()
    cl[5] += (0.0, 0.0, 0.4)
    cl[9] += (0.3, 0.0, 0.0)  # off the path (x beyond the pass end)
    labels = [f"block {k} (line {10 + k})" for k in range(len(cl))]
    with pytest.raises(AlignmentError, match=r"2 of the program.s CL points.*block 5 \(line 15\).*0\.4000 mm"
                       r".*block 9 \(line 19\)"):
        match_cl_points(cl, ax["t_ns"].to_numpy(), ax[["x_mm", "y_mm", "z_mm"]].to_numpy(),
                        config=MatchConfig(tol_mm=0.05), labels=labels)
    # the same points excluded from the check pass and report their distance
    check = np.ones(len(cl), bool)
    check[[5, 9]] = False
    m = match_cl_points(cl, ax["t_ns"].to_numpy(), ax[["x_mm", "y_mm", "z_mm"]].to_numpy(),
                        config=MatchConfig(tol_mm=0.05), check=check)
    assert m.dist_mm[5] == pytest.approx(0.4, abs=1e-3)


def test_wrong_program_refused():
    motion = Motion(zigzag(), feed_mm_min=3000.0)
    ax = motion.axes(100.0)
    with pytest.raises(AlignmentError, match="never comes within"):
        match_cl_points(motion.v + 50.0, ax["t_ns"].to_numpy(), ax[["x_mm", "y_mm", "z_mm"]].to_numpy())


def test_config_checks():
    with pytest.raises(AlignmentError, match="tol_mm"):
        MatchConfig(tol_mm=0)
    with pytest.raises(AlignmentError, match="drift"):
        MatchConfig(drift=1.5)
    with pytest.raises(AlignmentError, match="sparse_whole"):
        MatchConfig(sparse_whole="sometimes")
