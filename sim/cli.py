"""`feedlog sim PROGRAM... --profile PROFILE [-o OUTDIR | -o SERIES.parquet] [--json]`: simulate part programs.

One program prints its summary (and writes `-o SERIES.parquet`/`--blocks-out`). Several programs (or
`-o OUTDIR`, a folder) run as one task each on `feedlog.execution`'s backend (`-j N`, `--scheduler
ADDRESS`) and write OUTDIR/<program stem>/{series,blocks}.parquet, summary.json and the dataset
OUTDIR/dataset/ (`feedlog.sim.batch`). Programs and OUTDIR may be paths or fsspec URLs. `--lenient`
skips unsupported codes; the summary lists them (`skipped`) with the dialect read and its warnings.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from feedlog.atomic import atomic_outputs
from feedlog.cli_options import add_output, add_overwrite, add_quiet
from feedlog.errors import FeedlogError, SimulationError
from feedlog.execution import add_arguments as add_execution_arguments
from feedlog.toolpath.dialects import DIALECTS


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("programs", nargs="+", metavar="PROGRAM", help="part program(s) (G-code files)")
    parser.add_argument("--profile", required=True, help="machine profile: shipped name or .toml path")
    add_output(parser, metavar="OUT", aliases=("--outdir",),
               help="output folder, one subfolder per program (needed for several); for one program a "
                    "SERIES.parquet file gets the interpolated series")
    parser.add_argument("--blocks-out", type=Path, help="one program: write the per-block table as Parquet")
    add_overwrite(parser, help="replace existing output files", aliases=("--force",))
    add_quiet(parser, help="no progress bar")
    parser.add_argument("--lenient", action="store_true",
                        help="skip unsupported program codes (listed in the summary) instead of failing")
    parser.add_argument("--dialect", choices=DIALECTS, default="auto",
                        help="G-code dialect: rs274ngc (LinuxCNC), fanuc/hurco, sinumerik (default: detected)")
    add_execution_arguments(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.add_argument("--set", action="append", default=[], metavar="MECH.PARAM=VALUE",
                        help="set a mechanism parameter (value parsed as JSON), e.g. feed_override.override=0.5")
    parser.add_argument("--enable", action="append", default=[], metavar="MECH", help="switch a mechanism on")
    parser.add_argument("--disable", action="append", default=[], metavar="MECH", help="switch a mechanism off")
    parser.add_argument("--dt", type=float, help="output period in seconds (default: the profile's)")


def parse_settings(settings: list[str], enable: list[str], disable: list[str]) -> dict[str, Any]:
    """`--set/--enable/--disable` as the `mechanisms` mapping of `simulate`."""
    spec: dict[str, Any] = {}
    for name in enable:
        spec.setdefault(name, {})["enabled"] = True
    for item in settings:
        key, sep, value = item.partition("=")
        mech, dot, param = key.partition(".")
        if not (sep and dot and mech and param):
            raise SimulationError(f"--set expects MECH.PARAM=VALUE, got {item!r}")
        try:
            parsed = json.loads(value)
        except json.JSONDecodeError:
            parsed = value
        spec.setdefault(mech, {})[param] = parsed
    for name in disable:
        spec[name] = False
    return spec


def _program(path: str, *, lenient: bool = False, dialect: str = "auto"):
    from feedlog.toolpath import load_program  # noqa: PLC0415

    return load_program(path, lenient=lenient, dialect=dialect)


def run(args: argparse.Namespace) -> int:
    series_file = args.out is not None and str(args.out).lower().endswith(".parquet")
    if len(args.programs) > 1 or (args.out is not None and not series_file):
        return _run_many(args)
    return _run_one(args, args.programs[0], series=Path(args.out) if series_file else None)


def _run_many(args: argparse.Namespace) -> int:
    from feedlog.sim.batch import simulate_many  # noqa: PLC0415

    if args.out is None or str(args.out).lower().endswith(".parquet"):
        raise FeedlogError(f"{len(args.programs)} programs need an output folder: pass -o OUTDIR")
    if args.blocks_out is not None:
        raise FeedlogError("--blocks-out is for one program; with -o OUTDIR each program's tables go to "
                           "OUTDIR/<program>/")
    items = simulate_many(args.programs, str(args.out), profile=args.profile,
                          mechanisms=parse_settings(args.set, args.enable, args.disable) or None, dt_s=args.dt,
                          jobs=args.jobs, scheduler=args.scheduler, overwrite=args.overwrite, progress=not args.quiet,
                          lenient=args.lenient, dialect=args.dialect)
    failed = [i for i in items if not i.ok]
    for item in failed:
        print(f"feedlog sim: error: {item.program}: {item.error}", file=sys.stderr)
    if args.json:
        docs = [i.summary if i.ok else {"program": i.program, "error": i.error} for i in items]
        json.dump(docs[0] if len(docs) == 1 else docs, sys.stdout, allow_nan=False)
        sys.stdout.write("\n")
    else:
        for i in items:
            if i.ok:
                print(f"{i.program}: {i.summary['blocks']} blocks on {i.summary['profile']}: cycle time "
                      f"{i.summary['cycle_time_s']:.3f} s (CAM estimate {i.summary['cam_time_s']:.3f} s) -> {i.outdir}")
    return min((i.exit_code or 2 for i in failed), default=0)  # 1 if an output could not be written, else 2


def _run_one(args: argparse.Namespace, source: str, *, series: Path | None) -> int:
    from feedlog.sim.batch import program_notes  # noqa: PLC0415
    from feedlog.sim.simulate import simulate  # noqa: PLC0415

    for out in (series, args.blocks_out):
        if out is not None and out.exists() and not args.overwrite:
            raise FeedlogError(f"{out} exists; pass --overwrite to replace it")
    program = _program(source, lenient=args.lenient, dialect=args.dialect)
    result = simulate(program, args.profile, mechanisms=parse_settings(args.set, args.enable, args.disable) or None,
                      dt_s=args.dt)
    outputs = {path: table for path, table in ((series, lambda: result.series), (args.blocks_out, lambda: result.blocks))
               if path is not None}
    if outputs:
        with atomic_outputs(*outputs) as temporaries:  # both files or neither
            for temporary, table in zip(temporaries, outputs.values()):
                table().to_parquet(temporary, index=False)
    summary = {"program": str(source), **result.summary(), **program_notes(program)}
    if args.json:
        json.dump(summary, sys.stdout, allow_nan=False)
        sys.stdout.write("\n")
    else:
        print(f"{source}: {summary['blocks']} blocks on {summary['profile']}: cycle time "
              f"{result.cycle_time_s:.3f} s (CAM estimate {result.cam_time_s:.3f} s)")
        print("mechanisms: " + ", ".join(summary["mechanisms"]))
        if summary["dialect"] != "rs274ngc":
            print(f"dialect: {summary['dialect']}")
        for item in summary.get("skipped", []):
            print(f"skipped: line {item['line']}: {item['code']} ({item['reason']})")
        for warning in summary.get("warnings", []):
            if not warning.startswith("line ") or "skipped" not in warning:
                print(f"warning: {warning}")
    return 0
