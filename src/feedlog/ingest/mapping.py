"""Column mappings: which source field feeds which recording column, in which unit.

A mapping is `target -> source field`, given on the command line (`--map t=time,x=X1_ActualPosition`)
or by a named preset (`ingest/presets/<name>.toml`). Targets are short names of standard columns
(`t`, `x` .. `c`, `feed`, `requested_feed`, `vx`/`vy`/`vz` (axis velocities, mm/s), `line`, `block_number`, `jN`,
`jN_fb`, `in_position`,
`motion_type`, `spindle`, `feed_override`/`rapid_override` (percent in, a fraction out), `tool`) or an explicit `stream.column` kept as is. Units are declared, never guessed:
lengths, angles, feeds and times are converted here to mm, deg, mm/min and int64 ns.

A preset may list several source names for a target (`x = ["Xact", "Xabs"]`, controllers and adapters
spell the same signal differently): `ColumnMap.resolve(names)` takes the first one the source has and
says which in the metadata. A preset may also fix the CSV `delimiter` and the `decimal` mark.
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass, field
from importlib import resources

import numpy as np
import pandas as pd

from feedlog.errors import IngestError, UnitError
from feedlog.units import angle_factor, length_factor, time_factor, velocity_factor

# target -> (stream, column, kind); kind picks the unit conversion and the dtype
TARGETS: dict[str, tuple[str, str, str]] = {
    "x": ("axes", "x_mm", "length"), "y": ("axes", "y_mm", "length"), "z": ("axes", "z_mm", "length"),
    "a": ("axes", "a_deg", "angle"), "b": ("axes", "b_deg", "angle"), "c": ("axes", "c_deg", "angle"),
    "feed": ("feed", "feed_mm_min", "velocity"),
    "requested_feed": ("feed", "requested_feed_mm_min", "velocity"),
    # the controller's own axis velocities, mm/s as recorded (not converted: a witness for the feed's
    # declared unit must not depend on it; MTConnect's AXIS_FEEDRATE and the UMich columns are mm/s)
    "vx": ("velocity", "x_mm_s", "float"), "vy": ("velocity", "y_mm_s", "float"),
    "vz": ("velocity", "z_mm_s", "float"),
    "line": ("line", "line", "int"),
    "block_number": ("line", "block_number", "int"),  # the controller's N word (align maps it to lines)
    "in_position": ("status", "in_position", "bool"),
    "motion_type": ("status", "motion_type", "int8"),
    "spindle": ("spindle", "spindle_rpm", "float"),
    # override dials (MTConnect PATH_FEEDRATE_OVERRIDE, PERCENT): the fraction, 1.0 = 100 %, as the
    # simulation's `sim.feed_override.override` / `sim.rapid_override.override` spell it
    "feed_override": ("override", "feed_override", "percent"),
    "rapid_override": ("override", "rapid_override", "percent"),
    "tool": ("tool", "tool", "int"),   # the tool in the spindle (an event: it changes at a tool change)
}
_JOINT = re.compile(r"^j(\d+)(_fb)?$")
_EXPLICIT = re.compile(r"^([a-z][a-z0-9_]*)\.([a-z][a-z0-9_]*)$")
TIME_UNITS = ("s", "ms", "us", "ns", "datetime")
_VECTOR_ITEM = re.compile(r"^(.*)\[\d\]$")


def resolve_target(target: str) -> tuple[str, str, str]:
    """(stream, column, kind) for a mapping target; IngestError listing the known ones otherwise."""
    if target in TARGETS:
        return TARGETS[target]
    m = _JOINT.match(target)
    if m:
        return ("joints", f"j{m.group(1)}_pos" + ("_fb" if m.group(2) else ""), "float")
    m = _EXPLICIT.match(target)
    if m:
        return (m.group(1), m.group(2), "float")
    raise IngestError(f"unknown mapping target {target!r}; known: t, {', '.join(TARGETS)}, jN, jN_fb, "
                      "or stream.column (lower_snake_case)")


@dataclass
class ColumnMap:
    """A mapping with its declared units. `required` targets must exist in the source."""

    mapping: dict[str, str]
    time_unit: str = "s"
    length_unit: str = "mm"
    angle_unit: str = "deg"
    feed_unit: str = "mm/min"
    timezone: str = "UTC"
    time_format: str | None = None
    required: list[str] = field(default_factory=list)
    name: str = "--map"
    controller: str = ""
    candidates: dict[str, list[str]] = field(default_factory=dict)  # target -> source names, first found wins
    delimiter: str | None = None     # CSV field delimiter the source uses (None: the reader's default)
    decimal: str = "."               # decimal mark of the source's numbers
    comment: str = "#"               # lines before the header starting with this are comments
    rate_hz: float | None = None     # fixed-rate source without a time column: t = row index / rate_hz

    def __post_init__(self) -> None:
        if self.rate_hz is not None:
            if not (isinstance(self.rate_hz, (int, float)) and 0 < self.rate_hz <= 1e9):
                raise IngestError(f"mapping {self.name}: rate_hz must be a number of samples per second in "
                                  f"(0, 1e9], got {self.rate_hz!r}")
            if "t" in self.mapping:
                raise IngestError(f"mapping {self.name} names a time column (t={self.mapping['t']}) and a fixed "
                                  f"rate ({self.rate_hz:g} Hz): give one of them")
            if not self.mapping:
                raise IngestError(f"mapping {self.name} maps no value column")
            self.time_unit = "s"
        elif "t" not in self.mapping:
            raise IngestError(f"mapping {self.name} has no time column: add t=<column>, or give the sampling "
                              "rate of a file without one (--rate-hz)")
        elif len(self.mapping) < 2:
            raise IngestError(f"mapping {self.name} maps only the time column; map at least one value")
        if self.time_unit not in TIME_UNITS:
            raise IngestError(f"time unit {self.time_unit!r} is not one of {', '.join(TIME_UNITS)}")
        try:
            length_factor(self.length_unit), angle_factor(self.angle_unit), velocity_factor(self.feed_unit)
        except UnitError as exc:
            raise IngestError(f"mapping {self.name}: {exc}") from None
        try:  # the zone pandas localises naive wall-clock times in
            pd.Timestamp("2000-01-01").tz_localize(self.timezone)
        except Exception:  # noqa: BLE001 - pytz, zoneinfo and dateutil raise their own kinds
            raise IngestError(f"unknown time zone {self.timezone!r} (--timezone): give an IANA name such as "
                              "Europe/Berlin, or UTC") from None
        for target in self.mapping:
            if target != "t":
                resolve_target(target)
        missing = [r for r in self.required if r not in self.mapping]
        if missing:
            raise IngestError(f"mapping {self.name}: required targets {missing} are not mapped")
        if not self.required:
            self.required = list(self.mapping)
        if self.delimiter is not None and len(self.delimiter) != 1:
            raise IngestError(f"mapping {self.name}: delimiter must be one character, got {self.delimiter!r}")
        if not self.comment:
            raise IngestError(f"mapping {self.name}: comment must be a non-empty prefix, got {self.comment!r}")
        if self.decimal not in (".", ","):
            raise IngestError(f"mapping {self.name}: decimal must be '.' or ',', got {self.decimal!r}")

    def resolve(self, names, *, file: str | None = None, line: int | None = None) -> ColumnMap:
        """The mapping for a source whose fields are `names`: each target with candidates takes the
        first candidate present (targets none of whose candidates exist are left out, unless required:
        then the first candidate stays, so the reader names it as missing). `file`/`line`: where the
        names come from, for the error when no value field is left."""
        if not self.candidates:
            return self
        present = set(names)
        if not any(o in present for options in self.candidates.values() for o in options) and \
                not any(s in present for t, s in self.mapping.items() if t != "t" and t not in self.candidates):
            # `KEY[i]` (the i-th number of a vector value) are offered for every KEY: name the KEYs only
            items = {n: _VECTOR_ITEM.match(n) for n in present}
            real = sorted(n for n, m in items.items() if not (m and m.group(1) in present))
            shown = ", ".join(real[:30]) + (f", ... ({len(real)} in all)" if len(real) > 30 else "")
            raise IngestError(f"{self.name}: none of the fields it maps is in the source; it has: {shown or 'none'}",
                              file=file, line=line)
        mapping = dict(self.mapping)
        for target, options in self.candidates.items():
            found = next((o for o in options if o in present), None)
            if found is not None:
                mapping[target] = found
            elif target not in self.required:
                mapping.pop(target, None)
        return ColumnMap(**{**self.__dict__, "mapping": mapping, "candidates": {}})

    def with_units(self, **units: str | None) -> ColumnMap:
        """A copy with the given units replaced (None keeps the current one)."""
        changes = {k: v for k, v in units.items() if v is not None}
        return ColumnMap(**{**self.__dict__, **changes})

    def metadata(self) -> dict[str, str]:
        time = f"row index / {self.rate_hz:g} Hz (no time column)" if self.rate_hz else self.time_unit
        return {"units": f"length {self.length_unit}->mm, angle {self.angle_unit}->deg, "
                         f"feed {self.feed_unit}->mm/min, time {time}", "mapping": self.name,
                "columns": ",".join(f"{t}={s}" for t, s in self.mapping.items())}


def parse_map(text: str) -> dict[str, str]:
    """`t=time,x=X1_ActualPosition` -> {"t": "time", "x": "X1_ActualPosition"}. Commas inside brackets
    belong to the column name (`x=/Channel/GeometricAxis/actToolBasePos[u1,1]`)."""
    mapping: dict[str, str] = {}
    for item in filter(None, (part.strip() for part in re.split(r",(?![^\[]*\])", text))):
        target, sep, source = item.partition("=")
        if not sep or not target.strip() or not source.strip():
            raise IngestError(f"--map entry {item!r} is not TARGET=COLUMN")
        mapping[target.strip()] = source.strip()
    return mapping


def preset_names() -> list[str]:
    folder = resources.files("feedlog.ingest") / "presets"
    return sorted(p.name.removesuffix(".toml") for p in folder.iterdir() if p.name.endswith(".toml"))


def load_preset(name: str) -> ColumnMap:
    path = resources.files("feedlog.ingest") / "presets" / f"{name}.toml"
    if not path.is_file():
        raise IngestError(f"unknown preset {name!r}; presets: {', '.join(preset_names())}")
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    mapping = data.pop("map")
    data.pop("description", None)
    candidates = {t: list(v) for t, v in mapping.items() if isinstance(v, list)}
    mapping = {t: (v[0] if isinstance(v, list) else v) for t, v in mapping.items()}
    return ColumnMap(mapping=mapping, name=f"preset {name}", candidates=candidates, **data)


def preset_description(name: str) -> str:
    path = resources.files("feedlog.ingest") / "presets" / f"{name}.toml"
    return tomllib.loads(path.read_text(encoding="utf-8")).get("description", "")


def _scaled(values: np.ndarray, factor: float) -> np.ndarray:
    """float64 `values` x `factor`; `values` itself (float64 already) for a factor of 1, which changes no bit."""
    values = values.astype(np.float64, copy=False)
    return values if factor == 1.0 else values * factor


def convert(values: np.ndarray, kind: str, cmap: ColumnMap) -> np.ndarray:
    """Source values (float64 or int64) -> the target column in feedlog units and dtype (may be `values`
    itself when nothing changes)."""
    if kind == "length":
        return _scaled(values, length_factor(cmap.length_unit))
    if kind == "angle":
        return _scaled(values, angle_factor(cmap.angle_unit))
    if kind == "velocity":
        return _scaled(values, velocity_factor(cmap.feed_unit))
    if kind == "int":
        return np.rint(values).astype(np.int64)
    if kind == "int8":
        return np.rint(values).astype(np.int8)
    if kind == "bool":
        return values.astype(np.float64) != 0
    if kind == "percent":
        return values.astype(np.float64) / 100.0
    return values.astype(np.float64, copy=False)


def time_to_ns(values: np.ndarray, cmap: ColumnMap) -> np.ndarray:
    """Numeric time in the declared unit (or datetime64[ns]) -> int64 ns."""
    if cmap.time_unit == "datetime":
        return values.astype("datetime64[ns]").astype(np.int64)
    if cmap.time_unit == "ns" and values.dtype.kind in "iu":
        return values.astype(np.int64)
    ns = values.astype(np.float64, copy=False) * (time_factor(cmap.time_unit) * 1e9)
    return np.rint(ns, out=ns).astype(np.int64)


def build_streams(t_ns: np.ndarray, values: dict[str, np.ndarray], cmap: ColumnMap, *,
                  owned: bool = False) -> dict[str, pd.DataFrame]:
    """Group converted target columns into their streams, each with the shared `t_ns`. `owned`: the
    arrays are the caller's to give away (fresh columns nobody else holds): the streams take them without
    a copy, except an array that is read-only or shares memory with one already taken (`t_ns` in a second
    stream, a column mapped twice), which is copied, so no two columns alias and every column can be
    written. Otherwise pandas copies every column (its default for a dict)."""
    grouped: dict[str, dict[str, np.ndarray]] = {}
    for target, raw in values.items():
        stream, column, kind = resolve_target(target)
        try:
            converted = convert(raw, kind, cmap)
        except (TypeError, ValueError) as exc:   # a text column (e.g. the wall-clock time) mapped to a number
            source = cmap.mapping.get(target, target)
            raise IngestError(f"{cmap.name}: {target}={source}: the column does not hold numbers "
                              f"({str(exc).splitlines()[0]})") from None
        grouped.setdefault(stream, {"t_ns": t_ns})[column] = converted
    if not owned:
        return {stream: pd.DataFrame(cols) for stream, cols in grouped.items()}
    taken: list[np.ndarray] = []
    for cols in grouped.values():
        for name, array in cols.items():
            if not array.flags.writeable or any(np.may_share_memory(array, other) for other in taken):
                array = cols[name] = array.copy()
            taken.append(array)
    return {stream: pd.DataFrame(cols, copy=False) for stream, cols in grouped.items()}
