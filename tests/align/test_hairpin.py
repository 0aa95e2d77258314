"""The constrained match at a hairpin of very short blocks (docs/align.md, "Rejected recordings").

A blended path is shorter than the program (every corner is cut), so the chunk search predicts the
measured length of a point too far ahead. Just before a hairpin the pass coming back lies as close to the
short blocks as the approach does, and nearer that prediction: the search used to give the points the
far side of the hairpin, 0.06-0.6 mm away, and the running maximum dragged the next ones there too.
Synthetic truth: the program's corners replaced by quadratic blends deviating P = 0.1 mm, moved at a
constant 1000 mm/min, sampled at 1 kHz."""

from __future__ import annotations

import numpy as np
import pytest

from feedlog.align import align_recording
from feedlog.align.chunks import Path, untangle
from feedlog.align.match import MatchConfig, match_cl_points
from feedlog.errors import AlignmentError
from feedlog.ingest import read_recording
from test_recordings import ALIGN_REFUSED, ROOT

P_MM = 0.1
SPEED_MM_S = 1000.0 / 60.0
N_SHORT = 10


def blended(vertices: np.ndarray, dev_mm: float) -> np.ndarray:
    """The polyline with each corner replaced by a quadratic Bezier whose middle is dev_mm from the
    vertex (control point on the vertex, legs at most half of either neighbouring segment), densely."""
    d = np.diff(vertices, axis=0)
    length = np.linalg.norm(d, axis=1)
    u = d / length[:, None]
    t = np.linspace(0.0, 1.0, 200)[:, None]
    parts = [vertices[:1]]
    for i in range(1, len(vertices) - 1):
        turn = np.linalg.norm(u[i] - u[i - 1])  # |u2 - u1|: the Bezier's middle lies leg x turn / 4 inside
        leg = min(4.0 * dev_mm / turn if turn > 1e-12 else 0.0, 0.5 * length[i - 1], 0.5 * length[i])
        a, c, b = vertices[i] - leg * u[i - 1], vertices[i], vertices[i] + leg * u[i]
        parts.append((1 - t) ** 2 * a + 2 * t * (1 - t) * c + t ** 2 * b)
    parts.append(vertices[-1:])
    p = np.vstack(parts)
    return p[np.r_[True, np.linalg.norm(np.diff(p, axis=0), axis=1) > 0]]


def hairpin_program(reversal_deg: float) -> np.ndarray:
    """A zig-zag of long blocks (its blends make the measured path ~1 mm shorter than the program), then
    N_SHORT blocks of 0.06 mm in +x ending in a reversal by `reversal_deg`, a long block back beside the
    short ones and one more block away."""
    v = [np.array([x, y, 0.0]) for x, y in [(0, 0), (6, 1.2), (0.5, 2.4), (6.5, 3.6), (1, 4.8), (7, 6.0)]]
    for _ in range(N_SHORT):
        v.append(v[-1] + (0.06, 0.0, 0.0))
    back = np.radians(180.0 - reversal_deg)
    v.append(v[-1] + 6.0 * np.array([-np.cos(back), np.sin(back), 0.0]))
    v.append(v[-1] + (0.0, 4.0, 0.0))
    return np.array(v)


def sampled(path: np.ndarray, rate_hz: float = 1000.0) -> tuple[np.ndarray, np.ndarray]:
    """(t_ns, positions) of the path moved at SPEED_MM_S from t = 1 s."""
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    t_s = np.arange(0.0, s[-1] / SPEED_MM_S, 1.0 / rate_hz)
    pos = np.column_stack([np.interp(t_s * SPEED_MM_S, s, path[:, i]) for i in range(3)])
    return 1_000_000_000 + np.rint(t_s * 1e9).astype(np.int64), pos


def closest_on_polyline(c: np.ndarray, pos: np.ndarray, lo: int, hi: int) -> tuple[float, float]:
    """(fractional sample index, distance) of the point of pos[lo:hi + 1] closest to c."""
    p0, d = pos[lo:hi], pos[lo + 1:hi + 1] - pos[lo:hi]
    u = np.clip(((c - p0) * d).sum(axis=1) / (d * d).sum(axis=1), 0.0, 1.0)
    dist = np.linalg.norm(c - (p0 + u[:, None] * d), axis=1)
    j = int(np.argmin(dist))
    return lo + j + u[j], float(dist[j])


@pytest.mark.parametrize("reversal_deg", [161.0, 180.0])
def test_short_blocks_before_a_hairpin_match_the_approach(reversal_deg):
    v = hairpin_program(reversal_deg)
    t, pos = sampled(blended(v, P_MM))
    # the tolerance the pipeline would give under G64 P0.1: 0.05 + P
    m = match_cl_points(v, t, pos, config=MatchConfig(tol_mm=0.05 + P_MM))
    short = np.arange(6, 6 + N_SHORT)
    tip = int(np.argmax(pos[:, 0]))  # the hairpin's tip: farthest along +x
    for k in short:
        idx, dist = closest_on_polyline(v[k], pos, 0, tip)  # where the approach passes the point
        assert m.index[k] == pytest.approx(idx, abs=1.0)  # within one sample, on the approach
        assert m.dist_mm[k] == pytest.approx(dist, abs=1e-6)
    assert np.all(np.diff(m.index) >= 0)
    assert m.index[short].max() <= tip
    if reversal_deg == 180.0:
        # the return pass retraces the short blocks: plain nearest samples take it for most of them
        nearest = np.argmin(np.linalg.norm(pos[None, :, :] - v[short, None, :], axis=2), axis=1)
        assert (nearest > tip).sum() >= N_SHORT // 2


def test_a_match_is_the_closest_point_of_its_passage():
    """At a blended corner the progress term must not pull the match off the closest point: the matched
    distance is the least distance over the pass (the zig-zag's corner tips, 0.1 mm from the blend)."""
    v = hairpin_program(161.0)
    t, pos = sampled(blended(v, P_MM))
    m = match_cl_points(v, t, pos, config=MatchConfig(tol_mm=0.05 + P_MM))
    for k in range(1, 5):
        j = int(m.index[k])
        idx, dist = closest_on_polyline(v[k], pos, max(j - 200, 0), min(j + 200, len(pos) - 1))
        assert dist == pytest.approx(P_MM, abs=0.01)
        assert m.dist_mm[k] == pytest.approx(dist, abs=1e-6)
        assert m.index[k] == pytest.approx(idx, abs=0.01)


@pytest.mark.parametrize("name", sorted(ALIGN_REFUSED))
def test_refused_recordings_are_still_refused(name):
    """ALIGN_REFUSED names what really still fails (a deviation beyond the tolerance, not the matcher)."""
    path = ROOT / f"{name}.mcap"
    if not path.exists():
        pytest.skip(f"{path} not present")
    with pytest.raises(AlignmentError, match="farther than their tolerance"):
        align_recording(read_recording(path))


def _line_path(vertices: np.ndarray) -> Path:
    p = np.asarray(vertices, dtype=np.float64)
    d = np.diff(p, axis=0)
    dd = (d * d).sum(axis=1)
    sv = np.concatenate([[0.0], np.cumsum(np.sqrt(dd))])
    return Path(cols=(p[:-1, 0], p[:-1, 1], p[:-1, 2], d[:, 0], d[:, 1], d[:, 2]), dd=dd, seg_len=np.sqrt(dd),
                sv=sv, sv_len=np.diff(sv), seg_dt=np.full(len(dd), 1e-3))


@pytest.mark.parametrize("wrong", [[4, 5], [8, 9]])  # inside the sequence, and at its end
def test_untangle_puts_matches_on_the_far_pass_back(wrong):
    """A line out to x = 10 and back (vertices every 0.5 mm): CL points at x = 0..9 on the way out.
    Matches on the way back for some of them contradict progress; untangle brings them to the way out."""
    xs = np.r_[np.arange(0.0, 10.0, 0.5), np.arange(10.0, -0.01, -0.5)]
    path = _line_path(np.column_stack([xs, np.zeros_like(xs), np.zeros_like(xs)]))
    cl = np.column_stack([np.arange(10.0), np.zeros(10), np.zeros(10)])
    s_prog = cl[:, 0].copy()
    seg = (2 * np.arange(10)).astype(np.int64)  # vertex 2k is x = k on the way out
    u = np.zeros(10)
    back = np.array(wrong)
    seg[back] = 39 - 2 * back  # x = k on the way back: segment 39 - 2k ends there
    u[back] = 1.0
    dist = np.zeros(10)
    order = np.arange(10)
    n = untangle(cl, s_prog, order, seg, u, dist, path, weight=0.25, min_mm=0.05)
    assert n >= len(back)
    S = path.sv[seg] + u * path.sv_len[seg]
    np.testing.assert_allclose(S, cl[:, 0], atol=1e-9)
    np.testing.assert_allclose(dist, 0.0, atol=1e-9)
