"""Feedback positions: commanded axis (joint) positions through the profile's `feedback` mechanisms.

A servo loop reports where the axis is, not where it was told to be. The `feedback` mechanisms of a
profile (`feedback_delay`, `following_lag`) say how the reported position trails the command. The
same functions serve the simulation (`SimResult.feedback`, recorded by the measurement model as
`joints.jN_pos_fb`) and `feedlog diagnose`, which runs them on a recording's own commanded positions,
so a feedback model is judged independently of the timing of the motion.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from feedlog.sim.mechanism import Mechanism


def feedback_chain(mechanisms: Sequence[Mechanism]) -> list[Mechanism]:
    """The feedback mechanisms of a resolved chain, in chain order."""
    return [m for m in mechanisms if m.kind == "feedback"]


def feedback_positions(chain: Sequence[Mechanism], dt_s: float, axes: tuple[str, ...], cmd: np.ndarray) -> np.ndarray:
    """Feedback (n, k) for the commanded positions `cmd` (n, k) sampled every `dt_s`, columns `axes`."""
    fb = np.asarray(cmd, dtype=np.float64)
    for mech in chain:
        fb = mech.feedback(dt_s, axes, fb)
    return fb


def feedback_table(chain: Sequence[Mechanism], t_ns: np.ndarray, axes: tuple[str, ...], cmd: np.ndarray,
                   dt_s: float) -> pd.DataFrame:
    """`t_ns`, `jN_pos` (command) and `jN_pos_fb` (feedback), with the command held at its end for as
    long as the mechanisms need to settle."""
    settle = max((m.settle_s() for m in chain), default=0.0)
    n = int(np.ceil(settle / dt_s)) if len(t_ns) else 0
    if n:
        step = int(round(dt_s * 1e9))
        t_ns = np.concatenate([t_ns, t_ns[-1] + step * np.arange(1, n + 1, dtype=np.int64)])
        cmd = np.vstack([cmd, np.repeat(cmd[-1:], n, axis=0)])
    fb = feedback_positions(chain, dt_s, axes, cmd)
    table: dict[str, np.ndarray] = {"t_ns": np.asarray(t_ns, dtype=np.int64)}
    for i in range(cmd.shape[1]):
        table[f"j{i}_pos"] = cmd[:, i]
        table[f"j{i}_pos_fb"] = fb[:, i]
    return pd.DataFrame(table)
