"""`feedlog sim PROGRAM... --profile PROFILE [--out series.parquet | -o OUTDIR] [--json]`: simulate part programs.

One program prints its summary (and writes `--out`/`--blocks-out`). Several programs (or `-o OUTDIR`)
run as one task each on `feedlog.execution`'s backend (`-j N`, `--scheduler ADDRESS`) and write
OUTDIR/<program stem>/{series,blocks}.parquet, summary.json and the dataset OUTDIR/dataset/
(`feedlog.sim.batch`). Programs and OUTDIR may be paths or fsspec URLs.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from feedlog.atomic import atomic_outputs
from feedlog.errors import FeedlogError, SimulationError
from feedlog.execution import add_arguments as add_execution_arguments

STREAM_BYTES = 16 << 20   # programs this large (~500k blocks) are simulated window by window


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("programs", nargs="+", metavar="PROGRAM", help="part program(s) (G-code files)")
    parser.add_argument("--profile", required=True, help="machine profile: shipped name or .toml path")
    parser.add_argument("--out", type=Path, help="write the interpolated series as Parquet")
    parser.add_argument("--blocks-out", type=Path, help="write the per-block table as Parquet")
    parser.add_argument("-o", "--outdir", help="output folder, one subfolder per program (needed for several)")
    parser.add_argument("--force", action="store_true", help="overwrite existing output files")
    parser.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
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


def _program(path: str):
    try:
        from feedlog.toolpath import parse_program  # noqa: PLC0415 (optional until toolpath lands)
    except ImportError:
        raise FeedlogError("feedlog.toolpath.parse_program is not available in this version") from None
    return parse_program(path)


def run(args: argparse.Namespace) -> int:
    if args.outdir is not None or len(args.programs) > 1:
        return _run_many(args)
    return _run_one(args, args.programs[0])


def _run_many(args: argparse.Namespace) -> int:
    from feedlog.sim.batch import simulate_many  # noqa: PLC0415

    if args.outdir is None:
        raise FeedlogError(f"{len(args.programs)} programs need an output folder: pass -o OUTDIR")
    if args.out is not None or args.blocks_out is not None:
        raise FeedlogError("--out/--blocks-out are for one program without -o; with -o each program's tables go "
                           "to OUTDIR/<program>/")
    items = simulate_many(args.programs, args.outdir, profile=args.profile,
                          mechanisms=parse_settings(args.set, args.enable, args.disable) or None, dt_s=args.dt,
                          jobs=args.jobs, scheduler=args.scheduler, overwrite=args.force, progress=not args.quiet)
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


def _run_one(args: argparse.Namespace, source: str) -> int:
    from feedlog.sim.simulate import simulate  # noqa: PLC0415

    for out in (args.out, args.blocks_out):
        if out is not None and out.exists() and not args.force:
            raise FeedlogError(f"{out} exists; pass --force to overwrite")
    mechanisms = parse_settings(args.set, args.enable, args.disable) or None
    if _streams(args, source, mechanisms):
        result = _run_windowed(args, source, mechanisms)
    else:
        program = _program(source)
        _check_fits(args, program)
        result = simulate(program, args.profile, mechanisms=mechanisms, dt_s=args.dt)
        outputs = {path: table for path, table in ((args.out, lambda: result.series),
                                                   (args.blocks_out, lambda: result.blocks)) if path is not None}
        if outputs:
            with atomic_outputs(*outputs) as temporaries:  # both files or neither
                for temporary, table in zip(temporaries, outputs.values()):
                    table().to_parquet(temporary, index=False)
    summary = {"program": str(source), **result.summary()}
    if args.json:
        json.dump(summary, sys.stdout, allow_nan=False)
        sys.stdout.write("\n")
    else:
        print(f"{source}: {summary['blocks']} blocks on {summary['profile']}: cycle time "
              f"{result.cycle_time_s:.3f} s (CAM estimate {result.cam_time_s:.3f} s)")
        print("mechanisms: " + ", ".join(summary["mechanisms"]))
    return 0


def _streams(args: argparse.Namespace, source: str, mechanisms) -> bool:
    """--stream, or by default a program file of STREAM_BYTES or more whose mechanisms all have a
    windowed form (otherwise the whole-program run, refused if it would not fit)."""
    if args.stream is not None:
        return args.stream
    try:
        large = Path(source).stat().st_size >= STREAM_BYTES
    except OSError:
        return False      # not a local file: parse_program says what is wrong with it
    if not large:
        return False
    from feedlog.profile import load_profile  # noqa: PLC0415
    from feedlog.sim.mechanism import resolve_mechanisms  # noqa: PLC0415
    from feedlog.sim.window import unsupported  # noqa: PLC0415

    return not unsupported(resolve_mechanisms(load_profile(args.profile), mechanisms))


def _run_windowed(args: argparse.Namespace, source: str, mechanisms):
    from tqdm import tqdm  # noqa: PLC0415

    from feedlog.sim.output import write_windowed  # noqa: PLC0415
    from feedlog.sim.window import WindowedSimulation  # noqa: PLC0415

    run = WindowedSimulation(source, args.profile, mechanisms=mechanisms, dt_s=args.dt, series=args.out is not None)
    try:
        size = Path(source).stat().st_size
    except OSError:
        size = None       # G-code text or a source without a size: the bar counts bytes only
    # disable=None: shown on a terminal only
    with tqdm(total=size, unit="B", unit_scale=True, desc="sim", disable=True if args.quiet else None,
              leave=False) as bar:
        return write_windowed(run, series=args.out, blocks=args.blocks_out,
                              progress=lambda r: bar.update(r.reader.chars - bar.n))


def _check_fits(args: argparse.Namespace, program) -> None:
    """Refuse (one line, exit 2) a whole-program run whose tables would not fit in memory."""
    from feedlog.profile import load_profile  # noqa: PLC0415
    from feedlog.sim.output import available_bytes, in_memory_bytes  # noqa: PLC0415

    profile = load_profile(args.profile)
    dt_s = args.dt or profile.interpolator.interpolation_period_s
    series_s = None
    if args.out is not None:   # the series lasts at least the CAM time (sum of L / F, dwells)
        from feedlog.toolpath.features import block_features  # noqa: PLC0415
        nominal = block_features(program, profile)["nominal_time_s"].to_numpy()
        series_s = float(np.nansum(nominal)) + float(program.blocks["dwell_s"].sum())
    need = in_memory_bytes(rows=len(program.blocks), series_s=series_s, dt_s=dt_s, axes=len(profile.axis_names))
    have = available_bytes()
    if need > have:
        raise SimulationError(f"simulating {program.name} at once needs about {need / 1e9:.1f} GB "
                              f"({have / 1e9:.1f} GB available); run it window by window with --stream "
                              "(--out/--blocks-out are then written to Parquet as it goes)")
