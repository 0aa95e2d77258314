"""`feedlog program FILE`: summarise a part program (blocks, length, CAM time, extents, feeds)."""

from __future__ import annotations

import argparse
import contextlib
import json
from dataclasses import replace
from pathlib import Path

from feedlog.atomic import atomic_output
from feedlog.cli_options import add_output, add_overwrite
from feedlog.errors import FeedlogError
from feedlog.profile import load_profile
from feedlog.toolpath.features import DEFAULT_PROFILE
from feedlog.parquet_sink import ParquetSink
from feedlog.toolpath.dialects import DIALECTS
from feedlog.toolpath.expand import expand
from feedlog.toolpath.interp import InterpOptions
from feedlog.toolpath.load import load_program, stream_dialect
from feedlog.toolpath.stream import open_program_reader
from feedlog.toolpath.summary import Summary, format_summary, summarize

STREAM_BYTES = 16 << 20   # files this large are read and summarised chunk by chunk


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", metavar="FILE", type=Path, nargs="?",
                        help="part program (RS274/NGC G-code); not with --calibration")
    parser.add_argument("--profile", default=None,
                        help=f"machine profile: shipped name or TOML path (default: {DEFAULT_PROFILE}, or "
                             f"{FIVE_AXIS_PROFILE} for a program that moves A or C; the summary says which)")
    parser.add_argument("--lenient", action="store_true",
                        help="list unsupported codes and skip them instead of stopping at the first")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    add_output(parser, type=Path, metavar="BLOCKS.parquet", aliases=("--parquet",),
               help="write the block table to this Parquet file")
    add_overwrite(parser, help="allow -o to replace an existing file")
    parser.add_argument("--dialect", choices=DIALECTS, default="auto",
                        help="G-code dialect: rs274ngc (LinuxCNC), fanuc/hurco, sinumerik (default: detected)")
    parser.add_argument("--expand", type=Path, metavar="FLAT.ngc",
                        help="write the flattened motion (loops unrolled, subroutines inlined, cycles and "
                             "compensation resolved) as RS274/NGC, one line per move tagged with file, line "
                             "and call stack")
    parser.add_argument("--calibration", type=Path, metavar="CAL.ngc",
                        help="write the air-cut program that would pin down the axis limits --profile's "
                             "recordings did not constrain (its [coverage]; all of them without one)")
    parser.add_argument("--for", dest="calibrate_for", metavar="KEY,KEY",
                        help="with --calibration: these axis limits (e.g. axes.z.vel_max) instead of the missing ones")
    parser.add_argument("--travel", type=float, default=100.0, metavar="MM",
                        help="with --calibration: distance each axis may move from the start (default %(default)s)")
    add_interpreter_arguments(parser)
    parser.add_argument("--stream", action=argparse.BooleanOptionalAction, default=None,
                        help="read the program in chunks, summarise and write -o batch by batch "
                             f"(RS274/NGC only; default: for such files of {STREAM_BYTES >> 20} MiB or more)")


FIVE_AXIS_PROFILE = "linuxcnc-xyzac"


def pick_profile(program) -> tuple[str, str]:
    """A shipped profile for a program given without one, by the axes it moves, and why."""
    m = program.motion
    moved = [a for a, col, col0 in (("A", "a_deg", "a0_deg"), ("B", "b_deg", "b0_deg"), ("C", "c_deg", "c0_deg"))
             if len(m) and (m[col] - m[col0]).abs().max() > 1e-9]
    if not moved:
        return DEFAULT_PROFILE, f"{DEFAULT_PROFILE}: the program moves X, Y, Z only (give --profile for your machine)"
    if "B" in moved:
        raise FeedlogError(f"{program.name}: the program moves {', '.join(moved)}; no shipped profile has a B axis: "
                           "give --profile a TOML profile of the machine")
    return FIVE_AXIS_PROFILE, (f"{FIVE_AXIS_PROFILE}: the program moves {', '.join(moved)} "
                               "(give --profile for your machine)")


def add_interpreter_arguments(parser: argparse.ArgumentParser) -> None:
    """What the interpreter reads besides the program (programs with subroutines, tools, offsets)."""
    parser.add_argument("--ini", type=Path, help="LinuxCNC INI file: its [RS274NGC] SUBROUTINE_PATH, PARAMETER_FILE, "
                                                 "CENTER_ARC_RADIUS_TOLERANCE_* and [EMCIO] TOOL_TABLE")
    parser.add_argument("--subroutine-path", action="append", default=[], type=Path, metavar="DIR",
                        help="folder searched for `o<name> call` files after the program's own (repeatable)")
    parser.add_argument("--tool-table", type=Path, metavar="TOOLS.tbl",
                        help="LinuxCNC tool table (mm): tool lengths for G43 (default: tools taken as zero length)")
    parser.add_argument("--parameter-file", type=Path, metavar="PARAMS.var",
                        help="LinuxCNC parameter file (mm): work offsets G54-G59.3, G28/G30 homes")
    parser.add_argument("--arc-tolerance", type=float, metavar="MM",
                        help="largest start/end radius difference of a centre-format arc (LinuxCNC's "
                             "CENTER_ARC_RADIUS_TOLERANCE_MM; default 0.0283 mm, inch programs 0.00283 in)")


def interp_options(args: argparse.Namespace) -> InterpOptions:
    over = dict(tool_table=args.tool_table, parameter_file=args.parameter_file, arc_tolerance_mm=args.arc_tolerance)
    if args.arc_tolerance is not None:
        over["arc_tolerance_inch"] = args.arc_tolerance / 25.4
    if args.ini is not None:
        options = InterpOptions.from_ini(args.ini, **over)
    else:
        options = InterpOptions(**{k: v for k, v in over.items() if v is not None})
    if args.subroutine_path:
        options = replace(options, search_path=tuple(args.subroutine_path) + tuple(options.search_path))
    return options


def run(args: argparse.Namespace) -> int:
    if args.calibration is not None:
        return _write_calibration(args)
    if args.file is None:
        raise FeedlogError("a part program FILE is needed (or --calibration CAL.ngc to write one)")
    if args.out is not None and args.out.exists() and not args.overwrite:
        raise FeedlogError(f"{args.out} exists; pass --overwrite to replace it")
    if _streams(args):
        summary = _summarize_stream(args, load_profile(args.profile or DEFAULT_PROFILE))
        if not args.profile:   # a streamed program on a three-axis machine reads only X Y Z moves
            summary["profile_choice"] = f"{DEFAULT_PROFILE}: the program moves X, Y, Z only (give --profile for your machine)"
    else:
        program = load_program(args.file, lenient=args.lenient, dialect=args.dialect, interp=interp_options(args))
        name, why = (args.profile, None) if args.profile else pick_profile(program)
        summary = summarize(program, load_profile(name))
        if why:
            summary["profile_choice"] = why
        if args.expand is not None:
            if args.expand.exists() and not args.overwrite:
                raise FeedlogError(f"{args.expand} exists; pass --overwrite to replace it")
            with atomic_output(args.expand) as temporary:
                Path(temporary).write_text(expand(program))
            summary["expanded"] = str(args.expand)
        if args.out is not None:
            with atomic_output(args.out) as temporary:
                program.blocks.to_parquet(temporary, index=False)
    if args.out is not None:
        summary["parquet"] = str(args.out)
    if args.json:
        print(json.dumps(summary, allow_nan=False))
    else:
        print(format_summary(summary))
        if args.out is not None:
            print(f"  block table  {args.out}")
    return 0


def _write_calibration(args: argparse.Namespace) -> int:
    """`--calibration CAL.ngc`: the air-cut for what the profile's recordings left unconstrained."""
    from feedlog.toolpath.calibration import calibration_program, missing

    if args.file is not None:
        raise FeedlogError("--calibration writes a program; give no FILE with it")
    if args.calibration.exists() and not args.overwrite:
        raise FeedlogError(f"{args.calibration} exists; pass --overwrite to replace it")
    profile = load_profile(args.profile or DEFAULT_PROFILE)
    keys = [k.strip() for k in args.calibrate_for.split(",") if k.strip()] if args.calibrate_for else missing(profile)
    text = calibration_program(profile, travel=args.travel, keys=keys)
    with atomic_output(args.calibration) as temporary:
        Path(temporary).write_text(text)
    if args.json:
        print(json.dumps({"calibration": str(args.calibration), "profile": profile.name, "parameters": keys}))
    else:
        print(f"wrote {args.calibration}: air-cut for {', '.join(keys) if keys else 'nothing (all constrained)'}")
    return 0


def _streams(args: argparse.Namespace) -> bool:
    """--stream, or by default an RS274/NGC file of STREAM_BYTES or more (other dialects are
    translated as a whole)."""
    if args.stream is False or args.expand is not None:   # --expand needs the whole table
        return False
    if args.stream:
        dialect = stream_dialect(args.file, args.dialect)
        if dialect != "rs274ngc":
            raise FeedlogError(f"{args.file}: --stream reads RS274/NGC (LinuxCNC) programs; this one is {dialect}")
        return True
    try:
        large = args.file.stat().st_size >= STREAM_BYTES
    except OSError:
        return False      # the reader says what is wrong with the path
    return large and stream_dialect(args.file, args.dialect) == "rs274ngc"


def _summarize_stream(args: argparse.Namespace, profile) -> dict:
    """The summary and the --parquet table, batch by batch (memory bounded by a chunk of the file)."""
    with contextlib.ExitStack() as stack:
        reader = stack.enter_context(open_program_reader(args.file, lenient=args.lenient, interp=interp_options(args)))
        sink = None
        if args.out is not None:
            sink = ParquetSink(stack.enter_context(atomic_output(args.out)))
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
        return summary.result(warnings=reader.warnings, unsupported=reader.unsupported,
                              metadata={**reader.metadata, "dialect": "rs274ngc"})
