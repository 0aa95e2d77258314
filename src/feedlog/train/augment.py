"""Simulated training programs: random toolpaths timed by feedlog.sim, to jump-start the learners.

Chien et al. train on dedicated training toolpaths (long lines and short segments, sharp and shallow
corners, several feeds and tolerances) run through their trajectory generator. `simulated_tables`
does the same with feedlog's simulation of the machine profile: random polylines that mix long
lines, runs of short segments (sampled curves) and corners of all angles, at each combination of feed
(1000, 2000, 3000 mm/min) and tolerance (0 = G61 exact path, P0.01, P0.1). Half of the blended programs
use G64 Q0 (no merging of short segments). On a machine with A/C axes most runs also turn A and C
(short segments then become rotary-speed-limited, as on five-axis toolpaths). The tables have the block
features and `duration_s` = the simulated block time (groups the simulation merged are spread by
length, as align splits them).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from feedlog.errors import ModelError
from feedlog.profile import MachineProfile
from feedlog.train.dataset import ProgramTable

OFFSET_SHARE = 0.4  # share of five-axis programs that set a work offset


def random_program_text(*, n_blocks: int, feed_mm_min: float, tol_mm: float, seed: int,
                        rotary: bool = False) -> str:
    """G-code of a random polyline: long lines, short-segment curves, corners of every angle.

    With `rotary` (a five-axis A/C machine) most runs also turn A (kept in -55..0 deg, often near the
    A = 0 singularity) and C by up to a few degrees per block, so that on short segments the rotary
    axes' speed, not L / F, sets the time (as on a five-axis test toolpath); the rest are 3-axis runs.
    Four programs in ten then set a work offset (G10 L2 P1, X/Y within 15 mm, Z within 5 mm, as the
    random-mix recordings do), so that the learners see Chien's Xo, Yo, Zo vary. LinuxCNC's TCP kinematics
    plan the path in the table frame, so an offset changes how far the joints travel but not the planned
    time (the simulation matches the recorded offset sessions within 0.13 %): what the learners should
    take from these programs is that the offset alone does not change the time.
    """
    rng = np.random.default_rng(seed)
    # half of the blended programs forbid LinuxCNC's merging of short collinear segments (Q0)
    # (drawn whatever the tolerance, so one seed gives one geometry at every tolerance)
    no_merge = bool(rng.random() < 0.5)
    mode = "G61" if tol_mm <= 0 else f"G64 P{tol_mm:g}" + (" Q0" if no_merge else "")
    start = "G0 X0 Y0 Z5 A-20 C0" if rotary else "G0 X0 Y0 Z5"
    lines = ["G21 G90 G17", mode]
    if rotary:  # a workpiece away from the rotary axes' origin in 4 of 10 programs (own stream: same paths)
        off_rng = np.random.default_rng([seed, 1])
        if off_rng.random() < OFFSET_SHARE:
            ox, oy, oz = off_rng.uniform(-15.0, 15.0, 2).tolist() + [float(off_rng.uniform(-5.0, 5.0))]
            lines += [f"G10 L2 P1 X{ox:.1f} Y{oy:.1f} Z{oz:.1f} A0 C0", "G54"]
    lines += [start, f"G1 Z0 F{feed_mm_min:g}"]
    x = y = z = heading = 0.0
    a, c = -20.0, 0.0
    count = 0
    while count < n_blocks:
        if rng.random() < 0.4:  # a sampled curve: a run of short segments turning slowly
            run = int(rng.integers(10, 60))
            step = float(np.exp(rng.uniform(np.log(0.005), np.log(1.0 if not rotary else 5.0))))
            turn = float(rng.uniform(-0.25, 0.25))
            lengths, turns = np.full(run, step), np.full(run, turn)
        else:  # lines with corners of any angle
            run = int(rng.integers(1, 6))
            lengths = np.exp(rng.uniform(np.log(0.5), np.log(60.0), run))
            turns = rng.uniform(-3.0, 3.0, run) * (rng.random(run) < 0.8)
        da = dc = 0.0
        if rotary and rng.random() < 0.7:
            if rng.random() < 0.3:  # near the singularity: A close to 0, large C turns
                a = float(rng.uniform(-3.0, 0.0))
            da = float(rng.uniform(-3.0, 3.0))
            dc = float(rng.uniform(-10.0, 10.0))
        dz = float(rng.uniform(-0.05, 0.05)) if rng.random() < 0.3 else 0.0
        for length, turn in zip(lengths, turns):
            heading += float(turn)
            x, y = x + float(length) * np.cos(heading), y + float(length) * np.sin(heading)
            x, y = float(np.clip(x, -400, 400)), float(np.clip(y, -400, 400))
            z = float(np.clip(z + dz * float(length), -20.0, 20.0))
            words = f"X{x:.4f} Y{y:.4f}" + (f" Z{z:.4f}" if dz else "")
            if rotary:
                a, c = float(np.clip(a + da, -55.0, 0.0)), c + dc
                words += f" A{a:.4f} C{c:.4f}"
            lines.append(words)
            count += 1
    lines += ["G0 Z5", "M2"]
    return "\n".join(lines) + "\n"


def simulated_tables(profile: MachineProfile, *, n_programs: int = 8, n_blocks: int = 300, seed: int = 0,
                     feeds: Sequence[float] = (1000.0, 2000.0, 3000.0), tols: Sequence[float] = (0.0, 0.01, 0.1)
                     ) -> list[ProgramTable]:
    """`n_programs` simulated training tables, cycling through every feed x tolerance combination.

    On a machine with rotary axes A or C the programs move them too (`random_program_text(rotary=True)`).
    """
    try:
        from feedlog.sim import simulate
        from feedlog.toolpath import block_features, parse_program
    except ImportError as exc:
        raise ModelError(f"simulated training data needs feedlog.sim and feedlog.toolpath: {exc}") from None
    from feedlog.train.features import with_program_columns
    from feedlog.train.model_hybrid import spread_merged

    rotary = any(axis in profile.axes for axis in ("a", "c"))
    combos = [(f, t) for f in feeds for t in tols]
    tables = []
    for i in range(n_programs):
        feed, tol = combos[i % len(combos)]
        name = f"sim-{seed}-{i}"
        text = random_program_text(n_blocks=n_blocks, feed_mm_min=feed, tol_mm=tol, seed=seed * 10_007 + i,
                                   rotary=rotary)
        program = parse_program(text, name=name)
        features = with_program_columns(block_features(program, profile), program, profile)
        sim = simulate(program, profile).blocks.groupby("block")["duration_s"].sum()
        times = features["block"].map(sim).fillna(0.0).to_numpy(np.float64)
        features["duration_s"] = spread_merged(times, features["length_mm"].to_numpy(np.float64))
        tables.append(ProgramTable(name, features, program=name, split="train", profile=profile,
                                   program_text=text, metadata={"source": "simulated"}))
    return tables
