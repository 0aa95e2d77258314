"""One spelling for the options every command shares: `-o/--out`, `--overwrite`, `-q/--quiet`.

Commands call these instead of spelling the options themselves. Older spellings (`--outdir`,
`--output`, `--parquet`, `--force`) stay accepted as hidden aliases (not in `--help`), so scripts and
documents that use them keep working.
"""

from __future__ import annotations

import argparse


def _hidden(parser: argparse.ArgumentParser, aliases, **kwargs) -> None:
    for alias in aliases:
        parser.add_argument(alias, help=argparse.SUPPRESS, **kwargs)


def add_output(parser: argparse.ArgumentParser, *, help: str, required: bool = False, type=None,  # noqa: A002
               default=None, metavar: str = "OUT", aliases: tuple[str, ...] = ()) -> None:
    """`-o/--out` (dest `out`), plus hidden `aliases` (e.g. `--outdir`) writing the same dest."""
    grouped = bool(aliases and required)
    group = parser.add_mutually_exclusive_group(required=True) if grouped else parser
    group.add_argument("-o", "--out", dest="out", type=type, default=default, metavar=metavar, help=help,
                       **({} if grouped else {"required": required}))
    for alias in aliases:
        group.add_argument(alias, dest="out", type=type, default=default, metavar=metavar, help=argparse.SUPPRESS)


def add_overwrite(parser: argparse.ArgumentParser, *, help: str = "replace existing outputs",  # noqa: A002
                  aliases: tuple[str, ...] = ()) -> None:
    """`--overwrite` (dest `overwrite`), plus hidden `aliases` (e.g. `--force`)."""
    parser.add_argument("--overwrite", action="store_true", help=help)
    _hidden(parser, aliases, dest="overwrite", action="store_true")


def add_quiet(parser: argparse.ArgumentParser, *, help: str = "no progress output") -> None:  # noqa: A002
    """`-q/--quiet` (dest `quiet`)."""
    parser.add_argument("-q", "--quiet", action="store_true", help=help)
