"""One registry: a source's scheme or file suffix -> the reader that turns it into a `Recording`.

`read_source("trace.csv", options)` picks the reader by suffix; a scheme prefix forces one
(`can:bus.csv` is a python-can CSV log, `csv:trace.txt` a data CSV). Readers are imported on first
use. An unknown suffix or scheme raises `IngestError` listing the supported ones.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from feedlog.errors import IngestError
from feedlog.ingest.mapping import ColumnMap, load_preset, parse_map
from feedlog.recording import Recording
from feedlog.registry import Registry

# scheme -> "module:function"; each function is `read(path: Path, options: ImportOptions) -> Recording`
READERS: Registry[Callable[..., Recording]] = Registry.lazy("reader", {
    "mcap": "feedlog.ingest.mcap_import:read_mcap_source",
    "csv": "feedlog.ingest.csv_reader:read_csv_source",
    "can": "feedlog.ingest.can_log:read_can_source",
    "mtconnect": "feedlog.ingest.mtconnect:read_mtconnect_source",
}, error=IngestError)
# file suffix -> scheme (one line per format)
SUFFIXES: dict[str, str] = {
    ".mcap": "mcap",
    ".csv": "csv",
    ".tsv": "csv",
    ".blf": "can",
    ".asc": "can",
    ".trc": "can",
    ".mf4": "can",
    ".log": "can",
    ".xml": "mtconnect",
    ".shdr": "mtconnect",
    ".txt": "mtconnect",
}
_SCHEME = re.compile(r"^([a-z][a-z0-9]+):(?!//)(.+)$")


@dataclass
class ImportOptions:
    """What `feedlog import` passes to readers; each reader uses the fields that concern it."""

    preset: str | None = None
    mapping: str | None = None  # `t=time,x=X1_ActualPosition,...`
    time_unit: str | None = None
    length_unit: str | None = None
    angle_unit: str | None = None
    feed_unit: str | None = None
    timezone: str | None = None
    time_format: str | None = None
    delimiter: str | None = None    # CSV field delimiter (None: the preset's, else ",")
    rate_hz: float | None = None     # CSV without a time column, sampled at a fixed rate
    dbc: str | None = None
    device: str | None = None        # MTConnect: the device to read when a file holds several
    strict: bool = True
    recover: bool = False

    def __post_init__(self) -> None:
        if self.preset and self.mapping:
            raise IngestError(f"give either a preset ({self.preset!r}) or --map, not both")
        if self.delimiter is not None and len(self.delimiter) != 1:
            raise IngestError(f"delimiter must be one character, got {self.delimiter!r}")

    def column_map(self, *, default_preset: str | None = None) -> ColumnMap:
        """The preset or --map mapping with declared unit overrides applied."""
        if self.mapping:
            base = ColumnMap(mapping=parse_map(self.mapping), time_unit=self.time_unit or "s", rate_hz=self.rate_hz)
        elif self.preset or default_preset:
            base = load_preset(self.preset or default_preset)
            if self.rate_hz is not None:  # a preset with a time column read as a fixed-rate file
                base = ColumnMap(**{**base.__dict__, "rate_hz": self.rate_hz,
                                    "mapping": {k: v for k, v in base.mapping.items() if k != "t"},
                                    "candidates": {k: v for k, v in base.candidates.items() if k != "t"},
                                    "required": [r for r in base.required if r != "t"]})
        else:
            raise IngestError("this source needs a column mapping: --preset NAME or --map t=COL,x=COL,...")
        return base.with_units(time_unit=self.time_unit, length_unit=self.length_unit, angle_unit=self.angle_unit,
                               feed_unit=self.feed_unit, timezone=self.timezone, time_format=self.time_format)


def split_source(source: str | os.PathLike) -> tuple[str, Path]:
    """(scheme, path) from `scheme:path` or from the path's suffix."""
    text = str(source)
    m = _SCHEME.match(text)
    if m and m.group(1) in READERS:
        return m.group(1), Path(m.group(2))
    if m and not Path(text).exists():
        raise IngestError(f"unknown source scheme {m.group(1)!r}; schemes: {', '.join(READERS)}", file=text)
    path = Path(text)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise IngestError(f"no reader for suffix {suffix or '(none)'!r}; supported: {', '.join(SUFFIXES)} "
                          f"(or force one with a scheme prefix: {', '.join(s + ':' for s in READERS)})", file=text)
    return SUFFIXES[suffix], path


def read_source(source: str | os.PathLike, options: ImportOptions | None = None) -> Recording:
    """Read any supported source into a recording (not yet written anywhere)."""
    scheme, path = split_source(source)
    if not path.is_file():
        raise IngestError("no such file", file=str(path))
    return READERS.get(scheme)(path, options or ImportOptions())
