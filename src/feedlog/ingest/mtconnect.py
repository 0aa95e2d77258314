"""MTConnect (SHDR text, Streams XML) -> a feedlog recording: wide columns, held values, units.

MTConnect reports a data item only when it changes, each with its own timestamp. `pivot` turns the
long observations into one row per distinct time of any mapped data item, each column holding its
last value (forward fill: what the agent itself would answer at that time). `UNAVAILABLE` (the agent
knows no value: adapter disconnected, machine off) empties a column until its next value; rows of a
stream with an empty column are left out and counted (`unavailable`), never filled with a guess.

Which data item feeds which column:
- `--map x=Xabs,y=Yabs,feed=path_feed,line=line` (names or dataItemIds; `KEY[i]` takes the i-th
  number of a space-separated value, e.g. `x=pp[0]` of a PathPosition "x y z");
- `--preset NAME`: a preset file (`mtconnect-shdr`, the default for SHDR logs, lists the key names
  common adapters use for each target and takes the first the log has);
- Streams XML without either: by meaning (`auto_mapping`): `Position` of the Linear components X/Y/Z
  (subType ACTUAL first), `Angle` of Rotary A/B/C, `PathPosition`, `PathFeedrate` (ACTUAL -> feed,
  COMMANDED or PROGRAMMED -> requested_feed), `LineNumber`/`Line` -> line, `LineLabel` -> block_number
  (the N word; align maps it to program lines), `SpindleSpeed`/`RotaryVelocity` of a spindle -> spindle.
Units are MTConnect's standard ones unless declared: positions mm, angles deg, PathFeedrate mm/s
(an adapter that logs native units, e.g. inches and in/min, needs `--length-unit in --feed-unit in/min`;
`feedlog import` warns when the feed and the positions' speed disagree, `ingest.unit_check`).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd

from feedlog.errors import IngestError
from feedlog.ingest.mapping import ColumnMap, convert, load_preset, parse_map, resolve_target
from feedlog.ingest.mtconnect_obs import UNAVAILABLE, DataItemType, Observations
from feedlog.recording import Recording

DEFAULT_SHDR_PRESET = "mtconnect-shdr"
STANDARD_UNITS = {"length_unit": "mm", "angle_unit": "deg", "feed_unit": "mm/s"}
_INDEXED = re.compile(r"^(.*)\[(\d)\]$")
OWN_TIMES = ("override", "tool")   # streams on their own observation times, not the motion's grid
_LINEAR = re.compile(r"^([XYZ])\d*$", re.IGNORECASE)
_ROTARY = re.compile(r"^([ABC])\d*$", re.IGNORECASE)
_SUBTYPE_RANK = {"ACTUAL": 0, "": 1, "COMMANDED": 2, "PROGRAMMED": 3}


def auto_mapping(types: dict[str, DataItemType]) -> dict[str, str]:
    """target -> data item (id) chosen by type: see the module docstring. Ties: ACTUAL before
    COMMANDED, then document order."""
    best: dict[str, tuple[int, str]] = {}

    def offer(target: str, source: str, rank: int) -> None:
        if target not in best or rank < best[target][0]:
            best[target] = (rank, source)

    for key, ty in types.items():
        sub = ty.sub_type.upper()
        rank = _SUBTYPE_RANK.get(sub, 9)
        el, comp = ty.element, ty.component
        if el == "Position" and comp == "Linear" and _LINEAR.match(ty.component_name):
            offer(_LINEAR.match(ty.component_name).group(1).lower(), key, rank)
        elif el == "Angle" and comp == "Rotary" and _ROTARY.match(ty.component_name):
            offer(_ROTARY.match(ty.component_name).group(1).lower(), key, rank)
        elif el == "PathPosition":
            for i, axis in enumerate("xyz"):
                offer(axis, f"{key}[{i}]", 10 + rank)   # after the Linear components' own positions
        elif el == "PathFeedrate":
            if sub in ("COMMANDED", "PROGRAMMED"):
                offer("requested_feed", key, rank)
            else:
                offer("feed", key, rank)
        elif el == "LineNumber" and sub in ("", "ABSOLUTE"):
            offer("line", key, 0)
        elif el == "Line":
            offer("line", key, 1)
        elif el == "LineLabel":
            offer("block_number", key, 0)
        elif el in ("SpindleSpeed", "RotaryVelocity") and (comp == "Rotary" or "spindle" in ty.component_name.lower()):
            offer("spindle", key, rank)
    return {target: source for target, (_, source) in best.items()}


def column_map(options, obs: Observations, *, xml: bool) -> ColumnMap:
    """The mapping for these observations: --map, --preset, the type-based one (XML) or the default
    SHDR preset; units declared on the command line override the preset's (or the standard ones)."""
    units = {"length_unit": options.length_unit, "angle_unit": options.angle_unit, "feed_unit": options.feed_unit,
             "timezone": options.timezone}
    if options.mapping:
        mapping = parse_map(options.mapping)
        mapping.pop("t", None)  # MTConnect observations carry their own timestamps
        base = ColumnMap(mapping={"t": "timestamp", **mapping}, time_unit="datetime", name="--map", **STANDARD_UNITS)
    elif options.preset or not xml:
        base = load_preset(options.preset or DEFAULT_SHDR_PRESET)
    else:
        found = auto_mapping(obs.types)
        if not found:
            kinds = sorted({f"{t.component}/{t.element}" for t in obs.types.values()})[:20]
            raise IngestError("no axis positions, path feed or line in the Streams document (found: "
                              f"{', '.join(kinds)}); map data items with --map x=ID,...", file=obs.metadata.get("file"))
        base = ColumnMap(mapping={"t": "timestamp", **found}, time_unit="datetime", name="MTConnect types",
                         required=["t"], **STANDARD_UNITS)
    base = base.with_units(**units)
    names = set(obs.keys()) | {t.name for t in obs.types.values() if t.name}
    return base.resolve(names | {f"{n}[{i}]" for n in names for i in range(3)}, file=obs.metadata.get("file"), line=1)


def _source_rows(obs: Observations, source: str, alias: dict[str, str]) -> tuple[np.ndarray, int | None]:
    """Rows of `obs` for a mapping source (`KEY` or `KEY[i]`, KEY a name or id) and the index i."""
    m = _INDEXED.match(source)
    key, index = (m.group(1), int(m.group(2))) if m else (source, None)
    key = alias.get(key, key)
    return np.flatnonzero(obs.key == key), index


def _values(text: np.ndarray, index: int | None, kind: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Observation texts -> (float values, unavailable mask, bad mask)."""
    series = pd.Series(text, dtype=object).fillna("").astype(str).str.strip()
    unavailable = (series.str.upper() == UNAVAILABLE).to_numpy()
    if index is not None:
        series = series.str.split(r"\s+", regex=True).str[index].fillna("")
    if kind == "int":  # a block label `N120` or a line number
        series = series.str.replace(r"^[Nn]", "", regex=True)
    values = pd.to_numeric(series, errors="coerce").to_numpy(np.float64)
    bad = ~np.isfinite(values) & ~unavailable
    if kind == "int":
        bad |= np.isfinite(values) & ((np.abs(values) > 2**53) | (values != np.rint(values)))
    return np.where(bad | unavailable, np.nan, values), unavailable, bad


def pivot(obs: Observations, cmap: ColumnMap, *, strict: bool, file: str) -> tuple[dict[str, pd.DataFrame], dict]:
    """Long observations -> streams (wide, forward-filled, UNAVAILABLE respected) and metadata."""
    alias = {t.name: key for key, t in obs.types.items() if t.name}
    targets = {t: s for t, s in cmap.mapping.items() if t != "t"}
    found: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    missing = []
    for target, source in targets.items():
        rows, index = _source_rows(obs, source, alias)
        if not len(rows):
            missing.append(f"{target}={source}")
            continue
        kind = resolve_target(target)[2]
        values, unavailable, bad = _values(obs.value[rows], index, "int" if kind in ("int", "int8") else kind)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            obs.bad.add(obs.where[rows[bad]], f"{source}: {obs.value[rows[k]]!r} is not a number")
            keep = ~bad
            rows, values, unavailable = rows[keep], values[keep], unavailable[keep]
        found[target] = (obs.t_ns[rows], values, unavailable)
    required = [t for t in cmap.required if t != "t" and t in targets]
    absent = [m for m in missing if m.split("=")[0] in required]
    keys = ", ".join(obs.keys()[:30])
    if absent or not found:
        raise IngestError(f"{cmap.name}: data items not in the file: {', '.join(absent or missing)}; the file has: "
                          f"{keys}", file=file, line=1)
    if len(obs.bad) and strict:
        raise IngestError(f"{obs.bad.describe()} (lenient import skips them: --lenient)", file=file,
                          line=obs.bad.lines[0])
    by_stream: dict[str, list[str]] = {}
    for target in found:
        by_stream.setdefault(resolve_target(target)[0], []).append(target)
    # the motion streams share one grid (every observation time of theirs); a stream of its own (the dials,
    # the tool: events set by hand) keeps its own times and adds none to the others
    shared = [t for t in found if resolve_target(t)[0] not in OWN_TIMES] or list(found)
    grid = np.unique(np.concatenate([found[t][0] for t in shared]))
    filled, grids = {}, {}
    for stream, members in by_stream.items():
        grids[stream] = (np.unique(np.concatenate([found[m][0] for m in members]))
                         if stream in OWN_TIMES and len(shared) < len(found) else grid)
        for target in members:
            t, values, _ = found[target]
            at = np.searchsorted(t, grids[stream], side="right") - 1   # the last observation at or before each time
            filled[target] = np.where(at >= 0, values[np.maximum(at, 0)], np.nan)
    streams: dict[str, pd.DataFrame] = {}
    gaps: dict[str, int] = {}
    for stream, members in by_stream.items():
        ok = np.logical_and.reduce([np.isfinite(filled[m]) for m in members])
        if (~ok).any() and grids[stream] is grid:
            gaps[stream] = int((~ok).sum())
        if not ok.any():
            continue
        cols = {"t_ns": grids[stream][ok]}
        for m in members:
            _, column, kind = resolve_target(m)
            cols[column] = convert(filled[m][ok], kind, cmap)
        streams[stream] = pd.DataFrame(cols)
    if not streams:
        raise IngestError("every mapped data item is UNAVAILABLE throughout", file=file, line=1)
    meta = {"mapping_found": ",".join(f"{t}={s}" for t, s in targets.items() if t in found),
            "observations": str(int(sum(len(v[0]) for v in found.values())))}
    named = {t: obs.types[_INDEXED.sub(r"\1", s)].name for t, s in targets.items()
             if t in found and _INDEXED.sub(r"\1", s) in obs.types}
    if any(name and name != targets[t] for t, name in named.items()):   # ids (XML): say the names too
        meta["mapping_names"] = ",".join(f"{t}={name or targets[t]}" for t, name in named.items())
    if missing:
        meta["not_in_file"] = ",".join(missing)
    if gaps:
        meta["unavailable"] = (", ".join(f"{s} {n}" for s, n in gaps.items()) + f" of {len(grid)} rows without "
                               "a value (before the first value or UNAVAILABLE), left out")
    return streams, meta


def read_mtconnect(path: str | Path, options) -> Recording:
    """Read an SHDR log or a Streams XML file (by suffix: .xml is XML, anything else SHDR)."""
    from feedlog.ingest.mtconnect_shdr import read_shdr
    from feedlog.ingest.mtconnect_xml import read_streams_xml

    path = Path(path)
    head = path.read_bytes()[:512].lstrip(b"\xef\xbb\xbf \t\r\n")
    xml = path.suffix.lower() == ".xml" or head.startswith(b"<")
    timezone = options.timezone or "UTC"
    if xml:
        obs = read_streams_xml(path, timezone=timezone)
    else:
        obs = read_shdr(path, timezone=timezone, device=options.device)
    obs.metadata["file"] = str(path)
    cmap = column_map(options, obs, xml=xml)
    if not xml:  # conditions or messages carrying a mapped key are bad lines: read again knowing the keys
        wanted = {_INDEXED.sub(r"\1", s) for t, s in cmap.mapping.items() if t != "t"}
        obs = read_shdr(path, timezone=timezone, wanted=wanted, device=options.device)
    devices = [d for d in obs.metadata.get("devices", "").split(",") if d]
    if len(devices) > 1 and not options.device:
        raise IngestError(f"the file holds several devices ({', '.join(devices)}): choose one with --device",
                          file=str(path), line=1)
    if xml and options.device:
        obs = _only_device(obs, options.device, file=str(path))
    streams, meta = pivot(obs, cmap, strict=options.strict, file=str(path))
    metadata = {"source": path.name, "controller": "mtconnect", **cmap.metadata(), **obs.metadata, **meta}
    metadata.pop("file", None)
    if len(obs.bad):
        metadata["bad_records"] = obs.bad.describe()
    t0 = min(int(s["t_ns"].iloc[0]) for s in streams.values())
    metadata["start_time"] = pd.Timestamp(t0, tz="UTC").isoformat()
    return Recording(streams=streams, metadata={k: str(v) for k, v in metadata.items()}, source=str(path))


def _only_device(obs: Observations, device: str, *, file: str) -> Observations:
    """The observations of one DeviceStream (by name or uuid)."""
    mine = {key for key, t in obs.types.items() if t.device == device}
    if not mine:
        devices = sorted({t.device for t in obs.types.values()})
        raise IngestError(f"no device {device!r} in the file (devices: {', '.join(devices)})", file=file, line=1)
    keep = np.isin(obs.key, list(mine))
    return Observations(t_ns=obs.t_ns[keep], key=obs.key[keep], value=obs.value[keep], where=obs.where[keep],
                        bad=obs.bad, metadata={**obs.metadata, "devices": device},
                        types={k: t for k, t in obs.types.items() if k in mine}, place=obs.place)


def read_mtconnect_source(path: Path, options) -> Recording:
    """Registry entry (`.xml`, `.shdr`, `.txt`, `mtconnect:`)."""
    return read_mtconnect(path, options)
