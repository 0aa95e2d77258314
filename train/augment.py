"""Simulated training programs: random toolpaths timed by feedlog.sim, to jump-start the learners.

Chien et al. train on dedicated training toolpaths (long lines and short segments, sharp and shallow
corners, several feeds and tolerances) run through their trajectory generator. `simulated_tables`
does the same with feedlog's simulation of the machine profile: random 3-axis polylines that mix long
lines, runs of short segments (sampled curves) and corners of all angles, at each combination of feed
and tolerance (0 = G61 exact path). Half of the blended programs use G64 Q0 (no merging of short segments). The tables have the block
features and `duration_s` = the
simulated block time (groups the simulation merged are spread by length, as align splits them).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from feedlog.errors import ModelError
from feedlog.profile import MachineProfile
from feedlog.train.dataset import ProgramTable


def random_program_text(*, n_blocks: int, feed_mm_min: float, tol_mm: float, seed: int) -> str:
    """G-code of a random 3-axis polyline: long lines, short-segment curves, corners of every angle."""
    rng = np.random.default_rng(seed)
    # half of the blended programs forbid LinuxCNC's merging of short collinear segments (Q0)
    mode = "G61" if tol_mm <= 0 else f"G64 P{tol_mm:g}" + (" Q0" if rng.random() < 0.5 else "")
    lines = ["G21 G90 G17", mode, "G0 X0 Y0 Z5", f"G1 Z0 F{feed_mm_min:g}"]
    x = y = heading = 0.0
    count = 0
    while count < n_blocks:
        if rng.random() < 0.4:  # a sampled curve: a run of short segments turning slowly
            run = int(rng.integers(10, 60))
            step = float(np.exp(rng.uniform(np.log(0.005), np.log(1.0))))
            turn = float(rng.uniform(-0.25, 0.25))
            lengths, turns = np.full(run, step), np.full(run, turn)
        else:  # lines with corners of any angle
            run = int(rng.integers(1, 6))
            lengths = np.exp(rng.uniform(np.log(0.5), np.log(60.0), run))
            turns = rng.uniform(-3.0, 3.0, run) * (rng.random(run) < 0.8)
        for length, turn in zip(lengths, turns):
            heading += float(turn)
            x, y = x + float(length) * np.cos(heading), y + float(length) * np.sin(heading)
            x, y = float(np.clip(x, -400, 400)), float(np.clip(y, -400, 400))
            lines.append(f"X{x:.4f} Y{y:.4f}")
            count += 1
    lines += ["G0 Z5", "M2"]
    return "\n".join(lines) + "\n"


def simulated_tables(profile: MachineProfile, *, n_programs: int = 8, n_blocks: int = 300, seed: int = 0,
                     feeds: Sequence[float] = (1000.0, 3000.0), tols: Sequence[float] = (0.0, 0.01, 0.1)
                     ) -> list[ProgramTable]:
    """`n_programs` simulated training tables, cycling through every feed x tolerance combination."""
    try:
        from feedlog.sim import simulate
        from feedlog.toolpath import block_features, parse_program
    except ImportError as exc:
        raise ModelError(f"simulated training data needs feedlog.sim and feedlog.toolpath: {exc}") from None
    from feedlog.train.features import with_program_columns
    from feedlog.train.model_hybrid import spread_merged

    combos = [(f, t) for f in feeds for t in tols]
    tables = []
    for i in range(n_programs):
        feed, tol = combos[i % len(combos)]
        name = f"sim-{seed}-{i}"
        text = random_program_text(n_blocks=n_blocks, feed_mm_min=feed, tol_mm=tol, seed=seed * 10_007 + i)
        program = parse_program(text, name=name)
        features = with_program_columns(block_features(program, profile), program, profile)
        sim = simulate(program, profile).blocks.groupby("block")["duration_s"].sum()
        times = features["block"].map(sim).fillna(0.0).to_numpy(np.float64)
        features["duration_s"] = spread_merged(times, features["length_mm"].to_numpy(np.float64))
        tables.append(ProgramTable(name, features, program=name, split="train", profile=profile,
                                   program_text=text, metadata={"source": "simulated"}))
    return tables
