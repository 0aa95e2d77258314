"""Backlash: play between the drive and what the feedback measures, taken up at every reversal.

Source: lost motion of a ball screw nut or gear train (ISO 230-2 reversal value B). With a linear
scale on the table and the command on the motor, the table stays put after the drive reverses until
the drive has crossed the play: the reported position is the command through a *play operator* of
width `backlash_mm` (it follows the command at half the play behind it in the direction of travel,
and holds while the command crosses the play after a reversal). 0 leaves an axis unchanged. The
first sample is taken as centred in the play. A `feedback` mechanism: the commanded motion and the
cycle time are unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from feedlog.sim.mechanism import Mechanism


def play(cmd: np.ndarray, width: float) -> np.ndarray:
    """The play (backlash) operator of `width` on one axis' command: out stays within width / 2 of it."""
    out = np.empty(len(cmd))
    half = 0.5 * width
    y = float(cmd[0]) if len(cmd) else 0.0
    for k, u in enumerate(cmd.tolist()):
        if u - y > half:
            y = u - half
        elif y - u > half:
            y = u + half
        out[k] = y
    return out


@dataclass
class Backlash(Mechanism):
    name = "backlash"
    kind = "feedback"
    order = 40  # after the scale: play in the mechanics between drive and measuring system

    backlash_mm: dict[str, float] = field(default_factory=lambda: {"x": 0.0, "y": 0.0, "z": 0.0})

    def __post_init__(self) -> None:
        for axis, value in self.backlash_mm.items():
            if not (isinstance(value, (int, float)) and 0 <= value <= 10):
                raise ValueError(f"backlash_mm[{axis!r}] must be a number from 0 to 10, got {value!r}")

    def feedback(self, dt_s: float, axes: tuple[str, ...], pos: np.ndarray) -> np.ndarray:
        pos = np.array(pos, dtype=np.float64)
        for i, axis in enumerate(axes):
            width = float(self.backlash_mm.get(axis, 0.0))
            if width > 0 and len(pos):
                pos[:, i] = play(pos[:, i], width)
        return pos
