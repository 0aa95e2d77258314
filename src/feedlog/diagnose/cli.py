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
    parser.add_argument("--program", "-p", help="part program (default: each recording's program.ngc)")
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
    add_execution_arguments(parser, jobs_help="worker processes for the recordings and the hypothesis fits "
                                              "(default: 1, here; FEEDLOG_SCHEDULER or --scheduler: a Dask cluster)")
    add_quiet(parser, help="no progress messages")


def run(args: argparse.Namespace) -> int:
    from feedlog.diagnose.engine import DiagnoseConfig, diagnose
    from feedlog.diagnose.summary import summary_lines, to_json
    from feedlog.diagnose.write import write_outputs

    try:
        if args.out is not None and args.out.exists() and not args.overwrite and (
                not args.out.is_dir() or any(args.out.iterdir())):
            raise FeedlogError(f"{args.out} exists; pass --overwrite to replace it")
        families = tuple(f.strip() for f in args.families.split(",")) if args.families else None
        scheduler = args.scheduler or (os.environ.get("FEEDLOG_SCHEDULER") if args.jobs is None else None)
        jobs = args.jobs if args.jobs is not None else (None if scheduler else 1)
        config = DiagnoseConfig(min_effect_pct=args.min_effect, min_gain=args.min_gain, families=families,
                                learned=not args.no_learned, jobs=jobs, calibrate=args.calibrate,
                                scheduler=None if scheduler in (None, "", "none") else scheduler)
        say = None if args.quiet or args.json else (lambda msg: print(f"  {msg}", file=sys.stderr, flush=True))
        dx = diagnose(args.recordings, args.profile, program=args.program, config=config, lenient=args.lenient,
                      progress=say)
        if args.out is not None:
            write_outputs(dx, args.out, overwrite=args.overwrite, rrd=not args.no_rrd)
    except FeedlogError as exc:
        print(f"feedlog diagnose: error: {exc}", file=sys.stderr)
        return exc.exit_code
    if args.json:
        json.dump(to_json(dx), sys.stdout, allow_nan=False)
        sys.stdout.write("\n")
    else:
        print("\n".join(summary_lines(dx)))
        if args.out is not None:
            print(f"wrote {args.out}/: report.md, diagnose.json, profile.toml"
                  + ("" if args.no_rrd else ", diagnose.rrd (rerun FILE)"))
    return 0
