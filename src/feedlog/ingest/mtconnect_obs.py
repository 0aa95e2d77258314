"""MTConnect observations in long form: what both readers (SHDR text, Streams XML) produce.

One row per observation: `t_ns` (int64 ns since the epoch), `key` (the data item's name or id), `value`
(text as sent; `UNAVAILABLE` when the agent knows no value), `where` (the line or element it came from,
for messages). The Streams XML reader also knows each data item's type (`DataItemType`: the element
name such as `Position` or `PathFeedrate`, its `subType`, the component it belongs to), so it can map
signals by meaning; SHDR keys are whatever the adapter calls them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from feedlog.errors import IngestError
from feedlog.ingest.csv_reader import BadRows
from feedlog.units import MAX_ABS_T_NS

UNAVAILABLE = "UNAVAILABLE"


@dataclass(frozen=True)
class DataItemType:
    """What a Streams document says about a data item."""

    element: str                 # Position, PathFeedrate, Line, LineNumber, LineLabel, Angle, ...
    category: str = ""           # Samples, Events, Condition
    sub_type: str = ""           # ACTUAL, COMMANDED, PROGRAMMED, ABSOLUTE, ...
    component: str = ""          # Linear, Rotary, Path, Controller, ...
    component_name: str = ""     # X, Y, Z, A, C, path, ...
    name: str = ""               # the data item's name attribute (may be empty)
    device: str = ""             # the DeviceStream it belongs to


@dataclass
class Observations:
    t_ns: np.ndarray
    key: np.ndarray              # object (str)
    value: np.ndarray            # object (str)
    where: np.ndarray            # int64: line (SHDR) or line of the element (XML)
    bad: BadRows = field(default_factory=BadRows)
    metadata: dict[str, str] = field(default_factory=dict)
    types: dict[str, DataItemType] = field(default_factory=dict)   # key -> type (XML only)
    place: str = "line"

    def __len__(self) -> int:
        return len(self.t_ns)

    def keys(self) -> list[str]:
        return list(dict.fromkeys(self.key.tolist()))


def parse_times(values: np.ndarray, *, timezone: str = "UTC") -> tuple[np.ndarray, np.ndarray]:
    """ISO 8601 timestamps (text) -> (int64 ns since the epoch, ok mask). MTConnect times are UTC and
    end in `Z`; times without an offset are taken in `timezone`. Parsed once per distinct text."""
    series = pd.Series(values, dtype=object)
    uniq, inverse = np.unique(series.fillna("").astype(str).to_numpy(), return_inverse=True)
    aware = np.array([u.endswith(("Z", "z")) or (len(u) > 6 and u[-6] in "+-" and u[-3] == ":") for u in uniq])
    t = np.zeros(len(uniq), dtype=np.int64)
    ok = np.zeros(len(uniq), dtype=bool)
    for flag in (True, False):
        sel = aware == flag
        if not sel.any():
            continue
        text = pd.Series(uniq[sel])
        looks = text.str.match(r"^\d{4}-\d\d-\d\d[T ]\d\d:\d\d").to_numpy()
        parsed = pd.to_datetime(text.where(looks), format="ISO8601", errors="coerce", utc=flag)
        if not flag:
            try:
                parsed = parsed.dt.tz_localize(timezone, ambiguous="NaT", nonexistent="NaT")
            except Exception:  # noqa: BLE001 - pytz/zoneinfo raise their own kinds
                raise IngestError(f"unknown time zone {timezone!r} (--timezone)") from None
        good = parsed.notna().to_numpy().copy()
        ns = np.zeros(len(text), dtype=np.int64)
        ns[good] = parsed[good].dt.tz_convert("UTC").dt.tz_localize(None).to_numpy().astype("datetime64[ns]").astype(np.int64)
        good &= np.abs(ns) <= MAX_ABS_T_NS
        t[sel], ok[sel] = ns, good
    return t[inverse], ok[inverse]
