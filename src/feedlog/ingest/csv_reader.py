"""CSV readers (pyarrow.csv): low-rate monitoring exports and high-rate servo traces.

A `ColumnMap` (a preset or `--map`) names the time column and the value columns with their units.
Fast path: pyarrow parses only the mapped columns, typed, on all cores. If anything is wrong (a row
with the wrong number of fields, a value that is not a finite number within +-MAX_ABS_VALUE (1e12: a
corrupt 1e20 is not a position), an empty cell, a time beyond
int64 nanoseconds, time going backwards) the file is read again in a diagnostic pass that knows every
row's line number: strict mode (the default) raises `IngestError` naming the file, the first bad line
and the count; lenient mode drops and counts the bad rows and lists their lines in
`metadata["bad_rows"]`. Header names are taken without surrounding spaces (and without a UTF-8 BOM);
lines may end in LF, CR LF or a lone CR.

A fixed-rate export without a time column (`ColumnMap.rate_hz`, `--rate-hz`) gets t = data row index /
rate: the row's place in the file, so a row dropped as bad leaves its slot empty rather than pulling the
rows after it earlier. Only for exports written at a fixed rate (the metadata says so); a jittery stream
needs its own time column.
"""

from __future__ import annotations

import csv
import os
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.csv as pacsv

from feedlog.errors import IngestError
from feedlog.ingest.mapping import ColumnMap, build_streams, time_to_ns
from feedlog.ingest.preset_detect import detect_preset
from feedlog.recording import Recording
from feedlog.units import MAX_ABS_T_NS, MAX_ABS_VALUE, time_factor

_OFFSET = re.compile(r"(Z|[+-]\d\d:?\d\d)$")
SHOW_LINES = 10  # bad line numbers quoted in messages
# bytes pyarrow parses per block (one block per thread at a time): 1 MiB parses in 8-9 % fewer CPU-seconds
# than 8 MiB on 2 M servo-trace rows (the block and its numbers stay in a core's 2 MiB L2 cache)
BLOCK_SIZE = 1 << 20


@dataclass
class BadRows:
    """Rows the reader could not use: count, line numbers and the first reason."""

    lines: list[int] = field(default_factory=list)
    reasons: dict[int, str] = field(default_factory=dict)

    def add(self, lines, reason: str) -> None:
        for line in np.asarray(lines, dtype=np.int64).tolist():
            self.reasons.setdefault(line, reason)
        self.lines = sorted(self.reasons)

    def __len__(self) -> int:
        return len(self.lines)

    def describe(self) -> str:
        shown = ", ".join(str(n) for n in self.lines[:SHOW_LINES])
        more = f" (+{len(self.lines) - SHOW_LINES} more)" if len(self.lines) > SHOW_LINES else ""
        return f"{len(self.lines)} bad rows at lines {shown}{more}; first: {self.reasons[self.lines[0]]}"


def _header(path: Path, delimiter: str, comment: str = "#") -> tuple[int, list[str]]:
    """(1-based line number of the header, column names); leading comment (`comment`, default '#') and
    blank lines skipped."""
    with open(path, "rb") as f:
        if f.read(2) in (b"\xff\xfe", b"\xfe\xff"):
            raise IngestError("the file is UTF-16 text (it starts with a UTF-16 byte-order mark); save it as "
                              "UTF-8", file=str(path), line=1)
    with open(path, newline="", encoding="utf-8-sig", errors="replace") as f:
        for number, text in enumerate(f, start=1):
            if text.strip() and not text.lstrip().startswith(comment):
                names = [name.strip() for name in next(csv.reader([text], delimiter=delimiter))]
                return number, names
    raise IngestError("empty CSV file (no header row)", file=str(path), line=1)


def read_csv(path: str | os.PathLike, cmap: ColumnMap, *, strict: bool = True, delimiter: str | None = None) -> Recording:
    """Read one CSV file into a recording using `cmap` (columns and units). `delimiter`: the field
    delimiter (default: the mapping's, else ",")."""
    path = Path(path)
    if not path.is_file():
        raise IngestError("no such file", file=str(path))
    delimiter = delimiter or cmap.delimiter or ","
    header_line, names = _header(path, delimiter, cmap.comment)
    cmap = cmap.resolve(names, file=str(path), line=header_line)
    absent = [f"{t}={cmap.mapping[t]}" for t in cmap.required if cmap.mapping[t] not in names]
    if absent:
        raise IngestError(f"{cmap.name}: columns not in the file: {', '.join(absent)}; the file has: "
                          f"{', '.join(names[:30])}", file=str(path), line=header_line)
    used = {target: source for target, source in cmap.mapping.items() if source in names}
    if len(used) < (1 if cmap.rate_hz else 2):
        raise IngestError(f"{cmap.name}: no mapped value column is in the file; the file has: "
                          f"{', '.join(names[:30])}", file=str(path), line=header_line)
    twice = next((source for source in used.values() if names.count(source) > 1), None)
    if twice:
        raise IngestError(f"column {twice!r} appears twice in the header", file=str(path), line=header_line)
    table = _fast_read(path, header_line, names, used, cmap, delimiter)
    columns = None if table is None else _columns(table, used, cmap)
    bad = BadRows()
    if columns is None:
        t_ns, values, lines = _diagnostic_read(path, header_line, names, used, cmap, delimiter, bad)
    else:
        (t_ns, values), lines = columns, None
    if cmap.rate_hz:  # t_ns holds each row's index among the data rows
        t_ns = np.rint(t_ns.astype(np.float64) * (1e9 / cmap.rate_hz)).astype(np.int64)
    dt = np.diff(t_ns)
    back = _backwards(t_ns, dt)
    if len(back):
        if lines is None:
            lines = _data_lines(path, header_line)
        bad.add(lines[back], "time goes backwards")
    if len(bad) and strict:
        raise IngestError(f"{bad.describe()} (lenient import skips them: --lenient)", file=str(path),
                          line=bad.lines[0])
    if len(t_ns) - len(back) == 0:
        raise IngestError("no data rows" + (f" left ({bad.describe()})" if len(bad) else " after the header"),
                          file=str(path), line=header_line)
    if len(back):
        keep = np.ones(len(t_ns), dtype=bool)
        keep[back] = False
        t_ns, values = t_ns[keep], {k: v[keep] for k, v in values.items()}
        dt = np.diff(t_ns)
    metadata = {"source": path.name, **cmap.metadata(), "rows": str(len(t_ns))}
    if cmap.controller:
        metadata["controller"] = cmap.controller
    if len(bad):
        metadata["bad_rows"] = bad.describe()
    if len(t_ns) > 1:
        med = float(np.median(dt, overwrite_input=True))   # dt is not needed after this
        if med > 0:
            metadata["nominal_rate_hz"] = f"{1e9 / med:.6g}"
    if cmap.time_unit == "datetime" and len(t_ns):
        metadata["start_time"] = pd.Timestamp(int(t_ns[0]), tz="UTC").isoformat()
    # every array here is fresh (pyarrow's columns joined, or filtered copies): the streams take them as they are
    return Recording(streams=build_streams(t_ns, values, cmap, owned=True), metadata=metadata, source=str(path))


def _time_type(cmap: ColumnMap) -> pa.DataType:
    if cmap.time_unit == "datetime":
        return pa.string()
    return pa.int64() if cmap.time_unit == "ns" else pa.float64()


def _fast_read(path: Path, header_line: int, names: list[str], used: dict[str, str], cmap: ColumnMap,
               delimiter: str) -> pa.Table | None:
    """Typed multi-threaded read; None when the file needs the diagnostic pass."""
    invalid = 0

    def on_invalid(row) -> str:
        nonlocal invalid
        invalid += 1
        return "skip"

    types = {source: pa.float64() for source in used.values()}
    if "t" in used:
        types[used["t"]] = _time_type(cmap)
    try:
        table = pacsv.read_csv(
            path,
            read_options=pacsv.ReadOptions(skip_rows=header_line, column_names=_unique(names), block_size=BLOCK_SIZE),
            parse_options=pacsv.ParseOptions(delimiter=delimiter, invalid_row_handler=on_invalid),
            convert_options=pacsv.ConvertOptions(column_types=types, include_columns=list(dict.fromkeys(used.values())),
                                                 strings_can_be_null=False, quoted_strings_can_be_null=False,
                                                 decimal_point=cmap.decimal))
    except pa.ArrowException:
        return None
    if invalid or any(table.column(source).null_count for source in set(used.values())):
        return None
    return table  # NaN, infinite and out-of-range values are found on the numbers (`_columns`)


def _unique(names: list[str]) -> list[str]:
    """Column names for pyarrow: repeated names (never mapped, see read_csv) made unique."""
    seen: dict[str, int] = {}
    out = []
    for name in names:
        seen[name] = seen.get(name, 0) + 1
        out.append(name if seen[name] == 1 else f"{name}\0{seen[name]}")
    return out


def _in_range(values: np.ndarray) -> bool:
    """Every value a finite number within +-MAX_ABS_VALUE: from the minimum and maximum (a NaN makes both
    NaN, which fails the comparison), two passes without a copy."""
    return not len(values) or bool(values.min() >= -MAX_ABS_VALUE and values.max() <= MAX_ABS_VALUE)


def _joined(column: pa.ChunkedArray) -> np.ndarray:
    """A numeric column without nulls as one fresh numpy array: the chunks' buffers viewed and joined by
    numpy (one copy; ChunkedArray.to_numpy took ~2.7 x as long on 1 MiB blocks)."""
    if not column.num_chunks:
        return column.to_numpy()
    return np.concatenate([chunk.to_numpy() for chunk in column.chunks])


def _columns(table: pa.Table, used: dict[str, str], cmap: ColumnMap) -> tuple[np.ndarray, dict[str, np.ndarray]] | None:
    """(t_ns or row index, target -> numbers) from the typed table, each column converted once; None when
    a value is NaN, infinite or beyond +-MAX_ABS_VALUE (1e20 is no position), or a time is not a time: the
    diagnostic pass reads the file again and names the lines."""
    arrays = {}
    for source in dict.fromkeys(used.values()):
        column = table.column(source)
        if not (pa.types.is_floating(column.type) or pa.types.is_integer(column.type)):
            arrays[source] = column.to_numpy(zero_copy_only=False)    # wall-clock times, as text
            continue
        arrays[source] = _joined(column)
        if pa.types.is_floating(column.type) and not _in_range(arrays[source]):
            return None
    if "t" not in used:  # fixed rate: the row index (read_csv turns it into time)
        return np.arange(table.num_rows, dtype=np.int64), {target: arrays[source] for target, source in used.items()}
    if cmap.time_unit == "datetime":
        t_ns, ok = _parse_datetimes(arrays[used["t"]], cmap)
    else:
        t_ns, ok = _times(arrays[used["t"]], cmap)
    if not ok.all():
        return None
    return t_ns, {target: arrays[source] for target, source in used.items() if target != "t"}


def _times(values: np.ndarray, cmap: ColumnMap) -> tuple[np.ndarray, np.ndarray]:
    """Numeric times -> (int64 ns, ok mask): NaN, infinite and out-of-range times are not ok (0 there)."""
    if len(values):  # all in range (the common case): known from the extremes, no mask computed
        scale, limit = time_factor(cmap.time_unit), MAX_ABS_T_NS / 1e9
        if abs(float(values.min()) * scale) <= limit and abs(float(values.max()) * scale) <= limit:
            return time_to_ns(values, cmap), np.ones(len(values), dtype=bool)
    if values.dtype.kind in "iu":
        seconds = values.astype(np.float64) * time_factor(cmap.time_unit)
    else:
        seconds = values * time_factor(cmap.time_unit)
    ok = np.abs(seconds) <= MAX_ABS_T_NS / 1e9  # False for NaN
    return time_to_ns(np.where(ok, values, 0), cmap), ok


def _parse_datetimes(text: np.ndarray, cmap: ColumnMap) -> tuple[np.ndarray, np.ndarray]:
    """Wall-clock strings -> (int64 ns since the epoch, ok mask). Naive times are in `cmap.timezone`."""
    series = pd.Series(text, dtype=object)
    sample = next((s for s in series if isinstance(s, str) and s.strip()), "")
    aware = bool(_OFFSET.search(sample.strip()))
    try:
        parsed = pd.to_datetime(series, format=cmap.time_format or "ISO8601", errors="coerce", utc=aware)
        if not aware:
            parsed = parsed.dt.tz_localize(cmap.timezone, ambiguous="NaT", nonexistent="NaT")
    except (ValueError, TypeError) as exc:
        raise IngestError(f"cannot read times with --time-format {cmap.time_format!r}: {exc}") from None
    ok = parsed.notna().to_numpy()
    t_ns = np.zeros(len(series), dtype=np.int64)
    t_ns[ok] = parsed[ok].dt.tz_convert("UTC").dt.tz_localize(None).to_numpy().astype("datetime64[ns]").astype(np.int64)
    ok = ok & (np.abs(t_ns) <= MAX_ABS_T_NS)
    return t_ns, ok


def _diagnostic_read(path: Path, header_line: int, names: list[str], used: dict[str, str], cmap: ColumnMap,
                     delimiter: str, bad: BadRows) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """Single-threaded read as text with line numbers; bad rows go to `bad` and are dropped."""
    wrong_width: list[tuple[int, str]] = []

    def on_invalid(row) -> str:
        wrong_width.append((row.number, f"expected {row.expected_columns} fields, got {row.actual_columns}"))
        return "skip"

    sources = list(dict.fromkeys(used.values()))
    try:  # as bytes: a cell that is not even UTF-8 is a bad value, not a crash
        table = pacsv.read_csv(
            path,
            read_options=pacsv.ReadOptions(skip_rows=header_line, column_names=_unique(names), use_threads=False),
            parse_options=pacsv.ParseOptions(delimiter=delimiter, invalid_row_handler=on_invalid),
            convert_options=pacsv.ConvertOptions(column_types={s: pa.binary() for s in sources},
                                                 include_columns=sources))
    except pa.ArrowException as exc:
        raise IngestError(f"unreadable CSV: {exc}", file=str(path)) from None
    lines = _data_lines(path, header_line)
    all_lines = lines
    # pyarrow numbers a row as skip_rows + 1 (header) + its 1-based index among non-empty data rows
    dropped = np.array([number - header_line - 1 for number, _ in wrong_width], dtype=np.int64)
    for (_, reason), index in zip(wrong_width, dropped):
        bad.add([lines[index]] if index < len(lines) else [], reason)
    lines = np.delete(lines, dropped[dropped < len(lines)])[: table.num_rows]
    keep = np.ones(table.num_rows, dtype=bool)
    converted: dict[str, np.ndarray] = {}
    for target, source in used.items():
        raw = pd.Series(table.column(source).to_numpy(zero_copy_only=False), dtype=object)
        text = raw.str.decode("utf-8", errors="replace").to_numpy(dtype=object)
        if target == "t" and cmap.time_unit == "datetime":
            values, ok = _parse_datetimes(text, cmap)
            kind = "timestamp"
        else:
            cells = pd.Series(text, dtype=object).str.strip()
            if cmap.decimal == ",":
                cells = cells.str.replace(",", ".", regex=False)
            values = pd.to_numeric(cells, errors="coerce").to_numpy(np.float64)
            ok = np.abs(values) <= MAX_ABS_VALUE  # False for NaN
            kind = f"finite number within +-{MAX_ABS_VALUE:g}"
            if target == "t":
                values, ok = _times(values, cmap)
                kind = "time (a finite number within +-146 years)"
        if not ok.all():
            first = int(np.flatnonzero(~ok)[0])
            bad.add(lines[~ok], f"column {source!r}: {text[first]!r} is not a {kind}")
        keep &= ok
        converted[target] = values
    if "t" in converted:
        t_ns = converted.pop("t")[keep]
    else:  # fixed rate: each kept row's index among all data rows
        t_ns = np.searchsorted(all_lines, lines[keep]).astype(np.int64)
    return t_ns, {k: v[keep] for k, v in converted.items()}, lines[keep]


def _data_lines(path: Path, header_line: int) -> np.ndarray:
    """1-based line numbers of the non-empty lines after the header (one per data row). A line ends
    at LF, at CR LF or at a lone CR, as pyarrow's parser reads them."""
    raw = np.frombuffer(path.read_bytes(), dtype=np.uint8)
    lf = raw == ord("\n")
    cr = raw == ord("\r")
    lone_cr = cr & ~np.r_[lf[1:], False]
    ends = np.flatnonzero(lf | lone_cr)
    starts = np.concatenate(([0], ends + 1))
    ends = np.concatenate((ends, [len(raw)]))
    length = ends - starts
    has_cr = (length > 0) & cr[np.maximum(ends - 1, 0)] if len(raw) else np.zeros(0, bool)
    numbers = np.arange(1, len(starts) + 1)
    return numbers[(numbers > header_line) & ((length - has_cr) > 0)]


def _backwards(t_ns: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """Indices of rows earlier than a row before them (dropping these leaves t_ns non-decreasing); `dt`:
    np.diff(t_ns)."""
    if len(t_ns) < 2 or dt.min() >= 0:
        return np.zeros(0, dtype=np.int64)
    running = np.maximum.accumulate(t_ns)
    return np.flatnonzero(t_ns[1:] < running[:-1]) + 1


def read_csv_source(path: Path, options) -> Recording:
    """Registry entry (`.csv`, `.tsv`, `csv:`): `options` is an `ImportOptions`."""
    delimiter = options.delimiter or ("\t" if path.suffix.lower() == ".tsv" else None)
    found = None if options.preset or options.mapping else detect_preset(path)
    cmap = options.column_map(default_preset=found)
    if found is not None:   # said in the `mapped:` line `feedlog import` prints
        cmap = replace(cmap, name=f"preset {found}, found from the header")
    return read_csv(path, cmap, strict=options.strict, delimiter=delimiter)
