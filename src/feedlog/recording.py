"""The in-memory recording: a set of named streams, session metadata and attachments.

Each stream is a table (pandas DataFrame) whose first column is `t_ns` (int64 nanoseconds, one clock
per recording, monotonic non-decreasing) and whose other columns are typed and carry their unit in
their name. The on-disk form is feedlog's MCAP recording format (docs/recording-format.md).

Standard stream and column names (readers map their sources onto these where they can):
- `axes`:   x_mm, y_mm, z_mm, a_deg, b_deg, c_deg   commanded/planned axis positions
- `joints`: j0_pos, j1_pos, ...  (+ j0_pos_fb ...)  joint command (and feedback) positions
- `feed`:   feed_mm_min (actual path feed), requested_feed_mm_min
- `line`:   line (int64)                            executing program line
- `status`: in_position (bool), motion_type (int8), ...
Other streams (spindle, CAN signals, ...) are allowed; names are lower_snake_case.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from feedlog.errors import IngestError
from feedlog.units import MAX_ABS_T_NS

# metadata keys every writer fills in (values are strings)
METADATA_KEYS = ("machine", "controller", "units", "nominal_rate_hz", "start_time", "notes")
# attachment names
PROGRAM_ATTACHMENT = "program.ngc"
PROFILE_ATTACHMENT = "profile.toml"


@dataclass
class Recording:
    streams: dict[str, pd.DataFrame] = field(default_factory=dict)
    metadata: dict[str, str] = field(default_factory=dict)
    attachments: dict[str, bytes] = field(default_factory=dict)
    dropped_frames: int = 0
    source: str = ""

    def __post_init__(self) -> None:
        for name, table in self.streams.items():
            check_stream(name, table, source=self.source)

    def stream(self, name: str) -> pd.DataFrame:
        try:
            return self.streams[name]
        except KeyError:
            raise IngestError(f"recording has no stream {name!r}; it has: {', '.join(self.streams) or 'none'}",
                              file=self.source or None) from None

    @property
    def t_range_ns(self) -> tuple[int, int]:
        starts = [int(t["t_ns"].iloc[0]) for t in self.streams.values() if len(t)]
        ends = [int(t["t_ns"].iloc[-1]) for t in self.streams.values() if len(t)]
        if not starts:
            return (0, 0)
        return (min(starts), max(ends))

    @property
    def duration_s(self) -> float:
        t0, t1 = self.t_range_ns
        return (t1 - t0) / 1e9

    @property
    def program_text(self) -> str | None:
        data = self.attachments.get(PROGRAM_ATTACHMENT)
        return None if data is None else data.decode("utf-8", errors="replace")


def first_bad_value(t_ns: np.ndarray, columns: dict[str, np.ndarray]) -> tuple[str, int] | None:
    """(what, sample) of the first value a recording must not hold: a time beyond +-MAX_ABS_T_NS (NaN
    cast to int64 becomes INT64_MIN), a NaN or infinite float, an empty (None) value; None if all fine."""
    # the extremes first (two passes, no copy): the element-wise search only runs when something is wrong
    if len(t_ns) and (t_ns.min() < -MAX_ABS_T_NS or t_ns.max() > MAX_ABS_T_NS):
        out = (t_ns < -MAX_ABS_T_NS) | (t_ns > MAX_ABS_T_NS)
        k = int(np.flatnonzero(out)[0])
        return f"t_ns {int(t_ns[k])} is not a time (beyond +-2**62 ns)", k
    for name, values in columns.items():
        if values.dtype.kind == "f":
            if not len(values) or (np.isfinite(values.min()) and np.isfinite(values.max())):
                continue   # a NaN makes the minimum NaN; an infinity is an extreme
            bad = ~np.isfinite(values)
        elif values.dtype.kind == "O":
            bad = pd.isna(values)
        else:
            continue
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            return f"column {name!r} holds {values[k]!r}", k
    return None


def check_stream(name: str, table: pd.DataFrame, *, source: str = "") -> None:
    """A stream needs an int64 `t_ns` first column that never goes back in time, and finite values."""
    if len(table.columns) == 0 or table.columns[0] != "t_ns":
        raise IngestError(f"stream {name!r}: first column must be 't_ns', got {list(table.columns)[:3]}",
                          file=source or None)
    t = table["t_ns"].to_numpy()
    if t.dtype != np.int64:
        raise IngestError(f"stream {name!r}: t_ns must be int64 nanoseconds, got {t.dtype}", file=source or None)
    bad = first_bad_value(t, {str(c): table[c].to_numpy() for c in table.columns[1:]})
    if bad:
        raise IngestError(f"stream {name!r}: {bad[0]}", file=source or None, position=f"sample {bad[1]}")
    if len(t) > 1:
        back = t[1:] < t[:-1]     # within +-2**62 (checked above), so no difference overflows
        if back.any():
            k = int(np.argmax(back)) + 1
            raise IngestError(f"stream {name!r}: time goes backwards at sample {k}", file=source or None,
                              position=f"sample {k}")
