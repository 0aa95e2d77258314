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

import numpy as np

from feedlog.atomic import atomic_outputs
from feedlog.cli_options import add_output, add_overwrite, add_quiet
from feedlog.coverage import program_warnings
from feedlog.errors import FeedlogError, SimulationError
from feedlog.execution import add_arguments as add_execution_arguments
from feedlog.toolpath.cli import add_interpreter_arguments, interp_options
from feedlog.toolpath.dialects import DIALECTS

STREAM_BYTES = 16 << 20   # programs this large (~500k blocks) are simulated window by window


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
    add_interpreter_arguments(parser)
    add_execution_arguments(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.add_argument("--set", action="append", default=[], metavar="MECH.PARAM=VALUE",
                        help="set a mechanism parameter (value parsed as JSON), e.g. feed_override.override=0.5")
    parser.add_argument("--enable", action="append", default=[], metavar="MECH", help="switch a mechanism on")
    parser.add_argument("--disable", action="append", default=[], metavar="MECH", help="switch a mechanism off")
    parser.add_argument("--dt", type=float, help="output period in seconds (default: the profile's)")
    parser.add_argument("--stream", action=argparse.BooleanOptionalAction, default=None,
                        help="simulate window by window in bounded memory, writing --out/--blocks-out as it goes "
                             f"(default: for programs of {STREAM_BYTES >> 20} MiB or more)")


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


def _program(path: str, *, lenient: bool = False, dialect: str = "auto", interp=None):
    from feedlog.toolpath import load_program

    return load_program(path, lenient=lenient, dialect=dialect, interp=interp)


def run(args: argparse.Namespace) -> int:
    series_file = args.out is not None and str(args.out).lower().endswith(".parquet")
    if len(args.programs) > 1 or (args.out is not None and not series_file):
        return _run_many(args)
    return _run_one(args, args.programs[0], series=Path(args.out) if series_file else None)


def _run_many(args: argparse.Namespace) -> int:
    from feedlog.sim.batch import simulate_many

    if args.out is None or str(args.out).lower().endswith(".parquet"):
        raise FeedlogError(f"{len(args.programs)} programs need an output folder: pass -o OUTDIR")
    if args.blocks_out is not None:
        raise FeedlogError("--blocks-out is for one program; with -o OUTDIR each program's tables go to "
                           "OUTDIR/<program>/")
    items = simulate_many(args.programs, str(args.out), profile=args.profile,
                          mechanisms=parse_settings(args.set, args.enable, args.disable) or None, dt_s=args.dt,
                          jobs=args.jobs, scheduler=args.scheduler, overwrite=args.overwrite, progress=not args.quiet,
                          lenient=args.lenient, dialect=args.dialect, interp=interp_options(args))
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
    from feedlog.sim.batch import program_notes
    from feedlog.sim.simulate import simulate

    for out in (series, args.blocks_out):
        if out is not None and out.exists() and not args.overwrite:
            raise FeedlogError(f"{out} exists; pass --overwrite to replace it")
    mechanisms = parse_settings(args.set, args.enable, args.disable) or None
    if _streams(args, source, mechanisms):
        result = _run_windowed(args, source, mechanisms, series)
        notes = {"dialect": "rs274ngc"}
    else:
        program = _program(source, lenient=args.lenient, dialect=args.dialect, interp=interp_options(args))
        _check_fits(args, program, series)
        result = simulate(program, args.profile, mechanisms=mechanisms, dt_s=args.dt)
        outputs = {path: table for path, table in ((series, lambda: result.series),
                                                   (args.blocks_out, lambda: result.blocks)) if path is not None}
        if outputs:
            with atomic_outputs(*outputs) as temporaries:  # both files or neither
                for temporary, table in zip(temporaries, outputs.values()):
                    table().to_parquet(temporary, index=False)
        notes = program_notes(program)
        # only a fitted profile carries coverage: sampling the whole series for it costs memory (and a
        # program of hours at 1 kHz cannot be sampled at all), so a plain profile never asks for it
        beyond = (program_warnings(result.profile, result.series, program.blocks)
                  if getattr(result.profile, "coverage", None) else [])
        if beyond:  # a fitted profile used where its recordings never went
            notes = {**notes, "coverage_warnings": beyond}
    summary = {"program": str(source), **result.summary(), **notes}
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
    for warning in summary.get("coverage_warnings", []):
        print(f"feedlog sim: warning: {warning}", file=sys.stderr)
    return 0


def _streams(args: argparse.Namespace, source: str, mechanisms) -> bool:
    """--stream, or by default a program file of STREAM_BYTES or more whose mechanisms all have a
    windowed form (otherwise the whole-program run, refused if it would not fit). Only RS274/NGC text
    streams: another dialect is translated whole."""
    from feedlog.toolpath.load import stream_dialect

    if args.stream is False:
        return False
    if args.stream:
        dialect = stream_dialect(source, args.dialect)
        if dialect != "rs274ngc":
            raise FeedlogError(f"{source}: --stream reads RS274/NGC (LinuxCNC) programs; this one is {dialect}")
        return True
    try:
        large = Path(source).stat().st_size >= STREAM_BYTES
    except OSError:
        return False      # not a local file: parse_program says what is wrong with it
    if not large or stream_dialect(source, args.dialect) != "rs274ngc":
        return False
    from feedlog.profile import load_profile
    from feedlog.sim.mechanism import resolve_mechanisms
    from feedlog.sim.window import unsupported

    return not unsupported(resolve_mechanisms(load_profile(args.profile), mechanisms))


def _run_windowed(args: argparse.Namespace, source: str, mechanisms, series: Path | None):
    from tqdm import tqdm

    from feedlog.sim.output import write_windowed
    from feedlog.sim.window import WindowedSimulation

    run = WindowedSimulation(source, args.profile, mechanisms=mechanisms, dt_s=args.dt, series=series is not None,
                             lenient=args.lenient)
    try:
        size = Path(source).stat().st_size
    except OSError:
        size = None       # G-code text or a source without a size: the bar counts bytes only
    # disable=None: shown on a terminal only
    with tqdm(total=size, unit="B", unit_scale=True, desc="sim", disable=True if args.quiet else None,
              leave=False) as bar:
        return write_windowed(run, series=series, blocks=args.blocks_out,
                              progress=lambda r: bar.update(r.reader.chars - bar.n))


def _check_fits(args: argparse.Namespace, program, series: Path | None) -> None:
    """Refuse (one line, exit 2) a whole-program run whose tables would not fit in memory."""
    from feedlog.profile import load_profile
    from feedlog.sim.output import available_bytes, in_memory_bytes

    profile = load_profile(args.profile)
    dt_s = args.dt or profile.interpolator.interpolation_period_s
    series_s = None
    if series is not None:   # the series lasts at least the CAM time (sum of L / F, dwells)
        from feedlog.toolpath.features import block_features
        nominal = block_features(program, profile)["nominal_time_s"].to_numpy()
        series_s = float(np.nansum(nominal)) + float(program.blocks["dwell_s"].sum())
    need = in_memory_bytes(rows=len(program.blocks), series_s=series_s, dt_s=dt_s, axes=len(profile.axis_names))
    have = available_bytes()
    if need > have:
        raise SimulationError(f"simulating {program.name} at once needs about {need / 1e9:.1f} GB "
                              f"({have / 1e9:.1f} GB available); run it window by window with --stream "
                              "(--out/--blocks-out are then written to Parquet as it goes)")
