"""`feedlog program FILE`: summarise a part program (blocks, length, CAM time, extents, feeds)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from feedlog.atomic import atomic_output
from feedlog.cli_options import add_output, add_overwrite
from feedlog.errors import FeedlogError
from feedlog.profile import load_profile
from feedlog.toolpath.features import DEFAULT_PROFILE
from feedlog.toolpath.dialects import DIALECTS
from feedlog.toolpath.load import load_program
from feedlog.toolpath.summary import format_summary, summarize


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", metavar="FILE", type=Path, help="part program (RS274/NGC G-code)")
    parser.add_argument("--profile", default=DEFAULT_PROFILE,
                        help=f"machine profile: shipped name or TOML path (default {DEFAULT_PROFILE})")
    parser.add_argument("--lenient", action="store_true",
                        help="list unsupported codes and skip them instead of stopping at the first")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    add_output(parser, type=Path, metavar="BLOCKS.parquet", aliases=("--parquet",),
               help="write the block table to this Parquet file")
    add_overwrite(parser, help="allow -o to replace an existing file")
    parser.add_argument("--dialect", choices=DIALECTS, default="auto",
                        help="G-code dialect: rs274ngc (LinuxCNC), fanuc/hurco, sinumerik (default: detected)")


def run(args: argparse.Namespace) -> int:
    if args.out is not None and args.out.exists() and not args.overwrite:
        raise FeedlogError(f"{args.out} exists; pass --overwrite to replace it")
    profile = load_profile(args.profile)
    program = load_program(args.file, lenient=args.lenient, dialect=args.dialect)
    summary = summarize(program, profile)
    if args.out is not None:
        with atomic_output(args.out) as temporary:
            program.blocks.to_parquet(temporary, index=False)
        summary["parquet"] = str(args.out)
    if args.json:
        print(json.dumps(summary, allow_nan=False))
    else:
        print(format_summary(summary))
        if args.out is not None:
            print(f"  block table  {args.out}")
    return 0
