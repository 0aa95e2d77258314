"""A recording's positions and the steps between consecutive samples, worked out once for the import checks.

The jump check (`data_checks.position_jumps`), the rounding check (`data_checks.quantisation`) and the
feed's unit check (`unit_check.feed_unit_check`) all look at the same x/y/z columns: the time between
samples, the length of each step and how finely each column is resolved. `PositionSteps.of(recording)`
takes the columns as float64 views of the stream (no copy when they are float64 already) and computes
each of these once, on first use, so `run_checks` makes one pass over the positions instead of one per
check. It lives for one `run_checks` call: a recording edited afterwards needs a new one.

The step length is sqrt(dx*dx + dy*dy + dz*dz) summed in column order, the same floating-point sum
`numpy.linalg.norm(..., axis=1)` makes over the rows of an (n, k) array, without building that array.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from feedlog.ingest.quantum import position_step_mm
from feedlog.recording import Recording

POSITION_COLUMNS = ("x_mm", "y_mm", "z_mm")


@dataclass
class PositionSteps:
    """Times (int64 ns) and position columns (float64, in `POSITION_COLUMNS` order) of one stream."""

    t_ns: np.ndarray
    columns: dict[str, np.ndarray]
    _quanta: dict[str, tuple[float, str] | None] = field(default_factory=dict, repr=False)

    @classmethod
    def of(cls, recording: Recording, stream: str = "axes") -> PositionSteps | None:
        """The positions of `stream`; None without at least two samples of x, y or z."""
        table = recording.streams.get(stream)
        if table is None or len(table) < 2:
            return None
        cols = [c for c in POSITION_COLUMNS if c in table.columns]
        if not cols:
            return None
        return cls(table["t_ns"].to_numpy(dtype=np.int64),
                   {c: table[c].to_numpy(dtype=np.float64) for c in cols})

    def __len__(self) -> int:
        return len(self.t_ns)

    @cached_property
    def dt_s(self) -> np.ndarray:
        """Seconds from each sample to the next (n - 1 values): the int64 difference, then / 1e9, as
        `np.diff(t) / 1e9` computes it, in one array."""
        t = self.t_ns
        dt = np.subtract(t[1:], t[:-1], out=np.empty(len(t) - 1, dtype=np.float64))
        return np.divide(dt, 1e9, out=dt)

    @cached_property
    def step_mm(self) -> np.ndarray:
        """Length of the step from each sample to the next (n - 1 values; NaN where a position is), in two
        arrays whatever the number of axes (large fresh arrays cost page faults)."""
        total, scratch = None, None
        for values in self.columns.values():
            if total is None:
                d = total = np.subtract(values[1:], values[:-1])
            else:
                scratch = d = np.subtract(values[1:], values[:-1], out=scratch)
            np.multiply(d, d, out=d)
            if d is not total:
                total += d
        return np.sqrt(total, out=total)

    def quantum(self, column: str) -> tuple[float, str] | None:
        """`quantum.position_step_mm` of one column, computed once."""
        if column not in self._quanta:
            self._quanta[column] = position_step_mm(self.columns[column])
        return self._quanta[column]
