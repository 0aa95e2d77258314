"""The recordings manifest: one reader and one schema for `manifest.toml` (and `held_back.toml`).

A manifest lists recorded sessions, one table per recording, in either of two spellings:

    [[recording]]                 [recording.corners_f3000]
    name = "corners_f3000"        program = "programs/corners_f3000.ngc"
    file = "corners_f3000.mcap"   ...
    ...

Every row becomes a `ManifestEntry`. The fields feedlog reads have one rule each:

- `name`: the row's `name`, else its table key, else the stem of its `file`; unique in the manifest;
- `file`: the recording, relative to the manifest's folder (`path` is accepted as another spelling);
  without one, `<name>.mcap`;
- `split`: `train` (the default) or `test`;
- `program`, `profile`, `family`: text when given; `program` is relative to the manifest's folder
  unless absolute;
- `samples`, `dropped_frames`: whole numbers >= 0; `cycle_time_s`: a finite number >= 0.

Anything else on a row is kept as written in `fields`; `entry["key"]` reads the row with the defaults
filled in. A row that breaks a
rule raises `ManifestError` naming the file, the line of the row's header and the field.
`recordings/manifest.toml` (train and test sessions), `recordings/held_back.toml` (recorded alike, kept
out of the simulation's accuracy test) and `recordings/interp/manifest.toml` (keyed tables) are read by
the demo, `feedlog train`, the benchmarks, the scripts and the tests through `read_manifest`.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from feedlog.errors import LocatedError

MANIFEST = "manifest.toml"
HELD_BACK = "held_back.toml"
SPLITS = ("train", "test")
TEXT_FIELDS = ("program", "profile", "family")
COUNT_FIELDS = ("samples", "dropped_frames")
SECONDS_FIELDS = ("cycle_time_s",)


class ManifestError(LocatedError):
    """A recordings manifest that cannot be used: names the file, the row's line and the field."""


@dataclass(frozen=True)
class ManifestEntry:
    """One recording of a manifest."""

    name: str
    file: str                                # as written, relative to `folder`
    folder: Path                             # the manifest's folder
    split: str = "train"
    program: str | None = None               # as written
    profile: str | None = None               # a shipped profile's name or a path
    family: str = ""
    fields: Mapping[str, Any] = field(default_factory=dict)   # the whole row as written
    line: int | None = None                  # line of the row's table header in the manifest

    @property
    def path(self) -> Path:
        """The recording file."""
        return self.folder / self.file

    @property
    def program_path(self) -> Path | None:
        """The part program file, when the row names one."""
        return None if self.program is None else self.folder / self.program

    @property
    def expected(self) -> dict[str, Any]:
        """What the manifest says was recorded: samples, dropped frames, cycle time (those given)."""
        return {k: self.fields[k] for k in (*COUNT_FIELDS, *SECONDS_FIELDS) if k in self.fields}

    @property
    def row(self) -> dict[str, Any]:
        """The row as written with the schema's defaults filled in (`name`, `file`, `split`)."""
        return {**self.fields, "name": self.name, "file": self.file, "split": self.split}

    def __getitem__(self, key: str) -> Any:
        return self.row[key]

    def __contains__(self, key: object) -> bool:
        return key in self.row

    def get(self, key: str, default: Any = None) -> Any:
        return self.row.get(key, default)


def read_manifest(path: str | Path) -> list[ManifestEntry]:
    """Every recording a manifest lists, in the order written."""
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ManifestError(f"not UTF-8 text (byte {exc.start}); TOML files are UTF-8", file=str(path)) from None
    except OSError as exc:
        raise ManifestError(f"cannot read the recordings manifest: {exc.strerror or exc}", file=str(path)) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ManifestError(f"not valid TOML: {exc}", file=str(path)) from None
    return parse_manifest(data, path=path, lines=_header_lines(text))


def read_manifests(*paths: str | Path) -> dict[str, ManifestEntry]:
    """Name -> entry over several manifests that exist; a later one's row replaces an earlier one's."""
    out: dict[str, ManifestEntry] = {}
    for p in paths:
        if Path(p).is_file():
            out.update((e.name, e) for e in read_manifest(p))
    return out


def with_held_back(manifest: str | Path) -> dict[str, ManifestEntry]:
    """Name -> entry of a manifest and of the `held_back.toml` beside it (the manifest's row wins)."""
    manifest = Path(manifest)
    return read_manifests(manifest.parent / HELD_BACK, manifest)


def parse_manifest(data: Mapping[str, Any], *, path: Path, lines: Mapping[object, int] | None = None) -> list[ManifestEntry]:
    """The entries of an already parsed manifest (`lines`: row index or key -> line of its header)."""
    lines = lines or {}
    items = data.get("recording", [])
    if isinstance(items, Mapping):
        rows: list[tuple[object, str | None, Any]] = [(k, str(k), v) for k, v in items.items()]
    elif isinstance(items, list):
        rows = [(i, None, v) for i, v in enumerate(items)]
    else:
        raise ManifestError("'recording' must be [[recording]] tables or [recording.<name>] tables", file=str(path))
    entries: list[ManifestEntry] = []
    seen: dict[str, int] = {}
    for index, (pos, key, row) in enumerate(rows):
        line = lines.get(pos, lines.get("="))   # an inline array's rows: the line of `recording = [...]`
        entry = _entry(row, key=key, index=index, folder=path.parent, where=(str(path), line))
        if entry.name in seen:
            raise ManifestError(f"recording {entry.name!r} is listed twice (rows {seen[entry.name]} and {index + 1})",
                                file=str(path), line=line)
        seen[entry.name] = index + 1
        entries.append(entry)
    return entries


def _entry(row: Any, *, key: str | None, index: int, folder: Path, where: tuple[str, int | None]) -> ManifestEntry:
    file_name, line = where

    def fail(message: str) -> ManifestError:
        return ManifestError(f"recording entry {index + 1}: {message}", file=file_name, line=line)

    if not isinstance(row, Mapping):
        raise fail(f"a table expected, got {type(row).__name__}")
    text = {k: row[k] for k in ("name", "file", "path", "split", *TEXT_FIELDS) if k in row}
    for k, v in text.items():
        if not isinstance(v, str) or not v.strip():
            raise fail(f"'{k}' must be non-empty text, got {v!r}")
    file = text.get("file") or text.get("path")
    name = text.get("name") or key or (Path(file).stem if file else None)
    if not name:
        raise fail("has neither 'name' nor 'file'")
    split = text.get("split", "train")
    if split not in SPLITS:
        raise fail(f"split must be one of {', '.join(SPLITS)}, got {split!r}")
    for k in COUNT_FIELDS:
        if k in row and (isinstance(row[k], bool) or not isinstance(row[k], int) or row[k] < 0):
            raise fail(f"'{k}' must be a whole number >= 0, got {row[k]!r}")
    for k in SECONDS_FIELDS:
        v = row.get(k)
        if k in row and (isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v < 0):
            raise fail(f"'{k}' must be a finite number of seconds >= 0, got {v!r}")
    return ManifestEntry(name=name, file=file or f"{name}.mcap", folder=folder, split=split,
                         program=text.get("program"), profile=text.get("profile"), family=text.get("family", ""),
                         fields=dict(row), line=line)


_ARRAY_HEADER = re.compile(r"^\s*\[\[\s*recording\s*\]\]")
_INLINE = re.compile(r"^\s*recording\s*=")
_TABLE_HEADER = re.compile(r"""^\s*\[\s*recording\s*\.\s*(?:"([^"]*)"|'([^']*)'|([A-Za-z0-9_-]+))\s*\]""")


def _header_lines(text: str) -> dict[object, int]:
    """Row index ([[recording]]) or key ([recording.<key>]) -> 1-based line of its header ("=": the line
    of an inline `recording = [...]`)."""
    out: dict[object, int] = {}
    rows = 0
    for number, line in enumerate(text.split("\n"), start=1):   # TOML's newlines (splitlines would also split at U+2028)
        if _ARRAY_HEADER.match(line):
            out[rows] = number
            rows += 1
            continue
        if _INLINE.match(line):
            out.setdefault("=", number)
            continue
        m = _TABLE_HEADER.match(line)
        if m:
            out.setdefault(next(g for g in m.groups() if g is not None), number)
    return out
