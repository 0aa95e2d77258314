"""`feedlog align RECORDING... [--program P] -o OUTDIR [--json] [-j N | --scheduler ADDRESS]`: align recordings.

Writes OUTDIR/<recording stem>/points.parquet, blocks.parquet and report.json for every recording
(docs/align.md), and the same tables as one partitioned dataset, OUTDIR/dataset/{blocks,points}/
(docs/scaleout.md). Recordings and OUTDIR may be paths or fsspec URLs; `--scheduler` runs the
recordings on a Dask cluster. `--json` prints, for one recording, {"recording", "outdir", "cycle_time_s",
"blocks": [{block, line, t_start_ns, t_end_ns, duration_s}, ...]}; for several, a summary (`summary_doc`:
counts and the recordings that were not aligned; each recording's detail is in its output folder).

Several recordings: a recording refused for its data (off the path, no program, unreadable) is a warning
and the others are still aligned. Exit code: 0 when at least one recording aligned and the rest were
refused (`--strict`: 2 if any was refused), 2 when none aligned or outputs exist without --overwrite,
1 when an output could not be written.
"""

from __future__ import annotations

import argparse
import sys

from feedlog.align.line_numbering import NUMBERINGS
from feedlog.align.batch import align_many
from feedlog.align.feed import FeedSmoothing
from feedlog.align.partial import parse_lines
from feedlog.align.pipeline import BOUNDARIES, FEED_SOURCES, AlignConfig
from feedlog.align.tables import to_json
from feedlog.cli_options import add_output, add_overwrite, add_quiet
from feedlog.errors import FeedlogError
from feedlog.toolpath.dialects import DIALECTS
from feedlog.execution import add_arguments as add_execution_arguments


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recordings", nargs="+", metavar="RECORDING", help="feedlog recordings (.mcap)")
    parser.add_argument("--program", "-p", help="part program (default: the recording's program.ngc attachment)")
    parser.add_argument("--profile", help="machine profile name or TOML (default: the attached profile.toml)")
    add_output(parser, required=True, metavar="OUTDIR", aliases=("--outdir",),
               help="output folder; one subfolder per recording, and OUTDIR/dataset/")
    parser.add_argument("--json", action="store_true", help="print cycle time and block times as JSON")
    parser.add_argument("--tol-mm", type=float, default=AlignConfig.tol_mm,
                        help="allowed CL point distance on top of the block's G64 P (default %(default)s); "
                             "sparse data add half the distance travelled per sample automatically")
    parser.add_argument("--unstated-tol-mm", type=float, default=AlignConfig.unstated_tol_mm,
                        help="allowed CL point distance where the program states no blending tolerance (G64 "
                             "without P; Sinumerik G641-G645, whose tolerance is machine data): the distance "
                             "really found there is reported (default %(default)s)")
    parser.add_argument("--check-rapids", action="store_true", help="apply the tolerance to rapid moves too")
    parser.add_argument("--boundary", choices=BOUNDARIES, default="auto",
                        help="geometric block end: closest approach to the end point (pass), start of the "
                             "corner blend (leave), or auto (leave at <= 5 ms sampling)")
    parser.add_argument("--feed-source", choices=FEED_SOURCES, default="auto",
                        help="path feed from the recording's feed stream or from positions (auto: stream if any)")
    parser.add_argument("--feed-window-s", type=float, default=None,
                        help="feed differentiation window (default: max(sample period, 4 ms))")
    parser.add_argument("--sync-lines", action="store_true",
                        help="estimate and remove the line stream's clock offset against the positions")
    parser.add_argument("--work-offset", type=float, nargs=3, metavar=("X", "Y", "Z"), default=(0.0, 0.0, 0.0),
                        help="extra program origin offset in the recorded frame, mm, for a work offset set "
                             "on the machine rather than in the program (G10/G54/G92 in it are applied)")
    parser.add_argument("--dialect", choices=DIALECTS, default="auto",
                        help="G-code dialect: rs274ngc (LinuxCNC), fanuc/hurco, sinumerik (default: detected)")
    parser.add_argument("--estimate-offset", action="store_true",
                        help="estimate a constant work offset between program and recorded positions (machine "
                             "coordinates with a G54 set on the machine); reported in report.json")
    parser.add_argument("--no-auto-offset", action="store_true",
                        help="do not retry with an estimated work offset when the program is nowhere on the path")
    parser.add_argument("--lines", metavar="FIRST:LAST", type=parse_lines,
                        help="the recording covers only these program lines (default: found from the recorded "
                             "line or block-number stream when it leaves feed moves out)")
    parser.add_argument("--numbering", default="auto", choices=("auto",) + NUMBERINGS,
                        help="what the recorded block values count when there are no positions: file lines "
                             "(with or without a leading %%), N words or a block counter (default: detected "
                             "from the line times against the program, reported)")
    parser.add_argument("--whole-program", action="store_true",
                        help="never cut the program to the lines the line stream saw")
    parser.add_argument("--lenient", action="store_true",
                        help="skip unsupported program codes (reported in report.json) instead of failing")
    add_execution_arguments(parser)
    add_overwrite(parser, help="replace existing output files")
    parser.add_argument("--strict", action="store_true",
                        help="several recordings: exit with code 2 when any is refused (default: a warning)")
    add_quiet(parser, help="no progress bar")


def run(args: argparse.Namespace) -> int:
    config = AlignConfig(tol_mm=args.tol_mm, unstated_tol_mm=args.unstated_tol_mm, check_rapids=args.check_rapids, boundary=args.boundary,
                         feed_source=args.feed_source, sync_lines=args.sync_lines,
                         smoothing=FeedSmoothing(window_s=args.feed_window_s),
                         work_offset_mm=tuple(args.work_offset), lenient=args.lenient, lines=args.lines,
                         auto_lines=not args.whole_program, estimate_offset=args.estimate_offset,
                         auto_offset=not args.no_auto_offset,
                         dialect=args.dialect, numbering=args.numbering)
    single = len(args.recordings) == 1
    items = align_many(args.recordings, args.out, program=args.program, profile=args.profile, config=config,
                       jobs=args.jobs, scheduler=args.scheduler, overwrite=args.overwrite, progress=not args.quiet,
                       with_blocks=args.json and single)
    failed = [i for i in items if not i.ok]
    if single and failed:
        error = FeedlogError(failed[0].error or "alignment failed")
        error.exit_code = failed[0].exit_code
        raise error
    for item in failed:
        kind = "warning" if outcome(item) == "refused" and not args.strict else "error"
        print(f"feedlog align: {kind}: {item.recording}: {item.error}", file=sys.stderr)
    if args.json:
        doc = ({"recording": items[0].recording, "outdir": items[0].outdir, "cycle_time_s": items[0].cycle_time_s,
                "blocks": items[0].blocks} if single else summary_doc(items, args.out, strict=args.strict))
        print(to_json(doc, indent=1))
    else:
        for i in items:
            if i.ok:
                notes = f" ({'; '.join(i.notes)})" if i.notes else ""
                print(f"{i.recording}: cycle time {i.cycle_time_s:.3f} s -> {i.outdir}{notes}")
    if not single:
        print(summary(items), file=sys.stderr if args.json else sys.stdout)
    return exit_code(items, strict=args.strict)


def outcome(item) -> str:
    """aligned; refused (its data: off the path, no program, unreadable); exists (not run, outputs there);
    not written (an output could not be written)."""
    if item.ok:
        return "aligned"
    if item.exists:
        return "exists"
    return "not written" if item.exit_code == 1 else "refused"


def exit_code(items, *, strict: bool = False) -> int:
    """1 if an output could not be written; 2 if nothing aligned, outputs exist without --overwrite, or
    (`strict`) a recording was refused; else 0: refused recordings of a batch are warnings."""
    kinds = [outcome(i) for i in items]
    if "not written" in kinds:
        return 1
    if "aligned" not in kinds or "exists" in kinds or (strict and "refused" in kinds):
        return 2
    return 0


def summary_doc(items, outdir, *, strict: bool = False) -> dict:
    """`--json` for several recordings: counts, where the outputs are, and each recording not aligned
    with its reason (per-recording detail is in OUTDIR/<recording>/report.json and OUTDIR/dataset/)."""
    kinds = [outcome(i) for i in items]
    return {"outdir": str(outdir), "aligned": kinds.count("aligned"), "refused": kinds.count("refused"),
            "exists": kinds.count("exists"), "not_written": kinds.count("not written"),
            "exit_code": exit_code(items, strict=strict),
            "not_aligned": [{"recording": i.recording, "outcome": k, "error": i.error, "try": hint(i.error)}
                            for i, k in zip(items, kinds) if k != "aligned"]}


# what an alignment error usually means, and what to try (first pattern found in the message wins)
HINTS = (
    ("never comes within", "the program does not lie on the measured path: check the program, the import units "
                           "(--length-unit) or a work offset set on the machine (--estimate-offset)"),
    ("farther than their tolerance", "part of the program is off the path: a partial recording (--lines A:B), "
                                     "corner rounding beyond G64 P (--tol-mm), or another program version"),
    ("use --overwrite", "outputs from an earlier run are there: --overwrite"),
    ("no program given", "attach the program at import (--program) or pass --program"),
)


def hint(error: str | None) -> str | None:
    return next((h for pattern, h in HINTS if pattern in (error or "")), None)


def summary(items) -> str:
    """`116 aligned, 1 refused` and, per distinct failure, how many, one example and what to try."""
    kinds = [outcome(i) for i in items]
    text = ", ".join([f"{kinds.count('aligned')} aligned", f"{kinds.count('refused')} refused"]
                     + [f"{kinds.count(k)} {shown}" for k, shown in (("exists", "with outputs already there"),
                                                                      ("not written", "not written")) if k in kinds])
    groups: dict[str, list] = {}
    for item in items:
        if not item.ok:
            reason = (item.error or "alignment failed").split(";")[0]
            groups.setdefault(reason, []).append(item)
    for reason, members in groups.items():
        text += f"\n  {len(members)} x {reason} (e.g. {members[0].recording})"
        if hint(members[0].error):
            text += f"\n    try: {hint(members[0].error)}"
    return text
