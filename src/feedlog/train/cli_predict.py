"""`feedlog predict PROGRAM --model CKPT [--profile M] [--json] [-o BLOCKS]`: predict a program's cycle time.

Prints `cycle_time_s` (text or `--json`); the per-block predictions (block, line, kind, nominal_time_s,
duration_s) are written only when asked: `-o BLOCKS` (.parquet, or .csv by suffix). Without
`--profile` the model's own training machine is used, the one whose axes the program needs when the
model was trained on several; a program moving an axis that machine lacks is refused.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from feedlog.atomic import atomic_output
from feedlog.cli_options import add_output, add_overwrite
from feedlog.errors import ModelError
from feedlog.toolpath.dialects import DIALECTS
from feedlog.train.predict import predict_program


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("program", help="part program (G-code: RS274/NGC, Fanuc/Hurco, Sinumerik)")
    parser.add_argument("--model", required=True, help="trained checkpoint (.pt) from feedlog train")
    parser.add_argument("--profile", help="machine profile (default: the model's training machine that has the "
                                          "program's axes)")
    add_output(parser, help="per-block predictions file (.parquet or .csv); none is written without it",
               aliases=("--output",))
    add_overwrite(parser)
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.add_argument("--lenient", action="store_true",
                        help="skip unsupported program codes (listed in the notes) instead of failing")
    parser.add_argument("--dialect", choices=DIALECTS, default="auto", help="G-code dialect (default: detected)")


def run(args: argparse.Namespace) -> int:
    program = Path(args.program)
    if not program.is_file():
        raise ModelError(f"{program}: part program not found")
    out = Path(args.out) if args.out else None
    if out is not None and out.exists() and not args.overwrite:
        raise ModelError(f"{out} exists; use --overwrite to replace it")
    pred = predict_program(program, args.model, profile=args.profile, name=program.stem, lenient=args.lenient,
                           dialect=args.dialect)
    if out is not None:
        with atomic_output(out) as temporary:
            if out.suffix == ".csv":
                pred.blocks.to_csv(temporary, index=False)
            else:
                pred.blocks.to_parquet(temporary, index=False)
    if args.json:
        print(json.dumps({**pred.to_dict(), "blocks_file": None if out is None else str(out)}, indent=1))
    else:
        print(f"cycle_time_s {pred.cycle_time_s:.3f}")
        print(f"cam_time_s {pred.cam_time_s:.3f}")
        where = f"per-block predictions -> {out}" if out else "per-block predictions: -o FILE.parquet"
        print(f"model {pred.model} ({pred.profile or 'no profile'}); {where}")
        for note in pred.notes:
            print(f"note: {note}")
    return 0
