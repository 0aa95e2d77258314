"""Seeded mutations of input files: the damage real files suffer and the mistakes people make.

Every function takes the bytes (or text) of a good file and a `random.Random`, so a corpus built from
the same seed is the same corpus. Byte-level damage (truncation, bit flips, inserted or lost bytes) and
text-level mistakes (line endings, a byte-order mark, another encoding, swapped or repeated lines,
numbers that do not fit, padded cells) are kept apart from any format's own structure; MCAP record
surgery lives in `mcap_edit`.
"""

from __future__ import annotations

import random

BOM = b"\xef\xbb\xbf"
HUGE_DIGITS = "9" * 320            # overflows float64 (> 1.8e308)
NON_FINITE = ("nan", "NaN", "inf", "-inf", "Infinity", "1e400", "-1e400")


def truncate(data: bytes, rng: random.Random) -> bytes:
    """The file cut at a random byte (never empty, never whole)."""
    return data[: rng.randrange(1, max(len(data) - 1, 2))]


def flip_bits(data: bytes, rng: random.Random, *, count: int = 1, start: int = 0, end: int | None = None) -> bytes:
    """`count` single-bit flips at random positions in data[start:end]."""
    out = bytearray(data)
    end = len(out) if end is None else end
    for _ in range(count):
        k = rng.randrange(start, max(end, start + 1))
        out[k] ^= 1 << rng.randrange(8)
    return bytes(out)


def insert_bytes(data: bytes, rng: random.Random, *, count: int = 4) -> bytes:
    k = rng.randrange(len(data) + 1)
    return data[:k] + bytes(rng.randrange(256) for _ in range(count)) + data[k:]


def delete_bytes(data: bytes, rng: random.Random, *, count: int = 4) -> bytes:
    k = rng.randrange(max(len(data) - count, 1))
    return data[:k] + data[k + count:]


def line_endings(data: bytes, ending: bytes) -> bytes:
    """All line ends replaced by `ending` (b"\\r" for old Mac files, b"\\r\\n" for Windows)."""
    return data.replace(b"\r\n", b"\n").replace(b"\n", ending)


def mixed_endings(data: bytes, rng: random.Random) -> bytes:
    lines = data.replace(b"\r\n", b"\n").split(b"\n")
    return b"".join(line + rng.choice([b"\n", b"\r\n", b"\r"]) for line in lines[:-1]) + lines[-1]


def reencode(data: bytes, encoding: str) -> bytes:
    """The same text saved in another encoding (utf-16 has a BOM and NUL bytes everywhere)."""
    return data.decode("utf-8", errors="replace").encode(encoding, errors="replace")


def lines_of(data: bytes) -> list[bytes]:
    return data.split(b"\n")


def swap_lines(data: bytes, rng: random.Random, *, first: int = 0) -> bytes:
    """Two random lines at or after line `first` (0-based) change places."""
    lines = lines_of(data)
    if len(lines) - first < 3:
        return data
    i, j = rng.sample(range(first, len(lines) - 1), 2)
    lines[i], lines[j] = lines[j], lines[i]
    return b"\n".join(lines)


def repeat_line(data: bytes, rng: random.Random, *, first: int = 0, times: int = 3) -> bytes:
    lines = lines_of(data)
    if len(lines) - first < 2:
        return data
    i = rng.randrange(first, len(lines) - 1)
    return b"\n".join(lines[:i] + [lines[i]] * times + lines[i + 1:])


def drop_lines(data: bytes, rng: random.Random, *, first: int = 0, count: int = 5) -> bytes:
    lines = lines_of(data)
    keep = set(range(len(lines))) - set(rng.sample(range(first, len(lines) - 1), min(count, max(len(lines) - 1 - first, 0))))
    return b"\n".join(lines[i] for i in sorted(keep))


def replace_line(data: bytes, rng: random.Random, new: bytes, *, first: int = 0) -> bytes:
    lines = lines_of(data)
    i = rng.randrange(first, max(len(lines) - 1, first + 1))
    lines[i] = new
    return b"\n".join(lines)


def insert_line(data: bytes, rng: random.Random, new: bytes, *, first: int = 0) -> bytes:
    lines = lines_of(data)
    i = rng.randrange(first, max(len(lines), first + 1))
    return b"\n".join(lines[:i] + [new] + lines[i:])


def csv_cell(data: bytes, rng: random.Random, value: str, *, column: int | None = None, header_lines: int = 1,
             every_row: bool = False, delimiter: bytes = b",") -> bytes:
    """One cell (or a whole column with `every_row`) of a CSV replaced by `value`."""
    lines = lines_of(data)
    rows = [i for i in range(header_lines, len(lines)) if lines[i].strip() and not lines[i].startswith(b"#")]
    if not rows:
        return data
    targets = rows if every_row else [rng.choice(rows)]
    width = len(lines[rows[0]].split(delimiter))
    col = rng.randrange(width) if column is None else column
    for i in targets:
        cells = lines[i].split(delimiter)
        if col < len(cells):
            cells[col] = value.encode()
            lines[i] = delimiter.join(cells)
    return b"\n".join(lines)


def pad_cells(data: bytes, *, header: bool, cells: bool, header_lines: int = 1, delimiter: bytes = b",") -> bytes:
    """Spaces around header names and/or data cells (`" x ", "  1.5 "`), as spreadsheets export them."""
    lines = lines_of(data)
    for i, line in enumerate(lines):
        if not line.strip() or line.startswith(b"#"):
            continue
        is_header = i < header_lines
        if (is_header and header) or (not is_header and cells):
            lines[i] = delimiter.join(b" " + c.strip() + b"  " for c in line.split(delimiter))
    return b"\n".join(lines)
