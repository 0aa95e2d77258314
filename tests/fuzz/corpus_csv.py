"""Fuzz cases for data CSV imports: `feedlog import FILE.csv --preset P -o out.mcap` (strict and --lenient).

Seeds are the committed CSV fixtures with their presets. Mutations: time columns that are NaN, inf or
1e400 (once imported as t_start_ns = INT64_MIN), padded headers and cells, CR-only and mixed line
endings, a BOM, other encodings, truncated and swapped rows, unknown time zones, huge files of bad rows.
"""

from __future__ import annotations

import random

from tests.fuzz import mutate
from tests.fuzz.cases import FIXTURES, Case, Run

SEEDS = {  # file -> (preset, header lines before the data)
    "servo_trace_1khz.csv": ("servo-trace-1khz", 1),
    "linuxcnc_trace.csv": ("linuxcnc-trace", 1),
    "monitoring_5hz.csv": ("monitoring-5hz", 2),
}
NAME = "d.csv"


def _case(name: str, data: bytes, preset: str, expect: str = "any", *, lenient: str | None = None,
          seed: bytes | None = None, extra: tuple[str, ...] = (), blame: str | None = None) -> Case:
    """`blame`: the option an error must name instead of the file (a bad --timezone, not a bad row)."""
    argv = ["import", NAME, "--preset", preset, *extra, "-o", "out.mcap"]
    runs = [Run(argv, expect, same_as_seed=seed is not None)]
    if lenient is not None:
        runs.append(Run(argv + ["--lenient"], lenient))
    return Case("csv", f"csv/{name}", {NAME: data}, runs, blame or NAME,
                seed={NAME: seed} if seed is not None else {}, located=blame is None)


def build(rng: random.Random) -> list[Case]:
    cases = []
    for file, (preset, header) in SEEDS.items():
        data = (FIXTURES / file).read_bytes()
        stem = file.removesuffix(".csv")

        def cell(value: str, **kw) -> bytes:
            return mutate.csv_cell(data, rng, value, header_lines=header, **kw)

        for token in ("nan", "inf", "1e400", "-inf", ""):
            label = token or "empty"
            cases.append(_case(f"{stem}/time-all-{label}", cell(token, column=0, every_row=True), preset, "error",
                               lenient="error"))
        cases += [
            _case(f"{stem}/time-one-nan", cell("nan", column=0), preset, "error", lenient="ok"),
            _case(f"{stem}/time-one-1e400", cell("1e400", column=0), preset, "error", lenient="ok"),
            _case(f"{stem}/time-1e300", cell("1e300", column=0), preset, "error", lenient="ok"),
            _case(f"{stem}/value-nan", cell("nan", column=1), preset, "error", lenient="ok"),
            _case(f"{stem}/value-inf", cell("-inf", column=1), preset, "error", lenient="ok"),
            _case(f"{stem}/value-1e400", cell("1e400", column=1), preset, "error", lenient="ok"),
            _case(f"{stem}/value-text", cell("abc"), preset, "any", lenient="any"),
            _case(f"{stem}/padded-header", mutate.pad_cells(data, header=True, cells=False, header_lines=header),
                  preset, seed=data),
            _case(f"{stem}/padded-cells", mutate.pad_cells(data, header=False, cells=True, header_lines=header),
                  preset, seed=data),
            _case(f"{stem}/padded-both", mutate.pad_cells(data, header=True, cells=True, header_lines=header),
                  preset, seed=data),
            _case(f"{stem}/cr-only", mutate.line_endings(data, b"\r"), preset, seed=data),
            _case(f"{stem}/crlf", mutate.line_endings(data, b"\r\n"), preset, seed=data),
            _case(f"{stem}/mixed-endings", mutate.mixed_endings(data, rng), preset, seed=data),
            _case(f"{stem}/bom", mutate.BOM + data, preset, seed=data),
            _case(f"{stem}/utf16", mutate.reencode(data, "utf-16"), preset, "error"),
            _case(f"{stem}/truncated", mutate.truncate(data, rng), preset, lenient="any"),
            _case(f"{stem}/swapped-rows", mutate.swap_lines(data, rng, first=header), preset, lenient="any"),
            _case(f"{stem}/bitflip", mutate.flip_bits(data, rng, count=2), preset, lenient="any"),
            _case(f"{stem}/header-only", b"\n".join(mutate.lines_of(data)[:header]) + b"\n", preset, "error"),
            _case(f"{stem}/bad-timezone", data, preset, "error", extra=("--timezone", "Mars/Olympus_Mons"),
                  blame="--timezone"),
        ]
    cases += _machine_exports(rng)
    servo = (FIXTURES / "servo_trace_1khz.csv").read_bytes()
    header, *rows = mutate.lines_of(servo)
    good_rows = b"\n".join(f"{k},{k * 0.001:.3f},0,0,3000".encode() for k in range(200_000))
    cases += [
        _case("servo/200k-bad-rows", header + b"\n" + b"abc,def,ghi,jkl,mno\n" * 200_000, "servo-trace-1khz", "error",
              lenient="error"),
        _case("servo/200k-rows-one-nan-at-end", header + b"\n" + good_rows + b"\n200000,nan,0,0,3000\n",
              "servo-trace-1khz", "error", lenient="ok"),
        _case("servo/latin1-cell", servo.replace(b"3000", "3000\xb5".encode("latin-1"), 1), "servo-trace-1khz",
              "error", lenient="ok"),
        _case("servo/semicolons", servo.replace(b",", b";"), "servo-trace-1khz", "error"),
        _case("servo/quoted", servo.replace(b",3000", b',"3000"'), "servo-trace-1khz", "ok"),
        _case("servo/empty", b"", "servo-trace-1khz", "error"),
        _case("servo/blank-lines", servo.replace(b"\n", b"\n\n"), "servo-trace-1khz", seed=servo),
        _case("monitoring/dst-gap", (FIXTURES / "monitoring_5hz.csv").read_bytes().replace(b"2026-11-22 13", b"2026-03-29 02"),
              "monitoring-5hz", "error", lenient="any", extra=("--timezone", "Europe/Berlin")),
        _case("monitoring/bad-format", (FIXTURES / "monitoring_5hz.csv").read_bytes(), "monitoring-5hz", "error",
              extra=("--time-format", "%Q"), blame="--time-format"),
    ]
    return cases


# real machines' exports (tests/fixtures/ingest/real): a fixed-rate file without a time column and a
# `;`-separated trace with a comment line before its header
MACHINE_EXPORTS = {  # file -> (preset, lines up to the header, delimiter, column of X)
    "umich_experiment.csv": ("umich-tool-wear", 1, b",", 0),
    "sinumerik_trace.csv": ("sinumerik-trace", 2, b";", 1),
}


def _machine_exports(rng: random.Random) -> list[Case]:
    cases = []
    for file, (preset, header, delimiter, x) in MACHINE_EXPORTS.items():
        data = (FIXTURES / "real" / file).read_bytes()
        stem = file.removesuffix(".csv")

        def cell(value: str, **kw) -> bytes:
            return mutate.csv_cell(data, rng, value, column=x, header_lines=header, delimiter=delimiter, **kw)

        cases += [
            _case(f"{stem}/x-one-nan", cell("nan"), preset, "error", lenient="ok"),
            _case(f"{stem}/x-one-inf", cell("inf"), preset, "error", lenient="ok"),
            _case(f"{stem}/x-all-1e400", cell("1e400", every_row=True), preset, "error",
                  lenient="error"),
            _case(f"{stem}/crlf", mutate.line_endings(data, b"\r\n"), preset, seed=data),
            _case(f"{stem}/cr-only", mutate.line_endings(data, b"\r"), preset, seed=data),
            _case(f"{stem}/bom", mutate.BOM + data, preset, seed=data),
            _case(f"{stem}/utf16", mutate.reencode(data, "utf-16"), preset, "error"),
            _case(f"{stem}/truncated", mutate.truncate(data, rng), preset, lenient="any"),
            _case(f"{stem}/bitflip", mutate.flip_bits(data, rng, count=3), preset, lenient="any"),
            _case(f"{stem}/header-only", b"\n".join(mutate.lines_of(data)[:header]) + b"\n", preset, "error"),
        ]
    return cases
