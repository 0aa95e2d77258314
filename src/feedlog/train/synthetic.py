"""Synthetic aligned block tables with a known ground truth, for tests, benchmarks and smoke runs.

Each program is a random 3-D polyline. A block's "measured" time follows trapezoidal velocity
profiles: the path accelerates at `acc_mm_s2` from the entry corner speed towards F and decelerates
to the exit corner speed, where the corner speed is limited by the centripetal acceleration on a
blend arc that stays within the path tolerance; programs start and end at rest. The time therefore
depends on F, L, both corner angles and the tolerance, like a real interpolator's, but it is exact
and cheap, so a model that learns it can be checked.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from feedlog.train.dataset import ProgramTable
from feedlog.train.kinematic import blend_radius

DEFAULT_TOL_MM = 1.0  # blend tolerance assumed where the program has none (tol_mm NaN)


def corner_speed_mm_s(theta_deg: np.ndarray, feed_mm_s: float, tol_mm: float, acc_mm_s2: float) -> np.ndarray:
    """Speed through a corner whose direction changes by theta, on a blend arc within tol."""
    half = np.radians(np.clip(theta_deg, 0.0, 179.9)) / 2.0
    return np.minimum(feed_mm_s, np.sqrt(acc_mm_s2 * blend_radius(half, tol_mm)))


def trapezoid_time_s(length: np.ndarray, v_in: np.ndarray, v_out: np.ndarray, v_max: float, acc: float) -> np.ndarray:
    """Time to travel `length` from v_in to v_out, cruising at most at v_max, accelerating at acc.

    The synthetic law keeps both end speeds even where the length cannot join them (the time is then
    |v_in - v_out| / acc); `kinematic.trapezoid_time` lowers them to what the length allows.
    """
    full = length / v_max + (v_max - v_in) ** 2 / (2 * acc * v_max) + (v_max - v_out) ** 2 / (2 * acc * v_max)
    reach = (2 * v_max**2 - v_in**2 - v_out**2) / (2 * acc) <= length
    peak = np.sqrt(np.maximum(acc * length + (v_in**2 + v_out**2) / 2.0, 0.0))
    peak = np.maximum(peak, np.maximum(v_in, v_out))
    short = (2 * peak - v_in - v_out) / acc
    return np.where(reach, full, short)


def synthetic_program(n_blocks: int, *, seed: int, feed_mm_min: float = 1500.0, tol_mm: float = 0.05,
                      acc_mm_s2: float = 1000.0, noise: float = 0.0, name: str | None = None,
                      split: str = "train", sim_acc_factor: float | None = None) -> ProgramTable:
    """One random polyline program with its block features and 'measured' block times.

    `sim_acc_factor` adds `sim_duration_s`, the same law with the acceleration scaled (an imperfect
    physics model for the hybrid).
    """
    rng = np.random.default_rng(seed)
    length = np.exp(rng.uniform(np.log(0.3), np.log(40.0), n_blocks))
    heading = np.cumsum(rng.choice([0.0, 0.0, 1.0], n_blocks) * rng.uniform(-2.6, 2.6, n_blocks))
    climb = np.where(rng.random(n_blocks) < 0.1, rng.uniform(-0.5, 0.5, n_blocks), 0.0)
    d = np.column_stack([np.cos(heading), np.sin(heading), climb])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    cosang = np.clip((d[1:] * d[:-1]).sum(axis=1), -1.0, 1.0)
    corner = np.concatenate([[0.0], np.degrees(np.arccos(cosang))])  # direction change entering block k
    corner_end = np.concatenate([corner[1:], [0.0]])
    nominal = length / feed_mm_min * 60.0
    v_nom = feed_mm_min * d
    a_nom = np.diff(np.vstack([np.zeros(3), v_nom]), axis=0) / 60.0 / nominal[:, None]

    def block_times(acc: float) -> np.ndarray:
        f = feed_mm_min / 60.0
        v_in = np.concatenate([[0.0], corner_speed_mm_s(corner[1:], f, tol_mm, acc)])
        v_out = np.concatenate([v_in[1:], [0.0]])
        return trapezoid_time_s(length, v_in, v_out, f, acc)

    duration = block_times(acc_mm_s2) * (1.0 + noise * rng.standard_normal(n_blocks))
    ends = np.cumsum(duration)
    t_end = np.rint(ends * 1e9).astype(np.int64)
    blocks = pd.DataFrame({
        "block": np.arange(n_blocks, dtype=np.int32), "line": np.arange(1, n_blocks + 1, dtype=np.int32),
        "kind": pd.Categorical(["linear"] * n_blocks),
        "t_start_ns": np.concatenate([[0], t_end[:-1]]), "t_end_ns": t_end, "duration_s": duration,
        "length_mm": length, "ori_arc_deg": 0.0, "corner_start_deg": corner, "corner_end_deg": corner_end,
        "ori_corner_start_deg": 0.0, "ori_corner_end_deg": 0.0, "sin_rot": 0.0,
        "feed_mm_min": feed_mm_min, "tol_mm": tol_mm, "nominal_time_s": nominal,
        "vx_nom_mm_min": v_nom[:, 0], "vy_nom_mm_min": v_nom[:, 1], "vz_nom_mm_min": v_nom[:, 2],
        "ax_nom_mm_s2": a_nom[:, 0], "ay_nom_mm_s2": a_nom[:, 1], "az_nom_mm_s2": a_nom[:, 2],
    })
    if sim_acc_factor is not None:
        blocks["sim_duration_s"] = block_times(acc_mm_s2 * sim_acc_factor)
    name = name or f"synthetic-{seed}"
    return ProgramTable(name, blocks, program=name, split=split)


def synthetic_set(*, n_train: int = 4, n_test: int = 2, n_blocks: int = 400, seed: int = 0,
                  feeds: tuple[float, ...] = (1000.0, 3000.0), tols: tuple[float, ...] = (0.01, 0.1),
                  noise: float = 0.005, sim_acc_factor: float | None = 1.5) -> list[ProgramTable]:
    """Training and held-out test programs at Chien's combinations of feed and tolerance."""
    tables = []
    for i in range(n_train + n_test):
        split = "train" if i < n_train else "test"
        tables.append(synthetic_program(
            n_blocks, seed=seed * 1000 + i, feed_mm_min=feeds[i % len(feeds)],
            tol_mm=tols[(i // len(feeds)) % len(tols)], noise=noise, split=split,
            name=f"{split}-{i}", sim_acc_factor=sim_acc_factor))
    return tables
