"""`feedlog sim PROGRAM --profile PROFILE [--out series.parquet] [--json]`: simulate a part program."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from feedlog.atomic import atomic_outputs
from feedlog.errors import FeedlogError, SimulationError


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("program", help="part program (G-code file)")
    parser.add_argument("--profile", required=True, help="machine profile: shipped name or .toml path")
    parser.add_argument("--out", type=Path, help="write the interpolated series as Parquet")
    parser.add_argument("--blocks-out", type=Path, help="write the per-block table as Parquet")
    parser.add_argument("--force", action="store_true", help="overwrite existing output files")
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


def _program(path: str):
    try:
        from feedlog.toolpath import parse_program  # noqa: PLC0415 (optional until toolpath lands)
    except ImportError:
        raise FeedlogError("feedlog.toolpath.parse_program is not available in this version") from None
    return parse_program(path)


def run(args: argparse.Namespace) -> int:
    from feedlog.sim.simulate import simulate  # noqa: PLC0415

    for out in (args.out, args.blocks_out):
        if out is not None and out.exists() and not args.force:
            raise FeedlogError(f"{out} exists; pass --force to overwrite")
    program = _program(args.program)
    result = simulate(program, args.profile, mechanisms=parse_settings(args.set, args.enable, args.disable) or None,
                      dt_s=args.dt)
    outputs = {path: table for path, table in ((args.out, lambda: result.series), (args.blocks_out, lambda: result.blocks))
               if path is not None}
    if outputs:
        with atomic_outputs(*outputs) as temporaries:  # both files or neither
            for temporary, table in zip(temporaries, outputs.values()):
                table().to_parquet(temporary, index=False)
    summary = {"program": str(args.program), **result.summary()}
    if args.json:
        json.dump(summary, sys.stdout, allow_nan=False)
        sys.stdout.write("\n")
    else:
        print(f"{args.program}: {summary['blocks']} blocks on {summary['profile']}: cycle time "
              f"{result.cycle_time_s:.3f} s (CAM estimate {result.cam_time_s:.3f} s)")
        print("mechanisms: " + ", ".join(summary["mechanisms"]))
    return 0
