"""Pieces of synthetic part programs (benchmarks, tests, augmentation): G-code text built from a
heading, as CAM output of a random or mould-like path would have it."""

from __future__ import annotations

import math


def tangent_arc(x: float, y: float, heading: float, radius: float, sweep: float) -> tuple[str, float, float, float]:
    """A G2/G3 arc in XY leaving (x, y) along `heading` (rad) and turning by `sweep` (rad; positive:
    counter-clockwise) on `radius`: (the block, end x, end y, end heading). Centre as I/J."""
    side = 1.0 if sweep > 0 else -1.0
    cx, cy = x - side * radius * math.sin(heading), y + side * radius * math.cos(heading)
    ang = math.atan2(y - cy, x - cx) + sweep
    ex, ey = cx + radius * math.cos(ang), cy + radius * math.sin(ang)
    return (f"{'G3' if side > 0 else 'G2'} X{ex:.4f} Y{ey:.4f} I{cx - x:.4f} J{cy - y:.4f}", ex, ey,
            heading + sweep)
