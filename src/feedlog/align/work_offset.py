"""Estimate a constant work offset between a program's coordinates and the recorded machine positions.

Controllers log machine coordinates; a program runs in work coordinates whose origin (G54 ...) was set
on the machine and is not in the program. When the two frames differ by a translation, the measured
path is the program path shifted: `estimate_work_offset` finds the shift in two steps:
1. the lowest corner of both bounding boxes (mills cut downwards and to the part's edges, so the lowest
   X, Y and Z the program reaches are reached by the machine too; a reference return goes up, not down);
2. a few rounds of nearest-neighbour refinement (scipy's cKDTree): each program point's nearest measured
   point, the median of the differences added to the offset, until it moves less than 1 um.
The result is reported with the median distance left, so a wrong estimate (a program that is not the
one recorded) is visible; align then checks every point against its tolerance as usual.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

ROUNDS = 8


@dataclass(frozen=True)
class OffsetEstimate:
    offset_mm: tuple[float, float, float]   # add to program coordinates to get the measured frame
    residual_median_mm: float               # median program-point distance to the measured path after it

    def as_dict(self) -> dict:
        return {"offset_mm": list(self.offset_mm), "residual_median_mm": self.residual_median_mm}


def estimate_work_offset(program_xyz: np.ndarray, measured_xyz: np.ndarray) -> OffsetEstimate:
    """The translation taking `program_xyz` (n, 3, mm) onto the path `measured_xyz` (m, 3, mm)."""
    prog = np.asarray(program_xyz, dtype=np.float64)
    meas = np.asarray(measured_xyz, dtype=np.float64)
    prog, meas = prog[np.isfinite(prog).all(axis=1)], meas[np.isfinite(meas).all(axis=1)]
    if not len(prog) or not len(meas):
        return OffsetEstimate((0.0, 0.0, 0.0), float("nan"))
    offset = meas.min(axis=0) - prog.min(axis=0)
    tree = cKDTree(meas)
    for _ in range(ROUNDS):
        _, nearest = tree.query(prog + offset)
        step = np.median(meas[nearest] - (prog + offset), axis=0)
        offset = offset + step
        if np.abs(step).max() < 1e-3:
            break
    dist, _ = tree.query(prog + offset)
    return OffsetEstimate(tuple(float(v) for v in offset), float(np.median(dist)))
