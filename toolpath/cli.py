"""`feedlog program FILE`: summarise a part program (blocks, length, CAM time, extents, feeds)."""

from __future__ import annotations

import argparse
import contextlib
import json
from pathlib import Path

from feedlog.atomic import atomic_output
from feedlog.errors import FeedlogError
from feedlog.profile import load_profile
from feedlog.toolpath.features import DEFAULT_PROFILE
from feedlog.parquet_sink import ParquetSink
from feedlog.toolpath.parser import parse_program
from feedlog.toolpath.stream import ProgramReader
from feedlog.toolpath.summary import Summary, format_summary, summarize

STREAM_BYTES = 16 << 20   # files this large are read and summarised chunk by chunk


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", metavar="FILE", type=Path, help="part program (RS274/NGC G-code)")
    parser.add_argument("--profile", default=DEFAULT_PROFILE,
                        help=f"machine profile: shipped name or TOML path (default {DEFAULT_PROFILE})")
    parser.add_argument("--lenient", action="store_true",
                        help="list unsupported codes and skip them instead of stopping at the first")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.add_argument("--parquet", metavar="OUT", type=Path, help="write the block table to OUT (Parquet)")
    parser.add_argument("--overwrite", action="store_true", help="allow --parquet to replace an existing file")
    parser.add_argument("--stream", action=argparse.BooleanOptionalAction, default=None,
                        help="read the program in chunks, summarise and write --parquet batch by batch "
                             f"(default: for files of {STREAM_BYTES >> 20} MiB or more)")


def run(args: argparse.Namespace) -> int:
    if args.parquet is not None and args.parquet.exists() and not args.overwrite:
        raise FeedlogError(f"{args.parquet} exists; pass --overwrite to replace it")
    profile = load_profile(args.profile)
    if _streams(args):
        summary = _summarize_stream(args, profile)
    else:
        program = parse_program(args.file, lenient=args.lenient)
        summary = summarize(program, profile)
        if args.parquet is not None:
            with atomic_output(args.parquet) as temporary:
                program.blocks.to_parquet(temporary, index=False)
    if args.parquet is not None:
        summary["parquet"] = str(args.parquet)
    if args.json:
        print(json.dumps(summary, allow_nan=False))
    else:
        print(format_summary(summary))
        if args.parquet is not None:
            print(f"  block table  {args.parquet}")
    return 0


def _streams(args: argparse.Namespace) -> bool:
    if args.stream is not None:
        return args.stream
    try:
        return args.file.stat().st_size >= STREAM_BYTES
    except OSError:
        return False      # parse_program says what is wrong with the path


def _summarize_stream(args: argparse.Namespace, profile) -> dict:
    """The summary and the --parquet table, batch by batch (memory bounded by a chunk of the file)."""
    with contextlib.ExitStack() as stack:
        reader = stack.enter_context(ProgramReader(args.file, lenient=args.lenient))
        sink = None
        if args.parquet is not None:
            sink = ParquetSink(stack.enter_context(atomic_output(args.parquet)))
            stack.callback(sink.close)    # closed before the rename
        summary = Summary(profile, name=reader.name)
        first = None
        for batch in reader:
            summary.add(batch)
            if sink is not None:
                sink.write(batch)
            first = batch.iloc[:0] if first is None else first
        if sink is not None and first is not None:
            sink.close(first)
        return summary.result(warnings=reader.warnings, unsupported=reader.unsupported, metadata=reader.metadata)
