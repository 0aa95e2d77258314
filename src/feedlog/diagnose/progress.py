"""Progress along the program: how far along the programmed path each position sample is.

Sparse data (a 5 Hz monitoring box) sees the tool a few millimetres apart. When did it finish a
block? Every sample is projected onto the program's cutter-location polyline (`toolpath.cl_points`,
the points align matched), near where the timing says it is (the CL points whose times bracket it,
and two more segments either side), and its arc length there is its *progress* (made monotone). The
time a block ended is when the progress reached the block's end, interpolated between the two
samples around it. Unlike "the sample chord closest to the end point", this does not jump a whole
sampling period when a corner is cut and two chords are about equally close.

The same function serves the recording (CL times from align's match) and a simulation sampled at
the recording's own instants (CL times from the simulated block times), so both are measured alike.
"""

from __future__ import annotations

import numpy as np

WINDOW = 2  # CL segments searched either side of the bracketing one


def sample_progress(t: np.ndarray, pos: np.ndarray, cl_xyz: np.ndarray, cl_s: np.ndarray,
                    cl_t: np.ndarray) -> np.ndarray:
    """Arc length along the CL polyline of each sample (n,) at times `t`, positions `pos` (n, 3).
    `cl_t` (ascending, finite) say roughly when each CL point was passed: each sample is searched on the
    CL segments passed within a sampling period of it (CL times matched to sparse samples are those
    samples' times, so a short block's points all carry one of them), and `WINDOW` segments either side."""
    m, n = len(cl_xyz), len(t)
    if m < 2 or n == 0:
        return np.zeros(n)
    period = float(np.median(np.diff(t))) if n > 1 else 0.0
    k = np.clip(np.searchsorted(cl_t, t) - 1, 0, m - 2)
    lo = np.clip(np.minimum(k - WINDOW, np.searchsorted(cl_t, t - period, side="left") - 1), 0, m - 2)
    hi = np.clip(np.maximum(k + WINDOW, np.searchsorted(cl_t, t + period, side="right")), 0, m - 2)
    best_s = np.zeros(n)
    best_d = np.full(n, np.inf)
    for off in range(int((hi - lo).max()) + 1):
        kk = np.minimum(lo + off, hi)
        a, b = cl_xyz[kk], cl_xyz[kk + 1]
        ab = b - a
        den = np.einsum("ij,ij->i", ab, ab)
        f = np.clip(np.einsum("ij,ij->i", pos - a, ab) / np.where(den > 0, den, 1.0), 0.0, 1.0)
        d = np.einsum("ij,ij->i", a + f[:, None] * ab - pos, a + f[:, None] * ab - pos)
        s = cl_s[kk] + f * (cl_s[kk + 1] - cl_s[kk])
        better = d < best_d
        best_s, best_d = np.where(better, s, best_s), np.where(better, d, best_d)
    return np.maximum.accumulate(best_s)


def crossing_times(t: np.ndarray, s: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """When the (monotone) progress `s` reached each target arc length, linearly between samples."""
    keep = np.concatenate([[True], np.diff(s) > 1e-9])
    return np.interp(targets, s[keep], t[keep])


def block_end_progress(cl_block: np.ndarray, cl_s: np.ndarray, blocks: np.ndarray) -> np.ndarray:
    """Arc length at the end of each block (its last CL point)."""
    rev = cl_block[::-1]
    ids, first = np.unique(rev, return_index=True)
    last = len(rev) - 1 - first
    at = np.clip(np.searchsorted(ids, blocks), 0, len(ids) - 1)
    return np.where(ids[at] == blocks, cl_s[last[at]], np.nan)
