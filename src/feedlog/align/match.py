"""Constrained nearest-point matching of the program's cutter-location (CL) points to the measured path.

Sun et al. (2022, §2.2) give each CL point the measured feed of the closest measured point. Plain
nearest-neighbour search breaks on programs that pass the same place twice (pocket rings, zig-zags,
crossings, a finishing pass over a roughing pass): the closest sample may belong to another pass. Here
every CL point is projected onto the measured *polyline* (segments between consecutive samples, so that
5 Hz data with one sample every few mm still matches within the path tolerance), and the search is
constrained to progress along the program:

1. The measured path is reduced to vertices at least `resolution_mm` of path length apart (standstill
   and dwell collapse to their first and last sample; nothing moves between them), and its cumulative
   length S is computed. Steps 2-3 search a coarser copy (`coarse_mm`); every match is then refined on
   the fine path within its coarse segment and the two next to it.
2. The first CL point that the tool reaches fixes the start: the *earliest* passage within `tol_mm`.
3. CL points are then processed in order, in chunks (`chunk_points`, `chunk_mm`). The anchor is the last
   well-matched point of the previous chunk. CL point k, ds = s_k - s_anchor of program ahead of it, may
   only match measured segments whose length coordinate S lies in a window: for sparse data (sampling
   period > `sparse_ns`) [S_anchor - W, S_anchor + (1 + drift) ds + W] (W = `window_mm`), since sampled
   chords across wiggles can make the measured path much shorter than the program but not much longer;
   for dense data S_pred +- (W + drift ds), since the path follows the program up to blends. A pass that
   comes back to the same place later lies beyond the window. Inside it the candidate with the least
   distance + progress_weight x |S - S_pred| wins, S_pred = S_anchor + r ds with r the measured/programmed
   length ratio of the last chunk; this separates a line retraced right after a reversal (equally close,
   far apart in progress) and never moves the foot point on a straight stretch (weight < 1). A best
   candidate on the window's edge means the window was too small: it is widened (up to MAX_WIDEN times).
   Blends make the measured path shorter than the program, so the prediction may run ahead of the tool;
   before a hairpin of very short blocks the pass coming back is then as close and nearer the prediction.
   Runs of matches that contradict monotone progress by more than `coarse_mm` are therefore matched
   again together (`chunks.untangle`): between the agreeing matches around them, with the prediction
   interpolated between those two, as the best non-decreasing sequence (dynamic programming).
4. After the refinement every match of dense data slides downhill along the fine path to the closest
   point of its passage (the progress term chose the passage but, beside a straight stretch or on a
   corner blend, also pulls the foot point towards the prediction). Then progress is made monotone (a running maximum over
   the matched positions); a point pushed forward is re-measured at its new position.

Every match returns the fractional sample index, the time (interpolated between samples) and the
distance. Points farther than their tolerance (among those checked) raise `AlignmentError` listing the
worst. The tolerance is `tol_mm` (or the per-point `tolerance`) plus `chord_allowance` x the reach of
the sampling interval the point matched in: the sampled chord's length, or (when `speed_mm_s` is given)
the programmed speed x the interval, if longer. Between two samples the tool travels at most that far,
so it may leave the chord by up to half of it (a corner, a reversal tip); sparse data (5 Hz, several mm
per sample) is judged fairly and dense data keeps a tight tolerance.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from feedlog.align.chunks import (TIE_MM, WHOLE_PIECES, Path, Search, project_cols, project_gathered, rematch_whole,
                                  search_chunks, untangle)
from feedlog.errors import AlignmentError


@dataclass(frozen=True)
class MatchConfig:
    tol_mm: float = 0.1            # largest allowed CL-point-to-measured-path distance
    window_mm: float | None = None  # base half-window in path length; None: max(0.5 mm dense / 2 mm
                                    # sparse, 3 x sample spacing, 4 x tolerance)
    drift: float | None = None     # extra window per mm of program since the anchor; None: 0.2 sparse,
                                   # 0.05 dense
    progress_weight: float = 0.25  # mm of score per mm of distance from the predicted progress
    chunk_points: int = 256        # CL points per chunk
    chunk_mm: float | None = None  # program length per chunk (at least one point); None: 25 mm dense,
                                   # 50 mm sparse
    sparse_ns: int = 5_000_000     # sampling period above which the data count as sparse
    resolution_mm: float = 1e-3    # vertex spacing of the reduced measured path
    coarse_mm: float = 0.05        # vertex spacing of the path the search runs on (then refined)
    still_mm: float = 1e-6         # path length below which the tool has not left a point (departure)
    chord_allowance: float = 0.5   # tolerance += this x the matched sampled chord (a chord cuts corners)
    # sparse data: match all points at once after the chunk search ("always", see rematch_whole) or keep
    # the chunk search's matches ("off")
    sparse_whole: str = "always"
    whole_cells: int = 2_000_000   # largest point x piece table at once for that (longer programs: in groups)

    def __post_init__(self) -> None:
        if not self.tol_mm > 0:
            raise AlignmentError(f"tol_mm must be > 0, got {self.tol_mm}")
        if self.sparse_whole not in ("always", "off"):
            raise AlignmentError(f"sparse_whole must be 'always' or 'off', got {self.sparse_whole!r}")
        if self.window_mm is not None and not self.window_mm > 0:
            raise AlignmentError(f"window_mm must be > 0, got {self.window_mm}")
        if self.drift is not None and not 0 <= self.drift < 1:
            raise AlignmentError(f"drift must be in [0, 1), got {self.drift}")
        if not 0 <= self.progress_weight < 1:
            raise AlignmentError(f"progress_weight must be in [0, 1), got {self.progress_weight}")
        if self.chunk_points < 1 or not (self.chunk_mm is None or self.chunk_mm > 0):
            raise AlignmentError(f"chunk_points >= 1 and chunk_mm > 0 needed, got {self.chunk_points}, {self.chunk_mm}")
        if not self.chord_allowance >= 0:
            raise AlignmentError(f"chord_allowance must be >= 0, got {self.chord_allowance}")
        if not self.still_mm >= 0:
            raise AlignmentError(f"still_mm must be >= 0, got {self.still_mm}")
        if not self.coarse_mm >= self.resolution_mm:
            raise AlignmentError(f"coarse_mm ({self.coarse_mm}) must be >= resolution_mm ({self.resolution_mm})")
        if not self.resolution_mm > 0:
            raise AlignmentError(f"resolution_mm must be > 0, got {self.resolution_mm}")


@dataclass
class Match:
    """Per CL point: where on the measured path it matched."""

    index: np.ndarray      # fractional index into the measured samples (NaN: unmatched)
    t_ns: np.ndarray       # matched time, int64 (min int64 where unmatched)
    dist_mm: np.ndarray    # distance CL point -> measured path (NaN: unmatched)
    s_meas_mm: np.ndarray  # measured path length at the match
    nearest: np.ndarray    # nearest measured sample index (int64, -1: unmatched)
    t_depart_ns: np.ndarray  # when the tool left the point again (> t_ns after a stop or dwell)
    chord_mm: np.ndarray | None = None  # what the sampled chord may cut off at the point (in its tolerance)

    @property
    def matched(self) -> np.ndarray:
        return np.isfinite(self.index)


NO_TIME = np.iinfo(np.int64).min
REFINE_ROWS = 256  # CL points per refinement batch
WHOLE_MARGIN = 25  # segments past the chunk search's farthest match that a group of _match_whole spans
WHOLE_MIN_GROUP = 64  # points per group at least (fewer: each group's choice becomes greedy)
DESCENT_HOP = 4    # fine segments a match looks either way per step of its walk to its closest point
DESCENT_HOPS = 8   # steps at most


def path_length(positions: np.ndarray) -> np.ndarray:
    """Cumulative chord length (n,) of an (n, k) polyline from 0, column by column (same values as
    summing the squared differences over each row)."""
    p = np.asarray(positions, dtype=np.float64)
    sq = np.zeros(len(p) - 1 if len(p) else 0)
    for i in range(p.shape[1]):
        di = np.diff(p[:, i])
        sq = di * di if i == 0 else sq + di * di
    s = np.empty(len(p))
    if len(p):
        s[0] = 0.0
        np.cumsum(np.sqrt(sq), out=s[1:])
    return s


def reduce_path(positions: np.ndarray, resolution_mm: float, period_s: float | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """Indices of vertices at least ~resolution_mm of path length apart (first and last sample of every
    bin kept, so standstills keep their start and end) and the cumulative length at every sample.

    With `period_s` of dense data, the steps of a standstill that are only sensor noise add no length
    (`noise_steps`): a tool change or a feed hold of seconds at 1 kHz would otherwise lay millimetres
    of jitter into the path length, and the progress window of the next points would miss the tool."""
    p = np.asarray(positions, dtype=np.float64)
    still = noise_steps(p, period_s) if period_s is not None else None
    if still is None:
        s = path_length(p)
    else:
        step = np.sqrt((np.diff(p, axis=0) ** 2).sum(axis=1))
        step[still] = 0.0
        s = np.concatenate([[0.0], np.cumsum(step)])
    b = np.floor(s / resolution_mm)  # whole numbers: compared as floats, no integer copy
    keep = np.zeros(len(s), dtype=bool)
    keep[0] = keep[-1] = True
    change = b[1:] != b[:-1]
    keep[1:] |= change
    keep[:-1] |= change
    return np.flatnonzero(keep), s


NOISE_WINDOW_S = 0.02   # a standstill is a window this long whose samples stay within the noise band
NOISE_BAND = 8.0        # band: this many noise sigmas per axis (a 21-sample range of Gaussian noise is ~4)
DENSE_S = 0.005


def noise_steps(p: np.ndarray, period_s: float) -> np.ndarray | None:
    """Steps (n-1,) between two samples of a standstill whose motion is only noise, or None when the
    data are sparse, short or noise-free. The noise sigma per axis comes from the median absolute
    second difference (at a dense rate the path's own curvature is far below it on cruise and rest)."""
    if not period_s or period_s > DENSE_S or len(p) < 50:
        return None
    d2 = np.diff(p, n=2, axis=0)
    sigma = 1.4826 * np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0) / np.sqrt(6.0)
    if not (sigma > 0).any():
        return None
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    w = max(5, int(round(NOISE_WINDOW_S / period_s))) | 1
    spread = maximum_filter1d(p, w, axis=0, mode="nearest") - minimum_filter1d(p, w, axis=0, mode="nearest")
    still = (spread <= NOISE_BAND * sigma).all(axis=1)
    return still[:-1] & still[1:]


def _bin_edges(s: np.ndarray, step: float) -> np.ndarray:
    """Indices of the first and last element of every `step`-wide bin of the non-decreasing `s`."""
    b = np.floor(s / step)
    keep = np.zeros(len(s), dtype=bool)
    keep[0] = keep[-1] = True
    change = b[1:] != b[:-1]
    keep[1:] |= change
    keep[:-1] |= change
    return np.flatnonzero(keep)


def _path_on(pos: np.ndarray, t: np.ndarray, keep: np.ndarray, s_full: np.ndarray) -> Path:
    """The measured path through the samples `keep` as segment columns (see `chunks.Path`)."""
    vx, vy, vz = pos[keep, 0], pos[keep, 1], pos[keep, 2]
    dx, dy, dz = np.diff(vx), np.diff(vy), np.diff(vz)
    dd = dx * dx + dy * dy + dz * dz
    sv = s_full[keep]
    seg_dt = np.diff(t[keep]) / 1e9  # sampling interval each segment spans (s), outliers capped
    if len(seg_dt):
        seg_dt = np.minimum(seg_dt, 10 * max(float(np.median(seg_dt)), 1e-9))
    return Path(cols=(vx[:-1], vy[:-1], vz[:-1], dx, dy, dz), dd=dd, seg_len=np.sqrt(dd), sv=sv, sv_len=np.diff(sv),
                seg_dt=seg_dt)


def _match_whole(cl: np.ndarray, rest: np.ndarray, j0: int, found: np.ndarray, path: Path, allowed: np.ndarray,
                 speed: np.ndarray | None, cfg: MatchConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`chunks.rematch_whole` over all of `rest` in groups that keep each point x piece table within
    `cfg.whole_cells`: each group spans the segments from where the previous one ended to
    `WHOLE_MARGIN` segments past the farthest match the chunk search `found` for it; only its first
    three quarters are kept, the rest is matched again at the head of the next group."""
    n, last = len(rest), path.nseg - 1
    seg, u, dist = np.empty(n, dtype=np.int64), np.empty(n), np.empty(n)
    reach_max = np.maximum.accumulate(np.where(found >= 0, found, 0))
    i, group = 0, n
    while i < n:
        g = min(group, n - i)
        j1 = min(last, int(reach_max[i + g - 1]) + WHOLE_MARGIN)
        if g > WHOLE_MIN_GROUP and g * (j1 - j0 + 1) * WHOLE_PIECES > cfg.whole_cells:
            group = max(WHOLE_MIN_GROUP, g // 2)
            continue
        s_g, u_g, d_g = rematch_whole(cl, rest[i:i + g], j0, max(j1, j0), path, allowed, speed,
                                      chord_allowance=cfg.chord_allowance)
        keep = g if i + g == n else max(1, (3 * g) // 4)
        seg[i:i + keep], u[i:i + keep], dist[i:i + keep] = s_g[:keep], u_g[:keep], d_g[:keep]
        j0 = int(s_g[keep - 1])
        i += keep
    return seg, u, dist


def _refine(cl, m, seg_of, u_of, sv_c, s_full, fine_keep, pos, weight):
    """Move matches from the coarse path onto the fine one: each point is projected onto the fine
    segments spanning its coarse segment and the neighbouring two; the least distance +
    weight x |S - coarse S| wins (earliest on ties), so a retraced neighbour never steals the match."""
    ks = np.flatnonzero(m)
    j = seg_of[ks]
    s_coarse = sv_c[j] + u_of[ks] * (sv_c[np.minimum(j + 1, len(sv_c) - 1)] - sv_c[j])
    lo_s = sv_c[np.maximum(j - 1, 0)]
    hi_s = sv_c[np.minimum(j + 2, len(sv_c) - 1)]
    fs = s_full[fine_keep]
    nf = len(fine_keep) - 1
    lo = np.clip(np.searchsorted(fs, lo_s, side="left") - 1, 0, nf - 1)
    hi = np.clip(np.searchsorted(fs, hi_s, side="right"), 0, nf - 1)
    seg_new = np.full(len(seg_of), -1, dtype=np.int64)
    u_new = np.full(len(seg_of), np.nan)
    d_new = np.full(len(seg_of), np.nan)
    width = hi - lo + 1
    order = np.argsort(width)
    px, py, pz = pos[:, 0], pos[:, 1], pos[:, 2]
    # rows sorted by window width, in parts of a few hundred: each part pads only to its own widest row
    for part in np.array_split(order, max(1, len(order) // REFINE_ROWS, int(width.sum()) // 1_000_000 + 1)):
        if not len(part):
            continue
        band = int(width[part].max())
        idx = lo[part, None] + np.arange(band)[None, :]
        valid = idx <= hi[part, None]
        idx = np.minimum(idx, nf - 1)
        u, dk = _project_fine(cl[ks[part]], px, py, pz, fine_keep[idx], fine_keep[idx + 1])
        dk = np.where(valid, dk, np.inf)
        score = dk + weight * np.abs(fs[idx] + u * (fs[idx + 1] - fs[idx]) - s_coarse[part, None])
        best = np.argmax(score <= score.min(axis=1, keepdims=True) + TIE_MM, axis=1)
        rows = np.arange(len(part))
        seg_new[ks[part]] = idx[rows, best]
        u_new[ks[part]] = u[rows, best]
        d_new[ks[part]] = dk[rows, best]
    return fine_keep, seg_new, u_new, d_new


def _project_fine(c: np.ndarray, px: np.ndarray, py: np.ndarray, pz: np.ndarray, a: np.ndarray, b: np.ndarray):
    """`project_cols` of points c (k, 3) onto the fine segments from samples a (k, m) to samples b."""
    x0, y0, z0 = px[a], py[a], pz[a]
    dx, dy, dz = px[b] - x0, py[b] - y0, pz[b] - z0
    return project_cols(c[:, 0:1], c[:, 1:2], c[:, 2:3], x0, y0, z0, dx, dy, dz, dx * dx + dy * dy + dz * dz)


def _descend(cl, m, keep, seg_of, u_of, dist, pos, *, min_gain: float, hop: int = DESCENT_HOP,
             hops: int = DESCENT_HOPS) -> None:
    """Slide every match along the fine path to the nearest local minimum of its distance (in place).

    The progress term of the search picks the passage; on a curved one (a corner blend) or for a point
    beside the path it also pulls the foot point towards the predicted progress, off the closest point.
    Walking downhill from the chosen point never crosses the distance maximum between two passes, so the
    passage stays and the match becomes the place where the tool passes the point most closely. The walk
    looks `hop` segments either way at a time; matches still going downhill at the edge walk on, at
    most `hops` times. A step must gain more than `min_gain` (the path's resolution): sub-micrometre
    wiggles while the tool stands (a five-axis exact stop turning A/C) keep the arrival."""
    ks = np.flatnonzero(m)
    nf = len(keep) - 1
    offs = np.arange(-hop, hop + 1)
    for _ in range(hops):
        if not len(ks):
            return
        idx = np.minimum(np.maximum(seg_of[ks, None] + offs[None, :], 0), nf - 1)
        u, dk = _project_fine(cl[ks], pos[:, 0], pos[:, 1], pos[:, 2], keep[idx], keep[idx + 1])
        # steps that go strictly downhill, counted from the match's own segment outwards
        right = np.cumprod(dk[:, hop + 1:] < dk[:, hop:-1] - TIE_MM, axis=1).sum(axis=1)
        left = np.cumprod((dk[:, :hop] < dk[:, 1:hop + 1] - TIE_MM)[:, ::-1], axis=1).sum(axis=1)
        step = np.where(right > 0, right, -left)
        col = hop + step
        rows = np.arange(len(ks))
        moved = dk[rows, col] < dist[ks] - min_gain  # (also: closer inside its own segment)
        r = np.flatnonzero(moved)
        seg_of[ks[r]] = idx[r, col[r]]
        u_of[ks[r]] = u[r, col[r]]
        dist[ks[r]] = dk[r, col[r]]
        ks = ks[moved & (np.abs(step) == hop)]


class _LazySegments:
    """p0[j] (segment start) or d[j] (segment vector) of the path keep[j] -> keep[j + 1], on demand."""

    def __init__(self, pos: np.ndarray, keep: np.ndarray, *, start: bool) -> None:
        self.pos, self.keep, self.start = pos, keep, start

    def __getitem__(self, j):
        a = self.pos[self.keep[j]]
        return a if self.start else self.pos[self.keep[np.asarray(j) + 1]] - a


class _LazyLength:
    def __init__(self, pos: np.ndarray, keep: np.ndarray) -> None:
        self.d = _LazySegments(pos, keep, start=False)

    def __getitem__(self, j):
        v = self.d[j]
        return np.sqrt((v * v).sum(axis=-1))


class _LazyDiff:
    def __init__(self, values: np.ndarray) -> None:
        self.values = values

    def __getitem__(self, j):
        j = np.asarray(j)
        return self.values[j + 1] - self.values[j]


def _first_passage(c: np.ndarray, tol: float, path: Path):
    """(segment, u, distance) of the closest point of the earliest passage of the path within `tol` of
    point c, or None. Scans the path from its start in growing blocks (the start is usually early)."""
    n = path.nseg
    lo, size = 0, 4096
    while lo < n:
        hi = min(n, lo + size)
        u, dk = project_gathered(c, slice(lo, hi), path)
        near = np.flatnonzero(dk <= tol)
        if len(near):
            j = int(near[0])
            end = j  # the passage goes on while within tol; extend the block if it runs past it
            while True:
                out = np.flatnonzero(dk[j:] > tol)
                if len(out) or hi == n:
                    end = j + (int(out[0]) if len(out) else len(dk) - j)
                    break
                hi2 = min(n, hi + size)
                u2, dk2 = project_gathered(c, slice(hi, hi2), path)
                u, dk, hi = np.concatenate([u, u2]), np.concatenate([dk, dk2]), hi2
            best = j + int(np.argmin(dk[j:end]))
            return lo + best, float(u[best]), float(dk[best])
        lo, size = hi, size * 2
    return None


def match_cl_points(cl_xyz: np.ndarray, t_ns: np.ndarray, positions: np.ndarray, *,
                    s_mm: np.ndarray | None = None, config: MatchConfig | None = None,
                    tolerance: np.ndarray | None = None, check: np.ndarray | None = None,
                    labels: Sequence[str] | None = None, speed_mm_s: np.ndarray | None = None,
                    period_ns: int | None = None) -> Match:
    """Match ordered CL points (k, 3) to the measured path (`t_ns` (n,), `positions` (n, 3)).

    `s_mm`: the program's cumulative length at each CL point (default: chord length of `cl_xyz`).
    `tolerance`: per-point tolerance in mm (default `config.tol_mm` everywhere), e.g. widened by a
    block's G64 P blending tolerance. `check`: which points the tolerance applies to (default all finite
    ones); `labels` name points in the error message (e.g. "block 12 (line 40)"); `speed_mm_s`: the
    programmed speed at each point, which bounds how far the tool can stray between two samples;
    `period_ns`: the sampling period when the caller knows it (default: median interval).
    """
    cfg = config or MatchConfig()
    cl = np.asarray(cl_xyz, dtype=np.float64)
    pos = np.asarray(positions, dtype=np.float64)
    t = np.asarray(t_ns, dtype=np.int64)
    k_all = len(cl)
    if len(pos) != len(t):
        raise AlignmentError(f"{len(t)} timestamps but {len(pos)} positions")
    if len(pos) < 2:
        raise AlignmentError(f"the measured path needs at least 2 samples, got {len(pos)}")
    finite_cl = np.isfinite(cl).all(axis=1)
    if s_mm is None:
        seg = np.sqrt((np.diff(np.where(finite_cl[:, None], cl, 0.0), axis=0) ** 2).sum(axis=1))
        seg[~(finite_cl[1:] & finite_cl[:-1])] = 0.0
        s_mm = np.concatenate([[0.0], np.cumsum(seg)])
    s_prog = np.asarray(s_mm, dtype=np.float64)
    tol = np.full(k_all, float(cfg.tol_mm)) if tolerance is None else np.broadcast_to(
        np.asarray(tolerance, dtype=np.float64), (k_all,)).copy()
    if not (tol > 0).all():
        raise AlignmentError(f"tolerances must be > 0 mm, got min {np.nanmin(tol)}")

    if period_ns is None:
        dt_all = np.diff(t)
        period = int(np.median(dt_all[dt_all > 0])) if (dt_all > 0).any() else 0
    else:
        period = int(period_ns)
    fine_keep, s_full = reduce_path(pos, cfg.resolution_mm, period / 1e9)
    # search on a coarse copy of the path (vertices >= coarse_mm apart), refine on the fine one
    keep = fine_keep[_bin_edges(s_full[fine_keep], cfg.coarse_mm)]
    coarse = _path_on(pos, t, keep, s_full)
    sv, sv_len, nseg = coarse.sv, coarse.sv_len, coarse.nseg
    spacing = float(np.median(sv_len)) if nseg else 0.0
    sparse = period > cfg.sparse_ns
    w_min = 2.0 if sparse else 0.5
    w0 = cfg.window_mm if cfg.window_mm is not None else max(w_min, 3.0 * spacing, 4.0 * float(tol.max()))
    chunk_mm = cfg.chunk_mm if cfg.chunk_mm is not None else (50.0 if sparse else 25.0)
    drift = cfg.drift if cfg.drift is not None else (0.2 if sparse else 0.05)

    seg_of = np.full(k_all, -1, dtype=np.int64)
    u_of = np.full(k_all, np.nan)
    dist = np.full(k_all, np.nan)

    # 2. start: the earliest passage of the first reachable CL point within tolerance
    order = np.flatnonzero(finite_cl)
    start = None
    for k in order[: min(len(order), 64)]:
        found = _first_passage(cl[k], tol[k], coarse)
        if found is not None:
            seg_of[k], u_of[k], dist[k] = found
            start = k
            break
    if start is None:
        raise AlignmentError(f"the measured path never comes within {tol[order[0]] if len(order) else cfg.tol_mm:g} mm "
                             "of the program's first "
                             f"points (e.g. {np.round(cl[order[0]], 3).tolist() if len(order) else '-'}); wrong "
                             "program, units or work offset?")
    anchor_s, anchor_S = s_prog[start], sv[seg_of[start]] + u_of[start] * sv_len[seg_of[start]]
    speed = None if speed_mm_s is None else np.nan_to_num(np.asarray(speed_mm_s, dtype=np.float64), nan=0.0)

    # 3. chunks of CL points after the start (`chunks`)
    rest = order[order > start]
    search = Search(w0=w0, drift=drift, sparse=sparse, weight=cfg.progress_weight,
                    chord_allowance=cfg.chord_allowance, chunk_points=cfg.chunk_points, chunk_mm=chunk_mm)
    seg_of[rest], u_of[rest], dist[rest] = search_chunks(cl, s_prog, tol, speed, rest, coarse, search,
                                                         anchor_s=float(anchor_s), anchor_S=float(anchor_S))
    # 3b. runs of matches that contradict monotone progress (a hairpin's far side) matched again together
    untangle(cl, s_prog, order, seg_of, u_of, dist, coarse, weight=cfg.progress_weight, min_mm=cfg.coarse_mm)
    # refine every match on the fine path, around its coarse segment and the two next to it
    m = seg_of >= 0
    if m.any():
        keep, seg_of, u_of, dist = _refine(cl, m, seg_of, u_of, sv, s_full, fine_keep, pos, cfg.progress_weight)
        if not sparse:  # sparse samples are long chords: a walk over them may leave the passage
            _descend(cl, m, keep, seg_of, u_of, dist, pos, min_gain=cfg.resolution_mm)
        sv = s_full[keep]
        nseg = len(keep) - 1
        # fine segment geometry, gathered only where needed
        p0 = _LazySegments(pos, keep, start=True)
        d = _LazySegments(pos, keep, start=False)
        seg_len = _LazyLength(pos, keep)
        sv_len = _LazyDiff(sv)

    # 3c. sparse data: the whole program matched at once on the fine path (the chunk search's prediction
    # of measured length runs ahead of the tool on zig-zags sampled at 5 Hz)
    if sparse and cfg.sparse_whole == "always" and len(rest) and m[start]:
        checked0 = finite_cl if check is None else (np.asarray(check, dtype=bool) & finite_cl)
        seg_of[rest], u_of[rest], dist[rest] = _match_whole(
            cl, rest, int(seg_of[start]), seg_of[rest], _path_on(pos, t, keep, s_full),
            np.where(checked0, tol, np.inf), speed, cfg)
        m = seg_of >= 0

    # 4. monotone progress
    frac = np.where(m, seg_of + np.nan_to_num(u_of), np.nan)
    mono = frac.copy()
    mono[m] = np.maximum.accumulate(frac[m])
    pushed = m & (mono > frac)
    if pushed.any():
        j = np.minimum(np.floor(mono[pushed]).astype(np.int64), nseg - 1)
        j = np.where(mono[pushed] <= seg_of[pushed] + 1, seg_of[pushed], j)  # the end of its own segment
        uu = mono[pushed] - j
        q = p0[j] + uu[:, None] * d[j]
        moved = np.sqrt(((cl[pushed] - q) ** 2).sum(axis=1))
        # sparse data: a point pushed along its own sampled chord keeps its distance from it. Where the
        # tool turned back within one interval (a U-turn, a reversal tip) the chord cannot order the
        # points before and after the turn; the push only keeps times monotone.
        same = (j == seg_of[pushed]) if sparse else np.zeros(len(j), dtype=bool)
        dist[pushed] = np.where(same, dist[pushed], moved)
        seg_of[pushed], u_of[pushed] = j, uu

    # map reduced segments back to samples and times
    index = np.full(k_all, np.nan)
    t_match = np.full(k_all, NO_TIME, dtype=np.int64)
    s_meas = np.full(k_all, np.nan)
    nearest = np.full(k_all, -1, dtype=np.int64)
    depart = np.full(k_all, NO_TIME, dtype=np.int64)
    if m.any():
        j, uu = seg_of[m], u_of[m]
        a, b = keep[j], keep[j + 1]
        # inside a reduced segment the path is (nearly) straight: locate by length, not by sample count
        s_at = sv[j] + uu * sv_len[j]
        sub = np.searchsorted(s_full, s_at, side="left") - 1
        sub = np.clip(np.maximum(sub, a), a, np.maximum(b - 1, a))
        span = s_full[sub + 1] - s_full[sub] if len(s_full) > 1 else np.zeros(len(sub))
        f = np.where(span > 0, (s_at - s_full[sub]) / np.where(span > 0, span, 1.0), 0.0)
        f = np.clip(f, 0.0, 1.0)
        index[m] = sub + f
        t_match[m] = t[sub] + np.rint(f * (t[np.minimum(sub + 1, len(t) - 1)] - t[sub])).astype(np.int64)
        s_meas[m] = s_at
        nearest[m] = np.where(f < 0.5, sub, np.minimum(sub + 1, len(t) - 1))
        # departure: the last sample still within still_mm of path length of the match
        last_here = np.searchsorted(s_full, s_at + cfg.still_mm, side="right") - 1
        depart[m] = np.maximum(t_match[m], t[np.clip(last_here, 0, len(t) - 1)])
    result = Match(index=index, t_ns=t_match, dist_mm=dist, s_meas_mm=s_meas, nearest=nearest,
                   t_depart_ns=depart)

    checked = finite_cl if check is None else (np.asarray(check, dtype=bool) & finite_cl)
    # a sampled path is a chord polygon: between two samples it may cut a corner by up to half the chord
    if m.any() and cfg.chord_allowance > 0:
        reach = seg_len[seg_of[m]]
        if speed_mm_s is not None:
            sub_i = np.floor(index[m]).astype(np.int64)
            dt = (t[np.minimum(sub_i + 1, len(t) - 1)] - t[sub_i]) / 1e9
            sp = np.nan_to_num(np.asarray(speed_mm_s, dtype=np.float64)[m], nan=0.0)
            reach = np.maximum(reach, sp * dt)
        tol[m] += cfg.chord_allowance * reach
        result.chord_mm = np.zeros(k_all)
        result.chord_mm[m] = cfg.chord_allowance * reach
    bad = checked & ~(dist <= tol)
    if bad.any():
        raise AlignmentError(violation_message(np.flatnonzero(bad), dist, cl, tol, labels))
    return result


def violation_message(bad: np.ndarray, dist: np.ndarray, cl: np.ndarray, tol: np.ndarray,
                      labels: Sequence[str] | None, worst: int = 5) -> str:
    d = np.where(np.isfinite(dist[bad]), dist[bad], np.inf)
    order = bad[np.argsort(-d)][:worst]
    parts = []
    for k in order:
        name = labels[k] if labels is not None else f"CL point {k}"
        dk = "unmatched" if not np.isfinite(dist[k]) else f"{dist[k]:.4f} mm"
        parts.append(f"{name} at ({cl[k, 0]:.3f}, {cl[k, 1]:.3f}, {cl[k, 2]:.3f}): {dk} (tol {tol[k]:g} mm)")
    return (f"{len(bad)} of the program's CL points are farther than their tolerance from the measured path; "
            f"worst: " + "; ".join(parts))
