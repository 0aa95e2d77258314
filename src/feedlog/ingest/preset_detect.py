"""Which shipped preset a CSV file is, found from its header: `feedlog import FILE.csv` with neither
`--preset` nor `--map`.

A preset fits a file when every column its required targets map to (any of a target's candidate names)
is in the header, split with the preset's own delimiter after its comment lines, and it finds a position,
feed or line column there (a time column alone is no fit); among those, the one
that finds the largest share of all its mapped columns wins. No fit is the error that asks for a mapping,
with the presets' names; two equally good fits are an error naming both (the user picks one with
`--preset`). Only the first 64 KiB are read.
"""

from __future__ import annotations

import csv
from pathlib import Path

from feedlog.errors import IngestError
from feedlog.ingest.mapping import ColumnMap, load_preset, preset_names

HEAD_BYTES = 65536
MOTION = {"x", "y", "z", "a", "b", "c", "feed", "line", "block_number"}   # one of these must be found


def _header(text: str, cmap: ColumnMap) -> set[str]:
    """The header's column names as the preset would read them (its delimiter, its comment lines)."""
    for line in text.splitlines():
        if not line.strip() or (cmap.comment and line.lstrip().startswith(cmap.comment)):
            continue
        row = next(csv.reader([line], delimiter=cmap.delimiter or ","), [])
        return {name.strip() for name in row}
    return set()


def _columns(cmap: ColumnMap, target: str) -> list[str]:
    names = cmap.candidates.get(target) or [cmap.mapping[target]]
    return [str(n) for n in names]


def detect_preset(path: Path) -> str:
    """The name of the shipped preset whose columns the file's header holds (see the module text)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(HEAD_BYTES)
    except OSError as exc:
        raise IngestError(f"cannot read: {exc.strerror or exc}", file=str(path)) from None
    text = head.decode("utf-8-sig", errors="replace")
    scored: list[tuple[float, str]] = []
    for name in preset_names():
        cmap = load_preset(name)
        header = _header(text, cmap)
        if not header:
            continue
        required = [t for t in cmap.required if t in cmap.mapping]
        if not all(any(c in header for c in _columns(cmap, t)) for t in required):
            continue
        hits = {t for t in cmap.mapping if any(c in header for c in _columns(cmap, t))}
        if not hits & MOTION:   # a time column alone (a CAN log's `timestamp`) is no fit
            continue
        scored.append((len(hits) / max(1, len(cmap.mapping)), name))
    if not scored:
        raise IngestError("this source needs a column mapping: no shipped preset matches its header; give "
                          f"--preset NAME ({', '.join(preset_names())}) or --map t=COL,x=COL,...", file=str(path))
    scored.sort(reverse=True)
    if len(scored) > 1 and scored[0][0] == scored[1][0]:
        raise IngestError(f"its header fits presets {scored[0][1]} and {scored[1][1]} equally: give --preset",
                          file=str(path))
    return scored[0][1]
