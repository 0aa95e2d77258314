"""Step 3 of the constrained match (`match`): the CL points after the start, searched chunk by chunk.

Chunk c places its search windows from the state chunk c - 1 left behind: the anchor (program length s
and measured length S of the last well-matched point) and r, the measured/programmed length ratio.
This is inherently sequential: an anchor is usually a block end at a corner blend, where the winning
foot point moves continuously with the prediction, so chunks searched from guessed states (tried: a
Jacobi iteration over all chunks at once, exact once the states stop changing) settle only one or two
chunks per pass and cost 3-5x more. What is fast here is the per-chunk step: the coarse path is held
as separate x/y/z columns so that every projection is a handful of 2-D numpy operations (no reductions
over a length-3 axis, which numpy does slowly), with the same floating-point operations per point as
before, and the chunk state is plain Python floats.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MAX_WIDEN = 4
TIE_MM = 1e-6
WHOLE_PENALTY = 1000.0  # mm of score per mm outside the tolerance (rematch_whole)
WHOLE_PIECES = 8        # pieces per segment in rematch_whole


@dataclass(frozen=True)
class Path:
    """The coarse measured path the search runs on, as columns: segment starts x0, y0, z0 and vectors
    dx, dy, dz (`cols`), squared lengths dd and lengths seg_len, path length sv at each vertex,
    sv_len = diff(sv), and seg_dt, the sampling interval (s) each segment spans."""

    cols: tuple[np.ndarray, ...]
    dd: np.ndarray
    seg_len: np.ndarray
    sv: np.ndarray
    sv_len: np.ndarray
    seg_dt: np.ndarray

    @property
    def nseg(self) -> int:
        return len(self.dd)


@dataclass(frozen=True)
class Search:
    """How windows are placed and scored (see `match.MatchConfig`)."""

    w0: float
    drift: float
    sparse: bool
    weight: float
    chord_allowance: float
    chunk_points: int
    chunk_mm: float


def project_cols(cx, cy, cz, x0, y0, z0, dx, dy, dz, dd):
    """Project points (cx, cy, cz) onto segments (x0, y0, z0) + u (dx, dy, dz) with squared lengths dd,
    all as separate (broadcasting) columns; returns u in [0, 1] and the distance. Columns, not (..., 3)
    arrays: numpy reduces over a length-3 axis slowly."""
    wx, wy, wz = cx - x0, cy - y0, cz - z0
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(dd > 0, (wx * dx + wy * dy + wz * dz) / np.where(dd > 0, dd, 1.0), 0.0)
    u = np.minimum(np.maximum(u, 0.0), 1.0)  # np.clip's values, without its wrapper's cost per call
    rx, ry, rz = wx - u * dx, wy - u * dy, wz - u * dz
    return u, np.sqrt(rx * rx + ry * ry + rz * rz)


def project_gathered(c: np.ndarray, idx: np.ndarray | slice, path: Path):
    """`project_cols` of points c (k, 3) onto the segments idx ((k, m) indices or a slice) of `path`."""
    if isinstance(idx, slice):
        return project_cols(c[..., 0:1], c[..., 1:2], c[..., 2:3], *(a[idx] for a in path.cols), path.dd[idx])
    return project_cols(c[:, 0:1], c[:, 1:2], c[:, 2:3], *(a[idx] for a in path.cols), path.dd[idx])


def best_in_windows(c, pred, lo, hi, path: Path, weight: float):
    """For points c (k, 3): the best segment in [lo, hi] by distance + weight x |S - pred| (earliest of
    near-equal ones: arrival, not departure, at a standstill). For a point on a straight stretch the
    distance grows with slope 1 away from the foot point, so a weight < 1 never moves the minimum, but
    between equally close passes (a retraced line) it picks the expected one."""
    nseg = path.nseg
    band = int((hi - lo).max()) + 1
    idx = lo[:, None] + np.arange(band)[None, :]
    valid = idx <= hi[:, None]
    np.minimum(idx, nseg - 1, out=idx)
    u, dk = project_gathered(c, idx, path)
    dk = np.where(valid, dk, np.inf)
    score = dk + weight * np.abs(path.sv[idx] + u * path.sv_len[idx] - pred[:, None])
    best = np.argmax(score <= score.min(axis=1, keepdims=True) + TIE_MM, axis=1)
    rows = np.arange(len(c))
    return idx[rows, best], u[rows, best], dk[rows, best]


def chunk_bounds(s_sel: np.ndarray, chunk_points: int, chunk_mm: float) -> list[int]:
    """Start offsets (and the end) of the chunks of the ordered points with program length s_sel: at most
    chunk_points points and chunk_mm of program each, at least one point."""
    bounds = [0]
    i, n = 0, len(s_sel)
    while i < n:
        hi = min(i + chunk_points, n)
        cut = int(np.searchsorted(s_sel[i:hi], s_sel[i] + chunk_mm, side="right"))
        i += max(1, cut)
        bounds.append(i)
    return bounds


def search_chunks(cl: np.ndarray, s_prog: np.ndarray, tol: np.ndarray, speed: np.ndarray | None,
                  rest: np.ndarray, path: Path, cfg: Search, *, anchor_s: float, anchor_S: float,
                  ratio: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(segment, u, distance) of every CL point in `rest` (ordered, after the start match), searching
    its chunks one after the other from the start state (anchor_s, anchor_S, ratio)."""
    n = len(rest)
    seg = np.full(n, -1, dtype=np.int64)
    u = np.full(n, np.nan)
    dist = np.full(n, np.nan)
    nseg = path.nseg
    if n == 0 or nseg == 0:
        return seg, u, dist
    s_rest = s_prog[rest]
    c_rest = cl[rest]
    # the tolerance a match must meet to become the anchor, and the reach speed x interval, per point
    tol_rest = tol[rest]
    speed_rest = None if speed is None else speed[rest]
    sv, sv_len, seg_len, seg_dt = path.sv, path.sv_len, path.seg_len, path.seg_dt
    w0, drift, last_seg = cfg.w0, cfg.drift, max(nseg - 1, 0)
    bounds = chunk_bounds(s_rest, cfg.chunk_points, cfg.chunk_mm)
    for i, j in zip(bounds[:-1], bounds[1:]):
        ds = np.maximum(s_rest[i:j] - anchor_s, 0.0)
        pred = anchor_S + ratio * ds
        # the measured path may be much shorter than the program (chords over wiggles, blends) but not
        # much longer: search from just behind the anchor to (1 + drift) x the programmed distance ahead
        if cfg.sparse:
            lo_s = np.full(j - i, anchor_S - w0)
            hi_s = anchor_S + (1 + drift) * ds + w0
        else:  # dense samples follow the program closely: a window around the prediction
            lo_s = pred - w0 - drift * ds
            hi_s = pred + w0 + drift * ds
        # np.clip on integers looks up the type's limits on every call: maximum/minimum instead
        lo = np.minimum(np.maximum(np.searchsorted(sv, lo_s, side="right") - 1, 0), last_seg)
        hi = np.minimum(np.maximum(np.searchsorted(sv, hi_s, side="left"), 0), last_seg)
        c = c_rest[i:j]
        sb, ub, db = best_in_windows(c, pred, lo, hi, path, cfg.weight)
        for _ in range(MAX_WIDEN - 1):
            # a best candidate on the window's edge may hide a better one beyond it: widen and retry
            edge = ((sb == lo) & (lo > 0)) | ((sb == hi) & (hi < last_seg))
            if not edge.any():
                break
            e = np.flatnonzero(edge)
            width = hi[e] - lo[e] + 1
            lo[e] = np.maximum(lo[e] - width, 0)
            hi[e] = np.minimum(hi[e] + width, last_seg)
            sb[e], ub[e], db[e] = best_in_windows(c[e], pred[e], lo[e], hi[e], path, cfg.weight)
        seg[i:j], u[i:j], dist[i:j] = sb, ub, db
        reach = seg_len[sb]
        if speed_rest is not None:
            reach = np.maximum(reach, speed_rest[i:j] * seg_dt[sb])
        good = np.flatnonzero(db <= tol_rest[i:j] + cfg.chord_allowance * reach)
        if len(good):
            a = int(good[-1])
            new_s = float(s_rest[i + a])
            new_S = float(sv[sb[a]] + ub[a] * sv_len[sb[a]])
            if new_s - anchor_s > w0:  # local ratio of measured to programmed length, for the prediction
                ratio = min(max((new_S - anchor_S) / (new_s - anchor_s), 0.05), 1.0 + drift)
            anchor_s, anchor_S = new_s, new_S
    return seg, u, dist


def monotone_path(score: np.ndarray) -> np.ndarray:
    """Per row (point, in program order) the column (segment) of the non-decreasing sequence with the
    least summed score (dynamic programming with a running minimum per row; earliest of equal costs)."""
    n, m = score.shape
    cols = np.arange(m)
    back = np.empty((n, m), dtype=np.int64)
    cost = score[0]
    for r in range(1, n):
        # best predecessor on this segment or an earlier one (earliest of equal costs)
        pm = np.minimum.accumulate(cost)
        new = np.concatenate([[True], cost[1:] < pm[:-1]])
        back[r] = np.maximum.accumulate(np.where(new, cols, 0))
        cost = score[r] + pm
    best = np.empty(n, dtype=np.int64)
    best[-1] = int(np.argmax(cost <= cost.min() + TIE_MM))
    for r in range(n - 1, 0, -1):
        best[r - 1] = back[r, best[r]]
    return best


def rematch_whole(cl: np.ndarray, run: np.ndarray, j0: int, j1: int, path: Path, allowed: np.ndarray,
                  speed: np.ndarray | None, *, chord_allowance: float, pieces: int = WHOLE_PIECES,
                  penalty: float = WHOLE_PENALTY) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(segment, u, distance) of the points `run` (program order) matched all at once to segments j0..j1.

    For sparse data (5 Hz: a sample every few mm, chords across corners), where a prediction of the
    measured length runs ahead of the tool on zig-zags and the chunk search can settle on a later pass;
    here the order of all points decides instead. Every segment is cut into `pieces`
    equal pieces and the non-decreasing sequence of pieces with the least summed score is chosen:
    distance + `penalty` x how far it exceeds the point's tolerance there (`allowed` + `chord_allowance`
    x the segment's reach: its chord, or `speed` x its interval if longer). Pieces, not whole segments,
    so that the points before and after a reversal inside one chord cannot share it out of order
    (the running maximum afterwards would drag the later ones back to the tip). The distance returned,
    and judged against the tolerance, is the one from the whole chord."""
    k = max(1, int(pieces))
    seg = np.repeat(np.arange(j0, j1 + 1), k)
    frac = np.tile(np.arange(k) / k, j1 - j0 + 1)
    x0, y0, z0, dx, dy, dz = (a[seg] for a in path.cols)
    c = cl[run]
    uu, dd = project_cols(c[:, 0:1], c[:, 1:2], c[:, 2:3], x0 + frac * dx, y0 + frac * dy, z0 + frac * dz,
                          dx / k, dy / k, dz / k, path.dd[seg] / (k * k))
    reach = path.seg_len[seg][None, :]
    if speed is not None:
        reach = np.maximum(reach, speed[run][:, None] * path.seg_dt[seg][None, :])
    excess = np.maximum(dd - allowed[run][:, None] - chord_allowance * reach, 0.0)
    best = monotone_path(dd + penalty * excess)
    rows = np.arange(len(run))
    # the distance returned (and judged against the tolerance) is the one from the whole chord: where
    # the tool turned back inside one interval, the chord cannot order the points before and after the
    # turn, so a point held behind its foot by the order of the pieces is still as close as its foot
    _, d_chord = project_cols(c[:, 0:1], c[:, 1:2], c[:, 2:3], *(a[seg[best]][:, None] for a in path.cols),
                              path.dd[seg[best]][:, None])
    return seg[best], frac[best] + uu[rows, best] / k, d_chord[:, 0]


def untangle(cl: np.ndarray, s_prog: np.ndarray, order: np.ndarray, seg: np.ndarray, u: np.ndarray,
             dist: np.ndarray, path: Path, *, weight: float, min_mm: float, max_cells: int = 1_000_000) -> int:
    """Re-match runs of points whose matches contradict monotone progress; updates seg, u, dist in place
    and returns how many points it re-matched.

    The chunk search predicts each point's measured length S from an anchor up to a chunk away; where
    blends make the measured path shorter than predicted, a point just before a hairpin of short blocks
    can win on the pass coming back (as close, nearer the prediction), and a running maximum would then
    drag the points after it there too. A conflict is a run of points (in program order `order`) where
    some point lies more than `min_mm` of S beyond a later one. Each run is matched again as a whole
    between the points around it (which agree with everything before and after): every point projected
    onto every segment in between, scored by distance + weight x |S - prediction| with the prediction
    interpolated in program length between those two points, and the best non-decreasing sequence of
    segments chosen by dynamic programming (a running minimum per point). Runs wider than `max_cells`
    point x segment pairs are left to the running maximum."""
    k = order[seg[order] >= 0]
    if len(k) < 3:
        return 0
    sv, sv_len = path.sv, path.sv_len
    S = sv[seg[k]] + u[k] * sv_len[seg[k]]
    conflict = np.maximum.accumulate(S) > np.minimum.accumulate(S[::-1])[::-1] + min_mm
    conflict[0] = False  # the start (earliest passage) stays
    edges = np.flatnonzero(np.diff(np.concatenate([[0], conflict.astype(np.int8), [0]])))
    redone = 0
    for a, b in zip(edges[::2], edges[1::2]):
        kb = k[a - 1]
        j0 = int(seg[kb])
        if b < len(k):
            ka = k[b]
            j1 = int(seg[ka])
            span_s = s_prog[ka] - s_prog[kb]
            ratio = (S[b] - S[a - 1]) / span_s if span_s > 0 else 1.0
        else:  # a run at the end: up to the farthest of its own matches
            j1, ratio = int(seg[k[a:b]].max()), 1.0
        j1 = max(j1, j0)
        run = k[a:b]
        if (j1 - j0 + 1) * len(run) > max_cells:
            continue
        pred = S[a - 1] + ratio * (s_prog[run] - s_prog[kb])
        uu, dd = project_gathered(cl[run], slice(j0, j1 + 1), path)
        score = dd + weight * np.abs(sv[j0:j1 + 1] + uu * sv_len[j0:j1 + 1] - pred[:, None])
        best = monotone_path(score)
        rows = np.arange(len(run))
        seg[run] = j0 + best
        u[run] = uu[rows, best]
        dist[run] = dd[rows, best]
        redone += len(run)
    return redone
