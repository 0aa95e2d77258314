"""`feedlog predict PROGRAM --model CKPT [--profile M] [--json] [-o BLOCKS]`: predict a program's cycle time.

Prints `cycle_time_s` and writes the per-block predictions (block, line, kind, nominal_time_s,
duration_s) to Parquet (or CSV by suffix): BLOCKS, or `<program stem>.<model>.blocks.parquet` in the
current folder (never beside the program, which may sit in a read-only or source folder).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from feedlog.atomic import atomic_output
from feedlog.errors import ModelError
from feedlog.train.predict import predict_program


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("program", help="part program (.ngc)")
    parser.add_argument("--model", required=True, help="trained checkpoint (.pt) from feedlog train")
    parser.add_argument("--profile", help="machine profile (default: the one the model was trained with)")
    parser.add_argument("-o", "--output", help="per-block predictions file (.parquet or .csv)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")


def run(args: argparse.Namespace) -> int:
    program = Path(args.program)
    if not program.is_file():
        raise ModelError(f"{program}: part program not found")
    pred = predict_program(program, args.model, profile=args.profile, name=program.stem)
    out = Path(args.output) if args.output else Path(f"{program.stem}.{pred.model}.blocks.parquet")
    if out.exists() and not args.overwrite:
        raise ModelError(f"{out} exists; use --overwrite to replace it")
    with atomic_output(out) as temporary:
        if out.suffix == ".csv":
            pred.blocks.to_csv(temporary, index=False)
        else:
            pred.blocks.to_parquet(temporary, index=False)
    if args.json:
        print(json.dumps({**pred.to_dict(), "blocks_file": str(out)}, indent=1))
    else:
        print(f"cycle_time_s {pred.cycle_time_s:.3f}")
        print(f"cam_time_s {pred.cam_time_s:.3f}")
        print(f"model {pred.model} ({pred.profile or 'no profile'}); per-block predictions -> {out}")
        for note in pred.notes:
            print(f"note: {note}")
    return 0
