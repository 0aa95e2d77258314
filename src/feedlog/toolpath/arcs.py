"""Arc geometry in the three planes, vectorised over many arcs at once.

A plane is described by its in-plane axes (u, v) and its normal w, ordered right-handed so that
counter-clockwise (G3) is counter-clockwise seen from +w, as in RS274/NGC:
G17: (x, y), normal z;  G18: (z, x), normal y;  G19: (y, z), normal x.
Arcs move along the circle in (u, v) and linearly along w (helical arcs); the centre's w coordinate
equals the start's.
"""

from __future__ import annotations

import numpy as np

# plane code -> column indices (u, v, w) into an (n, 3) xyz array
PLANE_AXES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}
TWO_PI = 2.0 * np.pi


def plane_index(plane: np.ndarray) -> np.ndarray:
    """(n,) plane codes -> (n, 3) column indices u, v, w."""
    table = np.zeros((20, 3), dtype=np.int64)
    for code, axes in PLANE_AXES.items():
        table[code] = axes
    return table[np.asarray(plane, dtype=np.int64)]


def to_plane(points: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """(n, 3) xyz -> (n, 3) uvw for each row's plane."""
    return np.take_along_axis(points, idx, axis=1)


def from_plane(uvw: np.ndarray, idx: np.ndarray) -> np.ndarray:
    out = np.empty_like(uvw)
    np.put_along_axis(out, idx, uvw, axis=1)
    return out


def centre_from_radius(start_uv: np.ndarray, end_uv: np.ndarray, radius: np.ndarray,
                       ccw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centres (n, 2) of R-format arcs; R > 0 takes the arc of at most 180 deg, R < 0 the longer one.

    Returns (centre, ok) where ok is False when the radius is shorter than half the chord (beyond
    a 1e-6 relative slack) or start equals end.
    """
    d = end_uv - start_uv
    chord = np.hypot(d[:, 0], d[:, 1])
    half = chord / 2.0
    r = np.abs(radius)
    h2 = r * r - half * half
    ok = (chord > 0) & (h2 > -1e-6 * np.maximum(r * r, 1e-12))
    h = np.sqrt(np.clip(h2, 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        left = np.stack([-d[:, 1], d[:, 0]], axis=1) / chord[:, None]
    side = np.where(ccw, 1.0, -1.0) * np.sign(radius)  # +1: centre left of the chord direction
    centre = (start_uv + end_uv) / 2.0 + (side * h)[:, None] * left
    return centre, ok


def sweep(start_uv: np.ndarray, end_uv: np.ndarray, centre_uv: np.ndarray, ccw: np.ndarray,
          turns: np.ndarray) -> np.ndarray:
    """Swept angle (rad, > 0) of each arc; start == end is a full circle; `turns` adds full turns."""
    a0 = np.arctan2(start_uv[:, 1] - centre_uv[:, 1], start_uv[:, 0] - centre_uv[:, 0])
    a1 = np.arctan2(end_uv[:, 1] - centre_uv[:, 1], end_uv[:, 0] - centre_uv[:, 0])
    s = np.where(ccw, a1 - a0, a0 - a1) % TWO_PI
    same = np.hypot(*(end_uv - start_uv).T) <= 1e-9 * np.maximum(1.0, np.abs(start_uv).max(axis=1))
    s = np.where(same | (s <= 1e-12), TWO_PI, s)
    return s + TWO_PI * (np.maximum(turns, 1) - 1)


def arc_length(r0: np.ndarray, r1: np.ndarray, swept: np.ndarray, dw: np.ndarray) -> np.ndarray:
    """Length of a (helical, possibly slightly spiral) arc: mean radius times sweep, with the w rise."""
    return np.hypot((r0 + r1) / 2.0 * swept, dw)


def sample(start_uvw: np.ndarray, centre_uv: np.ndarray, r0: np.ndarray, r1: np.ndarray,
           a0: np.ndarray, swept: np.ndarray, ccw: np.ndarray, dw: np.ndarray,
           fractions: np.ndarray, owner: np.ndarray) -> np.ndarray:
    """Points (m, 3) in uvw at `fractions` (m,) of arc `owner` (m,): angle, radius and w vary linearly."""
    sgn = np.where(ccw, 1.0, -1.0)[owner]
    ang = a0[owner] + sgn * swept[owner] * fractions
    rad = r0[owner] + (r1[owner] - r0[owner]) * fractions
    u = centre_uv[owner, 0] + rad * np.cos(ang)
    v = centre_uv[owner, 1] + rad * np.sin(ang)
    w = start_uvw[owner, 2] + dw[owner] * fractions
    return np.stack([u, v, w], axis=1)
