"""Axis scale: the reported position of an axis is its command times a factor (a scale error).

Source: a ball screw whose lead differs from the drive's setting, a linear scale mounted at a slight
angle, a wrong encoder count per revolution (ISO 230-2 positioning accuracy: a linear error growing
with the distance from the reference point). The factor applies to the distance from machine zero:
`fb = cmd * scale`. 1.0 leaves an axis unchanged. A `feedback` mechanism: the commanded motion and the
cycle time are unchanged; seen where a recording carries commanded and feedback positions.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from feedlog.sim.mechanism import Mechanism

SCALE_RANGE = (0.5, 2.0)


@dataclass
class AxisScale(Mechanism):
    name = "axis_scale"
    kind = "feedback"
    order = 30  # after the delay and the lag: the drive's motion, then the measuring system

    scale: dict[str, float] = field(default_factory=lambda: {"x": 1.0, "y": 1.0, "z": 1.0})

    def __post_init__(self) -> None:
        for axis, value in self.scale.items():
            if not (isinstance(value, (int, float)) and SCALE_RANGE[0] <= value <= SCALE_RANGE[1]):
                raise ValueError(f"scale[{axis!r}] must be a number from {SCALE_RANGE[0]} to {SCALE_RANGE[1]}, "
                                 f"got {value!r}")

    def feedback(self, dt_s: float, axes: tuple[str, ...], pos: np.ndarray) -> np.ndarray:
        pos = np.array(pos, dtype=np.float64)
        for i, axis in enumerate(axes):
            pos[:, i] *= float(self.scale.get(axis, 1.0))
        return pos
