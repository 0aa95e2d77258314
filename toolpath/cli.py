"""`feedlog program FILE`: summarise a part program (blocks, length, CAM time, extents, feeds)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from feedlog.atomic import atomic_output
from feedlog.errors import FeedlogError
from feedlog.profile import load_profile
from feedlog.toolpath.features import DEFAULT_PROFILE
from feedlog.toolpath.parser import parse_program
from feedlog.toolpath.summary import format_summary, summarize


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", metavar="FILE", type=Path, help="part program (RS274/NGC G-code)")
    parser.add_argument("--profile", default=DEFAULT_PROFILE,
                        help=f"machine profile: shipped name or TOML path (default {DEFAULT_PROFILE})")
    parser.add_argument("--lenient", action="store_true",
                        help="list unsupported codes and skip them instead of stopping at the first")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.add_argument("--parquet", metavar="OUT", type=Path, help="write the block table to OUT (Parquet)")
    parser.add_argument("--overwrite", action="store_true", help="allow --parquet to replace an existing file")


def run(args: argparse.Namespace) -> int:
    if args.parquet is not None and args.parquet.exists() and not args.overwrite:
        raise FeedlogError(f"{args.parquet} exists; pass --overwrite to replace it")
    profile = load_profile(args.profile)
    program = parse_program(args.file, lenient=args.lenient)
    summary = summarize(program, profile)
    if args.parquet is not None:
        with atomic_output(args.parquet) as temporary:
            program.blocks.to_parquet(temporary, index=False)
        summary["parquet"] = str(args.parquet)
    if args.json:
        print(json.dumps(summary, allow_nan=False))
    else:
        print(format_summary(summary))
        if args.parquet is not None:
            print(f"  block table  {args.parquet}")
    return 0
