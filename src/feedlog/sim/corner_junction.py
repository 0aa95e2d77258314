"""Junction-deviation corner law: the corner speed of grbl and Klipper.

Source: grbl planner.c (S. Jeon, "Improving grbl: cornering algorithm", 2011) and Klipper
toolhead.py: a virtual circle tangent to both blocks whose distance from the corner is the junction
deviation delta; the corner speed is the speed at which the centripetal acceleration on that circle
equals the acceleration limit:

    v^2 = a * delta * sin(theta / 2) / (1 - sin(theta / 2)),  theta = pi - angle between the blocks.

The path itself is not altered (the corner is passed exactly at that speed). `deviation_mm` is the
G64 P tolerance of the block when one is given, otherwise `default_deviation_mm`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.sim.context import Context
from feedlog.sim.mechanism import Mechanism
from feedlog.sim.path import with_columns


def junction_speed(u1: np.ndarray, u2: np.ndarray, acc: np.ndarray, deviation: np.ndarray) -> np.ndarray:
    """grbl's corner speed for unit directions u1 -> u2 (rows)."""
    cos_theta = np.clip(-np.einsum("ij,ij->i", u1, u2), -1.0, 1.0)
    sin_half = np.sqrt(np.clip(0.5 * (1.0 - cos_theta), 0.0, 1.0))
    with np.errstate(divide="ignore"):
        v2 = acc * deviation * sin_half / (1.0 - sin_half)
    return np.sqrt(np.where(sin_half >= 1.0 - 1e-12, np.inf, v2))


@dataclass
class JunctionDeviationCorner(Mechanism):
    name = "junction_deviation"
    kind = "corner"
    windowed = True

    default_deviation_mm: float = 0.01

    def __post_init__(self) -> None:
        self.check_positive(default_deviation_mm=self.default_deviation_mm)

    def corner(self, ctx: Context) -> None:
        pc = ctx.pieces
        m = len(pc)
        if m < 2:
            return
        blocks = ctx.blocks
        lin = blocks.linear_index
        j = np.arange(m - 1)
        u1 = pc.tangent_xyz(j, pc.length[j], lin)
        u2 = pc.tangent_xyz(j + 1, np.zeros(m - 1), lin)
        tol = blocks.tol[pc.block[j]]
        dev = np.where(tol > 0, tol, self.default_deviation_mm)
        acc = np.minimum(pc.a_max[j], pc.a_max[j + 1])
        v = junction_speed(u1, u2, acc, dev)
        no_tcp = (np.linalg.norm(u1, axis=1) == 0) | (np.linalg.norm(u2, axis=1) == 0)
        v = np.where(no_tcp, 0.0, v)
        stop = blocks.stop_after[pc.block[j]] | (pc.hold_s[j] > 0)
        v_end = np.append(np.where(stop, 0.0, v), 0.0)
        ctx.pieces = with_columns(pc, v_end=v_end)
