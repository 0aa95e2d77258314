"""`feedlog diagnose REC... --profile P -o DIR`: what the simulation gets wrong, the cause, the gain.

Prints the answer in a few lines (or one JSON object with `--json`) and writes DIR/report.md,
DIR/diagnose.json, DIR/profile.toml (the extended profile, usable with --profile everywhere) and
DIR/diagnose.rrd. Input that cannot be diagnosed is one error line and exit code 2 (an output that
cannot be written: exit code 1); nothing is written half.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from feedlog.cli_options import add_output, add_overwrite, add_quiet
from feedlog.errors import FeedlogError
from feedlog.execution import add_arguments as add_execution_arguments


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recordings", nargs="+", metavar="RECORDING", help="recordings of one machine (.mcap)")
    parser.add_argument("--profile", help="machine profile to diagnose: shipped name or .toml (default: the "
                                          "profile the recordings carry)")
    parser.add_argument("--program", "-p", help="part program (default: each recording's program.ngc; with none "
                                                "anywhere: what the data alone says, docs/diagnose.md)")
    add_output(parser, type=Path, metavar="DIR", help="output folder (report.md, diagnose.json, profile.toml, "
                                                     "diagnose.rrd); nothing is written without it")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of the text summary")
    add_overwrite(parser, help="replace an existing output folder")
    parser.add_argument("--min-effect", type=float, default=1.0, metavar="PCT",
                        help="a cause must lower the held-out timing error by this many percentage points "
                             "(default %(default)s)")
    parser.add_argument("--min-gain", type=float, default=0.2, metavar="SHARE",
                        help="share of the remaining held-out residual a cause must remove (default %(default)s)")
    parser.add_argument("--families", help="comma-separated hypothesis families (default: all)")
    parser.add_argument("--calibrate", action="store_true",
                        help="fit every axis limit the recordings constrain (a machine with no profile of its "
                             "own: --profile generic-xyz or generic-xyzac); the written profile says which the "
                             "recordings covered")
    parser.add_argument("--no-learned", action="store_true", help="do not fit a learned correction")
    parser.add_argument("--no-rrd", action="store_true", help="do not write diagnose.rrd")
    parser.add_argument("--lenient", action="store_true", help="skip unsupported program codes")
    parser.add_argument("--numbering", default="auto",
                        choices=("auto", "file-lines", "file-lines-no-percent", "n-words", "counter"),
                        help="recordings without positions: what the recorded block values count (default: "
                             "detected from the line times against the program)")
    add_execution_arguments(parser, jobs_help="processes: each re-simulation's recordings shared out over them, "
                                              "the recordings prepared as tasks (default: the machine's cores for "
                                              "two or more recordings of 10 s of motion or more, else 1; "
                                              "FEEDLOG_SCHEDULER or --scheduler: the hypothesis fits on a Dask "
                                              "cluster)")
    add_quiet(parser, help="no progress messages")


def _run_lines(args: argparse.Namespace) -> int:
    """One recording with a line stream and no positions: diagnose.line_level; errors go to run's handler."""
    from feedlog.diagnose.line_level import diagnose_lines
    from feedlog.diagnose.line_report import summary_lines, to_json, write_line_outputs
    from feedlog.ingest import read_recording

    if len(args.recordings) != 1:
        raise FeedlogError("recordings without positions are diagnosed one at a time (line stream only); give one")
    ld = diagnose_lines(read_recording(args.recordings[0]), args.profile, args.program, lenient=args.lenient,
                        numbering=args.numbering)
    if args.out is not None:
        write_line_outputs(ld, args.out)
    wrote = [] if args.out is None else [f"wrote {args.out}/: report.md, diagnose.json, profile.toml"]
    return answer(args, to_json(ld), summary_lines(ld) + wrote)


def run(args: argparse.Namespace) -> int:
    from feedlog.diagnose import no_program_report

    if no_program_report.applies(args):   # no program anywhere: what the data alone says
        return no_program_report.run(args)
    from feedlog.diagnose.engine import DiagnoseConfig, diagnose
    from feedlog.diagnose.line_level import line_stream_only
    from feedlog.diagnose.summary import summary_lines, to_json
    from feedlog.diagnose.write import write_outputs

    try:
        refuse_taken_output(args)
        families = tuple(f.strip() for f in args.families.split(",")) if args.families else None
        scheduler = args.scheduler or (os.environ.get("FEEDLOG_SCHEDULER") if args.jobs is None else None)
        jobs = args.jobs  # None: automatic (DiagnoseConfig.scorer_processes), or the cluster's workers
        config = DiagnoseConfig(min_effect_pct=args.min_effect, min_gain=args.min_gain, families=families,
                                learned=not args.no_learned, jobs=jobs, calibrate=args.calibrate,
                                scheduler=None if scheduler in (None, "", "none") else scheduler)
        say = None if args.quiet or args.json else (lambda msg: print(f"  {msg}", file=sys.stderr, flush=True))
        if line_stream_only(args.recordings):   # no positions: the block level (diagnose.line_level)
            return _run_lines(args)
        dx = diagnose(args.recordings, args.profile, program=args.program, config=config, lenient=args.lenient,
                      progress=say)
        if args.out is not None:
            write_outputs(dx, args.out, overwrite=args.overwrite, rrd=not args.no_rrd)
    except FeedlogError as exc:
        print(f"feedlog diagnose: error: {exc}", file=sys.stderr)
        return exc.exit_code
    wrote = [] if args.out is None else [f"wrote {args.out}/: report.md, diagnose.json, profile.toml"
                                         + ("" if args.no_rrd else ", diagnose.rrd (rerun FILE)")]
    return answer(args, to_json(dx), summary_lines(dx) + wrote)


def refuse_taken_output(args: argparse.Namespace) -> None:
    """An output folder that exists and holds something is replaced only with --overwrite."""
    if args.out is not None and args.out.exists() and not args.overwrite and (
            not args.out.is_dir() or any(args.out.iterdir())):
        raise FeedlogError(f"{args.out} exists; pass --overwrite to replace it")


def answer(args: argparse.Namespace, doc: dict, lines: list[str]) -> int:
    """Print the result: one JSON object with --json, else the summary lines."""
    if args.json:
        json.dump(doc, sys.stdout, allow_nan=False)
        sys.stdout.write("\n")
    else:
        print("\n".join(lines))
    return 0
